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
