"""A robot that is not built in, from a user's description file, on a scene made of mesh files.

HyQ (example-robot-data's ``hyq_description``) is described in
``bench/scenes/mesh-files/robots/hyq.yaml``, outside the package, as a user would; the scene
``bench/scenes/mesh-files/hyq-mesh-scene.yaml`` is a floor, a rigid step from an STL file whose
surfaces are found on the mesh (``surfaces: auto``) and a soft foam pad meshed from a
closed STL (``type: soft_mesh``). ``bench/bench_hyq_mesh_scene.py`` plans the whole scene.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import environments
import stances
from conftest import assert_point_feet_are_their_spheres

SCENES = Path(__file__).resolve().parents[1] / "bench" / "scenes" / "mesh-files"
GRAVITY = 9.81


@pytest.fixture(scope="module")
def hyq():
    return stances.Robot.load(SCENES / "robots" / "hyq.yaml")


@pytest.fixture(scope="module")
def scenario():
    return environments.load(SCENES / "hyq-mesh-scene.yaml")


def test_the_user_file_describes_hyq_with_its_own_foot_spheres(hyq):
    """The description's radius and ball centre are those of the model's collision
    spheres (measured on the model, not guessed), and only the ball may touch."""
    assert hyq.name == "hyq" and hyq.mass == pytest.approx(86.774, abs=1e-3)  # kg, the URDF's links
    assert hyq.support.keep == 3 and len(hyq.surfaces_with_role("foot")) == 4
    assert_point_feet_are_their_spheres(hyq)


def test_the_mesh_files_give_a_rigid_step_top_and_a_soft_pad_top(scenario):
    surfaces = scenario.scene.surfaces
    assert not surfaces["step_top_0"].deformable and surfaces["pad_top_0"].deformable
    # The step is 5 cm high, the pad 4 cm thick (the STL files' own heights).
    assert surfaces["step_top_0"].transform_surface_to_world[2, 3] == pytest.approx(0.05, abs=1e-6)
    assert surfaces["pad_top_0"].transform_surface_to_world[2, 3] == pytest.approx(0.04, abs=1e-6)


def test_hyq_holds_a_foot_on_the_soft_mesh_and_the_stance_verifies(hyq, scenario):
    """A front foot on the foam pad, three on the floor: the solve is feasible, the
    independent check passes, the pad carries part of the weight through its nodes,
    and the forces balance the robot's weight.

    Left to choose, the solver puts the ball on the pad with no load (the three floor
    feet hold the robot, and a ball sinking into the pad stores energy the objective
    weighs): a stance that means the foot to bear load says so with ``min_normal_force``."""
    stance = scenario.stance("left-front-on-pad")
    free = stances.solve(hyq, scenario.scene, stance)
    assert free.feasible, free.reason
    result = stances.solve(hyq, scenario.scene, stance, min_normal_force=30.0)
    assert result.feasible, result.reason
    assert stances.verify(hyq, scenario.scene, result.stance, result).ok
    on_pad = sum(p.force for p in result.forces_on(hyq.surface("left_front_foot").frame))
    assert on_pad[2] >= 30.0 - 1e-6  # newtons: the foot bears load, not a touch
    np.testing.assert_allclose(result.total_force(), [0.0, 0.0, hyq.mass * GRAVITY], atol=1e-3 * hyq.mass * GRAVITY)
    depth = result.verification.measures["indentation of pad"]
    assert 1e-4 < depth < 0.25 * 0.04  # pressed, within the default bound (a quarter of the thickness)
    assert np.abs(result.deformations["pad"]).max() > 0.0


def test_a_plan_of_a_scenario_named_by_a_relative_path_checks_from_another_folder(tmp_path, monkeypatch):
    """The scenario, its robot file and its mesh files are given relative to where
    the user plans; the saved plan is checked from another working directory (as
    ``cbm check plan.json`` would be), and finds them all."""
    import shutil

    from cbm.plan import Plan
    from cbm.planner import plan

    work = tmp_path / "work"
    shutil.copytree(SCENES / "meshes", work / "meshes")
    shutil.copytree(SCENES / "robots", work / "robots")
    shutil.copy(SCENES / "hyq-mesh-scene.yaml", work)
    monkeypatch.chdir(work)
    planned = plan(environments.load("hyq-mesh-scene.yaml"), robot=stances.Robot.load("robots/hyq.yaml"), max_expansions=1)
    saved = planned.save(Path("plan.json").resolve())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    report = Plan.load(saved).check()
    assert report.ok, report.problems


def test_cbm_scenarios_lists_the_surfaces_found_on_the_mesh_files(capsys):
    """A user writing stances on a scene of mesh files needs the names ``surfaces: auto``
    gave and where their prints go: ``cbm scenarios FILE`` prints them."""
    from cbm.cli import main

    assert main(["scenarios", str(SCENES / "hyq-mesh-scene.yaml")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("hyq-mesh-scene\n") and "stances: start (start), left-front-on-pad" in out
    assert (
        "pad_top_0: soft, on pad; frame origin (0.700, 0.000, 0.040) m, normal (0.00, 0.00, 1.00), world; "
        "spans x -0.180..0.180 m, y -0.430..0.430 m in its own frame (prints are given there)"
    ) in out
    assert "step_top_0: rigid, on step; frame origin (1.225, 0.000, 0.050) m" in out
