"""End to end with the real posture solver: planning the built-in multi-step scenarios, the CLI."""

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import environments

from cbm.cli import main
from cbm.plan import Plan
from cbm.planner import plan
from cbm.stance_graph import differ_by_one_contact

from clearance import robot_clearances
from stances.problem import PostureOptions
from test_cbm_output import chromium_binary, page_status

MULTI_STEP = ["cross-soft-block", "climb-with-soft-support"]
# Coarse settings: the scenarios' own print grids, a tight expansion budget, and
# the solver's iteration cap lowered (a converging solve takes < 30 iterations
# on these stances; a failing one otherwise spends 100 before it gives up).
COARSE = {"max_expansions": 40, "time_limit": 240.0, "solver_options": {"max_iterations": 40}}


@pytest.fixture(scope="module", params=MULTI_STEP)
def planned(request, tmp_path_factory):
    """A plan of a user's scenario file (a copy of the built-in one under another name)."""
    user_file = tmp_path_factory.mktemp("user") / f"my-{request.param}.yaml"
    shutil.copy(environments.builtin_scenario_path(request.param), user_file)
    scenario = environments.load(user_file)
    return scenario, plan(scenario, **COARSE)


def test_multi_step_scenario_plans_with_verified_stances(planned):
    scenario, result = planned
    assert result.success, result.reason
    assert len(result.stances) >= 4
    assert result.stances[0].stance == scenario.start_stance
    assert scenario.goal.is_satisfied(result.stances[-1].stance, scenario.scene)
    for before, after in zip(result.stances, result.stances[1:]):
        assert differ_by_one_contact(before.stance, after.stance)
    report = result.check(scenario)
    assert report.ok, report.problems
    # Solved with max_iterations=40: recorded, so the check verifies with it.
    assert all(s.result.statistics["options"] == {"max_iterations": 40} for s in result.stances)


def test_check_verifies_what_the_plan_shows_not_a_copy(planned):
    """A posture moved in the plan (not in its nested result) fails the check."""
    import dataclasses

    scenario, result = planned
    moved = list(result.stances)
    q = np.array(moved[1].q)
    q[2] += 0.05  # the base 5 cm up: the soles leave their prints
    moved[1] = dataclasses.replace(moved[1], q=q)
    report = dataclasses.replace(result, stances=tuple(moved)).check(scenario)
    assert not report.ok
    assert any(problem.startswith("stance 1: ") for problem in report.problems)


def test_planned_stances_keep_all_but_the_contact_geometry_off_the_supports(planned, robot):
    """Measured on the full meshes, independently of the solver's collision code
    (tests/clearance.py): a palm touches with its plate only, a sole with its foot."""
    scenario, result = planned
    # The collision block lets the QP eat 0.1 mm of the clearance (its slack).
    minimum = PostureOptions().collision_distance - 1e-4 - 1e-9
    for step in result.stances:
        clearances = robot_clearances(robot, scenario.scene, step.stance, step.q)
        close = {pair: distance for pair, distance in clearances.items() if distance < minimum}
        assert not close, (step.stance, close)


def test_planned_stances_survive_the_json_round_trip_and_still_verify(planned, tmp_path):
    scenario, result = planned
    path = result.save(tmp_path / "plan.json")
    loaded = Plan.load(path)
    assert loaded.to_dict() == result.to_dict()
    report = loaded.check(scenario)
    assert report.ok, report.problems
    # Each value once: a stance's posture, forces and displacements are not repeated in its result...
    for entry in json.loads(path.read_text())["stances"]:
        assert not {"q", "point_forces", "deformations", "stance"} & set(entry["result"])
    # ... and the result read back holds them all the same.
    for original, read in zip(result.stances, loaded.stances):
        np.testing.assert_array_equal(read.result.q, original.result.q)
        np.testing.assert_array_equal(read.result.torques, original.result.torques)
        assert [f.frame for f in read.result.point_forces] == [f.frame for f in original.point_forces]
        np.testing.assert_array_equal([f.force for f in read.result.point_forces], original.contact_forces)
        assert read.result.stance == original.stance


def test_a_copied_plan_checks_without_the_scenario_file(planned, tmp_path, capsys):
    """plan.json carries its scenario: move the user's YAML away, copy the plan, check it."""
    scenario, result = planned
    copy = tmp_path / "elsewhere" / "plan.json"
    copy.parent.mkdir()
    shutil.copy(result.save(tmp_path / "plan.json"), copy)
    hidden = scenario.path.with_suffix(".hidden")
    scenario.path.rename(hidden)
    try:
        report = Plan.load(copy).check()
        assert report.ok, report.problems
        assert main(["check", str(copy)]) == 0
    finally:
        hidden.rename(scenario.path)
    assert f"plan of {scenario.name!r}, {len(result.stances)} stances: every stance verifies" in capsys.readouterr().out


def test_cli_plan_writes_every_file(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["plan", "cross-soft-block", "--out", str(out), "--quiet", "--max-expansions", "40"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    loaded = Plan.load(out / "plan.json")
    count = len(loaded.stances)
    expected = {"plan.json", "plan.pvd", "viewer.html"}
    expected |= {f"stance_{i:02d}.png" for i in range(count)}
    expected |= {f"stance_{i:02d}_foam.vtu" for i in range(count)} | {f"stance_{i:02d}_robot.vtu" for i in range(count)}
    assert {p.name for p in out.iterdir()} == expected
    assert "plan found" in printed
    if chromium_binary() is not None:
        assert page_status(out / "viewer.html", tmp_path) == "ok"


def test_cli_plan_with_motions_writes_the_trajectory_of_every_step(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["plan", "foot-on-block", "--motion", "--no-pictures", "--out", str(out), "--quiet"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    steps = len(Plan.load(out / "plan.json").stances) - 1
    assert f"motions: {steps} of {steps} found" in printed
    assert "searched" not in printed  # every step had its motion: one search
    assert {"trajectory.csv", "trajectory.npz"} <= {p.name for p in out.iterdir()}


def test_cli_check_reports_a_feasible_stance_and_draws_it(tmp_path, capsys):
    code = main(["check", "cross-soft-block", "--stance", "right-on-foam", "--out", str(tmp_path)])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "feasible" in printed and "iterations" in printed
    for line in ["forces on the robot (N, world frame):", "    right_sole on foam_top: ", "    left_sole on floor: ",
                 "depths in the soft bodies:", "    foam: indented ", "margins:", "    largest torque: "]:
        assert line in printed
    assert (tmp_path / "right-on-foam.png").stat().st_size > 0


def test_cli_runs_as_a_separate_process(tmp_path):
    script = Path(sys.executable).with_name("cbm")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "cbm"]
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    listed = subprocess.run(command + ["scenarios"], capture_output=True, text=True, timeout=120, env=env)
    assert listed.returncode == 0 and "cross-soft-block" in listed.stdout
    bad = subprocess.run(command + ["plan", "nowhere"], capture_output=True, text=True, timeout=120, env=env)
    assert bad.returncode == 2 and "cross-soft-block" in bad.stderr


def test_hand_on_table_plans_with_defaults():
    # Its goal palm lies beyond the reach model's arm (0.69 m from the reference
    # shoulder, 0.66 m reach): kept as a candidate because the goal names it.
    scenario = environments.load("hand-on-table")
    result = plan(scenario)
    assert result.success, result.reason
    assert [s.stance for s in result.stances] == [scenario.stance("stand"), scenario.stance("hand-on-table")]
    assert result.check(scenario).ok


def test_a_quarter_turn_plans_with_default_headings():
    """bench/scenes/turn.yaml lists no headings: the planner samples the start's (0),
    the goal's (90 degrees) and 45 between them, and the feet turn on the soft mat."""
    scenario = environments.load(Path(__file__).parents[1] / "bench" / "scenes" / "turn.yaml")
    assert "theta_values_deg" not in scenario.options
    result = plan(scenario, time_limit=120)
    assert result.success, result.reason
    headings = {round(math.degrees(c.contact_print.theta)) for s in result.stances for c in s.stance}
    assert headings == {0, 45, 90}
    assert result.check(scenario).ok


# A low wall across the way, 0.25 m ahead: every step forward puts a foot into it.
_WALLED = """\
robot: talos
objects:
  - {name: floor, type: floor, size: [3.0, 1.0]}
  - {name: wall, type: box, size: [0.1, 1.0, 0.3], center: [0.25, 0.0, 0.15]}
stances:
  start:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
start: start
goal:
  regions:
    - {robot_surface: left_sole, lower: [0.8, -0.4], upper: [1.2, 0.4]}
    - {robot_surface: right_sole, lower: [0.8, -0.4], upper: [1.2, 0.4]}
"""


def test_cbm_plan_verbose_says_why_a_real_scene_fails_and_where_the_search_would_go(tmp_path, capsys):
    """A scene built to fail, planned by the command line with --verbose: the summary
    names the real cause (feet in the wall: collision) with a whole example, the search's
    open stances nearest the goal, and the print grids tried; plan.json keeps the frontier."""
    from cbm import cli
    from cbm.plan import FRONTIER_SIZE, Plan

    scene = tmp_path / "walled.yaml"
    scene.write_text(_WALLED)
    out = tmp_path / "results"
    code = cli.main(["plan", str(scene), "--out", str(out), "--no-pictures", "--max-expansions", "3", "--quiet",
                     "--verbose"])
    printed = capsys.readouterr().out
    assert code == cli.EXIT_FAILED
    assert printed.startswith("walled: no plan: budget exhausted: max_expansions on a 0.050 m print grid, after 3 "
                              "stances expanded on the default 0.100 m one found no plan")
    rejected = next(line for line in printed.splitlines() if "stances rejected: " in line)
    assert rejected.split("stances rejected: ")[1].startswith(tuple(f"{n} collision" for n in range(1, 1000)))
    assert "    collision, e.g. collision of a placed link: at its print, leg_" in printed
    assert "into wall whatever the posture" in printed
    assert f"  the search would have gone on with ({FRONTIER_SIZE} open stances nearest the goal):" in printed
    frontier = printed.split("nearest the goal):\n")[1].splitlines()[:FRONTIER_SIZE]
    assert all(" m from the goal: left_" in line and " (by: place " in line for line in frontier)
    assert "  print grid: 0.050 m, " in printed
    saved = Plan.load(out / "plan.json")
    assert len(saved.frontier) == FRONTIER_SIZE
    distances = [entry["goal_distance"] for entry in saved.frontier]
    assert distances == sorted(distances) and all(d > 0.5 for d in distances)
