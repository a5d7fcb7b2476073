"""The Coulomb forces' curvature in the SQP's Hessian (:meth:`stances.deformable.DeformableContact.force_curvature`).

A slipping node's friction lies along its slip, whose direction turns with the links'
motion: the soft forces curve in their variables W, and a QP whose Hessian leaves that out
asks for steps that the merit refuses once the iterate is feasible. hand-on-cube's palm
stopped so 3.2 % above the optimum its curvature reaches.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import environments
from stances import PostureOptions, solve
from stances.deformable import DeformableContact
from stances.problem import build_problem


def _objective(robot, scenario, stance, result):
    problem = build_problem(robot, scenario.scene, stance, PostureOptions())
    return problem.linearize(np.asarray(result.q), np.asarray(result.statistics["lambda"])).objective


def test_the_forces_curvature_takes_a_palm_past_the_point_where_the_line_search_stalled(robot, monkeypatch):
    """hand-on-cube with and without the forces' curvature (``force_curvature`` returning None):
    both verified, the curvature's answer 2 % lower. (The comparison reads the answer the
    solver reaches without it, which a better line search might also improve.)"""
    scenario = environments.load("hand-on-cube")
    stance = scenario.stance("hand-on-cube")
    curved = solve(robot, scenario.scene, stance)
    monkeypatch.setattr(DeformableContact, "force_curvature", lambda self, model, data, w: None)
    linear = solve(robot, scenario.scene, stance)
    assert curved.feasible and curved.verification.ok and linear.feasible and linear.verification.ok
    with_curvature, without = _objective(robot, scenario, stance, curved), _objective(robot, scenario, stance, linear)
    assert with_curvature < 0.98 * without  # measured 2.1960 against 2.2653
    assert curved.statistics["objective"] == pytest.approx(with_curvature, rel=1e-9)


@pytest.mark.parametrize("law", ["bonded", "sticking"])
def test_laws_whose_forces_are_linear_in_w_have_no_curvature(robot, law):
    scenario = environments.load("hand-on-cube")
    problem = build_problem(robot, scenario.scene, scenario.stance("hand-on-cube"), PostureOptions(contact_law=law))
    (palm,) = [c for c in problem.contacts if c.kind == "deformable"]
    q = robot.reference_configuration
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    s = problem.variable_slices[problem.contacts.index(palm)]
    assert palm.force_curvature(robot.model, data, problem.initial_variables(q)[s]) is None


def test_coulomb_prints_whose_nodes_all_stick_have_no_curvature(robot):
    """Two soles on cross-soft-block's foam at their answer: every node sticks (or lifts), the
    forces are linear in the motion, and the turn's second order is left out."""
    scenario = environments.load("cross-soft-block")
    stance = scenario.stance("both-on-foam")
    result = solve(robot, scenario.scene, stance)
    assert result.feasible, result.reason
    problem = build_problem(robot, scenario.scene, stance, PostureOptions())
    (soles,) = [c for c in problem.contacts if c.kind == "deformable"]
    s = problem.variable_slices[problem.contacts.index(soles)]
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(result.q))
    w = np.asarray(result.statistics["lambda"])[s]
    assert soles._values(robot.model, data, w).solved.n_slip == 0
    assert soles.force_curvature(robot.model, data, w) is None


def _linearization(blocks, n=4):
    from stances.problem import Linearization

    return Linearization(1.0, np.zeros(n), np.eye(n), blocks, -np.ones(n), np.ones(n), np.zeros((0, 3)), np.zeros(n))


def test_the_sqp_adds_indefinite_force_curvature_near_feasibility_only_and_one_sided_rows_always():
    """``stances.sqp._with_curvature`` on made-up blocks: an equality's curvature (either sign)
    only near feasibility, a one-sided bound's at any violation, each multiplier clipped to
    its bound's side (an upper bound's negative multiplier weighs nothing), and a positive
    semidefinite term added exactly as given."""
    from stances.blocks import ConstraintBlock
    from stances.sqp import _with_curvature

    n = 4
    seen = {}

    def curvature_of(name, matrix):
        def curvature(weights):
            seen[name] = np.array(weights)
            out = np.zeros((n, n))
            out[2:, 2:] = weights.sum() * matrix
            return out
        return curvature

    indefinite = np.array([[1.0, 0.0], [0.0, -1.0]])
    equality = ConstraintBlock("equilibrium", np.zeros(1), np.eye(n)[:1], 0.0, 0.0, 1.0, ("eq",),
                               variable_curvature=curvature_of("eq", indefinite))
    upper = ConstraintBlock("strain", np.zeros(1), np.eye(n)[1:2], -np.inf, 1.0, 1.0, ("up",),
                            variable_curvature=curvature_of("up", np.eye(2)))
    linearization = _linearization([equality, upper])
    far_qp, far = _with_curvature(linearization, {"eq": 2.0, "up": 3.0}, near_feasible=False)
    assert set(seen) == {"up"} and np.array_equal(far.hessian[2:, 2:], np.eye(2) + 3.0 * np.eye(2))
    assert np.array_equal(far_qp.hessian, far.hessian)  # no sigma A^T A without the configuration's
    seen.clear()
    _, near = _with_curvature(linearization, {"eq": 4.0, "up": 1.0}, near_feasible=True)
    assert set(seen) == {"eq", "up"}
    # Along the last variable the curvature, -4 + 1, would take the Hessian (the objective's 1
    # there) below a quarter of it: cut to -0.75; along the other, 4 + 1 is added whole.
    assert near.hessian[2, 2] == pytest.approx(1.0 + 4.0 + 1.0) and near.hessian[3, 3] == pytest.approx(0.25)
    seen.clear()
    unchanged_qp, unchanged = _with_curvature(linearization, {"up": -5.0}, near_feasible=True)
    assert "up" not in seen and unchanged is linearization and unchanged_qp is linearization
