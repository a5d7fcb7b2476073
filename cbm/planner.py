"""``cbm.plan``: contact-before-motion planning for one scenario.

Wires the pieces: prints sampled on the scene (:mod:`cbm.sampling`),
neighbours of a stance (:mod:`cbm.stance_graph`), the posture solver of
:mod:`stances` as the feasibility oracle, and the lazy best-first search
(:mod:`cbm.search`) guided by the goal's distance.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import os
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

import environments
import stances
from stances.cold_start import initial_configuration
from stances.description import description_path
from environments.errors import SceneError
from environments.scene_checks import check_self_weight
from fem.errors import FemError
from stances.errors import StanceError

from .errors import CbmError, UnknownScenario
from .plan import FRONTIER_SIZE, Plan, PlannedStance, PlanStatistics, robot_description, scenario_source
from .slip_chain import chained, history_of
from .parallel import PosturePool, check_workers
from .rejections import (
    FINEST_GRID, UNRESOLVED_BALL, cause_of, finer_grid_hint, pivoting_print_hint, soft_support_hint, stiff_reach_hint,
    strain_bound_hint, summarise, unresolved_ball_hint,
)
from .prefilter import Prefilter
from .reach import ReachLimits, ReachModel
from .sampling import (
    check_goal_regions,
    coarse_grid_hint,
    default_headings,
    default_print_spacing,
    obstacle_boxes,
    options_from_scenario,
    sample_prints,
    with_prints,
)
from .search import (
    DEFAULT_MAX_EXPANSIONS,
    DEFAULT_TIME_LIMIT,
    NO_FEASIBLE_NEIGHBOUR,
    SearchInterrupted,
    SearchLimits,
    best_first_search,
    budget_exhausted,
)
from .stance_graph import StanceNeighbours
from .terrain import TerrainCost, terrain_weight as _terrain_weight

__all__ = [
    "plan",
    "PlanInterrupted",
    "load_scenario",
    "StanceCheck",
    "PostureOracle",
    "LookaheadHeuristic",
    "initial_configuration",
    "check_robot_surfaces",
    "load_robot",
    "DEFAULT_PATH_COST",
    "DEFAULT_MAX_EXPANSIONS",
    "DEFAULT_TIME_LIMIT",
]

logger = logging.getLogger(__name__)

#: Path cost per move, metres of goal distance: small, so the search stays
#: greedy towards the goal but prefers fewer moves among equally close stances.
DEFAULT_PATH_COST = 0.02

def load_scenario(scenario):
    """A scenario from a name, a path, or a Scenario (returned as is).

    Raises
    ------
    UnknownScenario
        Listing the built-in names when ``scenario`` is neither a built-in
        name nor an existing file.
    environments.ScenarioError
        If the file exists but is not a valid scenario.
    """
    if not isinstance(scenario, (str, os.PathLike)):
        return scenario
    names = environments.scenario_names()
    if str(scenario) not in names and not os.path.isfile(scenario):
        raise UnknownScenario(str(scenario), names)
    return environments.load(scenario)


def load_robot(source) -> stances.Robot:
    """The robot a built-in name or description file gives, loaded once while its files are
    unchanged: the plans that name it share it (the planner changes nothing of a robot).

    Loading builds the model and its collision meshes: 0.16 s of CPU for Talos, 0.76 s
    for Romeo, against a second or two for a plan of a small scene; plans run in a loop
    (a user's scenario tests, the benchmarks) paid it at every call.

    Parameters
    ----------
    source : str or os.PathLike
        As :meth:`stances.Robot.load`.

    Returns
    -------
    stances.Robot
        The same object for the same name while its description, URDF and SRDF files keep
        their modification times; a new one after any of them changes.

    Raises
    ------
    stances.RobotNotFound, stances.RobotDescriptionError
        As :meth:`stances.Robot.load`.
    """
    key = os.fspath(description_path(source))
    files, stamps, robot = _LOADED_ROBOTS.get(key, ((), None, None))
    if robot is None or stamps != _stamps(files):
        description = stances.read_description(source)
        robot = stances.Robot.from_description(description)
        files = tuple(f for f in (description.path, description.urdf, description.srdf) if f is not None)
        _LOADED_ROBOTS.pop(key, None)
        while len(_LOADED_ROBOTS) >= _LOADED_ROBOTS_KEPT:
            del _LOADED_ROBOTS[next(iter(_LOADED_ROBOTS))]  # the oldest
        _LOADED_ROBOTS[key] = (files, _stamps(files), robot)
    return robot


def _stamps(files) -> tuple:
    """Modification times (ns) of ``files``, None for one that is gone."""
    return tuple(os.stat(f).st_mtime_ns if os.path.exists(f) else None for f in files)


# Description file -> (its files, their stamps, the robot): load_robot's robots.
_LOADED_ROBOTS: dict = {}
_LOADED_ROBOTS_KEPT = 8

_OUT_OF_TIME = "time limit reached before this stance was solved"


class PlanInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`plan`'s search, carrying the best partial plan so far.

    A ``KeyboardInterrupt``: uncaught, it stops a program like any Ctrl-C.

    Parameters
    ----------
    plan : Plan
        ``success`` False, its reason saying it was interrupted; its stances
        lead from the start towards the goal (none if the start was not yet
        solved). From :func:`cbm.plan_with_motions` after a first plan was made:
        the best plan made before (then ``success`` may be True).
    motions : tuple of cbm.motion.Motion, optional
        That plan's motions, when they were planned.
    """

    def __init__(self, plan, motions=None):
        super().__init__(plan.reason)
        self.plan = plan
        self.motions = motions


@dataclass(frozen=True)
class StanceCheck:
    """Answer of the feasibility oracle for one stance.

    Parameters
    ----------
    feasible : bool
        Solved and independently verified.
    reason : str
        Why not, if infeasible.
    result : stances PostureResult or None
        The solver's result (None if the solver raised or was not run).
    rejected_by : str
        Name of the cheap check that rejected the stance without a posture
        solve (:mod:`cbm.prefilter`), ``""`` if it was solved.
    bad_input : bool
        The solver refused the stance as bad input for this scene (it raised one
        of the packages' errors, which ``reason`` gives: e.g. two prints pressing
        the same nodes): a candidate to drop in a search, an error to fix in a
        stance a user wrote.
    """

    feasible: bool
    reason: str
    result: Any = None
    rejected_by: str = ""
    bad_input: bool = False


def posture_api():
    """``(solve, verify)`` of :mod:`stances`: the oracle's solver and its independent
    check, looked up at call time (tests put a failing solver in their place)."""
    return stances.solve, stances.verify


class PostureOracle:
    """Feasibility oracle: posture solve warm-started from the parent, then verify.

    Parameters
    ----------
    robot : stances Robot
    scene : environments Scene
    solver_options : dict, optional
        Keyword arguments of ``stances.solve``.
    retry_cold : bool
        If the warm-started solve fails, solve once more from
        :func:`initial_configuration` (the parent's posture can be a poor
        start, e.g. straddling a step when one foot is lifted).
    deadline : float, optional
        ``time.perf_counter()`` value after which no solve runs on: each solve
        gets the time left as its ``time_budget``, so a planner's time limit
        holds during a solve too.
    prefilter : bool
        Before solving, reject the stances that no posture can hold, found by
        checks of milliseconds (:class:`cbm.prefilter.Prefilter`: links that
        rigid prints place inside something, static equilibrium of the
        contact set); such a stance gets an infeasible answer without result,
        ``rejected_by`` naming the check. Off: every stance is solved (for
        benchmarks).
    """

    def __init__(self, robot, scene, solver_options=None, retry_cold=True, deadline=None, prefilter=True):
        self.robot = robot
        self.scene = scene
        self.solver_options = dict(solver_options or {})
        self.retry_cold = retry_cold
        self.deadline = deadline
        self.solves = 0  # posture solves, retries included
        self.prefilter = bool(prefilter)
        self._filter = None  # built on first use: its setup reads the robot's mass and tree

    def __call__(self, stance, parent=None, parent_check=None):
        """Check one stance; ``parent_check`` gives the warm start and, where its answer is a
        PostureResult, the history: the soft prints the stance keeps start where it left them."""
        if self._time_left() == 0.0:
            return StanceCheck(False, _OUT_OF_TIME)
        rejection = self._prefiltered(stance)
        if rejection is not None:
            return StanceCheck(False, rejection.reason, None, rejected_by=rejection.rejected_by)
        starts = []
        if parent_check is not None and parent_check.result is not None:
            starts.append(parent_check.result.q)
        history = None if parent_check is None else history_of(parent_check)
        if self.retry_cold or not starts:
            starts.append(initial_configuration(self.robot, self.scene, stance))
        check = None
        for q_init in starts:
            # The prints kept from the parent start where its answer left them (history).
            check = self._solve(stance, q_init, history)
            # (a ball the mesh does not resolve is refused from any start: the HyQ mesh scene's
            # 29 such refusals were each solved twice)
            if check.feasible or cause_of(check.reason) == UNRESOLVED_BALL:
                break
        return check

    def _prefiltered(self, stance):
        """The prefilter's :class:`~cbm.prefilter.Rejection` of ``stance``, None to solve it."""
        if not self.prefilter:
            return None
        if self._filter is None:
            self._filter = Prefilter(self.robot, self.scene, self.solver_options)
        try:
            return self._filter(stance)
        except (StanceError, SceneError):
            return None  # a malformed stance: the solve reports it as it always has

    def _time_left(self):
        """Seconds left before the deadline (0.0 once past it), None without one."""
        if self.deadline is None:
            return None
        return max(self.deadline - time.perf_counter(), 0.0)

    def _solve(self, stance, q_init, history=None):
        solve, verify = posture_api()
        options = dict(self.solver_options)
        left = self._time_left()
        if left == 0.0:
            return StanceCheck(False, _OUT_OF_TIME)
        if left is not None:
            options["time_budget"] = min(left, options.get("time_budget") or np.inf)
        self.solves += 1
        logger.debug("solving %s", stance.to_dict())
        try:
            result = solve(self.robot, self.scene, stance, q_init=q_init, history=history, **options)
        except (StanceError, SceneError, FemError) as error:
            # Bad stance for this scene (e.g. a print covering too few FEM
            # nodes): an infeasible stance for the search, not a crash. Only the
            # packages' own errors: any other ValueError (numpy's LinAlgError) is a bug.
            logger.debug("solve raised on %s: %s", stance, error)
            return StanceCheck(False, f"{type(error).__name__}: {error}", bad_input=True)
        if not result.feasible:
            return StanceCheck(False, str(result.reason), result)
        verification = getattr(result, "verification", None)
        if verification is None:
            verification = verify(self.robot, self.scene, stance, result)
        if not verification.ok:
            return StanceCheck(False, "verification failed: " + "; ".join(map(str, verification.reasons)), result)
        return StanceCheck(True, "", result)


class LookaheadHeuristic:
    """Goal distance, looking one placement ahead when a foot is lifted.

    A stance with a foot in the air is only a step towards placing it again:
    its goal distance counts the lifted foot as missing, which makes every
    lift look like a step back, and a greedy search then expands every
    equally good two-feet stance before it lifts a foot. Rating a lifted
    stance by its best re-placement (the minimum goal distance over the
    reachable prints of that foot) removes that plateau.

    Parameters
    ----------
    goal : environments Goal
    scene : environments Scene
    neighbours : StanceNeighbours
        Gives the reachable prints.
    feet : sequence of str
        The robot's support surfaces (its feet), from the robot's roles.
    """

    def __init__(self, goal, scene, neighbours, feet):
        self.goal = goal
        self.scene = scene
        self.neighbours = neighbours
        self.feet = tuple(feet)

    def __call__(self, stance):
        """Heuristic value, metres, >= 0."""
        h = self.goal.distance(stance, self.scene)
        lifted = [rs for rs in self.feet if rs not in stance.robot_surfaces]
        if len(lifted) == 1 and len(lifted) < len(self.feet):
            for child, _ in self.neighbours.additions(stance, lifted[0]):
                h = min(h, self.goal.distance(child, self.scene))
        return h


def _usable_robot_surfaces(robot, options):
    """Robot surfaces the planner may place: the scenario's ``robot_surfaces`` option, or all."""
    names = list(robot.surfaces)
    wanted = (options or {}).get("robot_surfaces")
    if wanted is None:
        return names
    unknown = sorted(set(wanted) - set(names))
    if unknown:
        raise CbmError(f"options.robot_surfaces names unknown robot surfaces {unknown}; robot surfaces: {', '.join(names)}")
    return [name for name in names if name in wanted]


def check_robot_surfaces(scenario, robot, goal=None):
    """Refuse a scenario, or a goal given in its place, naming surfaces the robot lacks.

    Raises
    ------
    environments.ScenarioError
        For the scenario's stances and goal: naming the file, the key, the
        surface and the robot's surfaces.
    CbmError
        For ``goal``: naming the surface and the robot's surfaces.
    """
    if isinstance(scenario, environments.Scenario):
        scenario.check_robot_surfaces(robot.surfaces, f"robot {robot.name!r}")
    if goal is not None:
        named = [c.robot_surface for c in goal.contacts] + [r.robot_surface for r in goal.regions]
        for robot_surface in named:
            if robot_surface not in robot.surfaces:
                raise CbmError(
                    f"the goal names robot surface {robot_surface!r}, not a surface of robot {robot.name!r}; "
                    f"its surfaces: {', '.join(robot.surfaces)}"
                )


def _resolve_stance(value, scenario, what):
    if value is None:
        return None
    if isinstance(value, str):
        if value not in scenario.stances:
            names = ", ".join(sorted(scenario.stances)) or "(none)"
            raise CbmError(f"unknown {what} stance {value!r} in scenario {scenario.name!r}; stances: {names}")
        return scenario.stances[value]
    return value


def plan(
    scenario,
    *,
    goal=None,
    start=None,
    robot=None,
    print_spacing=None,
    max_expansions=DEFAULT_MAX_EXPANSIONS,
    max_solver_calls=None,
    time_limit=DEFAULT_TIME_LIMIT,
    seed=0,
    progress=False,
    solver_options=None,
    reach=ReachLimits(),
    path_cost=DEFAULT_PATH_COST,
    eager=False,
    oracle=None,
    workers=1,
    prefilter=True,
    terrain_weight=None,
    forbidden=(),
):
    """Plan a sequence of stances from the scenario's start to its goal.

    Parameters
    ----------
    scenario : environments Scenario, str or path
        A scenario, a built-in scenario name or a scenario file.
    goal : environments Goal, optional
        Overrides the scenario's goal.
    start : environments Stance or str, optional
        Start stance, or a stance name of the scenario; default the
        scenario's start.
    robot : stances Robot or str, optional
        The robot, or a built-in robot's name or a description file (loaded by
        :func:`load_robot`, once for every plan that names it, as ``cbm plan --robot``
        does). Default: ``scenario.robot``.
    print_spacing : float, optional
        Print grid step, metres; default the scenario's ``print_spacing``
        option, else a quarter of the robot's step, at most 0.1 m; on that
        default grid, a search that finds no plan within ``max_expansions`` (or
        runs out of feasible stances) is followed by one on a grid half as fine,
        with the time left (the reason and ``statistics.print_spacing`` say so;
        the statistics count both searches). The print
        headings are the scenario's ``theta_values_deg``, else the start's and
        the goal's foot headings and enough between them for the feet to turn
        (:func:`cbm.sampling.default_headings`).
    max_expansions, max_solver_calls : int or None
        Search budgets (None: unlimited).
    time_limit : float or None
        Wall-time budget, seconds.
    seed : int
        Seed of the neighbour shuffling that breaks ties between equally
        promising prints; the same seed gives the same plan.
    progress : bool
        Show a progress display (tqdm, stderr) during the search: stances expanded,
        solves, cache hits, open stances, the best distance to the goal, the time left.
    solver_options : dict, optional
        Keyword arguments of ``stances.solve``.
    reach : ReachLimits or ReachModel
        Ratios of the reach pruning, applied to the robot's own dimensions
        (:mod:`cbm.reach`), or a ready reach model.
    path_cost : float
        Priority added per move, metres of goal distance.
    eager : bool
        Baseline: solve every neighbour when generated (for benchmarks).
    oracle : callable, optional
        Replaces the posture oracle (tests): ``oracle(stance, parent,
        parent_check) -> StanceCheck``.
    workers : int
        Processes solving stances (:mod:`cbm.parallel`): with more than one,
        the search solves the open list's next stances (in eager mode, an
        expansion's candidates) ahead, in parallel; the plan is the same, bit
        for bit, for any number. Needs a scenario read from YAML and a robot
        from ``stances.Robot.load``, and the built-in oracle.
    terrain_weight : float, optional
        Metres of goal distance per joule of elastic energy stored in the soft
        supports, added to the priority for each stance of a path
        (:mod:`cbm.terrain`): 0 ignores the terrain, a large weight avoids soft
        ground where a rigid way exists. Default: the scenario's
        ``terrain_weight`` option, else 0 (then plans are those of a search
        without the term, bit for bit).
    forbidden : iterable of (Stance, Stance), optional
        Transitions the search may not take, ``(stance, next stance)``: steps
        that no quasi-static motion joins (:func:`cbm.replan.plan_with_motions`).

    Returns
    -------
    Plan
        ``success`` False with the reason and the best partial sequence if no
        goal stance was reached.

    Raises
    ------
    CbmError
        If the scenario has no start or no goal and none is given, or
        ``terrain_weight`` is not a finite number >= 0.
    environments.ScenarioError
        If a stance or the goal names a surface the robot lacks.
    environments.SceneError
        If a soft object's own weight strains it beyond its strain bound.
    PlanInterrupted
        On Ctrl-C during the search, with the best partial plan so far.
    """
    scenario = load_scenario(scenario)
    weight = _terrain_weight(getattr(scenario, "options", None), terrain_weight)
    scene = scenario.scene
    goal = goal if goal is not None else scenario.goal
    if goal is None:
        raise CbmError(f"scenario {scenario.name!r} has no goal; pass goal=")
    start = _resolve_stance(start if start is not None else scenario.start, scenario, "start")
    if start is None:
        raise CbmError(f"scenario {scenario.name!r} has no start stance; pass start=")
    if isinstance(scenario, environments.Scenario):
        scenario.check_self_weight()  # naming the file and the object's line
    else:  # a scenario-like object built in code (tests)
        check_self_weight(scene)
    if robot is None or isinstance(robot, (str, os.PathLike)):
        robot = load_robot(scenario.robot if robot is None else robot)
    check_robot_surfaces(scenario, robot, goal)
    reach_model = reach if isinstance(reach, ReachModel) else ReachModel.of(robot, reach)
    feet = reach_model.supports(robot.surfaces)
    headings = default_headings(
        tuple(start) + tuple(goal.contacts), scene.surfaces, feet, reach_model.limits.max_foot_yaw_difference
    )
    options = getattr(scenario, "options", None)
    usable = _usable_robot_surfaces(robot, options)
    default_spacing = default_print_spacing(reach_model.step_length)
    # The grid is the planner's own choice unless the user or the scenario sets it: then,
    # where it finds no plan, a grid half as fine is tried before giving up.
    own_grid = print_spacing is None and not (options or {}).get("print_spacing")
    # Regions the start already meets need no print of the grid.
    unmet = [region for region, distance in zip(goal.regions, goal.distances(start, scene)[len(goal.contacts):])
             if distance > 0.0]
    check_goal_regions(unmet, scene.surfaces, {name: robot.surfaces[name] for name in usable},
                       options_from_scenario(options, print_spacing, default_spacing, headings))
    limits = SearchLimits(max_expansions=max_expansions, max_solver_calls=max_solver_calls, time_limit=time_limit)
    pool = None
    if check_workers(workers) > 1 and oracle is not None:
        raise CbmError("workers > 1 runs the posture oracle in worker processes; a custom oracle= needs workers=1")
    started = time.perf_counter()
    if oracle is None:
        deadline = None if time_limit is None else started + time_limit
        oracle = PostureOracle(robot, scene, solver_options, deadline=deadline, prefilter=prefilter)
        if workers > 1:
            pool = PosturePool(workers, scenario, robot, solver_options, deadline=deadline, prefilter=prefilter)

    sampled = [0]  # prints sampled by each search so far (what an interrupted one reports)

    def search(spacing, limits):
        """The best-first search on one print grid: (search result, prints sampled, the grid's sampling)."""
        sampling = options_from_scenario(options, spacing, default_spacing, headings)
        print_sets = sample_prints(
            scene.surfaces, {name: robot.surfaces[name] for name in usable}, sampling, obstacle_boxes(scene)
        )
        print_sets = with_prints(print_sets, goal.contacts, scene.surfaces)
        prints = sum(len(s) for s in print_sets.values())
        sampled.append(prints)
        logger.info(
            "%s: %d prints sampled (spacing %.3f m, %d angles)",
            scenario.name,
            prints,
            sampling.spacing,
            len(sampling.theta_values),
        )
        neighbours = StanceNeighbours(
            print_sets, scene.surfaces, reach_model, required=goal.contacts, forbidden=forbidden
        )
        bar = on_expand = None
        if progress:
            # A counter, not a bar against the expansion cap: a plan that reaches its goal
            # after 9 of 200 allowed expansions is done, not at 4 %. Redrawn at every
            # expansion (each costs at least a posture solve).
            bar = tqdm(desc=f"planning {scenario.name}", unit=" expanded", leave=False, mininterval=0, miniters=1)

            def on_expand(state):
                bar.set_postfix_str(_progress_text(state, limits.time_limit), refresh=False)
                bar.update(state.statistics.expanded - bar.n)

        try:
            # Log lines above the progress line, not run into it.
            with logging_redirect_tqdm() if bar is not None else contextlib.nullcontext():
                searched = best_first_search(
                    start,
                    neighbours=neighbours,
                    oracle=oracle,
                    heuristic=LookaheadHeuristic(goal, scene, neighbours, feet),
                    is_goal=lambda stance: goal.is_satisfied(stance, scene),
                    path_cost_weight=path_cost,
                    node_cost=TerrainCost(weight) if weight > 0 else None,
                    limits=limits,
                    eager=eager,
                    shuffle_neighbours=True,
                    seed=seed,
                    on_expand=on_expand,
                    submit=None if pool is None else pool.submit,
                    lookahead=workers,
                )
        finally:
            if bar is not None:
                bar.close()
        return searched, prints, sampling

    refusals = []  # the goal stance's refusal (_goal_stance_refusal), once asked

    def refused_goal():
        if not refusals:
            refusals.append(_goal_stance_refusal(goal, feet, oracle))
        return refusals[0]

    # Whether a goal stance that is not held is the plan's only way to its goal: the feet the
    # only surfaces it places (a stance adding a hand may hold where the goal's prints do not).
    goal_only = set(usable) <= {c.robot_surface for c in goal.contacts}
    earlier = None  # (statistics, spacing) of a search on the default grid that found no plan
    try:
        searched, prints, sampling = _out_of_time_said(search(print_spacing, limits))
        finer = sampling.spacing / 2.0
        left = None if time_limit is None else time_limit - (time.perf_counter() - started)
        if (own_grid and not searched.success and finer >= FINEST_GRID and (left is None or left > 0.0)
                and searched.reason in (budget_exhausted("max_expansions"), NO_FEASIBLE_NEIGHBOUR)
                and not (goal_only and refused_goal() is not None)):  # no grid reaches a goal not held
            # The default grid can miss every chain of prints clear of the obstacles (a
            # user's two 0.3 m mats end to end: 200 expansions, no plan, on 0.1 m; 11
            # stances in 1.8 s on 0.05 m), and a finer one from the start would slow
            # the many scenes where it does not (4x the prints). Same seed, the budgets
            # left.
            logger.info("%s: no plan on the %.3f m print grid (%s); searching a %.3f m one",
                        scenario.name, sampling.spacing, searched.reason, finer)
            earlier = (searched.statistics, sampling.spacing)
            finer_limits = SearchLimits(max_expansions, max_solver_calls, left)
            searched, prints, sampling = _out_of_time_said(search(finer, finer_limits))
    except SearchInterrupted as interrupted:
        searched = _with_earlier(interrupted.result, earlier)
        s = searched.statistics
        reason = (
            f"{searched.reason} after {s.expanded} stances expanded and {s.solver_calls} solver calls; "
            "the stances are the best partial sequence found so far"
        )
        raise PlanInterrupted(_plan_of(searched, scenario, robot, sampled[-1], reason, chain=False)) from None
    finally:
        if pool is not None:
            pool.close()
    searched = _with_earlier(searched, earlier)
    if pool is not None:
        # The workers' CPU too: what the plan cost, not only this process's share.
        statistics = dataclasses.replace(searched.statistics, cpu_time=searched.statistics.cpu_time + pool.worker_cpu)
        searched = dataclasses.replace(searched, statistics=statistics)
    reason = searched.reason
    if earlier is not None:
        reason += (f" on a {sampling.spacing:.3f} m print grid, after {earlier[0].expanded} stances expanded on "
                   f"the default {earlier[1]:.3f} m one found no plan")
    if not searched.success and not reason.startswith("start infeasible"):
        # Out of budget or out of stances among colliding ones, a finer grid may offer the
        # prints between the obstacles (a user's own 0.1 m grid on a rubber mat: at 200
        # expansions the hint, at 1000 the graph exhausted and no hint; 9 stances on 0.05 m).
        # A goal stance that is its own only way to the goal and is not held: the answer
        # whatever the grid, its reason in place of the grid's hints (and the ones it implies).
        goal_reason = refused_goal()
        only_way = goal_reason is not None and goal_only
        rejected = [goal_reason] if only_way else _rejected(searched)
        exhausted = searched.reason.startswith("budget exhausted") or searched.reason == NO_FEASIBLE_NEIGHBOUR
        if goal_reason is not None:
            reason += ("; the goal's own stance was not held from the reference posture: " if only_way else
                       "; the goal's prints alone were not held from the reference posture (with another "
                       "contact they may be): ") + goal_reason
        if not only_way:
            reason += coarse_grid_hint(sampling.spacing, reach_model.step_length)
        if exhausted and earlier is None and not only_way:
            reason += finer_grid_hint(rejected, sampling.spacing)
        # The strain bound named, or else the soft support that held the prints back: one hint.
        reason += strain_bound_hint(rejected) or soft_support_hint(rejected)
        reason += unresolved_ball_hint(rejected)
        reason += pivoting_print_hint(rejected)
        reason += stiff_reach_hint(rejected)
    return _plan_of(searched, scenario, robot, prints, reason, print_spacing=sampling.spacing,
                    solver_options=solver_options)


def _goal_stance_refusal(goal, feet, oracle):
    """The reason a solve of the goal's own stance gives, from the reference posture, where its
    prints alone stand on every foot (and it has no regions) and it is not held; None where
    it holds, where the goal is no such stance, or where the time ran out. One more solve, on
    a failed plan only: a user's goal with one sole 1.5 m ahead of the other took 200
    expansions and a reason that blamed the obstacles."""
    if goal.regions or not goal.contacts or not set(feet) <= {c.robot_surface for c in goal.contacts}:
        return None
    check = oracle(environments.Stance(goal.contacts), None, None)
    if check.feasible or not check.reason or cause_of(check.reason) == "time":  # (_OUT_OF_TIME's too)
        return None
    return check.reason


def _progress_text(progress, time_limit):
    """What the progress display says after an expansion (a :class:`cbm.search.SearchProgress`):
    solves, cache hits, open stances, the best distance to the goal, the time left."""
    statistics = progress.statistics
    text = (f"solves={statistics.solver_calls}, cached={statistics.cache_hits}, open={progress.queued}, "
            f"to goal={progress.best_heuristic:.2f} m")
    if time_limit is not None:
        text += f", {max(time_limit - statistics.time, 0.0):.0f} s left"
    return text


def _rejected(searched):
    """The reasons of the stances a search found infeasible."""
    return [
        getattr(attributes["result"], "reason", "") or "rejected"
        for _, attributes in searched.graph.nodes(data=True)
        if attributes.get("status") == "infeasible"
    ]


def _out_of_time_said(outcome):
    """A search's ``(result, prints, sampling)``, its reason "budget exhausted: time_limit" where
    it ran out of candidates because the posture checks ran out of time (the oracle's clock
    starts before the prints are sampled, the search's after: the checks can reject every
    candidate for time before the search's own limit is reached)."""
    searched, prints, sampling = outcome
    if searched.reason == NO_FEASIBLE_NEIGHBOUR and any(cause_of(r) == "time" for r in _rejected(searched)):
        searched = dataclasses.replace(searched, reason=budget_exhausted("time_limit"))
    return searched, prints, sampling


def _with_earlier(searched, earlier):
    """A search result whose counters add those of an earlier search, ``(statistics, spacing)``
    (None: the result as it is): a plan's statistics count all the work it took."""
    if earlier is None:
        return searched
    before, now = earlier[0].to_dict(), searched.statistics.to_dict()
    summed = type(searched.statistics)(**{name: before[name] + now[name] for name in now})
    return dataclasses.replace(searched, statistics=summed)


def _plan_of(searched, scenario, robot, prints, reason, print_spacing=None, solver_options=None, chain=True):
    """The Plan of a search result: its path's stances with their postures and the statistics;
    with ``chain``, a stance its path reaches through another parent than the one its answer
    was asked from solved again from where its predecessor leaves the soft prints they keep
    (:mod:`cbm.slip_chain`; an interrupted plan is given as found)."""
    planned = []
    for index, (stance, check) in enumerate(zip(searched.path, searched.results)):
        move = ""
        if index > 0:
            move = str(searched.graph.edges[searched.path[index - 1], stance]["move"])
        result = check.result
        planned.append(
            PlannedStance(
                stance=stance,
                q=result.q,
                point_forces=tuple(result.point_forces),
                deformations=dict(getattr(result, "deformations", {}) or {}),
                result=result,
                move=move,
            )
        )
    rechained = chained(planned, scenario.scene, robot, solver_options) if chain else planned
    if rechained is None:
        logger.warning("a stance of the plan has no posture from where the one before it leaves its soft "
                       "prints: its answer is the search's (Plan.check says which)")
    else:
        planned = rechained
    s = searched.statistics
    answers = [attributes["result"] for _, attributes in searched.graph.nodes(data=True)]
    prefiltered = Counter(getattr(a, "rejected_by", "") for a in answers if a is not None)
    prefiltered.pop("", None)
    # Every search counter, whatever SearchStatistics holds, the prints and the prefilter's rejections.
    statistics = PlanStatistics(**s.to_dict(), prints=prints, prefiltered=dict(sorted(prefiltered.items())),
                                print_spacing=print_spacing)
    return Plan(
        searched.success,
        reason,
        tuple(planned),
        statistics,
        scenario.name,
        summarise(_rejected(searched)),
        robot=robot_description(robot),
        scenario_source=scenario_source(scenario),
        frontier=() if searched.success else _frontier(searched.graph),
    )


def _frontier(graph):
    """The open stances of a search graph nearest the goal (:attr:`cbm.plan.Plan.frontier`):
    sorted by heuristic, then by the move's text, so the same search gives the same list."""
    entries = []
    for node, attributes in graph.nodes(data=True):
        if attributes.get("status") != "open" or attributes.get("result") is not None or "h" not in attributes:
            continue
        moves = sorted(str(graph.edges[parent, node]["move"]) for parent in graph.predecessors(node))
        if moves:
            entries.append({"goal_distance": float(attributes["h"]), "move": moves[0], "stance": _stance_text(node)})
    entries.sort(key=lambda entry: (entry["goal_distance"], entry["stance"], entry["move"]))
    return tuple(entries[:FRONTIER_SIZE])


def _stance_text(stance):
    """A stance's contacts in one line: each robot surface, its surface and its print (x, y
    in metres and the heading in degrees, in that surface's frame)."""
    return "; ".join(
        f"{c.robot_surface} on {c.contact_print.surface} at ({c.contact_print.x:.3f}, {c.contact_print.y:.3f}) m, "
        f"{math.degrees(c.contact_print.theta):.0f} deg"
        for c in stance
    )

