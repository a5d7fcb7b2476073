"""The support share: each foot down carries a share of the weight, so a quadruped's
centre of mass stays inside its support polygon instead of on an edge of it."""

from __future__ import annotations

import re

import numpy as np
import pytest

import environments
import stances
from cbm.equilibrium import EQUILIBRIUM_IMPOSSIBLE, EquilibriumFilter
from cbm.motion import ContactSample
from stances import StanceError
from stances.description import SupportRule
from stances.problem import PostureOptions, build_problem

GRAVITY = 9.81


def _normal_loads(result):
    """Newtons along +z carried by each foot's contact frame (the floor's normal)."""
    loads = {}
    for point_force in result.point_forces:
        loads[point_force.frame] = loads.get(point_force.frame, 0.0) + float(point_force.force[2])
    return loads


def test_anymal_keeps_a_tenth_of_its_weight_on_each_of_three_feet(anymal, walk):
    weight = anymal.mass * GRAVITY
    stance = walk.stance("three-feet")
    held = stances.solve(anymal, walk.scene, stance)
    assert held.feasible, held.reason
    loads = _normal_loads(held)
    assert len(loads) == 3 and min(loads.values()) >= 0.1 * weight * (1 - 1e-6)
    assert sum(loads.values()) == pytest.approx(weight, rel=1e-6)
    # The objective still leans toward the edge: one foot sits on its share, and the result says which.
    assert held.limits["least_load"] == pytest.approx(min(loads.values()) / weight, rel=1e-6)
    assert held.limits["least_load"] == pytest.approx(0.1, abs=1e-5)
    assert held.limits["least_load_print"].endswith(" on floor")
    assert any(re.fullmatch(r"\w+_foot on floor carrying 10\.0 % of the weight, its least", entry)
               for entry in held.limits["at_margin"])
    # Without the share the objective leaves a foot under it (7.6 % of the weight; under 2 %
    # while the adapters' ends inside the balls, trimmed since, kept the shanks upright).
    touching = stances.solve(anymal, walk.scene, stance, support_load=0.0)
    assert touching.feasible, touching.reason
    assert touching.limits["least_load"] < 0.1 * (1 - 1e-3)
    assert not any("of the weight" in entry for entry in touching.limits["at_margin"])


def test_each_print_gets_the_larger_of_its_support_share_and_the_least_normal_force(robot):
    scenario = environments.load("hand-on-table")
    stance = scenario.stance("hand-on-table")
    weight = robot.mass * GRAVITY
    problem = build_problem(robot, scenario.scene, stance, PostureOptions(support_load=0.1, min_normal_force=5.0))
    surfaces = [surface for contact in problem.contacts for surface in contact.print_surfaces]
    expected = [0.1 * weight if robot.surface(s).role == "foot" else 5.0 for s in surfaces]
    assert "right_palm" in surfaces and "left_sole" in surfaces
    np.testing.assert_allclose(problem.min_normal_loads, expected, rtol=1e-12)
    # Talos's own rule asks nothing of its feet: a foot may just touch.
    assert robot.support.load == 0.0
    default = build_problem(robot, scenario.scene, stance)
    assert not np.any(default.min_normal_loads)
    assert not any(type(term).__name__ == "NormalLoadConstraint" for term in default.constraints)


def test_a_share_three_feet_cannot_carry_is_rejected_by_the_equilibrium_filter(anymal, walk):
    stance = walk.stance("three-feet")
    assert EquilibriumFilter(anymal, walk.scene)(stance) == ""
    # Three feet on level ground carry the weight between them: 0.34 each is more.
    reason = EquilibriumFilter(anymal, walk.scene, PostureOptions(support_load=0.34))(stance)
    assert reason.startswith(EQUILIBRIUM_IMPOSSIBLE)
    assert EquilibriumFilter(anymal, walk.scene, PostureOptions(support_load=0.33))(stance) == ""


@pytest.mark.parametrize("value, message", [
    (1.0, "support_load must be a share of the robot's weight in [0, 1) (or None: the robot's support rule), got 1.0"),
    (-0.1, "support_load must be a share of the robot's weight in [0, 1) (or None: the robot's support rule), got -0.1"),
    ("0.1", "support_load must be a share of the robot's weight in [0, 1) (or None: the robot's support rule), got '0.1'"),
    (True, "support_load must be a share of the robot's weight in [0, 1) (or None: the robot's support rule), got True"),
])
def test_a_support_load_that_is_no_share_is_refused(value, message):
    with pytest.raises(StanceError, match=re.escape(message)):
        PostureOptions(support_load=value)


@pytest.mark.parametrize("value", [1.0, float("nan"), None, True])
def test_a_support_rule_load_that_is_no_share_is_refused(value):
    with pytest.raises(StanceError, match=re.escape("support 'load' must be a share of the robot's weight in [0, 1)")):
        SupportRule(role="foot", keep=3, load=value)


def test_a_contact_sample_moves_load_through_less_than_the_share():
    touch_down = ContactSample("LF_FOOT", "left_front_foot", "floor", "touch-down", unloaded=True)
    transfer = ContactSample("LF_FOOT", "left_front_foot", "floor", "transfer", unloaded=False, normal_load=12.0)
    assert touch_down.options({"support_load": 0.1})["support_load"] == 0.0
    assert transfer.options({"support_load": 0.1}) == {"support_load": 0.0}
