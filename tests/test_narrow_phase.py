"""coal distances of stances.narrow_phase against independent computations."""

from __future__ import annotations

import os

import numpy as np
import pinocchio as pin
import pytest
import trimesh

import environments
from environments.errors import SceneError
from environments.geometry import CollisionShape
from stances.collision import CollisionChecker
from stances.narrow_phase import (CollisionSetupError, DistanceQuery, box_shape, coal, robot_shape, scene_shape,
                                  world_boxes)

# Meshes of several sizes (small wrist link to large torso) and mirrored limbs.
MESHES = ["torso_2_link_0", "arm_left_4_link_0", "arm_right_5_link_0", "leg_left_1_link_0", "head_2_link_0"]


def placed_at(translation):
    """(4, 4) placement translated by ``translation``, metres."""
    transform = np.eye(4)
    transform[:3, 3] = translation
    return transform


def hull_of(robot, name):
    """(coal shape, (n, 3) mesh vertices in the geometry frame) of a robot mesh."""
    geometry_object = robot.collision_model.geometryObjects[robot.collision_model.getGeometryId(name)]
    shape, _, _ = robot_shape(geometry_object)
    # The vertices straight from the mesh file: the brute force below does not
    # depend on the hull the checker builds.
    mesh = trimesh.load(geometry_object.meshPath, force="mesh")
    return shape, np.asarray(mesh.vertices) * np.asarray(geometry_object.meshScale)


def random_rotation(rng):
    return pin.exp3(rng.standard_normal(3))


def test_a_mesh_is_hulled_once_a_process_and_again_when_its_file_changes(robot, tmp_path, monkeypatch):
    """A robot loaded again reads no collision mesh (the hull kept by file, time, size and
    scale gives the same shape); a copy of the file, or the file changed, is read again."""
    from stances import narrow_phase

    geometry_object = robot.collision_model.geometryObjects[robot.collision_model.getGeometryId(MESHES[0])]
    first = robot_shape(geometry_object)
    monkeypatch.setattr(trimesh, "load", lambda *args, **kwargs: pytest.fail("a mesh file was read again"))
    again = robot_shape(geometry_object)
    assert again[0] is first[0] and np.array_equal(again[1], first[1]) and again[2] == first[2]
    monkeypatch.undo()
    copy = tmp_path / ("copy" + os.path.splitext(geometry_object.meshPath)[1])
    copy.write_bytes(open(geometry_object.meshPath, "rb").read())
    moved = geometry_object.copy()
    moved.meshPath = str(copy)
    shape, center, radius = robot_shape(moved)
    assert shape is not first[0] and np.array_equal(center, first[1]) and radius == first[2]
    count = len(narrow_phase._HULLS)
    copy.write_bytes(open(geometry_object.meshPath, "rb").read() + b"\n")  # another size
    robot_shape(moved)
    assert len(narrow_phase._HULLS) == count + 1


def test_separated_hulls_match_a_vertex_certificate(robot):
    # Independent of GJK: with the reported direction n, the gap between the
    # two vertex sets' extents along n is a lower bound of the distance; two
    # points inside the hulls (checked on the hulls' face planes) at distance
    # d are an upper bound. Both within 1e-9 m of d certify d and the points.
    rng = np.random.default_rng(7)
    query = DistanceQuery()
    checked = 0
    for _ in range(60):
        name_a, name_b = rng.choice(MESHES, size=2)
        shape_a, vertices_a = hull_of(robot, name_a)
        shape_b, vertices_b = hull_of(robot, name_b)
        rotation_a, rotation_b = random_rotation(rng), random_rotation(rng)
        translation_a = np.zeros(3)
        translation_b = rng.standard_normal(3) * rng.uniform(0.05, 0.6)
        distance = query.distance(
            shape_a, coal.Transform3s(rotation_a, translation_a), shape_b, coal.Transform3s(rotation_b, translation_b)
        )
        point_a, point_b, normal = query.witness()
        if distance <= 1e-4:
            continue
        world_a = vertices_a @ rotation_a.T + translation_a
        world_b = vertices_b @ rotation_b.T + translation_b
        lower = np.min(world_a @ normal) - np.max(world_b @ normal)
        assert np.linalg.norm(point_a - point_b) == pytest.approx(distance, abs=1e-9)
        assert lower == pytest.approx(distance, abs=1e-9)
        for point, world in ((point_a, world_a), (point_b, world_b)):
            hull = trimesh.convex.convex_hull(world)
            outside = np.max(hull.face_normals @ point - np.sum(hull.face_normals * hull.triangles[:, 0], axis=1))
            assert outside <= 1e-9
        checked += 1
    assert checked > 30


@pytest.mark.parametrize("seed", range(5))
def test_overlapping_boxes_give_the_exact_penetration_depth(seed):
    # Two boxes with parallel faces: the smallest translation separating them
    # runs along the axis of least overlap, by that overlap. A common rotation
    # of both leaves the depth unchanged and turns the normal with them.
    rng = np.random.default_rng(seed)
    size_a, size_b = rng.uniform(0.1, 1.0, 3), rng.uniform(0.1, 1.0, 3)
    half_sum = 0.5 * (size_a + size_b)
    offset = rng.uniform(0.3, 0.9, 3) * half_sum * rng.choice([-1.0, 1.0], 3)
    overlap = half_sum - np.abs(offset)
    axis = int(np.argmin(overlap))
    rotation = random_rotation(rng)
    translation_a = rng.standard_normal(3)
    query = DistanceQuery()
    distance = query.distance(
        box_shape(size_a), coal.Transform3s(rotation, translation_a),
        box_shape(size_b), coal.Transform3s(rotation, translation_a + rotation @ offset),
    )
    point_a, point_b, normal = query.witness()
    # EPA's tolerance is 1e-9 (boxes are polytopes: no inflation of their sides).
    assert distance == pytest.approx(-overlap[axis], abs=1e-9)
    expected_normal = -np.sign(offset[axis]) * rotation[:, axis]
    np.testing.assert_allclose(normal, expected_normal, atol=1e-8)
    np.testing.assert_allclose(point_b - point_a, distance * -normal, atol=1e-8)


def test_hull_to_floor_distance_is_the_lowest_hull_vertex(robot):
    # Above a floor slab far wider than the robot, the distance from a hull to
    # the slab is the height of its lowest vertex: brute force on the vertices.
    rng = np.random.default_rng(2)
    model, data = robot.model, robot.model.createData()
    floor = CollisionShape(placed_at((0.0, 0.0, -0.05)), box_size=(10.0, 10.0, 0.1))
    checker = CollisionChecker(robot, [("floor", floor)], margin=10.0, self_collision=False)
    hulls = {
        geometry.name: hull_of(robot, geometry.name)[1]
        for geometry in robot.collision_model.geometryObjects
        if geometry.meshPath and "BVH" in type(geometry.geometry).__name__
    }
    compared = 0
    for _ in range(5):
        q = pin.integrate(model, robot.reference_configuration, 0.3 * rng.standard_normal(model.nv))
        q[2] += 0.2  # lift the robot off the floor
        pin.forwardKinematics(model, data, q)
        geometry_data = pin.GeometryData(robot.collision_model)
        pin.updateGeometryPlacements(model, data, robot.collision_model, geometry_data)
        for pair in checker.pairs(model, data):
            vertices = hulls.get(pair.name_a)
            if vertices is None:
                continue
            placement = geometry_data.oMg[robot.collision_model.getGeometryId(pair.name_a)]
            lowest = np.min((vertices @ placement.rotation.T + placement.translation)[:, 2])
            if lowest <= 1e-3:
                continue
            assert pair.distance == pytest.approx(lowest, abs=1e-9)
            np.testing.assert_allclose(pair.normal, [0.0, 0.0, 1.0], atol=1e-9)
            assert pair.point_b[2] == pytest.approx(0.0, abs=1e-9)
            compared += 1
    assert compared > 50


def test_scene_meshes_become_convex_or_triangle_shapes():
    box = trimesh.creation.box(extents=(0.4, 0.3, 0.2))
    convex = CollisionShape(placed_at((1.0, 0.0, 0.0)), vertices=box.vertices, triangles=box.faces)
    shape, _, translation = scene_shape("block", convex)
    assert isinstance(shape, coal.Convex)
    np.testing.assert_allclose(translation, [1.0, 0.0, 0.0])
    assert scene_shape("block", convex)[0] is shape  # built once per scene shape
    # An open mesh (the box without its top) stays a triangle mesh.
    open_box = CollisionShape(np.eye(4), vertices=box.vertices, triangles=box.faces[2:])
    assert isinstance(scene_shape("tray", open_box)[0], coal.BVHModelOBBRSS)


def test_other_scene_objects_are_refused_with_what_is_accepted():
    with pytest.raises(CollisionSetupError, match="must be an environments.geometry.CollisionShape or a coal.CollisionObject, got tuple"):
        scene_shape("sheet", (np.eye(3), np.zeros(3)))


def test_malformed_collision_shapes_are_refused_with_the_reason():
    with pytest.raises(SceneError, match="either a box"):
        CollisionShape(np.eye(4))
    with pytest.raises(SceneError, match="box_size must be 3 positive lengths"):
        CollisionShape(np.eye(4), box_size=(1.0, 0.0, 1.0))
    with pytest.raises(SceneError, match="triangles must index the 3 vertices"):
        CollisionShape(np.eye(4), vertices=np.eye(3), triangles=[[0, 1, 3]])


def test_a_scene_box_measures_like_the_same_coal_box(robot):
    # Same checker answers whether the scene arrives as a scene shape or a coal object.
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, robot.reference_configuration)
    center = np.array([0.45, 0.0, 0.5])
    from_scene = CollisionChecker(robot, [("table", CollisionShape(placed_at(center), box_size=(0.6, 0.8, 0.8)))], margin=10.0)
    from_coal = CollisionChecker(
        robot, [("table", coal.CollisionObject(coal.Box(0.6, 0.8, 0.8), coal.Transform3s(np.eye(3), center)))],
        margin=10.0,
    )
    pairs = from_scene.pairs(robot.model, data)
    assert len(pairs) > 10
    for one, other in zip(pairs, from_coal.pairs(robot.model, data)):
        assert (one.name_a, one.name_b) == (other.name_a, other.name_b)
        assert one.distance == other.distance


def test_a_meshs_world_boxes_from_its_triangles_as_given_are_those_read_back_from_its_bvh():
    """scene_geometry hands world_boxes the triangles a BVH was built from instead of reading
    them back one call a triangle: the same boxes, bit for bit (a dented foam's surface)."""
    foam = environments.load("cross-soft-block").scene.deformable_objects[0]
    dent = np.zeros((foam.mesh.nodes.shape[0], 3))
    dent[:, 2] = -0.01 * np.exp(-np.sum((foam.mesh.nodes[:, :2] - foam.mesh.nodes[:, :2].mean(axis=0)) ** 2, axis=1) / 0.01)
    surface = foam.deformed_collision_object(dent)
    shape, rotation, translation = scene_shape("foam (deformed)", surface)
    assert isinstance(shape, coal.BVHModelBase)  # dented: no convex hull
    given = world_boxes(shape, rotation, translation, triangles=surface.triangles)
    np.testing.assert_array_equal(given, world_boxes(shape, rotation, translation))
    assert len(given) == 32
