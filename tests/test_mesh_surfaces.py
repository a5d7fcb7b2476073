"""Contact surfaces found on meshes (``surfaces: auto``): an STL staircase gives the
surfaces of the same staircase built from boxes, and Talos stands on it."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
import trimesh

import environments
import stances
from environments import ScenarioError
from environments.mesh_surfaces import SurfaceSearch, find_surfaces

# Three steps, each a box from the floor up to its tread: (depth along x, height).
# The first tread is a landing deep enough for both soles.
STEPS = ((0.5, 0.1), (0.3, 0.2), (0.3, 0.3))
WIDTH, START = 1.0, -0.25


def step_boxes():
    """(size, center) of each step, world frame, metres."""
    boxes, x = [], START
    for depth, height in STEPS:
        boxes.append(((depth, WIDTH, height), (x + 0.5 * depth, 0.0, 0.5 * height)))
        x += depth
    return boxes


def staircase_scenarios(tmp_path):
    """The staircase as boxes and as one STL (boxes concatenated) with ``surfaces: auto``."""
    parts = [trimesh.creation.box(size).apply_translation(center) for size, center in step_boxes()]
    trimesh.util.concatenate(parts).export(tmp_path / "stairs.stl")
    stance = """
        stances:
          landing:
            left_sole: {surface: SURFACE, x: 0.0, y: 0.085}
            right_sole: {surface: SURFACE, x: 0.0, y: -0.085}
        """
    boxes = "\n".join(
        f"  - {{name: step{k}, type: box, size: {list(size)}, center: {list(center)}}}"
        for k, (size, center) in enumerate(step_boxes())
    )
    box_text = "objects:\n  - {name: floor, type: floor}\n" + boxes + textwrap.dedent(stance).replace("SURFACE", "step0_top")
    mesh_text = (
        "objects:\n  - {name: floor, type: floor}\n  - {name: stairs, type: mesh, file: stairs.stl, surfaces: auto}"
        + textwrap.dedent(stance).replace("SURFACE", "stairs_top_0")
    )
    (tmp_path / "boxes.yaml").write_text(box_text)
    (tmp_path / "mesh.yaml").write_text(mesh_text)
    return environments.load(tmp_path / "boxes.yaml"), environments.load(tmp_path / "mesh.yaml")


@pytest.fixture(scope="module")
def staircase(tmp_path_factory):
    return staircase_scenarios(tmp_path_factory.mktemp("stairs"))


def same_loop(first: np.ndarray, second: np.ndarray, tolerance: float) -> bool:
    """Whether two vertex loops are the same up to the starting vertex."""
    if first.shape != second.shape:
        return False
    return any(np.abs(np.roll(second, shift, axis=0) - first).max() <= tolerance for shift in range(len(first)))


def test_treads_found_on_the_stl_are_the_box_tops(staircase):
    by_boxes, by_mesh = staircase
    tops = [by_boxes.scene.surface(f"step{k}_top") for k in range(len(STEPS))]
    found = [s for name, s in by_mesh.scene.surfaces.items() if name.startswith("stairs_top_")]
    assert [s.name for s in found] == [f"stairs_top_{k}" for k in range(len(STEPS))]  # by height
    for top, tread in zip(tops, found):
        # STL stores float32: 1e-7 relative on coordinates of about 1 m.
        assert np.allclose(tread.transform_surface_to_world, top.transform_surface_to_world, atol=1e-6)
        assert same_loop(tread.polygon, top.polygon, 1e-6)
    assert [round(s.transform_surface_to_world[2, 3], 6) for s in found] == [h for _, h in STEPS]


def test_risers_are_hand_surfaces_with_their_y_axis_up(staircase):
    _, by_mesh = staircase
    sides = [s for name, s in by_mesh.scene.surfaces.items() if name.startswith("stairs_side_")]
    risers = [s for s in sides if np.allclose(s.normal_in_world, [-1.0, 0.0, 0.0])]
    # The front of each step (the part above the step below is its riser) faces -x.
    assert len(risers) == len(STEPS)
    for riser in risers:
        assert np.allclose(riser.transform_surface_to_world[:3, 1], [0.0, 0.0, 1.0])
        assert riser.area >= SurfaceSearch().min_area


def test_a_stance_on_the_found_landing_solves_and_verifies(staircase, robot):
    _, by_mesh = staircase
    result = stances.solve(robot, by_mesh.scene, by_mesh.stance("landing"))
    assert result.feasible, result.reason
    assert stances.verify(robot, by_mesh.scene, result.stance, result).ok


def l_shaped_slab() -> trimesh.Trimesh:
    """An L of two slabs sharing a 0.3 m x 0.3 m corner square, as one mesh with shared edges."""
    profile = np.array([[0, 0], [1, 0], [1, 0.3], [0.3, 0.3], [0.3, 1], [0, 1]], dtype=float)
    count = len(profile)
    vertices = np.vstack([np.column_stack([profile, np.zeros(count)]), np.column_stack([profile, np.full(count, 0.1)])])
    faces = []
    for i in range(count):  # walls
        j = (i + 1) % count
        faces += [[i, j, count + j], [i, count + j, count + i]]
    # Top and bottom fans around the re-entrant vertex 3, whose diagonals stay inside.
    for i in (4, 5, 0, 1):
        j = (i + 1) % count
        faces += [[count + 3, count + i, count + j], [3, j, i]]
    return trimesh.Trimesh(vertices, faces, process=True)


@pytest.mark.parametrize("subdivisions", [0, 3], ids=["as-made", "finely-meshed"])
def test_a_region_that_is_not_convex_is_cut_into_convex_pieces_covering_it(subdivisions):
    slab = l_shaped_slab()
    for _ in range(subdivisions):  # 4 ** 3 triangles for each: greedy merging alone left dozens of pieces
        slab = slab.subdivide()
    assert slab.is_watertight and slab.volume > 0
    tops = [f for f in find_surfaces(slab) if f.role == "foot"]
    assert len(tops) == 2  # an L needs two convex pieces, no more
    assert sum(f.area for f in tops) == pytest.approx(0.3 + 0.7 * 0.3, rel=1e-12)
    for piece in tops:
        edges = np.roll(piece.polygon, -1, axis=0) - piece.polygon
        turns = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
        assert np.all(turns > 0.0)  # strictly convex and counter-clockwise
        assert np.allclose(piece.transform_surface_to_object[:3, 2], [0.0, 0.0, 1.0])


def test_a_mesh_wound_inward_gives_the_same_surfaces():
    slab = trimesh.creation.box((1.0, 0.5, 0.2))
    inward = slab.copy()
    inward.invert()
    assert inward.volume < 0.0
    for first, second in zip(find_surfaces(slab), find_surfaces(inward), strict=True):
        assert first.role == second.role
        assert np.allclose(first.transform_surface_to_object, second.transform_surface_to_object)


def test_min_area_slope_and_sides_select_the_pieces():
    wedge = trimesh.creation.box((1.0, 1.0, 0.2))
    tilted = wedge.copy().apply_transform(trimesh.transformations.rotation_matrix(np.radians(25.0), [0, 1, 0]))
    # Tilted 25 degrees: a hand surface at the default 20-degree bound, a foot one at 30.
    assert [f.role for f in find_surfaces(tilted, search=SurfaceSearch(sides=True))].count("foot") == 0
    assert [f.role for f in find_surfaces(tilted, search=SurfaceSearch(max_slope_deg=30.0))].count("foot") == 1
    # The 1 m x 0.2 m sides (0.2 m^2) go below a 0.25 m^2 minimum; without sides only the top is left.
    assert len(find_surfaces(wedge, search=SurfaceSearch(min_area=0.25))) == 2  # top and bottom
    assert [f.role for f in find_surfaces(wedge, search=SurfaceSearch(sides=False))] == ["foot"]


@pytest.mark.parametrize(
    "entry, message",
    [
        ("surfaces: automatic", "objects[1].surfaces: must be 'auto' or a list of surfaces, got str 'automatic'"),
        ("surfaces: auto, auto_surfaces: {max_slope_deg: 95}",
         "objects[1].auto_surfaces.max_slope_deg: must be in [0, 90) degrees, got 95"),
        ("surfaces: auto, auto_surfaces: {min_area: 0}", "objects[1].auto_surfaces.min_area: must be > 0, got 0"),
        ("auto_surfaces: {sides: false}", "objects[1].auto_surfaces: applies only with 'surfaces: auto'"),
    ],
)
def test_bad_auto_settings_are_refused(tmp_path, entry, message):
    trimesh.creation.box((1.0, 1.0, 0.2)).apply_translation((2.0, 0.0, 0.1)).export(tmp_path / "slab.stl")
    path = tmp_path / "scene.yaml"
    path.write_text(
        "objects:\n  - {name: floor, type: floor}\n"
        f"  - {{name: slab, type: mesh, file: slab.stl, {entry}}}\n"
        "stances: {stand: {left_sole: {surface: floor, y: 0.1}, right_sole: {surface: floor, y: -0.1}}}\n"
    )
    with pytest.raises(ScenarioError) as caught:
        environments.load(path)
    assert str(caught.value) == f"{path}:3: {message}"
