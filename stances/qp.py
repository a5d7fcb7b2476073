"""The SQP's quadratic subproblem: its data from a linearisation, and a solver.

:func:`elastic_qp` turns a linearisation into the elastic QP of :mod:`stances.sqp`,
always feasible; :func:`plain_qp` into the QP without the elastic variable, which the
SQP solves first once its linearised rows are compatible (the previous elastic QP met
them); :class:`QPWorkspace` solves either with proxsuite (dense), each from a cold start.
"""

from __future__ import annotations

import numpy as np

from .blocks import stack
from .qp_backend import proxsuite

_INFINITY = 1e20  # proxsuite's stand-in for an absent bound
_WARM_QP_ITERATIONS = 60
_QP_ITERATIONS = 300  # proxsuite's iteration limit of a QP
_COLD_SHAPES = 8  # proxsuite objects a workspace keeps for cold starts (an SQP's QPs take two or three shapes)
# proxsuite's first proximal weight on the inequality rows (its default_mu_in, 0.1 by
# default). Measured on 76 QPs recorded from the SQPs of six stances (hand-on-table,
# stand, foot-on-block; hand-on-cube, foot-and-hand-on-foam, cross-two-mats), each
# solved from a cold start: 2,076 proxsuite iterations at 1e-3 against 3,514 at 0.1
# (3,612 with the warm starts of the previous policy), objectives as close to a 1e-11
# accurate answer (worst relative excess 1.5e-4 at 1e-3, 1.2e-4 at 0.1).
_FIRST_PROXIMAL_IN = 1e-3
# Iterations of proxsuite's Ruiz equilibration, run at every QP's init (its default 10;
# its 1e-3 accuracy is never met on these QPs, so all 10 ran). Measured by replaying
# the 424 QPs of the 60 random rigid stances (instruction counts, valgrind: the host's
# timings moved by 30 %): 5.54 G instructions at 10, 4.35 G at 3 (4,966 proxsuite
# iterations against 5,033), 4.50 G at 2, 4.66 G at 1, 4.77 G at 5; objectives within
# 7.6e-5 of a 1e-10 accurate answer (3.8e-6 at 10): the SQP corrects the step anyway.
_PRECONDITIONER_ITERATIONS = 3
_INACTIVE_MULTIPLIER = 1e-8  # QP multipliers (objective units per scaled row) below this are zero
_PENALTY_REFERENCE = 1e2  # the SQP's first elastic penalty (PostureOptions.elastic_penalty)
_SCALED_PENALTY = 1e6  # from this penalty on, the QP's objective is divided (objective_scale)


def objective_scale(penalty: float) -> float:
    """What the elastic QP's objective is divided by: 1, or from a penalty of 1e6 on,
    the penalty over 1e2.

    An infeasible stance drives the SQP's penalty to 1e6-1e8, where the elastic
    variable's cost outweighs the step's curvature by up to 1e16: proxsuite then
    spent 0.2-1.1 s on a QP of 99 variables, at its iteration limits (a two-palm
    stance of hand-on-table: 8 s for 15 iterations). Dividing the objective keeps
    the penalty the QP sees at 1e2 and changes no exact answer; the multipliers
    come out divided by the same factor (:func:`row_multipliers` takes it back).
    Below 1e6 it is left alone: converging solves reach 1e5 (step-on-cube's
    rigid support), and there the divided QP's looser dual accuracy took 8-14
    iterations instead of 7, and an accuracy divided as well cost 10x the QP time.
    """
    return float(penalty) / _PENALTY_REFERENCE if penalty >= _SCALED_PENALTY else 1.0


class QPWorkspace:
    """proxsuite dense QPs, solved from a cold start (or, with :attr:`warm_start`, from the
    previous answer when the shape is the same).

    Attributes
    ----------
    warm_start : bool
        Class setting: start a QP of the previous one's shape from its answer
        (False: every QP from x = 0).
    first_proximal_in : float
        Class setting: proxsuite's first proximal weight on the inequality rows.
    preconditioner_iterations : int
        Class setting: iterations of proxsuite's Ruiz equilibration at each QP's init.
    iterations : int
        proxsuite iterations spent by the last :meth:`solve`, an abandoned warm
        start included.
    solved : bool
        Whether the last :meth:`solve` reached its accuracy (not its iteration
        limit, nor rows it found incompatible).
    multipliers : (m + n,) float
        proxsuite's multipliers of the last answer: the rows of ``inequality``,
        then the box bounds; positive where an upper bound holds, negative
        where a lower one does (``H x + g + C^T z = 0``).
    """

    # proxsuite's automatic choice factorises the primal system H + C^T C / mu
    # when rows outnumber variables (the soft stances' QPs: 47 variables,
    # 173-356 rows), and there needed 2-5 times more iterations than the
    # primal-dual system, which it uses on the rigid stances' QPs anyway.
    backend = "PrimalDualLDLT"  # a proxsuite.proxqp.dense.DenseBackend name
    # A cold start begins at x = 0, the current iterate. proxsuite's default
    # guess minimises the objective under the (absent) equalities alone: along
    # the elastic variable and the base directions the curvature is the 1e-8
    # regularisation against a gradient of up to the penalty, so that guess
    # lies some 1e10 away (measured: the first QP of hand-on-table takes 108
    # iterations from it, 45 from zero).
    cold_guess = "NO_INITIAL_GUESS"  # a proxsuite.proxqp.InitialGuess name
    # Warm starts (proxsuite's WARM_START_WITH_PREVIOUS_RESULT, with the proximal
    # weights the previous solve ended with) were the policy until the first
    # proximal weight was lowered; on the QPs above they saved nothing over cold
    # starts (3,612 iterations against 3,514 at 0.1). Kept as an option, for
    # comparison (bench/qp_subproblems.py).
    warm_start = False
    first_proximal_in = _FIRST_PROXIMAL_IN
    preconditioner_iterations = _PRECONDITIONER_ITERATIONS

    def __init__(self):
        self.qp = None
        self.shape = None
        self._cold = {}  # shape -> the proxsuite object cold starts of that shape reuse
        self.iterations = 0
        self.solved = False
        self.multipliers = np.zeros(0)

    def _fresh(self, shape):
        dense = proxsuite.proxqp.dense
        backend = getattr(dense.DenseBackend, self.backend)
        qp = dense.QP(shape[0], 0, shape[1], True, dense.HessianType.Dense, backend)
        # The SQP corrects an inexact step at the next iteration, so a moderate
        # absolute accuracy suffices; the elastic QP is feasible by
        # construction, so proxsuite's infeasibility test is made strict (its
        # default fires falsely on our badly scaled first iterations).
        qp.settings.eps_abs = 1e-9
        qp.settings.eps_rel = 0.0
        qp.settings.eps_primal_inf = 1e-12
        # Bounded work per QP: an unlucky QP must not stall a search loop
        # (its step is still used; the line search judges it).
        qp.settings.max_iter = _QP_ITERATIONS
        qp.settings.max_iter_in = 50
        qp.settings.verbose = False
        qp.settings.initial_guess = getattr(proxsuite.proxqp.InitialGuess, self.cold_guess)
        qp.settings.default_mu_in = self.first_proximal_in
        qp.settings.preconditioner_max_iter = self.preconditioner_iterations
        return qp

    def solve(self, hessian, gradient, inequality, lower, upper, box_lower, box_upper, accuracy=1e-6,
              max_iterations=_QP_ITERATIONS, start=None):
        """Solve the QP ``min 1/2 x^T H x + g^T x, lower <= C x <= upper, box_lower <= x <= box_upper``.

        From a cold start (x = 0, or ``start``); with :attr:`warm_start`, from the
        previous answer when the previous QP had the same shape and cold when it did
        not, or when the warm start does not finish. :attr:`solved` says whether
        proxsuite reached its accuracy.

        Parameters
        ----------
        hessian : (n, n) float
        gradient : (n,) float
        inequality : (m, n) float
        lower, upper : (m,) float, +-1e20 where a row has no bound
        box_lower, box_upper : (n,) float, +-1e20 where a variable has no bound
        accuracy : float
            proxsuite's absolute accuracy (``eps_abs``) on the KKT residuals.
        max_iterations : int
            proxsuite's iteration limit.
        start : (n,) float, optional
            The primal point a cold start begins at (its multipliers at zero), e.g.
            :func:`elastic_start`; None: x = 0.

        Returns
        -------
        x : (n,) float
            The answer, or proxsuite's last iterate when it hit its iteration limit
            or found the rows incompatible.
        """
        shape = (len(gradient), inequality.shape[0])
        data = (hessian, gradient, None, None, inequality, lower, upper, box_lower, box_upper)
        self.iterations = 0
        if self.warm_start and self.qp is not None and self.shape == shape:
            # A warm start usually finishes in a few iterations; when it does
            # not, it tends to crawl (measured: 7,000 iterations, 350 ms) where
            # a cold start takes a few milliseconds. Hence the short budget.
            settings = self.qp.settings
            settings.eps_abs = accuracy
            settings.max_iter = _WARM_QP_ITERATIONS
            settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            # With the proximal weights the previous solve ended with: resetting
            # them to proxsuite's first ones cut this QP's iterations by a quarter
            # offline, but changed the SQP's path on cross-soft-block from 1 to 5
            # iterations (measured), so they are kept.
            self.qp.update(*data)
            self.qp.solve()
            self.iterations += self.qp.results.info.iter
            if self.qp.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED:
                return self._answer()
        # First solve, a change of size, or a warm start that did not finish. A cold
        # start reuses the proxsuite object made for a QP of this shape (init sets it up
        # afresh: the same answers bit for bit, on the 433 QPs of the 60 random rigid
        # stances, for 6 % less of their time than a new object each).
        qp = self._cold.get(shape)
        if qp is None:
            if len(self._cold) >= _COLD_SHAPES:
                self._cold.clear()
            qp = self._cold[shape] = self._fresh(shape)
        qp.settings.initial_guess = getattr(proxsuite.proxqp.InitialGuess, self.cold_guess)
        qp.settings.eps_abs = accuracy
        qp.settings.max_iter = max_iterations
        self.qp, self.shape = qp, shape
        self.qp.init(*data)
        if start is None:
            self.qp.solve()
        else:
            self.qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START
            self.qp.solve(np.asarray(start, dtype=float), None, None)
        self.iterations += self.qp.results.info.iter
        return self._answer()

    def _answer(self) -> np.ndarray:
        self.solved = self.qp.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
        self.multipliers = np.array(self.qp.results.z)
        return np.array(self.qp.results.x)


def elastic_qp(linearization, penalty, hold=True):
    """Elastic QP data from a linearisation (the QP of :mod:`stances.sqp`).

    A row's bound that the iterate violates is relaxed by the elastic variable
    (``value + J x <= upper + t s``, one QP row each); a row the iterate meets on
    both sides (lower <= value <= upper, a torque or joint-velocity row inside its
    limits) is one QP row, ``lower <= value + J x <= upper``, not relaxed: ``x = 0``
    still meets it, so the QP stays feasible, and its step may not buy another row's
    violation with a new one here. Each such row, half the rows of a rigid stance's
    QP (torque limits), would otherwise be two. ``hold=False`` relaxes every row (the
    conflict QP of an infeasible answer's reason, which names the rows sharing the
    elastic variable, a torque at its limit among them).
    """
    jacobian, lower_gap, upper_gap, scale, upper, lower, held = _qp_rows(linearization, hold)
    n = len(linearization.gradient)
    hessian = np.zeros((n + 1, n + 1))
    # A small regularisation keeps the QP strictly convex in directions the
    # objective ignores (base translation, unconstrained lambdas).
    hessian[:n, :n] = linearization.hessian + 1e-8 * np.eye(n)
    hessian[n, n] = 1e-8
    gradient = np.append(linearization.gradient, penalty)
    scale_down = objective_scale(penalty)
    hessian /= scale_down
    gradient /= scale_down
    upper_rows = np.hstack([jacobian[upper], -np.ones((upper.sum(), 1))])
    lower_rows = np.hstack([jacobian[lower], np.ones((lower.sum(), 1))])
    held_rows = np.hstack([jacobian[held], np.zeros((held.sum(), 1))])
    inequality = np.vstack([upper_rows, lower_rows, held_rows])
    qp_lower = np.concatenate([np.full(upper.sum(), -_INFINITY), lower_gap[lower], lower_gap[held]])
    qp_upper = np.concatenate([upper_gap[upper], np.full(lower.sum(), _INFINITY), upper_gap[held]])
    box_lower = np.append(np.maximum(linearization.step_lower, -_INFINITY), 0.0)
    box_upper = np.append(np.minimum(linearization.step_upper, _INFINITY), _INFINITY)
    return hessian, gradient, inequality, qp_lower, qp_upper, box_lower, box_upper


def elastic_start(qp_data) -> np.ndarray:
    """A feasible point of an :func:`elastic_qp`: no step (``x = 0``, which meets its
    held rows and step bounds), the elastic variable at the largest violation it relaxes.

    proxsuite started there rather than at ``x = 0`` (where every violated row is
    violated in the QP too) took 2,380 iterations against 2,755 on the 84 elastic QPs
    of the 60 random rigid bench stances (21 % less time), 2,560 against 2,787 on the
    55 of the 15 built-in soft stances, the objectives equal to proxsuite's accuracy.

    Parameters
    ----------
    qp_data : tuple
        What :func:`elastic_qp` returns.

    Returns
    -------
    (n + 1,) float
    """
    _, gradient, inequality, lower, upper, _, _ = qp_data
    start = np.zeros(len(gradient))
    elastic = inequality[:, -1]
    # Upper rows read J x - t <= upper, lower rows J x + t >= lower (held rows: t absent).
    needed = np.concatenate([-upper[elastic < 0.0], lower[elastic > 0.0], [0.0]])
    start[-1] = needed.max()
    return start


def plain_qp(linearization):
    """QP data of the step that meets every linearised row: ``min 1/2 x^T H x + g^T x``,
    ``lower <= value + J x <= upper`` for every row (one QP row each, an equality's
    bounds equal), within the step bounds; no elastic variable.

    Where the linearised rows are compatible, the elastic QP's answer has its elastic
    variable at zero and is this QP's (an exact penalty), but the elastic QP has two
    rows per violated equality and a variable that proxsuite weighs at 1e-8 against the
    penalty: on the 389 QPs of the 60 random rigid stances whose elastic variable came
    out zero, this QP took 3,061 proxsuite iterations against 3,905, 12 % less time, the
    configuration steps equal within 1.2e-3 (proxsuite's accuracy). Where the rows are
    not compatible it has no answer (:attr:`QPWorkspace.solved` False): the SQP then
    solves the elastic QP. Its multipliers are the rows', in the stacked order
    (:func:`row_multipliers` with ``plain``). Returns the arguments of
    :meth:`QPWorkspace.solve`.
    """
    jacobian, lower_gap, upper_gap, *_ = _qp_rows(linearization, hold=False)
    n = len(linearization.gradient)
    hessian = linearization.hessian + 1e-8 * np.eye(n)  # as elastic_qp regularises it
    lower = np.where(np.isfinite(lower_gap), lower_gap, -_INFINITY)
    upper = np.where(np.isfinite(upper_gap), upper_gap, _INFINITY)
    box_lower = np.maximum(linearization.step_lower, -_INFINITY)
    box_upper = np.minimum(linearization.step_upper, _INFINITY)
    return hessian, linearization.gradient.copy(), jacobian, lower, upper, box_lower, box_upper


def _qp_rows(linearization, hold=True):
    """The stacked rows divided by their scale, the gaps to their bounds, and which
    rows give the QP's relaxed upper rows, relaxed lower rows and held two-sided rows
    (boolean masks over the rows, in that QP order; none held unless ``hold``)."""
    value, jacobian, lower, upper, scale, _ = stack(linearization.blocks)
    # Rows are divided by their scale: every row then reads in "violations
    # that matter", the elastic variable enters with coefficient one, and
    # rows in newtons no longer dwarf rows in metres (proxsuite stalls on that).
    if jacobian is None:
        jacobian = np.zeros((0, len(linearization.gradient)))
    lower_gap = (lower - value) / scale
    upper_gap = (upper - value) / scale
    has_lower, has_upper = np.isfinite(lower_gap), np.isfinite(upper_gap)
    held = has_lower & has_upper & (lower_gap <= 0.0) & (upper_gap >= 0.0) & (lower_gap < upper_gap) & hold
    return jacobian / scale[:, None], lower_gap, upper_gap, scale, has_upper & ~held, has_lower & ~held, held


def row_multipliers(linearization, multipliers, penalty=_PENALTY_REFERENCE, plain=False, hold=True) -> dict:
    """The multiplier of each constraint row of a linearisation, from its QP's answer.

    Parameters
    ----------
    linearization : Linearization
        What :func:`elastic_qp` (or :func:`plain_qp`) was given.
    multipliers : (rows + n + 1,) float
        :attr:`QPWorkspace.multipliers` after solving that QP.
    penalty : float
        The elastic penalty of that QP (its objective was divided by
        :func:`objective_scale` of it).
    plain : bool
        The QP was :func:`plain_qp`'s (``penalty`` is then not read).
    hold : bool
        As given to :func:`elastic_qp`.

    Returns
    -------
    dict
        Row label -> multiplier ``y``, in objective units per row unit: the
        QP's stationarity reads ``grad f + sum_i y_i grad c_i = 0`` (with the
        bounds' terms), so ``y_i > 0`` where an upper bound holds and ``< 0``
        where a lower one does; an equality's two QP rows add up.
    """
    labels = [label for block in linearization.blocks if len(block) for label in block.labels]
    return dict(zip(labels, stacked_row_multipliers(linearization, multipliers, penalty, plain, hold)))


def stacked_row_multipliers(linearization, multipliers, penalty=_PENALTY_REFERENCE, plain=False, hold=True) -> np.ndarray:
    """:func:`row_multipliers` as an array over the stacked rows (labels need not be unique)."""
    _, _, _, scale, upper, lower, held = _qp_rows(linearization, hold)
    if plain:
        rows = np.array(multipliers[: len(scale)], dtype=float)  # one QP row a row, in order
    else:
        uppers, lowers = int(upper.sum()), int(lower.sum())
        rows = np.zeros(len(scale))
        rows[upper] += multipliers[:uppers]
        rows[lower] += multipliers[uppers : uppers + lowers]
        rows[held] += multipliers[uppers + lowers : uppers + lowers + int(held.sum())]
        rows *= objective_scale(penalty)  # the QP's objective was divided by it
    # proxsuite leaves specks (1e-70 to 1e-9) on inactive rows; a row that
    # weighs nothing should cost nothing downstream.
    rows[np.abs(rows) < _INACTIVE_MULTIPLIER] = 0.0
    # The QP's rows are c_i / s_i: their multiplier is y_i s_i.
    return rows / scale


__all__ = ["QPWorkspace", "elastic_qp", "elastic_start", "objective_scale", "plain_qp", "row_multipliers",
           "stacked_row_multipliers"]
