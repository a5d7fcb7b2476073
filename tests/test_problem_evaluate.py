"""The values-only evaluation a line search uses (PostureProblem.evaluate) against the
full linearisation: the same numbers, bit for bit, at random points of rigid and soft
stances, in either order (the pieces memoise what a linearisation then reuses)."""

from __future__ import annotations

import environments
import numpy as np
import pinocchio as pin
import pytest
from conftest import coarse_scenario

from dataclasses import replace

from stances import initial_configuration
from stances.errors import StanceError
from stances.narrow_phase import DistanceQuery, coal
from stances.problem import PostureOptions, build_problem

CASES = {
    "rigid-palm-on-table": ("hand-on-table", "hand-on-table", {}),
    "soft-palm-coulomb": ("hand-on-soft-cube", "hand-on-soft-cube", {}),
    "soft-feet-and-palm-on-a-stepped-foam-mesh": ("foot-and-hand-on-foam", "foot-and-hand", {}),
    "soft-palm-traction-bonded-min-load": (
        "hand-on-soft-cube", "hand-on-soft-cube",
        dict(contact_law="bonded", reaction_model="traction", min_normal_force=5.0, deformation_cost="force"),
    ),
}


def assert_same_values(evaluation, linearization):
    assert evaluation.objective == linearization.objective
    assert [b.labels for b in evaluation.blocks] == [b.labels for b in linearization.blocks]
    for values_only, full in zip(evaluation.blocks, linearization.blocks):
        assert values_only.jacobian is None
        assert full.jacobian is not None
        np.testing.assert_array_equal(values_only.value, full.value, err_msg=full.name)
        np.testing.assert_array_equal(values_only.lower, full.lower, err_msg=full.name)
        np.testing.assert_array_equal(values_only.upper, full.upper, err_msg=full.name)
    np.testing.assert_array_equal(evaluation.forces, linearization.forces)
    np.testing.assert_array_equal(evaluation.torques, linearization.torques)
    assert evaluation.max_violation() == linearization.max_violation()
    assert evaluation.met(1e-7) == linearization.met(1e-7)


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_values_only_evaluation_equals_the_linearisation_values(robot, case):
    scenario_name, stance_name, options = CASES[case]
    scenario = coarse_scenario(scenario_name)
    problem = build_problem(robot, scenario.scene, scenario.stance(stance_name), PostureOptions(**options))
    rng = np.random.default_rng(7)
    start = robot.reference_configuration
    violated = 0
    for k in range(4):
        # Postures 0.05 rad around the reference: rows violated, collision pairs
        # within reach, soft prints pressed, lifted or slipping.
        q = problem.check_configuration(pin.integrate(robot.model, start, 0.05 * rng.standard_normal(robot.nv)))
        lam = problem.initial_variables(q) + rng.uniform(0.0, 20.0, problem.n_variables)
        torque_weight = [None, 0.0, 1.0, 3.0][k]
        # Either order: the evaluation first (the line search: the accepted trial is
        # then linearised at the same point), or the linearisation first.
        if k % 2 == 0:
            evaluation = problem.evaluate(q, lam, torque_weight)
            linearization = problem.linearize(q, lam, torque_weight)
        else:
            linearization = problem.linearize(q, lam, torque_weight)
            evaluation = problem.evaluate(q, lam, torque_weight)
        assert_same_values(evaluation, linearization)
        violated += linearization.max_violation()[0] > 0.0
    assert violated  # the points are not all trivially feasible


@pytest.mark.parametrize("case", ["rigid-palm-on-table", "soft-palm-coulomb"])
def test_a_linearisation_reweighted_is_the_linearisation_at_that_torque_weight(robot, case):
    # The SQP's switch to the torque-usage term sums the costs again instead of
    # linearising again: the same bits, the same rows.
    scenario_name, stance_name, options = CASES[case]
    scenario = coarse_scenario(scenario_name)
    problem = build_problem(robot, scenario.scene, scenario.stance(stance_name), PostureOptions(**options))
    rng = np.random.default_rng(5)
    q = problem.check_configuration(pin.integrate(robot.model, robot.reference_configuration,
                                                  0.05 * rng.standard_normal(robot.nv)))
    lam = problem.initial_variables(q) + rng.uniform(0.0, 20.0, problem.n_variables)
    for first, then in ((0.0, 1.0), (1.0, 0.0), (0.0, 3.0), (1.0, 3.0)):
        reweighted = problem.reweighted(problem.linearize(q, lam, first), then)
        direct = problem.linearize(q, lam, then)
        assert reweighted.objective == direct.objective
        np.testing.assert_array_equal(reweighted.gradient, direct.gradient)
        np.testing.assert_array_equal(reweighted.hessian, direct.hessian)
        assert [b.labels for b in reweighted.blocks] == [b.labels for b in direct.blocks]
        for mine, theirs in zip(reweighted.blocks, direct.blocks):
            np.testing.assert_array_equal(mine.value, theirs.value)
            np.testing.assert_array_equal(mine.jacobian, theirs.jacobian)
        np.testing.assert_array_equal(reweighted.step_lower, direct.step_lower)
        np.testing.assert_array_equal(reweighted.step_upper, direct.step_upper)
    # The weight matters here (the term is not zero at this point).
    assert problem.linearize(q, lam, 0.0).objective != problem.linearize(q, lam, 3.0).objective
    # Evaluations elsewhere in between (a line search's trials, which overwrite the
    # problem's kinematics) change nothing it reads.
    first = problem.linearize(q, lam, 0.0)
    before = problem.reweighted(first, 3.0)
    problem.evaluate(pin.integrate(robot.model, q, 0.05 * rng.standard_normal(robot.nv)), lam, 0.0)
    after = problem.reweighted(first, 3.0)
    assert after.objective == before.objective
    np.testing.assert_array_equal(after.gradient, before.gradient)
    np.testing.assert_array_equal(after.hessian, before.hessian)
    with pytest.raises(StanceError, match="reweighted needs a linearisation of this problem"):
        problem.reweighted(replace(first, cost_parts={}), 3.0)


def test_closest_distances_and_pairs_are_the_closest_of_all_pairs(robot):
    """closest_distances / closest_pairs (the line search's and the linearisation's
    collision rows) are the first rows of every pair sorted by distance, including
    pairs against a non-convex mesh (a stepped foam block, boxed in parts)."""
    scenario = coarse_scenario("foot-and-hand-on-foam")
    problem = build_problem(robot, scenario.scene, scenario.stance("foot-and-hand"))
    checker, model, data = problem.collision_checker, robot.model, problem.data
    everything = checker.with_exclusions(checker.exclude, margin=10.0)  # no broad-phase cut
    rng = np.random.default_rng(11)
    for _ in range(3):
        q = pin.integrate(model, robot.reference_configuration, 0.1 * rng.standard_normal(robot.nv))
        pin.framesForwardKinematics(model, data, q)
        expected = sorted(
            (p for p in everything.pairs(model, data) if p.distance <= checker.margin), key=lambda p: p.distance
        )[:20]
        distances, names = checker.closest_distances(model, data, 20)
        pairs = checker.closest_pairs(model, data, 20)
        assert names == [(p.name_a, p.name_b) for p in expected] == [(p.name_a, p.name_b) for p in pairs]
        np.testing.assert_array_equal(distances, [p.distance for p in expected])
        for pair, reference in zip(pairs, expected):
            assert pair.distance == reference.distance
            np.testing.assert_array_equal(pair.point_a, reference.point_a)
            np.testing.assert_array_equal(pair.normal, reference.normal)


def test_a_shape_turned_about_its_bounding_centre_is_measured_again(robot, monkeypatch):
    """The skip's bound counts rotation. The robot's largest geometry, tilted so that its
    bounds let it through the broad phase, is placed 1 mm beyond the margin over the floor
    and measured; turned about its bounding sphere's centre (which does not move) until it
    lies within the margin, it is measured again and reported, as a checker with no past
    reports it."""
    scenario = environments.load("stand")  # a floor and nothing else
    problem = build_problem(robot, scenario.scene, scenario.stance("stand"))
    checker, model, data = problem.collision_checker, robot.model, problem.data
    floor = checker.scene_names.index("floor")
    shape_b, placement_b = checker._scene_shapes[floor], checker._scene_placements[floor]
    geometry = checker._geometry
    a = int(np.argmax(geometry.sphere_radius))
    pin.framesForwardKinematics(model, data, robot.reference_configuration)
    rotation, translation = checker._geometry_to_world(data, None)
    centre = rotation[a] @ geometry.sphere_center[a] + translation[a]

    def about_centre(turn, height):
        """Placements with geometry a turned about its sphere's centre, then raised."""
        r, t = rotation.copy(), translation.copy()
        r[a] = turn @ rotation[a]
        t[a] = centre - r[a] @ geometry.sphere_center[a] + [0.0, 0.0, height]
        return r, t

    def distance(placements):
        r, t = placements
        return DistanceQuery().distance(geometry.shapes[a], coal.Transform3s(r[a], t[a]), shape_b, placement_b)

    tilt = pin.utils.rotate("x", 0.5)
    height = checker.margin + 1e-3 - distance(about_centre(tilt, 0.0))
    before = about_centre(tilt, height)
    after = min((about_centre(pin.utils.rotate(axis, angle) @ tilt, height) for axis in "xy" for angle in (-0.3, 0.3)),
                key=distance)
    assert distance(after) < checker.margin - 1e-3
    name = (geometry.names[a], "floor")

    def placed(placements, check):
        monkeypatch.setattr(check, "_geometry_to_world", lambda data, given: placements)
        return check.closest_distances(model, data, 20)[1]

    assert name not in placed(before, checker)
    assert name in placed(after, checker)
    assert placed(after, checker.with_exclusions(checker.exclude)) == placed(after, checker)


def test_pairs_skipped_by_earlier_distances_leave_the_closest_pairs_unchanged(robot, monkeypatch):
    """Along a walk of SQP-sized steps, the closest pairs of a checker that skips
    pairs by the distances it measured before (CollisionChecker._carry_bounds, _unreachable) are
    those of a checker with no past, bit for bit, and it skips some coal calls."""
    scenario = coarse_scenario("foot-and-hand-on-foam")
    problem = build_problem(robot, scenario.scene, scenario.stance("foot-and-hand"))
    checker, model, data = problem.collision_checker, robot.model, problem.data
    calls = []
    measure = DistanceQuery.kept_distance
    monkeypatch.setattr(DistanceQuery, "kept_distance", lambda self, *args: calls.append(1) or measure(self, *args))
    rng = np.random.default_rng(5)
    q = initial_configuration(robot, scenario.scene, scenario.stance("foot-and-hand"))  # its feet and hand near the supports
    skipped = 0
    for size in (0.3, 0.03, 0.01, 0.003, 0.3, 0.001, 0.01, 0.0):
        q = pin.integrate(model, q, size * rng.standard_normal(robot.nv))
        pin.framesForwardKinematics(model, data, q)
        fresh = checker.with_exclusions(checker.exclude)  # the same pairs, nothing measured yet
        calls.clear()
        expected = fresh.closest_pairs(model, data, 20)
        every = len(calls)
        calls.clear()
        pairs = checker.closest_pairs(model, data, 20)
        skipped += every - len(calls)
        assert [(p.name_a, p.name_b) for p in pairs] == [(p.name_a, p.name_b) for p in expected]
        for pair, reference in zip(pairs, expected):
            assert pair.distance == reference.distance
            np.testing.assert_array_equal(pair.point_a, reference.point_a)
            np.testing.assert_array_equal(pair.point_b, reference.point_b)
            np.testing.assert_array_equal(pair.normal, reference.normal)
        distances, names = checker.closest_distances(model, data, 5)
        assert names == [(p.name_a, p.name_b) for p in expected[:5]]
        np.testing.assert_array_equal(distances, [p.distance for p in expected[:5]])
    assert skipped > 0
