"""Neighbours of a stance: add one contact or remove one, keeping the robot's support."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from environments.stance import Contact, ContactPrint

from .sampling import contacts_in_world

__all__ = ["Move", "StanceNeighbours", "differ_by_one_contact"]


@dataclass(frozen=True)
class Move:
    """A transition between two stances.

    Parameters
    ----------
    kind : str
        ``"add"`` or ``"remove"``.
    robot_surface : str
        Robot surface that makes or breaks contact.
    contact_print : ContactPrint or None
        Print reached, for an ``"add"``.
    """

    kind: str
    robot_surface: str
    contact_print: ContactPrint | None = None

    def __str__(self):
        if self.kind == "remove":
            return f"lift {self.robot_surface}"
        p = self.contact_print
        # Spelled out: bare "(x, y, theta)" reads like a world point in radians.
        return (
            f"place {self.robot_surface} on {p.surface} at x {p.x:.3f} m, y {p.y:.3f} m, "
            f"theta {math.degrees(p.theta):.0f} deg in {p.surface}'s frame"
        )


class StanceNeighbours:
    """Callable giving the candidate neighbours of a stance (no solve).

    Parameters
    ----------
    print_sets : dict of str to sampling.PrintSet
        Candidate prints per robot surface.
    surfaces : mapping of str to ContactSurface
        The scene's surfaces (to place the stance's prints in the world).
    reach : cbm.reach.ReachModel
        The robot's reach and support rule.
    required : iterable of environments Contact, optional
        The goal's own contacts: a hand's print among them stays a candidate, and a
        hand holding one is not asked to stay within reach when feet move, even
        where the reach model would prune. The model measures an arm from its
        shoulder at the reference posture and a leaning torso reaches farther
        (the palms of hand-on-table and foot-and-hand-on-foam lie 0.69 m from that
        shoulder, past the model's 0.66 m): without this, those goals could never
        be generated. A foot's print among them stays a candidate once the
        goal's other feet stand on their own goal prints: the last step into
        the goal's footing is always offered, even where the step rules would
        prune it (the step height, 0.37 leg lengths, is 0.18 m for iCub's
        0.48 m legs, and iCub holds foot-on-block's 0.2 m block). The posture
        solve decides.
    forbidden : iterable of (Stance, Stance), optional
        Transitions never offered, ``(stance, neighbour)``: steps an earlier plan
        took that no quasi-static motion joins (:func:`cbm.replan.plan_with_motions`).

    Notes
    -----
    A stance keeps the robot's support (a biped: a foot in contact): lifting
    a surface that would break it is not a neighbour. Added prints must pass
    :meth:`cbm.reach.ReachModel.reachable_mask`.
    """

    def __init__(self, print_sets, surfaces, reach, required=(), forbidden=()):
        self.print_sets = dict(print_sets)
        self.forbidden = frozenset(forbidden)
        self.surfaces = surfaces
        self.reach = reach
        # Hands' (robot surface, print) pairs the reach model leaves alone, and
        # their indices in the print sets (found once: the sets hold thousands).
        required = tuple(required)
        self.required = {
            (c.robot_surface, c.contact_print) for c in required if reach.roles.get(c.robot_surface) != reach.support_role
        }
        self.required_indices = self._indices(self.required)
        # The goal's feet: each one's print, a candidate once the others stand on theirs.
        self.goal_feet = {
            (c.robot_surface, c.contact_print) for c in required if reach.roles.get(c.robot_surface) == reach.support_role
        }
        self.goal_feet_indices = self._indices(self.goal_feet)
        self.pruned = 0  # candidate prints removed by reach pruning so far

    def _indices(self, contacts):
        """Robot surface -> indices of the given (robot surface, print) pairs in its print set."""
        indices = {}
        for robot_surface, contact_print in contacts:
            prints = self.print_sets[robot_surface].prints if robot_surface in self.print_sets else ()
            if contact_print in prints:
                indices.setdefault(robot_surface, []).append(prints.index(contact_print))
        return indices

    def _on_goal_footing(self, stance, robot_surface):
        """Whether the goal has other feet than ``robot_surface`` and each stands on its goal print in ``stance``."""
        others = [pair for pair in self.goal_feet if pair[0] != robot_surface]
        in_stance = {(c.robot_surface, c.contact_print) for c in stance}
        return bool(others) and all(pair in in_stance for pair in others)

    def __call__(self, stance):
        """List ``(neighbour stance, Move)`` pairs: removals first, then additions."""
        result = []
        in_contact = stance.robot_surfaces
        for robot_surface in in_contact:
            if not self.reach.may_lift(robot_surface, in_contact):
                continue
            result.append((stance.without(robot_surface), Move("remove", robot_surface)))
        placed = contacts_in_world(stance, self.surfaces)
        for robot_surface in sorted(self.print_sets):
            if robot_surface not in in_contact:
                result.extend(self.additions(stance, robot_surface, placed))
        if self.forbidden:
            result = [(child, move) for child, move in result if (stance, child) not in self.forbidden]
        return result

    def additions(self, stance, robot_surface, placed=None):
        """List ``(stance + one contact of robot_surface, Move)`` for every reachable print.

        Parameters
        ----------
        stance : environments Stance
            Without ``robot_surface``.
        robot_surface : str
            Robot surface to place.
        placed : dict, optional
            :func:`cbm.sampling.contacts_in_world` of ``stance``, if known.
        """
        if placed is None:
            placed = contacts_in_world(stance, self.surfaces)
        print_set = self.print_sets[robot_surface]
        # A hand on a required print is not asked to stay within the model's reach.
        held = {c.robot_surface for c in stance if (c.robot_surface, c.contact_print) in self.required}
        mask = self.reach.reachable_mask(print_set, {rs: p for rs, p in placed.items() if rs not in held})
        if any(self.reach.roles.get(rs) == self.reach.support_role for rs in placed):
            mask[self.required_indices.get(robot_surface, [])] = True
            if robot_surface in self.goal_feet_indices and self._on_goal_footing(stance, robot_surface):
                mask[self.goal_feet_indices[robot_surface]] = True
        self.pruned += int(len(mask) - np.count_nonzero(mask))
        return [
            (
                stance.with_contact(Contact(robot_surface, print_set.prints[index])),
                Move("add", robot_surface, print_set.prints[index]),
            )
            for index in np.flatnonzero(mask)
        ]


def differ_by_one_contact(first, second):
    """Whether two stances differ by exactly one contact added or removed.

    Parameters
    ----------
    first, second : environments Stance

    Returns
    -------
    bool
    """
    a, b = set(first.contacts), set(second.contacts)
    return len(a ^ b) == 1
