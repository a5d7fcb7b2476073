"""Benchmark of the posture solver on randomised rigid stances, against scipy's SLSQP.

Run as ``.venv/bin/python bench/bench_posture.py``; prints a markdown table and
writes it to ``bench/results/posture.md``. With ``--qp-only`` it runs only the last
part, the side-by-side table of the SQP's QP subproblems (proxsuite with the library's
policy and with the old one, piqp dense and sparse when installed; see
``bench/qp_subproblems.py``), and writes it to ``bench/results/posture_qp.md``.

Stances are drawn with a fixed seed by perturbing the stances of the rigid
built-in scenarios (``stand``, ``hand-on-table``, ``foot-on-block``): each print
is shifted by a few centimetres and turned by a few degrees, and a print is
kept only when the whole robot-surface polygon lies on its surface.

Each stance is solved twice, on the same :class:`stances.problem.PostureProblem`:

* ``stances.solve`` (the library's SQP, proxsuite QPs);
* scipy's SLSQP, the obvious alternative a user would write: unknowns
  ``x = (dq, lambda)`` with ``q = pin.integrate(model, q0, dq)``, objective and
  constraints read from ``problem.linearize(q, lambda)`` with analytic
  Jacobians (the tangent columns chained through ``pin.dIntegrate``), rows
  divided by their scale as the SQP does, bounds from the joint limits and
  ``lambda >= 0``. One linearisation per ``x`` serves objective, constraints
  and Jacobians.

SLSQP counts as a success only when its final posture passes
:func:`stances.verify.verify_problem`, the same independent check a feasible
answer of ``stances.solve`` must pass.
"""

from __future__ import annotations

import datetime
import math
import os
import sys
import time

# One BLAS thread, set before numpy loads: on this shared 2-core machine a threaded
# OpenBLAS made each SLSQP subproblem (82 x 96 dense) some 30 times slower, by spinning
# on cores other processes hold. The SQP's times barely change either way.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

import qp_subproblems  # noqa: E402
from benchmark_info import code_version, machine  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402
from stances.problem import PostureOptions, build_problem  # noqa: E402
from stances.results import PostureResult  # noqa: E402
from stances.sqp import problem_point_forces, solve  # noqa: E402
from stances.verify import verify_problem  # noqa: E402

SEED = 20240607
STANCES_PER_SCENARIO = 20  # 3 scenarios -> 60 stances
SLSQP_MAX_ITERATIONS = 200
SLSQP_TIME_LIMIT = 3.0  # s per stance
SLSQP_FTOL = 1e-10  # SLSQP also stops on this for the norm of the (scaled) violation
TARGET_SUCCESS = 0.95
TARGET_MEDIAN = 0.100  # s

# Perturbations: (dx, dy) ranges in metres, dtheta in degrees, per (scenario, robot surface).
# Feet only move outwards in y so the soles never overlap; prints off their surface are redrawn.
SHIFTS = {
    "left_sole": ((-0.06, 0.10), (0.0, 0.05), 8.0),
    "right_sole": ((-0.06, 0.10), (-0.05, 0.0), 8.0),
    "right_palm": ((-0.06, 0.08), (-0.06, 0.06), 10.0),
}
BLOCK_SHIFT = ((-0.04, 0.04), (-0.04, 0.04), 5.0)  # right sole on the block top


class _TimeLimit(Exception):
    """Raised from inside SLSQP's callbacks when its time budget is spent."""


def _print_on_surface(robot, scene, robot_surface, contact_print) -> bool:
    surface = scene.surface(contact_print.surface)
    corners = surface.print_polygon_in_surface(
        robot.surface(robot_surface).polygon, contact_print.x, contact_print.y, contact_print.theta
    )
    return bool(np.all(surface.contains(corners)))


def random_stances(robot, rng):
    """(scenario name, scene, stance) triples, STANCES_PER_SCENARIO per rigid scenario."""
    cases = []
    for scenario_name, stance_name in (("stand", "stand"), ("hand-on-table", "hand-on-table"),
                                       ("foot-on-block", "foot-on-block")):
        scenario = environments.load(scenario_name)
        nominal = scenario.stances[stance_name]
        drawn = 0
        while drawn < STANCES_PER_SCENARIO:
            contacts = []
            for contact in nominal:
                p = contact.contact_print
                on_block = p.surface != "floor" and contact.robot_surface.endswith("sole")
                (x_lo, x_hi), (y_lo, y_hi), theta_deg = BLOCK_SHIFT if on_block else SHIFTS[contact.robot_surface]
                moved = environments.ContactPrint(
                    p.surface,
                    p.x + rng.uniform(x_lo, x_hi),
                    p.y + rng.uniform(y_lo, y_hi),
                    p.theta + math.radians(rng.uniform(-theta_deg, theta_deg)),
                )
                contacts.append(environments.Contact(contact.robot_surface, moved))
            if all(_print_on_surface(robot, scenario.scene, c.robot_surface, c.contact_print) for c in contacts):
                cases.append((scenario_name, scenario.scene, environments.Stance(tuple(contacts))))
                drawn += 1
    return cases


class SlsqpProblem:
    """The posture problem as SLSQP functions of x = (dq from q0, lambda).

    One linearisation per x (cached on ``x.tobytes()``) serves the objective,
    the constraints and their Jacobians. Constraint rows are those of
    ``problem.linearize``: equalities where ``lower == upper``, one inequality
    per finite bound otherwise; the collision block's rows are kept even when
    inactive (value +1, zero Jacobian) so their number stays fixed.
    """

    def __init__(self, problem, q0, lam0, deadline):
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

    def _evaluate(self, x):
        key = x.tobytes()
        if key == self._key:
            return
        if time.perf_counter() > self.deadline:
            raise _TimeLimit
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
        self.linearization = lin
        self._key = key

    def fun(self, x):
        self._evaluate(x)
        return self.objective[0]

    def jac(self, x):
        self._evaluate(x)
        return self.objective[1]

    def constraints(self):
        def part(name, index):
            def function(x):
                self._evaluate(x)
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
        # Revolute joints: q[7:] = q0[7:] + dq[6:] exactly.
        lower[6:nv] = self.model.lowerPositionLimit[7:] - self.q0[7:]
        upper[6:nv] = self.model.upperPositionLimit[7:] - self.q0[7:]
        lower[nv:] = self.problem.variable_lower
        return list(zip(lower, upper))


def solve_slsqp(robot, scene, stance):
    """SLSQP on the stance's posture problem; returns (success, seconds, iterations, why, violation)."""
    problem = build_problem(robot, scene, stance, PostureOptions())
    start = time.perf_counter()
    q0 = problem.check_configuration(robot.reference_configuration)
    lam0 = problem.initial_variables(q0)
    wrapped = SlsqpProblem(problem, q0, lam0, start + SLSQP_TIME_LIMIT)
    x0 = np.concatenate([np.zeros(robot.nv), lam0])
    best = {"x": x0}
    try:
        answer = minimize(
            wrapped.fun, x0, jac=wrapped.jac, method="SLSQP", bounds=wrapped.bounds(lam0),
            constraints=wrapped.constraints(),
            options={"maxiter": SLSQP_MAX_ITERATIONS, "ftol": SLSQP_FTOL},
            callback=lambda xk: best.update(x=np.array(xk), nit=best.get("nit", 0) + 1),
        )
        x, iterations, message, converged = answer.x, answer.nit, answer.message, answer.success
    except _TimeLimit:
        x, iterations = best["x"], best.get("nit", 0)
        message, converged = f"time limit {SLSQP_TIME_LIMIT:g} s", False
    elapsed = time.perf_counter() - start
    # Final check, outside the timed region: linearise at the answer, build a result, verify it.
    nv = robot.nv
    q = wrapped.configuration(x)
    lam = np.maximum(x[nv:], 0.0)
    lin = problem.linearize(q, lam)
    violation, label = lin.max_violation()
    result = PostureResult(
        feasible=False, q=q, point_forces=problem_point_forces(problem, lin, q), torques=lin.torques[6:],
        iterations=iterations, solve_time=elapsed, reason="", stance=stance,
    )
    verification = verify_problem(problem, result)
    why = "" if verification.ok else f"{message}; {'; '.join(verification.reasons)}"
    if not verification.ok and violation > 0:
        why += f" (worst row: {label}, {violation:.2g} scaled)"
    return verification.ok, converged, elapsed, iterations, why, violation


def summary(name, successes, times, iterations):
    times_ms = 1e3 * np.asarray(times)
    return (
        f"| {name} | {np.mean(successes):.0%} ({int(np.sum(successes))}/{len(successes)}) "
        f"| {np.median(times_ms):.1f} | {np.percentile(times_ms, 90):.1f} | {np.median(iterations):.0f} |"
    )


def qp_section(robot):
    """The side-by-side QP table, as a markdown section."""
    return f"""QP subproblems of the SQP, side by side:

{qp_subproblems.table(robot)}
"""


def main_qp_only():
    robot = stances.Robot.load("talos")
    text = f"""# Posture solver: QP subproblems

Date: {datetime.date.today().isoformat()}
Machine: {machine()}
Code: {code_version()}

{qp_section(robot)}"""
    print(text)
    with open(os.path.join(os.path.dirname(__file__), "results", "posture_qp.md"), "w") as handle:
        handle.write(text)


def main():
    robot = stances.Robot.load("talos")
    rng = np.random.default_rng(SEED)
    cases = random_stances(robot, rng)
    # One untimed solve so imports and first-call caches are not charged to stance 1.
    solve(robot, cases[0][1], cases[0][2])

    ours = {"ok": [], "time": [], "wall": [], "it": []}
    theirs = {"ok": [], "time": [], "it": [], "converged": [], "violation": []}
    failures = []
    per_scenario = {}
    for index, (scenario_name, scene, stance) in enumerate(cases):
        tic = time.perf_counter()
        result = solve(robot, scene, stance)
        wall = time.perf_counter() - tic
        ours["ok"].append(result.feasible)
        ours["time"].append(result.solve_time)
        ours["wall"].append(wall)
        ours["it"].append(result.iterations)
        ok, converged, seconds, iterations, why, violation = solve_slsqp(robot, scene, stance)
        theirs["ok"].append(ok)
        theirs["converged"].append(converged)
        theirs["time"].append(seconds)
        theirs["it"].append(iterations)
        theirs["violation"].append(violation)
        per_scenario.setdefault(scenario_name, []).append((result.feasible, result.solve_time, ok, seconds))
        if not result.feasible:
            failures.append(f"- stances.solve, stance {index} ({scenario_name}): {result.reason} {stance.to_dict()}")
        if not ok:
            failures.append(f"- SLSQP, stance {index} ({scenario_name}): {why}")
        print(
            f"{index:3d} {scenario_name:14s} ours {'ok ' if result.feasible else 'NO '} "
            f"{1e3 * result.solve_time:7.1f} ms {result.iterations:3d} it | SLSQP {'ok ' if ok else 'NO '} "
            f"{1e3 * seconds:7.1f} ms {iterations:3d} it viol {violation:.1e}",
            file=sys.stderr,
        )

    table = "\n".join(
        [
            "| method | success | median ms | p90 ms | median iterations |",
            "|---|---|---|---|---|",
            summary("stances.solve (SQP, proxsuite)", ours["ok"], ours["time"], ours["it"]),
            summary("stances.solve, wall clock incl. build + verify", ours["ok"], ours["wall"], ours["it"]),
            summary("scipy SLSQP, same problem functions", theirs["ok"], theirs["time"], theirs["it"]),
        ]
    )
    scenario_rows = ["| scenario | stances | ours success | ours median ms | SLSQP success | SLSQP median ms |",
                     "|---|---|---|---|---|---|"]
    for name, rows in per_scenario.items():
        rows = np.array(rows, dtype=float)
        scenario_rows.append(
            f"| {name} | {len(rows)} | {rows[:, 0].mean():.0%} | {1e3 * np.median(rows[:, 1]):.1f} "
            f"| {rows[:, 2].mean():.0%} | {1e3 * np.median(rows[:, 3]):.1f} |"
        )

    success = float(np.mean(ours["ok"]))
    median = float(np.median(ours["time"]))
    verdicts = [
        f"- success {success:.0%} (target >= {TARGET_SUCCESS:.0%}): {'MET' if success >= TARGET_SUCCESS else 'MISSED'}",
        f"- median solve time {1e3 * median:.1f} ms (target < {1e3 * TARGET_MEDIAN:.0f} ms): "
        f"{'MET' if median < TARGET_MEDIAN else 'MISSED'}",
    ]
    slsqp_converged = int(np.sum(theirs["converged"]))
    text = f"""# Posture solver benchmark

Date: {datetime.date.today().isoformat()}
Machine: {machine()}
Code: {code_version()}
Stances: {len(cases)} (seed {SEED}; {STANCES_PER_SCENARIO} each perturbed from the built-in
`stand`, `hand-on-table` and `foot-on-block` stances: prints shifted by a few cm and turned by
up to 5-10 degrees, whole print polygon kept on its surface).

Times exclude building the problem (collision checker, contact models) and, for
`stances.solve`, the final `verify` (its `solve_time`); the wall-clock row includes both.
SLSQP: `scipy.optimize.minimize(method="SLSQP")` over x = (dq from the reference posture,
lambda), objective and constraints of `PostureProblem.linearize` with analytic Jacobians
(tangent columns times `pin.dIntegrate`), rows divided by their scale, bounds from joint limits
and lambda >= 0, maxiter {SLSQP_MAX_ITERATIONS}, ftol {SLSQP_FTOL:g}, time limit {SLSQP_TIME_LIMIT:g} s.
A success is a final posture that passes `stances.verify.verify_problem` (for both methods).
SLSQP reported convergence on {slsqp_converged}/{len(cases)} stances.

{table}

Per scenario:

{chr(10).join(scenario_rows)}

Targets (stances.solve):

{chr(10).join(verdicts)}

Failures:

{chr(10).join(failures) if failures else "- none"}

{qp_section(robot)}"""
    print(text)
    out = os.path.join(os.path.dirname(__file__), "results", "posture.md")
    with open(out, "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    if "--qp-only" in sys.argv[1:]:
        main_qp_only()
    else:
        main()
