"""Tests of the scenario files: every built-in one loads and is consistent; bad files fail clearly."""

import math
import textwrap

import numpy as np
import pytest
import trimesh

from environments import ScenarioError, SceneError, load, scenario_names
from stances.description import builtin_robot_names

BUILTIN = scenario_names()
EXPECTED = {
    "stand",
    "hand-on-table",
    "foot-on-block",
    "hand-on-cube",
    "step-on-cube",
    "hand-on-soft-cube",
    "hand-on-coarse-cube",
    "cross-soft-block",
    "climb-with-soft-support",
    "foot-and-hand-on-foam",
    "quadruped-walk",
    "romeo-hand-on-soft-cube",
    "icub-hand-on-soft-cube",
}


@pytest.fixture(scope="module")
def loaded():
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = load(name)
        return cache[name]

    return get


def test_every_expected_scenario_is_built_in():
    assert EXPECTED <= set(BUILTIN)
    assert BUILTIN == sorted(BUILTIN)


@pytest.mark.parametrize("name", BUILTIN)
def test_builtin_scenario_loads_with_a_builtin_robot_and_a_start_stance(name, loaded):
    scenario = loaded(name)
    assert scenario.name == name and scenario.robot in builtin_robot_names()
    assert scenario.start in scenario.stances
    assert scenario.description
    assert "floor" in scenario.scene.surfaces


@pytest.mark.parametrize("name", BUILTIN)
def test_every_named_stance_has_its_print_origins_on_their_surfaces(name, loaded):
    scenario = loaded(name)
    for stance_name, stance in scenario.stances.items():
        for contact in stance:
            contact_print = contact.contact_print
            surface = scenario.scene.surface(contact_print.surface)
            assert surface.contains((contact_print.x, contact_print.y)), (stance_name, contact.robot_surface)


def _inside_object(scene, object_name, point):
    obj = scene.objects[object_name]
    if obj.deformable:
        # Any soft solid (a soft step is not convex): inside one of its tets.
        nodes = obj.points_in_world(obj.mesh.nodes)[np.asarray(obj.mesh.tets)]
        edges = nodes[:, 1:] - nodes[:, :1]
        barycentric = np.linalg.solve(edges.transpose(0, 2, 1), (point - nodes[:, 0])[:, :, None])[:, :, 0]
        # Closed tets: a point on a face shared by two tets (a grid line) is inside.
        return bool(np.any(np.all(barycentric >= -1e-12, axis=1) & (barycentric.sum(axis=1) <= 1.0 + 1e-12)))
    mesh = obj.mesh_in_world()
    offsets = np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles[:, 0])
    assert mesh.is_convex
    return bool(np.all(mesh.face_normals @ point < offsets))


@pytest.mark.parametrize("name", BUILTIN)
def test_surface_frames_are_rigid_and_their_z_points_out_of_the_object(name, loaded):
    scene = loaded(name).scene
    for surface in scene.surfaces.values():
        rotation = surface.transform_surface_to_world[:3, :3]
        np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
        assert np.linalg.det(rotation) == pytest.approx(1.0)
        for corner in surface.polygon:
            point = surface.point_in_world(*(0.9 * corner + 0.1 * surface.centroid))
            assert not _inside_object(scene, surface.object_name, point + 1e-3 * surface.normal_in_world)
            assert _inside_object(scene, surface.object_name, point - 1e-3 * surface.normal_in_world)


def test_soles_stand_where_talos_stands(loaded):
    stance = loaded("stand").stance("stand")
    scene = loaded("stand").scene
    np.testing.assert_allclose(scene.print_origin_in_world(stance.contact("left_sole")), [0, 0.085, 0])
    np.testing.assert_allclose(scene.print_origin_in_world(stance.contact("right_sole")), [0, -0.085, 0])


@pytest.mark.parametrize(
    "name, robot_surface, low, high",
    [
        ("hand-on-table", "right_palm", [0.45, -0.3, 0.79], [0.55, -0.2, 0.81]),
        ("hand-on-cube", "right_palm", [0.45, -0.3, 0.99], [0.55, -0.2, 1.01]),
        ("foot-on-block", "right_sole", [0.15, -0.25, 0.19], [0.45, 0.0, 0.21]),
    ],
)
def test_hand_and_foot_prints_are_where_the_scenario_says(name, robot_surface, low, high, loaded):
    scenario = loaded(name)
    origin = scenario.scene.print_origin_in_world(scenario.stance(name).contact(robot_surface))
    assert np.all(origin >= low) and np.all(origin <= high), origin


def test_soft_cube_scenarios_differ_only_in_young_modulus(loaded):
    stiff, soft = loaded("hand-on-cube"), loaded("hand-on-soft-cube")
    assert stiff.scene.deformable("cube").body.material.young_modulus == 1e6
    assert soft.scene.deformable("cube").body.material.young_modulus == 5e5
    assert stiff.stance("hand-on-cube") == soft.stance("hand-on-soft-cube")


@pytest.mark.parametrize("name", ["cross-soft-block", "climb-with-soft-support"])
def test_planner_scenarios_start_away_from_the_goal_and_can_reach_it(name, loaded):
    scenario = loaded(name)
    goal, scene = scenario.goal, scenario.scene
    assert not goal.is_satisfied(scenario.start_stance, scene)
    assert goal.distance(scenario.start_stance, scene) > 0.5
    final = list(scenario.stances.values())[-1]
    assert goal.is_satisfied(final, scene) and goal.distance(final, scene) == 0.0
    assert scenario.options["print_spacing"] > 0 and scenario.options["theta_values_deg"] == [0]
    assert any(surface.deformable for surface in scene.surfaces.values())


def test_foam_block_lies_across_the_way(loaded):
    foam = loaded("cross-soft-block").scene.deformable("foam")
    nodes = foam.points_in_world(foam.mesh.nodes)
    np.testing.assert_allclose(nodes.min(axis=0), [0.35, -0.6, 0.0], atol=1e-12)
    np.testing.assert_allclose(nodes.max(axis=0), [0.65, 0.6, 0.1], atol=1e-12)


def test_unknown_builtin_name_lists_the_builtins():
    with pytest.raises(ScenarioError, match="built-in scenarios: climb-with-soft-support"):
        load("hand-on-sofa")


# --------------------------------------------------------------- malformed files
GOOD = """\
robot: talos
description: test
objects:
  - {name: floor, type: floor}
  - {name: table, type: box, size: [0.6, 0.8, 0.8], center: [0.65, -0.25, 0.4]}
stances:
  stand:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
  reach:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_palm: {surface: table_top, x: -0.2, y: 0.0, theta_deg: 90}
start: stand
goal: {stance: reach}
options: {print_spacing: 0.1}
"""


def write(tmp_path, text, name="case.yaml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_a_well_formed_file_loads_with_degrees_converted(tmp_path):
    scenario = load(write(tmp_path, GOOD))
    assert scenario.name == "case"
    assert scenario.stance("reach").contact("right_palm").contact_print.theta == pytest.approx(math.pi / 2)
    assert scenario.goal.contacts == scenario.stance("reach").contacts
    with pytest.raises(SceneError, match="stances: reach, stand"):
        scenario.stance("sit")


@pytest.mark.parametrize(
    "old, new, key, message",
    [
        ("  - {name: table, type: box, size: [0.6, 0.8, 0.8], center: [0.65, -0.25, 0.4]}",
         "  - {name: table, type: box, size: [0.6, 0.8, 0.8]}", "objects[1]", "missing key 'center'"),
        ("size: [0.6, 0.8, 0.8]", "size: [0.6, 0.8]", "objects[1].size", "list of 3 numbers"),
        ("size: [0.6, 0.8, 0.8]", "size: [0.6, tall, 0.8]", "objects[1].size[1]", "must be a number"),
        ("right_palm: {surface: table_top,", "right_palm: {surface: tabel_top,", "stances.reach.right_palm.surface",
         "unknown surface 'tabel_top'; known surfaces: floor, table_top"),
        ("right_palm: {surface: table_top, x: -0.2,", "right_palm: {surface: table_top, x: -0.5,",
         "stances.reach.right_palm", "off surface 'table_top'"),
        ("y: -0.085}\n  reach", "y: -0.085, z: 1}\n  reach", "stances.stand.right_sole.z",
         "unknown key 'z'; valid keys: surface, x, y, theta, theta_deg"),
        ("start: stand", "start: sit", "start", "unknown stance 'sit'; stances: reach, stand"),
        ("type: floor", "type: flor", "objects[0].type", "valid types: floor, box, soft_box, soft_blocks, mesh"),
        ("center: [0.65", "centre: [0.65", "objects[1].centre", "unknown key 'centre'"),
        ("goal: {stance: reach}", "goal: {stance: reach, regions: [{robot_surface: left_sole, lower: [1, 0]}]}",
         "goal.regions[0]", "missing key 'upper'"),
        ("options: {print_spacing: 0.1}", "options: [0.1]", "options", "must be a mapping"),
    ],
    ids=["missing-key", "short-vector", "not-a-number", "unknown-surface", "print-off-surface", "unknown-print-key",
         "unknown-start", "unknown-type", "misspelt-key", "goal-region-missing-upper", "options-not-mapping"],
)
def test_malformed_file_raises_scenario_error_naming_file_key_and_line(tmp_path, old, new, key, message, request):
    assert old in GOOD
    path = write(tmp_path, GOOD.replace(old, new))
    with pytest.raises(ScenarioError) as info:
        load(path)
    error = info.value
    assert error.path == str(path) and error.key == key
    assert message in str(error)
    assert str(error).startswith(f"{path}:{error.line}: {key}: ")
    # The line points at the offending entry (lines of GOOD: objects 4-5, stances 7-12, start 13, ...).
    expected_line = {
        "missing-key": 5, "short-vector": 5, "not-a-number": 5, "unknown-surface": 12, "print-off-surface": 12,
        "unknown-print-key": 9, "unknown-start": 13, "unknown-type": 4, "misspelt-key": 5,
        "goal-region-missing-upper": 14, "options-not-mapping": 15,
    }[request.node.callspec.id]
    assert error.line == expected_line


def test_yaml_syntax_error_reports_its_line(tmp_path):
    path = write(tmp_path, GOOD.replace("  reach:\n", "  reach: [\n"))
    with pytest.raises(ScenarioError, match="YAML syntax error") as info:
        load(path)
    assert info.value.line is not None and 10 <= info.value.line <= 13
    assert str(info.value).startswith(f"{path}:{info.value.line}:")


def test_missing_top_level_key_and_empty_file(tmp_path):
    with pytest.raises(ScenarioError, match="missing key 'stances'"):
        load(write(tmp_path, "objects:\n  - {name: floor, type: floor}\n"))
    with pytest.raises(ScenarioError, match="missing key 'objects'"):
        load(write(tmp_path, "", name="empty.yaml"))


def test_bad_friction_override_and_unknown_surface_override(tmp_path):
    with pytest.raises(ScenarioError, match="surfaces.table_top.friction: must be > 0"):
        load(write(tmp_path, GOOD + "surfaces: {table_top: {friction: -1}}\n"))
    with pytest.raises(ScenarioError, match="surfaces.tabletop: unknown surface 'tabletop'; known surfaces: floor, table_top"):
        load(write(tmp_path, GOOD + "surfaces: {tabletop: {friction: 0.5}}\n"))
    scenario = load(write(tmp_path, GOOD + "surfaces: {table_top: {friction: 0.4}}\n"))
    assert scenario.scene.surface("table_top").friction == 0.4


def test_mesh_objects_are_read_relative_to_the_file_with_declared_surfaces(tmp_path):
    trimesh.creation.box(extents=(0.4, 0.4, 0.2)).export(tmp_path / "step.stl")
    text = GOOD.replace(
        "stances:",
        "  - name: step\n    type: mesh\n    file: step.stl\n    center: [1.0, 0.5, 0.1]\n"  # clear of the table
        "    surfaces:\n      - {name: step_top, polygon: [[-0.2, -0.2], [0.2, -0.2], [0.2, 0.2], [-0.2, 0.2]],"
        " origin: [0, 0, 0.1], friction: 0.6}\nstances:",
    )
    scenario = load(write(tmp_path, text))
    surface = scenario.scene.surface("step_top")
    np.testing.assert_allclose(surface.point_in_world(0, 0), [1.0, 0.5, 0.2])
    names = [name for name, _ in scenario.scene.collision_objects()]
    assert names == ["floor", "table", "step"]
    with pytest.raises(ScenarioError, match=r"objects\[2\].file: mesh file not found"):
        load(write(tmp_path, text.replace("file: step.stl", "file: stair.stl")))
    clockwise = text.replace("[[-0.2, -0.2], [0.2, -0.2], [0.2, 0.2], [-0.2, 0.2]]", "[[-0.2, -0.2], [-0.2, 0.2], [0.2, 0.2], [0.2, -0.2]]")
    with pytest.raises(ScenarioError, match=r"objects\[2\].surfaces\[0\]: .*counter-clockwise"):
        load(write(tmp_path, clockwise))


def test_soft_box_material_errors_name_the_material_key(tmp_path):
    soft = GOOD.replace(
        "stances:",
        "  - {name: cube, type: soft_box, size: [0.3, 0.3, 0.3], center: [1.2, 0, 0.15],"  # clear of the table
        " material: {E: 1e6, nu: 0.5}, resolution: coarse}\nstances:",
    )
    # Named by the file's keys (E, nu, rho), not fem's field names.
    with pytest.raises(ScenarioError, match=r"objects\[2\].material.nu: must lie in \(-1, 0.5\), got 0.5; "):
        load(write(tmp_path, soft))
    with pytest.raises(ScenarioError, match=r"objects\[2\].material.rho: must be >= 0 kg/m\^3, got -1$"):
        load(write(tmp_path, soft.replace("nu: 0.5", "nu: 0.3, rho: -1")))
    # "1e6" is a string in YAML 1.1: accepted as a number all the same.
    scenario = load(write(tmp_path, soft.replace("nu: 0.5", "nu: 0.3")))
    assert scenario.scene.deformable("cube").body.material.young_modulus == 1e6
    with pytest.raises(ScenarioError, match=r"objects\[2\].resolution: unknown resolution 'fine'"):
        load(write(tmp_path, soft.replace("coarse", "fine")))
    # So is a spacing written "5e-2": the same mesh as 0.05, and its errors a number's.
    spaced = load(write(tmp_path, soft.replace("nu: 0.5", "nu: 0.3").replace("coarse", "5e-2")))
    assert np.array_equal(spaced.scene.deformable("cube").body.mesh.nodes, scenario.scene.deformable("cube").body.mesh.nodes)
    with pytest.raises(ScenarioError, match=r"objects\[2\].resolution: must be > 0, got -0.05$"):
        load(write(tmp_path, soft.replace("nu: 0.5", "nu: 0.3").replace("coarse", "-5e-2")))


def test_the_paper_like_coarse_cube_has_its_grid_and_the_palm_print_on_its_nodes(loaded):
    """hand-on-coarse-cube: 180 nodes and 600 tets (the paper's 166 and 570), the
    palm's print on grid lines, so its four corners are the print's nodes."""
    scenario = loaded("hand-on-coarse-cube")
    cube = scenario.scene.deformable("cube")
    assert cube.body.mesh.nodes.shape == (180, 3) and cube.body.mesh.tets.shape == (600, 4)
    default = loaded("hand-on-cube")
    assert scenario.stance("hand-on-cube") == default.stance("hand-on-cube")
    np.testing.assert_array_equal(cube.transform_body_to_world, default.scene.deformable("cube").transform_body_to_world)
    # The palm's print (10 x 7 cm at x = -0.40, y = 0.05 on the top): its corners.
    top = cube.body.mesh.nodes[cube.body.mesh.nodes[:, 2] == 1.0]
    corners = {(x, y) for x in (-0.45, -0.35) for y in (0.015, 0.085)}
    assert corners <= {tuple(np.round(p[:2], 9)) for p in top}


SOFT_GRID = """\
objects:
  - {name: floor, type: floor}
  - name: cube
    type: soft_box
    size: [1.0, 1.0, 0.5]
    center: [1.0, 0.0, 0.25]
    material: {E: 1.0e+6, nu: 0.4}
    grid: {x: [-0.5, 0.0, 0.5], y: [-0.5, 0.1, 0.5], z: [0.0, 0.2, 0.5]}
stances:
  stand:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
"""


def test_a_soft_box_grid_gives_its_grid_lines(tmp_path):
    cube = load(write(tmp_path, SOFT_GRID)).scene.deformable("cube")
    nodes = cube.body.mesh.nodes
    assert nodes.shape == (27, 3)
    for axis, lines in enumerate(([-0.5, 0.0, 0.5], [-0.5, 0.1, 0.5], [0.0, 0.2, 0.5])):
        np.testing.assert_array_equal(np.unique(nodes[:, axis]), lines)


@pytest.mark.parametrize(
    "old, new, key, message",
    [
        ("x: [-0.5, 0.0, 0.5]", "x: [-0.5, 0.0, 0.4]", "objects[1]", "grid xs must run from -0.5 to 0.5 m"),
        ("z: [0.0, 0.2, 0.5]", "z: [0.0, 0.3, 0.2, 0.5]", "objects[1]", "grid zs must be strictly increasing, got [0.0, 0.3, 0.2, 0.5]"),
        ("y: [-0.5, 0.1, 0.5]", "y: [0.5]", "objects[1]", "grid ys must be a list of at least two finite numbers"),
        ("y: [-0.5, 0.1, 0.5]", "y: 0.5", "objects[1].grid.y", "must be a list of numbers, got float 0.5"),
        ("y: [-0.5, 0.1, 0.5]", "y: [-0.5, wide, 0.5]", "objects[1].grid.y[1]", "must be a number, got 'wide'"),
        (", z: [0.0, 0.2, 0.5]}", "}", "objects[1].grid", "missing key 'z'"),
        ("    grid:", "    resolution: coarse\n    grid:", "objects[1].grid",
         "a grid fixes every grid line: remove 'resolution' or the grid"),
    ],
    ids=["wrong-end", "not-increasing", "one-line", "not-a-list", "not-a-number", "missing-axis", "with-resolution"],
)
def test_a_bad_soft_box_grid_is_refused_naming_the_key(tmp_path, old, new, key, message):
    assert old in SOFT_GRID
    with pytest.raises(ScenarioError) as info:
        load(write(tmp_path, SOFT_GRID.replace(old, new)))
    assert info.value.key == key
    assert message in str(info.value)
