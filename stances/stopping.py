"""The SQP's stopping test: when :func:`stances.sqp.run_sqp` ends, and at which iterate.

The iterations (:mod:`stances.sqp`) take steps; this module decides when they are
done. A :class:`StoppingTest` remembers what its rules read across iterations (the
violations after each step, failed line searches in a row, crawls, the best
feasible iterate) and answers at the three points of an iteration where a rule can
fire, in the order the loop meets them:

1. after the QP (:meth:`StoppingTest.converged_before_search`): a feasible iterate
   whose step is negligible is the answer;
2. after the line search: nearly feasible, steps cut or not found again and again
   without the violation halving (:meth:`StoppingTest.lingering`); far from feasible,
   steps cut again and again without the violation falling
   (:meth:`StoppingTest.hopeless`); no step found four times in a row, or at the
   constraints' rounding (:meth:`StoppingTest.stalled`);
3. after a step is taken: an infeasible iterate whose violation stagnates or falls
   too slowly to reach the tolerance (:meth:`StoppingTest.diverging`), or, in a stage
   that has a fallback, creeps far from feasible under cut steps
   (:meth:`StoppingTest.creeping`); a feasible one that no longer improves
   (:meth:`StoppingTest.converged`).

An infeasible stance ends with the status of the rule that ended it, which the
answer's reason reports. Every rule is a measured failure mode; the comments by the
constants say which.
"""

from __future__ import annotations

import numpy as np

__all__ = ["StoppingTest"]

_STAGNATION_WINDOW = 8
# At a penalty this large the QPs have long preferred feasibility: a violation that
# still falls, but at a rate that would not reach the tolerance within twice the
# iterations left, ends the solve (an infeasible quadruped stance fell 2 % an
# iteration for 87 iterations of 170 ms QPs, 17 s, and never got there).
_SLOW_PENALTY = 1e6
_SLOW_GRACE = 12  # iterations a too-slow convergence may go on while its QPs meet their rows
# Feasible iterates whose line search keeps cutting the step below this many
# times in a row stop: the QP's model no longer predicts the objective (a
# warm start at its loose tolerance crawled 70 iterations at alpha 1/256 on a
# climb stance, for an objective change of 4 %). Cuts from nearly feasible
# iterates that a restoration step follows count too when they gain less than
# _CRAWL_GAIN of the objective (see StoppingTest.converged).
CRAWL_ALPHA = 1.0 / 16.0
CRAWL_STEPS = 3
# A feasible iterate that no step of the next NO_GAIN_ITERATIONS beats by more than
# _NO_GAIN relative objective ends the SQP (at that iterate): near a node's mode
# switch the steps cycle between it and barely infeasible neighbours (measured on
# a two-sole stance of the turn scene: 14 iterations cycling, 1.4 s, objective
# moving by 1e-5).
_NO_GAIN = 1e-5
NO_GAIN_ITERATIONS = 4
# A feasible iterate is also final when the QP's model predicts a merit decrease
# below _NO_GAIN of the objective and the full step does not deliver it: the model
# is wrong there (a node's mode switch), and cutting the step gains no more than the
# rule above would wait for. Measured: foot-and-hand-on-foam's Coulomb stage ended
# with a step predicted to gain 3e-6 of the objective, which the line search cut to
# 1/128 through eight contact solves of both prints (60 ms of its 290).
PREDICTED_GAIN = _NO_GAIN
# ... and one whose best feasible objective gained less than _SLOW_GAIN (relative) over
# the last SLOW_GAIN_ITERATIONS: a cycle that still creeps, a feasible iterate and a
# barely infeasible neighbour in turn, each pair 7e-5 better (hand-on-cube's Coulomb
# stage: 20 iterations, 0.07 % of the objective, 2.9 s, to its iteration cap). Four
# iterations, not eight: a two-sole stance of the turn scene cycled so, 0.023 % of the
# objective a pair, each cut step nine contact solves of its two soles (1.31 -> 0.88 s,
# the posture 0.8 mrad apart; the other built-in soft and rigid stances the same bits).
_SLOW_GAIN = 1e-3
SLOW_GAIN_ITERATIONS = 4
_CRAWL_GAIN = _SLOW_GAIN / 8  # relative objective gain an iteration below which a cut step crawls
# A nearly feasible iterate (within NEARLY_FEASIBLE tolerances) whose step is predicted
# to gain under MINOR_GAIN of the objective cuts that step no shorter than
# CRAWL_ALPHA: below, the model is wrong (a node's mode switch within the step), and
# each cut costs a contact solve per soft print for a gain the crawl rules would not wait
# for. Measured on hand-on-cube's Coulomb stage: its last two line searches (predicted
# 1e-4 of the objective) cut to 1/128 and 1/512, 18 evaluations, 30 of its 200 ms.
MINOR_GAIN = 1e-3
NEARLY_FEASIBLE = 100.0  # times the feasibility tolerance: such an iterate is handed to verify
# A nearly feasible iterate (scaled violation within FINISHING_VIOLATION: a micrometre of
# placement, a millinewton of equilibrium) whose QP step would gain less than
# FINISHING_GAIN optimality tolerances of the objective by optimality has converged but
# for the violation its last step left (second order in that step): a restoration step,
# the shortest one onto the rows linearised there, removes it at once, where the
# optimality steps took one to three more iterations, each shrinking the step by the
# linear rate of the objective's Hessian. Measured at the defaults: the 60 random rigid
# stances 424 -> 387 iterations, the 15 soft ones 200 -> 185, objectives within 1.6e-6
# (relative) and postures within 2.3 mrad of the answers without it. Counting the step's
# whole model decrease instead of its optimality part (see stances.sqp._optimality_gain),
# a point just off a sphere stopped 2e-5 above its optimum; at one optimality tolerance
# of that part, 406 rigid iterations. The SQP asks only where its QP's rows were compatible
# and no bound held a component of the step (1/2 s^T H s leaves out what the bounds'
# multipliers take: a step held by the trust region along a direction of little
# curvature read 4.5e-7 and gained 9e-4; found by review).
# Where the last two iterations' steps also came to this test, with gains falling, the
# gains shrink at a rate r (a Gauss-Newton tail; a gain 1/2 s^T H s falls as the square of
# the step), read as the larger of the two last ratios, so that one sudden drop (a part of
# the problem that converged at once) is no rate; what the steps left would gain in all,
# gain / (1 - r), ends the solve once under FINISHING_TAIL optimality tolerances: 1e-5 of
# the objective at the default tolerance, the gain the other rules call none (_NO_GAIN,
# PREDICTED_GAIN). On the mirrored-cell mesh climb-with-soft-support's left-on-platform
# ended its Coulomb stage with six Gauss-Newton steps of 2.1 -> 1.3 mrad, each predicted to
# gain 6e-6 -> 2e-6 of the objective, 75-82 % of the one before. A tail that falls slowly
# waits: a point far off a sphere, its steps shrinking by 0.95 and its gains by 0.90, reads
# ten gains, and the rule on the gain alone decides there (a plain FINISHING_GAIN of 100
# stopped that point 2.0e-3 off its optimum, 6.5e-4 at 10). Measured 2026-12-04:
# left-on-platform 13 -> 8 iterations, 3.8e-6 of the objective higher, 2.5 mrad apart; over
# the 37 built-in and 60 random rigid stances three answers moved, by at most 2.5 mrad and
# 2.8e-5 of their objective, all verified. One ratio alone read a sudden drop (a variable
# converged at once) as a fast tail: a review's toy stopped 48.7 tolerances above its
# optimum, as FINISHING_GAIN = 100 did.
FINISHING_VIOLATION = 1e-4
FINISHING_GAIN = 10.0
FINISHING_TAIL = 100.0
# Far from feasible (scaled violation above HOPELESS_VIOLATION: 0.1 mm, 0.01 N),
# iterations whose line search cuts the step below CRAWL_ALPHA (or finds no
# step) CRAWL_STEPS times in a row, with the violation falling by less than
# _HOPELESS_PROGRESS over them, end the solve: the linear model does not
# describe the constraints there (a collision distance turning a corner, a
# contact that cannot be placed), and the steps left are the line search's
# ten linearisations each. Measured on 176 feasible solves of planner runs and
# perturbed planner stances: their crawls (three such cuts in a row) all began
# below a violation of 7e-4; infeasible solves crawled at 0.05-7 and then
# stalled (four line searches finding no step, 1-2 s on soft scenes).
HOPELESS_VIOLATION = 1e-2
_STALLED_SEARCHES = 4  # failed line searches in a row (the penalty raised after each) that end a solve
_HOPELESS_PROGRESS = 0.5
# An iterate nearly feasible (scaled violation above the tolerance, at most
# LINGER_VIOLATION and within the NEARLY_FEASIBLE tolerances that send an answer to
# verify; an absolute cap, so a warm start's loose tolerance leaves the band empty)
# from which LINGER_ITERATIONS steps were cut below CRAWL_ALPHA, not found, or left
# the QP's rows unmet, without the violation halving (or doubling) since, ends the
# solve, and goes to verify. Near a node's mode switch, or where two rows are nearly
# parallel (a foot's equilibrium and strain rows on foam, cosine 0.99996, incompatible
# by 4e-7 once linearised), steps alternate between a full one and one cut to 1/128
# and the violation hovers: a palm stance of rail-over-gap sat at 1.35-1.45e-7 for 13
# iterations of a held-mode stage, twice; a quadruped stance on foam at 1.2e-6 for 6
# iterations of its Coulomb stage, each with QPs at their iteration caps, before held
# modes converged in 5. Whole steps do not count: Gauss-Newton creeping along a curved
# row, 10 % an iteration, still converges (a point on a sphere: 86 iterations).
LINGER_VIOLATION = 1e-5
LINGER_ITERATIONS = 4
LINGERING = (f"nearly feasible but not converging: {LINGER_ITERATIONS} steps cut below 1/16 or not found "
             "without the violation halving")
# A solve that has somewhere else to go (a Coulomb stage's first, free-mode stage: held
# modes from its start follow) ends, far from feasible (above HOPELESS_VIOLATION), once
# CREEP_STEPS steps in a row were cut and the violation has not halved since the first:
# the free modes' model is wrong there and the stage would spend its iterations creeping.
# Measured on a quadruped-foam planner stance (seed 2): 25 free iterations, every step cut
# to 1/8-1/2, the violation 0.28 -> 0.10 (700 ms of a 1.0 s solve), then held modes from
# its start converged in 13.
CREEP_STEPS = 6
CREEPING = (f"far from feasible and creeping: {CREEP_STEPS} steps in a row cut with the violation falling "
            "by less than half")
ROUNDING_FLOOR = 3e-7  # scaled violation (three default tolerances) within which a failed line search ends the solve
NO_PROGRESS = f"no progress toward feasibility: the line search cut {CRAWL_STEPS} steps in a row below 1/16"
STALLED = "stalled"  # the SQP's status where line searches found no step (StoppingTest.stalled)


def at_rounding_floor(violation, elastic, tolerance) -> bool:
    """Whether what is left of the violation is the rows' rounding.

    Within three default tolerances (``ROUNDING_FLOOR``), with a step that meets its
    linearised rows (``elastic <= tolerance``): a steel-stiff print's rows read its
    micro-displacements times 1e11 Pa, which no penalty removes. Such an iterate goes
    to verify, whose tolerances are physical (1e-6 N of equilibrium, what the SQP's
    tolerance is on those rows, scaled by 10 N; 1e-6 m of placement, a thousand times
    the SQP's): it decides. The floor is
    absolute: a warm start's loose tolerance is not verified, and violations that far
    up are not rounding (a review found the rule, at ten tolerances, ending warm
    starts at 5e-3 that a raised penalty would have converged). hand-on-cube at
    E = 1e11 Pa sat at 1.5-2e-7 (scaled, the tolerance 1e-7) through three more
    failed searches, the penalty raised after each, ten contact solves a search.
    """
    return tolerance < violation <= ROUNDING_FLOOR and elastic <= tolerance


def better(best, current):
    """The feasible ``(q, lam, linearization)`` with the lower objective: ``best`` (None: none
    yet) or ``current`` (ties to ``current``)."""
    if best is not None and best[2].objective < current[2].objective:
        return best
    return current


class StoppingTest:
    """What the SQP's stopping rules remember across iterations, and the rules.

    Parameters
    ----------
    tolerance : float
        Feasibility tolerance (scaled rows), ``PostureOptions.feasibility_tolerance``.
    optimality_tolerance : float
        Relative objective change of a step below which a feasible iterate is final.
    limit : int
        The SQP's iteration limit (the too-slow rule compares with the iterations left).
    creep : bool
        Whether :meth:`creeping` may end the solve (a solve with a fallback).

    Attributes
    ----------
    best : tuple or None
        The best feasible ``(q, lam, linearization)`` seen since the objective last
        changed (:meth:`forget_objectives`), or None.
    """

    def __init__(self, tolerance, optimality_tolerance, limit, creep=False):
        self.tolerance = tolerance
        self.optimality_tolerance = optimality_tolerance
        self.limit = limit
        self.creep = creep
        self._cuts, self._creep_start = 0, np.inf  # cut steps in a row (creeping), and the violation before them
        self.best, self._best_iteration = None, 0
        self._best_history = []  # the best feasible objective after each iteration once there is one
        self._history = []  # the violation after each step taken
        self._stalled = 0  # failed line searches in a row
        self._crawls, self._crawl_start = 0, np.inf  # cut steps in a row far from feasible, and the violation where they began
        self._crawling = 0  # crawling iterations in a row near feasibility (see converged)
        self._slow_since = None  # the first iteration at which the violation fell too slowly to converge in time
        self._near, self._troubles = None, 0  # the nearly feasible violation steps are counted from, and the count
        self._gains = []  # (iteration, gain) of the finishing tests of the last three iterations

    def forget_objectives(self) -> None:
        """The objective changed (torque usage joined it): objectives seen before are
        another function's, and would stop the solve as soon as a step is cut."""
        self.best, self._best_history = None, []
        self._gains = []

    def final(self, current):
        """The answer of a solve stopped at ``current``: the best feasible iterate seen
        when ``current`` is not feasible (an iteration limit, a deadline), else ``current``."""
        if self.best is not None and not current[2].met(self.tolerance):
            return self.best
        return current

    def finishing(self, met, violation, gain, objective, iteration=None) -> bool:
        """After the QP: whether an iterate not feasible (``met`` False) but within
        ``FINISHING_VIOLATION`` (its scaled ``violation``), whose QP step would gain
        ``gain`` of the ``objective`` by optimality (not by feasibility), less than
        ``FINISHING_GAIN`` optimality tolerances, is finished by a restoration step rather
        than a line search (see ``FINISHING_VIOLATION``). With ``iteration`` given, and the
        gains of the two iterations before it known and falling to this one, the tail
        ``gain / (1 - r)`` (r the larger of the two ratios) under ``FINISHING_TAIL``
        tolerances finishes it too."""
        self._gains = [g for g in self._gains if iteration is not None and g[0] >= iteration - 2] + [(iteration, gain)]
        if met or violation > FINISHING_VIOLATION:
            return False
        unit = self.optimality_tolerance * (1.0 + abs(objective))
        if gain <= FINISHING_GAIN * unit:
            return True
        if len(self._gains) < 3:
            return False
        (first, a), (second, b), (_, c) = self._gains
        if first != iteration - 2 or second != iteration - 1 or not 0.0 < c < b < a:
            return False
        return c / (1.0 - max(b / a, c / b)) <= FINISHING_TAIL * unit

    def converged_before_search(self, linearization, step_length, predicted) -> bool:
        """After the QP: a feasible iterate whose step is negligible (in length, radians
        or metres, or in the merit decrease the QP predicts) is the answer."""
        return linearization.met(self.tolerance) and (
            step_length < 1e-7 or predicted <= 1e-9 * (1.0 + abs(linearization.objective))
        )

    def lingering(self, violation, met, troubled) -> bool:
        """After the line search: whether a nearly feasible solve hovers (see
        ``LINGER_ITERATIONS``).

        Parameters
        ----------
        violation : float
            Scaled violation of the iterate this iteration started from.
        met : bool
            Whether that iterate is feasible (:meth:`Linearization.met`).
        troubled : bool
            Whether this iteration's step was cut below ``CRAWL_ALPHA``, not found, or
            left the QP's linearised rows unmet (elastic variable above the tolerance).

        Returns
        -------
        bool
            True when ``LINGER_ITERATIONS`` troubled steps were taken from iterates in the
            band since the violation last halved or doubled there.
        """
        top = min(LINGER_VIOLATION, NEARLY_FEASIBLE * self.tolerance)
        if met or not self.tolerance < violation <= top:
            self._near = None
            return False
        if self._near is None or not 0.5 * self._near < violation <= 2.0 * self._near:
            self._near, self._troubles = violation, 0
        self._troubles += bool(troubled)
        return self._troubles >= LINGER_ITERATIONS

    def hopeless(self, violation, accepted, alpha) -> bool:
        """After the line search: far from feasible, whether the last ``CRAWL_STEPS`` steps
        were all cut below ``CRAWL_ALPHA`` (or not found: ``accepted`` None) while the
        violation fell by less than ``_HOPELESS_PROGRESS`` over them.

        Parameters
        ----------
        violation : float
            Scaled violation before this iteration's step.
        accepted : tuple or None
            ``(q, lam, linearization)`` the line search (or a restoration) found.
        alpha : float
            Its fraction of the QP's step.
        """
        self._crawls = self._crawls + 1 if violation > HOPELESS_VIOLATION and (
            accepted is None or alpha < CRAWL_ALPHA) else 0
        if self._crawls == 1:
            self._crawl_start = violation
        if self._crawls < CRAWL_STEPS:
            return False
        reached = violation if accepted is None else min(violation, accepted[2].max_violation()[0])
        return reached > _HOPELESS_PROGRESS * self._crawl_start

    def stalled(self, violation, elastic, penalty_raised, curved_phase) -> bool:
        """After a line search that found no step: whether the solve ends, stalled.

        Four in a row end it; one ends it at once at the rows' rounding
        (:func:`at_rounding_floor`), or when, the penalty not raised, nothing the next
        iteration reads has changed (the linearisation, the penalty, a model without the
        last QP's multipliers, outside the ``curved_phase``; QPs from a cold start): its
        QP and line search would be this one's again, but for the contact modes each soft
        print's solve starts from (the last trial's; where a print's Coulomb state is
        unique, the same answer). A soft palm on rail-over-gap's rail, feasible, repeated
        a failed line search three times, ten contact solves each (40 % of its solve).
        (Near feasibility the soft Coulomb forces' curvature reads the last QP's
        multipliers whatever the phase, so the next QP may differ a little: a review
        checked 12 soft stances, the shortcut ended 3 of them, and let go on those 3 ended
        at the same objectives three iterations later.)
        Far from feasible the repeats are left to :meth:`hopeless`, which ends them with
        its own reason.
        """
        self._stalled += 1
        if at_rounding_floor(violation, elastic, self.tolerance) or (
            not penalty_raised and violation <= HOPELESS_VIOLATION and not curved_phase
        ):
            self._stalled = _STALLED_SEARCHES
        return self._stalled >= _STALLED_SEARCHES

    def diverging(self, iteration, violation, elastic, penalty) -> str | None:
        """After a step (which it records, and which ends a run of failed line searches):
        the status ending an infeasible solve whose violation (scaled, after the step)
        stagnates or falls too slowly, else None.

        Infeasible stances end here rather than at the iteration limit: the violation
        has not fallen by 1 % over the last iterations although the penalty is already
        large, or at a rate that would not reach the tolerance within twice the
        iterations left.
        """
        self._stalled = 0
        history, tolerance = self._history, self.tolerance
        history.append(violation)
        if len(history) <= _STAGNATION_WINDOW or violation <= tolerance:
            return None
        if penalty >= 1e4 and violation > 0.99 * history[-_STAGNATION_WINDOW - 1]:
            return "stagnated"
        if penalty < _SLOW_PENALTY:
            return None
        rate = (violation / history[-_STAGNATION_WINDOW - 1]) ** (1.0 / _STAGNATION_WINDOW)
        needed = np.log(tolerance / violation) / np.log(rate) if rate < 1.0 else np.inf
        too_slow = needed > 2.0 * (self.limit - iteration)
        if too_slow and self._slow_since is None:
            self._slow_since = iteration
        # While the QP cannot meet its linearised rows (elastic > 0) that ends it; while
        # it meets them the violation can still fall faster, so _SLOW_GRACE iterations
        # more first (a rigid palm turned 30 degrees on hand-on-cube's cube crept 4 % an
        # iteration at elastic 0 from iteration 29 and converged at 39; an infeasible
        # two-feet-and-palm stance by a wall, creeping 2-6 % at elastic 0, now ends at
        # 59 rather than at 30, where ignoring the rule at elastic 0 ran it to 100).
        if too_slow and (elastic > tolerance or iteration - self._slow_since >= _SLOW_GRACE):
            return f"converging too slowly: {1.0 - rate:.1%} an iteration"
        return None

    def creeping(self, violation, reached, alpha) -> bool:
        """After a step is taken: with ``creep`` on, whether ``CREEP_STEPS`` steps in a row
        were cut and, far from feasible, the violation has not halved since the first of
        them. Failed line searches (no step) neither count nor break the run.

        Parameters
        ----------
        violation : float
            Scaled violation before the step.
        reached : float
            Scaled violation after it.
        alpha : float
            The step's fraction of the QP's step (1: whole).

        Returns
        -------
        bool
            True when the solve ends, creeping (status :data:`CREEPING`).
        """
        self._cuts = self._cuts + 1 if alpha < 1.0 else 0
        if self._cuts == 1:
            self._creep_start = violation
        return (self.creep and self._cuts >= CREEP_STEPS and reached > HOPELESS_VIOLATION
                and reached > _HOPELESS_PROGRESS * self._creep_start)

    def converged(self, iteration, current, previous, violation, alpha, searched, step_length):
        """After a step: the answer when the solve has converged there, else None.

        Parameters
        ----------
        iteration : int
        current : tuple
            ``(q, lam, linearization)`` after the step.
        previous : Linearization
            Before the step.
        violation : float
            Scaled violation before the step.
        alpha : float
            The step's fraction of the QP's step (1 for a restoration step).
        searched : float
            The optimality step's own cut (0 when the line search found none).
        step_length : float
            Largest configuration component of the QP's step, radians or metres.

        Returns
        -------
        tuple or None
            ``(q, lam, linearization)``: ``current`` or the best feasible iterate seen.
        """
        tolerance, linearization = self.tolerance, current[2]
        feasible = linearization.met(tolerance)
        objective, previous_objective = linearization.objective, previous.objective
        # Feasible (each row within its tolerance): the objective alone says
        # whether a step still improves. The violations left are below what
        # matters, and penalty times their change, as the SQP creeps linearly
        # along the constraints, would keep the merit moving for 5-10 more
        # iterations (hand-on-table: 19 iterations, now 11) for a posture that
        # moves by 1e-5 rad.
        # A crawl: a feasible iterate reached by a cut step; or, from any nearly
        # feasible iterate, an optimality step cut below CRAWL_ALPHA (whether or not
        # a restoration step then replaced it) that gained next to nothing. Near a
        # node's mode switch the QP's step turned out 1e6 times too long (a full
        # step's violation 1.1 from 1e-10), each cut to 1/256 landed just outside the
        # tolerance and a restoration brought it back at alpha 1, which reset a count
        # of the first kind alone: the Coulomb stage of hand-on-cube took 8 such
        # iterations, 11 contact solves each, for 0.03 % of the objective. The gain
        # guard keeps that second kind from stopping a curved path that still
        # improves (a point on a sphere: cut and restored, 0.3 % an iteration).
        cut = searched < CRAWL_ALPHA and violation <= NEARLY_FEASIBLE * tolerance
        gained = previous_objective - objective
        self._crawling = self._crawling + 1 if (feasible and alpha < CRAWL_ALPHA) or (
            cut and gained < _CRAWL_GAIN * (1.0 + abs(previous_objective))
        ) else 0
        best = self.best
        if feasible and (
            alpha * step_length < 1e-6
            # (An objective the step did not move says the optimality step found nothing
            # only when it was that step, ``alpha == searched``: a restoration that replaced
            # a failed or cut line search ignores the objective, and its gain of nothing is no
            # answer. The mixed stiffness sweep's baseline, its palm held rigid and its soles
            # on a soft mat, stopped so at objective 2.180 with a 0.022 rad step still
            # proposed; going on, 2.051 in five iterations, where a start from the stiff
            # answer's posture reached 2.050.)
            or (alpha == searched and abs(gained) < self.optimality_tolerance * (1.0 + abs(previous_objective)))
            or self._crawling >= CRAWL_STEPS
            # A step cut below CRAWL_ALPHA near feasibility, after which the iterate is
            # feasible but next to no better than the best feasible one before it: the
            # QP's model is wrong here (a node's mode switch within the step), and the
            # next steps were seen to be the same step cut again (hand-on-cube's Coulomb
            # stage: twice to 1/256, nine contact solves each; a two-sole turn stance
            # on a mat: a 0.15 rad lean cut to 1/512 and restored, three times).
            or (cut and (best is not None or violation <= tolerance)
                and (previous_objective if best is None else best[2].objective) - objective
                < _CRAWL_GAIN * (1.0 + abs(previous_objective)))
        ):
            # A cut step restored to feasibility can land above the best feasible
            # objective (restoration ignores the objective): that one is the answer.
            return better(best, current)
        if feasible and (best is None or objective < best[2].objective - _NO_GAIN * (1.0 + abs(best[2].objective))):
            self.best, self._best_iteration = current, iteration
        elif best is not None and iteration - self._best_iteration >= NO_GAIN_ITERATIONS:
            return best
        if self.best is not None:
            history = self._best_history
            history.append(self.best[2].objective)
            if len(history) > SLOW_GAIN_ITERATIONS and (
                history[-SLOW_GAIN_ITERATIONS - 1] - history[-1] < _SLOW_GAIN * (1.0 + abs(history[-1]))
            ):
                return self.best
        return None
