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
from dataclasses import replace

import numpy as np

import stances
from environments.errors import SceneError
from fem.errors import FemError
from stances.errors import StanceError

__all__ = ["chained", "history_of", "starts_where_left"]

logger = logging.getLogger(__name__)


def history_of(planned):
    """A planned stance's answer as the ``history`` of the stance after it (None where the
    plan holds no answer to start from)."""
    return planned.result if isinstance(planned.result, stances.PostureResult) else None


def starts_where_left(before, after) -> bool:
    """Whether planned stance ``after`` was solved from where ``before``'s answer left the soft
    prints they both keep (its ``held_slips`` exactly those :func:`stances.kept_slips` gives)."""
    history = history_of(before)
    wanted = {} if history is None else stances.kept_slips(history, after.stance)
    held = getattr(after.result, "held_slips", None) or {}
    if set(held) != set(wanted):
        return False
    return all(np.array_equal(held[s].nodes, wanted[s].nodes) and np.array_equal(held[s].slips, wanted[s].slips)
               for s in held)


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
        planned[index] = replace(after, q=result.q, point_forces=tuple(result.point_forces),
                                 deformations=dict(result.deformations or {}), result=result)
    return planned
