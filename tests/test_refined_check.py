"""A soft stance solved again on its meshes refined (``environments.refined``,
``stances.check_refined``, ``cbm check --refine``)."""

from __future__ import annotations

import re
import types

import numpy as np
import pytest

import environments
import fem
import stances
from cbm.cli import EXIT_BAD_INPUT, main
from environments import SceneError
from stances import StanceError

from conftest import coarse_scenario

G = 9.81


def test_refined_halves_every_cell_of_every_soft_object_and_keeps_the_rest():
    scenario = coarse_scenario("cross-two-mats")
    fine = environments.refined(scenario)
    assert fine.name == scenario.name and fine.stances == scenario.stances and fine.goal == scenario.goal
    assert sorted(fine.scene.surfaces) == sorted(scenario.scene.surfaces)
    for coarse, refined in zip(scenario.scene.deformable_objects, fine.scene.deformable_objects):
        assert refined.name == coarse.name
        assert np.allclose(refined.mesh.nodes.min(axis=0), coarse.mesh.nodes.min(axis=0))
        assert np.allclose(refined.mesh.nodes.max(axis=0), coarse.mesh.nodes.max(axis=0))
        # The finest spacing halves in each direction (graded cells round, so the count grows 4-8x).
        for axis in range(3):
            spacing = [np.diff(np.unique(m.mesh.nodes[:, axis].round(12))).min() for m in (coarse, refined)]
            assert spacing[1] == pytest.approx(spacing[0] / 2, rel=0.3)
        assert 4.0 < refined.mesh.n_nodes / coarse.mesh.n_nodes < 9.0
        assert repr(refined.body.material) == repr(coarse.body.material) and refined.strain_limit == coarse.strain_limit
        assert np.array_equal(refined.transform_body_to_world, coarse.transform_body_to_world)


def test_a_grid_given_box_gets_each_interval_cut_with_its_lines_kept():
    scenario = environments.load("hand-on-coarse-cube")
    fine = environments.refined(scenario, 3)
    coarse_nodes = scenario.scene.deformable("cube").mesh.nodes
    fine_nodes = fine.scene.deformable("cube").mesh.nodes
    for axis in range(3):
        lines = np.unique(coarse_nodes[:, axis])
        refined_lines = np.unique(fine_nodes[:, axis])
        assert refined_lines.size == 3 * (lines.size - 1) + 1
        assert set(lines.tolist()) <= set(refined_lines.tolist())  # the given lines, exactly
        # Each interval cut in three equal parts.
        steps = np.diff(refined_lines).reshape(-1, 3)
        assert np.allclose(steps, steps.mean(axis=1, keepdims=True), rtol=0, atol=1e-12)


@pytest.mark.parametrize("factor", [1, 0, 2.0, True, "2"])
def test_a_factor_that_is_not_an_integer_of_at_least_two_is_refused(factor):
    with pytest.raises(SceneError, match=re.escape(f"refinement factor must be an integer of at least 2, got {factor!r}")):
        environments.refined(coarse_scenario("cross-soft-block"), factor)


def test_a_scenario_without_soft_objects_or_text_cannot_be_refined():
    with pytest.raises(SceneError, match="scenario 'stand' has no soft object to refine"):
        environments.refined(environments.load("stand"))
    in_code = environments.Scenario("made-in-code", environments.load("step-on-cube").scene)
    with pytest.raises(SceneError, match="scenario 'made-in-code' was built in code and has no YAML text to refine"):
        environments.refined(in_code)


def test_a_refinement_over_the_node_limit_names_the_object_and_the_factor():
    with pytest.raises(SceneError, match=re.escape(
            "scenario 'step-on-cube' refined 40x: objects[2]: resolution 0.0005625 m would mesh this 0.3x0.3x0.3 m "
            "soft box with about")) as raised:
        environments.refined(environments.load("step-on-cube"), 40)
    assert str(raised.value).endswith("; use a smaller factor")


def test_a_tetrahedral_mesh_file_is_not_refined(tmp_path):
    solid = fem.box_mesh((0.4, 0.4, 0.1), (4, 4, 2))
    fem.write_mesh(tmp_path / "pad.vtu", solid)
    (tmp_path / "pad.yaml").write_text(
        "objects:\n"
        "  - {name: floor, type: floor}\n"
        "  - {name: pad, type: soft_mesh, file: pad.vtu, material: {E: 1.0e+6, nu: 0.4}}\n"
        "stances:\n"
        "  stand: {left_sole: {surface: floor, x: 0.0, y: 0.085}, right_sole: {surface: floor, x: 0.0, y: -0.085}}\n"
    )
    scenario = environments.load(tmp_path / "pad.yaml")
    with pytest.raises(SceneError, match=re.escape("object 'pad' is a tetrahedral mesh file (pad.vtu), used as it is")):
        environments.refined(scenario)


@pytest.fixture(scope="module")
def both_on_foam(robot):
    """cross-soft-block's two soles on the foam (4 cm mesh), solved, and its check on a 2 cm mesh."""
    scenario = coarse_scenario("cross-soft-block")
    result = stances.solve(robot, scenario.scene, scenario.stance("both-on-foam"))
    assert result.feasible, result.reason
    return scenario, result, stances.check_refined(robot, scenario, result)


def test_a_soft_stance_holds_on_its_meshes_refined_with_the_posture_barely_moved(robot, both_on_foam):
    scenario, result, check = both_on_foam
    assert check.ok and check.result.verification.ok
    assert check.factor == 2
    (name, coarse_nodes, fine_nodes), = check.nodes
    assert name == "foam" and fine_nodes > 5 * coarse_nodes
    # The coarse answer is close to, but not exactly, a solution on the finer mesh.
    assert 1e-7 < check.start_violation < 1e-2
    assert check.start_row.startswith("placement of ")
    assert check.result.iterations <= 5
    # Started from the answer: no rigid and bonded warm starts.
    assert "rigid_warm_start_iterations" not in check.result.statistics
    # Default-mesh forces are the answer's own, refined ones the re-solve's.
    for surface, coarse, fine in check.print_forces:
        frame = robot.surface(surface).frame
        assert np.array_equal(coarse, sum((np.asarray(p.force) for p in result.point_forces if p.frame == frame), np.zeros(3)))
        assert np.array_equal(fine, sum((np.asarray(p.force) for p in check.result.point_forces if p.frame == frame), np.zeros(3)))
    assert 0.0 < check.joint_change < 5e-3
    # Both soles on the foam carry the robot on either mesh.
    for forces in ([c for _, c, _ in check.print_forces], [f for _, _, f in check.print_forces]):
        assert sum(f[2] for f in forces) == pytest.approx(robot.mass * G, rel=1e-5)
    assert [s for s, _, _ in check.print_forces] == ["left_sole", "right_sole"]
    assert 0.0 < check.force_change < 0.02
    text = "\n".join(check.lines())
    assert f"foam {coarse_nodes:,} -> {fine_nodes:,} nodes" in text and "re-solved there: feasible, verified" in text


def test_an_infeasible_or_rigid_answer_has_nothing_to_check(robot, both_on_foam):
    scenario, result, _ = both_on_foam
    failed = stances.PostureResult(**{**result.__dict__, "feasible": False, "reason": "made up"})
    with pytest.raises(StanceError, match="check_refined needs a feasible answer; this one is not: made up"):
        stances.check_refined(robot, scenario, failed)
    rigid = stances.solve(robot, scenario.scene, scenario.stance("start"))
    with pytest.raises(StanceError, match="the stance has no print on a soft surface: nothing to refine"):
        stances.check_refined(robot, scenario, rigid)


def test_the_command_line_refuses_refining_what_it_cannot(capsys, tmp_path):
    assert main(["check", "stand", "--stance", "stand", "--refine", "2"]) == EXIT_BAD_INPUT
    assert "--refine: stance 'stand' has no print on a soft surface: nothing to refine" in capsys.readouterr().err
    assert main(["check", "step-on-cube", "--stance", "step-on-cube", "--refine", "1"]) == EXIT_BAD_INPUT
    assert "expected an integer of at least 2, got '1'" in capsys.readouterr().err


def test_a_stance_not_reached_on_the_refined_meshes_is_reported_not_ok(robot, both_on_foam):
    scenario, result, _ = both_on_foam
    # The soles sink some 2 mm into the foam: a 0.1 mm indentation bound cannot hold.
    check = stances.check_refined(robot, scenario, result, max_indentation=1e-4)
    assert not check.ok and np.isnan(check.joint_change) and np.isnan(check.force_change)
    assert check.print_forces == ()
    assert "re-solved there: infeasible: " + check.result.reason in "\n".join(check.lines())


def test_a_plan_without_soft_stances_has_nothing_to_refine(robot, capsys, tmp_path):
    from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source

    scenario = environments.load("stand")
    answer = stances.solve(robot, scenario.scene, scenario.stance("stand"))
    path = tmp_path / "plan.json"
    Plan(False, "partial", (PlannedStance(answer.stance, answer.q, answer.point_forces, {}, answer),), PlanStatistics(),
         scenario.name, robot=robot_description(robot), scenario_source=scenario_source(scenario)).save(path)
    assert main(["check", str(path), "--refine", "2"]) == EXIT_BAD_INPUT
    assert "--refine: no stance of the plan has a print on a soft surface: nothing to refine" in capsys.readouterr().err


def test_the_command_line_says_how_the_answer_moves_on_finer_meshes(capsys, tmp_path):
    path = tmp_path / "cross-soft-block.yaml"
    path.write_text(coarse_scenario("cross-soft-block").text)
    assert main(["check", str(path), "--stance", "both-on-foam", "--refine", "2"]) == 0
    out = capsys.readouterr().out
    assert "meshes refined 2x: foam 729 -> 3,840 nodes" in out
    assert "re-solved there: feasible, verified" in out and "  left_sole: force [" in out


def test_each_soft_stance_of_a_saved_plan_is_checked_on_finer_meshes(robot, both_on_foam, capsys, tmp_path):
    from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source

    scenario, result, _ = both_on_foam
    # Consecutive stances differ by one contact: right sole on the foam, then off the floor, then both on the foam.
    right = scenario.stance("right-on-foam")
    # Each from where the one before left the sole it keeps on the foam (history).
    sequence = [right, environments.Stance(tuple(c for c in right.contacts if c.robot_surface == "right_sole")),
                result.stance]
    planned, answer = [], None
    for stance in sequence:
        answer = stances.solve(robot, scenario.scene, stance, history=answer)
        assert answer.feasible, answer.reason
        planned.append(PlannedStance(stance, answer.q, answer.point_forces, answer.deformations, answer))
    path = tmp_path / "plan.json"
    Plan(False, "partial", tuple(planned), PlanStatistics(), scenario.name, robot=robot_description(robot),
         scenario_source=scenario_source(scenario)).save(path)
    assert main(["check", str(path), "--refine", "2"]) == 0
    out = capsys.readouterr().out
    assert "3 stances: every stance verifies" in out
    for index in (0, 1, 2):
        assert f"stance {index}:\n  meshes refined 2x: foam 729 -> 3,840 nodes" in out
    assert out.count("re-solved there: feasible, verified") == 3


def test_the_check_reads_its_own_numbers(both_on_foam):
    """What lines() and force_change make of a check's fields, at their edge cases."""
    import dataclasses

    _, _, check = both_on_foam
    text = "\n".join(check.lines())
    assert f"the answer there as it is: {check.start_row} off by {check.start_violation:.3g} (m, rad or N" in text
    held = dataclasses.replace(check, start_violation=0.0, start_row="")
    assert "  the answer holds there as it is" in held.lines()
    light = dataclasses.replace(check, print_forces=(("left_sole", np.array([0.0, 0.0, 0.5]), np.array([0.0, 0.0, 0.6])),))
    assert light.force_change == pytest.approx(0.2)
    unloaded = dataclasses.replace(check, print_forces=(("left_sole", np.zeros(3), np.array([0.0, 0.0, 1.0])),))
    assert np.isnan(unloaded.force_change)


def _soft_plan(robot, both_on_foam, path):
    """A one-stance plan file of cross-soft-block's both-on-foam answer (its coarse mesh)."""
    from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source

    scenario, result, _ = both_on_foam
    Plan(False, "partial", (PlannedStance(result.stance, result.q, result.point_forces, {}, result),), PlanStatistics(),
         scenario.name, robot=robot_description(robot), scenario_source=scenario_source(scenario)).save(path)
    return path


def test_a_plan_checked_on_refined_meshes_ends_with_its_verdict(robot, both_on_foam, capsys, tmp_path, monkeypatch):
    path = _soft_plan(robot, both_on_foam, tmp_path / "plan.json")
    assert main(["check", str(path), "--refine", "2"]) == 0
    out = capsys.readouterr().out
    assert out.rstrip().endswith("meshes refined 2x: every stance with a soft print holds (1 of 1)")
    # A stance that does not hold there: the last line says which, and how to fix it.
    failed = types.SimpleNamespace(ok=False, lines=lambda: ["re-solved there: infeasible: made up"])
    monkeypatch.setattr(stances, "check_refined", lambda *args, **kwargs: failed)
    assert main(["check", str(path), "--refine", "2"]) == 1
    out = capsys.readouterr().out
    assert out.rstrip().endswith(
        "meshes refined 2x: 1 of the 1 stances with a soft print do not hold (stance 0): the plan's soft meshes "
        "are too coarse for them; plan again with a finer resolution of those objects")


def test_an_answer_whose_refined_contact_has_no_coulomb_state_is_checked_all_the_same(robot, both_on_foam, monkeypatch):
    """At very high friction a refined print's contact may have no Coulomb state at the answer's
    posture (``fem.ContactStateError``): the check says so instead of raising, and the re-solve
    from the answer answers for itself (here, its evaluation at the start made to fail)."""
    import stances.refined_check as refined_check

    scenario, result, _ = both_on_foam
    build = refined_check.build_problem

    def without_state_at_the_start(*args, **kwargs):
        problem = build(*args, **kwargs)

        def evaluate(q, lam):
            raise fem.ContactStateError("no Coulomb state (made up)")

        problem.evaluate = evaluate
        return problem

    monkeypatch.setattr(refined_check, "build_problem", without_state_at_the_start)
    check = stances.check_refined(robot, scenario, result)
    assert check.start_row == refined_check.NO_STATE_AT_START and check.start_violation == np.inf
    assert check.ok and check.result.verification.ok
    assert ("  the answer there as it is: contact of a soft print with no Coulomb state at the answer's posture"
            in check.lines())
