"""cbm.plan wired to a synthetic feasibility oracle, and the plan file round trip."""

import json
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest

import environments
from environments.goal import Goal, GoalRegion
from environments.objects import box, box_surfaces, floor
from environments.scene import Scene
from environments.stance import Contact, ContactPrint, Stance

from conftest import coarse_scenario, hand_made_biped

from cbm.errors import CbmError, PlanFileError
from cbm.plan import Plan, PlannedStance, PlanStatistics
from cbm.planner import StanceCheck, plan
from cbm.stance_graph import differ_by_one_contact



@dataclass(frozen=True)
class FakeResult:
    """Stands for a stances PostureResult."""

    q: np.ndarray
    point_forces: tuple = ()
    deformations: dict = field(default_factory=dict)
    feasible: bool = True
    reason: str = ""

    def to_dict(self):
        return {"q": list(self.q), "feasible": self.feasible, "reason": self.reason}


class SyntheticOracle:
    """Feasible iff no floor print lies in the forbidden x band; q encodes the call order."""

    def __init__(self, forbidden_x=None):
        self.forbidden_x = forbidden_x
        self.calls = []

    def __call__(self, stance, parent, parent_check):
        self.calls.append(stance)
        xs = [c.contact_print.x for c in stance if c.contact_print.surface == "floor"]
        if self.forbidden_x is not None and any(self.forbidden_x[0] < x < self.forbidden_x[1] for x in xs):
            return StanceCheck(False, "forbidden band", None)
        forces = tuple(
            SimpleNamespace(frame=f"{c.robot_surface}_contact", point=[c.contact_print.x, c.contact_print.y, 0.0],
                            force=[0.0, 0.0, 450.0 / len(stance)])
            for c in stance
        )
        result = FakeResult(np.arange(5.0) + len(self.calls), forces, {"cube": np.full((4, 3), 0.001)})
        return StanceCheck(True, "", result)


@pytest.fixture
def scenario():
    ground = floor(size=(3.0, 1.0))
    step = box("step", (0.6, 0.8, 0.1), center=(0.9, 0.0, 0.05))
    scene = Scene("walk", [ground, step], [], box_surfaces(ground, top_name="floor") + box_surfaces(step))
    start = Stance(
        (
            Contact("left_sole", ContactPrint("floor", -0.5, 0.1)),
            Contact("right_sole", ContactPrint("floor", -0.5, -0.1)),
        )
    )
    goal = Goal(
        regions=(
            GoalRegion("left_sole", (0.7, -0.4), (1.2, 0.4)),
            GoalRegion("right_sole", (0.7, -0.4), (1.2, 0.4)),
        )
    )
    return SimpleNamespace(
        name="walk", scene=scene, robot="fake", stances={"start": start}, start="start", goal=goal,
        description="walk onto a step", options={"print_spacing": 0.1},
    )


@pytest.fixture
def robot():
    """A robot without kinematics: its surfaces, a hand-made reach model given to
    plan(), and what a plan file records of a robot with no joints."""
    surfaces, reach = hand_made_biped()
    return SimpleNamespace(
        name="fake", surfaces=surfaces, reach=reach, configuration_names=[], actuated_joint_names=[],
        locked_joints={}, mass=0.0,
    )


def test_plan_walks_to_the_goal_one_contact_at_a_time(scenario, robot):
    result = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), max_expansions=100)
    assert result.success, result.reason
    assert len(result.stances) >= 4
    assert result.stances[0].stance == scenario.stances["start"]
    assert scenario.goal.is_satisfied(result.stances[-1].stance, scenario.scene)
    for before, after in zip(result.stances, result.stances[1:]):
        assert differ_by_one_contact(before.stance, after.stance)
        assert any("sole" in rs for rs in after.stance.robot_surfaces)
        assert after.move
    assert result.statistics.solver_calls >= len(result.stances)


def test_plan_avoids_infeasible_prints(scenario, robot):
    oracle = SyntheticOracle(forbidden_x=(-0.25, -0.05))
    result = plan(scenario, robot=robot, reach=robot.reach, oracle=oracle, max_expansions=200)
    assert result.success, result.reason
    for planned in result.stances:
        assert not any(
            -0.25 < c.contact_print.x < -0.05 for c in planned.stance if c.contact_print.surface == "floor"
        )
    # Lazy and cached: never solved twice.
    assert len(oracle.calls) == len(set(oracle.calls))


def test_same_seed_gives_the_same_plan(scenario, robot):
    first = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), seed=3)
    again = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), seed=3)
    assert [s.stance for s in first.stances] == [s.stance for s in again.stances]
    assert first.statistics.solver_calls == again.statistics.solver_calls


def test_a_plan_shows_itself_on_one_line(scenario, robot):
    """A plan's repr is its verdict and effort, not its stances' arrays (their postures and
    point forces made the dataclass's own repr thousands of characters long)."""
    result = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), seed=3)
    s = result.statistics
    assert repr(result) == (f"Plan('walk', success=True, reason='goal reached', {len(result.stances)} stances, "
                            f"{s.expanded} expanded, {s.solver_calls} solver calls, {s.time:.3g} s)")


def test_unreachable_goal_fails_within_budget_with_a_partial_plan(scenario, robot):
    oracle = SyntheticOracle(forbidden_x=(0.0, 10.0))  # nothing past x = 0 is feasible
    result = plan(scenario, robot=robot, reach=robot.reach, oracle=oracle, max_expansions=15)
    assert not result.success
    assert result.reason in ("budget exhausted: max_expansions", "no feasible neighbour")
    assert result.statistics.expanded <= 15
    assert result.stances and result.stances[0].stance == scenario.stances["start"]


def test_a_failed_plan_on_a_grid_coarser_than_the_robots_default_names_the_robots_grid(scenario, robot):
    """A scenario's print_spacing is chosen for its robot; for a robot whose step is
    shorter (iCub's 0.24 m on cross-soft-block's 0.1 m grid) a step reaches few prints.
    A failed plan on a grid coarser than a quarter of the robot's step names the
    robot's default grid (on this one, 0.2 m, the fake robot finds no feasible
    neighbour); a failed plan on the default grid, or one that succeeds, says nothing."""
    oracle = SyntheticOracle(forbidden_x=(0.0, 10.0))
    scenario.options = {"print_spacing": 0.2}  # the fake robot's step is 0.4 m: its grid is 0.1 m
    failed = plan(scenario, robot=robot, reach=robot.reach, oracle=oracle, max_expansions=15)
    assert not failed.success
    assert failed.reason.endswith(
        "; the print grid (0.2 m) is coarser than a quarter of the 0.40 m step of this robot, so a step reaches "
        "few prints: its default grid is print_spacing 0.1 (cbm plan --print-spacing 0.1)"
    )
    scenario.options = {"print_spacing": 0.1}
    assert "print grid" not in plan(scenario, robot=robot, reach=robot.reach, oracle=oracle, max_expansions=15).reason
    assert plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle()).reason == "goal reached"


class RejectingOracle(SyntheticOracle):
    """As SyntheticOracle, its forbidden band's stances rejected with ``reason``."""

    def __init__(self, reason, forbidden_x=None):
        super().__init__(forbidden_x)
        self.reason = reason

    def __call__(self, stance, parent, parent_check):
        check = super().__call__(stance, parent, parent_check)
        if check.reason == "forbidden band":
            return StanceCheck(False, self.reason, None)
        return check


COLLIDING = "collision between leg_left_5_link_0 and step (depth 0.01 m)"
STRAINED = ("static equilibrium (fx) violated by 2.3 N; no step meets together: strain bound (compression) of tet "
            "7509 of step, placement of right_sole (z)")
PIVOTING = "contact of right_sole on step_top (corner 2 lifted: pivoting on an edge) violated by 0.0003"
HELD_BACK = ("soft support cannot hold the print: placement of right_sole on step_top (z, elastic) violated by 0.0007 "
             "m or rad; no step meets together: placement of right_sole on step_top (z, elastic), mesh overlap bound "
             "(0.002 m, max_mesh_overlap) at node 3016 of step")


def test_a_search_out_of_budget_among_colliding_stances_suggests_a_finer_grid(scenario, robot):
    failed = plan(scenario, robot=robot, reach=robot.reach, oracle=RejectingOracle(COLLIDING, (0.0, 10.0)),
                  max_expansions=15)
    assert failed.reason.startswith("budget exhausted: max_expansions; ")
    rejected = failed.rejections["collision"]["count"]
    assert failed.reason.endswith(
        f"; {rejected} of the {rejected} stances rejected collide: a finer print grid offers prints between the "
        "obstacles (print_spacing 0.05, cbm plan --print-spacing 0.05)")
    # Out of stances rather than budget: the same hint.
    exhausted = plan(scenario, robot=robot, reach=robot.reach, oracle=RejectingOracle(COLLIDING, (0.0, 10.0)),
                     max_expansions=100_000)
    rejected = exhausted.rejections["collision"]["count"]
    assert exhausted.reason == (
        f"no feasible neighbour; {rejected} of the {rejected} stances rejected collide: a finer print grid offers "
        "prints between the obstacles (print_spacing 0.05, cbm plan --print-spacing 0.05)")
    # Other causes: no such hint.
    other = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(forbidden_x=(0.0, 10.0)),
                 max_expansions=15)
    assert other.reason == "budget exhausted: max_expansions"


@pytest.mark.parametrize("reason, cause, hint, absent", [
    (STRAINED, "balance (static equilibrium)",
     "meet the strain bound of step (the worst row or among those no step meets together): it may be too soft to "
     "stand on; a stiffer material or a larger strain_limit would carry more (the strain under a print follows its "
     "pressure over the stiffness: a thicker body lowers it little, if at all)", "strain bound"),
    (PIVOTING, "soft support (indentation, strain, contact)",
     "could not press a sole or palm on a soft body with its whole face: one that must lean on its edge is refused "
     "(its force on the mesh is no converged one); plan with --solver-option max_corner_lift=inf "
     "(solver_options={'max_corner_lift': inf}) to let prints pivot", "pivot"),
    (HELD_BACK, "soft support (indentation, strain, contact)",
     "sank a print deeper than its soft support holds it (its strain bound, or its mesh reaching into the link): a "
     "stiffer material carries more, and a finer mesh under the prints reaches less far into the links", "sank"),
], ids=["strain bound", "pivoting prints", "held back by the soft support"])
def test_a_search_failing_on_a_soft_support_says_what_to_do(scenario, robot, reason, cause, hint, absent):
    """A search whose stances are rejected on a soft object's strain bound, or on a sole or
    palm that cannot press with its whole face, says so and what to change."""
    failed = plan(scenario, robot=robot, reach=robot.reach, oracle=RejectingOracle(reason, (0.0, 10.0)),
                  max_expansions=15)
    rejected = failed.rejections[cause]["count"]
    assert failed.reason.endswith(f"; {rejected} of the {rejected} stances rejected {hint}")
    assert absent not in plan(scenario, robot=robot, reach=robot.reach,
                              oracle=SyntheticOracle(forbidden_x=(0.0, 10.0)), max_expansions=15).reason


def test_a_search_failing_on_the_strain_of_soft_prints_held_back_gives_one_hint(scenario, robot):
    """Soft prints held back by their body's strain bound: the strain bound's hint, not the
    soft support's as well (the same advice twice, a review found)."""
    reason = HELD_BACK.replace("mesh overlap bound (0.002 m, max_mesh_overlap) at node 3016 of step",
                               "strain bound (compression) of tet 7509 of step")
    failed = plan(scenario, robot=robot, reach=robot.reach, oracle=RejectingOracle(reason, (0.0, 10.0)),
                  max_expansions=15)
    assert "meet the strain bound of step" in failed.reason
    assert "sank a print deeper" not in failed.reason


class SplitRefusingOracle(SyntheticOracle):
    """Refuses any stance whose floor prints lie more than 0.8 m apart, as a robot's reach would."""

    def __call__(self, stance, parent, parent_check):
        xs = [c.contact_print.x for c in stance if c.contact_print.surface == "floor"]
        if xs and max(xs) - min(xs) > 0.8:
            self.calls.append(stance)
            return StanceCheck(False, "print unreachable: placement of right_sole on floor (x) violated by 0.7 m",
                               None)
        return super().__call__(stance, parent, parent_check)


class GoalOutOfTimeOracle(SplitRefusingOracle):
    """As SplitRefusingOracle, its solve of the goal's own stance cut by the time left."""

    def __init__(self, goal):
        super().__init__()
        self.goal_stance = Stance(goal.contacts)

    def __call__(self, stance, parent, parent_check):
        if parent is None and stance == self.goal_stance:
            return StanceCheck(False, "time budget of 0.3 s spent before convergence", None)
        return super().__call__(stance, parent, parent_check)


def test_a_failed_plan_whose_goal_stance_is_not_held_says_so(scenario, robot):
    """A goal whose prints stand on every foot but are not held (one sole 1.5 m ahead of the
    other): the search cannot reach it on any grid, and the reason says why, from one solve of
    the goal's own stance after the search (a user's such goal was blamed on the obstacles).
    With the feet the only surfaces to place, it stands in place of the grid's hints (and of a
    search on a finer grid of the planner's own); where a hand may be placed too, a stance
    adding it may hold, and the grid's hints stay. A goal that holds, or a time-cut solve of
    it, gets no such words."""
    split = Goal(contacts=(Contact("left_sole", ContactPrint("floor", 0.0, 0.1)),
                           Contact("right_sole", ContactPrint("floor", 1.5, -0.1))))
    unreached = "print unreachable: placement of right_sole on floor (x) violated by 0.7 m"
    scenario.options = {"print_spacing": 0.2, "robot_surfaces": ["left_sole", "right_sole"]}  # a coarse grid's hint
    oracle = SplitRefusingOracle()
    failed = plan(scenario, robot=robot, reach=robot.reach, oracle=oracle, goal=split, max_expansions=15)
    assert not failed.success
    assert failed.reason.endswith(f"; the goal's own stance was not held from the reference posture: {unreached}")
    assert "print grid" not in failed.reason  # no grid reaches it: no grid hint
    assert oracle.calls[-1] == Stance(split.contacts)
    scenario.options = {"print_spacing": 0.2}  # the palms may be placed too
    with_hands = plan(scenario, robot=robot, reach=robot.reach, oracle=SplitRefusingOracle(), goal=split,
                      max_expansions=15)
    assert ("; the goal's prints alone were not held from the reference posture (with another contact they may "
            f"be): {unreached}; the print grid (0.2 m) is coarser") in with_hands.reason
    beyond = Goal(contacts=(Contact("left_sole", ContactPrint("floor", 1.5, 0.1)),
                            Contact("right_sole", ContactPrint("floor", 1.5, -0.1))))
    held = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(forbidden_x=(0.0, 1.0)),
                goal=beyond, max_expansions=15)
    assert not held.success and "goal's" not in held.reason
    # On the planner's own grid, a goal not held is said before a finer grid is searched, and
    # none is: a goal that holds gets the finer search.
    scenario.options = {"robot_surfaces": ["left_sole", "right_sole"]}
    own_grid = plan(scenario, robot=robot, reach=robot.reach, oracle=SplitRefusingOracle(), goal=split,
                    max_expansions=15)
    assert own_grid.reason == ("budget exhausted: max_expansions; the goal's own stance was not held from the "
                               f"reference posture: {unreached}")
    finer = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(forbidden_x=(0.0, 1.0)),
                 goal=beyond, max_expansions=15)
    assert "m print grid, after" in finer.reason and "goal's" not in finer.reason
    cut = plan(scenario, robot=robot, reach=robot.reach, oracle=GoalOutOfTimeOracle(split), goal=split,
               max_expansions=15)
    assert not cut.success and "goal's" not in cut.reason


def test_missing_goal_is_a_clear_error(scenario, robot):
    scenario.goal = None
    with pytest.raises(CbmError, match="has no goal"):
        plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle())


def test_a_goal_region_on_no_surface_is_refused_before_any_solve(scenario, robot):
    scenario.goal = Goal(regions=(GoalRegion("left_sole", (20.0, -0.4), (21.0, 0.4)),))
    oracle = SyntheticOracle()
    with pytest.raises(CbmError, match=r"the goal region of left_sole \(x 20\.\.21, y -0\.4\.\.0\.4 m\) overlaps no "
                                       r"surface left_sole can go on \(floor x -1\.5\.\.1\.5, .*step_top x 0\.6\.\.1\.2"):
        plan(scenario, robot=robot, reach=robot.reach, oracle=oracle)
    assert oracle.calls == []
    # Met by the start already (its left sole at x -0.5), a region outside the sampling region is no error.
    scenario.goal = Goal(regions=(GoalRegion("left_sole", (-0.6, 0.0), (-0.4, 0.2)),))
    scenario.options = {**scenario.options, "sampling_region": {"lower": [0.0, -0.5], "upper": [1.5, 0.5]}}
    assert plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle()).success


def test_unknown_start_stance_names_the_valid_ones(scenario, robot):
    with pytest.raises(CbmError, match="stances: start"):
        plan(scenario, robot=robot, reach=robot.reach, start="sit", oracle=SyntheticOracle())


def test_plan_json_round_trip_preserves_everything(scenario, robot, tmp_path):
    original = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), max_expansions=100)
    path = original.save(tmp_path / "plan.json")
    loaded = Plan.load(path)
    assert loaded.to_dict() == json.loads(path.read_text())
    assert loaded.to_dict() == original.to_dict()
    assert (loaded.success, loaded.reason, loaded.scenario_name) == (
        original.success, original.reason, original.scenario_name
    )
    assert loaded.statistics == original.statistics
    for a, b in zip(original.stances, loaded.stances):
        assert a.stance == b.stance
        np.testing.assert_array_equal(a.q, b.q)
        assert a.move == b.move
        assert [f.frame for f in a.point_forces] == [f.frame for f in b.point_forces]
        np.testing.assert_array_equal(a.contact_forces, b.contact_forces)
        assert a.deformations.keys() == b.deformations.keys()
        for name in a.deformations:
            np.testing.assert_array_equal(a.deformations[name], b.deformations[name])


def test_loading_something_else_than_a_plan_is_a_clear_error(tmp_path):
    path = tmp_path / "x.json"
    path.write_text('{"hello": 1}')
    with pytest.raises(PlanFileError, match="not a plan"):
        Plan.load(path)
    path.write_text("{")
    with pytest.raises(PlanFileError, match="cannot read plan"):
        Plan.load(path)


def test_check_flags_a_transition_changing_two_contacts():
    a = Stance((Contact("left_sole", ContactPrint("floor", 0.0, 0.1)),))
    b = Stance((Contact("right_sole", ContactPrint("floor", 0.0, -0.1)),))
    planned = [PlannedStance(s, np.zeros(3)) for s in (a, b)]
    broken = Plan(False, "test", planned, PlanStatistics(), "none")
    report = broken.check(scenario=SimpleNamespace(scene=None, robot="fake"), robot=object())
    assert not report.ok
    assert any("differ by exactly one contact" in p for p in report.problems)


def test_posture_oracle_past_its_deadline_does_not_solve(scenario):
    from cbm.planner import PostureOracle

    oracle = PostureOracle(robot=None, scene=scenario.scene, deadline=0.0)
    check = oracle(scenario.stances["start"])
    assert not check.feasible
    assert check.reason == "time limit reached before this stance was solved"
    assert oracle.solves == 0


def test_check_flags_a_success_flag_that_the_last_stance_does_not_earn(scenario):
    start = scenario.stances["start"]
    planned = [PlannedStance(start, np.zeros(3))]
    claimed = Plan(True, "goal reached", planned, PlanStatistics(), "walk")
    report = claimed.check(scenario=scenario, robot=object())
    assert not report.ok
    assert "the plan says it succeeded but its last stance does not reach the scenario's goal" in report.problems


def test_a_plan_says_why_stances_were_rejected(scenario, robot, tmp_path):
    oracle = SyntheticOracle(forbidden_x=(-0.25, -0.05))
    result = plan(scenario, robot=robot, reach=robot.reach, oracle=oracle, max_expansions=200)
    forbidden = [
        s for s in oracle.calls
        if any(-0.25 < c.contact_print.x < -0.05 for c in s if c.contact_print.surface == "floor")
    ]
    assert forbidden  # the band was met
    assert result.rejections == {"other": {"count": len(forbidden), "example": "forbidden band"}}
    result.save(tmp_path / "plan.json")
    assert Plan.load(tmp_path / "plan.json").rejections == result.rejections


@pytest.mark.parametrize(
    "reason, cause",
    [
        ("even with its soft supports held rigid: print unreachable: placement of left_sole on floor (x) violated by "
         "0.5 m", "reach (placement)"),
        ("static equilibrium (fz) violated by 3 N (stagnated after 9 iterations)", "balance (static equilibrium)"),
        ("torque limit of arm_right_2_joint less its 10 % margin violated by 3.1 N m", "torque limit"),
        ("centre of pressure of right_sole on mat_top (past edge 1 of its outline) violated by 0.4 N m",
         "balance (static equilibrium)"),
        ("collision between leg_left_6_link_0 and firm_mat violated by 0.002 m", "collision"),
        ("indentation bound at node 375 of cube violated by 0.01 m", "soft support (indentation, strain, contact)"),
        ("mesh overlap bound (0.002 m, max_mesh_overlap) at node 4453 of block violated by 2.38e-05 m",
         "soft support (indentation, strain, contact)"),
        ("print unreachable: placement of left_sole on block_top (z, elastic) violated by 0.000118 m or rad; no step "
         "meets together: placement of left_sole on block_top (z, elastic), mesh overlap bound (0.002 m, "
         "max_mesh_overlap) at node 4353 of block", "soft support (indentation, strain, contact)"),
        ("friction cone of the resultant of right_palm on cube_top (-x) violated by 0.9 N", "friction"),
        ("time limit reached before this stance was solved", "time"),
        ("time budget of 2 s spent before convergence; at the last iterate: collision between a and b", "time"),
        ("verification failed: joint limit exceeded by 0.1 rad", "verification"),
        ("StanceError: the print of right_front_foot on foam_top holds 2 mesh node(s); at least 3 are needed: "
         "refine the mesh of 'foam' where prints land", "soft mesh too coarse for the print"),
        ("StanceError: the prints of left_sole on foam_top and right_sole on foam_top overlap (3 shared mesh node(s))",
         "prints overlap"),
        ("StanceError: the print of left_sole at (0.400, 0.000) lies off surface 'floor'", "print off its surface"),
        ("something new", "other"),
    ],
)
def test_each_rejection_reason_has_its_cause(reason, cause):
    from cbm.rejections import cause_of

    assert cause_of(reason) == cause


def test_ctrl_c_in_a_solve_raises_with_the_partial_plan_so_far(scenario, robot):
    from cbm.planner import PlanInterrupted

    complete = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), max_expansions=100)

    class InterruptedOracle(SyntheticOracle):
        def __call__(self, stance, parent, parent_check):
            if len(self.calls) == 3:
                raise KeyboardInterrupt
            return super().__call__(stance, parent, parent_check)

    oracle = InterruptedOracle()
    with pytest.raises(PlanInterrupted) as stopped:
        plan(scenario, robot=robot, reach=robot.reach, oracle=oracle, max_expansions=100)
    partial = stopped.value.plan
    assert not partial.success
    assert partial.reason.startswith("interrupted (Ctrl-C) after 3 stances expanded and 3 solver calls")
    # The same seed walks the same way: the partial plan is the complete plan's beginning.
    assert [p.stance for p in partial.stances] == [p.stance for p in complete.stances[: len(partial.stances)]]
    assert 1 <= len(partial.stances) <= 3


def test_a_plan_on_a_body_too_soft_for_its_own_weight_is_refused_before_searching():
    """Every stance on such a body would be refused: the plan says why at once."""
    scenario = coarse_scenario("cross-soft-block", young_modulus=1e4, density=3000.0)
    with pytest.raises(environments.SceneError, match=r"object 'foam': its own weight strains it 0\.1\d+ at .* beyond "
                       r"its strain bound 0\.05"):
        plan(scenario)


def _steps(planned):
    """The (stance, next stance) pairs a plan takes."""
    chain = [s.stance for s in planned.stances]
    return list(zip(chain, chain[1:]))


def test_a_forbidden_step_is_never_taken_and_the_search_goes_around_it(scenario, robot):
    first = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), max_expansions=100)
    assert first.success
    step = _steps(first)[2]
    again = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), max_expansions=100,
                 forbidden={step})
    assert again.success, again.reason
    assert step not in _steps(again)
    assert all(differ_by_one_contact(a, b) for a, b in _steps(again))
    # Forbidding a step no plan takes changes nothing.
    unused = (first.stances[-1].stance, first.stances[0].stance)
    same = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), max_expansions=100,
                forbidden={unused})
    assert _steps(same) == _steps(first)


def _motions_failing(bad):
    """A stand-in for plan_motions_reposing: a motion is found unless its step is in ``bad``
    (a set, or a function of the plan giving the set)."""

    def motions(planned, scenario, robot, **options):
        failing = bad(planned) if callable(bad) else bad
        return planned, tuple(
            SimpleNamespace(index=i, feasible=step not in failing, reason="" if step not in failing else "no waypoint held")
            for i, step in enumerate(_steps(planned))
        )

    return motions


def test_a_step_without_a_motion_is_planned_around(scenario, robot, monkeypatch):
    from cbm import replan

    options = dict(robot=robot, reach=robot.reach, max_expansions=100)
    first = plan(scenario, oracle=SyntheticOracle(), **options)
    bad = _steps(first)[2]
    monkeypatch.setattr(replan, "plan_motions_reposing", _motions_failing({bad}))
    moving = replan.plan_with_motions(scenario, oracle=SyntheticOracle(), **options)
    assert moving.plans == 2 and moving.missing == 0
    assert moving.plan.success and bad not in _steps(moving.plan)
    assert [(s.before, s.after) for s in moving.avoided] == [bad]
    assert moving.avoided[0].move == first.stances[3].move
    assert moving.avoided[0].reason == "no waypoint held"
    # One search only: the first plan, with its step that has no motion.
    once = replan.plan_with_motions(scenario, oracle=SyntheticOracle(), attempts=1, **options)
    assert once.plans == 1 and once.missing == 1 and once.avoided == ()
    assert _steps(once.plan) == _steps(first)


def test_when_every_plan_misses_a_motion_the_earliest_with_fewest_misses_is_kept(scenario, robot, monkeypatch):
    from cbm import replan

    options = dict(robot=robot, reach=robot.reach, max_expansions=100)
    first = plan(scenario, oracle=SyntheticOracle(), **options)
    # Every plan's last step has no motion: three searches, each one step more avoided.
    monkeypatch.setattr(replan, "plan_motions_reposing", _motions_failing(lambda planned: {_steps(planned)[-1]}))
    moving = replan.plan_with_motions(scenario, oracle=SyntheticOracle(), attempts=3, **options)
    assert moving.plans == 3 and moving.missing == 1
    assert _steps(moving.plan) == _steps(first) and moving.avoided == ()


@pytest.mark.parametrize("options, message", [
    (dict(attempts=0), "attempts must be a positive integer, got 0"),
    (dict(attempts=True), "attempts must be a positive integer, got True"),
    (dict(forbidden=()), "plan_with_motions sets forbidden itself"),
])
def test_plan_with_motions_refuses_bad_options(scenario, robot, options, message):
    from cbm.replan import plan_with_motions

    with pytest.raises(CbmError, match=message):
        plan_with_motions(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), **options)


def test_ctrl_c_after_a_first_plan_keeps_it_with_its_motions(scenario, robot, monkeypatch):
    from cbm import replan
    from cbm.planner import PlanInterrupted

    options = dict(robot=robot, reach=robot.reach, max_expansions=100)
    first = plan(scenario, oracle=SyntheticOracle(), **options)
    bad = _steps(first)[2]
    found = _motions_failing({bad})
    calls = []

    def motions(planned, scenario_, robot_, **kwargs):
        calls.append(planned)
        if len(calls) == 2:
            raise KeyboardInterrupt  # Ctrl-C while the second plan's motions are planned
        return found(planned, scenario_, robot_, **kwargs)

    monkeypatch.setattr(replan, "plan_motions_reposing", motions)
    with pytest.raises(PlanInterrupted) as stopped:
        replan.plan_with_motions(scenario, oracle=SyntheticOracle(), **options)
    assert _steps(stopped.value.plan) == _steps(first)
    assert [m.feasible for m in stopped.value.motions] == [step != bad for step in _steps(first)]


def test_the_progress_display_counts_expansions_and_says_how_close_and_how_long(scenario, robot, capsys):
    """The display is a counter of expanded stances (not a bar against the expansion cap,
    which a plan reaching its goal after a few expansions left at a few percent), with
    the solves, the open stances, the best distance to the goal and the time left."""
    from cbm.planner import _progress_text
    from cbm.search import SearchProgress, SearchStatistics

    progress = SearchProgress(SearchStatistics(expanded=9, solver_calls=14, cache_hits=2, time=12.4), 0.4219, 31)
    assert _progress_text(progress, 300.0) == "solves=14, cached=2, open=31, to goal=0.42 m, 288 s left"
    assert _progress_text(progress, None) == "solves=14, cached=2, open=31, to goal=0.42 m"
    result = plan(scenario, robot=robot, reach=robot.reach, oracle=SyntheticOracle(), max_expansions=100,
                  progress=True)
    assert result.success
    shown = capsys.readouterr().err
    assert f"planning walk: {result.statistics.expanded} expanded [" in shown and "%|" not in shown
    assert "solves=" in shown and "to goal=" in shown


class CoarseGridOracle(SyntheticOracle):
    """Rejects a stance with a floor print in 0 < x < 0.6 on the 0.1 m grid's points:
    on that grid no chain of prints crosses the band, on a 0.05 m one the points
    between them do (what an obstacle's sides did to a user's two mats)."""

    def __call__(self, stance, parent, parent_check):
        xs = [c.contact_print.x for c in stance if c.contact_print.surface == "floor"]
        if any(0.0 < x < 0.6 and abs(x / 0.1 - round(x / 0.1)) < 1e-6 for x in xs):
            self.calls.append(stance)
            return StanceCheck(False, "collision between a foot and the band", None)
        return super().__call__(stance, parent, parent_check)


def test_a_plan_the_default_grid_misses_is_searched_on_a_grid_half_as_fine(scenario, robot):
    """On the planner's own grid, a search that finds no plan is followed by one on a
    grid half as fine: the plan says so and counts both searches; a grid the scenario
    (or the user) sets is kept as it is."""
    own = SimpleNamespace(**{**vars(scenario), "options": {}})
    oracle = CoarseGridOracle()
    result = plan(own, robot=robot, reach=robot.reach, oracle=oracle, max_expansions=60)
    assert result.success, result.reason
    assert result.reason.startswith("goal reached on a 0.050 m print grid, after ")
    assert result.reason.endswith(" stances expanded on the default 0.100 m one found no plan")
    assert result.statistics.print_spacing == 0.05
    assert result.statistics.solver_calls == len(oracle.calls)  # both searches counted
    assert any(abs(c.contact_print.x - 0.05) < 1e-9 or abs(c.contact_print.x - 0.15) < 1e-9
               for planned in result.stances for c in planned.stance if c.contact_print.surface == "floor")
    kept = plan(scenario, robot=robot, reach=robot.reach, oracle=CoarseGridOracle(), max_expansions=60)
    assert not kept.success and kept.statistics.print_spacing == 0.1
    assert "print grid" not in kept.reason.split(";")[0]


class OutOfTimeOracle(SyntheticOracle):
    """The start holds; every other stance comes back as the posture oracle answers once its
    deadline has passed (its clock starts before the prints are sampled, the search's after)."""

    def __call__(self, stance, parent, parent_check):
        if parent is None:
            return super().__call__(stance, parent, parent_check)
        self.calls.append(stance)
        return StanceCheck(False, "time limit reached before this stance was solved", None)


def test_a_search_whose_checks_ran_out_of_time_says_so_and_tries_no_finer_grid(scenario, robot):
    """Every candidate rejected for time empties the search's queue: that is the time limit,
    not 'no feasible neighbour', and no finer grid is searched with no time left (an audit's
    narrow gap with --time-limit 0.3 ended in a bad-input error: a finer search given 0 s)."""
    own = SimpleNamespace(**{**vars(scenario), "options": {}})
    result = plan(own, robot=robot, reach=robot.reach, oracle=OutOfTimeOracle(), max_expansions=60, time_limit=100.0)
    assert not result.success
    assert result.reason.startswith("budget exhausted: time_limit")
    assert result.statistics.print_spacing == 0.1 and "print grid" not in result.reason
    assert list(result.rejections) == ["time"]
