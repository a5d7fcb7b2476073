"""stances.verify and Plan.check, each fed one violation at a time (issue 13, item 2).

One solved stance, a sole on a rigid block and a sole on a soft cube (step-on-cube,
coarse mesh), verifies as it is; each case changes what the result (or the plan file)
shows in one way, and both checks must refuse it with the reason that names it.
"""

import dataclasses
import re

import numpy as np
import pytest

import stances
from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source
from conftest import coarse_scenario, solved_stance
from stances.problem import build_problem
from stances.results import PointForce


@pytest.fixture(scope="module")
def scenario():
    return coarse_scenario("step-on-cube")


@pytest.fixture(scope="module")
def solved(robot, scenario):
    return solved_stance(robot, scenario, "step-on-cube")


@pytest.fixture(scope="module")
def problem(robot, scenario, solved):
    return build_problem(robot, scenario.scene, solved.stance)


def _slices(problem):
    """(rigid contact, its loads), (soft contact, its loads)."""
    pairs = list(zip(problem.contacts, problem.load_slices))
    return next(p for p in pairs if p[0].kind != "deformable"), next(p for p in pairs if p[0].kind == "deformable")


def _forces(result, change):
    """The result with its point forces replaced by ``change((k, 3) forces) -> (k, 3)``."""
    forces = change(np.array([p.force for p in result.point_forces]))
    return dataclasses.replace(
        result, point_forces=tuple(PointForce(p.frame, p.point, f) for p, f in zip(result.point_forces, forces))
    )


def _deformations(result, change):
    return dataclasses.replace(result, deformations={k: change(np.array(v)) for k, v in result.deformations.items()})


def _unbalanced(result, problem):
    return _forces(result, lambda f: 1.5 * f), r"free-flyer wrench unbalanced by [0-9.e+-]+ N \(N m\)"


def _out_of_cone(result, problem):
    (rigid, loads), _ = _slices(problem)

    def push(f):
        # Sideways twice the sole's normal force: outside any cone of friction below 2.
        f[loads, 0] += 2.0 * np.abs(f[loads, 2]) + 1.0
        return f

    return _forces(result, push), rf"a force of {re.escape(rigid.label)} leaves its friction cone by [0-9.e+-]+ N"


def _misplaced(result, problem):
    (rigid, _), _ = _slices(problem)
    q = np.array(result.q)
    q[2] += 0.01  # the whole robot 1 cm up: both soles leave their prints
    return dataclasses.replace(result, q=q), rf"{re.escape(rigid.label)} is off its print by 0\.01 m and [0-9.e+-]+ rad"


def _pulling(result, problem):
    _, (soft, loads) = _slices(problem)
    # The first print node pulls the sole down by 1 N along its own normal (world frame).
    normal = soft.rotation_body @ soft.node_frames[0][2]
    node = int(soft.node_ids[0])

    def pull(f):
        f[loads.start] = -1.0 * normal
        return f

    return _forces(result, pull), rf"node {node} of cube pulls on the robot \(-1 N\): adhesion"


def _node_out_of_cone(result, problem):
    _, (soft, loads) = _slices(problem)
    # The most pressed print node pushes sideways twice its normal force more: outside its
    # own cone (mu below 1, whatever tangential force it had) whatever its neighbours carry.
    forces = np.array([p.force for p in result.point_forces[loads]])
    normals = soft.rotation_body @ soft.node_frames[:, 2].T  # (3, p) world
    index = int(np.argmax(np.einsum("ij,ji->i", forces, normals)))
    tangent = soft.rotation_body @ soft.node_frames[index, 0]
    node = int(soft.node_ids[index])

    def push(f):
        f[loads.start + index] += 2.0 * (f[loads.start + index] @ normals[:, index]) * tangent
        return f

    return _forces(result, push), rf"node {node} of cube leaves its friction cone by [0-9.e+-]+ N \(tangential .*\)"


def _nan_forces(result, problem):
    frame = result.point_forces[0].frame
    return _forces(result, lambda f: np.full_like(f, np.nan)), rf"a contact force on {frame} is not finite"


def _nan_q(result, problem):
    q = np.array(result.q)
    q[10] = np.nan
    return dataclasses.replace(result, q=q), r"q has non-finite entries"


def _nan_deformation(result, problem):
    def spoil(u):
        u[7, 2] = np.nan
        return u

    n = len(next(iter(result.deformations.values())))
    return _deformations(result, spoil), rf"the deformation of cube is not a finite {n} x 3 field"


def _deformation_not_of_the_forces(result, problem):
    return _deformations(result, lambda u: 2.0 * u), r"the deformation of cube is off the one its forces make by [0-9.e+-]+ m"


def _extra_force(result, problem):
    # A balanced pair on two links (same point): no wrench on the whole robot, but
    # forces no contact holds; the sole force on the other link moves a load.
    first, last = result.point_forces[0], result.point_forces[-1]
    hook = (PointForce(first.frame, first.point, [0.0, 0.0, 5.0]), PointForce(last.frame, first.point, [0.0, 0.0, -5.0]))
    n = len(result.point_forces)
    changed = dataclasses.replace(result, point_forces=result.point_forces + hook)
    return changed, rf"{n + 2} contact forces reported for the {n} application points of the stance's contacts"


def _force_on_another_link(result, problem):
    (_, rigid_loads), (_, soft_loads) = _slices(problem)
    other = result.point_forces[soft_loads.start].frame
    own = result.point_forces[rigid_loads.start].frame
    moved = list(result.point_forces)
    moved[rigid_loads.start] = PointForce(other, moved[rigid_loads.start].point, moved[rigid_loads.start].force)
    changed = dataclasses.replace(result, point_forces=tuple(moved))
    return changed, rf"contact force {rigid_loads.start} acts on {other}, not on its contact's {own}"


CASES = {
    "unbalanced": _unbalanced,
    "out-of-cone": _out_of_cone,
    "misplaced": _misplaced,
    "pulling-node": _pulling,
    "node-out-of-cone": _node_out_of_cone,
    "nan-forces": _nan_forces,
    "nan-q": _nan_q,
    "nan-deformation": _nan_deformation,
    "deformation-not-of-the-forces": _deformation_not_of_the_forces,
    "extra-forces": _extra_force,
    "force-on-another-link": _force_on_another_link,
}


def _plan_of(robot, scenario, result, shown):
    """A one-stance plan whose stance shows ``shown``'s q, forces and deformations
    while its nested result stays ``result``."""
    planned = PlannedStance(
        result.stance, shown.q, shown.point_forces, {k: np.array(v) for k, v in shown.deformations.items()}, result
    )
    return Plan(
        False, "test", [planned], PlanStatistics(), scenario.name,
        robot=robot_description(robot), scenario_source=scenario_source(scenario),
    )


def _assert_named(reasons, pattern):
    assert any(re.fullmatch(pattern, reason) for reason in reasons), (pattern, reasons)


def test_the_untouched_result_passes_both_checks(robot, scenario, solved):
    assert stances.verify(robot, scenario.scene, solved.stance, solved).ok
    assert _plan_of(robot, scenario, solved, solved).check(scenario, robot).ok


@pytest.mark.parametrize("case", CASES)
def test_verify_refuses_the_violation_and_names_it(robot, scenario, solved, problem, case):
    changed, pattern = CASES[case](solved, problem)
    check = stances.verify(robot, scenario.scene, solved.stance, changed)
    assert not check.ok
    _assert_named(check.reasons, pattern)


@pytest.mark.parametrize("case", CASES)
def test_plan_check_refuses_the_violation_the_plan_shows(robot, scenario, solved, problem, case):
    """The plan file shows the violation; its nested result is the good one."""
    changed, pattern = CASES[case](solved, problem)
    report = _plan_of(robot, scenario, solved, changed).check(scenario, robot)
    assert not report.ok
    _assert_named(report.problems, "stance 0: .*")
    _assert_named(report.problems[0][len("stance 0: "):].split("; "), pattern)


def test_verify_refuses_a_bonded_prints_resultant_outside_its_cone(robot, scenario):
    """The paper's bonded law keeps each print's resultant in its cone (not each node's):
    the soft sole's forces pushed sideways by twice their normal sum more leave it."""
    options = {"contact_law": "bonded"}
    result = stances.solve(robot, scenario.scene, scenario.stance("step-on-cube"), **options)
    assert result.feasible, result.reason
    assert stances.verify(robot, scenario.scene, result.stance, result, **options).ok
    problem = build_problem(robot, scenario.scene, result.stance, stances.PostureOptions(**options))
    _, (soft, loads) = _slices(problem)
    normal = soft.rotation_body @ soft.node_frames[0, 2]
    tangent = soft.rotation_body @ soft.node_frames[0, 0]

    def push(f):
        f[loads] += (2.0 * (f[loads] @ normal).sum() / (loads.stop - loads.start)) * tangent
        return f

    check = stances.verify(robot, scenario.scene, result.stance, _forces(result, push), **options)
    assert not check.ok
    _assert_named(check.reasons, rf"the resultant of {re.escape(soft.prints[0].label)} leaves its friction cone "
                                 r"by [0-9.e+-]+ N \(tangential .*\)")


def _robot_with_lower_limit(joint_name, limit):
    """A fresh Talos whose one joint's effort limit is ``limit`` N m."""
    robot = stances.Robot.load("talos")
    limits = np.array(robot.model.effortLimit)
    limits[6 + robot.actuated_joint_names.index(joint_name)] = limit
    robot.model.effortLimit = limits
    return robot


@pytest.mark.parametrize("side", [1.0, -1.0], ids=["positive", "negative"])
def test_both_checks_refuse_a_torque_over_its_limit_on_either_side(scenario, solved, side):
    """The joint pushing hardest one way, its limit set to half its torque: both checks name it."""
    torques = np.asarray(solved.torques) * side
    joint = int(np.argmax(torques))
    assert torques[joint] > 10.0  # a joint that works, on this side
    names = stances.Robot.load("talos").actuated_joint_names
    weak = _robot_with_lower_limit(names[joint], 0.5 * torques[joint])
    check = stances.verify(weak, scenario.scene, solved.stance, solved)
    assert not check.ok
    # The torque recomputed by verify (RNEA) is the solver's to 1e-6 N m.
    assert check.measures["torque_margin"] == pytest.approx(-0.5 * torques[joint], abs=1e-5)
    assert check.reasons == (f"torque limit of {names[joint]} exceeded by {-check.measures['torque_margin']:.3g} N m",)
    report = _plan_of(weak, scenario, solved, solved).check(scenario, weak)
    assert report.problems == ("stance 0: " + check.reasons[0],)


def test_both_checks_refuse_a_print_deeper_than_the_bound_it_was_solved_with(robot, scenario, solved):
    """Too deep a print: verify with a bound under the print's depth; Plan.check with the
    bound recorded in the result's options (the options it was solved with)."""
    depth = stances.verify(robot, scenario.scene, solved.stance, solved).measures["indentation of cube"]
    bound = 0.5 * depth
    expected = f"a node of cube is indented {depth:.3g} m, beyond its bound {bound:.3g} m"
    check = stances.verify(robot, scenario.scene, solved.stance, solved, max_indentation=bound)
    assert expected in check.reasons
    recorded = dataclasses.replace(solved, statistics={**solved.statistics, "options": {"max_indentation": bound}})
    report = _plan_of(robot, scenario, recorded, solved).check(scenario, robot)
    assert report.problems == (f"stance 0: {expected}",)


def test_both_checks_refuse_a_mesh_overlap_beyond_the_bound_it_was_solved_with(robot, scenario, solved):
    """The soft sole's partly covered nodes lie their coupling's stretch behind the sole:
    verify with a bound under that overlap names the node and the bound; Plan.check with the
    bound recorded in the result's options."""
    overlap = stances.verify(robot, scenario.scene, solved.stance, solved).measures["mesh overlap into the links on cube"]
    assert 0.0 < overlap <= stances.PostureOptions().max_mesh_overlap
    bound = 0.5 * overlap
    pattern = rf"node [0-9]+ of cube reaches {overlap:.3g} m into its link, beyond the mesh overlap bound {bound:g} m " \
              r"\(max_mesh_overlap\)"
    check = stances.verify(robot, scenario.scene, solved.stance, solved, max_mesh_overlap=bound)
    assert not check.ok
    _assert_named(check.reasons, pattern)
    recorded = dataclasses.replace(solved, statistics={**solved.statistics, "options": {"max_mesh_overlap": bound}})
    report = _plan_of(robot, scenario, recorded, solved).check(scenario, robot)
    assert not report.ok
    _assert_named(report.problems, "stance 0: " + pattern)


def test_a_sole_turned_on_its_print_is_reported_in_metres_and_radians_apart(robot, scenario, solved, problem):
    """The placement check reads the residual's translation (m) and rotation (rad) apart:
    1 mm off and 0.02 rad turned reads so, not 0.02 m."""
    from stances.verify import VerificationTolerances

    (rigid, _), _ = _slices(problem)
    data = robot.model.createData()
    rigid._placement_residual = lambda data_: np.array([0.001, 0.0, 0.0, 0.02, 0.0, 0.0])
    try:
        measures = {}
        reasons = rigid._verify_placement(data, VerificationTolerances(), measures)
    finally:
        del rigid._placement_residual
    assert reasons == [f"{rigid.label} is off its print by 0.001 m and 0.02 rad"]
    assert measures[f"placement error of {rigid.label}"] == 0.02
