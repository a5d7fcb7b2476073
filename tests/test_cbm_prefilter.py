"""The cheap checks before posture solves (cbm.prefilter): they reject what cannot stand, and only that."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import environments
import stances
from environments import Contact, ContactPrint, Stance

import cbm
from cbm.equilibrium import EQUILIBRIUM_IMPOSSIBLE, EquilibriumFilter, com_distance_bounds
from cbm.planner import PostureOracle
from cbm.prefilter import FILTERS, Prefilter
from cbm.print_collision import PRINTS_COLLIDE
from cbm.rejections import cause_of

from conftest import coarse_scenario

# A floor and a rigid box whose vertical sides are contact surfaces of low friction.
WALL_SCENE = """
robot: talos
objects:
  - {name: floor, type: floor}
  - {name: wall, type: box, size: [0.2, 2.0, 1.6], center: [0.5, 0.0, 0.8], friction: 0.3, side_surfaces: true}
stances:
  stand:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
"""


@pytest.fixture(scope="module")
def wall():
    return environments.load_string(WALL_SCENE, name="wall").scene


@pytest.fixture(scope="module")
def wall_filter(robot, wall):
    return Prefilter(robot, wall)


def stance(**prints):
    """A stance from ``robot_surface=(surface, x, y[, theta])``."""
    return Stance(tuple(Contact(name, ContactPrint(*spec)) for name, spec in prints.items()))


def test_com_bound_covers_the_robot_in_random_postures(robot):
    # The bound must hold in every configuration: sample postures, measure.
    bounds = com_distance_bounds(robot)
    model, data = robot.model, robot.model.createData()
    lower, upper = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
    lower[:7], upper[:7] = -1.0, 1.0  # the free flyer: anywhere near the origin, any orientation
    pin.seed(0)
    worst = 0.0
    for _ in range(200):
        q = pin.randomConfiguration(model, lower, upper)
        pin.centerOfMass(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        for name, surface in robot.surfaces.items():
            distance = np.linalg.norm(data.com[0] - data.oMf[robot.frame_id(surface.frame)].translation)
            worst = max(worst, distance / bounds[name])
    assert 0.3 < worst <= 1.0  # holds, and is not absurdly loose


def test_palm_alone_on_a_wall_is_rejected_for_its_weight(wall_filter):
    rejection = wall_filter(stance(right_palm=("wall_back", 0.0, 0.0)))
    assert rejection.rejected_by == "static equilibrium"
    assert rejection.reason.startswith(
        f"{EQUILIBRIUM_IMPOSSIBLE}: the friction cones of right_palm on wall_back cannot carry the robot's weight ("
    )
    assert cause_of(rejection.reason) == "balance (static equilibrium)"


def test_palm_on_a_wall_with_a_foot_on_the_floor_passes(wall_filter):
    assert wall_filter(stance(right_palm=("wall_back", 0.0, 0.3), right_sole=("floor", 0.0, -0.1))) is None


def test_foot_alone_on_a_steep_surface_is_rejected(wall_filter):
    rejection = wall_filter(stance(left_sole=("wall_back", 0.0, 0.3)))
    assert rejection is not None and "cannot carry the robot's weight" in rejection.reason


def test_feet_farther_apart_than_the_centre_of_mass_can_be_are_rejected(robot, wall):
    check = EquilibriumFilter(robot, wall)
    reach = com_distance_bounds(robot)["left_sole"]
    near = stance(left_sole=("floor", -1.0, 0.2), right_sole=("floor", -1.0 + reach, -0.2))
    far = stance(left_sole=("floor", -1.0, 0.2), right_sole=("floor", -1.0 + 2.1 * reach, -0.2))
    assert check(near) == ""
    assert check(far) == (
        f"{EQUILIBRIUM_IMPOSSIBLE}: no centre of mass within the robot's reach of left_sole on floor, right_sole on "
        "floor balances the moments of forces inside their friction cones"
    )


def test_friction_decides_a_palm_and_foot_pushing_against_each_other(robot):
    # A foot on the floor and a palm pressing the wall: with no floor friction
    # the palm's push is unbalanced, so only a palm force along the wall could help.
    text = WALL_SCENE.replace("- {name: floor, type: floor}", "- {name: floor, type: floor, friction: 1.0e-6}")
    scene = environments.load_string(text, name="slippery").scene
    check = EquilibriumFilter(robot, scene)
    pushed = stance(right_palm=("wall_back", 0.0, 0.3), right_sole=("floor", 0.0, -0.1))
    assert check(pushed) == ""  # zero palm force is allowed
    pushing = Prefilter(robot, scene, {"min_normal_force": 50.0, "time_budget": 1.0})(pushed)
    assert pushing.reason.startswith(f"{EQUILIBRIUM_IMPOSSIBLE}: the friction cones")


def test_foot_print_inside_a_box_is_rejected_as_a_collision(wall_filter):
    # The sole's origin on the floor 5 cm inside the wall's footprint: the foot is in the wall.
    rejection = wall_filter(stance(left_sole=("floor", 0.45, 0.1), right_sole=("floor", 0.0, -0.1)))
    assert rejection.rejected_by == "print collision"
    assert rejection.reason.startswith(f"{PRINTS_COLLIDE}: at its print, leg_left_6_link_0 sinks ")
    assert rejection.reason.endswith(" m into wall whatever the posture")
    assert cause_of(rejection.reason) == "collision"


def test_foot_print_nearer_a_box_than_the_solver_keeps_links_is_rejected_with_the_distance(robot, wall, wall_filter):
    # The wall's face at x = 0.4; the toe of a sole at x = 0.29 stands 5.5 mm from it. At
    # x = 0.292 (3.45 mm) the solver, which keeps links 5 mm from the scene (0.1 mm of it
    # may be eaten), holds no posture: refused before solving, with the distance.
    near = stance(left_sole=("floor", 0.292, 0.1), right_sole=("floor", 0.0, -0.1))
    rejection = wall_filter(near)
    assert rejection.rejected_by == "print collision" and cause_of(rejection.reason) == "collision"
    assert rejection.reason == (
        f"{PRINTS_COLLIDE}: at its print, leg_left_6_link_0 comes within 3.45 mm of wall whatever the posture, "
        "where the solver keeps every link 4.9 mm away")
    solved = stances.solve(robot, wall, near)
    assert not solved.feasible  # the premise: the solver finds no posture either
    assert wall_filter(stance(left_sole=("floor", 0.289, 0.1), right_sole=("floor", 0.0, -0.1))) is None


def test_two_feet_on_one_print_are_rejected_as_a_collision(wall_filter):
    rejection = wall_filter(stance(left_sole=("floor", 0.0, 0.0), right_sole=("floor", 0.02, 0.0)))
    assert rejection.rejected_by == "print collision"
    assert "leg_" in rejection.reason and "sinks" in rejection.reason


def test_filters_are_named_in_order(wall_filter):
    assert tuple(name for name, _ in wall_filter.checks) == FILTERS


# Declared stances that stances.solve finds feasible (rigid, and one cheap soft one).
SOLVED = [
    ("stand", "stand"),
    ("hand-on-table", "hand-on-table"),
    ("foot-on-block", "foot-on-block"),
    ("quadruped-walk", "three-feet"),
    ("quadruped-walk", "front-feet-up"),
    ("hand-on-soft-cube", "hand-on-soft-cube"),
]


@pytest.mark.parametrize("name, stance_name", SOLVED, ids=[f"{n}/{s}" for n, s in SOLVED])
def test_stances_the_solver_accepts_pass_the_prefilter(name, stance_name):
    scenario = coarse_scenario(name)
    robot = stances.Robot.load(scenario.robot)
    held = scenario.stance(stance_name)
    result = stances.solve(robot, scenario.scene, held)
    assert result.feasible, result.reason  # the premise: the solver accepts it
    assert Prefilter(robot, scenario.scene)(held) is None


def test_oracle_rejects_without_solving_and_names_the_check(robot, wall):
    oracle = PostureOracle(robot, wall)
    check = oracle(stance(right_palm=("wall_back", 0.0, 0.0)))
    assert (check.feasible, check.result, check.rejected_by, oracle.solves) == (False, None, "static equilibrium", 0)
    unfiltered = PostureOracle(robot, wall, prefilter=False, solver_options={"max_iterations": 5})
    assert unfiltered(stance(right_palm=("wall_back", 0.0, 0.0))).rejected_by == ""
    assert unfiltered.solves >= 1


def test_plan_is_the_same_with_and_without_the_prefilter(robot):
    scenario = environments.load("cross-soft-block")
    runs = {}
    for prefilter in (True, False):
        oracle = PostureOracle(robot, scenario.scene, prefilter=prefilter)
        result = cbm.plan(scenario, robot=robot, oracle=oracle, max_expansions=12, time_limit=None)
        runs[prefilter] = (result, oracle.solves)
    (on, solves_on), (off, solves_off) = runs[True], runs[False]
    assert [p.move for p in on.stances] == [p.move for p in off.stances]
    assert on.success == off.success
    assert solves_on + sum(on.statistics.prefiltered.values()) >= solves_off >= solves_on
    assert off.statistics.prefiltered == {}
    assert math.isfinite(on.statistics.time)


def test_a_soft_prints_partly_covered_nodes_widen_its_margin_by_their_reach(robot):
    # The solver's print takes nodes up to a cell outside the polygon (fem.print_coverage);
    # the LP, a relaxation of the solver, must let forces act that far out.
    from cbm.equilibrium import _covered_reach

    scenario = environments.load("cross-soft-block")
    check = EquilibriumFilter(robot, scenario.scene)
    (contact,) = [c for c in scenario.stance("right-on-foam") if c.contact_print.surface == "foam_top"]
    forces = check._print_forces(contact)
    body = scenario.scene.deformable_of_surface("foam_top")
    reach = _covered_reach(body, forces.points)
    spacing = 0.0225  # the default mesh's cells under prints
    assert 0.0 < reach < spacing
    assert forces.margin == pytest.approx(
        cbm.equilibrium.soft_print_margin(body, forces.rotation[:, 2], check.options) + reach
    )
