"""Tests of stances.collision: distances, witness points, normals and linearisation rows."""

from __future__ import annotations

from operator import attrgetter

import coal
import numpy as np
import pinocchio as pin
import pytest

from environments.geometry import CollisionShape
from stances import Robot, StanceError
from stances.collision import (
    CollisionChecker,
    CollisionSetupError,
    contact_exclusions,
)

FEET = {"leg_left_6_link_0", "leg_right_6_link_0"}
# Curved primitives: GJK stops at its tolerance on them (about 1e-9 m here),
# which a 1e-6 finite-difference step would amplify to 1e-3; polytope pairs
# (convex hulls, boxes) are computed exactly and are used for the FD check.
CURVED = {
    "wrist_left_ft_link_0",
    "wrist_left_ft_tool_link_0",
    "wrist_right_ft_link_0",
    "wrist_right_ft_tool_link_0",
}


@pytest.fixture(scope="module")
def robot():
    return Robot.load("talos")


def box(size, center, rotation=np.eye(3)):
    """A box scene shape of sides ``size`` centred at ``center``, metres, world frame."""
    box_to_world = np.eye(4)
    box_to_world[:3, :3], box_to_world[:3, 3] = rotation, center
    return CollisionShape(box_to_world, box_size=size)


@pytest.fixture(scope="module")
def floor():
    """A 10 m x 10 m slab whose top face is the plane z = 0."""
    return box((10.0, 10.0, 0.1), (0.0, 0.0, -0.05))


@pytest.fixture(scope="module")
def feet_on_floor(robot):
    return contact_exclusions(robot, "left_sole", "floor") + contact_exclusions(
        robot, "right_sole", "floor"
    )


@pytest.fixture
def data(robot):
    return robot.model.createData()


def placed_at(robot, data, q):
    pin.forwardKinematics(robot.model, data, q)
    return data


def by_names(pairs):
    return {(pair.name_a, pair.name_b): pair for pair in pairs}


def geometry_to_world(robot, data, name):
    geometry = robot.collision_model.geometryObjects[robot.collision_model.getGeometryId(name)]
    return data.oMi[geometry.parentJoint] * geometry.placement, geometry


def test_reference_posture_has_no_self_collision(robot, floor, data):
    checker = CollisionChecker(robot, [("floor", floor)], margin=10.0)
    pairs = checker.pairs(robot.model, placed_at(robot, data, robot.reference_configuration))
    self_pairs = [pair for pair in pairs if pair.is_self_collision]
    assert len(self_pairs) == len(robot.collision_model.collisionPairs)
    assert min(pair.distance for pair in self_pairs) > 0.0


def test_floor_is_touched_only_by_the_feet(robot, floor, feet_on_floor, data):
    q = robot.reference_configuration
    everything = CollisionChecker(robot, [("floor", floor)], margin=10.0, self_collision=False)
    floor_pairs = everything.pairs(robot.model, placed_at(robot, data, q))
    # The sole meshes sit on z = 0 (within the half-sitting posture's 1 mm).
    touching = {pair.name_a for pair in floor_pairs if pair.distance < 2e-3}
    assert touching == FEET
    assert min(p.distance for p in floor_pairs if p.name_a not in FEET) > 0.02

    excluded = CollisionChecker(robot, [("floor", floor)], exclude=feet_on_floor)
    reported = excluded.pairs(robot.model, data)
    assert not [pair for pair in reported if pair.name_b == "floor"]
    assert all(pair.distance > 0.0 for pair in reported)


def test_contact_exclusions_designate_the_foot_and_optionally_the_ankle(robot):
    assert contact_exclusions(robot, "left_sole", "floor") == [("leg_left_6_link_0", "floor")]
    with_ankle = contact_exclusions(robot, "right_sole_contact", "floor", include_parent_joint=True)
    assert sorted(with_ankle) == [("leg_right_5_link_0", "floor"), ("leg_right_6_link_0", "floor")]


@pytest.mark.parametrize(
    "key", ["leg_left_6_link_0", "leg_left_6_joint", "leg_left_6_link", 7], ids=str
)
def test_excluded_pairs_are_never_reported(robot, floor, data, key):
    checker = CollisionChecker(robot, [("floor", floor)], margin=10.0, exclude=[(key, "floor")])
    pairs = by_names(checker.pairs(robot.model, placed_at(robot, data, robot.reference_configuration)))
    assert ("leg_left_6_link_0", "floor") not in pairs
    assert ("leg_right_6_link_0", "floor") in pairs


def test_self_pairs_can_be_excluded(robot, data):
    checker = CollisionChecker(
        robot, [], margin=10.0, exclude=[("arm_left_3_link_0", "arm_left_5_link_0")]
    )
    pairs = by_names(checker.pairs(robot.model, placed_at(robot, data, robot.reference_configuration)))
    assert ("arm_left_3_link_0", "arm_left_5_link_0") not in pairs
    assert ("arm_right_3_link_0", "arm_right_5_link_0") in pairs


@pytest.mark.parametrize(
    "exclude, scene_names",
    [
        ([("no_such_link", "floor")], ["floor"]),
        ([("leg_left_6_link_0", "no_such_object")], ["floor"]),
        ([], ["floor", "floor"]),
        ([], ["base_link_0"]),
    ],
    ids=["unknown-robot-key", "unknown-object", "duplicate-scene-name", "scene-name-of-robot"],
)
def test_bad_setup_raises_a_stance_error(robot, floor, exclude, scene_names):
    with pytest.raises(CollisionSetupError) as error:
        CollisionChecker(robot, [(name, floor) for name in scene_names], exclude=exclude)
    assert isinstance(error.value, StanceError)


def test_broad_phase_keeps_every_pair_within_margin(robot, floor, data):
    rng = np.random.default_rng(3)
    table = box((0.6, 0.8, 0.8), (0.45, 0.0, 0.4))
    scene = [("floor", floor), ("table", table)]
    narrow_only = CollisionChecker(robot, scene, margin=10.0)
    for _ in range(5):
        q = pin.integrate(robot.model, robot.reference_configuration, 0.2 * rng.standard_normal(robot.nv))
        placed_at(robot, data, q)
        expected = {
            names: pair.distance
            for names, pair in by_names(narrow_only.pairs(robot.model, data)).items()
            if pair.distance <= 0.05
        }
        reported = {names: pair.distance for names, pair in by_names(
            narrow_only.with_exclusions((), margin=0.05).pairs(robot.model, data)
        ).items()}
        assert reported == expected


def test_witness_points_give_the_distance_and_the_normal(robot, floor, data):
    rng = np.random.default_rng(5)
    q = pin.integrate(robot.model, robot.reference_configuration, 0.2 * rng.standard_normal(robot.nv))
    checker = CollisionChecker(robot, [("floor", floor)], margin=10.0)
    pairs = checker.pairs(robot.model, placed_at(robot, data, q))
    apart = [pair for pair in pairs if pair.distance > 1e-4]
    assert len(apart) > 300
    for pair in apart:
        offset = pair.point_a - pair.point_b
        assert np.linalg.norm(offset) == pytest.approx(pair.distance, abs=1e-9)
        np.testing.assert_allclose(pair.normal, offset / pair.distance, atol=1e-6)


def test_sphere_beside_the_wrist_cylinder_gives_the_analytic_distance(robot, data):
    placed_at(robot, data, robot.reference_configuration)
    cylinder_to_world, geometry = geometry_to_world(robot, data, "wrist_left_ft_tool_link_0")
    radius, half_length = geometry.geometry.radius, geometry.geometry.halfLength
    sphere_radius, gap = 0.03, 0.012
    # On the cylinder's local x axis, level with its centre: a side contact.
    center = cylinder_to_world.act(np.array([radius + sphere_radius + gap, 0.0, 0.0]))
    ball = coal.CollisionObject(coal.Sphere(sphere_radius), coal.Transform3s(np.eye(3), center))
    checker = CollisionChecker(robot, [("ball", ball)], margin=0.1, self_collision=False)
    pair = by_names(checker.pairs(robot.model, data))[("wrist_left_ft_tool_link_0", "ball")]
    # GJK on curved shapes stops at its tolerance, well under a micrometre.
    assert pair.distance == pytest.approx(gap, abs=1e-6)
    outward = cylinder_to_world.rotation[:, 0]
    np.testing.assert_allclose(pair.normal, -outward, atol=1e-4)
    np.testing.assert_allclose(pair.point_b, center - sphere_radius * outward, atol=1e-5)
    assert abs(half_length) > 0.0  # the side point is within the cylinder's length


def test_penetration_gives_negative_distance_and_a_separating_normal(robot, data):
    placed_at(robot, data, robot.reference_configuration)
    cylinder_to_world, geometry = geometry_to_world(robot, data, "wrist_left_ft_tool_link_0")
    depth = 0.01
    side = np.array([geometry.geometry.radius + 0.1 - depth, 0.0, 0.0])
    box_center = cylinder_to_world.act(side)
    checker = CollisionChecker(
        robot, [("box", box((0.2, 0.2, 0.2), box_center, cylinder_to_world.rotation))], margin=0.1, self_collision=False
    )
    pair = by_names(checker.pairs(robot.model, data))[("wrist_left_ft_tool_link_0", "box")]
    assert pair.distance == pytest.approx(-depth, abs=1e-6)
    # Moving the box against the normal (i.e. the cylinder along it) separates them.
    np.testing.assert_allclose(pair.normal, -cylinder_to_world.rotation[:, 0], atol=1e-6)


def test_left_and_right_distances_mirror_each_other(robot, floor, data):
    # Talos's right limbs use the left meshes with scale y = -1, and half
    # sitting is left-right symmetric except for the ankle rolls (both
    # -0.0017 rad, where a mirror needs opposite signs): zero them.
    q = robot.reference_configuration.copy()
    for side in ("left", "right"):
        q[robot.model.joints[robot.model.getJointId(f"leg_{side}_6_joint")].idx_q] = 0.0
    # Floor pairs only: the floor distance of each limb is exact (surface
    # triangles against a box), whereas hull-hull GJK and the asymmetric
    # base-link mesh differ by tens of micrometres between sides.
    checker = CollisionChecker(robot, [("floor", floor)], margin=10.0, self_collision=False)
    pairs = by_names(checker.pairs(robot.model, placed_at(robot, data, q)))

    def mirrored(name):
        return name.replace("left", "@").replace("right", "left").replace("@", "right")

    checked = 0
    for (name_a, name_b), pair in pairs.items():
        twin = pairs.get((mirrored(name_a), mirrored(name_b))) or pairs.get(
            (mirrored(name_b), mirrored(name_a))
        )
        assert twin is not None, (name_a, name_b)
        assert twin.distance == pytest.approx(pair.distance, abs=1e-6), (name_a, name_b)
        checked += "right" in name_a + name_b
    assert checked == 16  # 15 limb and wrist geometries and the palm plate


def test_jacobian_rows_match_finite_differences_on_the_manifold(robot, floor, data):
    rng = np.random.default_rng(11)
    table = box((0.6, 0.8, 0.8), (0.45, 0.0, 0.5))
    checker = CollisionChecker(robot, [("floor", floor), ("table", table)], margin=0.3)
    model = robot.model
    q = pin.integrate(model, robot.reference_configuration, 0.1 * rng.standard_normal(model.nv))
    pairs = [
        pair
        for pair in checker.pairs(model, placed_at(robot, data, q))
        if pair.distance > 0.01 and not {pair.name_a, pair.name_b} & CURVED
    ]
    assert sum(not pair.is_self_collision for pair in pairs) > 5
    assert sum(pair.is_self_collision for pair in pairs) > 20
    rows = checker.jacobian_rows(model, data, pairs)
    names = [(pair.name_a, pair.name_b) for pair in pairs]

    def distances(q_step):
        measured = by_names(checker.pairs(model, placed_at(robot, data, q_step)))
        return np.array([measured[key].distance for key in names])

    eps = 1e-6
    for _ in range(4):
        direction = rng.standard_normal(model.nv)
        direction /= np.linalg.norm(direction)
        finite_difference = (
            distances(pin.integrate(model, q, eps * direction))
            - distances(pin.integrate(model, q, -eps * direction))
        ) / (2 * eps)
        # Central differences: O(eps^2) truncation; rounding ~1e-16/1e-6.
        np.testing.assert_allclose(rows @ direction, finite_difference, rtol=1e-4, atol=1e-7)


def test_jacobian_rows_of_a_free_flyer_translation_are_the_normal(robot, floor, data):
    # Translating the whole robot by t changes a scene distance by n . t and
    # leaves self distances unchanged: the first three columns (free-flyer
    # linear velocity, base frame) rotated to the world are n (and 0).
    checker = CollisionChecker(robot, [("floor", floor)], margin=10.0)
    pairs = checker.pairs(robot.model, placed_at(robot, data, robot.reference_configuration))
    rows = checker.jacobian_rows(robot.model, data, pairs)
    base_rotation = data.oMi[1].rotation
    for pair, row in zip(pairs, rows):
        expected = np.zeros(3) if pair.is_self_collision else base_rotation.T @ pair.normal
        np.testing.assert_allclose(row[:3], expected, atol=1e-12)


def test_no_pairs_gives_an_empty_jacobian(robot, data):
    checker = CollisionChecker(robot, [], self_collision=False)
    pairs = checker.pairs(robot.model, placed_at(robot, data, robot.reference_configuration))
    assert pairs == []
    assert checker.jacobian_rows(robot.model, data, pairs).shape == (0, robot.nv)


def test_geometry_placements_from_pinocchio_give_the_same_pairs(robot, floor, data):
    checker = CollisionChecker(robot, [("floor", floor)], margin=0.05)
    placed_at(robot, data, robot.reference_configuration)
    geometry_data = pin.GeometryData(robot.collision_model)
    pin.updateGeometryPlacements(robot.model, data, robot.collision_model, geometry_data)
    from_oMi = by_names(checker.pairs(robot.model, data))
    from_oMg = by_names(checker.pairs(robot.model, data, geometry_data.oMg))
    assert from_oMi.keys() == from_oMg.keys()
    for key, pair in from_oMi.items():
        assert from_oMg[key].distance == pytest.approx(pair.distance, abs=1e-12)


def test_a_pair_without_a_direction_or_depth_from_coal_falls_back_on_the_bounds(robot, floor, feet_on_floor, data):
    """When coal gives no separating direction, a scene pair's normal runs from the
    nearest point of the object's bounds to the geometry's bounding-sphere centre; when
    its penetration solver gives up (a distance below -1.8e308), the pair stands at
    -1 m between those two points (copies: the pair owns read-only vectors)."""
    checker = CollisionChecker(robot, [("floor", floor)], exclude=feet_on_floor)
    placed_at(robot, data, robot.reference_configuration)
    rotation, translation = checker._geometry_to_world(data, None)
    candidate = next(c for c in checker._candidates(rotation, translation) if not c[7])
    centre = np.array(candidate[5])
    nearest = np.clip(centre, [-5.0, -5.0, -0.1], [5.0, 5.0, 0.0])  # the floor slab's bounds
    undirected = checker._pair(0.3, (np.zeros(3), np.zeros(3), None), *candidate)
    np.testing.assert_allclose(undirected.normal, (centre - nearest) / np.linalg.norm(centre - nearest), atol=1e-15)
    assert undirected.distance == 0.3
    lost = checker._pair(-np.inf, (np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0])), *candidate)
    assert lost.distance == -1.0
    np.testing.assert_array_equal(lost.point_a, centre)
    np.testing.assert_array_equal(lost.point_b, nearest)
    assert not lost.point_a.flags.writeable and not np.shares_memory(lost.point_a, candidate[5])


def test_distances_alone_are_the_pairs_names_and_distances(robot, floor, feet_on_floor, data, monkeypatch):
    """The clearance check's distances (no witness points) are :meth:`pairs`' names,
    order and distances, at random postures near the reference, a wrist inside a box,
    and where coal's penetration solver gives up (the same -1 m stand-in)."""
    rng = np.random.default_rng(3)
    placed_at(robot, data, robot.reference_configuration)
    cylinder_to_world, geometry = geometry_to_world(robot, data, "wrist_left_ft_tool_link_0")
    inside = box((0.2, 0.2, 0.2), cylinder_to_world.act(np.array([geometry.geometry.radius + 0.09, 0.0, 0.0])),
                 cylinder_to_world.rotation)
    checker = CollisionChecker(robot, [("floor", floor), ("box", inside)], exclude=feet_on_floor, margin=0.1)
    for step in [0.0] + [0.2] * 5:
        q = pin.integrate(robot.model, robot.reference_configuration, step * rng.standard_normal(robot.model.nv))
        placed_at(robot, data, q)
        expected = [((pair.name_a, pair.name_b), pair.distance) for pair in checker.pairs(robot.model, data)]
        assert checker.distances(robot.model, data) == expected and len(expected) > 0
    placed_at(robot, data, robot.reference_configuration)
    assert ("wrist_left_ft_tool_link_0", "box") in dict(checker.distances(robot.model, data))
    assert dict(checker.distances(robot.model, data))[("wrist_left_ft_tool_link_0", "box")] == pytest.approx(-0.01, abs=1e-6)
    original = checker._query.distance
    monkeypatch.setattr(checker._query, "distance", lambda *shapes: -np.inf if original(*shapes) < 0.0 else original(*shapes))
    lost = dict(checker.distances(robot.model, data))
    assert lost[("wrist_left_ft_tool_link_0", "box")] == -1.0
    assert lost == {(pair.name_a, pair.name_b): pair.distance for pair in checker.pairs(robot.model, data)}


def test_the_closest_pairs_as_arrays_are_the_pairs_sorted_with_their_stand_ins(
        robot, floor, feet_on_floor, data, monkeypatch):
    """:meth:`closest` (the linearisation's arrays, witness points read all at once) holds
    the pairs of :meth:`pairs` sorted by distance, field by field, and their Jacobian rows;
    where coal's penetration solver gives up, the same -1 m stand-in between the bounds."""
    placed_at(robot, data, robot.reference_configuration)
    cylinder_to_world, geometry = geometry_to_world(robot, data, "wrist_left_ft_tool_link_0")
    inside = box((0.2, 0.2, 0.2), cylinder_to_world.act(np.array([geometry.geometry.radius + 0.09, 0.0, 0.0])),
                 cylinder_to_world.rotation)
    checker = CollisionChecker(robot, [("floor", floor), ("box", inside)], exclude=feet_on_floor, margin=0.1)

    def agree(count):
        expected = sorted(checker.pairs(robot.model, data), key=lambda pair: pair.distance)[:count]
        measured = checker.closest(robot.model, data, count)
        assert len(measured) == len(expected) > 0
        assert measured.names == tuple((pair.name_a, pair.name_b) for pair in expected)
        for field, name in (("distances", "distance"), ("points_a", "point_a"), ("points_b", "point_b"),
                            ("normals", "normal"), ("joint_a", "joint_a"), ("joint_b", "joint_b")):
            np.testing.assert_array_equal(getattr(measured, field), [getattr(pair, name) for pair in expected])
        for pair, reference in zip(measured.pairs(), expected):
            assert (pair.name_a, pair.name_b, pair.joint_a, pair.joint_b, pair.distance) == (
                reference.name_a, reference.name_b, reference.joint_a, reference.joint_b, reference.distance)
            np.testing.assert_array_equal(np.vstack([pair.point_a, pair.point_b, pair.normal]),
                                          np.vstack([reference.point_a, reference.point_b, reference.normal]))
            assert not pair.normal.flags.writeable
        np.testing.assert_array_equal(checker.jacobian_rows(robot.model, data, measured),
                                      checker.jacobian_rows(robot.model, data, expected))
        return measured

    wrist = ("wrist_left_ft_tool_link_0", "box")
    assert dict(zip(*attrgetter("names", "distances")(agree(20))))[wrist] == pytest.approx(-0.01, abs=1e-6)
    query = checker._query
    distance, kept = query.distance, query.kept_distance
    monkeypatch.setattr(query, "distance", lambda *shapes: -np.inf if distance(*shapes) < 0.0 else distance(*shapes))

    def lost_depth(*arguments):
        measured, result = kept(*arguments)
        return (-np.inf if measured < 0.0 else measured), result

    monkeypatch.setattr(query, "kept_distance", lost_depth)
    checker._last_closest = None  # measured again, with the depth lost
    assert dict(zip(*attrgetter("names", "distances")(agree(20))))[wrist] == -1.0


def test_clearance_is_what_every_distance_gives_for_fewer_measurements(robot, floor, feet_on_floor, data, monkeypatch):
    """:meth:`clearance` (the final check's collision test) gives the least distance within
    the margin and the pairs deeper than the depth exactly as :meth:`distances` does, at
    random postures near the reference with a wrist inside a box, measuring fewer pairs."""
    placed_at(robot, data, robot.reference_configuration)
    cylinder_to_world, geometry = geometry_to_world(robot, data, "wrist_left_ft_tool_link_0")
    inside = box((0.2, 0.2, 0.2), cylinder_to_world.act(np.array([geometry.geometry.radius + 0.09, 0.0, 0.0])),
                 cylinder_to_world.rotation)
    checker = CollisionChecker(robot, [("floor", floor), ("box", inside)], exclude=feet_on_floor, margin=0.1)
    calls = []
    measure = checker._query.distance
    monkeypatch.setattr(checker._query, "distance", lambda *shapes: calls.append(1) or measure(*shapes))
    rng = np.random.default_rng(4)
    deep_seen, every, fewer = 0, 0, 0
    for step in [0.0] + [0.15] * 12:
        q = pin.integrate(robot.model, robot.reference_configuration, step * rng.standard_normal(robot.model.nv))
        placed_at(robot, data, q)
        for depth in (1e-4, 0.02):
            calls.clear()
            pairs = checker.distances(robot.model, data)
            every += len(calls)
            calls.clear()
            least, deep = checker.clearance(robot.model, data, depth)
            fewer += len(calls)
            assert least == min((distance for _, distance in pairs), default=np.inf)
            assert deep == [(names, distance) for names, distance in pairs if distance < -depth]
            deep_seen += len(deep)
    assert deep_seen > 0 and fewer < 0.6 * every
