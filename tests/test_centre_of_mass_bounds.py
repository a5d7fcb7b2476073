"""``stances.CentreOfMassBounds``: a caller's rows keeping the centre of mass in a box."""

from __future__ import annotations

import math

import environments
import numpy as np
import pinocchio as pin
import pytest

from stances import CentreOfMassBounds, StanceError, solve
from stances.problem import PostureOptions, build_problem

EPS = 1e-6


@pytest.fixture(scope="module")
def stand_problem(robot):
    scenario = environments.load("stand")
    return build_problem(robot, scenario.scene, scenario.stance("stand"), PostureOptions()), scenario


def test_its_rows_are_the_centre_of_mass_with_the_jacobian_finite_differences_give(robot, stand_problem):
    problem, _ = stand_problem
    bounds = CentreOfMassBounds(lower=(0.0, -math.inf, 0.5), upper=(0.1, 0.2, math.inf), label="kept")
    model = robot.model
    rng = np.random.default_rng(3)
    q = pin.integrate(model, robot.reference_configuration, 0.2 * rng.normal(size=model.nv))
    lam = problem.initial_variables(q)
    linearization = problem.linearize(q, lam)
    iterate = problem.iterate(q, lam)
    (block,) = bounds.blocks(problem, iterate)
    assert block.labels == ("kept (x)", "kept (y)", "kept (z)")
    assert np.array_equal(block.lower, [0.0, -math.inf, 0.5]) and np.array_equal(block.upper, [0.1, 0.2, math.inf])
    centre = pin.centerOfMass(model, model.createData(), q)
    assert np.allclose(block.value, centre, atol=1e-14)
    columns = []
    for i in range(model.nv):
        step = np.zeros(model.nv)
        step[i] = EPS
        ahead = pin.centerOfMass(model, model.createData(), pin.integrate(model, q, step))
        behind = pin.centerOfMass(model, model.createData(), pin.integrate(model, q, -step))
        columns.append((ahead - behind) / (2 * EPS))
    assert block.jacobian.shape == (3, problem.n_step) and not block.jacobian[:, model.nv :].any()
    assert np.allclose(block.jacobian[:, : model.nv], np.column_stack(columns), atol=1e-8)
    # Values only (a line search's trial): the same numbers, no Jacobian; the problem's own
    # kinematics untouched.
    (values,) = bounds.blocks(problem, problem.iterate(q, lam, derivatives=False))
    assert values.jacobian is None and np.array_equal(values.value, block.value)
    assert np.array_equal(problem.linearize(q, lam).gradient, linearization.gradient)


def test_a_solve_keeps_the_centre_of_mass_in_the_box_the_caller_gives(robot, stand_problem):
    _, scenario = stand_problem
    stance = scenario.stance("stand")
    free = solve(robot, scenario.scene, stance)
    bounds = CentreOfMassBounds(lower=(free.q[0] + 0.03, -math.inf, -math.inf), label="ahead")
    assert bounds.position(robot.model, free.q)[0] < bounds.lower[0]
    held = solve(robot, scenario.scene, stance, constraints=[bounds])
    assert held.feasible and held.verification.ok, held.reason
    assert bounds.position(robot.model, held.q)[0] >= bounds.lower[0] - 1e-8
    # Beyond the soles no posture holds it: refused, the rows named in the reason.
    beyond = CentreOfMassBounds(lower=(0.5, -math.inf, -math.inf), label="ahead")
    refused = solve(robot, scenario.scene, stance, constraints=[beyond])
    assert not refused.feasible and "ahead (x)" in refused.reason


@pytest.mark.parametrize("arguments, message", [
    ({"lower": (0.1, 0.2)}, r"CentreOfMassBounds lower must be three numbers \(x, y, z, metres; -inf / inf where an "
                            r"axis has no bound\), got \(0.1, 0.2\)"),
    ({"upper": (0.0, math.nan, 1.0)}, r"CentreOfMassBounds upper must be three numbers"),
    ({"lower": "ahead"}, r"CentreOfMassBounds lower must be three numbers \(x, y, z, metres\), got 'ahead'"),
    ({"lower": (0.2, 0.0, 0.0), "upper": (0.1, 1.0, 1.0)},
     r"CentreOfMassBounds: the lower bound on x is above the upper one \(\[0.2, 0.0, 0.0\] against \[0.1, 1.0, 1.0\]\)"),
    ({}, r"CentreOfMassBounds needs a finite bound on at least one axis \(x, y or z\)"),
])
def test_bounds_that_are_no_box_are_refused_saying_what_is_wrong(arguments, message):
    with pytest.raises(StanceError, match=message):
        CentreOfMassBounds(**arguments)
