"""Refine lines: bands of fine cells on a soft box's top face where ball feet land.

A ball foot's contact radius (5-9 mm for ANYmal's 31 mm foot) is below the cells a whole
region can afford; bands along the planner's print lines give those cells where the
balls land and nowhere else.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import environments
import fem
from environments.deformable import RefineLines, soft_box_coordinates
from environments.refinement import refined
from test_ball_contact import RADIUS, ball_force

FOAM = fem.LinearElasticMaterial(3e6, 0.4, 100.0)
BLOCK = (0.2, 0.2, 0.05)  # metres: a 5 cm foam block, base fixed


def centre_force(coordinates, depth: float) -> float:
    """Normal force (N) of a ball pressed ``depth`` (m) into the top centre of the block meshed
    on ``coordinates`` (every top node it reaches 2.5 mm deep may touch)."""
    mesh = fem.tensor_mesh(*coordinates)
    body = fem.DeformableBody(mesh, FOAM, np.flatnonzero(mesh.nodes[:, 2] < 1e-12), cache=False)
    return ball_force(body, (0.0, 0.0), depth, reach=0.013)[0]


def test_bands_have_cells_of_their_resolution_and_the_rest_is_the_boxs_mesh():
    lines = RefineLines(x=[-0.05, 0.03], y=[0.0], half_width=0.015, resolution=0.005)
    xs, ys, zs = soft_box_coordinates(BLOCK, 0.01, refine_lines=lines)
    base_xs, base_ys, base_zs = soft_box_coordinates(BLOCK, 0.01)
    for coordinates, centres, base in ((xs, lines.x, base_xs), (ys, lines.y, base_ys)):
        for centre in centres:
            band = coordinates[np.abs(coordinates - centre) <= 0.015 + 1e-12]
            np.testing.assert_allclose(band, centre + 0.005 * np.arange(-3, 4), atol=1e-12)
        far = base[np.min(np.abs(base[:, None] - np.asarray(centres)[None, :]), axis=1) > 0.015 + 0.006]
        assert np.all(np.isin(far.round(12), coordinates.round(12)))  # the box's own lines away from the bands
    # The top layer is the bands' resolution, the layers under it thicken by 1.5 (5, 7.5,
    # 11.25 mm) while thinner than the box's own there; the box's heights below stay.
    layers = np.diff(zs)[::-1]
    assert layers[0] == pytest.approx(0.005, rel=1e-9) and np.all(layers[1:3] / layers[:2] == pytest.approx(1.5))
    graded_bottom = BLOCK[2] - layers[:3].sum()
    assert zs[0] == 0.0 and zs[-1] == BLOCK[2]
    assert np.all(np.isin(base_zs[base_zs < graded_bottom - 1e-9].round(12), zs.round(12)))
    # Out of a band, cells grow by 1.5 to the box's own: no neighbours more than 1.5 apart here.
    cells = np.diff(xs)
    assert np.max(np.maximum(cells[1:] / cells[:-1], cells[:-1] / cells[1:])) <= 1.5 + 1e-9


@pytest.mark.parametrize("spacing", [0.006, 0.007, 0.0075, 0.008])
def test_the_top_layer_is_the_bands_resolution_even_when_the_box_is_nearly_as_fine(spacing):
    _, _, zs = soft_box_coordinates((0.4, 0.4, 0.1), spacing, refine_lines=RefineLines([0.0], [0.0], 0.015, 0.005))
    layers = np.diff(zs)[::-1]
    assert layers[0] == pytest.approx(0.005, rel=1e-9)
    assert np.all(np.diff(zs) > 0.0) and layers.min() >= 0.005 * (1 - 1e-9)
    assert np.max(layers[1:] / layers[:-1]) < 2.0  # no layer twice as thick as the one above it


def test_a_balls_force_on_5_mm_bands_is_within_5_percent_of_bands_twice_as_fine():
    # Measured: 10 mm mesh 28.3 / 60.6 / 103.7 N at 0.7 / 1.5 / 2.5 mm; 5 mm bands 18.1 /
    # 60.8 / 129.9 N; 2.5 mm bands 18.2 / 58.6 / 133.4 N (friction 0.7; an independent
    # brick-element FEM converged at 1 mm on the scene's foam: within about 5 % of those).
    coarse = soft_box_coordinates(BLOCK, 0.01)
    bands = soft_box_coordinates(BLOCK, 0.01, refine_lines=RefineLines([0.0], [0.0], 0.015, 0.005))
    finer = soft_box_coordinates(BLOCK, 0.01, refine_lines=RefineLines([0.0], [0.0], 0.015, 0.0025))
    errors_bands, errors_coarse = [], []
    for depth in (0.0007, 0.0015, 0.0025):
        reference = centre_force(finer, depth)
        errors_bands.append(centre_force(bands, depth) / reference - 1.0)
        errors_coarse.append(centre_force(coarse, depth) / reference - 1.0)
    assert np.abs(errors_bands).max() < 0.05, errors_bands
    assert np.abs(errors_coarse).max() > 0.2, errors_coarse  # what the bands are for


def test_bands_converge_to_themselves_not_to_the_continuum():
    """2.5 mm bands under a ball 2.5 mm deep: some 45 pressed nodes, yet at least 5 % over the
    continuum's force (fem.sphere_on_layer_force, within 0.5 % of converged FEMs; friction adds
    under 1 %): the layers under the bands grow by 1.5, and no count of pressed nodes says a
    node contact's force is converged. Why verify refuses a ball where no continuum estimate
    exists (bench/results/ball_node_contact.md: 9-74 nodes up to +10 %)."""
    mesh = fem.tensor_mesh(*soft_box_coordinates(BLOCK, 0.01, refine_lines=RefineLines([0.0], [0.0], 0.015, 0.0025)))
    body = fem.DeformableBody(mesh, FOAM, np.flatnonzero(mesh.nodes[:, 2] < 1e-12), cache=False)
    force, pressed, _ = ball_force(body, (0.0, 0.0), 0.0025, reach=0.013)
    continuum = fem.sphere_on_layer_force(0.0025, RADIUS, BLOCK[2], FOAM.young_modulus, FOAM.poisson_ratio)[0]
    assert pressed.size >= 40
    assert force / continuum - 1.0 > 0.05, force / continuum


def test_a_scenario_refines_a_soft_box_along_its_print_lines_and_a_refined_scenario_halves_them():
    text = environments.builtin_scenario_path("quadruped-foam").read_text()
    lines = "    refine_lines: {x: [-0.1, 0.0], y: [-0.2, 0.2], half_width: 0.01, resolution: 0.005}\n"
    marked = text.replace("    refine: [[-0.2, -0.35], [0.05, 0.35]]\n", "    refine: [[-0.2, -0.35], [0.05, 0.35]]\n" + lines)
    assert marked != text
    scenario = environments.load_string(marked, name="quadruped-foam-lines")
    nodes = scenario.scene.deformable("foam").body.mesh.nodes
    top = nodes[np.isclose(nodes[:, 2], 0.05)]
    xs = np.unique(top[:, 0].round(9))
    np.testing.assert_allclose(xs[np.abs(xs + 0.1) <= 0.01 + 1e-9], -0.1 + 0.005 * np.arange(-2, 3), atol=1e-9)
    twice = refined(scenario, 2).scene.deformable("foam").body.mesh.nodes
    xs2 = np.unique(twice[np.isclose(twice[:, 2], 0.05), 0].round(9))
    np.testing.assert_allclose(xs2[np.abs(xs2 + 0.1) <= 0.01 + 1e-9], -0.1 + 0.0025 * np.arange(-4, 5), atol=1e-9)


def _with_lines(value: str) -> str:
    text = environments.builtin_scenario_path("quadruped-foam").read_text()
    return text.replace("    refine: [[-0.2, -0.35], [0.05, 0.35]]\n",
                        "    refine: [[-0.2, -0.35], [0.05, 0.35]]\n    refine_lines: " + value + "\n")


@pytest.mark.parametrize("value, message", [
    ("{x: [-0.3]}", "objects[1].refine_lines: x = -0.3 m must lie on the top face (|x| <= 0.2 m, top-surface frame), "
                    "on an edge or at least 0.003 m inside it"),
    ("{x: [0.199]}", "objects[1].refine_lines: x = 0.199 m must lie on the top face (|x| <= 0.2 m, top-surface frame), "
                     "on an edge or at least 0.003 m inside it"),
    ("{x: [0.0], half_width: 1.0e+6, resolution: 1.0e-6}",
     "objects[1].refine_lines: give at least 1.6e+06 nodes, more than the limit of 1000000; use fewer lines"),
    ("{x: [0.0], y: [0.0], half_width: 1.0e+300, resolution: 1.0e-300}",
     "objects[1].refine_lines: give far more nodes, more than the limit of 1000000"),
    ("{x: '12'}", "objects[1].refine_lines.x: must be a list of numbers, got str '12'"),
    ("{x: [0.0], resolution: 0.02}",
     "objects[1].refine_lines: half_width (0.015 m) must be at least its resolution (0.02 m): a band narrower than a "
     "cell refines nothing"),
    ("{x: [0.0], half_width: 0.03, resolution: 0.02}",
     "objects[1].refine_lines: resolution (0.02 m) must be finer than the box's resolution (0.01 m)"),
    ("{}", "objects[1].refine_lines: needs at least one line: give x, y or both (metres, top-surface frame)"),
    ("{x: 0.1}", "objects[1].refine_lines.x: must be a list of numbers, got float 0.1"),
    ("{x: [0.0], z: [1]}", "objects[1].refine_lines.z: unknown key 'z'; valid keys: x, y, half_width, resolution"),
    ("{y: [0.0], resolution: -1}", "objects[1].refine_lines.resolution: must be > 0, got -1"),
])
def test_bad_refine_lines_are_refused_with_the_reason(value, message):
    with pytest.raises(environments.ScenarioError, match=re.escape(message)):
        environments.load_string(_with_lines(value))


def test_refine_lines_and_a_grid_are_refused_together():
    with pytest.raises(environments.SceneError, match=re.escape(
            "object 'foam': give either grid or refine_lines, not both (grid fixes every grid line)")):
        environments.soft_box("foam", BLOCK, (0, 0, 0.025), FOAM, grid=[[-0.1, 0.1], [-0.1, 0.1], [0, 0.05]],
                              refine_lines=RefineLines([0.0]))
    with pytest.raises(environments.ScenarioError, match=re.escape(
            "refine_lines: a grid fixes every grid line: remove 'refine_lines' or the grid")):
        text = _with_lines("{x: [0.0]}").replace("    resolution: 0.01\n", "").replace(
            "    refine: [[-0.2, -0.35], [0.05, 0.35]]\n",
            "    grid: {x: [-0.2, 0.2], y: [-0.5, 0.5], z: [0, 0.05]}\n")
        environments.load_string(text)
