"""The constraints' curvature (:mod:`stances.curvature`) against second differences of the rows' values."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

import environments
from stances import Robot
from stances.curvature import ConstraintCurvature, _kinematic_hessian, bounded_below
from stances.problem import PostureOptions, build_problem

SEED = 20261122


@pytest.fixture(scope="module")
def hand_on_table(robot):
    scenario = environments.load("hand-on-table")
    return build_problem(robot, scenario.scene, scenario.stances["hand-on-table"], PostureOptions())


def random_configuration(robot, rng, size=0.1):
    return pin.integrate(robot.model, robot.reference_configuration, size * rng.standard_normal(robot.model.nv))


def second_differences(model, q, value, step, columns=None):
    """(..., c, c) central second differences of ``dq -> value(q (+) dq)`` at 0, values
    only, along the tangent ``columns`` (all by default)."""
    nv = model.nv
    columns = np.arange(nv) if columns is None else np.asarray(columns)
    basis = step * np.eye(nv)[columns]

    def at(dq):
        return np.asarray(value(pin.integrate(model, q, dq)), float)

    count = len(columns)
    hessian = np.zeros(at(np.zeros(nv)).shape + (count, count))
    for i in range(count):
        for j in range(i, count):
            hessian[..., i, j] = hessian[..., j, i] = (
                at(basis[i] + basis[j]) - at(basis[i] - basis[j]) - at(basis[j] - basis[i]) + at(-basis[i] - basis[j])
            ) / (4.0 * step**2)
    return hessian


def test_placement_curvature_matches_second_differences_of_the_residuals(robot, hand_on_table):
    """sum_i y_i d2 c_i for the 18 placement rows (log6 of each contact frame vs its print)
    at a random posture and random multipliers, computed directly (frame_curvature):
    within 1e-6 of second differences of the residuals' values (measured 3.9e-8, what the
    second differences' steps of 1e-4 leave; the forward differences this replaced were
    1.5e-6 off)."""
    rng = np.random.default_rng(SEED)
    model, problem = robot.model, hand_on_table
    q = random_configuration(robot, rng)
    linearization = problem.linearize(q, problem.initial_variables(q))
    blocks = [block for block in linearization.blocks if block.name == "placement"]
    assert len(blocks) == 3 and all(block.second_order is not None for block in blocks)
    weights = [rng.standard_normal(len(block)) for block in blocks]
    data = model.createData()

    def weighted_residuals(configuration):
        pin.framesForwardKinematics(model, data, configuration)
        return sum(w @ contact._placement(model, data)[0] for contact, w in zip(problem.contacts, weights))

    expected = second_differences(model, q, weighted_residuals, 1e-4)
    hessian = ConstraintCurvature(model).hessian(q, blocks, weights)
    assert np.abs(expected).max() > 0.1  # the rows are curved: the test can fail
    np.testing.assert_allclose(hessian, expected, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(hessian, hessian.T)


def test_kinematic_hessian_is_read_as_the_derivative_of_each_jacobian_column(robot):
    """pinocchio's kinematic Hessian, as :func:`_kinematic_hessian` reads it, is
    ``[:, j, k] = d J_j / d q_k`` (J the joint's local Jacobian, k a tangent direction of
    ``q (+) dq``): against central differences of the Jacobian, for a leg, an arm and the
    free flyer's joint. pinocchio 3's binding hands the tensor over with mixed-up strides
    (read as it comes, a leg's is wrong by O(1)); the order is found at run time."""
    rng = np.random.default_rng(SEED)
    model = robot.model
    q = random_configuration(robot, rng, 0.3)
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.computeJointKinematicHessians(model, data)
    step = 1e-6

    def jacobian(configuration, joint):
        moved = model.createData()
        pin.computeJointJacobians(model, moved, configuration)
        return pin.getJointJacobian(model, moved, joint, pin.LOCAL)

    for name in ("leg_left_6_joint", "arm_right_7_joint", "root_joint"):
        joint = model.getJointId(name)
        expected = np.stack([
            (jacobian(pin.integrate(model, q, e), joint) - jacobian(pin.integrate(model, q, -e), joint)) / (2 * step)
            for e in step * np.eye(model.nv)
        ], axis=2)
        read = _kinematic_hessian(model, data, joint)
        np.testing.assert_allclose(read, expected, rtol=0, atol=1e-7, err_msg=name)
        # A limb's Jacobian turns with its joints; the free flyer's own local one does not.
        assert (np.abs(expected).max() > 0.5) == (name != "root_joint")


def test_placement_curvature_equals_the_differences_of_the_weighted_jacobians(robot, hand_on_table):
    """The placement rows' direct curvature (:func:`stances.curvature.frame_curvature`)
    against the forward differences of their weighted Jacobian (``second_order``), which
    it replaces: within the differences' truncation error (measured 9e-7)."""
    rng = np.random.default_rng(SEED + 1)
    model, problem = robot.model, hand_on_table
    q = random_configuration(robot, rng)
    linearization = problem.linearize(q, problem.initial_variables(q))
    blocks = [block for block in linearization.blocks if block.name == "placement"]
    assert all(block.curvature is not None for block in blocks)
    weights = [rng.standard_normal(len(block)) for block in blocks]
    curvature = ConstraintCurvature(model)
    direct = curvature.hessian(q, blocks, weights)
    differenced = curvature.hessian(q, [replace(block, curvature=None) for block in blocks], weights)
    assert np.abs(direct).max() > 0.1
    np.testing.assert_allclose(direct, differenced, rtol=0, atol=1e-5)


def test_point_foot_curvature_matches_second_differences_of_the_residuals():
    """A point foot's three placement rows (its ball's centre against its print) on
    ANYmal's three-feet stance: the direct curvature against second differences of the
    weighted residuals' values."""
    anymal = Robot.load("anymal")
    walk = environments.load("quadruped-walk")
    problem = build_problem(anymal, walk.scene, walk.stance("three-feet"), PostureOptions(min_normal_force=5.0))
    rng = np.random.default_rng(SEED + 2)
    model = anymal.model
    q = pin.integrate(model, anymal.reference_configuration, 0.1 * rng.standard_normal(model.nv))
    linearization = problem.linearize(q, problem.initial_variables(q))
    blocks = [block for block in linearization.blocks if block.name == "placement"]
    assert [len(block) for block in blocks] == [3, 3, 3] and all(block.curvature is not None for block in blocks)
    weights = [rng.standard_normal(3) for _ in blocks]
    data = model.createData()

    def weighted_residuals(configuration):
        pin.framesForwardKinematics(model, data, configuration)
        return sum(w @ contact._placement_residual(data) for contact, w in zip(problem.contacts, weights))

    expected = second_differences(model, q, weighted_residuals, 1e-4)
    hessian = ConstraintCurvature(model).hessian(q, blocks, weights)
    assert np.abs(expected).max() > 0.05
    np.testing.assert_allclose(hessian, expected, rtol=0, atol=1e-6)


def test_collision_curvature_matches_second_differences_of_the_distances(robot, hand_on_table):
    """Each collision row's curvature (its pair measured again along the differences)
    against second differences of the distance the checker reports (full broad and
    narrow phase), pair by pair, for the pairs whose distance is smooth there.

    A distance between convex hulls has kinks where its closest features are
    degenerate (parallel faces: the wrist sensor against the forearm at this
    posture); there a second derivative does not exist and the second
    differences depend on their step. Such pairs are told apart by comparing two
    steps, and left out; the rest agree within 2e-5 plus 1e-3 of the pair's
    largest curvature, per entry (the forward difference's step of 1e-5 times the
    third derivative; measured 3e-6 on most pairs, 1.7e-4 of 0.73 on the soles' hulls)."""
    rng = np.random.default_rng(SEED + 1)
    model, problem = robot.model, hand_on_table
    checker = problem.collision_checker
    q = random_configuration(robot, rng, 0.05)
    linearization = problem.linearize(q, problem.initial_variables(q))
    (block,) = [block for block in linearization.blocks if block.name == "collision"]
    # Pairs clearly apart (penetration depths come from another algorithm, EPA).
    rows = [i for i, label in enumerate(block.labels) if label.startswith("collision") and block.value[i] > 1e-3]
    data = model.createData()

    def distances(configuration):
        pin.forwardKinematics(model, data, configuration)
        measured = {f"collision between {p.name_a} and {p.name_b}": p.distance for p in checker.pairs(model, data)}
        return [measured[block.labels[i]] for i in rows]

    # Twelve of the 34 tangent columns (the free flyer's rotation, legs, torso, arms), to keep
    # the test fast; every entry among them is compared.
    columns = np.sort(np.concatenate([[3, 4], rng.choice(np.arange(6, model.nv), 10, replace=False)]))
    fine = second_differences(model, q, distances, 1e-4, columns)
    coarse = second_differences(model, q, distances, 3e-4, columns)
    smooth = [k for k in range(len(rows)) if np.abs(fine[k] - coarse[k]).max() < 1e-4]
    assert len(smooth) >= 8, (len(smooth), len(rows))
    curvature = ConstraintCurvature(model)
    for k in smooth:
        weights = np.zeros(len(block))
        weights[rows[k]] = 1.0
        hessian = curvature.hessian(q, [block], [weights])[np.ix_(columns, columns)]
        tolerance = 2e-5 + 1e-3 * np.abs(fine[k]).max()
        np.testing.assert_allclose(hessian, fine[k], rtol=0, atol=tolerance, err_msg=block.labels[rows[k]])
    assert max(np.abs(fine[k]).max() for k in smooth) > 0.1  # the distances are curved: the test can fail


def test_rows_without_second_order_or_weight_add_no_curvature(robot, hand_on_table):
    q = robot.reference_configuration
    problem = hand_on_table
    linearization = problem.linearize(q, problem.initial_variables(q))
    weights = [np.ones(len(block)) if block.second_order is None else np.zeros(len(block))
               for block in linearization.blocks]
    assert any(block.second_order is None for block in linearization.blocks)
    np.testing.assert_array_equal(ConstraintCurvature(robot.model).hessian(q, linearization.blocks, weights), 0.0)


@pytest.mark.parametrize("floor", [0.1, 0.25, 1.0])
def test_bounded_curvature_keeps_the_floor_and_only_cuts_what_breaks_it(floor):
    """reference + bounded >= floor * reference (generalised eigenvalues >= floor), with the
    curvature on the first block only; a curvature that already complies comes back unchanged."""
    rng = np.random.default_rng(SEED)
    n, k = 12, 7
    root = rng.standard_normal((n, n))
    reference = root @ root.T + 0.1 * np.eye(n)
    raw = rng.standard_normal((k, k))
    curvature = 20.0 * (raw + raw.T)
    bounded = bounded_below(curvature, reference, floor)
    full = reference.copy()
    full[:k, :k] += bounded
    lower = np.linalg.cholesky(reference)
    inverse = np.linalg.inv(lower)
    relative = np.linalg.eigvalsh(inverse @ full @ inverse.T)
    assert relative[0] == pytest.approx(floor, abs=1e-9)  # this curvature breaks the floor: cut to it
    # The cut is the least one: along directions the curvature keeps above the floor, unchanged.
    unchanged = reference.copy()
    unchanged[:k, :k] += curvature
    assert np.linalg.eigvalsh(inverse @ unchanged @ inverse.T)[-1] == pytest.approx(relative[-1], rel=1e-9)
    gentle = 0.01 * np.eye(k)
    assert bounded_below(gentle, reference, floor) is gentle
