"""Soft solids of any shape (``soft_mesh``): a box's surface meshed by gmsh presses back
like the soft box of that size, a Talos sole stands on one, and bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import environments
import fem
import stances
from environments import ScenarioError, SceneError
from environments.deformable import soft_box
from environments.soft_mesh import soft_mesh

MATERIAL = fem.LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4)
SIZE = np.array([0.6, 0.6, 0.2])
# A sole-sized print (0.2 m x 0.11 m) at the centre of the top face, world frame.
SOLE = np.array([[-0.1, -0.055, 0.2], [0.1, -0.055, 0.2], [0.1, 0.055, 0.2], [-0.1, 0.055, 0.2]])


def print_force(obj, motion) -> np.ndarray:
    """Resultant force (3,) N, world frame, on a rigid sole print moved by ``motion`` (3,) m, world frame."""
    transform = obj.transform_body_to_world
    polygon_in_body = (SOLE - transform[:3, 3]) @ transform[:3, :3]
    ids = fem.nodes_in_polygon(obj.mesh, polygon_in_body, tolerance=1e-6)
    press = np.tile(np.asarray(motion) @ transform[:3, :3], (len(ids), 1))
    return obj.body.contact_patch(ids).reaction_forces(press).sum(axis=0) @ transform[:3, :3].T


@pytest.fixture(scope="module")
def same_box():
    """The 0.6 x 0.6 x 0.2 m box as a soft_mesh and a soft_box at h = 25 mm, and a soft_box at 50 mm."""
    surface = trimesh.creation.box(SIZE).apply_translation((0.0, 0.0, 0.1))
    solid, surfaces = soft_mesh("solid", surface, MATERIAL, resolution=0.025)
    box, top = soft_box("box", SIZE, (0.0, 0.0, 0.1), MATERIAL, resolution=0.025)
    coarser, _ = soft_box("coarser", SIZE, (0.0, 0.0, 0.1), MATERIAL, resolution=0.05)
    return solid, surfaces, box, top, coarser


@pytest.mark.parametrize("motion", [(0.0, 0.0, -0.001), (0.0005, 0.0, 0.0)], ids=["press", "shear"])
def test_a_soft_mesh_of_a_box_surface_presses_back_like_the_soft_box(same_box, motion):
    """Both meshes have spacing h = 25 mm under the print. A rigid print's force
    converges slowly (h^1.3, see environments.deformable.RESOLUTIONS), so each mesh
    is still some 10-20 % from the converged force: the tolerance is the soft box's
    own change from h = 50 mm to 25 mm, the size of the discretisation error.
    Measured: press 398 N (box) vs 393 N (gmsh), box at 50 mm 480 N; shear 95.9 N
    vs 96.4 N, box at 50 mm 110 N."""
    solid, surfaces, box, top, coarser = same_box
    axis = int(np.argmax(np.abs(motion)))
    by_mesh, by_box, by_coarser = (print_force(obj, motion)[axis] for obj in (solid, box, coarser))
    assert by_box * np.sign(motion[axis]) < 0.0  # it pushes back
    assert abs(by_mesh - by_box) < abs(by_coarser - by_box)
    # The found top face is the soft box's top surface.
    assert surfaces[0].name == "solid_top_0"
    assert np.allclose(surfaces[0].transform_surface_to_world, top.transform_surface_to_world, atol=1e-9)
    assert np.allclose(np.sort(surfaces[0].polygon, axis=0), np.sort(top.polygon, axis=0), atol=1e-9)


def test_the_fixed_part_is_the_face_on_the_floor():
    surface = trimesh.creation.box((0.3, 0.3, 0.1))
    solid, _ = soft_mesh("solid", surface, MATERIAL, position=(1.0, 0.0, 0.05), resolution=0.05)
    world = solid.points_in_world(solid.mesh.nodes)
    assert np.array_equal(np.sort(solid.body.fixed_nodes), np.flatnonzero(np.abs(world[:, 2]) <= 1e-6))
    lifted, _ = soft_mesh("lifted", surface, MATERIAL, position=(1.0, 0.0, 0.35), fixed="z = 0.3", resolution=0.05)
    world = lifted.points_in_world(lifted.mesh.nodes)
    assert np.allclose(world[lifted.body.fixed_nodes, 2], 0.3) and lifted.body.fixed_nodes.size >= 9


def test_a_tet_mesh_file_gives_the_same_solid(tmp_path):
    surface = trimesh.creation.box((0.3, 0.3, 0.1))
    solid, surfaces = soft_mesh("solid", surface, MATERIAL, position=(0.0, 0.0, 0.05), resolution=0.05)
    fem.write_mesh(tmp_path / "solid.vtu", solid.mesh)
    again, surfaces_again = soft_mesh("solid", tmp_path / "solid.vtu", MATERIAL, position=(0.0, 0.0, 0.05))
    assert again.mesh.n_nodes == solid.mesh.n_nodes and again.mesh.n_tets == solid.mesh.n_tets
    assert np.array_equal(again.body.fixed_nodes, solid.body.fixed_nodes)
    assert [s.name for s in surfaces_again] == [s.name for s in surfaces]
    for first, second in zip(surfaces, surfaces_again):
        assert np.allclose(first.transform_surface_to_world, second.transform_surface_to_world, atol=1e-9)


# A rubber pad turned 90 degrees about z: its body x axis is world y, so a sole
# pointing along world x has theta = -90 degrees on its top.
PAD_SCENE = """
objects:
  - {name: floor, type: floor}
  - name: pad
    type: soft_mesh
    file: pad.stl
    position: [0.5, 0.0, 0.0]
    rpy_deg: [0, 0, 90]
    material: {E: 2.0e+6, nu: 0.45, rho: 1100}
    resolution: coarse
stances:
  right-on-pad:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: pad_top_0, x: -0.085, y: 0.1, theta_deg: -90}   # world (0.4, -0.085)
"""


@pytest.fixture(scope="module")
def pad_scenario(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pad")
    trimesh.creation.box((0.8, 0.4, 0.05)).apply_translation((0.0, 0.0, 0.025)).export(folder / "pad.stl")
    (folder / "pad.yaml").write_text(PAD_SCENE)
    return environments.load(folder / "pad.yaml")


def test_a_stance_on_a_soft_mesh_solves_and_verifies(pad_scenario, robot):
    scene = pad_scenario.scene
    origin = scene.print_origin_in_world(pad_scenario.stance("right-on-pad").contacts[1])
    assert np.allclose(origin, [0.4, -0.085, 0.05], atol=1e-6)
    result = stances.solve(robot, scene, pad_scenario.stance("right-on-pad"))
    assert result.feasible, result.reason
    assert stances.verify(robot, scene, result.stance, result).ok
    assert 0.0 < result.verification.measures["indentation of pad"] < 1e-3


@pytest.mark.parametrize(
    "change, message",
    [
        ("position: [0.5, 0.0, 0.0]", None),
        ("position: [0.5, 0.0, 0.2]",
         "objects[1]: object 'pad': 0 boundary node(s) lie on the fixing plane z = 0 (the solid spans z = 0.2 .. 0.25 m "
         "in the world); place it so that a face lies on that plane, or give the plane it rests on"),
        ("position: [0.5, 0.0, 0.0]\n    fixed: {plane: up}",
         "objects[1].fixed.plane: plane must read '<x|y|z> = <metres>' in the world frame, e.g. 'z = 0'; got 'up'"),
        ("position: [0.5, 0.0, 0.0]\n    fixed: below", "objects[1].fixed: must be on_floor or {plane: '<x|y|z> = <metres>'}, got str 'below'"),
        ("position: [0.5, 0.0, 0.0]\n    surfaces: []",
         "objects[1].surfaces: must be 'auto' (a soft mesh's surfaces are found on it), got an empty list"),
    ],
    ids=["fine", "off-the-plane", "bad-plane", "bad-fixed", "explicit-surfaces"],
)
def test_bad_soft_meshes_are_refused_with_the_key(tmp_path, change, message):
    trimesh.creation.box((0.8, 0.4, 0.05)).apply_translation((0.0, 0.0, 0.025)).export(tmp_path / "pad.stl")
    text = PAD_SCENE.replace("position: [0.5, 0.0, 0.0]", change)
    path = tmp_path / "pad.yaml"
    path.write_text(text)
    if message is None:
        assert "pad_top_0" in environments.load(path).scene.surfaces
        return
    with pytest.raises(ScenarioError) as caught:
        environments.load(path)
    # objects[1] starts on line 4; an added key is on line 8.
    line = 4 if message.startswith("objects[1]: ") else 8
    assert str(caught.value) == f"{path}:{line}: {message}"


def test_an_open_surface_is_refused():
    open_box = trimesh.creation.box((0.3, 0.3, 0.1))
    open_box.update_faces(np.arange(len(open_box.faces)) != 0)
    with pytest.raises(SceneError, match=r"^object 'solid': the surface mesh is not closed \(watertight\): a soft solid "
                                         r"needs a closed surface$"):
        soft_mesh("solid", open_box, MATERIAL, position=(0.0, 0.0, 0.05), resolution=0.05)
