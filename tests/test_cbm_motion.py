"""Quasi-static motions between the stances of a short plan, and their joint trajectory."""

import csv
import json
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin
import pytest

import environments
import stances
from environments.stance import Contact, ContactPrint

from cbm.motion import (HELD_DRIFT, UNLOADED_FORCE, ContactSample, FramePlacementConstraint, MotionError,
                        _motion_on_path, held_strays, motions_summary, plan_motion, plan_motions,
                        plan_motions_reposing, retreat, verify_motion)
from cbm.step_path import RAMP, lifted_path
from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source
from cbm.trajectory import plan_trajectory, write_trajectory


@pytest.fixture(scope="module")
def scenario():
    return environments.load("stand")


@pytest.fixture(scope="module")
def step_plan(robot, scenario):
    """A step: both soles down, right sole lifted, right sole 15 cm ahead (each solved and verified)."""
    both = scenario.stance("stand")
    left = both.without("right_sole")
    ahead = left.with_contact(Contact("right_sole", ContactPrint("floor", 0.15, -0.085)))
    planned, q = [], None
    for stance in (both, left, ahead):
        result = stances.solve(robot, scenario.scene, stance, q_init=q)
        assert result.feasible, result.reason
        q = result.q
        planned.append(PlannedStance(stance, result.q, result.point_forces, {}, result, move=""))
    return Plan(True, "goal reached", planned, PlanStatistics(), "stand",
                robot=robot_description(robot), scenario_source=scenario_source(scenario))


@pytest.fixture(scope="module")
def motions(step_plan, scenario, robot):
    return plan_motions(step_plan, scenario, robot, samples=3)[1]  # (rigid: the plan as it was)


def test_every_motion_sample_verifies_and_joins_its_two_stances(step_plan, motions, scenario, robot):
    assert [m.moving_surface for m in motions] == ["right_sole", "right_sole"]
    for index, motion in enumerate(motions):
        assert motion.feasible, motion.reason
        # Two stances, three across, two straight above the ends, and the sole on its print unloaded.
        assert len(motion.configurations) == 3 + 2 + 2 + 1
        np.testing.assert_array_equal(motion.configurations[0], step_plan.stances[index].q)
        np.testing.assert_array_equal(motion.configurations[-1], step_plan.stances[index + 1].q)
        assert motion.support == step_plan.stances[1].stance  # the left sole alone holds the robot
        assert verify_motion(motion, step_plan, scenario, robot) == []
        # Lift-off first (stance 0 -> 1), touch-down last (1 -> 2).
        switch = 0 if index == 0 else -1
        expected = [False] * len(motion.paths)
        expected[switch] = True
        assert [isinstance(p, ContactSample) for p in motion.paths] == expected
        assert motion.paths[switch].label == ("lift-off" if index == 0 else "touch-down") + " of right_sole"
        holding = step_plan.stances[0 if index == 0 else 2].stance
        for path, result in zip(motion.paths, motion.results):
            # Checked here as a stance, independently of the motion code: of the support,
            # or the sole on its print carrying nothing.
            if isinstance(path, ContactSample):
                assert stances.verify(robot, scenario.scene, holding, result).ok
                on_sole = [p.force for p in result.point_forces if p.frame == robot.surface("right_sole").frame]
                assert len(on_sole) == 4 and np.abs(on_sole).max() < 1e-5
            else:
                assert stances.verify(robot, scenario.scene, motion.support, result).ok


def test_the_moving_sole_is_lifted_clear_of_the_floor_between_its_prints(motions, robot):
    frame = robot.model.getFrameId(robot.surface("right_sole").frame)
    data = robot.model.createData()
    for motion, on_print in zip(motions, [0, -1]):  # leaves its print, then reaches the new one
        heights = []
        for q in motion.configurations[1:-1]:
            pin.framesForwardKinematics(robot.model, data, q)
            heights.append(data.oMf[frame].translation[2])
        # On the print at lift-off (touch-down), then 1.5 cm straight above it, higher elsewhere
        # (the floor is z = 0, the sole frame on the sole).
        switch = heights.pop(on_print)
        assert switch == pytest.approx(0.0, abs=1e-6)
        assert heights[on_print] == pytest.approx(0.015, abs=1e-6)
        assert min(heights) >= 0.015 - 1e-6 and max(heights) >= 0.05


def test_verify_motion_reports_a_sample_moved_off_its_path(step_plan, motions, scenario, robot):
    motion = motions[1]
    result = motion.results[2]
    q = np.array(result.q)
    q[2] += 0.01  # the whole robot 1 cm up: the left sole leaves its print
    broken = replace(motion, results=motion.results[:2] + (replace(result, q=q),) + motion.results[3:])
    problems = verify_motion(broken, step_plan, scenario, robot)
    assert problems[0] == "sample 3: its result is not its posture"
    assert problems[1].startswith("sample 3: left_sole on floor is off its print by 0.01 m")  # stances.verify
    assert problems[2] == "sample 3: right_sole is 0.01 m or rad off its path"
    assert len(problems) == 3


def test_a_motion_needs_stances_that_differ_by_one_contact(step_plan, scenario, robot):
    skipping = replace(step_plan, stances=(step_plan.stances[0], step_plan.stances[2]))
    with pytest.raises(MotionError) as raised:
        plan_motion(skipping, 0, scenario, robot)
    assert str(raised.value) == (
        "a motion joins stances that differ by exactly one contact; these differ by 2: ['right_sole', 'right_sole']"
    )
    with pytest.raises(MotionError, match="stance 2 has no next stance: the plan has 3 stances"):
        plan_motion(step_plan, 2, scenario, robot)


def rows_of(constraint, problem, q):
    iterate = problem.iterate(q, np.zeros(problem.n_variables))
    return constraint.blocks(problem, iterate)[0]


def test_a_position_only_path_leaves_the_frame_free_to_turn(robot):
    data = robot.model.createData()
    q = robot.reference_configuration
    pin.framesForwardKinematics(robot.model, data, q)
    frame = robot.surface("right_sole").frame
    target = data.oMf[robot.model.getFrameId(frame)].homogeneous.copy()
    target[:3, :3] = pin.exp3(np.array([0.0, 0.0, 0.5])) @ target[:3, :3]  # turned, same origin
    target[2, 3] += 2e-3
    assert FramePlacementConstraint(frame, target).error(robot, q) == pytest.approx(0.5)
    assert FramePlacementConstraint(frame, target, position_only=True).error(robot, q) == pytest.approx(2e-3)
    # Moved 1 cm and turned 5 mrad about its own x: the error is the larger of the two, each on its own.
    moved = data.oMf[robot.model.getFrameId(frame)].homogeneous.copy()
    moved[:3, :3] = moved[:3, :3] @ pin.exp3(np.array([0.005, 0.0, 0.0]))
    moved[:3, 3] += moved[:3, 0] * 0.01
    assert FramePlacementConstraint(frame, moved).error(robot, q) == pytest.approx(0.01, rel=1e-6)


@pytest.mark.parametrize("position_only, free", [(False, None), (True, None), (False, [0.3, 1.0, 0.1]),
                                                 (True, [0.3, 1.0, 0.1])],
                         ids=["placement", "position", "placement-free-sideways", "position-free-sideways"])
def test_path_constraint_jacobian_matches_finite_differences(robot, scenario, position_only, free):
    problem = stances.build_problem(robot, scenario.scene, scenario.stance("stand").without("right_sole"))
    rng = np.random.default_rng(3)
    q = pin.integrate(robot.model, robot.reference_configuration, 0.1 * rng.standard_normal(robot.model.nv))
    target = np.eye(4)
    target[:3, :3] = pin.exp3(np.array([0.1, -0.2, 0.3]))
    target[:3, 3] = [0.1, -0.1, 0.05]
    constraint = FramePlacementConstraint(robot.surface("right_sole").frame, target, position_only=position_only,
                                          free_direction=free)
    rows = 3 - (free is not None) + 3 * (not position_only)
    assert rows_of(constraint, problem, q).value.shape == (rows,)

    def rows(q):
        return rows_of(constraint, problem, q)

    analytic = rows(q).jacobian[:, : robot.model.nv]
    step = 1e-6
    numeric = np.column_stack([
        (rows(pin.integrate(robot.model, q, step * e)).value - rows(pin.integrate(robot.model, q, -step * e)).value)
        / (2 * step)
        for e in np.eye(robot.model.nv)
    ])
    np.testing.assert_allclose(analytic, numeric, atol=1e-6)


def test_lifted_path_goes_up_turns_while_crossing_and_comes_down():
    start, end = np.eye(4), np.eye(4)
    end[:3, :3] = pin.exp3(np.array([0.0, 0.0, 0.6]))
    end[:3, 3] = [0.3, 0.0, 0.1]
    path = lifted_path(start, end, [0.0, 0.0, 2.0], 0.05, 5)
    angles = np.array([pin.log3(p[:3, :3])[2] for p in path])
    progress = path[:, 0, 3] / 0.3
    # The turn goes with the crossing: none while rising, all of it once across.
    np.testing.assert_allclose(angles, 0.6 * progress, atol=1e-12)
    np.testing.assert_allclose(progress[[0, 1, -2, -1]], [0, 0, 1, 1], atol=1e-12)
    # 1.5 cm above each end, crossing 5 cm above the higher one.
    np.testing.assert_allclose(path[[0, -1], 2, 3], [0.015, 0.115])
    assert path[3, 2, 3] == pytest.approx(0.15)
    assert np.all(path[progress > 0, 2, 3] >= 0.115 - 1e-12)  # never lower than touch-down once moving across


def test_trajectory_files_name_the_joints_and_replay_the_plan(step_plan, motions, tmp_path):
    trajectory = plan_trajectory(step_plan, motions)
    csv_path, npz_path = write_trajectory(trajectory, tmp_path / "trajectory")
    with open(csv_path) as stream:
        rows = list(csv.reader(stream))
    locked = step_plan.robot["locked_joints"]
    assert locked and all(len(values) == 1 for values in locked.values())  # Talos's: one coordinate each
    nq = len(step_plan.robot["configuration_names"])
    # The locked joints last, at their values: a row is the whole URDF configuration.
    assert rows[0] == ["time", "stance", "segment", *step_plan.robot["configuration_names"], *locked]
    assert all([float(v) for v in row[3 + nq:]] == [values[0] for values in locked.values()] for row in rows[1:])
    assert len(rows) == 1 + 1 + 2 * 7  # the first stance, then each motion's samples and its arriving stance
    read = np.load(npz_path)
    np.testing.assert_array_equal(read["q"], np.array([[float(v) for v in row[3:3 + nq]] for row in rows[1:]]))
    assert list(read["names"]) == step_plan.robot["configuration_names"]
    assert json.loads(str(read["locked_joints"])) == {k: list(v) for k, v in step_plan.robot["locked_joints"].items()}
    assert np.all(np.diff(read["times"]) > 0)
    assert str(read["interpolation"]).startswith("pinocchio.interpolate between consecutive samples")
    stance_rows = np.flatnonzero(read["stance"] >= 0)
    assert read["stance"][stance_rows].tolist() == [0, 1, 2]
    for index, row in zip(range(3), stance_rows):
        np.testing.assert_array_equal(read["q"][row], step_plan.stances[index].q)


def test_outputs_write_the_trajectory_and_the_viewer_plays_the_motions(step_plan, motions, scenario, robot, tmp_path):
    from cbm.output import write_outputs
    from test_cbm_output import chromium_binary, page_status

    files = write_outputs(step_plan, scenario, robot, tmp_path, pictures=False, motions=motions)
    assert [p.name for p in files.trajectory] == ["trajectory.csv", "trajectory.npz"]
    page = files.viewer.read_text()
    start = page.index('type="application/json">') + len('type="application/json">')
    data = json.loads(page[start: page.index("</script>", start)])
    meshes = len(data["robot"]["meshes"])
    assert [(m["from"], m["moving"], len(m["robot"])) for m in data["motions"]] == [(0, "right_sole", 6), (1, "right_sole", 6)]
    assert all(len(pose) == meshes for m in data["motions"] for pose in m["robot"])
    assert all(np.all(np.diff(m["times"]) > 0) for m in data["motions"])
    if chromium_binary() is not None:
        assert page_status(files.viewer, tmp_path) == "ok"


def _plan_of(robot, scenario, sequence):
    """A plan of stances solved one after another, each warm-started from the last."""
    planned, q = [], None
    for stance in sequence:
        result = stances.solve(robot, scenario.scene, stance, q_init=q)
        assert result.feasible, result.reason
        q = result.q
        planned.append(PlannedStance(stance, result.q, result.point_forces, {}, result, move=""))
    return Plan(True, "goal reached", planned, PlanStatistics(), scenario.name,
                robot=robot_description(robot), scenario_source=scenario_source(scenario))


def test_a_point_foot_steps_with_its_centre_on_the_path_and_its_orientation_free():
    """ANYmal's 3-joint legs cannot also hold a foot orientation: the path places the ball's centre."""
    robot, scenario = stances.Robot.load("anymal"), environments.load("quadruped-walk")
    three = scenario.stance("three-feet")
    ahead = three.with_contact(Contact("left_front_foot", ContactPrint("floor", 0.45, 0.201)))
    plan = _plan_of(robot, scenario, (scenario.stance("start"), three, ahead))
    for motion in plan_motions(plan, scenario, robot, samples=3)[1]:
        assert motion.feasible, motion.reason
        assert verify_motion(motion, plan, scenario, robot) == []
        frame = robot.surface("left_front_foot").frame
        turns = [FramePlacementConstraint(frame, t).error(robot, r.q) for t, r in zip(motion.targets, motion.results)]
        assert max(turns) > 1e-3  # the foot did turn off the path's orientation, which binds it no more


def test_while_crossing_the_swing_sole_is_free_sideways_only(step_plan, motions, robot):
    """Height, progress and orientation held on the path; the sideways offset left to the solver."""
    frame = robot.surface("right_sole").frame
    for motion in motions:
        step = _placement(robot, motion.configurations[-1], frame)[:3, 3] - _placement(
            robot, motion.configurations[0], frame)[:3, 3]
        assert len(motion.paths) == 6  # 3 samples and 2 straight above the ends, none halved, and the switch
        s = np.arange(5) / 4
        crossing = (s > RAMP) & (s < 1 - RAMP)
        on_path = [(p, r) for p, r in zip(motion.paths, motion.results) if isinstance(p, FramePlacementConstraint)]
        assert [p.free_direction is not None for p, _ in on_path] == crossing.tolist()
        for path, result in on_path:
            placement = _placement(robot, result.q, frame)
            offset = placement[:3, 3] - path.transform_frame_to_world[:3, 3]
            turn = pin.log3(path.transform_frame_to_world[:3, :3].T @ placement[:3, :3])
            if path.free_direction is None:
                np.testing.assert_allclose(offset, 0.0, atol=1e-6)
            else:
                # Sideways: across the normal (world z) and the step.
                assert path.free_direction[2] == pytest.approx(0.0, abs=1e-12)
                assert path.free_direction @ step == pytest.approx(0.0, abs=1e-12)
                np.testing.assert_allclose(offset - (offset @ path.free_direction) * path.free_direction, 0.0,
                                           atol=1e-6)
            np.testing.assert_allclose(turn, 0.0, atol=1e-6)


def test_a_free_direction_must_be_a_vector():
    with pytest.raises(MotionError) as error:
        FramePlacementConstraint("f", np.eye(4), free_direction=[0.0, 0.0, 0.0])
    assert str(error.value) == "free_direction must be a non-zero (3,) vector, got [0.0, 0.0, 0.0]"


def test_a_waypoint_out_of_reach_forward_is_solved_backward_from_the_next_stance(step_plan, scenario, robot,
                                                                                 monkeypatch):
    """Forward solves are made to fail past the middle of the step; the motion still joins both stances."""
    solve, frame = stances.solve, robot.surface("right_sole").frame
    middle = 0.5 * (_frame_x(robot, step_plan.stances[1].q, frame) + _frame_x(robot, step_plan.stances[2].q, frame))

    def blocked_past_the_middle(robot_, scene, stance, q_init=None, constraints=(), **options):
        result = solve(robot_, scene, stance, q_init=q_init, constraints=constraints, **options)
        waypoint = getattr(constraints[0], "transform_frame_to_world", None)  # None: the touch-down sample
        if waypoint is not None and _frame_x(robot, q_init, frame) < middle < waypoint[0, 3]:
            return replace(result, feasible=False, reason="blocked by the test")
        return result

    monkeypatch.setattr(stances, "solve", blocked_past_the_middle)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert motion.feasible, motion.reason
    assert verify_motion(motion, step_plan, scenario, robot) == []
    x = [_frame_x(robot, q, frame) for q in motion.configurations]
    assert motion.seam is not None and x[motion.seam - 1] < middle < x[motion.seam]
    # Backward, the path's own waypoints only: the forward shorter steps that failed are not redone.
    backward = [path.label for path in motion.paths[motion.seam - 1:-1]]
    forward_reached = {path.label for path in motion.paths[: motion.seam - 1] if "toward" not in path.label}
    assert all("toward" not in label for label in backward)
    assert len(backward) + len(forward_reached) == 5 and not forward_reached & set(backward)
    assert motion.paths[-1].label == "touch-down of right_sole"  # after the backward samples, as always last
    np.testing.assert_array_equal(motion.configurations[-1], step_plan.stances[2].q)
    # The samples in path order, both halves (the touch-down sample's frame is where its solve put
    # it, on its print within the placement accuracy, 1e-7 m, not exactly on the last waypoint's x).
    assert np.all(np.diff(motion.targets[:, 0, 3]) >= -1e-6)


def test_a_waypoint_out_of_reach_both_ways_gives_both_reasons(step_plan, scenario, robot, monkeypatch):
    solve = stances.solve

    def blocked_at_the_top(robot_, scene, stance, q_init=None, constraints=(), **options):
        result = solve(robot_, scene, stance, q_init=q_init, constraints=constraints, **options)
        if not isinstance(constraints[0], ContactSample) and constraints[0].transform_frame_to_world[2, 3] > 0.06:
            return replace(result, feasible=False, reason="blocked by the test")
        return result

    monkeypatch.setattr(stances, "solve", blocked_at_the_top)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert not motion.feasible and motion.seam is None
    # Waypoints 2-4 cross 5 cm above the lifted sole (z > 6 cm): forward stops at 2, backward at 4.
    assert motion.reason == ("5 waypoints; forward, waypoint 2 (2 shorter steps tried): blocked by the test; "
                             "backward from the next stance, waypoint 4 (2 shorter steps tried): blocked by the test")
    assert len(motion.configurations) == 1 + len(motion.results)  # the forward samples, no arriving stance


def _placement(robot, q, frame):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q))
    return data.oMf[robot.model.getFrameId(frame)].homogeneous


def _frame_x(robot, q, frame):
    return _placement(robot, q, frame)[0, 3]


def test_the_summary_counts_motions_and_names_where_one_was_joined_backward(step_plan, motions):
    joined = replace(motions[1], seam=2)
    step = joined.joint_steps[1]
    assert step == np.abs(motions[1].configurations[2, 7:] - motions[1].configurations[1, 7:]).max()
    failed = replace(motions[0], configurations=motions[0].configurations[:-1], feasible=False, reason="r")
    assert motions_summary([failed, joined]) == (
        f"motions: 1 of 2 found; joined backward: 1 -> 2 at sample 2 (largest joint step there {step:.2f} rad)")


def test_each_sample_is_pulled_toward_the_stances_postures_blended_along_the_path(step_plan, scenario, robot,
                                                                                  monkeypatch):
    solve, references = stances.solve, []

    def recording(*arguments, reference=None, **options):
        references.append(reference)
        return solve(*arguments, reference=reference, **options)

    monkeypatch.setattr(stances, "solve", recording)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert motion.feasible and len(references) == 6
    before, after = step_plan.stances[1].q, step_plan.stances[2].q
    for k, reference in enumerate(references[:5]):
        np.testing.assert_allclose(reference, pin.interpolate(robot.model, before, after, k / 4), atol=1e-15)
    # The touch-down sample is pulled toward the lifted sample above it: the sole only comes down.
    np.testing.assert_array_equal(references[5], motion.configurations[-3])


def test_a_first_waypoint_out_of_reach_forward_leaves_the_whole_path_to_the_backward_solves(step_plan, scenario,
                                                                                             robot, monkeypatch):
    solve, leaving = stances.solve, step_plan.stances[1].q

    def blocked_from_the_first_stance(robot_, scene, stance, q_init=None, **options):
        result = solve(robot_, scene, stance, q_init=q_init, **options)
        return replace(result, feasible=False, reason="blocked by the test") if np.array_equal(q_init, leaving) else result

    monkeypatch.setattr(stances, "solve", blocked_from_the_first_stance)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert motion.feasible and motion.seam == 1
    assert [p.label for p in motion.paths] == [f"path of right_sole (waypoint {k})" for k in range(1, 6)] + [
        "touch-down of right_sole"]
    assert verify_motion(motion, step_plan, scenario, robot) == []


def test_a_motion_whose_samples_do_not_add_up_is_refused(motions):
    motion = motions[0]
    with pytest.raises(MotionError) as error:
        replace(motion, paths=motion.paths[:-1])
    assert str(error.value) == "a motion with 8 configurations (feasible) has 6 interior samples, got 5 paths and 6 results"
    with pytest.raises(MotionError) as error:
        replace(motion, seam=7)
    assert str(error.value) == "seam 7 is not an interior sample (1..6)"


def test_steps_between_samples_are_checked_for_collisions_the_resting_sole_excepted(step_plan, scenario, robot):
    """The moving sole may sink into its print's floor as deep as at the step's ends; nothing else may."""
    from cbm.between_samples import BETWEEN, BetweenSamples

    support, moving = step_plan.stances[1].stance, Contact("right_sole", ContactPrint("floor", 0.0, -0.085))
    between = BetweenSamples(robot, scenario.scene, support, moving, {})
    sunk, lifted = np.array(step_plan.stances[0].q), np.array(step_plan.stances[0].q)
    sunk[2] -= 0.01  # both soles 1 cm into the floor (the left one rests there by design)
    lifted[2] += 0.02
    assert between.first_collision(sunk, lifted) is None  # rising out of the floor
    fallen = sunk.copy()
    fallen[2] -= 0.4  # knees and more through the floor
    t, pair, depth = between.first_collision(sunk, fallen)
    assert t == BETWEEN[0] and pair.name_b == "floor" and depth > 0.01
    # Without the allowance the resting sole itself would be a collision at every posture.
    between.moving = set()
    t, pair, depth = between.first_collision(sunk, sunk)
    assert (t, pair.name_a, pair.name_b) == (BETWEEN[0], "leg_right_6_link_0", "floor")
    assert 0.01 <= depth < 0.011  # the foot's geometry reaches 0.4 mm below the sole's plane


def test_the_moving_soles_allowance_is_its_depth_at_the_ends_interpolated_not_the_deeper_one(step_plan, scenario,
                                                                                            robot):
    """2 cm deep at the start, out at the end, 1.5 cm deep halfway: 0.5 cm too deep there."""
    from cbm.between_samples import BetweenSamples

    support, moving = step_plan.stances[1].stance, Contact("right_sole", ContactPrint("floor", 0.0, -0.085))
    between = BetweenSamples(robot, scenario.scene, support, moving, {})
    q0, q1 = np.array(step_plan.stances[0].q), np.array(step_plan.stances[0].q)
    q1[0] += 1.0  # the base's x stands in for the fraction of the way

    def depth_at(q):
        t = q[0] - q0[0]
        return 0.02 * (1 - t) if abs(t - 0.5) > 0.2 else 0.015

    between._pairs = lambda q: [CollisionPairStub(*sorted(between.moving)[0], distance=-depth_at(q))]
    t, pair, depth = between.first_collision(q0, q1)
    assert t == 0.375 and depth == pytest.approx(0.015 - 0.02 * (1 - 0.375))


def test_a_colliding_step_is_reported_where_it_first_collides_and_how_deep_it_goes(step_plan, scenario, robot):
    """A wrist grazing a cube at 1/8 of a step and 12.8 mm deep halfway (romeo's approach):
    the first collision decides, the message gives the deepest too."""
    from cbm.between_samples import BetweenSamples

    support, moving = step_plan.stances[1].stance, Contact("right_sole", ContactPrint("floor", 0.0, -0.085))
    between = BetweenSamples(robot, scenario.scene, support, moving, {})
    q0, q1 = np.array(step_plan.stances[0].q), np.array(step_plan.stances[0].q)
    q1[0] += 1.0  # the base's x stands in for the fraction of the way

    swept = {0.125: 0.00087, 0.25: 0.0065, 0.375: 0.0119, 0.5: 0.0128, 0.625: 0.0026}  # metres deep

    def depth_at(q):
        return swept.get(round(float(q[0] - q0[0]), 3), -0.005)  # 5 mm clear elsewhere

    between._pairs = lambda q: [CollisionPairStub("r_wrist_0", "cube", distance=-depth_at(q))]
    t, pair, depth = between.first_collision(q0, q1)
    assert t == 0.125 and depth == pytest.approx(0.00087)
    kind, words = between.first_problem(q0, q1)
    assert kind == "collision"
    assert words.startswith(f"at 0.125 of the way: collision between r_wrist_0 and cube (depth {depth:.3g} m; ")
    assert words.endswith("deepest 0.0128 m at 0.5 of the way, between r_wrist_0 and cube)")
    # Where the first is the deepest, nothing more is said.
    between._pairs = lambda q: [CollisionPairStub("r_wrist_0", "cube", distance=-0.01 if abs(q[0] - q0[0] - 0.5) < 0.01 else 0.0)]
    kind, words = between.first_problem(q0, q1)
    assert words == "at 0.5 of the way: collision between r_wrist_0 and cube (depth 0.01 m)"


def test_the_drift_of_held_contacts_between_samples_is_their_distance_from_the_chord(step_plan, scenario, robot):
    """The base turned 0.2 rad about its own z axis between two postures: the joint-space
    interpolation turns every sole vertex along an arc about that axis, whose largest distance
    from the chord between its ends is computed here with scipy's rotations; a pure
    translation of the base moves them along the chord (no drift)."""
    from scipy.spatial.transform import Rotation

    from cbm.between_samples import BETWEEN, BetweenSamples

    support, moving = step_plan.stances[1].stance, Contact("right_sole", ContactPrint("floor", 0.0, -0.085))
    between = BetweenSamples(robot, scenario.scene, support, moving, {})
    q0 = np.array(step_plan.stances[1].q)
    base = Rotation.from_quat(q0[3:7])  # pinocchio's (x, y, z, w), as scipy's
    q1 = q0.copy()
    q1[3:7] = (base * Rotation.from_rotvec([0.0, 0.0, 0.2])).as_quat()
    sole = robot.surface("left_sole")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q0)
    placement = data.oMf[robot.model.getFrameId(sole.frame)]
    vertices = sole.vertices_in_frame @ placement.rotation.T + placement.translation
    axis = base.apply([0.0, 0.0, 1.0])
    arm = vertices - q0[:3]
    ends = [vertices, q0[:3] + Rotation.from_rotvec(0.2 * axis).apply(arm)]
    expected = max(
        (float(np.linalg.norm(q0[:3] + Rotation.from_rotvec(t * 0.2 * axis).apply(arm) - (1 - t) * ends[0] - t * ends[1],
                              axis=1).max()), t) for t in BETWEEN)
    t, name, drift = between.largest_drift(q0, q1)
    assert name == "left_sole" and t == expected[1] == 0.5
    assert drift == pytest.approx(expected[0], rel=1e-9) and 5e-4 < drift < 0.01
    shifted = q0.copy()
    shifted[:3] += [0.1, -0.05, 0.02]
    assert between.largest_drift(q0, shifted)[2] < 1e-12
    # The moving sole counts where it is held at both ends, alone when nothing else is held.
    assert between.largest_drift(q0, q1, held=True)[2] >= drift
    between.support_points = []
    assert between.largest_drift(q0, q1) == (0.0, "", 0.0)
    assert between.largest_drift(q0, q1, held=True)[1] == "right_sole"


def test_held_strays_measure_every_step_and_the_held_moving_sole_on_the_last(step_plan, motions, scenario, robot):
    """The touch-down motion's strays: within the bound; its last step (touch-down sample to
    the stance, both holding the right sole) computed again here with pinocchio over both
    soles' vertices."""
    from cbm.motion import BETWEEN

    motion = motions[1]
    strays = held_strays(motion, step_plan, scenario, robot)
    assert len(strays) == len(motion.configurations) - 1
    assert 0.0 < max(d for _, _, d in strays) <= HELD_DRIFT
    data = robot.model.createData()

    def vertices(q):
        pin.framesForwardKinematics(robot.model, data, q)
        placed = []
        for name in ("left_sole", "right_sole"):
            surface = robot.surface(name)
            placement = data.oMf[robot.model.getFrameId(surface.frame)]
            placed.append(surface.vertices_in_frame @ placement.rotation.T + placement.translation)
        return np.vstack(placed)

    q0, q1 = motion.configurations[-2:]
    ends = vertices(q0), vertices(q1)
    expected = max(np.linalg.norm(vertices(pin.interpolate(robot.model, q0, q1, t)) - (1 - t) * ends[0] - t * ends[1],
                                  axis=1).max() for t in BETWEEN)
    assert strays[-1][2] == pytest.approx(expected, rel=1e-12, abs=1e-15)
    with pytest.raises(MotionError, match="needs a feasible motion"):
        held_strays(replace(motion, feasible=False, configurations=motion.configurations[:-1], reason="x"),
                    step_plan, scenario, robot)


def test_a_step_that_carries_a_held_sole_off_its_line_gets_samples_inserted(step_plan, motions, scenario, robot):
    """With a bound of 0.1 mm on the support sole's stray, the lift-off motion gets samples
    inserted until every step keeps it, and verify_motion reports a step that does not."""
    from cbm.between_samples import HELD_DRIFT, BetweenSamples

    loose = motions[0]
    support, moving = loose.support, Contact("right_sole", ContactPrint("floor", 0.0, -0.085))
    between = BetweenSamples(robot, scenario.scene, support, moving, {})
    steps = [between.largest_drift(a, b)[2] for a, b in zip(loose.configurations[:-1], loose.configurations[1:])]
    assert max(steps) < HELD_DRIFT and max(steps) > 1e-4  # the default bound holds; 0.1 mm does not
    problems = verify_motion(loose, step_plan, scenario, robot, held_drift=1e-4)
    k = int(np.argmax(np.array(steps) > 1e-4))
    assert any(p.startswith(f"between samples {k} and {k + 1}, at ") and "the held left_sole strays" in p
               and p.endswith("m off its line (bound 0.0001 m)") for p in problems), problems
    tight = plan_motion(step_plan, 0, scenario, robot, samples=3, held_drift=1e-4)
    assert tight.feasible, tight.reason
    assert len(tight.configurations) > len(loose.configurations)
    assert all(between.largest_drift(a, b)[2] <= 1e-4
               for a, b in zip(tight.configurations[:-1], tight.configurations[1:]))
    assert verify_motion(tight, step_plan, scenario, robot, held_drift=1e-4) == []


@pytest.mark.parametrize("bound", [0.0, -1e-3, float("nan"), "far", True])
def test_a_drift_bound_that_is_not_a_positive_distance_is_refused(step_plan, scenario, robot, bound):
    with pytest.raises(MotionError) as error:
        plan_motion(step_plan, 0, scenario, robot, held_drift=bound)
    assert str(error.value) == f"held_drift must be a positive distance in metres (default 0.001), got {bound!r}"


def test_verify_motion_reports_a_step_between_samples_that_collides(step_plan, motions, scenario, robot):
    motion = motions[1]
    fallen = np.array(motion.configurations)
    fallen[-2, 2] -= 0.4  # the last sample's base 40 cm down: through the floor on both sides of it
    problems = verify_motion(replace(motion, configurations=fallen), step_plan, scenario, robot)
    assert problems[0].startswith("between samples 5 and 6, at 0.125 of the way: collision between ")
    assert problems[1].startswith("between sample 6 and the next stance's posture, at 0.125 of the way: "
                                  "collision between ")
    assert problems[2] == "sample 6: its result is not its posture"


@pytest.mark.parametrize("reach", [0.05, 0.005])
def test_a_step_that_collides_gets_samples_inserted_or_makes_the_motion_infeasible(step_plan, scenario, robot,
                                                                                     monkeypatch, reach):
    """Steps are made to 'collide' when the swing sole moves more than ``reach`` in x across them."""
    from cbm.between_samples import BetweenSamples
    from cbm.motion import MAX_INSERTED

    frame = robot.surface("right_sole").frame

    def long_steps_collide(between, q0, q1, held=False):
        moved = abs(_frame_x(robot, q1, frame) - _frame_x(robot, q0, frame))
        return (0.5, CollisionPairStub(), moved) if moved > reach else None

    monkeypatch.setattr(BetweenSamples, "first_collision", long_steps_collide)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    inserted = [path for path in motion.paths if "(between samples" in path.label]
    x = [_frame_x(robot, q, frame) for q in motion.configurations]
    if reach == 0.05:  # the two steps across (7.5 cm each) are halved once
        assert motion.feasible and len(inserted) == 2 and len(motion.paths) == 8
        assert np.all(np.abs(np.diff(x)) <= reach)
    else:
        assert not motion.feasible and len(inserted) == MAX_INSERTED
        # The first step across (7.5 cm) halved MAX_INSERTED times is still longer than 5 mm
        # somewhere: it stops at the first such step, every sample kept.
        k = int(np.flatnonzero(np.abs(np.diff(x)) > reach)[0])
        assert 2 <= k <= 2 + MAX_INSERTED
        assert motion.reason == (f"between samples {k} and {k + 1}, at 0.5 of the way: collision between a and b "
                                 f"(depth {abs(x[k + 1] - x[k]):.3g} m), after {MAX_INSERTED} samples inserted in that step")
        assert len(motion.configurations) == 1 + 5 + 1 + MAX_INSERTED  # with the touch-down sample


def test_a_colliding_approach_gets_a_waypoint_halfway_down_that_may_touch_the_support(step_plan, scenario, robot,
                                                                                     monkeypatch):
    """Steps that lower the swing sole onto the floor from more than 1 cm 'collide': the 1.5 cm
    approach onto its print is halved by a waypoint 7.5 mm up, nearer the floor than the 5 mm
    collision distance allows the sole's geometry, so it is solved with the pair touching."""
    from cbm.between_samples import BetweenSamples

    frame = robot.surface("right_sole").frame
    data = robot.model.createData()

    def height(q):
        pin.framesForwardKinematics(robot.model, data, q)
        return data.oMf[robot.model.getFrameId(frame)].translation[2]

    def deep_descents_collide(between, q0, q1, held=False):
        dropped = height(q0) - height(q1)
        return (0.5, CollisionPairStub(), dropped) if dropped > 0.01 and abs(height(q1)) < 1e-3 else None

    monkeypatch.setattr(BetweenSamples, "first_collision", deep_descents_collide)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert motion.feasible, motion.reason
    inserted = [(path, result) for path, result in zip(motion.paths, motion.results) if "(between samples" in path.label]
    assert len(inserted) == 1
    path, result = inserted[0]
    assert isinstance(path, FramePlacementConstraint)
    assert result.statistics["options"]["touching"] == (("right_sole", "floor"),)
    assert height(result.q) == pytest.approx(0.0075, abs=1e-6)
    assert verify_motion(motion, step_plan, scenario, robot) == []


@dataclass
class CollisionPairStub:
    name_a: str = "a"
    name_b: str = "b"
    distance: float = 0.0


@pytest.mark.parametrize("scenario_name, stance_name, surface", [("stand", "stand", "floor"),
                                                                  ("step-on-cube", "step-on-cube", "cube_top")],
                         ids=["rigid", "soft"])
def test_the_unloaded_contact_row_matches_finite_differences(robot, scenario_name, stance_name, surface):
    """The right sole's normal load and its derivative in q and the contact variables (on
    the soft cube with bonded nodes: the Coulomb solve's modes would switch under the steps)."""
    scenario = environments.load(scenario_name)
    stance = scenario.stance(stance_name)
    problem = stances.build_problem(robot, scenario.scene, stance, stances.PostureOptions(contact_law="bonded"))
    sample = ContactSample(robot.surface("right_sole").frame, "right_sole", surface, "touch-down of right_sole")
    rng = np.random.default_rng(5)
    standing = stances.solve(robot, scenario.scene, stance, deformable_as_rigid=True).q
    q = pin.integrate(robot.model, standing, 1e-3 * rng.standard_normal(robot.model.nv))
    lam = problem.initial_variables(q) + rng.uniform(1.0, 50.0, problem.n_variables)

    def row(x):
        step_q = pin.integrate(robot.model, q, x[: robot.model.nv])
        (block,) = sample.blocks(problem, problem.iterate(step_q, lam + x[robot.model.nv:]))
        return block

    block = row(np.zeros(problem.n_step))
    assert block.labels == ("touch-down of right_sole (normal load)",)
    assert block.upper[0] == 0.0 and block.lower[0] == -np.inf
    assert block.value[0] > 1.0  # the sole pushes (N)
    step = 1e-7
    numeric = np.array([(row(step * e).value[0] - row(-step * e).value[0]) / (2 * step) for e in np.eye(problem.n_step)])
    np.testing.assert_allclose(block.jacobian[0], numeric, rtol=1e-5, atol=1e-5 * np.abs(numeric).max())


def test_a_contact_sample_of_a_print_the_problem_lacks_is_refused(robot, scenario):
    problem = stances.build_problem(robot, scenario.scene, scenario.stance("stand"))
    iterate = problem.iterate(robot.reference_configuration, problem.initial_variables(robot.reference_configuration))
    sample = ContactSample(robot.surface("right_palm").frame, "right_palm", "floor", "touch-down of right_palm")
    with pytest.raises(MotionError) as error:
        sample.blocks(problem, iterate)
    assert str(error.value) == "touch-down of right_palm: the posture problem has no print 'right_palm on floor'"
    assert ContactSample("f", "p", "s", "l", unloaded=False).blocks(problem, iterate) == []  # load transfer: no row


def test_verify_motion_reports_a_touch_down_that_carries_load_or_is_missing(step_plan, motions, scenario, robot):
    motion = motions[1]
    arrived = step_plan.stances[2]
    # The touch-down sample replaced by the arriving stance's own posture, where the sole bears weight.
    configurations = np.array(motion.configurations)
    configurations[-2] = arrived.q
    loaded = replace(motion, configurations=configurations, results=motion.results[:-1] + (arrived.result,))
    problems = verify_motion(loaded, step_plan, scenario, robot)
    load = np.linalg.norm(np.sum([p.force for p in arrived.result.point_forces
                                  if p.frame == robot.surface("right_sole").frame], axis=0))
    assert load > 100.0
    assert problems == [f"sample 6 (touch-down of right_sole): {load:.3g} N on right_sole"]
    missing = replace(motion, configurations=np.delete(motion.configurations, -2, axis=0), paths=motion.paths[:-1],
                      results=motion.results[:-1])
    assert verify_motion(missing, step_plan, scenario, robot) == ["no touch-down or lift-off sample: a motion has one at least"]


def test_verify_motion_reports_a_contact_sample_recorded_off_its_frame(step_plan, motions, scenario, robot):
    motion = motions[1]
    touch = motion.paths[-1]
    moved = np.array(touch.transform_frame_to_world)
    moved[0, 3] += 1.0
    broken = replace(motion, paths=motion.paths[:-1] + (replace(touch, transform_frame_to_world=moved),))
    assert verify_motion(broken, step_plan, scenario, robot) == ["sample 6: right_sole is 1 m or rad off its path"]


def test_a_touch_down_needs_no_minimum_load_on_any_print(step_plan, scenario, robot):
    """min_normal_force asks every print to carry some load; the unloaded sample is exempt."""
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3, solver_options={"min_normal_force": 5.0})
    assert motion.feasible, motion.reason
    touch = motion.results[-1]
    assert "min_normal_force" not in touch.statistics["options"]  # its default, 0 N
    assert motion.results[0].statistics["options"]["min_normal_force"] == 5.0  # the path samples keep it
    assert motion.paths[-1].load(touch) < UNLOADED_FORCE
    assert verify_motion(motion, step_plan, scenario, robot, solver_options={"min_normal_force": 5.0}) == []


def _held_steps_collide_once(monkeypatch):
    """Make the first step whose two ends hold the moving contact 'collide' (1 cm deep), once."""
    from cbm.between_samples import BetweenSamples

    real, hits = BetweenSamples.first_collision, []

    def held_step_collides_once(between, q0, q1, held=False):
        if held and not hits:
            hits.append((q0, q1))
            return (0.5, CollisionPairStub(), 0.01)
        return real(between, q0, q1, held)

    monkeypatch.setattr(BetweenSamples, "first_collision", held_step_collides_once)


def test_a_colliding_load_transfer_step_gets_a_loaded_sample_of_the_holding_stance(step_plan, scenario, robot,
                                                                                   monkeypatch):
    """(From a review.) The step from touch-down to the arriving stance made to collide once."""
    _held_steps_collide_once(monkeypatch)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert motion.feasible, motion.reason
    transfer = motion.paths[-1]
    assert isinstance(transfer, ContactSample) and not transfer.unloaded
    assert transfer.label == "load transfer of right_sole (between samples 6 and 7)"
    assert motion.paths[-2].unloaded and motion.paths[-2].label == "touch-down of right_sole"
    assert motion.results[-1].stance == step_plan.stances[2].stance
    # Halfway between touch-down (no load) and the stance, the sole carries half the
    # stance's load along the floor's normal (z), within the solver's tolerance.
    frame = robot.surface("right_sole").frame
    stance_load = sum(p.force[2] for p in step_plan.stances[2].point_forces if p.frame == frame)
    assert stance_load > 100.0 and transfer.normal_load == pytest.approx(0.5 * stance_load, abs=1e-12)
    halfway_load = sum(p.force[2] for p in motion.results[-1].forces_on(frame))
    assert halfway_load == pytest.approx(0.5 * stance_load, abs=1e-6)
    # Pulled toward the step's midpoint harder than a stance toward its reference posture.
    assert motion.results[-1].statistics["options"]["posture_weight"] == 10.0
    assert verify_motion(motion, step_plan, scenario, robot) == []
    # A sample claiming another load than its print carries is reported.
    claimed = replace(transfer, normal_load=transfer.normal_load + 1.0)
    problems = verify_motion(replace(motion, paths=motion.paths[:-1] + (claimed,)), step_plan, scenario, robot)
    assert problems == [f"sample 7 ({transfer.label}): its print carries {halfway_load:.6g} N along its normal, "
                        f"not the {transfer.normal_load + 1.0:.6g} N pinned"]


def test_a_load_transfer_sample_whose_load_cannot_be_met_is_solved_with_its_load_free(step_plan, scenario, robot,
                                                                                       monkeypatch):
    """The colliding load-transfer step again, with every posture pinned to a load refused."""
    _held_steps_collide_once(monkeypatch)
    solve, pinned = stances.solve, []

    def pinned_loads_refused(robot_, scene, stance, constraints=(), **options):
        result = solve(robot_, scene, stance, constraints=constraints, **options)
        if constraints and getattr(constraints[0], "normal_load", None) is not None:
            pinned.append(constraints[0].normal_load)
            return replace(result, feasible=False, reason="refused by the test")
        return result

    monkeypatch.setattr(stances, "solve", pinned_loads_refused)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert motion.feasible, motion.reason
    transfer = motion.paths[-1]
    assert transfer.label == "load transfer of right_sole (between samples 6 and 7)"
    assert transfer.normal_load is None and not transfer.unloaded
    assert len(pinned) == 3  # tried from the midpoint, then from either end
    assert verify_motion(motion, step_plan, scenario, robot) == []


def test_the_seam_moves_past_a_lift_off_sample(step_plan, scenario, robot, monkeypatch):
    """(From a review.) Waypoint 3 out of reach forward on a lift-off: the seam counts the lift-off sample."""
    solve, backward = stances.solve, []

    def waypoint_3_out_of_reach_forward(robot_, scene, stance, q_init=None, constraints=(), **options):
        result = solve(robot_, scene, stance, q_init=q_init, constraints=constraints, **options)
        label = getattr(constraints[0], "label", "") if constraints else ""
        backward.append("waypoint 5" in label or bool(backward and backward[-1]))
        if "waypoint 3" in label and not backward[-1]:
            return replace(result, feasible=False, reason="blocked by the test")
        return result

    monkeypatch.setattr(stances, "solve", waypoint_3_out_of_reach_forward)
    motion = plan_motion(step_plan, 0, scenario, robot, samples=3)
    assert motion.feasible and motion.paths[0].label == "lift-off of right_sole"
    assert motion.paths[motion.seam - 1].label == "path of right_sole (waypoint 3)"  # the first backward sample


def test_a_touch_down_on_foam_beside_a_loaded_sole_is_unloaded_and_held_rigid(robot):
    """(From a review.) On a soft mat the unloaded sole is held rigid on the undeformed surface."""
    from conftest import coarse_scenario

    scenario = coarse_scenario("cross-soft-block")
    both = scenario.stance("both-on-foam")
    plan = _plan_of(robot, scenario, (both.without("right_sole"), both))
    # (The arriving stance, solved from rest, is solved again from where the motion leaves the
    # left sole's print: the plan plan_motions returns holds that answer.)
    plan, (motion,) = plan_motions(plan, scenario, robot, samples=3)
    assert motion.feasible, motion.reason
    touch = motion.results[-1]
    assert motion.paths[-1].unloaded and touch.statistics["options"]["rigid_prints"] == ("right_sole",)
    assert motion.paths[-1].load(touch) < UNLOADED_FORCE
    assert verify_motion(motion, plan, scenario, robot) == []


@pytest.mark.parametrize("reposing_helps", [True, False])
def test_a_stance_whose_posture_its_motion_cannot_reach_is_solved_again_from_the_touch_down(
        step_plan, scenario, robot, monkeypatch, reposing_helps):
    """Every step into the last stance's planned posture is made to 'collide' (with
    ``reposing_helps`` False, every step into any posture of that stance): the touch-down
    motion fails, the stance is solved again from its touch-down sample, and the motion
    into the new posture is found; where nothing helps, plan and motion stay as they were."""
    from cbm.between_samples import BetweenSamples

    planned = np.array(step_plan.stances[2].q)
    real = BetweenSamples.first_collision
    data = robot.model.createData()
    frame = robot.model.getFrameId(robot.surface("right_sole").frame)

    def settled(q):  # the right sole down at its new print (x = 0.15 m), as in the last stance
        pin.framesForwardKinematics(robot.model, data, q)
        return abs(data.oMf[frame].translation[0] - 0.15) < 0.02 and abs(data.oMf[frame].translation[2]) < 1e-3

    def blocked(between, q0, q1, held=False):
        into = np.array_equal(q1, planned) if reposing_helps else (held and settled(q1) and settled(q0))
        return (0.5, CollisionPairStub(), 0.01) if into else real(between, q0, q1, held)

    monkeypatch.setattr(BetweenSamples, "first_collision", blocked)
    plan, motions = plan_motions_reposing(step_plan, scenario, robot, samples=3)
    assert motions[0].feasible and not motions[0].reposed
    np.testing.assert_array_equal(plan.stances[1].q, step_plan.stances[1].q)
    if not reposing_helps:
        assert not motions[1].feasible and not motions[1].reposed
        assert plan.stances == step_plan.stances
        assert motions_summary(motions) == "motions: 1 of 2 found"
        return
    assert motions[1].feasible and motions[1].reposed
    reposed = plan.stances[2]
    assert reposed.stance == step_plan.stances[2].stance and reposed.move == step_plan.stances[2].move
    assert not np.array_equal(reposed.q, planned) and reposed.result.feasible
    np.testing.assert_array_equal(motions[1].configurations[-1], reposed.q)
    touch = next(r for p, r in zip(motions[1].paths, motions[1].results) if isinstance(p, ContactSample) and p.unloaded)
    # Solved from the touch-down and pulled toward it: nearer it than the planned posture.
    assert np.abs(reposed.q[7:] - touch.q[7:]).max() < np.abs(planned[7:] - touch.q[7:]).max()
    assert verify_motion(motions[1], plan, scenario, robot) == []
    assert plan.check(scenario, robot).ok
    assert motions_summary(motions) == "motions: 2 of 2 found; stances reposed for the motion into them: 2"


def test_a_reposed_middle_stance_starts_the_next_motion(step_plan, scenario, robot, monkeypatch):
    """Every step into the lift-off's arriving posture (stance 1, the left sole alone) made
    to 'collide': the stance is solved again from the last lifted sample, the lift-off
    motion found into it, and the touch-down motion after it starts there."""
    from cbm.between_samples import BetweenSamples

    planned = np.array(step_plan.stances[1].q)
    real = BetweenSamples.first_collision

    def blocked(between, q0, q1, held=False):
        return (0.5, CollisionPairStub(), 0.01) if np.array_equal(q1, planned) else real(between, q0, q1, held)

    monkeypatch.setattr(BetweenSamples, "first_collision", blocked)
    plan, motions = plan_motions_reposing(step_plan, scenario, robot, samples=3)
    assert [m.feasible for m in motions] == [True, True] and [m.reposed for m in motions] == [True, False]
    reposed = plan.stances[1].q
    assert not np.array_equal(reposed, planned)
    np.testing.assert_array_equal(motions[0].configurations[-1], reposed)
    np.testing.assert_array_equal(motions[1].configurations[0], reposed)
    np.testing.assert_array_equal(plan.stances[2].q, step_plan.stances[2].q)  # the others keep theirs
    assert all(verify_motion(m, plan, scenario, robot) == [] for m in motions)
    assert plan.check(scenario, robot).ok


def test_a_contact_sample_refuses_a_load_it_cannot_carry():
    with pytest.raises(MotionError) as error:
        ContactSample("f", "right_sole", "floor", "touch-down of right_sole", unloaded=True, normal_load=5.0)
    assert str(error.value) == ("touch-down of right_sole: an unloaded sample carries no normal_load "
                                "(it is held at zero)")
    for load in (-1.0, float("nan"), float("inf")):
        with pytest.raises(MotionError) as error:
            ContactSample("f", "right_sole", "floor", "load transfer", unloaded=False, normal_load=load)
        assert str(error.value) == f"load transfer: normal_load must be a finite load >= 0 newtons, got {load!r}"
    assert ContactSample("f", "right_sole", "floor", "load transfer", unloaded=False, normal_load=3).normal_load == 3.0


def test_motion_defaults_are_those_the_readme_measured():
    """The tests plan with 3 samples for speed; `cbm plan --motion` runs the defaults the
    README's measurements used: 6 waypoints across, 5 cm above the higher end, at most
    2 samples inserted in one step."""
    import inspect

    parameters = inspect.signature(plan_motion).parameters
    assert (parameters["samples"].default, parameters["clearance"].default, parameters["max_splits"].default) == (6, 0.05, 2)


def test_a_waypoint_not_reached_is_retried_from_a_waypoint_halfway_first(robot, monkeypatch):
    """The continuation's order: the far waypoint fails, the one halfway toward it is
    solved next (its placement halfway), then the far one again from there."""
    from types import SimpleNamespace

    import cbm.motion as motion

    solved = []

    def fake_solve(robot_, scene, support, holding, path, reference, q, previous, options, history=None):
        solved.append((path.label, np.round(path.transform_frame_to_world[:3, 3], 12).tolist()))
        # The far waypoint is out of reach from the start only.
        return SimpleNamespace(feasible=len(solved) > 1, q=q, reason="too far")

    monkeypatch.setattr(motion, "_solve_sample", fake_solve)
    target = np.eye(4)
    target[:3, 3] = [0.2, 0.0, 0.1]
    far = FramePlacementConstraint(robot.surface("right_sole").frame, target, label="right_sole (across)")
    q = robot.reference_configuration
    done = motion._continuation(robot, None, None, [("across", far, q)], q, np.eye(4), {}, max_splits=2)
    assert solved == [
        ("right_sole (across)", [0.2, 0.0, 0.1]),
        ("right_sole (toward across)", [0.1, 0.0, 0.05]),
        ("right_sole (across)", [0.2, 0.0, 0.1]),
    ]
    assert done.pending == [] and done.reason == ""
    assert [p.label for p in done.reached] == ["right_sole (toward across)", "right_sole (across)"]


def test_samples_inserted_around_the_seam_keep_it_on_the_first_backward_sample(step_plan, scenario, robot,
                                                                                monkeypatch):
    """Forward solves fail past the middle (the rest solved backward); the first step of the
    motion and the first step after the seam are made to collide once each: the sample inserted
    before the seam moves it, the one after it does not."""
    from cbm.between_samples import BetweenSamples

    solve, frame = stances.solve, robot.surface("right_sole").frame
    middle = 0.5 * (_frame_x(robot, step_plan.stances[1].q, frame) + _frame_x(robot, step_plan.stances[2].q, frame))

    def blocked_past_the_middle(robot_, scene, stance, q_init=None, constraints=(), **options):
        result = solve(robot_, scene, stance, q_init=q_init, constraints=constraints, **options)
        waypoint = getattr(constraints[0], "transform_frame_to_world", None)
        if waypoint is not None and _frame_x(robot, q_init, frame) < middle < waypoint[0, 3]:
            return replace(result, feasible=False, reason="blocked by the test")
        return result

    real, hits = BetweenSamples.first_collision, []

    def two_steps_collide_once(between, q0, q1, held=False):
        first = not hits
        past = _frame_x(robot, q0, frame) > middle and _frame_x(robot, q1, frame) > middle and "past" not in hits
        if first or past:
            hits.append("past" if past else "first")
            return (0.5, CollisionPairStub(), 0.01)
        return real(between, q0, q1, held)

    monkeypatch.setattr(stances, "solve", blocked_past_the_middle)
    monkeypatch.setattr(BetweenSamples, "first_collision", two_steps_collide_once)
    motion = plan_motion(step_plan, 1, scenario, robot, samples=3)
    assert motion.feasible, motion.reason
    assert hits == ["first", "past"]
    labels = [p.label for p in motion.paths]
    assert labels[0] == "path of right_sole (between samples 0 and 1)"  # inserted before the seam
    first_backward = labels[motion.seam - 1]
    assert first_backward.startswith("path of right_sole (waypoint ")
    assert labels[motion.seam].startswith("path of right_sole (between samples ")  # inserted after it
    x = [_frame_x(robot, q, frame) for q in motion.configurations]
    assert x[motion.seam - 1] < middle < x[motion.seam]


def _sole_held_above_floor(robot, scenario, height, **options):
    """The left sole alone holds the robot; the right sole's frame is held ``height`` above its stand print."""
    stance = scenario.stance("stand")
    stand = stances.solve(robot, scenario.scene, stance)
    frame = robot.surface("right_sole").frame
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, stand.q)
    target = data.oMf[robot.model.getFrameId(frame)].homogeneous.copy()
    target[2, 3] += height
    support = stance.without("right_sole")
    result = stances.solve(robot, scenario.scene, support, q_init=stand.q,
                           constraints=(FramePlacementConstraint(frame, target),), **options)
    return support, result


def test_touching_lets_a_limb_come_nearer_its_support_than_the_collision_distance(robot, scenario):
    # 2 mm above the floor is nearer than the 5 mm the solver keeps: held so, the sole's
    # collision row cannot be met; with the pair touching, it can, and verify passes.
    support, kept = _sole_held_above_floor(robot, scenario, 2e-3)
    assert not kept.feasible and "collision between" in kept.reason and "floor" in kept.reason
    touching = {"touching": (("right_sole", "floor"),)}
    support, near = _sole_held_above_floor(robot, scenario, 2e-3, **touching)
    assert near.feasible, near.reason
    assert stances.verify(robot, scenario.scene, support, near, **touching).ok
    checker = stances.build_problem(robot, scenario.scene, support, stances.PostureOptions(**touching)).collision_checker
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, near.q)
    sole = [p.distance for p in checker.pairs(robot.model, data) if p.name_b == "floor" and "right" in p.name_a]
    assert sole and 0.0 <= min(sole) < 2.5e-3
    # What the rows keep: 0.1 mm for the touching pair, the collision distance for the rest.
    problem = stances.build_problem(robot, scenario.scene, support, stances.PostureOptions(**touching))
    block = next(b for b in problem.linearize(near.q, near.statistics["lambda"]).blocks if b.name == "collision")
    lower = dict(zip(block.labels, block.lower))
    assert any(bound == 1e-4 and "right" in label and "floor" in label for label, bound in lower.items())
    assert all(bound == stances.PostureOptions().collision_distance for label, bound in lower.items()
               if "floor" not in label and "inactive" not in label)


def test_touching_names_are_checked():
    with pytest.raises(stances.StanceError, match=r"touching must be a sequence of \(robot surface, scene surface\)"):
        stances.PostureOptions(touching=("right_sole", "floor"))
    with pytest.raises(stances.StanceError, match="touching must be"):
        stances.PostureOptions(touching=(("right_sole",),))
    assert stances.PostureOptions(touching=[["right_sole", "floor"]]).touching == (("right_sole", "floor"),)


def test_touching_unknown_surfaces_are_named(robot, scenario):
    stance = scenario.stance("stand")
    with pytest.raises(stances.StanceError, match="right_hand"):
        stances.build_problem(robot, scenario.scene, stance, stances.PostureOptions(touching=(("right_hand", "floor"),)))
    with pytest.raises(environments.SceneError, match="ceiling"):
        stances.build_problem(robot, scenario.scene, stance, stances.PostureOptions(touching=(("right_sole", "ceiling"),)))


def test_a_retreat_moves_the_rise_off_its_free_end_and_takes_it_back_across():
    start, end = np.eye(4), np.eye(4)
    end[:3, 3] = [0.3, 0.0, 0.1]
    away = np.array([-0.05, 0.0, 0.0])
    straight = lifted_path(start, end, [0.0, 0.0, 1.0], 0.05, 5)
    path = lifted_path(start, end, [0.0, 0.0, 1.0], 0.05, 5, retreat=(away, None))
    shift = path[:, :3, 3] - straight[:, :3, 3]
    s = np.arange(7) / 6
    across = np.clip((s - RAMP) / (1.0 - 2.0 * RAMP), 0.0, 1.0)
    # None at the start's approach, all of it at the top of the rise, none once across.
    np.testing.assert_allclose(shift, np.outer(np.minimum(s / RAMP, 1.0) * (1.0 - across), away), atol=1e-15)
    assert shift[0].tolist() == [0.0, 0.0, 0.0] and shift[-1].tolist() == [0.0, 0.0, 0.0]
    np.testing.assert_array_equal(path[:, :3, :3], straight[:, :3, :3])
    # Given for the end, the same offset mirrored: kept from the top of the fall.
    mirrored = lifted_path(start, end, [0.0, 0.0, 1.0], 0.05, 5, retreat=(None, away))
    np.testing.assert_allclose(mirrored[:, :3, 3] - straight[:, :3, 3], shift[::-1], atol=1e-15)


@pytest.fixture(scope="module")
def romeo_reach():
    """Romeo standing, then its right palm on the soft cube (romeo-hand-on-soft-cube): its
    right hand hangs with the wrist 5 mm from the cube's front face."""
    scenario = environments.load("romeo-hand-on-soft-cube")
    romeo = stances.Robot.load(scenario.robot)
    planned, q = [], None
    for name in ("stand", "hand-on-soft-cube"):
        result = stances.solve(romeo, scenario.scene, scenario.stance(name), q_init=q)
        assert result.feasible, result.reason
        q = result.q
        planned.append(PlannedStance(scenario.stance(name), result.q, result.point_forces, {}, result, move=""))
    plan = Plan(True, "goal reached", planned, PlanStatistics(), scenario.name,
                robot=robot_description(romeo), scenario_source=scenario_source(scenario))
    return romeo, scenario, plan


def test_a_hand_beside_its_support_is_drawn_off_it_before_it_rises(romeo_reach):
    """Straight up from where it hangs, Romeo's wrist sweeps through the cube's face
    between samples and no posture halfway holds the palm on its chord; drawn 5 cm off
    that face first (away from the nearest scene object, across the print's normal), the
    motion is found and every sample and step verifies."""
    romeo, scenario, plan = romeo_reach
    start, end = retreat(romeo, scenario.scene, plan.stances[0], plan.stances[1], 0.05)
    assert end is None  # a touch-down: the start is the free end
    np.testing.assert_allclose(start, [-0.05, 0.0, 0.0], atol=1e-6)  # off the face at x = 0.17 m
    motion = plan_motion(plan, 0, scenario, romeo)
    assert motion.feasible, motion.reason
    assert verify_motion(motion, plan, scenario, romeo) == []
    # The second waypoint, on the rise, lies more than 1 cm behind where the palm hangs.
    assert motion.targets[1][0, 3] < plan_motion_start_x(romeo, plan) - 0.01
    # Without the detour the same motion fails: the wrist through the cube.
    straight = _motion_on_path(plan, 0, scenario, romeo, None, samples=6, clearance=0.05, max_splits=2,
                               solver_options=None, held_drift=HELD_DRIFT)
    assert not straight.feasible and "r_wrist_0 and cube" in straight.reason


def plan_motion_start_x(robot, plan):
    """x of the right palm frame where Romeo stands (world, metres)."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, plan.stances[0].q)
    return data.oMf[robot.frame_id(robot.surface("right_palm").frame)].translation[0]


def test_a_free_foot_over_the_floor_has_no_retreat(step_plan, scenario, robot):
    """The lifted right sole's nearest scene object is the floor under it, whose normal
    lies along the print's: there is nothing to draw the foot off across the normal."""
    from cbm.motion import _ACROSS
    from stances.problem import stance_collision_checker

    lifted = step_plan.stances[1]
    checker = stance_collision_checker(robot, scenario.scene, lifted.stance, stances.PostureOptions())
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, lifted.q)
    leg = set(robot.model.subtrees[robot.model.getJointId(robot.limbs["right_leg"])])
    near = [p for p in checker.pairs(robot.model, data) if not p.is_self_collision and p.joint_a in leg]
    assert near and min(near, key=lambda p: p.distance).name_b == "floor"
    assert np.hypot(*min(near, key=lambda p: p.distance).normal[:2]) < _ACROSS
    assert retreat(robot, scenario.scene, step_plan.stances[0], step_plan.stances[1], 0.05) is None


def test_a_saved_trajectory_gives_back_each_motion_to_replay(step_plan, motions, tmp_path):
    """read_trajectory(...).motions(): what cbm check plan.json --view replays between the
    stances: each found motion's samples between its two stances' postures, bit for bit."""
    from cbm.trajectory import read_trajectory

    _, npz_path = write_trajectory(plan_trajectory(step_plan, motions), tmp_path / "trajectory")
    replayed = read_trajectory(npz_path).motions()
    found = [m for m in motions if m.feasible]
    assert [m.index for m in replayed] == [m.index for m in found] and found
    for again, motion in zip(replayed, found):
        assert again.feasible
        np.testing.assert_array_equal(again.configurations, motion.configurations)
