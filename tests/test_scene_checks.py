"""Scenes that make sense: a soft object rests on something, objects do not overlap,
unless the file says so; each refusal names the objects and says what to write."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import trimesh

import environments
from environments import ScenarioError
from environments.scene_checks import find_overlaps

STANCES = "stances: {stand: {left_sole: {surface: floor, y: 0.1}, right_sole: {surface: floor, y: -0.1}}}\n"
CUBE = "{name: cube, type: soft_box, size: [0.5, 0.5, 0.5], center: [1.0, 0.0, CZ], material: {E: 1.0e+6, nu: 0.4}, resolution: coarse"


def scenario_file(tmp_path, objects: list[str], extra: str = ""):
    path = tmp_path / "scene.yaml"
    path.write_text("objects:\n" + "".join(f"  - {entry}\n" for entry in objects) + extra + STANCES)
    return path


def refusal(path) -> str:
    with pytest.raises(ScenarioError) as caught:
        environments.load(path)
    return str(caught.value)


def test_a_soft_box_floating_above_the_floor_is_refused_unless_declared(tmp_path):
    floating = CUBE.replace("CZ", "0.95")  # base at z = 0.7
    declared = environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", floating + ", floating: true}"]))
    nodes = declared.scene.deformable("cube").body.fixed_nodes.size  # its whole base
    path = scenario_file(tmp_path, ["{name: floor, type: floor}", floating + "}"])
    assert refusal(path) == (
        f"{path}:3: objects[1]: soft object 'cube' is fixed at {nodes} node(s) that rest on no rigid object (the "
        "lowest at z = 0.7 m): put its fixed part on the floor or on a rigid object, or write 'floating: true' on it "
        "if something else holds it"
    )
    # On the floor it loads.
    environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", CUBE.replace("CZ", "0.25") + "}"]))


def test_a_soft_box_sunk_into_the_floor_is_named_as_overlapping_it(tmp_path):
    """Not as resting on nothing (a new user's mat centred on the floor's plane was said to
    rest on no rigid object, as if it floated)."""
    sunk = CUBE.replace("CZ", "0.0") + "}"  # half of it below the floor's top
    message = refusal(scenario_file(tmp_path, ["{name: floor, type: floor}", sunk]))
    assert "objects[1]: objects 'floor' and 'cube' overlap (" in message
    assert message.endswith("move one, or list the pair in allowed_overlaps if it is intended, e.g. "
                            "allowed_overlaps: [[floor, cube]]")


def test_a_soft_object_may_rest_on_a_rigid_box(tmp_path):
    table = "{name: table, type: box, size: [0.8, 0.8, 0.3], center: [1.0, 0.0, 0.15]}"
    on_table = CUBE.replace("CZ", "0.55") + "}"  # base at z = 0.3, the table's top
    environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", table, on_table]))
    overhanging = on_table.replace("center: [1.0,", "center: [1.5,")  # half of its base past the table's edge
    message = refusal(scenario_file(tmp_path, ["{name: floor, type: floor}", table, overhanging]))
    assert "objects[2]: soft object 'cube' is fixed at" in message and "(the lowest at z = 0.3 m)" in message


def test_a_rigid_box_resting_on_a_soft_one_is_refused_unless_declared(tmp_path):
    """A rigid object is fixed in the world: a crate on a soft cube would leave the cube
    carrying nothing (a new user's crate on a mat: Talos stood on it with 271 N, the mat
    with none)."""
    cube = CUBE.replace("CZ", "0.25") + "}"  # top at z = 0.5
    crate = "{name: crate, type: box, size: [0.2, 0.2, 0.2], center: [1.0, 0.1, 0.6]"  # on the cube's top
    path = scenario_file(tmp_path, ["{name: floor, type: floor}", cube, crate + "}"])
    assert refusal(path) == (
        f"{path}:4: objects[2]: rigid object 'crate' rests on soft object 'cube' (on 'cube_top'): rigid objects are "
        "fixed in the world, so 'cube' would carry none of its weight nor of what stands on it; make it soft, move it "
        "onto a rigid object, or write 'floating: true' on it if something else holds it"
    )
    environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", cube, crate + ", floating: true}"]))
    # A board wider than the cube, its corners beyond the cube's top, still rests on it.
    board = "{name: board, type: box, size: [0.8, 0.8, 0.02], center: [1.0, 0.0, 0.51]}"
    assert "rigid object 'board' rests on soft object 'cube'" in refusal(
        scenario_file(tmp_path, ["{name: floor, type: floor}", cube, board]))
    # A board far wider than the cube, off its centre: none of the board's sample points
    # is on the cube's top, the cube's are under the board.
    wide = "{name: board, type: box, size: [3.0, 3.0, 0.02], center: [2.0, 0.0, 0.51]}"
    assert "rigid object 'board' rests on soft object 'cube'" in refusal(
        scenario_file(tmp_path, ["{name: floor, type: floor}", cube, wide]))
    # Beside the cube, on the floor, and a shelf two centimetres above it: no contact.
    beside = "{name: crate, type: box, size: [0.2, 0.2, 0.2], center: [1.5, 0.0, 0.1]}"
    above = "{name: shelf, type: box, size: [0.2, 0.2, 0.02], center: [1.0, 0.0, 0.53]}"
    environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", cube, beside]))
    environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", cube, above]))


def test_a_rigid_slab_inside_a_soft_cube_is_refused_unless_allowed(tmp_path, caplog):
    # The case: a slab filling 60 % of the cube.
    slab = "{name: slab, type: box, size: [0.5, 0.5, 0.3], center: [1.0, 0.0, 0.15]}"
    objects = ["{name: floor, type: floor}", slab, CUBE.replace("CZ", "0.25") + "}"]
    path = scenario_file(tmp_path, objects)
    # Each box is sampled on a 4 x 4 x 4 grid of cell centres: the slab's 64 are in
    # the cube, and the cube's two lower layers (z = 1/16 and 3/16 of 0.5 m) in the slab.
    assert refusal(path) == (
        f"{path}:4: objects[2]: objects 'slab' and 'cube' overlap ({64 + 32} sample point(s) of one lie inside the other): "
        "move one, or list the pair in allowed_overlaps if it is intended, e.g. allowed_overlaps: [[slab, cube]]"
    )
    with caplog.at_level(logging.DEBUG, logger="environments.scene_checks"):
        environments.load(scenario_file(tmp_path, objects, "allowed_overlaps: [[cube, slab]]\n"))
    assert caplog.messages == ["objects 'slab' and 'cube' overlap, as declared in allowed_overlaps"]
    path = scenario_file(tmp_path, objects, "allowed_overlaps: [[cube, slap]]\n")
    assert refusal(path) == f"{path}:5: allowed_overlaps[0]: unknown object 'slap'; objects: cube, floor, slab"


def test_touching_objects_do_not_overlap_and_meshes_are_tested_inside(tmp_path):
    step = trimesh.creation.box((0.5, 1.0, 0.2)).apply_translation((0.25, 0.0, 0.1))
    step.export(tmp_path / "step.stl")
    mesh = "{name: step, type: mesh, file: step.stl, surfaces: auto}"
    touching = "{name: crate, type: box, size: [0.4, 1.0, 0.4], center: [0.7, 0.0, 0.2]}"  # against the step's +x face
    scenario = environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", mesh, touching]))
    assert find_overlaps(scenario.scene) == []
    # 1 cm into the step: the crate's face is not a sample, the step's inward face
    # centres (2 mm in) near x = 0.5 are inside the crate.
    into = touching.replace("center: [0.7,", "center: [0.69,")
    message = refusal(scenario_file(tmp_path, ["{name: floor, type: floor}", mesh, into]))
    assert "objects[2]: objects 'step' and 'crate' overlap (" in message
    # And a point test on the mesh itself (winding number): the crate's grid inside the step.
    inside = "{name: crate, type: box, size: [0.2, 0.2, 0.1], center: [0.25, 0.0, 0.1]}"
    scene = environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", mesh, inside],
                                            "allowed_overlaps: [[step, crate]]\n")).scene
    assert find_overlaps(scene) == [("step", "crate", 64)]  # all 4 x 4 x 4 grid points of the crate


def test_a_rigid_shelf_against_a_soft_wall_does_not_rest_on_it(tmp_path):
    """Only a soft surface that faces up carries what rests on it: a shelf whose base edge
    touches a soft mesh's side wall (a contact surface of its own) is not refused."""
    trimesh.creation.box((0.5, 0.5, 0.5)).export(tmp_path / "pad.stl")
    pad = ("{name: pad, type: soft_mesh, file: pad.stl, position: [1.0, 0.0, 0.25], fixed: {plane: z = 0}, "
           "surfaces: auto, auto_surfaces: {sides: true}, material: {E: 1.0e+5, nu: 0.45}, resolution: coarse}")
    shelf = "{name: shelf, type: box, size: [0.2, 0.2, 0.02], center: [1.35, 0.0, 0.26]}"
    scenario = environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", pad, shelf]))
    assert any("side" in name for name in scenario.scene.surfaces)  # the wall is a soft contact surface


def test_a_soft_mesh_fixed_on_a_table_top_rests_on_it(tmp_path):
    trimesh.creation.box((0.4, 0.4, 0.1)).export(tmp_path / "cushion.stl")
    table = "{name: table, type: box, size: [0.8, 0.8, 0.3], center: [1.0, 0.0, 0.15]}"
    cushion = ("{name: cushion, type: soft_mesh, file: cushion.stl, position: [1.0, 0.0, 0.35], fixed: {plane: z = 0.3}, "
               "material: {E: 1.0e+5, nu: 0.45}, resolution: coarse}")
    scenario = environments.load(scenario_file(tmp_path, ["{name: floor, type: floor}", table, cushion]))
    assert np.isclose(scenario.scene.surface("cushion_top_0").transform_surface_to_world[2, 3], 0.4)
    path = scenario_file(tmp_path, ["{name: floor, type: floor}", cushion])
    assert "objects[1]: soft object 'cushion' is fixed at" in refusal(path)
