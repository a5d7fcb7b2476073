"""The SQP's quadratic subproblem: its data from a linearisation, and a reusable solver.

:func:`elastic_qp` turns a linearisation into the elastic QP of :mod:`stances.sqp`;
:class:`QPWorkspace` solves a sequence of such QPs with proxsuite (dense), warm-starting
each from the previous answer.
"""

from __future__ import annotations

import numpy as np

from .blocks import stack
from .qp_backend import proxsuite

_INFINITY = 1e20  # proxsuite's stand-in for an absent bound
_WARM_QP_ITERATIONS = 60


class QPWorkspace:
    """A proxsuite dense QP reused (and warm-started) across iterations."""

    def __init__(self):
        self.qp = None
        self.shape = None

    def _fresh(self, shape):
        qp = proxsuite.proxqp.dense.QP(shape[0], 0, shape[1], True)
        # The SQP corrects an inexact step at the next iteration, so a moderate
        # absolute accuracy suffices; the elastic QP is feasible by
        # construction, so proxsuite's infeasibility test is made strict (its
        # default fires falsely on our badly scaled first iterations).
        qp.settings.eps_abs = 1e-9
        qp.settings.eps_rel = 0.0
        qp.settings.eps_primal_inf = 1e-12
        # Bounded work per QP: an unlucky QP must not stall a search loop
        # (its step is still used; the line search judges it).
        qp.settings.max_iter = 300
        qp.settings.max_iter_in = 50
        qp.settings.verbose = False
        return qp

    def solve(self, hessian, gradient, inequality, lower, upper, box_lower, box_upper, accuracy=1e-6):
        shape = (len(gradient), inequality.shape[0])
        data = (hessian, gradient, None, None, inequality, lower, upper, box_lower, box_upper)
        if self.qp is not None and self.shape == shape:
            # A warm start usually finishes in a few iterations; when it does
            # not, it tends to crawl (measured: 7,000 iterations, 350 ms) where
            # a cold start takes a few milliseconds. Hence the short budget.
            self.qp.settings.eps_abs = accuracy
            self.qp.settings.max_iter = _WARM_QP_ITERATIONS
            self.qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            self.qp.update(*data)
            self.qp.solve()
            if self.qp.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED:
                return np.array(self.qp.results.x)
        # First solve, a change of size, or a warm start that did not finish.
        self.qp = self._fresh(shape)
        self.qp.settings.eps_abs = accuracy
        self.shape = shape
        self.qp.init(*data)
        self.qp.solve()
        return np.array(self.qp.results.x)


def elastic_qp(linearization, penalty):
    """Elastic QP data from a linearisation (the QP of :mod:`stances.sqp`).

    Each finite bound of a row gives one QP row (an equality gives two), so
    one-sided constraints (collisions, no adhesion) cost a single row.
    """
    value, jacobian, lower, upper, scale, _ = stack(linearization.blocks)
    n = len(linearization.gradient)
    hessian = np.zeros((n + 1, n + 1))
    # A small regularisation keeps the QP strictly convex in directions the
    # objective ignores (base translation, unconstrained lambdas).
    hessian[:n, :n] = linearization.hessian + 1e-8 * np.eye(n)
    hessian[n, n] = 1e-8
    gradient = np.append(linearization.gradient, penalty)
    # Rows are divided by their scale: every row then reads in "violations
    # that matter", the elastic variable enters with coefficient one, and
    # rows in newtons no longer dwarf rows in metres (proxsuite stalls on that).
    jacobian = jacobian / scale[:, None]
    lower_gap = (lower - value) / scale
    upper_gap = (upper - value) / scale
    has_upper = np.isfinite(upper_gap)
    has_lower = np.isfinite(lower_gap)
    upper_rows = np.hstack([jacobian[has_upper], -np.ones((has_upper.sum(), 1))])
    lower_rows = np.hstack([jacobian[has_lower], np.ones((has_lower.sum(), 1))])
    inequality = np.vstack([upper_rows, lower_rows])
    qp_lower = np.concatenate([np.full(has_upper.sum(), -_INFINITY), lower_gap[has_lower]])
    qp_upper = np.concatenate([upper_gap[has_upper], np.full(has_lower.sum(), _INFINITY)])
    box_lower = np.append(np.maximum(linearization.step_lower, -_INFINITY), 0.0)
    box_upper = np.append(np.minimum(linearization.step_upper, _INFINITY), _INFINITY)
    return hessian, gradient, inequality, qp_lower, qp_upper, box_lower, box_upper


__all__ = ["QPWorkspace", "elastic_qp"]
