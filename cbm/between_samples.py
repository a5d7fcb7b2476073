"""The joint-space interpolation between two motion samples: its collisions and the strays of
its held contacts.

A motion (:mod:`cbm.motion`) is a sequence of verified postures; a replay goes from one to
the next along ``pinocchio.interpolate`` (the joints linearly, the free flyer along the
SE(3) screw motion between its placements). :class:`BetweenSamples` checks that path at
:data:`BETWEEN`: no collision deeper than the verifier's tolerance, and every held contact
within :data:`HELD_DRIFT` of the straight line between where the two samples put it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import stances
from stances.collision import contact_exclusions
from stances.problem import stance_collision_checker
from stances.verify import VerificationTolerances

from .errors import MotionError

__all__ = ["BETWEEN", "HELD_DRIFT", "BetweenSamples", "checked_drift"]

#: Where the postures between two consecutive samples (joint-space interpolation,
#: ``pin.interpolate``) are checked for collisions and held contacts' strays: 7 points,
#: every 1/8 (a stray peaks halfway: a grid of 99 points found at most 1e-4 mm more).
BETWEEN = np.arange(1, 8) / 8

#: Metres: how far a held contact's point (a polygon's vertex, a point foot's centre) may
#: stray, at the postures interpolated between two samples (:data:`BETWEEN`), from the
#: straight line between where the two samples put it. The samples hold their contacts;
#: the joint-space interpolation between them holds nothing, and on seven built-in plans
#: it carried held contacts up to 24 mm off their line (climb-with-soft-support's palm;
#: cross-soft-block's soles 6.6 mm). A step beyond the bound gets a sample halfway, as a
#: colliding one does: the stray shrinks about fourfold with each halving (it is the
#: path's curvature times the step squared). The bound holds for ``pin.interpolate``
#: (the free flyer on SE(3)); a replay interpolating the base's position and orientation
#: apart strays more (up to 2.6 mm on the same steps).
HELD_DRIFT = 1e-3


class BetweenSamples:
    """The postures interpolated between two samples of a motion: their collisions and how
    far they carry the held contacts off their line.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments Scene
    support : environments Stance
        The contacts the motion holds throughout: their geometry may touch their
        supports, as in a posture of that stance, and their surfaces must stay on
        their lines.
    moving : environments Contact
        The contact the motion adds or removes: its geometry may sink into its
        print's object as deep as at the step's ends; held at both ends of a step,
        it must stay on its line too.
    options : dict
        Posture options (:class:`stances.PostureOptions`) the collision checker is built with.
    held_drift : float, optional
        Metres, the bound of :meth:`first_problem` (default :data:`HELD_DRIFT`).
    """

    def __init__(self, robot, scene, support, moving, options, held_drift=None):
        self.model = robot.model
        self.data = robot.model.createData()
        self.checker = stance_collision_checker(robot, scene, support, stances.PostureOptions(**options))
        print_object = scene.surface(moving.contact_print.surface).object_name
        self.moving = set(contact_exclusions(robot, moving.robot_surface, print_object))
        self.tolerance = VerificationTolerances().penetration
        self.held_drift = HELD_DRIFT if held_drift is None else checked_drift(held_drift)
        # The points of each contact surface that must stay put: a polygon's vertices (they
        # see a turn as well as a slide), a point foot's centre.
        surfaces = [robot.surface(contact.robot_surface) for contact in support.contacts]
        self.support_points = [_surface_points(self.model, surface) for surface in surfaces]
        self.moving_points = _surface_points(self.model, robot.surface(moving.robot_surface))

    def _points(self, q, held):
        """(k, 3) world positions of the held surfaces' points at posture ``q`` (forward
        kinematics already run for ``q``), and the surface each belongs to."""
        placed, names = [], []
        for name, frame, points in self.support_points + ([self.moving_points] if held else []):
            placement = pin.updateFramePlacement(self.model, self.data, frame)
            placed.append(points @ placement.rotation.T + placement.translation)
            names += [name] * len(points)
        return np.vstack(placed), names

    def largest_drift(self, q0, q1, held=False):
        """``(t, surface, metres)``: the largest distance, over the postures interpolated
        between ``q0`` and ``q1`` (:data:`BETWEEN`), of a held contact's point from the
        straight line between where it is at ``q0`` and at ``q1``; ``held``: the moving
        contact is held at both ends, and checked too. ``(0, "", 0)`` without held contacts."""
        if not self.support_points and not held:
            return 0.0, "", 0.0
        ends = []
        for q in (q0, q1):
            pin.forwardKinematics(self.model, self.data, q)
            ends.append(self._points(q, held)[0])
        worst = (0.0, "", 0.0)
        for t in BETWEEN:
            q = pin.interpolate(self.model, q0, q1, float(t))
            pin.forwardKinematics(self.model, self.data, q)
            points, names = self._points(q, held)
            drift = np.linalg.norm(points - ((1.0 - t) * ends[0] + t * ends[1]), axis=1)
            k = int(np.argmax(drift))
            if drift[k] > worst[2]:
                worst = (float(t), names[k], float(drift[k]))
        return worst

    def first_problem(self, q0, q1, held=False):
        """What makes the step from ``q0`` to ``q1`` unusable, or None: ``("collision",
        words)`` (:meth:`first_collision`), else ``("drift", words)`` for a held contact
        straying more than the drift bound (:meth:`largest_drift`)."""
        hit = self.first_collision(q0, q1, held)
        if hit is not None:
            t, pair, depth = hit
            # The first one found can be a graze on the way into a deep one (romeo's wrist:
            # 0.87 mm at 1/8 of a step, 12.8 mm halfway): say how deep the step goes too.
            deepest_t, deepest_pair, deepest = max(self._collisions(q0, q1, held), key=lambda found: found[2], default=hit)
            worst = "" if deepest <= depth else (
                f"; deepest {deepest:.3g} m at {deepest_t:g} of the way, between {deepest_pair.name_a} "
                f"and {deepest_pair.name_b}")
            return "collision", (f"at {t:g} of the way: collision between {pair.name_a} and {pair.name_b} "
                                 f"(depth {depth:.3g} m{worst})")
        t, name, drift = self.largest_drift(q0, q1, held)
        if drift > self.held_drift:
            return "drift", (f"at {t:g} of the way: the held {name} strays {drift:.3g} m off its line "
                             f"(bound {self.held_drift:g} m)")
        return None

    def _pairs(self, q):
        pin.forwardKinematics(self.model, self.data, q)
        return self.checker.pairs(self.model, self.data)

    def first_collision(self, q0, q1, held=False):
        """``(t, pair, depth)`` of the first interpolated posture deeper than the tolerance, or None.

        The moving contact geometry and its print's object may overlap as deep as
        their depths at the two ends, interpolated at ``t`` (a limb resting on a soft
        print sinks into it; deeper on the way is a collision). ``held``: both ends
        hold the moving contact; its geometry and its print's object are then not
        checked, as for the support's contacts: the joint-space interpolation holds no
        contact exactly, and :meth:`largest_drift` bounds how far it strays from its line
        (on a rigid print, how deep its geometry may dip).
        """
        return next(self._collisions(q0, q1, held), None)

    def _collisions(self, q0, q1, held):
        """``(t, pair, depth)`` of every pair deeper than the tolerance at the postures
        interpolated between ``q0`` and ``q1``, in the order of :data:`BETWEEN` (see
        :meth:`first_collision`)."""
        ends = [{(p.name_a, p.name_b): max(-p.distance, 0.0) for p in self._pairs(q)
                 if (p.name_a, p.name_b) in self.moving} for q in (q0, q1)]
        for t in BETWEEN:
            for pair in self._pairs(pin.interpolate(self.model, q0, q1, float(t))):
                key = (pair.name_a, pair.name_b)
                if held and key in self.moving:
                    continue
                allowed = (1.0 - t) * ends[0].get(key, 0.0) + t * ends[1].get(key, 0.0)
                depth = -pair.distance - allowed
                if depth > self.tolerance:
                    yield float(t), pair, depth


def _surface_points(model, surface):
    """``(name, frame id, (k, 3) points in the contact frame)`` of a robot surface: a
    polygon's vertices, a point foot's centre."""
    points = np.zeros((1, 3)) if surface.is_point else surface.vertices_in_frame
    return surface.name, model.getFrameId(surface.frame), points


def checked_drift(value) -> float:
    """``value`` as a positive finite distance in metres, or a MotionError naming it."""
    try:
        drift = np.nan if isinstance(value, bool) else float(value)  # True would read as 1 m
    except (TypeError, ValueError):
        drift = np.nan
    if not (np.isfinite(drift) and drift > 0.0):
        raise MotionError(f"held_drift must be a positive distance in metres (default {HELD_DRIFT:g}), got {value!r}")
    return drift
