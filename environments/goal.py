"""What the planner must reach: contacts to make and regions to put robot surfaces in."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import SceneError
from .geometry import readonly_array, wrap_angle
from .stance import Contact, Stance

__all__ = ["GoalRegion", "Goal"]

ANGLE_WEIGHT = 0.1
"""Metres per radian when a goal contact is at the right place but the wrong angle
(about a foot's half length: turning a foot by 1 rad moves its toe that far)."""

WRONG_SURFACE_DISTANCE = 0.01
"""Metres added when a goal contact's print is on another surface than asked."""

_TOLERANCE = 1e-9  # metres or radians: float noise from grids and YAML round trips


@dataclass(frozen=True, eq=False)
class GoalRegion:
    """An axis-aligned xy box, world frame, that a robot surface's print origin must lie in.

    Parameters
    ----------
    robot_surface : str
        Robot contact surface, e.g. ``"left_sole"``.
    lower, upper : (2,) float
        Corners of the box, metres, world x and y; ``lower <= upper``.
    """

    robot_surface: str
    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.robot_surface, str) or not self.robot_surface:
            raise SceneError(f"GoalRegion.robot_surface must be a non-empty string, got {self.robot_surface!r}")
        lower = readonly_array(self.lower, (2,), "GoalRegion.lower")
        upper = readonly_array(self.upper, (2,), "GoalRegion.upper")
        if np.any(lower > upper):
            raise SceneError(f"GoalRegion lower {lower.tolist()} must be <= upper {upper.tolist()}")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    def __eq__(self, other) -> bool:
        if not isinstance(other, GoalRegion):
            return NotImplemented
        return (
            self.robot_surface == other.robot_surface
            and np.array_equal(self.lower, other.lower)
            and np.array_equal(self.upper, other.upper)
        )

    def __hash__(self) -> int:
        return hash((self.robot_surface, tuple(self.lower), tuple(self.upper)))

    def distance_xy(self, point_xy) -> float:
        """Euclidean distance from a world xy point to the box, metres (0 inside)."""
        point = np.asarray(point_xy, dtype=float)[:2]
        gap = np.maximum(0.0, np.maximum(self.lower - point, point - self.upper))
        distance = float(np.linalg.norm(gap))
        return 0.0 if distance <= _TOLERANCE else distance


@dataclass(frozen=True)
class Goal:
    """Goal of a plan: contacts to make and regions to reach.

    Parameters
    ----------
    contacts : tuple of Contact
        Each must be in the final stance (same robot surface, surface, x, y, theta).
    regions : tuple of GoalRegion
        For each, the stance must have a contact of that robot surface whose print
        origin, in the world, lies in the region's xy box.

    Examples
    --------
    >>> from environments import load
    >>> scenario = load("stand")
    >>> goal = Goal(regions=(GoalRegion("left_sole", (-0.1, 0.0), (0.1, 0.2)),))
    >>> goal.is_satisfied(scenario.stance("stand"), scenario.scene)
    True
    """

    contacts: tuple[Contact, ...] = ()
    regions: tuple[GoalRegion, ...] = ()

    def __post_init__(self) -> None:
        contacts, regions = tuple(self.contacts), tuple(self.regions)
        for contact in contacts:
            if not isinstance(contact, Contact):
                raise SceneError(f"Goal.contacts must be Contact, got {type(contact).__name__}")
        for region in regions:
            if not isinstance(region, GoalRegion):
                raise SceneError(f"Goal.regions must be GoalRegion, got {type(region).__name__}")
        # A stance holds one contact per robot surface, so two goal contacts on one
        # robot surface could never be met together.
        Stance(contacts)
        object.__setattr__(self, "contacts", contacts)
        object.__setattr__(self, "regions", regions)

    def _contact_distance(self, goal_contact: Contact, stance: Stance, scene) -> float:
        target = scene.print_origin_in_world(goal_contact)
        if not stance.has(goal_contact.robot_surface):
            # Missing: at least as far as the nearest current contact, and never 0.
            nearest = min(
                (float(np.linalg.norm(scene.print_origin_in_world(c) - target)) for c in stance),
                default=0.0,
            )
            return nearest + WRONG_SURFACE_DISTANCE
        have = stance.contact(goal_contact.robot_surface).contact_print
        want = goal_contact.contact_print
        distance = float(np.linalg.norm(scene.print_origin_in_world(have) - target))
        distance = 0.0 if distance <= _TOLERANCE else distance
        angle = abs(wrap_angle(have.theta - want.theta))
        distance += 0.0 if angle <= _TOLERANCE else ANGLE_WEIGHT * angle
        if have.surface != want.surface:
            distance += WRONG_SURFACE_DISTANCE
        return distance

    def _region_distance(self, region: GoalRegion, stance: Stance, scene) -> float:
        if stance.has(region.robot_surface):
            return region.distance_xy(scene.print_origin_in_world(stance.contact(region.robot_surface)))
        nearest = min(
            (region.distance_xy(scene.print_origin_in_world(c)) for c in stance),
            default=0.0,
        )
        return nearest + WRONG_SURFACE_DISTANCE

    def distances(self, stance: Stance, scene) -> tuple[float, ...]:
        """Distance of each goal item (contacts, then regions), metres, >= 0, 0 iff met."""
        return tuple(self._contact_distance(c, stance, scene) for c in self.contacts) + tuple(
            self._region_distance(r, stance, scene) for r in self.regions
        )

    def distance(self, stance: Stance, scene) -> float:
        """Heuristic distance of a stance to the goal, metres, >= 0, 0 iff satisfied.

        The sum over goal items of how far the robot surface's print origin is
        from its target (world frame), plus ``ANGLE_WEIGHT`` per radian of
        heading error and ``WRONG_SURFACE_DISTANCE`` for a print on another
        surface or a robot surface not in contact (then measured from the nearest
        current contact).

        Parameters
        ----------
        stance : Stance
            Candidate stance.
        scene : Scene
            The scene its prints refer to.
        """
        return math.fsum(self.distances(stance, scene))

    def is_satisfied(self, stance: Stance, scene) -> bool:
        """Whether every goal contact is in the stance and every region is reached."""
        return all(d == 0.0 for d in self.distances(stance, scene))
