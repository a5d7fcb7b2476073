"""SQP for the posture problem, one proxsuite QP per iteration.

Each iteration linearises the problem (:mod:`stances.problem`), solves

    min_x  1/2 x^T H x + g^T x + rho t
    s.t.   lower - t s <= value + J x <= upper + t s     (every constraint row)
           step bounds on x,  t >= 0

for the step ``x = (dq, dlambda)`` and one elastic variable ``t`` (``H``: the
objective's Gauss-Newton Hessian, plus the constraints' curvature near a solution,
see :func:`_with_curvature`): the QP is always feasible, and ``t > 0`` says by how much (in units of each row's scale
``s``) the linearised constraints cannot be met. A backtracking line search on
the exact-penalty merit ``f + rho * max violation`` makes the iteration
globally convergent; ``rho`` grows when the QP prefers to stay infeasible.

A stance is declared infeasible, with the label of the worst constraint, when
the iterates stop moving while still violating constraints, when far from
feasible the line search keeps cutting the steps without the violation
falling, when the violation falls too slowly to reach the tolerance, or when
the iteration limit is reached (:mod:`stances.stopping` holds these rules and those
that end a feasible solve). Feasible answers are re-checked by :func:`stances.verify`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from fem.dense import single_threaded_blas
from fem.errors import ContactStateError

from .cold_start import initial_configuration, reaching_configuration, starting_configuration
from .curvature import ConstraintCurvature, bounded_below
from .qp import QPWorkspace, elastic_qp, elastic_start, plain_qp, row_multipliers, stacked_row_multipliers
from .results import LazyDeformations, PointForce, PostureResult, Verification
from .statics import points_in_world
from .stopping import (
    CRAWL_ALPHA, CREEPING, LINGERING, MINOR_GAIN, NEARLY_FEASIBLE, NO_PROGRESS, PREDICTED_GAIN, STALLED,
    StoppingTest,
    at_rounding_floor, better,
)
from .verify import verify_problem

logger = logging.getLogger(__name__)

_MAX_PENALTY = 1e8
_RESTORATION_PENALTY = 1e6
_SHORTEST_STEP = 1e-3  # the line search's shortest trial, a fraction of the QP's step
_TRUST_REGION_HELD = 0.999  # a step this close to the trust region's bound was held by it
# Scaled violation (1 mm, 1 N) below which torque usage enters the objective. Far from
# feasible it steers steps into poor basins (the soles of step-on-cube crossed). At 1
# (1 cm, 10 N) the 60 random rigid bench stances took 373 iterations instead of 387, but
# the suite's climb-with-soft-support plans 29-30 s of CPU instead of 21-22 s (10 seeds,
# about the same iterations, the longest solve 1.1-1.3 s instead of 0.56 s).
_USAGE_PHASE = 0.1
# Scaled violation below which a full step that the merit refuses for the violation it
# adds gets a second-order correction (see _line_search); up to _USAGE_PHASE, one whose
# violation at least doubles (_CORRECTION_GROWTH) gets it too.
_CORRECTION_PHASE = 1e-2
_CORRECTION_GROWTH = 2.0
# A QP whose elastic value (its shortfall on the linearised rows) is at most this fraction of
# the last step's, its step held by the trust region, leaves the penalty as it is, even when
# the line search cut the step: the rows lie beyond the region's reach rather than being
# incompatible, and each iteration brings them closer. Raised tenfold at each such step
# instead, turn's stance turning the right sole 45 degrees (from the posture on the left sole
# alone) took 17 Coulomb iterations instead of 9 and 18 in its rigid warm start instead of 15;
# over 10 seeds of quadruped-foam, quadruped-walk, climb-with-soft-support and turn, 5,316
# linearisations instead of 5,108 (2,837 trial evaluations instead of 2,761). A shortfall that
# stalls (an infeasible stance's hovered at 0.035-0.039 for 80 iterations) raises it as
# before, and the solve stops as early.
_ELASTIC_PROGRESS = 0.9
# A step cut below CRAWL_ALPHA from a feasible iterate says the QP's model holds over a
# small part of it only (rows curved at that scale): the next steps are bounded by this
# fraction of its length (rad or m, at least _SMALLEST_REGION), the bound doubling back
# after each full step. With the whole trust region each QP went back to the same far
# point and the line search crawled: turn's Coulomb stage stopped 'converged' at 3 % above
# the objective it reaches with the bound (1.462 against 1.414, 18 and 17 iterations), a
# point on a sphere 17 % above its optimum (see the toy tests).
_CRAWL_REGION = 0.1
_SMALLEST_REGION = 0.01
OUT_OF_TIME = "time budget spent"  # the SQP status when a deadline stops it
QP_FAILED = "the QP solver returned no finite step"
# proxsuite's iteration limit for a QP without the elastic variable: a compatible one
# took at most 35 on the 60 random rigid stances (341 QPs); one whose rows are not compatible
# gives up here and is solved as the elastic QP.
_PLAIN_QP_ITERATIONS = 100
_CONFLICT_FLOOR = 1e-6  # elastic value (scaled) below which the linearised rows are compatible
_CONFLICT_ROWS = 4  # rows named in an infeasible answer's conflict clause
_CONFLICT_PENALTY = 1e4  # largest elastic penalty of the conflict QP
_CONFLICT_SHARE = 1e-3  # share of that penalty a row's multiplier takes to be named in the conflict
_TIED = 0.9  # rows violated within this share of the worst: the reason names the conflict's among them
# The constraints' curvature (PostureOptions.constraint_curvature), see _with_curvature:
_CURVATURE_PHASE = 0.1  # scaled violation below which it may enter the QP (from the start: no fewer iterations)
_SLOW_CONTRACTION = 0.4  # step length ratio of Gauss-Newton beyond which it is switched on
_FLOOR = 0.25  # fraction of the Gauss-Newton curvature the Lagrangian's may not go below
_AUGMENTATION = 1e-2  # sigma, objective units per squared scaled row


# An infeasible answer whose worst row is a soft print's elastic placement, held back by a
# soft body's own rows (these, among the rows no step meets together, and no collision), starts
# with this.
SOFT_SUPPORT_GIVES = "soft support cannot hold the print: "
SOFT_SUPPORT_ROWS = ("strain bound", "mesh overlap", "indentation")


def _unit(label: str) -> str:
    if label.startswith(("placement", "path")):
        return "m or rad"
    if label.startswith("static equilibrium"):
        return "N or N m"
    if label.startswith(("torque", "centre of pressure")):
        return "N m"
    if (label.startswith(("collision", "mesh overlap")) or "indentation" in label or "lifted off" in label
            or "pivoting on an edge" in label):
        return "m"
    if label.startswith("strain"):
        return "(strain)"
    if label.startswith("tilt of the face"):
        return "rad"
    return "N"


def _reason(linearization, iterations, why, conflict=()) -> str:
    """The row an infeasible answer names: its worst violated row, or, of the rows within
    _TIED of it (the elastic QP leaves many rows violated alike), the first of ``conflict``
    (:func:`_conflict`'s rows, strongest first), with its violation."""
    worst, label = linearization.max_violation()
    scale = 1.0
    near = {}
    for block in linearization.blocks:
        for i in np.flatnonzero(block.violation() >= _TIED * worst).tolist():
            near.setdefault(block.labels[i], (float(block.violation()[i]), float(block.scale[i])))
    chosen = next((row for row in conflict if row in near), None)
    if chosen is not None:
        label, (worst, scale) = chosen, near[chosen]
    else:
        for block in linearization.blocks:
            if label in block.labels:
                scale = float(block.scale[block.labels.index(label)])
    amount = worst * scale
    prefix = ""
    if label.startswith("placement"):
        # A soft print's sinking held back by a soft body's own rows (its strain, its mesh
        # reaching into the link) is no matter of reach: the soft support cannot carry it
        # there (a sole on a 1.2e4 Pa mat beside a firmer one, an audit's fuzz: it read
        # "unreachable"). A collision among them stands in the way first (cbm.rejections).
        held_back = (label.endswith(", elastic)") and any(row.startswith(SOFT_SUPPORT_ROWS) for row in conflict)
                     and not any(row.startswith("collision") for row in conflict))
        prefix = SOFT_SUPPORT_GIVES if held_back else "print unreachable: "
    return f"{prefix}{label} violated by {amount:.3g} {_unit(label)} ({why} after {iterations} iterations)"


def _conflict(linearization, penalty) -> tuple:
    """The rows no step can meet together, as a clause for an infeasible answer's reason.

    The worst violated row at the last iterate depends on the path the SQP
    took; the rows that hold the elastic QP away from zero are the stance's
    conflict itself (e.g. an indentation bound against the depth equilibrium
    needs). One more QP at the last iterate finds them: the rows whose
    linearised violation equals the elastic variable.
    """
    # At the loop's largest penalties (1e8) proxsuite stops at its iteration
    # limit with the elastic variable near zero (measured on two contradicting
    # rows: 4e-14 instead of 0.5); any penalty that makes the QP prefer
    # feasibility names the same rows, so it is capped where proxsuite is sure.
    # Every row relaxed (none held at its bound): a torque at its limit is part of the
    # conflict it takes part in.
    weight = min(penalty, _CONFLICT_PENALTY)
    workspace = QPWorkspace()
    x = workspace.solve(*elastic_qp(linearization, weight, hold=False))
    step, elastic = x[:-1], max(float(x[-1]), 0.0)
    if elastic <= _CONFLICT_FLOOR:
        return ()
    # Each row's multiplier on its scaled row: the rows that hold the elastic variable up share
    # the penalty; a row the objective merely moved to the bound (the elastic QP spreads the
    # violation over every row it may) weighs little. Without a solved QP, by excess alone.
    multipliers = (stacked_row_multipliers(linearization, workspace.multipliers, weight, hold=False)
                   if workspace.solved else None)
    rows, first = [], 0
    for block in linearization.blocks:
        if len(block):
            moved = block.value + block.jacobian @ step
            excess = (np.maximum(block.lower - moved, 0.0) + np.maximum(moved - block.upper, 0.0)) / block.scale
            weights = (np.zeros(len(block)) if multipliers is None
                       else np.abs(multipliers[first: first + len(block)]) * block.scale)
            rows.extend((weights[i], excess[i], block.labels[i]) for i in np.flatnonzero(excess >= 0.99 * elastic))
            first += len(block)
    if multipliers is not None and any(w >= _CONFLICT_SHARE * weight for w, *_ in rows):
        rows = [row for row in rows if row[0] >= _CONFLICT_SHARE * weight]  # the conflict, not bystanders
    if not rows:
        return ()  # only the step bounds (trust region, joint limits) keep it short
    return tuple(label for *_, label in sorted(rows, key=lambda row: (-row[0], -row[1]))[:_CONFLICT_ROWS])


def _conflict_clause(conflict) -> str:
    """The reason's clause naming :func:`_conflict`'s rows ("" without)."""
    return f"; no step meets together: {', '.join(conflict)}" if conflict else ""


# Rounds of strain rows added where verify found the strain over its bound (_solve_problem).
_STRAIN_ROUNDS = 2


def solve_problem(problem, q_init=None, lam_init=None, max_iterations=None, deadline=None, check=True,
                  creep=False) -> PostureResult:
    """Run the SQP on a built :class:`~stances.problem.PostureProblem` (one BLAS thread).

    See :func:`_solve_problem`. Given no posture nor contact variables, and no print on a
    soft body's mesh (``options.reaching_start``), it starts from the reference posture
    over the prints brought onto them (:func:`stances.reaching_configuration`); if that
    answer is infeasible (and time is left), it solves again from the reference posture
    over the prints (:func:`stances.initial_configuration`), the first attempt's iterations
    and reason kept in the answer's statistics (``first_start``; the answer's
    ``iterations`` are its own attempt's).
    """
    with single_threaded_blas():
        if q_init is not None or lam_init is not None or not _reaches(problem):
            return _solve_problem(problem, q_init, lam_init, max_iterations, deadline, check, creep)
        over_prints = initial_configuration(problem.robot, problem.scene, problem.stance)
        reached = reaching_configuration(problem.robot, problem.scene, problem.stance, over_prints)
        if np.array_equal(reached, over_prints):
            return _solve_problem(problem, over_prints, None, max_iterations, deadline, check, creep)
        first = _solve_problem(problem, reached, None, max_iterations, deadline, check, creep)
        out_of_time = deadline is not None and time.perf_counter() >= deadline
        if first.feasible or first.statistics.get("status") == OUT_OF_TIME or out_of_time:
            return first
        second = _solve_problem(problem, over_prints, None, max_iterations, deadline, check, creep)
        statistics = dict(second.statistics, first_start={"iterations": first.iterations, "reason": first.reason})
        return replace(second, statistics=statistics, solve_time=first.solve_time + second.solve_time)


def _reaches(problem) -> bool:
    """Whether a solve of ``problem`` given no posture starts from the reaching start.

    Not where a print lies on a soft body's mesh: such a solve starts from its rigid
    warm start's answer, and from the reaching start the palms' warm starts took longer
    (hand-on-cube 8 -> 12 iterations, its solve 1.6 times the CPU; the 15 built-in soft
    stances' median 1.06 times); :func:`stances.stages.solve` starts their warm starts from the posture
    over the prints.
    """
    return problem.options.reaching_start and not any(c.kind == "deformable" for c in problem.contacts)


def _solve_problem(problem, q_init=None, lam_init=None, max_iterations=None, deadline=None, check=True,
                   creep=False) -> PostureResult:
    """Run the SQP on a built :class:`~stances.problem.PostureProblem`.

    Parameters
    ----------
    problem : PostureProblem
    q_init : (nq,) float, optional
        Warm start; by default the robot's reference posture moved over the
        stance's prints (:func:`stances.initial_configuration`).
    lam_init : (m,) float, optional
        Initial force variables.
    max_iterations : int, optional
        Lowers the options' iteration limit.
    deadline : float, optional
        ``time.perf_counter()`` value after which no new iteration starts; the
        iterate reached is still checked, so a feasible one is kept.
    check : bool, optional
        Run :func:`stances.verify` on a feasible answer and compute the soft
        bodies' displacement fields (default). A warm start, whose answer is
        only a starting posture, skips both: on a soft body they load the full
        FEM model and cost 10-30 ms.
    creep : bool, optional
        End the SQP far from feasible once its steps keep being cut without the
        violation halving (:meth:`~stances.stopping.StoppingTest.creeping`): for a
        stage that has a fallback.

    Returns
    -------
    PostureResult
        Feasible or not; never raises for an infeasible stance.
    """
    start = time.perf_counter()
    options = problem.options
    q = starting_configuration(problem, q_init)
    lam = (
        problem.initial_variables(q)
        if lam_init is None
        else np.maximum(np.asarray(lam_init, float), problem.variable_lower)
    )
    limit = options.max_iterations if max_iterations is None else min(max_iterations, options.max_iterations)
    outcome = run_sqp(problem, q, lam, limit, deadline, creep)
    result = posture_result(problem, outcome, time.perf_counter() - start, check)
    iterations = outcome.iterations
    soft = [contact for contact in problem.contacts if contact.deformable_object is not None]
    for _ in range(_STRAIN_ROUNDS):
        # verify found a strain over its bound where the strain rows do not look (far
        # from the prints): they look there from now on, and the SQP goes on.
        if result.feasible or not outcome.feasible or not any([contact.take_strain_outlier() for contact in soft]):
            break
        outcome = run_sqp(problem, outcome.q, outcome.lam, limit, deadline, creep)
        iterations += outcome.iterations
        result = replace(posture_result(problem, outcome, time.perf_counter() - start, check), iterations=iterations)
    return result


@dataclass(frozen=True)
class SqpOutcome:
    """Where the SQP iterations stopped, before the robot's own checks.

    Attributes
    ----------
    q : (nq,) float
        Last accepted configuration.
    lam : (m,) float
        Last accepted force variables.
    linearization : Linearization
        The problem linearised at ``(q, lam)``.
    iterations : int
        SQP iterations run.
    status : str
        "converged", "stalled", "stagnated", "iteration limit", "converging too
        slowly: ...", the no-progress status (a far-from-feasible line search
        crawling), the lingering status (a nearly feasible one hovering,
        :data:`stances.stopping.LINGERING`), the creeping status (with ``creep``: far
        from feasible, steps cut again and again, :data:`stances.stopping.CREEPING`),
        the QP-failure status, or the time-budget status.
    penalty : float
        Final weight of the elastic variable (of the merit's violation).
    qp_time : float
        Seconds spent in the QP solver.
    feasible : bool
        Whether every row is within the feasibility tolerance (scaled) or its
        block's own ``accuracy`` (:meth:`Linearization.met`).
    reason : str
        Empty when feasible; otherwise the worst row, by how much, why the
        iterations stopped, and the rows no step can meet together.
    curved_iterations : int
        Iterations whose QP had the constraints' curvature in its Hessian.
    corrections : int
        Full steps taken with a second-order correction (see :func:`_line_search`).
    """

    q: np.ndarray
    lam: np.ndarray
    linearization: object
    iterations: int
    status: str
    penalty: float
    qp_time: float
    feasible: bool
    reason: str
    curved_iterations: int = 0
    corrections: int = 0


def run_sqp(problem, q, lam, limit, deadline=None, creep=False) -> SqpOutcome:
    """The SQP iterations from ``(q, lam)``, on any problem that linearises like
    :class:`~stances.problem.PostureProblem`.

    What the iterations read of ``problem``: ``options`` (a
    :class:`~stances.problem.PostureOptions`: tolerances, elastic penalty,
    torque weight), ``variable_lower`` (m,), ``robot.model`` (a pinocchio
    model: the tangent size ``nv`` and ``pin.integrate`` for configuration
    steps), ``linearize(q, lam, torque_weight)`` returning a
    :class:`~stances.problem.Linearization` and ``evaluate(q, lam,
    torque_weight)`` returning the same values without Jacobians (an object
    with ``objective`` and ``max_violation()``, e.g. a
    :class:`~stances.problem.Evaluation`), for the line search's trials, and, if it
    has one, ``reweighted(linearization, torque_weight)``: the same linearisation at
    another torque weight (else ``linearize`` runs again). Nothing here knows contacts or
    torques, so the loop can be checked on a toy problem with a known optimum.

    Parameters
    ----------
    problem : PostureProblem or a problem with the attributes above
    q : (nq,) float
        Start configuration (already validated).
    lam : (m,) float
        Start force variables, at or above ``problem.variable_lower``.
    limit : int
        Iteration limit.
    deadline : float, optional
        ``time.perf_counter()`` value after which no new iteration starts.
    creep : bool, optional
        Whether a creep far from feasibility ends it (:meth:`StoppingTest.creeping`).

    Returns
    -------
    SqpOutcome
    """
    options = problem.options
    nv = problem.robot.model.nv
    penalty = options.elastic_penalty
    workspace = QPWorkspace()
    restoration = QPWorkspace()
    tolerance = options.feasibility_tolerance
    stops = StoppingTest(tolerance, options.optimality_tolerance, limit, creep)
    status = "iteration limit"
    # Far from feasible the torque-usage term steers steps into poor basins (the
    # soles of step-on-cube crossed); it joins the objective once the
    # iterate is near feasible, and stays.
    torque_weight = 0.0
    linearization = problem.linearize(q, lam, torque_weight)
    iteration = 0
    qp_time = 0.0
    curvature = None  # a ConstraintCurvature, made on first use
    last_qp = None  # (linearization, proxsuite multipliers, penalty, plain) of the last QP, for the curvature's weights
    compatible = False  # whether the last QP met its linearised rows (its elastic variable at zero)
    # Where Gauss-Newton converges fast (most stances: stand, foot-on-block) the
    # curvature costs more (1-3 ms a Hessian) than it saves; it is switched on,
    # for good, once two full steps in the local phase shrink by less than
    # _SLOW_CONTRACTION.
    slow = False
    curved_iterations = 0
    corrections = 0
    local_steps = []  # lengths of full steps in the local phase
    region = options.trust_region  # the configuration step's bound (see _CRAWL_REGION)
    last_elastic = None  # the elastic value of the last step taken (see _ELASTIC_PROGRESS)
    for iteration in range(1, limit + 1):
        if deadline is not None and time.perf_counter() > deadline:
            status, iteration = OUT_OF_TIME, iteration - 1
            break
        violation, _ = linearization.max_violation()
        if torque_weight != options.torque_weight and violation <= _USAGE_PHASE:
            torque_weight = options.torque_weight
            # Only the objective changes: summed again where the problem can (what
            # linearising again gives with the same contact modes).
            reweighted = getattr(problem, "reweighted", None)
            linearization = (problem.linearize(q, lam, torque_weight) if reweighted is None
                             else reweighted(linearization, torque_weight))
            # The usage term moves the loads: the last QP's multipliers are
            # those of another problem (measured: a step of 0.15 rad off).
            last_qp = None
            stops.forget_objectives()
        # The QP's model: the objective's Hessian, plus the constraints'
        # curvature once the multipliers of a previous QP are known (and
        # Gauss-Newton was seen to crawl).
        curved = model = linearization
        configuration = None
        if slow and last_qp is not None and violation <= _CURVATURE_PHASE:
            curvature = curvature or ConstraintCurvature(problem.robot.model)
            configuration = (curvature, q)
            curved_iterations += 1
        if last_qp is not None and (configuration is not None
                                    or any(block.variable_curvature is not None for block in linearization.blocks)):
            curved, model = _with_curvature(linearization, row_multipliers(*last_qp), configuration,
                                            near_feasible=violation <= _CURVATURE_PHASE)
        tic = time.perf_counter()
        # Solve the QP a hundred times more accurately than the current
        # violation (and no looser than 1e-6): loose steps far from the
        # solution are cheap, and near it the outer loop keeps converging fast.
        accuracy = float(np.clip(0.01 * violation, 1e-9, 1e-6))
        # Once a QP has met its linearised rows, the next is first solved without the
        # elastic variable (stances.qp.plain_qp: 12 % less proxsuite time); if its rows
        # are not compatible, as the elastic QP.
        bounded_qp = _within(curved, region, nv)
        x, plain = _solve_step_qp(workspace, bounded_qp, penalty, accuracy, plain_first=compatible)
        qp_time += time.perf_counter() - tic
        if not np.all(np.isfinite(x)):
            # proxsuite can diverge at the largest penalties (measured: NaN at a
            # penalty of 1e8 on an infeasible quadruped stance, which then raised
            # in the next linearisation): no step to take, the iterate is the answer.
            status = QP_FAILED
            break
        step, elastic = x[:-1], max(x[-1], 0.0)
        compatible = elastic <= tolerance
        step_length = float(np.max(np.abs(step[:nv])))
        last_qp = (curved, workspace.multipliers, penalty, plain)
        predicted = _predicted_decrease(model, step, elastic, penalty, violation)
        if stops.converged_before_search(linearization, step_length, predicted):
            status = "converged"
            break
        # (see stopping.PREDICTED_GAIN and MINOR_GAIN)
        met = linearization.met(tolerance)  # the iterate's, read again by the lingering test below
        finished = None  # the finishing restoration, when tried (reused below)
        # Converged but for the violation its last step left: the shortest step onto the
        # rows finishes it (see stopping.FINISHING_VIOLATION). Not when the rows were not
        # compatible, nor when a bound held the step: 1/2 s^T H s leaves out what the
        # bounds' multipliers take (a step held by the trust region along a direction of
        # little curvature gains far more than it reads).
        if (torque_weight == options.torque_weight and compatible and not _held_by_bounds(bounded_qp, step, accuracy)
                and stops.finishing(met, violation, _optimality_gain(model, step), linearization.objective,
                                   iteration)):
            finished = _restoration(problem, linearization, q, lam, restoration, torque_weight)
            if finished is not None and finished[2].met(tolerance):
                q, lam, linearization = better(stops.best, finished)
                status = "converged"
                break
        marginal = met and predicted <= PREDICTED_GAIN * (1.0 + abs(linearization.objective))
        minor = violation <= NEARLY_FEASIBLE * tolerance and predicted <= MINOR_GAIN * (1.0 + abs(linearization.objective))
        # (A marginal step is only tried whole: no correction, which costs a QP and a
        # linearisation, for a gain the stop below would not wait for.)
        accepted, alpha, corrected = _line_search(
            problem, q, lam, step, linearization, violation, penalty, predicted, torque_weight,
            shortest=1.0 if marginal else CRAWL_ALPHA if minor else _SHORTEST_STEP,
            correction=None if marginal else restoration, region=region,
        )
        corrections += corrected
        if marginal and accepted is None:
            status = "converged"
            q, lam, linearization = better(stops.best, (q, lam, linearization))
            break
        searched = alpha if accepted is not None else 0.0  # the optimality step's own cut
        # Near a feasible point the optimality step may cross a kink (a print
        # node switching between stick, slip and lift-off) where the linear model
        # is wrong, and the line search crawls. A restoration step, the shortest
        # step to the linearised constraints, stays within the current piece and
        # brings feasibility back quadratically.
        if violation > tolerance and (accepted is None or alpha < 0.1):
            restored = finished if finished is not None else _restoration(
                problem, linearization, q, lam, restoration, torque_weight)
            # Taken when it does better on feasibility than the crawling step.
            needed = violation if accepted is None else min(violation, accepted[2].max_violation()[0])
            if restored is not None and restored[2].max_violation()[0] < needed:
                accepted, alpha = restored, 1.0
        if stops.lingering(violation, met, accepted is None or alpha < CRAWL_ALPHA or elastic > tolerance):
            if accepted is not None and accepted[2].max_violation()[0] < violation:
                q, lam, linearization = accepted
            status = LINGERING
            break
        if stops.hopeless(violation, accepted, alpha):
            if accepted is not None:
                q, lam, linearization = accepted
            status = NO_PROGRESS
            break
        if accepted is None:
            raised = not at_rounding_floor(violation, elastic, tolerance) and violation > tolerance and penalty < _MAX_PENALTY
            if raised:
                penalty *= 10.0
            if stops.stalled(violation, elastic, raised, slow and violation <= _CURVATURE_PHASE):
                status = STALLED
                if linearization.met(tolerance):
                    # A restoration can have landed above the best feasible objective.
                    q, lam, linearization = better(stops.best, (q, lam, linearization))
                break
            continue
        previous = linearization
        q, lam, linearization = accepted
        # The bound follows the optimality step's own cut (a restoration taken in its
        # place is no full step); the penalty rule below reads the bound the QP had.
        qp_region = region
        if searched < CRAWL_ALPHA and previous.met(tolerance):
            region = min(options.trust_region, max(_SMALLEST_REGION, _CRAWL_REGION * step_length))
        elif searched == 1.0:
            region = min(options.trust_region, 2.0 * region)
        if options.constraint_curvature and not slow and torque_weight == options.torque_weight:
            # Two full steps in a row: a damped one says the model is off, not slow.
            local_steps = local_steps[-1:] + [step_length] if alpha == 1.0 else []
            slow = len(local_steps) == 2 and local_steps[1] > _SLOW_CONTRACTION * local_steps[0]
        new_violation, worst_label = linearization.max_violation()
        logger.debug(
            "iteration %d: step %.3g (alpha %.3g%s), violation %.3g (%s), objective %.6g, elastic %.3g, penalty %.3g",
            iteration, step_length, alpha, ", corrected" if corrected else "", new_violation, worst_label,
            linearization.objective, elastic, penalty,
        )
        diverging = stops.diverging(iteration, new_violation, elastic, penalty)
        if diverging is not None:
            status = diverging
            break
        if stops.creeping(violation, new_violation, alpha):
            status = CREEPING
            break
        # The QP kept some violation although the merit could trade it: raise rho.
        # Not when the optimality step was taken whole (no cut, no restoration in its
        # place) and held by the trust region: the violation left is what no step that
        # short removes, whatever rho (hand-on-cube's rigid warm start, its palm 0.2 rad
        # from its print, raised rho to 1e4 on its way there, for the same iterates, and
        # its QPs took 60-165 proxsuite iterations instead of 7-80: 1,471 in the solve
        # against 918). A cut step says the model is off, and rho rises as before (an
        # infeasible quadruped stance, whose steps at the trust region were cut to
        # 1/8-1/2, relies on it to stop early), unless the QP's own shortfall is falling
        # (see _ELASTIC_PROGRESS).
        progressing = last_elastic is not None and elastic < _ELASTIC_PROGRESS * last_elastic
        bounded = (searched == 1.0 or progressing) and _held_by_trust_region(step_length, qp_region)
        if elastic > tolerance and new_violation > 0.5 * violation and penalty < _MAX_PENALTY and not bounded:
            penalty *= 10.0
        elif linearization.met(tolerance) and penalty > options.elastic_penalty:
            # Feasible: the penalty raised on the way (up to 1e7) now weighs a
            # violation below the tolerance a million times the objective, and
            # the line search cut every step whose curvature raised it a little
            # (the Maratos effect): 40 iterations at alpha 1/4 crawling along the
            # constraints (turn's rigid warm start). Back to the first penalty;
            # the rule above raises it again if feasibility is lost.
            penalty = options.elastic_penalty
        last_elastic = elastic
        answer = stops.converged(iteration, (q, lam, linearization), previous, violation, alpha, searched, step_length)
        if answer is not None:
            status = "converged"
            q, lam, linearization = answer
            break
    q, lam, linearization = stops.final((q, lam, linearization))
    feasible = linearization.met(tolerance)
    if feasible and status in (STALLED, LINGERING):
        status = "converged"  # feasible, and the merit cannot decrease further
    conflict = () if feasible else _conflict(linearization, penalty)
    reason = "" if feasible else _reason(linearization, iteration, status, conflict) + _conflict_clause(conflict)
    return SqpOutcome(q, lam, linearization, iteration, status, penalty, qp_time, feasible, reason, curved_iterations,
                      corrections)


def _held_by_trust_region(step_length, region) -> bool:
    """Whether a QP step whose largest configuration component is ``step_length`` (rad or
    m) was held by the trust region's bound ``region`` (rad or m)."""
    return step_length >= _TRUST_REGION_HELD * region


def _held_by_bounds(linearization, step, accuracy) -> bool:
    """Whether a bound of the QP ``linearization`` held some component of its answer ``step``
    that moved (by more than ``accuracy``, the QP's, rad, m or N)."""
    moved = np.abs(step) > accuracy
    at_lower = step <= linearization.step_lower + accuracy
    at_upper = step >= linearization.step_upper - accuracy
    return bool(np.any(moved & (at_lower | at_upper)))


def _within(linearization, region, nv):
    """The linearisation with its configuration step bounded by ``region`` (rad or m), where
    that is tighter than its own bounds (the trust region, the joint limits)."""
    if region >= np.max(-linearization.step_lower[:nv]) and region >= np.max(linearization.step_upper[:nv]):
        return linearization
    lower, upper = linearization.step_lower.copy(), linearization.step_upper.copy()
    lower[:nv] = np.maximum(lower[:nv], -region)
    upper[:nv] = np.minimum(upper[:nv], region)
    return replace(linearization, step_lower=lower, step_upper=upper)


def _with_curvature(linearization, multipliers, configuration=None, *, near_feasible):
    """The linearisation with the constraints' curvature in its Hessian, kept convex.

    The Lagrangian's Hessian ``H_f + C``, ``C = sum_i y_i d^2 c_i``, is
    indefinite (placement rows: eigenvalues of ``C`` from -10 to 10 on
    hand-on-table), but the QP only needs convexity along the steps that keep
    its active rows; the other directions are fixed by the rows. So ``C`` is
    bounded against the reference ``R = H_f + sigma A^T A`` (``A``: the
    equalities and the rows active in the previous QP, scaled), which is
    large across the rows and equals the Gauss-Newton Hessian along them:
    ``C`` is cut where ``R + C`` would fall below ``_FLOOR * R``
    (:func:`~stances.curvature.bounded_below`), and the QP gets ``R + C``.
    Adding ``sigma A^T A`` changes no QP answer that keeps those rows active
    (``A step`` is fixed there).

    Measured: at hand-on-table's solution the iteration contracts by 0.63 with
    Gauss-Newton, 0.11 with ``R + C`` for any ``sigma >= 1e-2`` (as with the raw
    indefinite Hessian), 0.35 with ``H_f + C`` projected onto the positive
    semidefinite matrices. Away from a solution the Lagrangian's Hessian may be
    flat or negative along the rows' tangent, where the projection gave steps of
    0.15 rad along directions the objective barely sees; the floor keeps each
    step within ``1 / _FLOOR`` of the Gauss-Newton one.

    ``C`` has two parts, bounded together: the configuration's (``configuration``), and
    the blocks' in the force variables (:attr:`~stances.blocks.ConstraintBlock.variable_curvature`),
    weighted by the multipliers of their rows on their bound's side (an upper bound's
    ``y >= 0``, a lower one's ``y <= 0``, an equality's either). Blocks whose rows are all
    bounded on one side (a ball's strain, convex) add theirs from the start; a block with
    a row whose multiplier takes either sign (an equality, a two-sided bound: the soft
    Coulomb forces' curvature in static equilibrium and the torques, their slip
    directions', is indefinite) only ``near_feasible``, as the configuration's
    (``_CURVATURE_PHASE``, decided by the caller for both): farther out the last QP's
    multipliers are another point's, and with them the coarse cube of hand-on-soft-cube
    crept from a violation of 0.69 until it stopped, infeasible.

    Parameters
    ----------
    linearization : Linearization
    multipliers : dict
        Row label -> multiplier (:func:`~stances.qp.row_multipliers`) of the
        previous QP; rows it does not name (a collision pair just come
        within reach) weigh nothing.
    configuration : (ConstraintCurvature, (nq,) float), optional
        The configuration's curvature and the linearisation's configuration; None:
        the force variables' alone.
    near_feasible : bool
        Whether the iterate is near feasibility (see above).

    Returns
    -------
    for_qp : Linearization
        Hessian ``H_f + C' + sigma A^T A`` with ``C'`` the bounded curvature (``sigma A^T A``
        only with the configuration's).
    model : Linearization
        Hessian ``H_f + C'``: the model whose decrease the line search expects
        (on the QP's active rows the two differ by a constant).
    """
    n = len(linearization.gradient)
    extra, curved = np.zeros((n, n)), np.zeros(n, dtype=bool)
    # Each block's rows' multipliers, read once (the configuration's curvature, the force
    # variables' and sigma A^T A all weigh by them).
    row_weights = [_row_weights(block, multipliers) if len(block) else None for block in linearization.blocks]
    if configuration is not None:
        curvature, q = configuration
        nv = curvature.model.nv
        weights = [None if block.second_order is None else w for block, w in zip(linearization.blocks, row_weights)]
        extra[:nv, :nv] = curvature.hessian(q, linearization.blocks, weights)
        curved[:nv] = True
    for block, block_weights in zip(linearization.blocks, row_weights):
        if block.variable_curvature is None or block_weights is None:
            continue
        lower, upper = block.lower, block.upper
        if not near_feasible and np.any(np.isfinite(lower) & np.isfinite(upper)):
            continue
        weights = np.clip(block_weights, np.where(np.isfinite(lower), -np.inf, 0.0),
                          np.where(np.isfinite(upper), np.inf, 0.0))
        if weights.any():
            term = block.variable_curvature(weights)
            extra += term
            curved |= np.any(term != 0.0, axis=0)
    if not curved.any():
        return linearization, linearization
    augmentation = _augmentation(linearization, row_weights)
    # The regularisation elastic_qp adds keeps the reference definite.
    reference = linearization.hessian + augmentation + 1e-8 * np.eye(n)
    columns = np.flatnonzero(curved)
    # bounded_below bounds a leading block against the whole reference: the curved columns first.
    order = np.concatenate([columns, np.flatnonzero(~curved)])
    bounded = np.zeros((n, n))
    bounded[np.ix_(columns, columns)] = bounded_below(extra[np.ix_(columns, columns)], reference[np.ix_(order, order)],
                                                      _FLOOR)
    model = linearization.hessian + bounded
    # sigma A^T A goes into the QP with the configuration's curvature only, as it always did
    # (the force variables' alone, a ball's strain, went in without it: the same QPs).
    for_qp = model + augmentation if configuration is not None else model
    return replace(linearization, hessian=for_qp), replace(linearization, hessian=model)


def _row_weights(block, multipliers) -> np.ndarray:
    """(r,) the last QP's multiplier of each of ``block``'s rows (0 for a row it did not have)."""
    return np.array([multipliers.get(label, 0.0) for label in block.labels])


def _augmentation(linearization, row_weights) -> np.ndarray:
    """``sigma A^T A`` (n, n): ``A`` the linearisation's equalities and the rows the previous
    QP held (a nonzero multiplier in ``row_weights``, one array a block, None for an empty
    one), scaled (:func:`_with_curvature`)."""
    active = []
    for block, weights in zip(linearization.blocks, row_weights):
        if weights is None:
            continue
        held = (weights != 0.0) | (block.lower == block.upper)
        active.append(block.jacobian[held] / block.scale[held, None])
    rows = np.vstack(active) if active else np.zeros((0, len(linearization.gradient)))
    return _AUGMENTATION * (rows.T @ rows)


def _predicted_decrease(linearization, step, elastic, penalty, violation) -> float:
    """Decrease of the merit ``f + rho * violation`` the QP model predicts for ``step``."""
    model = (
        linearization.objective
        + linearization.gradient @ step
        + 0.5 * step @ linearization.hessian @ step
        + penalty * elastic
    )
    return linearization.objective + penalty * violation - model


def _line_search(problem, q, lam, step, linearization, violation, penalty, predicted, torque_weight,
                 shortest=_SHORTEST_STEP, correction=None, *, region):
    """Backtracking on the exact-penalty merit from ``linearization`` (whose largest
    scaled violation is ``violation``): ``((q, lam, linearization), alpha, corrected)``
    with the step length accepted and whether a second-order correction followed it,
    or ``(None, alpha, False)`` when no length down to ``shortest`` does.

    The full step is linearised at once: it is accepted in most line searches
    (hand-on-soft-cube: 33 of 49 trials, most of them first ones), and judging it
    on values first cost more than the linearisation saved (measured: no gain
    overall, the 60 random rigid stances slower). Shorter trials are judged on
    values alone (``problem.evaluate``: no Jacobians, the same numbers); only the
    accepted one is then linearised, reusing the evaluation's collision distances
    and contact solves.

    Near feasibility (violation within ``_CORRECTION_PHASE``) a full step that the merit
    refuses while it raised the violation gets a second-order correction first (Nocedal
    and Wright, section 15.6): the restoration step from the trial point, the shortest
    step back onto the constraints linearised there, taken whole if the merit then
    falls enough. Without it a step along curved rows (a palm's turn rows) leaves them
    at second order, the penalty outweighs the objective's gain, and the step is cut
    to 1/16-1/128 at every other iteration (the Maratos effect: hand-on-soft-cube's
    Coulomb stage crept so, 0.06 % of the objective a pair of iterations; a point on a
    sphere crawled to its iteration limit). The corrected point is judged on values and
    linearised only when taken. A step at the trust region's bound from a feasible
    iterate has its cut trials down to CRAWL_ALPHA corrected as well (each trial then
    linearised): the full step's correction fails there, the trial is too far, and the
    plain cuts crawled (a rigid palm turned -20 degrees on hand-on-cube's cube: 100
    iterations, each step cut to 1/128 and restored; 32 with the corrections). Elsewhere
    only the full step is corrected: hand-on-cube's Coulomb stage, its steps cut from
    nearly feasible iterates, took 16-18 iterations instead of 11 with every cut trial
    corrected. ``correction`` is the QP workspace it solves with; None: no correction.
    ``region`` is the configuration step's bound the QP had (``options.trust_region``, or
    less after a crawl: see ``_CRAWL_REGION``).

    Farther out, up to ``_USAGE_PHASE``, a full step gets the correction when it at least
    doubles the violation (``_CORRECTION_GROWTH``): the torque-usage term, entering the
    objective there, sends the QP 0.1-0.25 rad away along curved placement rows. Without
    it cross-soft-block's rigid warm start cut four such steps in a row to a quarter, the
    violation held at 0.06-0.08 (10 iterations; 5 with). A growth under 2 is left alone:
    corrected from 0.015 at 1.5 times, climb's left-on-platform then crept along its
    palm's rows, 21 Coulomb iterations instead of 7.
    """
    model, nv = problem.robot.model, problem.robot.model.nv
    tolerance = problem.options.feasibility_tolerance
    merit = linearization.objective + penalty * violation

    def sufficient(objective, new_violation, fraction):
        # Armijo on the merit, for a step ``fraction`` of the QP's.
        return objective + penalty * new_violation <= merit - 1e-4 * fraction * max(predicted, 0.0)

    # A step at the trust region's bound from a feasible iterate: where the objective's
    # model sends the QP along rows curved at that scale (see below), cut trials are
    # corrected as well.
    crawl_prone = linearization.met(tolerance) and _held_by_trust_region(np.max(np.abs(step[:nv])), region)
    alpha = 1.0
    while alpha >= shortest:
        q_try = pin.integrate(model, q, alpha * step[:nv])
        lam_try = np.maximum(lam + alpha * step[nv:], problem.variable_lower)
        trial = _values_or_none(problem.linearize if alpha == 1.0 else problem.evaluate, q_try, lam_try, torque_weight)
        if trial is None:
            alpha *= 0.5
            continue
        trial_violation, _ = trial.max_violation()
        # The second test is a filter-style escape from the Maratos effect: near
        # a solution a full step may raise the merit through curvature while
        # clearly improving feasibility; such a step is taken.
        if sufficient(trial.objective, trial_violation, alpha) or (
            alpha == 1.0 and violation > tolerance and trial_violation < 0.5 * violation
            and trial.objective <= linearization.objective + 1e-3 * (1.0 + abs(linearization.objective))
        ):
            if alpha != 1.0:
                trial = problem.linearize(q_try, lam_try, torque_weight)
            return (q_try, lam_try, trial), alpha, False
        if ((alpha == 1.0 or (alpha >= CRAWL_ALPHA and crawl_prone)) and correction is not None
                and trial_violation > violation
                and (violation <= _CORRECTION_PHASE
                     or (violation <= _USAGE_PHASE and trial_violation >= _CORRECTION_GROWTH * violation))):
            if alpha != 1.0:
                trial = problem.linearize(q_try, lam_try, torque_weight)
            corrected = restoration_step(problem, trial, q_try, lam_try, correction)
            if corrected is not None:
                values = _values_or_none(problem.evaluate, *corrected, torque_weight)
                if values is not None and sufficient(values.objective, values.max_violation()[0], alpha):
                    return (*corrected, problem.linearize(*corrected, torque_weight)), alpha, True
        alpha *= 0.5
    return None, alpha, False


def posture_result(problem, outcome, elapsed, check=True) -> PostureResult:
    """The answer at the SQP's last iterate, checked by :func:`stances.verify` when
    feasible (and ``check``; an unchecked answer keeps the SQP's own verdict)."""
    q, lam, linearization, feasible = outcome.q, outcome.lam, outcome.linearization, outcome.feasible
    violation, _ = linearization.max_violation()
    # An iterate that stopped just short of the SQP's tolerance (a floor of the QP's
    # accuracy on nearly rigid, statically indeterminate contacts) goes to the
    # independent check, whose tolerances are physical: it alone decides.
    nearly = not feasible and violation <= NEARLY_FEASIBLE * problem.options.feasibility_tolerance
    point_forces = problem_point_forces(problem, linearization, q)
    # A warm start's answer (not checked) is a starting posture only: no FEM field.
    deformations = deformation_fields(problem, q, point_forces) if check else {}
    result = PostureResult(
        feasible=feasible,
        q=q,
        point_forces=point_forces,
        torques=linearization.torques[6:],
        iterations=outcome.iterations,
        solve_time=elapsed,
        reason=outcome.reason,
        stance=problem.stance,
        deformations=deformations,
        limits=problem.limit_usage(q, linearization.torques[6:], linearization.iterate),
        statistics={
            "status": outcome.status, "qp_time": outcome.qp_time, "penalty": outcome.penalty,
            "lambda": lam.tolist(), "violation": violation, "objective": float(linearization.objective),
            "curvature_iterations": outcome.curved_iterations,
            "corrections": outcome.corrections,
        },
        slips=problem_slips(problem, q, lam),
        held_slips=problem_held_slips(problem),
    )
    if check and (feasible or nearly):
        verification = verify_shown(problem, result)
        if verification.ok:
            result = replace(result, verification=verification, feasible=True, reason="")
        elif feasible:
            result = replace(result, verification=verification, feasible=False,
                           reason="verification failed: " + "; ".join(verification.reasons))
    return result


def verify_shown(problem, result) -> Verification:
    """:func:`stances.verify` of ``result`` on ``problem``, the soft bodies' fields it solves
    handed to ``result.deformations`` (a :class:`LazyDeformations`): the check solves each
    soft body under the answer's forces, and the fields the result shows are those (the same
    function of the same q and forces)."""
    fields = {}
    verification = verify_problem(problem, result, fields=fields)
    result.deformations.provide(fields)
    return verification


def _restoration(problem, linearization, q, lam, workspace, torque_weight):
    """The shortest step onto the linearised constraints, taken whole, or None.

    Returns
    -------
    (q, lam, Linearization) at the restored point.
    """
    restored = restoration_step(problem, linearization, q, lam, workspace)
    linearization = None if restored is None else _values_or_none(problem.linearize, *restored, torque_weight)
    return None if linearization is None else (*restored, linearization)


def _values_or_none(evaluate, q, lam, torque_weight):
    """``evaluate(q, lam, torque_weight)`` (the problem's ``linearize`` or ``evaluate``), or None
    where a soft print's contact has no state at that posture: no trial there. With very high
    friction a node can need a tangential force with almost no normal force, where the discrete
    Coulomb problem has no state (``fem.ContactStateError``): a posture solve on a palm at
    mu = 50 raised it from a line search's trial, while nearer postures have states and the
    stance solves at mu = 30."""
    try:
        return evaluate(q, lam, torque_weight)
    except ContactStateError:
        return None


def _solve_step_qp(workspace, linearization, penalty, accuracy, plain_first):
    """The QP's answer ``(dq, dlambda, elastic)`` and whether it came from
    :func:`~stances.qp.plain_qp` (elastic 0): tried first when ``plain_first``, the
    elastic QP (``penalty``) solved when it was not or its rows proved incompatible
    (proxsuite gives up within ``_PLAIN_QP_ITERATIONS``)."""
    if plain_first:
        x = workspace.solve(*plain_qp(linearization), accuracy=accuracy, max_iterations=_PLAIN_QP_ITERATIONS)
        if workspace.solved:
            return np.append(x, 0.0), True
    data = elastic_qp(linearization, penalty)
    # From the feasible point of no step (fewer proxsuite iterations than x = 0).
    return workspace.solve(*data, accuracy=accuracy, start=elastic_start(data)), False


def _optimality_gain(linearization, step) -> float:
    """What the QP's ``step`` gains of the objective by optimality, not by feasibility:
    ``1/2 step^T H step`` (H the linearisation's Hessian).

    At the QP's answer ``g + H s + A^T y = 0`` and ``A s = -c`` on its active rows, so the
    model's decrease ``-(g^T s + 1/2 s^T H s)`` is ``1/2 s^T H s - y^T c``: the second
    term is what restoring the violation c costs, which near feasibility can hide the
    first (a point just outside a sphere, its target outside too).
    """
    return 0.5 * float(step @ linearization.hessian @ step)


def restoration_step(problem, linearization, q, lam, workspace):
    """The point :func:`_restoration` goes to, ``(q, lam)``, or None."""
    n = len(linearization.gradient)
    metric = np.ones(n)
    # Force variables (newtons) move more freely than joints (radians); a ratio much
    # larger than this makes the QP badly conditioned (measured: thousands of
    # proxsuite iterations at 1e-6).
    metric[problem.robot.model.nv :] = 1e-2
    shortest = replace(linearization, objective=0.0, gradient=np.zeros(n), hessian=np.diag(metric))
    # Without the elastic variable first: the rows are usually compatible here, a step
    # from a nearly feasible point.
    x, _ = _solve_step_qp(workspace, shortest, _RESTORATION_PENALTY, 1e-9, plain_first=True)
    if not np.all(np.isfinite(x)):
        return None
    nv = problem.robot.model.nv
    q_new = pin.integrate(problem.robot.model, q, x[:nv])
    lam_new = np.maximum(lam + x[nv:-1], problem.variable_lower)
    return q_new, lam_new


def deformation_fields(problem, q, point_forces) -> LazyDeformations:
    """The body displacement field of each deformable contact of a problem, computed on access.

    Parameters
    ----------
    problem : PostureProblem
    q : (nq,) float
        Configuration of ``problem.robot.model``.
    point_forces : tuple of PointForce
        The problem's contact forces at ``q`` (:func:`problem_point_forces`
        order), newtons, world frame.

    Returns
    -------
    LazyDeformations
        Deformable object name -> (N, 3) float, metres, body frame (eq. 36).
    """
    model = problem.robot.model
    return LazyDeformations(
        {
            contact.deformable_object.name: _field_producer(
                contact, model, q, [p.force for p in point_forces[loads]]
            )
            for contact, loads in zip(problem.contacts, problem.load_slices)
            if contact.deformable_object is not None
        }
    )


def _field_producer(contact, model, q, forces):
    """A closure computing a contact's body displacement field at ``q`` under its forces (eq. 36).

    It holds the body and the point loads on it (``contact.field_loads``), not the contact:
    a search keeps every answer, and through them their contacts' patches, factorisations
    and strain sets, 5-10 MB a soft solve (a user's 100-expansion plan held 1.5 GB). The
    traction model's field is its print's motion: its patch and link motion, taken now.
    """
    q, forces = np.array(q), np.array(forces)
    body = contact.deformable_object.body
    loads = contact.field_loads(forces)
    if loads is None:
        data = pin.Data(model)
        pin.framesForwardKinematics(model, data, q)
        patch, motion = contact.print_motion(data)
        motion = np.array(motion)
        return lambda: np.asarray(body.displacement_field(patch, motion))
    node_ids, node_loads = np.array(loads[0]), np.array(loads[1])
    return lambda: body.displacement_under_loads(node_ids, node_loads)


def problem_slips(problem, q, lam) -> dict:
    """Robot surface -> :class:`~stances.results.NodeSlips` of each soft print of ``problem``
    solved under the ``coulomb`` law, at ``q`` and the contact variables ``lam``."""
    model, data = problem.robot.model, problem.data
    pin.framesForwardKinematics(model, data, q)
    slips = {}
    for contact, variables in zip(problem.contacts, problem.variable_slices):
        if contact.kind == "deformable":
            slips.update(contact.print_slips(model, data, lam[variables]))
    return slips


def problem_held_slips(problem) -> dict:
    """Robot surface -> :class:`~stances.results.NodeSlips` each soft print of ``problem``
    starts from (the coulomb law's held slips; see :func:`stances.solve`'s ``history``)."""
    return {surface: slips for contact in problem.contacts if contact.kind == "deformable"
            for surface, slips in contact.held_slips.items()}


def problem_point_forces(problem, linearization, q) -> tuple:
    """Point forces of a linearised problem's contacts at ``q``, in the world frame."""
    model, data = problem.robot.model, problem.data
    pin.framesForwardKinematics(model, data, q)  # the last linearisation may have been a rejected trial
    points = points_in_world(data, problem.loads)
    frames = [frame for contact in problem.contacts for frame in contact.load_frames]
    return tuple(
        PointForce(frame, point, force)
        for frame, point, force in zip(frames, points, linearization.forces)
    )
