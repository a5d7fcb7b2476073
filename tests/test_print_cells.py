"""A flat print on cells too coarse for it is refused as a mesh too coarse, not answered.

hand-on-cube refines its cube's top where the palm lands; cells grow away from there to
9 cm. A palm moved to the far corner covers about one cell (4 nodes): its force lay 21-36 %
below the same palm's on the default resolution (``environments.DEFAULT_MINIMUM_PRINT_CELLS``).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import environments
import stances
from cbm.rejections import cause_of
from environments.deformable import DEFAULT_MINIMUM_PRINT_CELLS, DeformableObject
from environments.errors import SceneError
from stances.problem import build_problem
from stances.stages import posture_options

_FAR = "right_palm: {surface: cube_top, x: 0.35, y: -0.35, theta_deg: 0}"


def _palm_in_the_far_corner(extra: str = ""):
    text = environments.builtin_scenario_path("hand-on-cube").read_text()
    text = text.replace("right_palm: {surface: cube_top, x: -0.40, y: 0.05, theta_deg: 0}", _FAR)
    assert _FAR in text
    if extra:
        text = text.replace("    refine: [[-0.5, -0.2], [-0.2, 0.3]]", f"    refine: [[-0.5, -0.2], [-0.2, 0.3]]\n    {extra}")
        assert extra in text
    return environments.load_string(text, name="hand-on-cube")


def test_a_palm_on_cells_too_coarse_for_it_is_refused_with_the_reason(robot):
    scenario = _palm_in_the_far_corner()
    with pytest.raises(stances.StanceError) as raised:
        build_problem(robot, scenario.scene, scenario.stance("hand-on-cube"), posture_options({}))
    message = str(raised.value)
    found = re.search(r"the print of right_palm on cube_top covers (\d+\.\d) cells of the mesh under it; at least "
                      r"4 are needed for its force", message)
    assert found and float(found.group(1)) < DEFAULT_MINIMUM_PRINT_CELLS
    assert "refine the mesh of 'cube' where prints land" in message and "minimum_print_cells" in message
    assert cause_of(message) == "soft mesh too coarse for the print"
    # Where prints land (the refined region) it covers 15 cells and is built.
    scenario = environments.load("hand-on-cube")
    build_problem(robot, scenario.scene, scenario.stance("hand-on-cube"), posture_options({}))


def test_a_soft_box_may_accept_coarser_prints_by_its_own_minimum(robot):
    scenario = _palm_in_the_far_corner("minimum_print_cells: 0.5")
    (cube,) = scenario.scene.deformable_objects
    assert cube.minimum_print_cells == 0.5
    problem = build_problem(robot, scenario.scene, scenario.stance("hand-on-cube"), posture_options({}))
    assert problem.contacts


@pytest.mark.parametrize("value", [-1.0, np.inf, True, "4"])
def test_a_minimum_print_cells_that_is_no_count_is_refused(value):
    body = environments.load("hand-on-cube").scene.deformable_objects[0]
    with pytest.raises(SceneError, match=r"object 'cube': minimum_print_cells must be a number of mesh cells >= 0"):
        DeformableObject("cube", body.body, np.eye(4), minimum_print_cells=value)


def test_a_scenario_minimum_print_cells_below_zero_is_refused_where_it_is_written():
    text = environments.builtin_scenario_path("hand-on-cube").read_text().replace(
        "    refine: [[-0.5, -0.2], [-0.2, 0.3]]", "    refine: [[-0.5, -0.2], [-0.2, 0.3]]\n    minimum_print_cells: -2")
    with pytest.raises(environments.ScenarioError, match=r"objects\[1\]\.minimum_print_cells: must be a number of mesh "
                                                         r"cells >= 0 \(0: any print\), got -2"):
        environments.load_string(text, name="hand-on-cube")


def test_every_soft_object_type_takes_its_minimum_print_cells():
    """foot-and-hand-on-foam's step is a soft_blocks object: the key reaches it as a soft box's does."""
    text = environments.builtin_scenario_path("foot-and-hand-on-foam").read_text()
    assert "    type: soft_blocks\n" in text
    text = text.replace("    type: soft_blocks\n", "    type: soft_blocks\n    minimum_print_cells: 9.5\n")
    (step,) = environments.load_string(text, name="foot-and-hand-on-foam").scene.deformable_objects
    assert step.minimum_print_cells == 9.5
