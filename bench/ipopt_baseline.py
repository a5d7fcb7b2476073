"""IPOPT on the posture problem, through casadi, with the library's own functions.

casadi's ``nlpsol("ipopt")`` takes an NLP of casadi expressions; here the whole
problem is one :class:`casadi.Callback` around :class:`posture_nlp.PostureNlp`,
``x -> (f, g)`` with ``g`` the scaled equality rows then the scaled inequality
rows (``>= 0``), and a second callback for the exact Jacobians of both, so IPOPT
calls into numpy and pinocchio exactly where SLSQP does (one linearisation per x,
cached). Second derivatives of the constraints are not available; IPOPT gets the
curvature the SQP uses, the objective's Gauss-Newton Hessian, as its Hessian of
the Lagrangian (a third callback, casadi's ``hess_lag``).

casadi rather than cyipopt: casadi's wheel ships IPOPT with MUMPS and installs
with pip alone (cyipopt needs an IPOPT library built on the machine), and its
callbacks are cheap enough: a call answered from the cache costs 0.09 ms,
against 3.7 ms for a linearisation of a `stand` stance (measured here).
"""

from __future__ import annotations

import math
import time

import casadi
import numpy as np

from posture_nlp import BaselineRun, PostureNlp, final_check, first_start

from stances.problem import PostureOptions, build_problem

VERSION = f"casadi {casadi.__version__}"
TIME_LIMIT = 3.0  # CPU s per stance, IPOPT's own max_cpu_time (the SLSQP budget)
OPTIONS = {
    # The objective's Gauss-Newton Hessian, as the SQP has it (see _ObjectiveHessian).
    # IPOPT's limited-memory Hessian instead was measured on six stances of the
    # benchmark: none converged within 3 s (76-180 iterations, steps of 1e3-1e4 in x).
    "hessian_approximation": "exact",
    # Against the default (monotone) on those six: 60, 39, 30, 37 iterations instead of
    # 143, 130, 41, 62 on the hand and foot stances, 17 instead of 15-16 on the two stand.
    "mu_strategy": "adaptive",
    # Rows are scaled as the SQP scales them (1 = a violation that matters); the
    # SQP accepts 1e-7 of that, so IPOPT is asked for the same.
    "constr_viol_tol": 1e-7,
    "tol": 1e-8,
    "max_iter": 3000,
    "max_cpu_time": TIME_LIMIT,
    # IPOPT relaxes bounds by 1e-8 while it iterates; its answer is put back inside them.
    "honor_original_bounds": "yes",
    "print_level": 0,
    "sb": "yes",
}


class _Functions(casadi.Callback):
    """``x (n,) -> (f (1,), g (e + i,))`` of a :class:`PostureNlp`, with exact Jacobians."""

    def __init__(self, wrapped, n, rows):
        casadi.Callback.__init__(self)
        self.wrapped, self.n, self.rows = wrapped, n, rows
        self._jacobian = None  # casadi holds only a reference: keep the callback alive
        self.construct("posture_functions", {})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return 2

    def get_sparsity_in(self, index):
        return casadi.Sparsity.dense(self.n, 1)

    def get_sparsity_out(self, index):
        return casadi.Sparsity.dense(1, 1) if index == 0 else casadi.Sparsity.dense(self.rows, 1)

    def eval(self, arguments):
        wrapped = self.wrapped
        wrapped.evaluate(np.asarray(arguments[0]).ravel())
        return [wrapped.objective[0], np.concatenate([wrapped.eq[0], wrapped.ineq[0]])]

    def has_jacobian(self):
        return True

    def get_jacobian(self, name, inames, onames, options):
        self._jacobian = _Jacobians(name, self.wrapped, self.n, self.rows, options)
        return self._jacobian


class _Jacobians(casadi.Callback):
    """``(x, f, g) -> (df/dx (1, n), dg/dx (e + i, n))``: casadi's Jacobian signature
    (the nominal outputs come in as inputs, unused)."""

    def __init__(self, name, wrapped, n, rows, options):
        casadi.Callback.__init__(self)
        self.wrapped, self.n, self.rows = wrapped, n, rows
        self.construct(name, options)

    def get_n_in(self):
        return 3

    def get_n_out(self):
        return 2

    def get_sparsity_in(self, index):
        return [casadi.Sparsity.dense(self.n, 1), casadi.Sparsity.dense(1, 1),
                casadi.Sparsity.dense(self.rows, 1)][index]

    def get_sparsity_out(self, index):
        return casadi.Sparsity.dense(1, self.n) if index == 0 else casadi.Sparsity.dense(self.rows, self.n)

    def eval(self, arguments):
        wrapped = self.wrapped
        wrapped.evaluate(np.asarray(arguments[0]).ravel())
        return [wrapped.objective[1][None, :], np.vstack([wrapped.eq[1], wrapped.ineq[1]])]


class _ObjectiveHessian(casadi.Callback):
    """casadi's ``hess_lag`` signature, ``(x, p, lam_f, lam_g) -> triu(H)`` (n, n), with
    ``H = lam_f`` times the objective's Gauss-Newton Hessian: the curvature the SQP
    uses (the constraints' is not available)."""

    def __init__(self, wrapped, n, rows):
        casadi.Callback.__init__(self)
        self.wrapped, self.n, self.rows = wrapped, n, rows
        self.construct("posture_hessian", {})

    def get_n_in(self):
        return 4

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, index):
        return [casadi.Sparsity.dense(self.n, 1), casadi.Sparsity.dense(0, 1), casadi.Sparsity.dense(1, 1),
                casadi.Sparsity.dense(self.rows, 1)][index]

    def get_sparsity_out(self, index):
        return casadi.Sparsity.upper(self.n)

    def eval(self, arguments):
        self.wrapped.evaluate(np.asarray(arguments[0]).ravel())
        weight = float(arguments[2])
        return [casadi.triu(casadi.DM(weight * self.wrapped.hessian))]


def solve_ipopt(robot, scene, stance) -> BaselineRun:
    """IPOPT on the stance's posture problem; the time covers building casadi's solver too."""
    problem = build_problem(robot, scene, stance, PostureOptions())
    start, cpu_start = time.perf_counter(), time.process_time()
    q0 = first_start(problem)  # where stances.solve starts
    lam0 = problem.initial_variables(q0)
    wrapped = PostureNlp(problem, q0, lam0, deadline=math.inf)  # IPOPT keeps its own time limit
    n = robot.nv + len(lam0)
    equalities, inequalities = len(wrapped.equality_rows), len(wrapped.lower_rows) + len(wrapped.upper_rows)
    functions = _Functions(wrapped, n, equalities + inequalities)
    x = casadi.MX.sym("x", n)
    f, g = functions(x)
    options = {"ipopt": OPTIONS, "print_time": False, "error_on_fail": False}
    if OPTIONS["hessian_approximation"] == "exact":
        options["hess_lag"] = _ObjectiveHessian(wrapped, n, equalities + inequalities)
    solver = casadi.nlpsol("ipopt", "ipopt", {"x": x, "f": f, "g": g}, options)
    bounds = np.array(wrapped.bounds(lam0))
    answer = solver(
        x0=np.concatenate([np.zeros(robot.nv), lam0]), lbx=bounds[:, 0], ubx=bounds[:, 1],
        lbg=np.zeros(equalities + inequalities),
        ubg=np.concatenate([np.zeros(equalities), np.full(inequalities, np.inf)]),
    )
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu_start
    statistics = solver.stats()
    return final_check(
        problem, wrapped, np.asarray(answer["x"]).ravel(), stance=stance,
        iterations=int(statistics.get("iter_count", 0)), message=statistics["return_status"],
        converged=bool(statistics["success"]), seconds=seconds, cpu_seconds=cpu_seconds,
    )
