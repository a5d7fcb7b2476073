"""The posture problem as a plain nonlinear program, for general-purpose NLP solvers.

The baselines of ``bench/bench_posture.py`` (scipy's SLSQP, IPOPT through casadi)
solve the same :class:`stances.problem.PostureProblem` as ``stances.solve``: the
unknowns are ``x = (dq, lambda)`` with ``q = pin.integrate(model, q0, dq)``, and the
objective, constraint rows and their exact Jacobians are read from
``problem.linearize`` (tangent columns chained through ``pin.dIntegrate``). Their
answers pass the same final check, :func:`stances.verify.verify_problem`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from stances import initial_configuration, reaching_configuration
from stances.results import PostureResult
from stances.sqp import problem_point_forces
from stances.verify import verify_problem


def first_start(problem) -> np.ndarray:
    """(nq,) the posture ``stances.solve_problem`` starts a rigid stance from when given
    none: the reference posture over the prints brought onto them (its first attempt; it
    falls back to the posture over the prints when that attempt fails)."""
    robot, scene, stance = problem.robot, problem.scene, problem.stance
    start = reaching_configuration(robot, scene, stance, initial_configuration(robot, scene, stance))
    return problem.check_configuration(start)


class TimeLimit(Exception):
    """Raised from inside a baseline's callbacks when its time budget is spent."""


class PostureNlp:
    """The posture problem as NLP functions of x = (dq from q0, lambda), for SLSQP and IPOPT.

    One linearisation per x (cached on ``x.tobytes()``) serves the objective,
    the constraints and their Jacobians. Constraint rows are those of
    ``problem.linearize``: equalities where ``lower == upper``, one inequality
    per finite bound otherwise; the collision block's rows are kept even when
    inactive (value +1, zero Jacobian) so their number stays fixed.
    """

    def __init__(self, problem, q0, lam0, deadline):
        """``deadline``: a ``time.process_time()`` value (CPU seconds, not wall clock: the
        machine is shared) past which an evaluation raises :class:`TimeLimit`."""
        self.problem = problem
        self.model = problem.robot.model
        self.q0 = q0
        self.nv = self.model.nv
        self.deadline = deadline
        self.evaluations = 0
        self._key = None
        first = problem.linearize(q0, lam0)
        lower, upper = self._stacked_bounds(first)
        collision = np.concatenate([np.full(len(b), b.name == "collision") for b in first.blocks])
        equal = lower == upper
        self.equality_rows = np.flatnonzero(equal)
        self.lower_rows = np.flatnonzero(~equal & (np.isfinite(lower) | collision))
        self.upper_rows = np.flatnonzero(~equal & np.isfinite(upper))

    @staticmethod
    def _stacked_bounds(linearization):
        blocks = linearization.blocks
        return np.concatenate([b.lower for b in blocks]), np.concatenate([b.upper for b in blocks])

    def configuration(self, x):
        return pin.integrate(self.model, self.q0, x[: self.nv])

    def evaluate(self, x):
        key = x.tobytes()
        if key == self._key:
            return
        if time.process_time() > self.deadline:
            raise TimeLimit
        self.evaluations += 1
        nv = self.nv
        q = self.configuration(x)
        lin = self.problem.linearize(q, x[nv:])
        chain = pin.dIntegrate(self.model, self.q0, x[:nv], pin.ARG1)

        blocks = lin.blocks
        value = np.concatenate([b.value for b in blocks])
        jacobian = np.vstack([b.jacobian for b in blocks])
        scale = np.concatenate([b.scale for b in blocks])
        lower, upper = self._stacked_bounds(lin)
        jacobian = jacobian / scale[:, None]
        jacobian[:, :nv] = jacobian[:, :nv] @ chain
        e, lo, up = self.equality_rows, self.lower_rows, self.upper_rows
        self.eq = ((value[e] - lower[e]) / scale[e], jacobian[e])
        # An inactive collision row (lower = -inf) reads +1 with no gradient: satisfied.
        active = np.isfinite(lower[lo])
        lower_value = np.where(active, (value[lo] - np.where(active, lower[lo], 0.0)) / scale[lo], 1.0)
        lower_jacobian = jacobian[lo] * active[:, None]
        self.ineq = (
            np.concatenate([lower_value, (upper[up] - value[up]) / scale[up]]),
            np.vstack([lower_jacobian, -jacobian[up]]),
        )
        gradient = lin.gradient.copy()
        gradient[:nv] = chain.T @ gradient[:nv]
        self.objective = (lin.objective, gradient)
        # The objective's Gauss-Newton Hessian (the SQP's), its tangent rows and
        # columns chained like the gradient (the chain's own curvature left out).
        hessian = lin.hessian.copy()
        hessian[:nv] = chain.T @ hessian[:nv]
        hessian[:, :nv] = hessian[:, :nv] @ chain
        self.hessian = hessian
        self.linearization = lin
        self._key = key

    def fun(self, x):
        self.evaluate(x)
        return self.objective[0]

    def jac(self, x):
        self.evaluate(x)
        return self.objective[1]

    def constraints(self):
        def part(name, index):
            def function(x):
                self.evaluate(x)
                return getattr(self, name)[index]
            return function
        return [
            {"type": "eq", "fun": part("eq", 0), "jac": part("eq", 1)},
            {"type": "ineq", "fun": part("ineq", 0), "jac": part("ineq", 1)},
        ]

    def bounds(self, lam0):
        nv = self.nv
        lower = np.full(nv + len(lam0), -np.inf)
        upper = np.full(nv + len(lam0), np.inf)
        # Revolute joints: q[7:] = q0[7:] + dq[6:] exactly. The limits less the joint
        # margin, as the SQP keeps them (problem.q_lower, q_upper).
        lower[6:nv] = self.problem.q_lower - self.q0[7:]
        upper[6:nv] = self.problem.q_upper - self.q0[7:]
        lower[nv:] = self.problem.variable_lower
        return list(zip(lower, upper))


@dataclass(frozen=True)
class BaselineRun:
    """One baseline solve of one stance.

    Attributes
    ----------
    ok : bool
        The final posture passes :func:`stances.verify.verify_problem`.
    converged : bool
        The solver itself reported success.
    seconds, cpu_seconds : float
        Wall-clock and process CPU time of the solve, s (the final check excluded).
    iterations : int
    why : str
        Empty when ok; otherwise the solver's message, the verification's
        reasons and the worst row.
    violation : float
        Largest scaled row violation at the answer (as the SQP measures it).
    """

    ok: bool
    converged: bool
    seconds: float
    cpu_seconds: float
    iterations: int
    why: str
    violation: float


def final_check(problem, wrapped, x, *, stance, iterations, message, converged, seconds, cpu_seconds) -> BaselineRun:
    """Linearise at a baseline's answer ``x`` (n,), verify the posture it gives, and
    record the run."""
    nv = problem.robot.model.nv
    q = wrapped.configuration(x)
    lam = np.maximum(x[nv:], 0.0)
    lin = problem.linearize(q, lam)
    violation, label = lin.max_violation()
    result = PostureResult(
        feasible=False, q=q, point_forces=problem_point_forces(problem, lin, q), torques=lin.torques[6:],
        iterations=iterations, solve_time=seconds, reason="", stance=stance,
    )
    verification = verify_problem(problem, result)
    why = "" if verification.ok else f"{message}; {'; '.join(verification.reasons)}"
    if not verification.ok and violation > 0:
        why += f" (worst row: {label}, {violation:.2g} scaled)"
    return BaselineRun(verification.ok, converged, seconds, cpu_seconds, iterations, why, violation)
