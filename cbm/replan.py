"""Plans whose every step has a motion: plan, plan the motions, and plan again around a step without one.

The search (:func:`cbm.plan`) accepts a step when both stances hold, but a step
between two feasible stances can still lack a quasi-static motion: on the ``turn``
suite scene, a right foot carried 0.6 m forward past the left one on a foam mat,
in single support, reaches no posture near touch-down whose weight the left sole
holds within the mat's strain bound. As in contact-before-motion planning
(Bretl, Hauser), such a transition is taken out of the stance graph and the
search runs again; the next plan steps differently (there: the right foot set
down turned 0 instead of 45 degrees first, ten motions, every one found).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

from .errors import CbmError
from .motion import plan_motions_reposing
from .planner import PlanInterrupted, load_robot, load_scenario, plan

__all__ = ["AvoidedStep", "MovingPlan", "plan_with_motions"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class AvoidedStep:
    """A step an earlier plan took that no quasi-static motion joins.

    Parameters
    ----------
    before, after : environments Stance
        The stances it joined.
    move : str
        The move, as the plan spelled it (e.g. ``place right_sole on mat_top at ...``).
    reason : str
        Why its motion failed (:attr:`cbm.motion.Motion.reason`).
    """

    before: object
    after: object
    move: str
    reason: str


@dataclass(frozen=True)
class MovingPlan:
    """A plan with its motions, and the steps earlier plans took without one.

    Parameters
    ----------
    plan : cbm.Plan
        The plan kept: the first whose motions are all found, else the one with
        the fewest missing (the earliest of those).
    motions : tuple of cbm.motion.Motion
        Its ``len(plan.stances) - 1`` motions (:func:`cbm.motion.plan_motions_reposing`).
    avoided : tuple of AvoidedStep
        Steps of earlier plans without a motion, which this plan's search was
        not allowed to take.
    plans : int
        Searches run, this plan's and any after it.
    """

    plan: object
    motions: tuple
    avoided: tuple = ()
    plans: int = 1

    @property
    def missing(self) -> int:
        """Motions not found."""
        return sum(not motion.feasible for motion in self.motions)


def plan_with_motions(scenario, *, robot=None, attempts=3, motion_options=None, **plan_options) -> MovingPlan:
    """Plan stances and the motions between them; where a step has no motion, plan again without it.

    Parameters
    ----------
    scenario : environments Scenario, str or path
        As :func:`cbm.plan`.
    robot : stances Robot, optional
        Default: :func:`load_robot` of ``scenario.robot`` (loaded once, shared by plans).
    attempts : int
        Searches at most (>= 1); each has the budgets of ``plan_options``.
    motion_options : dict, optional
        Keyword arguments of :func:`cbm.motion.plan_motions_reposing`.
    **plan_options
        Keyword arguments of :func:`cbm.plan` (not ``forbidden``: this function
        sets it).

    Returns
    -------
    MovingPlan
        A search that finds no plan ends the attempts: the best earlier plan is
        kept, or, on the first search, that unsuccessful plan (its best partial
        sequence, with its motions).

    Raises
    ------
    CbmError
        If ``attempts`` is not a positive integer or ``plan_options`` names ``forbidden``.
    PlanInterrupted
        On Ctrl-C during a search or its motions: with the best plan made before and
        its motions, when there is one, else (during the first search) the search's
        partial plan; a Ctrl-C during the first plan's motions is a plain
        ``KeyboardInterrupt``.
    """
    if isinstance(attempts, bool) or not isinstance(attempts, int) or attempts < 1:
        raise CbmError(f"attempts must be a positive integer, got {attempts!r}")
    if "forbidden" in plan_options:
        raise CbmError("plan_with_motions sets forbidden itself (the steps without a motion); do not pass it")
    scenario = load_scenario(scenario)
    robot = robot if robot is not None else load_robot(scenario.robot)
    motion_options = dict(motion_options or {})
    best, avoided = None, []
    for attempt in range(1, attempts + 1):
        forbidden = frozenset((step.before, step.after) for step in avoided)
        try:
            planned = plan(scenario, robot=robot, forbidden=forbidden, **plan_options)
            if planned.success:
                planned, motions = plan_motions_reposing(planned, scenario, robot, **motion_options)
        except KeyboardInterrupt:  # PlanInterrupted too
            if best is None:
                raise
            raise PlanInterrupted(best.plan, best.motions) from None
        if not planned.success:
            logger.info("search %d found no plan without the %d steps avoided: %s", attempt, len(avoided), planned.reason)
            if best is not None:
                return replace(best, plans=attempt)
            # No plan at all: the best partial sequence, with its motions, as cbm.plan gives it.
            return MovingPlan(*plan_motions_reposing(planned, scenario, robot, **motion_options), (), attempt)
        current = MovingPlan(planned, motions, tuple(avoided), attempt)
        if best is None or current.missing < best.missing:
            best = current
        if current.missing == 0:
            return current
        for motion in motions:
            if not motion.feasible:
                before, after = planned.stances[motion.index], planned.stances[motion.index + 1]
                avoided.append(AvoidedStep(before.stance, after.stance, after.move, motion.reason))
                logger.info("step %d -> %d has no motion; planning again without it", motion.index, motion.index + 1)
    return replace(best, plans=attempts)
