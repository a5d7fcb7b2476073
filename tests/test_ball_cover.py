"""A collision cylinder that ends inside a point foot's ball is trimmed to where it leaves the
ball, and the robot's shape stays the same: what is cut off lies in the ball."""

from __future__ import annotations

import math

import coal
import numpy as np
import pinocchio as pin
import pytest

import environments
from environments import Contact, ContactPrint, Stance
from stances import solve
from stances.ball_cover import covered_span, trim_into_balls, trimmed_span

BALL = 0.031  # ANYmal B's foot, metres
ADAPTER = 0.015  # its adapter cylinder's radius
BALL_CENTRE = np.array([0.0, 0.0, -0.298])  # in the knee's frame, as the URDF has it
ADAPTER_HALF = 0.160625  # the adapter runs from the knee (z = 0) down to z = -0.32125


def test_a_coaxial_cylinder_lies_in_the_ball_where_its_rim_does():
    low, high = covered_span(ADAPTER, np.array([0.0, 0.0, -0.1]), BALL)
    half = math.sqrt(BALL**2 - ADAPTER**2)  # the rim (15 mm out) on the sphere
    assert (low, high) == pytest.approx((-0.1 - half, -0.1 + half), abs=1e-15)


def test_an_off_axis_centre_narrows_the_span_and_one_too_far_out_gives_none():
    _, high = covered_span(ADAPTER, np.array([0.01, 0.0, 0.0]), BALL)
    assert high == pytest.approx(math.sqrt(BALL**2 - (ADAPTER + 0.01) ** 2), rel=1e-12)
    assert covered_span(ADAPTER, np.array([0.0, 0.02, 0.0]), BALL) is None  # rim 35 mm out


@pytest.mark.parametrize("covered, expected", [
    ((-0.2, -0.12), (-0.12, 0.16)),  # the lower end in the ball: cut up to where it leaves
    ((0.12, 0.2), (-0.16, 0.12)),  # the upper end
    ((-0.2, 0.2), None),  # the whole cylinder in the ball: left (the ball holds it)
    ((-0.05, 0.05), None),  # passing through the ball: left
    (None, None),  # no cross-section fits
])
def test_only_a_cylinder_with_one_end_in_the_ball_is_trimmed(covered, expected):
    assert trimmed_span(0.16, covered) == expected


def _leg():
    """A knee joint holding ANYmal's adapter and foot ball, a cylinder crossing the ball,
    and an adapter on another joint."""
    model = pin.Model()
    knee = model.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "knee")
    other = model.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "other")
    geometry = pin.GeometryModel()
    at = lambda z: pin.SE3(np.eye(3), np.array([0.0, 0.0, z]))  # noqa: E731
    geometry.addGeometryObject(pin.GeometryObject("adapter", knee, at(-ADAPTER_HALF), coal.Cylinder(ADAPTER, 2 * ADAPTER_HALF)))
    geometry.addGeometryObject(pin.GeometryObject("ball", knee, at(BALL_CENTRE[2]), coal.Sphere(BALL)))
    geometry.addGeometryObject(pin.GeometryObject("through", knee, at(BALL_CENTRE[2]), coal.Cylinder(0.005, 0.2)))
    geometry.addGeometryObject(pin.GeometryObject("elsewhere", other, at(-ADAPTER_HALF), coal.Cylinder(ADAPTER, 2 * ADAPTER_HALF)))
    return geometry


def test_the_adapter_ends_where_it_leaves_the_ball_and_nothing_else_changes():
    geometry = _leg()
    before = {g.name: (g.geometry, g.placement.copy()) for g in geometry.geometryObjects}
    trimmed = trim_into_balls(geometry, [("ball",)])
    leaves = BALL_CENTRE[2] + math.sqrt(BALL**2 - ADAPTER**2)  # -0.2709 m
    assert trimmed == [("adapter", pytest.approx(leaves + 2 * ADAPTER_HALF, abs=1e-15))]
    adapter = geometry.geometryObjects[geometry.getGeometryId("adapter")]
    top = adapter.placement.translation[2] + adapter.geometry.halfLength
    bottom = adapter.placement.translation[2] - adapter.geometry.halfLength
    assert (top, bottom) == pytest.approx((0.0, leaves), abs=1e-15)
    assert adapter.geometry.radius == ADAPTER
    for name in ("ball", "through", "elsewhere"):
        g = geometry.geometryObjects[geometry.getGeometryId(name)]
        assert g.geometry is before[name][0] and g.placement == before[name][1]


def test_a_foot_without_a_collision_sphere_trims_nothing():
    """The ball is the foot's own sphere in the collision model, never a declared radius."""
    geometry = _leg()
    assert trim_into_balls(geometry, [("adapter",), ("no such geometry",)]) == []
    adapter = geometry.geometryObjects[geometry.getGeometryId("adapter")]
    assert adapter.geometry.halfLength == ADAPTER_HALF


def test_what_is_cut_off_lies_in_the_ball():
    geometry = _leg()
    trim_into_balls(geometry, [("ball",)])
    adapter = geometry.geometryObjects[geometry.getGeometryId("adapter")]
    bottom = adapter.placement.translation[2] - adapter.geometry.halfLength
    # The rim of every cross-section of the part cut off, from the old end to the new one.
    heights = np.linspace(-2 * ADAPTER_HALF, bottom, 50)
    height, angle = np.meshgrid(heights, np.linspace(0.0, 2 * np.pi, 36, endpoint=False))
    rim = np.stack([ADAPTER * np.cos(angle), ADAPTER * np.sin(angle), height], axis=-1).reshape(-1, 3)
    assert np.linalg.norm(rim - BALL_CENTRE, axis=1).max() <= BALL * (1 + 1e-12)
    # ... and the cylinder left starts where its rim leaves the ball.
    assert math.hypot(ADAPTER, bottom - BALL_CENTRE[2]) == pytest.approx(BALL, rel=1e-12)


def test_anymals_adapters_end_where_they_leave_its_balls(anymal):
    for leg in ("LF", "RF", "LH", "RH"):
        adapter = anymal.collision_model.geometryObjects[anymal.collision_model.getGeometryId(f"{leg}_ADAPTER_0")]
        ball = anymal.collision_model.geometryObjects[anymal.collision_model.getGeometryId(f"{leg}_FOOT_0")]
        axis = adapter.placement.rotation[:, 2]
        end = adapter.placement.translation - axis * adapter.geometry.halfLength
        # The end nearest the ball, 27.1 mm from its centre along the shank: where the 15 mm
        # rim meets the 31 mm sphere (the URDF's end, 7.75 mm above the ball's bottom, inside it).
        along = float(axis @ (end - ball.placement.translation))
        assert abs(along) == pytest.approx(math.sqrt(BALL**2 - ADAPTER**2), rel=1e-9)


# A quadruped-foam planner stance (seed 1, 2026-12-04) refused from both starts while the
# adapters' ends, inside the balls, kept 5 mm from the foam and the floor: the conflict named
# RF_ADAPTER_0 and LF_ADAPTER_0 against the foam with both front feet's placements.
_FRONT_FEET_ON_FOAM = Stance((
    Contact("left_front_foot", ContactPrint("foam_top", -0.1, 0.3)),
    Contact("left_hind_foot", ContactPrint("floor", -0.1, 0.2)),
    Contact("right_front_foot", ContactPrint("foam_top", -0.1, -0.1)),
    Contact("right_hind_foot", ContactPrint("floor", -0.1, 0.0)),
))


def test_a_stance_the_adapters_inside_the_balls_refused_solves(anymal):
    result = solve(anymal, environments.load("quadruped-foam").scene, _FRONT_FEET_ON_FOAM)
    assert result.feasible, result.reason
    assert result.verification.ok
