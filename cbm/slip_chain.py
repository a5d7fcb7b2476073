"""A plan's kept soft prints, chained: each stance solved from where the one before left them.

Under Coulomb friction a print node that slipped stays where it slipped to, so a stance's
answer depends on the answer before it through the soft prints both keep
(``stances.solve``'s ``history``). The search asks each stance from the parent it was
popped with; where its path reaches a stance through another parent (an answer found
earlier from another one, or a stance solved again for its motion), the stances from there
on are solved again from their predecessors here.
"""

from __future__ import annotations

import logging

import numpy as np

import stances
from environments.errors import SceneError
from fem.errors import FemError
from stances.errors import StanceError

__all__ = ["chained", "history_of", "slips_not_carried", "starts_where_left", "unkept_slips"]

logger = logging.getLogger(__name__)


def history_of(planned):
    """A planned stance's (or a stance check's) answer as the ``history`` of the stance after
    it (None where it holds no posture answer to start from)."""
    return planned.result if isinstance(planned.result, stances.PostureResult) else None


def starts_where_left(before, after) -> bool:
    """Whether planned stance ``after`` was solved from where ``before``'s answer left the soft
    prints they both keep (:func:`unkept_slips` finds nothing)."""
    return not unkept_slips(before, after)


def unkept_slips(before, after) -> list:
    """Each soft print planned stance ``after`` keeps from ``before`` whose solve did not start
    where ``before``'s answer left its link points (:func:`slips_not_carried` of their answers)."""
    return slips_not_carried(before.result, after.result, before.stance, after.stance)


def slips_not_carried(before, after, before_stance=None, after_stance=None, what="the stance before") -> list:
    """Each soft print posture answer ``after`` keeps from answer ``before`` whose solve did not
    start where ``before`` left its link points (``held_slips`` against ``slips``): under
    Coulomb friction the print would have slid between the two; and held slips of a print
    ``after`` did not keep. An answer that records no slips (None: a file before version 6,
    the stiff limit's spread answers) leaves the next one's prints at rest; a print ``after``
    records no slips of (held rigid, off the coulomb law) starts from none.

    Parameters
    ----------
    before, after : stances.PostureResult (or anything else: no slips)
    before_stance, after_stance : environments Stance, optional
        The stances they hold; by default the answers' own.
    what : str
        How the problems name ``before``.

    Returns
    -------
    list of str
        One line a print.
    """
    left = getattr(before, "slips", None)
    held = getattr(after, "held_slips", None) or {}
    read = getattr(after, "slips", None)
    kept = (set(getattr(before_stance or getattr(before, "stance", None), "contacts", ()))
            & set(getattr(after_stance or getattr(after, "stance", None), "contacts", ())))
    kept_surfaces = {contact.robot_surface for contact in kept}
    problems = [f"{surface}'s print starts from held slips although {what} "
                + ("records none" if left is None or surface not in left else "did not keep it")
                for surface in sorted(held) if surface not in kept_surfaces or left is None or surface not in left]
    for surface in sorted(kept_surfaces & set(left or {}) & set(held)):
        start, end = held[surface], left[surface]
        if not np.array_equal(start.nodes, end.nodes):
            problems.append(f"{surface}'s print starts from slips over other nodes than {what} left")
            continue
        off = np.linalg.norm(start.slips - end.slips, axis=1)
        if off.max(initial=0.0) > 1e-12:
            worst = int(np.argmax(off))
            problems.append(f"{surface}'s print starts {off[worst]:.3g} m off where {what} left it "
                            f"(node {int(start.nodes[worst])} of {start.body})")
    at_rest = kept_surfaces & set(left or {}) - set(held)
    if read is not None:
        at_rest &= set(read)  # the prints whose slips it keeps: those a solve starts from held ones
    problems.extend(f"{surface}'s print starts from rest, not where {what} left it "
                    f"(slips up to {left[surface].largest():.3g} m)"
                    for surface in sorted(at_rest))
    return problems


def chained(planned, scene, robot, solver_options=None, start=1):
    """``planned`` (PlannedStance, in order) with each stance from ``start`` on that did not
    start where the one before left its kept soft prints solved again from there, from its
    own posture, with the options its answer records (or ``solver_options``).

    Returns
    -------
    list of PlannedStance, or None
        None where such a stance then has no posture (the caller keeps its stances).
    """
    planned = list(planned)
    for index in range(max(start, 1), len(planned)):
        before, after = planned[index - 1], planned[index]
        if not isinstance(after.result, stances.PostureResult) or starts_where_left(before, after):
            continue
        options = dict(solver_options) if solver_options is not None else dict(
            (after.result.statistics or {}).get("options", {}))
        try:
            result = stances.solve(robot, scene, after.stance, q_init=after.q, history=history_of(before), **options)
        except (StanceError, SceneError, FemError) as error:
            logger.info("stance %d not solved again from the one before: %s", index, error)
            return None
        if not result.feasible:
            logger.info("stance %d has no posture from where the one before left its prints: %s", index,
                        result.reason)
            return None
        planned[index] = after.answered(result)
    return planned
