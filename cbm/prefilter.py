"""The cheap checks a stance passes before its posture solve, in order.

Each check is a necessary condition of feasibility (it rejects only stances no
posture solve could accept) that costs milliseconds where a solve costs
seconds: :mod:`cbm.print_collision` (links fixed by rigid prints sink into the
scene or into each other) and :mod:`cbm.equilibrium` (no contact forces in the
friction cones balance the robot's weight). The reach of the prints and the
overlap of two feet are already pruned when neighbours are generated
(:meth:`cbm.reach.ReachModel.reachable_mask`); two soft prints sharing mesh
nodes are refused by :func:`stances.solve` before its SQP.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from .equilibrium import EquilibriumFilter
from .print_collision import PrintCollisionFilter

__all__ = ["Prefilter", "Rejection", "FILTERS"]

#: Names of the checks, in the order they run (``StanceCheck.rejected_by``).
FILTERS = ("print collision", "static equilibrium")


@dataclass(frozen=True)
class Rejection:
    """A stance refused before solving.

    Parameters
    ----------
    rejected_by : str
        The check's name, one of :data:`FILTERS`.
    reason : str
        Why, in words (classified by :func:`cbm.rejections.cause_of`).
    """

    rejected_by: str
    reason: str


class Prefilter:
    """Runs the cheap checks on a stance; built once per robot, scene and solver options.

    Parameters
    ----------
    robot : stances Robot
    scene : environments Scene
    solver_options : dict, optional
        Keyword arguments of ``stances.solve`` (they shape the checks).
    """

    def __init__(self, robot, scene, solver_options=None):
        from stances.problem import PostureOptions

        # The solve's other keyword arguments (time_budget, constraints) do not shape the checks.
        names = {f.name for f in fields(PostureOptions)}
        options = PostureOptions(**{k: v for k, v in dict(solver_options or {}).items() if k in names})
        self.checks = (
            (FILTERS[0], PrintCollisionFilter(robot, scene, options)),
            (FILTERS[1], EquilibriumFilter(robot, scene, options)),
        )

    def __call__(self, stance):
        """The first check's :class:`Rejection` of ``stance``, or None if every check passes.

        Raises
        ------
        environments.SceneError, stances.StanceError
            For a malformed stance (unknown surfaces), as ``stances.solve`` would.
        """
        for name, check in self.checks:
            reason = check(stance)
            if reason:
                return Rejection(name, reason)
        return None
