"""The posture a solve starts from when given none: the reference posture over the stance."""

import math

import numpy as np
import pinocchio as pin
import pytest

import environments
import stances
from stances import initial_configuration, reaching_configuration
from stances.cold_start import placement_errors
from stances.problem import PostureOptions, build_problem
from stances.sqp import solve_problem


def _feet(robot, q, surfaces):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return np.array([data.oMf[robot.frame_id(robot.surface(s).frame)].translation for s in surfaces])


def _turned(stance, angle, shift):
    """The stance's prints turned by ``angle`` about the world z axis and moved by ``shift`` (on a floor)."""
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    contacts = []
    for c in stance:
        p = c.contact_print
        x, y = rotation @ np.array([p.x, p.y]) + shift
        contacts.append(environments.Contact(c.robot_surface, environments.ContactPrint(p.surface, x, y, p.theta + angle)))
    return environments.Stance(tuple(contacts))


def test_the_feet_mid_point_starts_over_the_prints_mid_point_at_the_highest_one(robot):
    """foot-on-block: one sole on the floor, one on the block. The soles' mid-point goes
    over the prints' mid-point, the base up by the block's height (the highest print),
    with the reference posture's shape unchanged."""
    scenario = environments.load("foot-on-block")
    stance = scenario.stance("foot-on-block")
    q = initial_configuration(robot, scenario.scene, stance)
    soles = [c.robot_surface for c in stance]
    prints = np.array([scenario.scene.transform_print_to_world(c.contact_print)[:3, 3] for c in stance])
    feet = _feet(robot, q, soles)
    np.testing.assert_allclose(feet.mean(axis=0)[:2], prints.mean(axis=0)[:2], atol=1e-12)
    assert feet.mean(axis=0)[2] == pytest.approx(prints[:, 2].max(), abs=1e-12)
    assert prints[:, 2].max() > prints[:, 2].min() + 0.05  # the case is one of two heights
    np.testing.assert_array_equal(q[7:], robot.reference_configuration[7:])


def test_a_turned_stance_turns_the_base_about_z(robot):
    scenario = environments.load("stand")
    angle = 0.7
    stance = _turned(scenario.stance("stand"), angle, np.array([0.4, -0.3]))
    q = initial_configuration(robot, scenario.scene, stance)
    yaw = pin.rpy.matrixToRpy(pin.XYZQUATToSE3(q[:7]).rotation)[2]
    reference_yaw = pin.rpy.matrixToRpy(pin.XYZQUATToSE3(robot.reference_configuration[:7]).rotation)[2]
    assert yaw - reference_yaw == pytest.approx(angle, abs=1e-9)
    feet = _feet(robot, q, [c.robot_surface for c in stance])
    prints = np.array([scenario.scene.transform_print_to_world(c.contact_print)[:3, 3] for c in stance])
    np.testing.assert_allclose(feet[:, :2], prints[:, :2], atol=1e-9)  # both soles land on their prints


def test_an_empty_stance_starts_at_the_reference_posture(robot):
    scenario = environments.load("stand")
    q = initial_configuration(robot, scenario.scene, environments.Stance(()))
    np.testing.assert_array_equal(q, robot.reference_configuration)


def test_a_solve_without_a_posture_starts_from_it(robot, monkeypatch):
    """solve_problem with no q_init hands the SQP the placed posture, not the raw reference."""
    import stances.sqp as sqp

    scenario = environments.load("foot-on-block")
    stance = scenario.stance("foot-on-block")
    problem = build_problem(robot, scenario.scene, stance, PostureOptions(max_iterations=1))
    seen = {}
    real = sqp.run_sqp

    def spy(problem, q, lam, limit, deadline=None, creep=False):
        seen["q"], seen["creep"] = np.array(q), creep
        return real(problem, q, lam, limit, deadline, creep)

    monkeypatch.setattr(sqp, "run_sqp", spy)
    solve_problem(problem, check=False)
    np.testing.assert_allclose(seen["q"], initial_configuration(robot, scenario.scene, stance), atol=1e-15)
    assert seen["creep"] is False  # the creep stop is the Coulomb first stage's alone
    solve_problem(problem, check=False, creep=True)
    assert seen["creep"] is True


def test_a_raised_stance_solves_from_no_posture(robot):
    """step-on-cube held rigid (both soles 0.3 m up) from no posture: feasible, in a
    few iterations (from the raw reference posture, legs inside the supports, its
    answer depended on the QP solver's last bits)."""
    scenario = environments.load("step-on-cube")
    result = stances.solve(robot, scenario.scene, scenario.stance("step-on-cube"), deformable_as_rigid=True)
    assert result.feasible, result.reason
    assert result.iterations <= 4  # 8-9 from the raw reference posture, when it converged


def test_a_soft_stance_without_warm_start_or_posture_starts_over_its_prints(robot):
    """rigid_warm_start=False, no q_init: the Coulomb solve starts from the placed
    posture (it once passed None on and raised a ConfigurationError)."""
    from conftest import coarse_scenario

    scenario = coarse_scenario("step-on-cube")
    result = stances.solve(robot, scenario.scene, scenario.stance("step-on-cube"), rigid_warm_start=False)
    assert result.feasible, result.reason
    assert "rigid_warm_start_iterations" not in result.statistics


def test_reference_positions_are_the_reference_postures_and_follow_it():
    """``Robot.reference_position`` (kept between cold starts) gives what forward kinematics
    at the reference posture gives, names an unknown frame, and follows a new reference."""
    robot = stances.Robot.load("talos")  # its own: the reference is replaced below
    frames = [robot.surface(s).frame for s in robot.surfaces] + ["base_link"]
    reference = np.array(robot.reference_configuration)

    def kinematics(q):
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, q)
        return np.array([data.oMf[robot.frame_id(f)].translation for f in frames])

    np.testing.assert_array_equal([robot.reference_position(f) for f in frames], kinematics(reference))
    with pytest.raises(stances.FrameNotFound, match="unknown frame 'no_such_frame'; known frames: "):
        robot.reference_position("no_such_frame")
    moved = reference.copy()
    moved[2] += 0.1
    moved[7:] += 0.05
    robot.reference_configuration = moved
    np.testing.assert_array_equal([robot.reference_position(f) for f in frames], kinematics(moved))
    with pytest.raises(AssertionError):
        np.testing.assert_allclose(kinematics(moved), kinematics(reference), atol=1e-3)


def _errors(robot, scene, stance, q):
    data = robot.model.createData()
    pin.computeJointJacobians(robot.model, data, q)
    pin.updateFramePlacements(robot.model, data)
    return placement_errors(robot, scene, stance, data)


@pytest.mark.parametrize("name, stance_name", [("hand-on-table", "hand-on-table"), ("quadruped-walk", "front-feet-up")])
def test_placement_errors_jacobian_matches_finite_differences(name, stance_name):
    """Soles and palms (6 rows each) and ball feet (3 rows), at a posture away from the answer."""
    scenario = environments.load(name)
    robot = stances.Robot.load(scenario.robot)
    stance = scenario.stance(stance_name)
    rng = np.random.default_rng(3)
    q = pin.integrate(robot.model, initial_configuration(robot, scenario.scene, stance), 0.1 * rng.standard_normal(robot.model.nv))
    residual, rotational, jacobian = _errors(robot, scenario.scene, stance, q)
    points = sum(robot.surface(c.robot_surface).is_point for c in stance)
    assert residual.shape == rotational.shape == (6 * len(stance) - 3 * points,) and jacobian.shape == (len(residual), robot.model.nv)
    assert rotational.sum() == 3 * (len(stance) - points)
    h = 1e-7
    numeric = np.column_stack([
        (_errors(robot, scenario.scene, stance, pin.integrate(robot.model, q, h * e))[0]
         - _errors(robot, scenario.scene, stance, pin.integrate(robot.model, q, -h * e))[0]) / (2 * h)
        for e in np.eye(robot.model.nv)])
    np.testing.assert_allclose(jacobian, numeric, atol=1e-6)


def test_the_reaching_start_brings_far_contacts_onto_their_prints_within_the_joint_limits(robot):
    """hand-on-table's palm starts 0.3-0.5 m from its print over the feet: five damped
    least-squares steps take every placement error below 1 cm or 10 mrad (the scale of the
    SQP's placement rows); joints stay within their limits; a stance already on its prints is left as
    it is (the same array values)."""
    scenario = environments.load("hand-on-table")
    stance = scenario.stance("hand-on-table")
    start = initial_configuration(robot, scenario.scene, stance)
    before = _errors(robot, scenario.scene, stance, start)[0]
    assert np.abs(before).max() > 0.3
    q = reaching_configuration(robot, scenario.scene, stance, start)
    after = _errors(robot, scenario.scene, stance, q)[0]
    assert np.abs(after).max() < 1e-2
    model = robot.model
    assert np.all(q[7:] >= model.lowerPositionLimit[7:]) and np.all(q[7:] <= model.upperPositionLimit[7:])
    stand = environments.load("stand")
    over_feet = initial_configuration(robot, stand.scene, stand.stance("stand"))
    np.testing.assert_array_equal(reaching_configuration(robot, stand.scene, stand.stance("stand"), over_feet), over_feet)
