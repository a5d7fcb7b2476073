"""Print sampling on contact surfaces and reach pruning."""

import math

import numpy as np
import pytest

from environments.geometry import pose_from_center_yaw, transform_from_rotation_translation
from environments.goal import GoalRegion
from environments.stance import Contact, ContactPrint, Stance
from environments.surfaces import ContactSurface, rectangle

from conftest import ARM_REACH, LEG, hand_made_biped
from stances.robot import RobotSurface

from cbm.errors import CbmError
from cbm.sampling import SamplingOptions, check_goal_regions, contacts_in_world, sample_prints, with_prints
from cbm.stance_graph import StanceNeighbours, differ_by_one_contact

ROBOT, REACH = hand_made_biped()
SOLE, PALM = ROBOT["left_sole"].polygon, ROBOT["left_palm"].polygon


def wall_transform():
    # A vertical wall at x = 0.6 facing -x: surface z axis = world -x.
    rotation = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    return transform_from_rotation_translation(rotation, [0.6, 0.0, 1.2])


@pytest.fixture
def surfaces():
    return {
        "floor": ContactSurface("floor", "floor", rectangle(2.0, 1.2), np.eye(4)),
        "block_top": ContactSurface(
            "block_top", "block", rectangle(0.5, 0.4), pose_from_center_yaw([1.3, 0.0, 0.2], 0.3), deformable=True
        ),
        "wall": ContactSurface("wall", "wall", rectangle(0.6, 0.6), wall_transform()),
    }


def test_every_sampled_print_lies_inside_its_surface(surfaces):
    options = SamplingOptions(spacing=0.07, theta_values=(0.0, 0.5, -1.0), margin=0.01)
    sets = sample_prints(surfaces, ROBOT, options)
    for robot_surface, print_set in sets.items():
        assert len(print_set) > 0
        for p, origin in zip(print_set.prints, print_set.origins_in_world):
            surface = surfaces[p.surface]
            vertices = surface.print_polygon_in_surface(ROBOT[robot_surface].polygon, p.x, p.y, p.theta)
            assert surface.contains(vertices, margin=0.01 - 1e-9).all()
            np.testing.assert_allclose(origin, surface.transform_print_to_world(p.x, p.y, p.theta)[:3, 3])


def test_a_print_near_the_edge_is_rejected(surfaces):
    sets = sample_prints({"block_top": surfaces["block_top"]}, {"left_sole": ROBOT["left_sole"]}, SamplingOptions(spacing=0.01))
    xs = np.array([p.x for p in sets["left_sole"].prints])
    # The block is 0.5 m long and the sole reaches 0.11 m forward, 0.10 back.
    assert xs.max() <= 0.25 - 0.11 + 1e-9 and xs.min() >= -0.25 + 0.10 - 1e-9
    assert xs.max() > 0.25 - 0.11 - 0.011


def test_spacing_and_theta_values_are_respected(surfaces):
    thetas = (0.0, math.radians(30.0))
    sets = sample_prints({"floor": surfaces["floor"]}, {"right_sole": ROBOT["right_sole"]}, SamplingOptions(0.25, thetas))
    prints = sets["right_sole"].prints
    assert sorted({p.theta for p in prints}) == pytest.approx(sorted(thetas))
    xs = np.unique(np.round([p.x for p in prints], 9))
    ys = np.unique(np.round([p.y for p in prints], 9))
    np.testing.assert_allclose(np.diff(xs), 0.25)
    np.testing.assert_allclose(np.diff(ys), 0.25)
    # Grid centred on the surface: symmetric about its centre.
    np.testing.assert_allclose(xs, -xs[::-1])


def test_soles_go_only_on_surfaces_facing_up_and_palms_anywhere(surfaces):
    sets = sample_prints(surfaces, ROBOT, SamplingOptions(spacing=0.1))
    assert {p.surface for p in sets["left_sole"].prints} == {"floor", "block_top"}
    assert {p.surface for p in sets["left_palm"].prints} == {"floor", "block_top", "wall"}


def test_the_role_not_the_name_decides_where_a_surface_goes(surfaces):
    """A hand called ``left_sole`` goes on the wall; a foot called ``grip`` does not."""
    misnamed = {
        "left_sole": RobotSurface("left_sole", "a", PALM, role="hand", limb="arm"),
        "grip": RobotSurface("grip", "b", PALM, role="foot", limb="leg"),
    }
    sets = sample_prints(surfaces, misnamed, SamplingOptions(spacing=0.1))
    assert {p.surface for p in sets["left_sole"].prints} == {"floor", "block_top", "wall"}
    assert {p.surface for p in sets["grip"].prints} == {"floor", "block_top"}


def feet_together():
    return Stance(
        (
            Contact("left_sole", ContactPrint("floor", 0.0, 0.1)),
            Contact("right_sole", ContactPrint("floor", 0.0, -0.1)),
        )
    )


def test_pruning_keeps_a_sole_within_a_step_on_its_own_side(surfaces):
    limits = REACH.limits
    sets = sample_prints({"floor": surfaces["floor"]}, ROBOT, SamplingOptions(spacing=0.05))
    placed = contacts_in_world(feet_together().without("left_sole"), surfaces)
    candidates = sets["left_sole"]
    mask = REACH.reachable_mask(candidates, placed)
    assert 0 < mask.sum() < len(mask)
    right = placed["right_sole"][0]
    delta = candidates.origins_in_world - right  # the right sole points along world x
    # Step: half a leg (0.4 m); own side: 0.3 x the hips' 0.2 m; apart: the sole's size + 1 cm.
    step = np.linalg.norm(delta[:, :2], axis=1) <= limits.step_length * LEG + 1e-12
    own_side = delta[:, 1] >= limits.foot_lateral * 0.2 - 1e-12
    apart = (np.abs(delta[:, 0]) >= 0.21 + limits.foot_clearance - 1e-12) | (
        np.abs(delta[:, 1]) >= 0.13 + limits.foot_clearance - 1e-12
    )
    np.testing.assert_array_equal(mask, step & own_side & apart)
    # The rule is not vacuous: a sole just ahead and slightly left is kept,
    # one overlapping the right sole is not.
    index = {(round(p.x, 3), round(p.y, 3)): i for i, p in enumerate(candidates.prints)}
    assert mask[index[(0.3, 0.0)]] and not mask[index[(0.1, 0.0)]] and not mask[index[(0.0, -0.2)]]


def test_pruning_keeps_palms_within_arm_reach_of_the_shoulder(surfaces):
    sets = sample_prints(surfaces, ROBOT, SamplingOptions(spacing=0.05))
    placed = contacts_in_world(feet_together(), surfaces)
    mask = REACH.reachable_mask(sets["left_palm"], placed)
    kept = sets["left_palm"].origins_in_world[mask]
    # The floor is out of reach (1.35 m below the shoulders, 0.65 m arms);
    # part of the wall in front at 0.6 m is reachable.
    assert {sets["left_palm"].prints[i].surface for i in np.flatnonzero(mask)} == {"wall"}
    shoulder = np.array([0.0, 0.2, 1.35])
    assert np.all(np.linalg.norm(kept - shoulder, axis=1) <= ARM_REACH + 1e-9)
    assert mask.sum() < sum(p.surface == "wall" for p in sets["left_palm"].prints)


def test_neighbours_add_or_remove_one_contact_and_keep_a_sole(surfaces):
    sets = sample_prints(surfaces, ROBOT, SamplingOptions(spacing=0.1))
    neighbours = StanceNeighbours(sets, surfaces, REACH)
    start = feet_together()
    pairs = neighbours(start)
    assert pairs and all(differ_by_one_contact(start, child) for child, _ in pairs)
    removals = [m for _, m in pairs if m.kind == "remove"]
    assert sorted(m.robot_surface for m in removals) == ["left_sole", "right_sole"]
    one_sole = start.without("left_sole")
    children = neighbours(one_sole)
    assert all("right_sole" in child.robot_surfaces for child, _ in children)
    assert neighbours.pruned > 0


def test_prints_under_another_object_are_dropped():
    from environments.objects import box, box_surfaces, floor
    from environments.scene import Scene

    from cbm.sampling import obstacle_boxes

    ground = floor(size=(2.0, 1.0))
    block = box("block", (0.6, 0.6, 0.1), center=(0.5, 0.0, 0.05))
    scene = Scene("s", [ground, block], [], box_surfaces(ground, top_name="floor") + box_surfaces(block))
    sets = sample_prints(scene.surfaces, {"left_sole": ROBOT["left_sole"]}, SamplingOptions(spacing=0.05), obstacle_boxes(scene))
    prints = sets["left_sole"].prints
    on_floor = [p for p in prints if p.surface == "floor"]
    on_block = [p for p in prints if p.surface == "block_top"]
    assert on_block, "the block's own top must keep its prints"
    # No floor print overlaps the block's footprint x in [0.2, 0.8], |y| <= 0.3.
    for p in on_floor:
        vertices = scene.surface("floor").print_polygon_in_world(SOLE, p.x, p.y, p.theta)
        overlaps = (vertices[:, 0] > 0.2) & (vertices[:, 0] < 0.8) & (np.abs(vertices[:, 1]) < 0.3)
        assert not overlaps.any()
    assert any(p.x >= 0.85 for p in on_floor)


def test_sampling_region_keeps_only_prints_inside_it(surfaces):
    options = SamplingOptions(spacing=0.1, region_lower=(-0.3, -0.2), region_upper=(0.5, 0.4))
    sets = sample_prints({"floor": surfaces["floor"]}, {"left_sole": ROBOT["left_sole"]}, options)
    origins = sets["left_sole"].origins_in_world
    assert len(origins) > 0
    assert np.all(origins[:, :2] >= np.array([-0.3, -0.2]) - 1e-12)
    assert np.all(origins[:, :2] <= np.array([0.5, 0.4]) + 1e-12)


def test_scenario_options_set_spacing_angles_and_region():
    from cbm.sampling import options_from_scenario

    options = options_from_scenario(
        {"print_spacing": 0.2, "theta_values_deg": [0, 90], "sampling_region": {"lower": [0, 1], "upper": [2, 3]}}
    )
    assert options.spacing == 0.2
    assert options.theta_values == pytest.approx((0.0, math.pi / 2))
    assert (options.region_lower, options.region_upper) == ((0.0, 1.0), (2.0, 3.0))
    assert options_from_scenario({"print_spacing": 0.2}, spacing=0.05).spacing == 0.05
    # The robot's default serves only when neither the user nor the scenario gives a spacing.
    assert options_from_scenario({"print_spacing": 0.2}, default_spacing=0.04).spacing == 0.2
    assert options_from_scenario({}, spacing=0.05, default_spacing=0.04).spacing == 0.05
    assert options_from_scenario({}, default_spacing=0.04).spacing == 0.04


def test_a_goal_print_off_the_grid_becomes_a_candidate_once(surfaces):
    """A goal naming a print between grid points (hand-on-cube's palm at y = 0.05 on a
    0.1 m grid) is added to its surface's candidates, at its world placement."""
    sets = sample_prints(surfaces, {"left_palm": ROBOT["left_palm"]}, SamplingOptions(spacing=0.1, theta_values=(0.0,)))
    goal = ContactPrint("block_top", 0.05, -0.03, 0.2)
    assert goal not in sets["left_palm"].prints
    contact = Contact("left_palm", goal)
    added = with_prints(sets, [contact, Contact("right_sole", ContactPrint("floor", 0.0, 0.0, 0.0))], surfaces)
    assert added["left_palm"].prints == sets["left_palm"].prints + (goal,)  # appended, order kept
    assert "right_sole" not in added  # a surface the planner does not move is left alone
    placed = surfaces["block_top"].transform_print_to_world(0.05, -0.03, 0.2)
    np.testing.assert_allclose(added["left_palm"].origins_in_world[-1], placed[:3, 3], atol=1e-15)
    np.testing.assert_allclose(added["left_palm"].x_axes_in_world[-1], placed[:3, 0], atol=1e-15)
    assert with_prints(added, [contact], surfaces)["left_palm"].prints == added["left_palm"].prints  # once


def test_goal_hand_prints_stay_candidates_beyond_the_reach_model(surfaces):
    # The wall's print farthest from the left shoulder: beyond the model's arm reach.
    sets = sample_prints(surfaces, ROBOT, SamplingOptions(spacing=0.05))
    walls = [i for i, p in enumerate(sets["left_palm"].prints) if p.surface == "wall"]
    shoulder = np.array([0.0, 0.2, 1.35])
    far = max(walls, key=lambda i: np.linalg.norm(sets["left_palm"].origins_in_world[i] - shoulder))
    assert np.linalg.norm(sets["left_palm"].origins_in_world[far] - shoulder) > ARM_REACH
    goal_palm = Contact("left_palm", sets["left_palm"].prints[far])
    start = feet_together()

    def palm_prints(neighbours, stance):
        return {m.contact_print for _, m in neighbours(stance) if m.robot_surface == "left_palm"}

    assert goal_palm.contact_print not in palm_prints(StanceNeighbours(sets, surfaces, REACH), start)
    required = StanceNeighbours(sets, surfaces, REACH, required=[goal_palm])
    assert goal_palm.contact_print in palm_prints(required, start)
    # The other prints beyond reach stay pruned.
    assert palm_prints(required, start) == palm_prints(StanceNeighbours(sets, surfaces, REACH), start) | {
        goal_palm.contact_print
    }
    # Feet move under a hand held on the goal print as if it were free; a hand on
    # any other print keeps them within its reach.
    held = start.with_contact(goal_palm).without("right_sole")
    free = start.without("right_sole")

    def sole_prints(neighbours, stance):
        return {m.contact_print for _, m in neighbours(stance) if m.robot_surface == "right_sole"}

    assert sole_prints(required, held) == sole_prints(required, free)
    assert sole_prints(StanceNeighbours(sets, surfaces, REACH), held) < sole_prints(required, held)


def test_a_lone_goal_foot_print_gets_no_reach_exemption(surfaces):
    sets = sample_prints(surfaces, ROBOT, SamplingOptions(spacing=0.1))
    far_sole = Contact("right_sole", ContactPrint("floor", 0.9, -0.1, 0.0))  # beyond a step
    sets = with_prints(sets, [far_sole], surfaces)
    neighbours = StanceNeighbours(sets, surfaces, REACH, required=[far_sole])
    moves = neighbours(feet_together().without("right_sole"))
    assert far_sole.contact_print not in {m.contact_print for _, m in moves if m.robot_surface == "right_sole"}


def test_a_goal_foot_print_beyond_the_step_rules_is_offered_once_the_goals_other_feet_stand(surfaces):
    """The last step into the goal's footing is offered even where the step rules
    prune it (here a print 1.3 m ahead and 0.2 m up; on iCub, whose step height is
    0.18 m, foot-on-block's 0.2 m block): from the left sole on its goal print, not
    from any other print; the posture solve decides."""
    sets = sample_prints(surfaces, ROBOT, SamplingOptions(spacing=0.1))
    # block_top is 0.2 m up, 1.3 m ahead: beyond a step of the left sole at x = 0.
    high_sole = Contact("right_sole", ContactPrint("block_top", 0.0, 0.0, 0.0))
    goal = [Contact("left_sole", ContactPrint("floor", 0.0, 0.1)), high_sole]
    sets = with_prints(sets, goal, surfaces)

    def sole_prints(neighbours, stance):
        return {m.contact_print for _, m in neighbours(stance) if m.robot_surface == "right_sole"}

    on_goal = feet_together().without("right_sole")
    elsewhere = Stance((Contact("left_sole", ContactPrint("floor", 0.1, 0.1)),))
    pruned = StanceNeighbours(sets, surfaces, REACH)
    required = StanceNeighbours(sets, surfaces, REACH, required=goal)
    assert high_sole.contact_print not in sole_prints(pruned, on_goal)
    assert sole_prints(required, on_goal) == sole_prints(pruned, on_goal) | {high_sole.contact_print}
    assert sole_prints(required, elsewhere) == sole_prints(pruned, elsewhere)


def _feet(*thetas_deg, surface="floor"):
    return tuple(
        Contact(name, ContactPrint(surface, 0.0, y, math.radians(t)))
        for name, y, t in zip(("left_sole", "right_sole"), (0.1, -0.1), thetas_deg)
    )


def test_default_headings_follow_the_feet_from_start_to_goal():
    from cbm.sampling import default_headings

    floor = {"floor": ContactSurface("floor", "floor", rectangle(2.0, 1.2), np.eye(4))}
    feet = ("left_sole", "right_sole")
    step = math.radians(45.0)
    # No turn: the one heading of the feet, exactly 0 (the planner's old default).
    assert default_headings(_feet(0, 0) + _feet(0, 0), floor, feet, step) == (0.0,)
    # A quarter turn with 45 degree steps: 0, 45, 90 (the goal's own theta exactly).
    assert default_headings(_feet(0, 0) + _feet(90, 90), floor, feet, step) == (0.0, math.pi / 4, math.pi / 2)
    # Steps are even and never larger than the bound: 0 to 100 degrees in three.
    got = default_headings(_feet(0, 0) + _feet(100, 100), floor, feet, step)
    assert np.degrees(got) == pytest.approx([0.0, 100 / 3, 200 / 3, 100.0])
    # Across +-180 degrees the short way: 170 -> 180 -> -170, not through 0.
    got = default_headings(_feet(170, 170) + _feet(-170, -170), floor, feet, math.radians(15.0))
    assert np.degrees(got) == pytest.approx([-170.0, 170.0, 180.0])
    # Only feet count: a palm's heading adds nothing.
    palm = (Contact("left_palm", ContactPrint("floor", 0.5, 0.0, 1.0)),)
    assert default_headings(_feet(0, 0) + palm, floor, feet, step) == (0.0,)
    assert default_headings(palm, floor, feet, step) == (0.0,)
    with pytest.raises(CbmError, match="largest heading step must be a positive angle"):
        default_headings(_feet(0, 0), floor, feet, 0.0)


def test_default_headings_are_world_headings_on_a_yawed_surface(surfaces):
    """On a box turned by 0.3 rad the same world headings read 0.3 rad less; a wall takes no feet."""
    from cbm.sampling import default_headings

    got = default_headings(_feet(0, 0) + _feet(90, 90), surfaces, ("left_sole", "right_sole"), math.radians(45.0))
    expected = sorted({*(math.radians(t) for t in (0, 45, 90)), *(math.radians(t) - 0.3 for t in (0, 45, 90))})
    assert got == pytest.approx(expected)
    # Sampled on the box with those thetas, the prints' x axes point along the world headings.
    options = SamplingOptions(spacing=0.1, theta_values=got)
    sets = sample_prints({"block_top": surfaces["block_top"]}, {"left_sole": ROBOT["left_sole"]}, options)
    yaws = {round(math.degrees(math.atan2(a[1], a[0])), 6) for a in sets["left_sole"].x_axes_in_world}
    assert {0.0, 45.0, 90.0} <= yaws


def test_goal_regions_that_some_print_can_reach_pass_the_check(surfaces):
    check_goal_regions([GoalRegion("left_sole", [0.5, -0.1], [0.9, 0.1]), GoalRegion("left_palm", [0.6, 0.0], [0.6, 0.1])],
                       surfaces, ROBOT, SamplingOptions(spacing=0.1))


def test_a_goal_region_off_every_surface_its_robot_surface_may_use_is_refused_before_a_search(surfaces):
    # Beyond the floor and the block: nothing there.
    with pytest.raises(CbmError, match=r"the goal region of left_sole \(x 3\.\.4, y -0\.1\.\.0\.1 m\) overlaps no "
                                       r"surface left_sole can go on \(block_top x .*; floor x -1\.\.1, y -0\.6\.\.0\.6\); "
                                       r"move the region onto one of them"):
        check_goal_regions([GoalRegion("left_sole", [3.0, -0.1], [4.0, 0.1])], surfaces, ROBOT, SamplingOptions())
    # A sole's region on the wall's footprint alone (no floor under it): a wall takes hands, not feet.
    wall_only = {"wall": surfaces["wall"]}
    with pytest.raises(CbmError, match=r"overlaps no surface left_sole can go on \(none\)"):
        check_goal_regions([GoalRegion("left_sole", [0.55, -0.1], [0.65, 0.1])], wall_only, ROBOT, SamplingOptions())
    check_goal_regions([GoalRegion("left_palm", [0.55, -0.1], [0.65, 0.1])], wall_only, ROBOT, SamplingOptions())


def test_a_goal_region_outside_the_sampling_region_is_refused_and_one_of_an_unplaced_surface_left_alone(surfaces):
    options = SamplingOptions(region_lower=(-0.5, -0.5), region_upper=(0.2, 0.5))
    with pytest.raises(CbmError, match=r"lies outside the sampling region \(x -0\.5\.\.0\.2, y -0\.5\.\.0\.5 m, "
                                       r"options\.sampling_region\), the only place prints are sampled"):
        check_goal_regions([GoalRegion("left_sole", [0.3, -0.1], [0.6, 0.1])], surfaces, ROBOT, options)
    check_goal_regions([GoalRegion("left_sole", [0.2, -0.1], [0.6, 0.1])], surfaces, ROBOT, options)  # touches it
    # A surface the planner does not place: its region is the start stance's to meet, not checked.
    feet = {name: ROBOT[name] for name in ("left_sole", "right_sole")}
    check_goal_regions([GoalRegion("left_palm", [30.0, -0.1], [31.0, 0.1])], surfaces, feet, SamplingOptions())
