"""The benchmark suite's scenes load, and their rigid twins keep the geometry and drop the softness."""

from __future__ import annotations

import numpy as np
import pytest

import environments
from conftest import BENCH, bench_module
from environments import SceneError
from environments.rigid_twin import rigid_object_of, rigid_twin

SUITE = bench_module("bench_suite")


def test_every_suite_scene_is_a_file_of_bench_scenes_or_a_built_in_and_every_file_is_in_the_suite():
    files = {path.stem for path in (BENCH / "scenes").glob("*.yaml")}
    built_in = set(environments.scenario_names())
    assert len(SUITE.SCENES) >= 10
    assert all(name in files or name in built_in for name in SUITE.SCENES)
    assert files <= set(SUITE.SCENES)


@pytest.fixture(scope="module")
def suite_scenes():
    """Every suite scene loaded once (the FEM bodies meshed at their resolution)."""
    return {name: environments.load(SUITE.scene_source(name)) for name in SUITE.SCENES}


def _world_bounds(obj):
    """(2, 3) world-frame bounds of a rigid or deformable object's boundary."""
    if obj.deformable:
        return np.array([obj.rest_surface().reshape(-1, 3).min(axis=0), obj.rest_surface().reshape(-1, 3).max(axis=0)])
    return obj.mesh_in_world().bounds


@pytest.mark.parametrize("name", SUITE.SCENES)
def test_a_suite_scene_has_a_start_a_goal_and_its_twin_is_the_same_scene_made_rigid(suite_scenes, name):
    scenario = suite_scenes[name]
    assert scenario.start_stance is not None and scenario.goal is not None
    twin = rigid_twin(scenario)
    scene, twin_scene = scenario.scene, twin.scene
    assert twin_scene.deformable_objects == ()
    assert not any(surface.deformable for surface in twin_scene.surfaces.values())
    # The rigid objects are the very same, in the same order, then one per soft object.
    assert twin_scene.rigid_objects[: len(scene.rigid_objects)] == scene.rigid_objects
    assert [obj.name for obj in twin_scene.rigid_objects[len(scene.rigid_objects):]] == [
        obj.name for obj in scene.deformable_objects
    ]
    for soft in scene.deformable_objects:
        np.testing.assert_allclose(_world_bounds(twin_scene.objects[soft.name]), _world_bounds(soft), atol=1e-12)
        assert twin_scene.objects[soft.name].mesh_in_world().volume == pytest.approx(float(np.sum(soft.mesh.volumes)))
    # The surfaces keep their names, polygons, frames and friction.
    assert list(twin_scene.surfaces) == list(scene.surfaces)
    for surface_name, surface in scene.surfaces.items():
        twin_surface = twin_scene.surface(surface_name)
        np.testing.assert_array_equal(twin_surface.polygon, surface.polygon)
        np.testing.assert_array_equal(twin_surface.transform_surface_to_world, surface.transform_surface_to_world)
        assert twin_surface.friction == surface.friction
    assert twin.stances == scenario.stances and twin.goal is scenario.goal and twin.options == scenario.options
    assert twin.text is None and twin.path is None


def test_a_soft_box_becomes_an_exact_box_and_another_soft_shape_its_boundary_mesh():
    scenario = environments.load_string(
        """
objects:
  - {name: floor, type: floor}
  - name: step
    type: soft_blocks
    blocks:
      - {name: tread, size: [0.3, 0.4, 0.1], center: [0.15, 0.0, 0.05]}
      - {name: ledge, size: [0.2, 0.4, 0.3], center: [0.4, 0.0, 0.15]}
    material: {E: 1.0e+6, nu: 0.4}
    resolution: coarse
  - name: pad
    type: soft_box
    size: [0.3, 0.2, 0.05]
    center: [1.0, 0.0, 0.025]
    yaw_deg: 30
    material: {E: 1.0e+6, nu: 0.4}
    resolution: coarse
stances:
  start: {left_sole: {surface: floor, x: 0.0, y: 0.085}}
"""
    )
    step = rigid_object_of(scenario.scene.deformable("step"))
    pad = rigid_object_of(scenario.scene.deformable("pad"))
    assert step.box_size is None  # an L-shaped solid: its boundary mesh, watertight
    assert step.mesh.is_watertight and step.mesh.volume == pytest.approx(0.3 * 0.4 * 0.1 + 0.2 * 0.4 * 0.3)
    np.testing.assert_allclose(pad.box_size, [0.3, 0.2, 0.05])
    np.testing.assert_allclose(pad.transform_object_to_world[:3, 3], [1.0, 0.0, 0.025], atol=1e-12)
    yaw = np.radians(30.0)
    np.testing.assert_allclose(pad.transform_object_to_world[:2, 0], [np.cos(yaw), np.sin(yaw)], atol=1e-12)


def test_the_twin_builder_refuses_what_is_not_a_loaded_scenario_or_a_soft_object():
    with pytest.raises(SceneError, match=r"rigid_twin needs a loaded Scenario \(environments.load\(name_or_path\)\), got str"):
        rigid_twin("cross-soft-block")
    floor = environments.floor()
    with pytest.raises(SceneError, match=r"rigid_object_of needs a deformable object .*, got RigidObject"):
        rigid_object_of(floor)


def test_a_scenario_without_soft_objects_has_a_twin_equal_to_it_but_for_its_name(suite_scenes):
    scenario = suite_scenes["stairs-10cm"]
    twin = rigid_twin(scenario)
    assert twin.name == "stairs-10cm-rigid"
    assert twin.scene.rigid_objects == scenario.scene.rigid_objects
    assert dict(twin.scene.surfaces) == dict(scenario.scene.surfaces)


def test_the_suite_table_reports_the_misses_against_the_targets():
    run = {"variant": "scene", "soft": True, "success": True, "wall": 4.0, "cpu": 3.0, "solver_calls": 10, "stances": 7,
           "reason": "goal reached", "rejections": {}}
    records = [
        {**run, "scene": "a", "seed": 0},
        {**run, "scene": "a", "seed": 1, "wall": 30.0, "success": False, "reason": "budget exhausted: time_limit",
         "rejections": {"torque limit": 3}},
        {**run, "scene": "a", "seed": 0, "variant": "twin", "wall": 2.0},
        {**run, "scene": "a", "seed": 1, "variant": "twin", "wall": 3.0},
    ]
    lines = SUITE.targets(records, ["a"])
    assert lines[0].startswith("- success over all scenes and seeds: 50 % (1 of 2")
    assert lines[1] == "- median plan > 10 s: a (17.0 s)"
    assert lines[2] == "- soft scene > 2x its rigid twin: a (6.8x)"
    assert SUITE.failures(records, ["a"]) == [
        "- a (scene), seed 1: budget exhausted: time_limit; rejected: 3 torque limit"
    ]
    row = SUITE.table(records, ["a"]).splitlines()[-1]
    assert row.startswith("| a | yes | 50 % of 2 | 17.0 / 27.4 |") and row.endswith("| 6.80 (1.00) |")


def test_timed_solves_records_each_solves_sqp_iterations_warm_starts_included(monkeypatch):
    import types

    import cbm.planner

    def fake_solve(robot, scene, stance, **options):
        if stance == "raises":
            raise ValueError("bad stance")
        return types.SimpleNamespace(iterations=5, statistics={"rigid_warm_start_iterations": 3} if stance else {})

    monkeypatch.setattr(cbm.planner, "posture_api", lambda: (fake_solve, None))
    with SUITE.timed_solves() as solves:
        solve, _ = cbm.planner.posture_api()
        solve(None, None, "soft")
        solve(None, None, None)
        with pytest.raises(ValueError, match="bad stance"):
            solve(None, None, "raises")
    assert [entry[2:] for entry in solves] == [("soft", 8), (None, 5), ("raises", None)]
    assert cbm.planner.posture_api()[0] is fake_solve  # put back


def test_the_suite_report_says_when_its_records_come_from_several_code_versions():
    run = {"variant": "scene", "soft": False, "success": True, "wall": 1.0, "cpu": 1.0, "solver_calls": 3, "stances": 2,
           "reason": "", "rejections": {}, "load_before": 0.5, "load_after": 0.5, "options": [], "scene": "a", "seed": 0,
           "longest_solve_cpu": 0.2, "longest_solve_wall": 0.2, "longest_solve_iterations": 9, "solver_iterations": 20}
    same = SUITE.report([{**run, "code": "commit abc"}, {**run, "seed": 1, "code": "commit abc"}], ["a"], "header")
    assert "several code versions" not in same
    assert "SQP iterations of every solve, warm starts included: 40 over 2 plans (the longest solve's: 9)" in same
    mixed = SUITE.report([{**run, "code": "commit abc"}, {**run, "seed": 1, "code": "commit def"}], ["a"], "header")
    assert "**Runs of several code versions** in these records: commit abc; commit def." in mixed
