"""Collision cylinders that end inside a point foot's ball, trimmed to where they leave it.

A point foot is a ball (:class:`stances.description.SurfaceDeclaration` with a radius); the
ball is the foot's contact geometry, allowed to touch and sink into its support. A robot's
collision model often runs the shank's or adapter's cylinder down into that ball: ANYmal B's
adapters (15 mm in radius) end 7.75 mm above the ball's lowest point, inside the 31 mm ball.
That end is no surface of the robot, the ball covers it, but as a geometry of its own it
kept the solver's 5 mm collision distance from the very support the ball stands on: a ball
could sink at most 2.75 mm into foam with its shank upright, and its shank tilt about 13
degrees on a rigid floor, before its own adapter "collided" (14 of the 20 failed warm
attempts of quadruped-foam's plans over 10 seeds named an adapter and a support in their
conflict, 2026-12-04).

The part cut off lies inside the ball, so the robot's shape (the union of its geometries)
is unchanged: against anything but the ball's own support the ball's distance is never more
than that part's. Only cylinders on the ball's own joint (rigidly attached to it) whose
end cap lies inside the ball are trimmed; a cylinder the ball does not reach, or that passes
through it, is left as it is. The ball is the foot's own collision sphere, never the radius
its description declares. One thing does change: the pairs checked. A self-collision pair
the SRDF enables for the cylinder but disables for the ball (ANYmal's hips against its feet)
no longer checks the part cut off.
"""

from __future__ import annotations

import logging
import math

import coal

logger = logging.getLogger(__name__)

__all__ = ["trim_into_balls"]


def covered_span(radius, offset, ball_radius):
    """The part of a cylinder's axis along which its whole cross-section lies in a ball.

    Parameters
    ----------
    radius : float
        The cylinder's, metres; its axis is z.
    offset : (3,) float
        The ball's centre in the cylinder's frame (its axis along z), metres.
    ball_radius : float
        Metres.

    Returns
    -------
    (float, float) or None
        ``(low, high)`` axial coordinates between which every point of the cylinder lies in
        the ball (a point at axial ``t`` is at most ``sqrt((t - z_c)^2 + (r + d)^2)`` from the
        centre, ``d`` the centre's distance from the axis); None when no cross-section fits.
    """
    reach = radius + math.hypot(offset[0], offset[1])
    if reach >= ball_radius:
        return None
    half = math.sqrt(ball_radius * ball_radius - reach * reach)
    return offset[2] - half, offset[2] + half


def trimmed_span(half_length, covered):
    """The axial span ``(low, high)`` of a cylinder left once the end inside ``covered`` is
    cut off, or None to leave it as it is (no end inside, or both: the ball holds it whole,
    or the cylinder passes through the ball)."""
    if covered is None:
        return None
    low_in = covered[0] <= -half_length <= covered[1]
    high_in = covered[0] <= half_length <= covered[1]
    if low_in == high_in:
        return None
    return (covered[1], half_length) if low_in else (-half_length, covered[0])


def trim_into_balls(collision_model, feet) -> list:
    """Trim, in place, the collision cylinders whose end lies inside a foot's ball.

    The balls are the feet's own collision spheres, as the collision model has them (a
    declared radius is not trusted: a foot without a sphere trims nothing).

    Parameters
    ----------
    collision_model : pinocchio.GeometryModel
    feet : iterable of iterable of str
        Per point foot, its contact geometries' names; those that are spheres are its
        balls (never trimmed themselves).

    Returns
    -------
    list of (str, float)
        The trimmed geometries and the length cut off each, metres (also logged).
    """
    by_name = {geometry.name: geometry for geometry in collision_model.geometryObjects}
    trimmed = []
    for own in feet:
        own = set(own)
        for name in sorted(own):
            ball = by_name.get(name)
            if ball is None or not isinstance(ball.geometry, coal.Sphere):
                continue
            centre, ball_radius = ball.placement.translation, float(ball.geometry.radius)
            for geometry in collision_model.geometryObjects:
                shape = geometry.geometry
                if (geometry.parentJoint != ball.parentJoint or geometry.name in own
                        or not isinstance(shape, coal.Cylinder)):
                    continue
                placement = geometry.placement
                offset = placement.rotation.T @ (centre - placement.translation)
                span = trimmed_span(shape.halfLength, covered_span(shape.radius, offset, ball_radius))
                if span is None:
                    continue
                low, high = span
                geometry.geometry = coal.Cylinder(shape.radius, high - low)
                placement.translation = placement.translation + placement.rotation[:, 2] * (0.5 * (low + high))
                geometry.placement = placement
                trimmed.append((geometry.name, 2.0 * shape.halfLength - (high - low)))
    if trimmed:
        logger.info("collision cylinders trimmed to where they leave a foot's ball: %s",
                    ", ".join(f"{name} by {cut * 1e3:.2f} mm" for name, cut in trimmed))
    return trimmed
