"""One soft solid made of blocks (``soft_blocks``): its mesh, its surfaces, its
prints pressing each other, and the shapes it refuses."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

import environments
import fem
from conftest import scene_distance, sphere
from environments import ScenarioError, SceneError
from environments.deformable import soft_blocks
from fem_reference import direct_reactions

MATERIAL = fem.LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4)
# A soft step: a 0.1 m tread beside a 0.85 m ledge (the built-in scenario's shape).
STEP = [("tread", (0.5, 0.55, 0.1), (0.1, -0.275, 0.05)), ("ledge", (0.4, 0.55, 0.85), (0.55, -0.275, 0.425))]


@pytest.fixture(scope="module")
def step():
    return soft_blocks("foam", STEP, MATERIAL, resolution=0.05)


def test_the_mesh_fills_the_blocks_and_nothing_else(step):
    obj, _ = step
    mesh = obj.mesh
    volume = sum(np.prod(size) for _, size, _ in STEP)
    assert np.isclose(mesh.volumes.sum(), volume, rtol=1e-12)
    centroids = obj.points_in_world(np.asarray(mesh.nodes)[np.asarray(mesh.tets)].mean(axis=1))
    inside = np.zeros(len(centroids), dtype=bool)
    for _, size, center in STEP:
        inside |= np.all(np.abs(centroids - center) < 0.5 * np.asarray(size), axis=1)
    assert inside.all()


def test_the_base_is_fixed_and_nothing_else(step):
    obj, _ = step
    world = obj.points_in_world(obj.mesh.nodes)
    assert np.array_equal(np.sort(obj.body.fixed_nodes), np.flatnonzero(np.abs(world[:, 2]) < 1e-12))


def test_each_block_top_is_a_soft_surface_of_the_same_body(step):
    obj, surfaces = step
    assert [s.name for s in surfaces] == ["foam_tread", "foam_ledge"]
    world = obj.points_in_world(obj.mesh.nodes)
    for surface, (_, size, center) in zip(surfaces, STEP):
        assert surface.object_name == "foam" and surface.deformable
        top = np.asarray(center) + [0.0, 0.0, 0.5 * size[2]]
        assert np.allclose(surface.transform_surface_to_world[:3, 3], top)
        # The top face's corners are mesh nodes on the body's boundary.
        boundary = world[obj.mesh.is_surface_node]
        for sx in (-0.5, 0.5):
            for sy in (-0.5, 0.5):
                corner = top + [sx * size[0], sy * size[1], 0.0]
                assert np.linalg.norm(boundary - corner, axis=1).min() < 1e-12


def test_a_print_on_each_block_matches_the_full_system_and_couples_them(step):
    """A sole on the tread and a palm on the ledge, condensed together, against a
    direct solve of the whole body with both prints prescribed; alone, the palm
    print would react differently (the sole's press moves the ledge)."""
    obj, _ = step
    body = obj.body
    world = obj.points_in_world(obj.mesh.nodes)

    def nodes_under(x, y, z):
        return np.flatnonzero((np.abs(world[:, 2] - z) < 1e-12) & (np.abs(world[:, 0] - x[0] - x[1]) <= x[1] + 1e-9)
                              & (np.abs(world[:, 1] - y[0] - y[1]) <= y[1] + 1e-9))

    sole = nodes_under((0.15, 0.1), (-0.35, 0.05), 0.1)  # 0.2 x 0.1 m near the ledge's foot
    palm = nodes_under((0.40, 0.05), (-0.30, 0.05), 0.85)
    assert sole.size >= 6 and palm.size >= 4
    both = np.concatenate([sole, palm])
    press = np.tile([0.0, 0.0, -0.004], (both.size, 1))
    coupled = body.contact_patch(both).reaction_forces(press)
    direct, _ = direct_reactions(body, both, press)
    assert np.abs(coupled + direct).max() <= 1e-8 * np.abs(direct).max()
    alone = body.contact_patch(palm).reaction_forces(press[sole.size :])
    assert np.abs(alone - coupled[sole.size :]).max() > 1e-6 * np.abs(alone).max()


def test_the_collision_shape_keeps_the_re_entrant_corner_free(step):
    """A foot over the tread, in front of the ledge, is outside the solid (a convex
    hull of the nodes would hold it)."""
    obj, surfaces = step
    scene = environments.Scene("step", [], [obj], surfaces)
    (name, foam), = scene.collision_objects()
    distance = scene_distance(foam, sphere(0.05, (-0.05, -0.275, 0.4)))
    assert name == "foam"
    assert distance == pytest.approx(0.4 - 0.1 - 0.05, abs=1e-6)  # down to the tread


@pytest.mark.parametrize(
    "blocks, message",
    [
        ([("a", (1, 1, 1), (0, 0, 0.5)), ("b", (1, 1, 1), (0.5, 0, 0.5))], "blocks 'a' and 'b' overlap"),
        ([("a", (1, 1, 1), (0, 0, 0.5)), ("b", (1, 1, 1), (0, 0, 1.5))], "block 'b' stands on the top face of 'a'"),
        ([("a", (1, 1, 1), (0, 0, 0.5)), ("b", (1, 1, 1), (1.5, 0, 0.5))], "block 'b' does not touch the others"),
        ([("a", (1, 1, 1), (0, 0, 0.5)), ("a", (1, 1, 1), (1, 0, 0.5))], "two blocks are named 'a'"),
        ([("a", (1, 0, 1), (0, 0, 0.5))], "size must be > 0 on every axis"),
        ([], "blocks must be a non-empty list"),
    ],
)
def test_shapes_that_are_not_one_solid_are_refused(blocks, message):
    with pytest.raises(SceneError, match=message):
        soft_blocks("foam", blocks, MATERIAL, resolution=0.25)


def test_a_scenario_file_names_the_bad_block(tmp_path):
    text = textwrap.dedent(
        """
        robot: talos
        description: a step whose blocks overlap
        objects:
          - {name: floor, type: floor}
          - name: foam
            type: soft_blocks
            blocks:
              - {name: tread, size: [0.5, 0.5, 0.1], center: [0.0, -0.3, 0.05]}
              - {name: ledge, size: [0.4, 0.5, 0.8], center: [0.4, -0.3, 0.4]}
            material: {E: 1.0e+6, nu: 0.4}
            resolution: 0.1
        stances:
          stand:
            left_sole: {surface: floor, x: 0.0, y: 0.085}
            right_sole: {surface: floor, x: 0.0, y: -0.085}
        start: stand
        """
    )
    path = tmp_path / "step.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"objects\[1\].*blocks 'tread' and 'ledge' overlap"):
        environments.load(str(path))
    path.write_text(text.replace("size: [0.4, 0.5, 0.8], center: [0.4,", "size: [0.4, 0.5, 0.8], center: [0.45,"))
    scenario = environments.load(str(path))
    assert {"foam_tread", "foam_ledge"} <= set(scenario.scene.surfaces)


def test_soft_box_yaw_turns_body_and_top_and_its_friction_is_the_tops():
    """A 0.6 x 0.4 x 0.2 m box centred at (1, -0.5, 0.1), turned 30 degrees about z:
    its top frame and every mesh node turn about the centre's vertical, its base stays
    on the floor, and the friction given is the top surface's."""
    import math

    from environments.deformable import soft_box

    material = fem.LinearElasticMaterial(1e6, 0.4)
    obj, top = soft_box("pad", (0.6, 0.4, 0.2), (1.0, -0.5, 0.1), material, resolution="coarse",
                        yaw=math.radians(30), friction=0.45)
    assert top.friction == 0.45
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(top.transform_surface_to_world[:3, :3], turn, atol=1e-15)
    np.testing.assert_allclose(top.transform_surface_to_world[:3, 3], [1.0, -0.5, 0.2], atol=1e-15)
    np.testing.assert_allclose(top.polygon, [[-0.3, -0.2], [0.3, -0.2], [0.3, 0.2], [-0.3, 0.2]], atol=1e-15)
    # Body frame: centre of the base, the box's axes.
    nodes = np.asarray(obj.mesh.nodes)
    world = obj.points_in_world(nodes)
    np.testing.assert_allclose(world, nodes @ turn.T + [1.0, -0.5, 0.0], atol=1e-12)
    assert world[:, 2].min() == pytest.approx(0.0, abs=1e-15) and world[:, 2].max() == pytest.approx(0.2, abs=1e-15)
    np.testing.assert_allclose(nodes.min(axis=0), [-0.3, -0.2, 0.0], atol=1e-15)
    np.testing.assert_allclose(nodes.max(axis=0), [0.3, 0.2, 0.2], atol=1e-15)


def test_collisions_see_the_blocks_faces_not_the_fine_boundary():
    """A soft step's collision shape is its blocks' 24 triangles: every outside point is as far
    from them as from the mesh's boundary (thousands of triangles), measured by coal both ways."""
    import coal
    from stances.narrow_phase import DistanceQuery, box_shape, scene_shape

    scenario = environments.load("foot-and-hand-on-foam")
    (name, shape), = [(n, s) for n, s in scenario.scene.collision_objects() if n == "foam"]
    obj = scenario.scene.deformable_objects[0]
    assert len(shape.triangles) == 24 and len(obj.mesh.surface_triangles) > 1000
    fine = environments.geometry.CollisionShape(obj.transform_body_to_world, vertices=obj.mesh.nodes,
                                               triangles=obj.mesh.surface_triangles)
    coarse_shape, coarse_rotation, coarse_translation = scene_shape(name, shape)
    fine_shape, fine_rotation, fine_translation = scene_shape(name, fine)
    probe = box_shape((0.02, 0.02, 0.02))
    query = DistanceQuery()
    rng = np.random.default_rng(4)
    low, high = obj.points_in_world(obj.mesh.nodes).min(axis=0), obj.points_in_world(obj.mesh.nodes).max(axis=0)
    checked = 0
    for centre in rng.uniform(low - 0.1, high + 0.1, size=(200, 3)):
        placed = coal.Transform3s(np.eye(3), centre)
        coarse = query.distance(probe, placed, coarse_shape, coal.Transform3s(coarse_rotation, coarse_translation))
        fine_distance = query.distance(probe, placed, fine_shape, coal.Transform3s(fine_rotation, fine_translation))
        if min(coarse, fine_distance) > 1e-3:  # outside both (a mesh has no inside for coal)
            assert coarse == pytest.approx(fine_distance, abs=1e-9)
            checked += 1
    assert checked > 50


def test_a_malformed_collision_mesh_is_refused_with_its_shapes():
    obj = environments.load("foot-and-hand-on-foam").scene.deformable_objects[0]
    from dataclasses import replace

    with pytest.raises(SceneError, match=r"object 'foam': collision_mesh must be finite \(n, 3\) vertices and \(t, 3\) "
                                         r"triangles indexing them, got shapes \(8, 3\) and \(1, 3\)"):
        replace(obj, collision_mesh=(np.zeros((8, 3)), [[0, 1, 8]]))
    with pytest.raises(SceneError, match=r"collision_mesh must be \(vertices, triangles\)"):
        replace(obj, collision_mesh=np.zeros((8, 3)))
