"""Command line: ``cbm plan``, ``cbm scenarios``, ``cbm robots``, ``cbm check``.

Exit codes: 0 success (plan found, stance feasible), 1 no plan found or stance
infeasible, 2 bad input (scenario, option or output folder), 130 interrupted
(Ctrl-C: ``cbm plan`` still writes the best partial plan found so far), 141
output pipe closed (``cbm scenarios | head -1``: not an error, no traceback). Only the packages' own bad-input errors become code 2; anything else
is a bug and ends with its traceback.

Defaults shared with Python: ``cbm plan``'s budgets are :func:`cbm.plan`'s own
(:data:`cbm.planner.DEFAULT_MAX_EXPANSIONS`, :data:`cbm.planner.DEFAULT_TIME_LIMIT`);
``--help`` shows them.
"""

from __future__ import annotations

import argparse
import functools
import logging
import os
import signal
import sys
from pathlib import Path

__all__ = [
    "main",
    "build_parser",
    "DEFAULT_SCENARIO",
    "EXIT_OK",
    "EXIT_FAILED",
    "EXIT_BAD_INPUT",
    "EXIT_INTERRUPTED",
    "EXIT_PIPE_CLOSED",
]

#: Scenario planned when ``cbm plan`` is given none.
DEFAULT_SCENARIO = "cross-soft-block"

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, what shells report for Ctrl-C
EXIT_PIPE_CLOSED = 141  # 128 + SIGPIPE, what shells report for `yes | head -1`

_EXIT_CODES = """exit codes:
  0    plan found (check: stance feasible, or plan.json verifies)
  1    no plan found (check: stance infeasible, or plan.json fails its check)
  2    bad input: unknown scenario, invalid scenario file or option, unusable --out
  130  interrupted (Ctrl-C): cbm plan writes the best partial plan so far, marked
       unsuccessful; a second Ctrl-C while it writes leaves --out as it was
  141  output pipe closed early (e.g. piped into head)"""

logger = logging.getLogger("cbm")


class _Parser(argparse.ArgumentParser):
    """An argparse parser that raises instead of exiting, so main() returns codes."""

    def error(self, message):
        raise _UsageError(f"{self.prog}: {message}")


class _UsageError(Exception):
    pass


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the epilog's layout (the exit codes) and shows each option's default.

    Like argparse's ArgumentDefaultsHelpFormatter, but silent for flags and for
    defaults of None ("not given"), where "(default: None)" would say nothing.
    """

    def _fill_text(self, text, width, indent):
        # One-line descriptions are wrapped; text with its own line breaks (the
        # exit-code table) is kept as written.
        if "\n" in text:
            return super()._fill_text(text, width, indent)
        return argparse.HelpFormatter._fill_text(self, text, width, indent)

    def _get_help_string(self, action):
        text = action.help or ""
        shown = action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE)
        # Identity, not ``in``: a default of 0 equals False but is worth showing.
        silent = action.default is None or action.default is False or action.default is argparse.SUPPRESS
        if shown and "%(default)" not in text and not silent:
            text += " (default: %(default)s)"
        return text


def _version():
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("softcbm")
    except PackageNotFoundError:
        return "unknown (softcbm is not installed; run pip install -e .)"



def _positive_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _solver_option(text):
    """``KEY=VALUE`` of ``--solver-option``: the value a number where it reads as one
    (``inf`` included), else ``true``/``false``, else the text."""
    key, equals, value = str(text).partition("=")
    if not equals or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE (a posture option, e.g. ball_force_error=inf), got {text!r}")
    value = value.strip()
    try:
        parsed = int(value)
    except ValueError:
        try:
            parsed = float(value)
        except ValueError:
            parsed = {"true": True, "false": False}.get(value.lower(), value)
    return key.strip(), parsed


def _add_solver_option(parser):
    parser.add_argument(
        "--solver-option", type=_solver_option, action="append", default=[], metavar="KEY=VALUE",
        help="a posture solver option (stances.PostureOptions), repeatable: e.g. ball_force_error=inf accepts "
        "ball feet whose contact the soft mesh does not resolve, max_iterations=200",
    )


def _solver_options(args) -> dict:
    """The ``--solver-option`` pairs, checked as posture options (bad input names the valid ones)."""
    from stances.stages import posture_options

    options = dict(args.solver_option)
    posture_options(options)
    return options


def _non_negative_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return value


def _positive_int(text):
    value = _non_negative_int(text)
    if value == 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _at_least_two(text):
    value = _non_negative_int(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected an integer of at least 2, got {text!r}")
    return value


def build_parser():
    """The argument parser of ``cbm``."""
    parser = _Parser(
        prog="cbm",
        description="Contact-before-motion planning for legged robots (humanoids, quadrupeds) on rigid and soft supports.",
        epilog=_EXIT_CODES,
        formatter_class=_HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    commands.required = True

    plan = commands.add_parser(
        "plan",
        help="plan a sequence of stances and write the results",
        description="Plan a sequence of stances and write plan.json, pictures, meshes and viewer.html. The "
        "files are written in a temporary folder beside --out and moved into place at the end, so --out "
        "holds one complete plan or is left as it was.",
        epilog=_EXIT_CODES,
        formatter_class=_HelpFormatter,
    )
    plan.add_argument(
        "scenario",
        nargs="?",
        default=DEFAULT_SCENARIO,
        metavar="SCENARIO",
        help="built-in scenario name or scenario file",
    )
    plan.add_argument("--out", type=Path, default=Path("cbm-out"), help="output folder, new or empty")
    plan.add_argument("--force", action="store_true", help="replace the content of a non-empty --out")
    from .planner import DEFAULT_MAX_EXPANSIONS, DEFAULT_TIME_LIMIT

    plan.add_argument(
        "--max-expansions", type=_non_negative_int, default=DEFAULT_MAX_EXPANSIONS, help="stances expanded at most"
    )
    plan.add_argument("--time-limit", type=_positive_float, default=DEFAULT_TIME_LIMIT, help="seconds of search at most")
    plan.add_argument("--seed", type=int, default=0, help="seed of the tie-breaking shuffle")
    plan.add_argument(
        "--print-spacing",
        type=_positive_float,
        default=None,
        help="print grid step, metres (default: the scenario's print_spacing option, else a quarter of the robot's step, at most 0.1)",
    )
    plan.add_argument(
        "--workers", type=_positive_int, default=1, help="processes solving stances in parallel (same plan for any number)"
    )
    plan.add_argument(
        "--no-prefilter",
        action="store_true",
        help="solve every stance, without the cheap checks that reject impossible ones first (benchmarks)",
    )
    plan.add_argument(
        "--terrain-weight",
        type=float,
        default=None,
        help="metres of goal distance per joule stored in soft supports: > 0 prefers stiff, shallow prints "
        "(default: the scenario's terrain_weight option, else 0)",
    )
    plan.add_argument("--no-pictures", action="store_true", help="skip the PNG pictures")
    _add_solver_option(plan)
    plan.add_argument(
        "--motion",
        action="store_true",
        help="also plan the quasi-static motion between consecutive stances (trajectory.csv, trajectory.npz, "
        "played by viewer.html); each sample is a verified posture solve; a stance whose posture its motion "
        "cannot reach is solved again from the motion's touch-down, or at a lift-off its last lifted sample "
        "(plan.json holds the new posture); a step that still has no motion is taken out and the search runs "
        "again, three searches at most, each with the budgets above",
    )
    plan.add_argument("--view", action="store_true",
                      help="show the plan in meshcat (pip install meshcat) and keep it open until you close it")
    plan.add_argument("--quiet", action="store_true", help="no progress bar, warnings only")
    plan.add_argument("--verbose", action="store_true",
                      help="say in full why stances were rejected (every cause with a whole example) and, for a "
                      "failed plan, where the search would have gone on (its open stances nearest the goal)")
    _add_robot_option(plan)

    batch = commands.add_parser(
        "batch",
        help="solve many stance checks on a Dask cluster and write a Parquet dataset",
        description="Solve and verify every (robot, scenario, stance) check of a YAML or CSV file "
        "(see cbm.batch) on a local Dask cluster, or on a running one with --scheduler, and write "
        "DIR/checks.parquet: one row per check with stance, feasible, reason, q, forces and times.",
        epilog=_EXIT_CODES,
        formatter_class=_HelpFormatter,
    )
    batch.add_argument("file", type=Path, metavar="FILE", help="batch file (.yaml, .yml or .csv)")
    batch.add_argument("--out", type=Path, required=True, help="folder of the dataset")
    batch.add_argument("--workers", type=_positive_int, default=2, help="processes of the local cluster")
    batch.add_argument("--scheduler", default=None, metavar="ADDRESS", help="a running Dask scheduler instead")
    batch.add_argument("--quiet", action="store_true", help="warnings only")

    scenarios = commands.add_parser(
        "scenarios",
        help="list the built-in scenarios and their stances, or given scenarios with their contact surfaces",
        description="Without arguments, list the built-in scenarios with their stances. Given scenario names or "
        "files, list those with their stances and every contact surface of their scene (those found on mesh "
        "files by surfaces: auto included): rigid or soft, object, frame origin and normal in the world, and "
        "the x, y range of the surface in its own frame, where a stance's prints are given.",
        formatter_class=_HelpFormatter,
    )
    scenarios.add_argument("scenario", nargs="*", metavar="SCENARIO", help="built-in scenario name or scenario file")
    commands.add_parser("robots", help="list the built-in robots")

    check = commands.add_parser(
        "check",
        help="solve one stance of a scenario, or verify a saved plan again",
        description="Solve one stance of a scenario and print its forces, depths in the soft bodies and "
        "margins to the robot's limits; or, given a plan.json, verify every stance of the plan again "
        "(with the scenario the file embeds, so it works on a copied plan).",
        epilog=_EXIT_CODES,
        formatter_class=_HelpFormatter,
    )
    check.add_argument(
        "scenario", metavar="SCENARIO", help="built-in scenario name, scenario file, or a plan .json file"
    )
    check.add_argument("--stance", help="name of the stance in the scenario (required unless checking a plan)")
    check.add_argument("--out", type=Path, default=None, help="directory for the stance's picture")
    check.add_argument("--quiet", action="store_true", help="warnings only")
    check.add_argument("--view", action="store_true",
                       help="show the stance (or the plan file) in meshcat (pip install meshcat) and keep it open "
                       "until you close it")
    check.add_argument(
        "--refine", type=_at_least_two, default=None, metavar="FACTOR",
        help="solve the stance (or each soft stance of a plan) again on its soft meshes FACTOR times finer "
        "(2: every cell halved, about 8x the nodes) and say how far the answer moves",
    )
    _add_solver_option(check)
    _add_robot_option(check)
    return parser


def _add_robot_option(parser):
    parser.add_argument(
        "--robot",
        default=None,
        metavar="ROBOT",
        help="built-in robot name (see `cbm robots`) or robot description file; default: the scenario's robot",
    )


def _quiet_on_closed_pipe(function):
    """Make a closed standard output (``cbm scenarios | head -1``) end quietly with code 141.

    Output is flushed inside the guard: otherwise the interpreter's last flush, at
    exit, meets the closed pipe and prints a traceback no code can catch.
    """

    @functools.wraps(function)
    def guarded(argv=None):
        try:
            code = function(argv)
            sys.stdout.flush()
        except BrokenPipeError:
            # Whatever is still buffered goes nowhere instead of failing again at exit.
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            return EXIT_PIPE_CLOSED
        return code

    return guarded


@_quiet_on_closed_pipe
def main(argv=None):
    """Run the command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        0 success, 1 no plan / infeasible, 2 bad input, 130 interrupted,
        141 standard output closed early.
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except _UsageError as error:
        print(error, file=sys.stderr)
        parser.print_usage(sys.stderr)
        return EXIT_BAD_INPUT
    except SystemExit as exit_:  # --help
        return int(exit_.code or 0)
    logging.basicConfig(
        level=logging.WARNING if getattr(args, "quiet", False) else logging.INFO,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        if args.command == "scenarios":
            return _scenarios(args.scenario)
        if args.command == "robots":
            return _robots()
        if args.command == "plan":
            return _plan(args)
        if args.command == "batch":
            return _batch(args)
        return _check(args)
    except _input_errors() as error:
        print(f"cbm {args.command}: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"cbm {args.command}: interrupted; nothing written", file=sys.stderr)
        return EXIT_INTERRUPTED


def _input_errors():
    """The packages' own bad-input exception types.

    Only these mean "bad input"; a plain ValueError (numpy's LinAlgError, a
    failed internal check) is a bug and must show its traceback.
    """
    from environments.errors import SceneError
    from fem.errors import FemError
    from stances.errors import StanceError

    from .errors import CbmError

    return (CbmError, SceneError, FemError, StanceError)


def _scenarios(names=()):
    """List scenarios: the built-in ones, or those named (names or files) with their surfaces."""
    import environments

    for name in names or environments.scenario_names():
        scenario = environments.load(name)
        description = " ".join(str(scenario.description).split())
        stance_names = ", ".join(f"{stance} (start)" if stance == scenario.start else stance for stance in scenario.stances)
        print(f"{scenario.name}\n    {description}\n    stances: {stance_names}")
        if names:
            print("    surfaces:")
            for surface in scenario.scene.surfaces.values():
                print(f"      {_surface_line(surface)}")
    return EXIT_OK


def _surface_line(surface):
    """One contact surface in words: what a user writing a stance's prints on it needs."""
    import numpy as np

    transform = np.asarray(surface.transform_surface_to_world, dtype=float)
    lower, upper = np.min(surface.polygon, axis=0), np.max(surface.polygon, axis=0)
    origin, normal = transform[:3, 3], transform[:3, 2]
    return (
        f"{surface.name}: {'soft' if surface.deformable else 'rigid'}, on {surface.object_name}; frame origin "
        f"({origin[0]:.3f}, {origin[1]:.3f}, {origin[2]:.3f}) m, normal ({normal[0]:.2f}, {normal[1]:.2f}, "
        f"{normal[2]:.2f}), world; spans x {lower[0]:.3f}..{upper[0]:.3f} m, y {lower[1]:.3f}..{upper[1]:.3f} m "
        "in its own frame (prints are given there)"
    )


def _robots():
    import stances

    for name in stances.builtin_robot_names():
        description = stances.read_description(name)
        roles = ", ".join(f"{s.name} ({s.role}, {s.limb})" for s in description.surfaces)
        print(f"{name}\n    {description.description}\n    surfaces: {roles}")
    return EXIT_OK


def _load_robot(args, scenario):
    """The robot of ``--robot``, else the scenario's, checked against the scenario's stances and goal."""
    import stances

    from .planner import check_robot_surfaces

    robot = stances.Robot.load(args.robot if args.robot is not None else scenario.robot)
    check_robot_surfaces(scenario, robot)
    return robot


def _plan(args):
    from stances.results import one_line

    from .output import StagedOutput, write_outputs
    from .planner import PlanInterrupted, load_scenario, plan
    from .replan import plan_with_motions

    scenario = load_scenario(args.scenario)
    robot = _load_robot(args, scenario)
    # Before the search: a bad --out must not cost a whole search, and the
    # temporary folder made here is where the files go.
    staged = StagedOutput(args.out, force=args.force)
    interrupted = False
    options = dict(
        print_spacing=args.print_spacing,
        max_expansions=args.max_expansions,
        time_limit=args.time_limit,
        seed=args.seed,
        progress=not args.quiet,
        workers=args.workers,
        prefilter=not args.no_prefilter,
        terrain_weight=args.terrain_weight,
        solver_options=_solver_options(args),
    )
    motions, moving = None, None
    try:
        try:
            if args.motion:
                # Where a step has no motion, the search runs again without it.
                moving = plan_with_motions(scenario, robot=robot, **options)
                result, motions = moving.plan, moving.motions
            else:
                result = plan(scenario, robot=robot, **options)
        except PlanInterrupted as stop:
            if not stop.plan.stances:
                raise  # not even the start solved: nothing worth writing
            result, motions, interrupted = stop.plan, stop.motions, True
            print(
                f"cbm plan: interrupted; writing the best partial plan ({len(result.stances)} stances), "
                "Ctrl-C again to abandon it",
                file=sys.stderr,
            )
        files = write_outputs(result, scenario, robot, staged.folder, pictures=not args.no_pictures, motions=motions)
        staged.publish()
    except BaseException:
        # Interrupted, failed or refused: leave --out as it was.
        staged.discard()
        raise
    s = result.statistics
    outcome = "plan found" if result.success else f"no plan: {result.reason}"
    print(f"{scenario.name}: {outcome}; {len(result.stances)} stances")
    print(
        f"  {s.expanded} stances expanded, {s.solver_calls} solver calls, "
        f"{s.cache_hits} cache hits, {s.time:.1f} s wall, {s.cpu_time:.1f} s CPU"
    )
    if s.prefiltered:
        checks = ", ".join(f"{count} by {name}" for name, count in s.prefiltered.items())
        print(f"  {sum(s.prefiltered.values())} of the solver calls rejected before solving: {checks}")
    if result.rejections:
        total = sum(entry["count"] for entry in result.rejections.values())
        causes = ", ".join(f"{entry['count']} {cause}" for cause, entry in result.rejections.items())
        print(f"  {total} stances rejected: {causes}")
        if not result.success or args.verbose:
            for cause, entry in result.rejections.items():
                example = entry["example"] if args.verbose else one_line(entry["example"])
                print(f"    {cause}, e.g. {example}")
    if result.frontier and args.verbose:
        print(f"  the search would have gone on with ({len(result.frontier)} open stances nearest the goal):")
        for entry in result.frontier:
            print(f"    {entry['goal_distance']:.2f} m from the goal: {entry['stance']} (by: {entry['move']})")
    if args.verbose and s.print_spacing is not None:
        print(f"  print grid: {s.print_spacing:.3f} m, {s.prints} prints")
    if moving is not None and moving.plans > 1:
        kept = ("the first" if not moving.avoided else
                f"one avoiding {len(moving.avoided)} step(s) of earlier plans that had no motion")
        print(f"  searched {moving.plans} times for a plan whose every step has a motion; kept {kept}"
              + ("" if moving.missing == 0 else f", {moving.missing} motion(s) still missing") + ":")
        for step in moving.avoided:
            print(f"    avoided {step.move}: {one_line(step.reason)}")
    for index, planned in enumerate(result.stances):
        print(f"  {index}: {planned.move or 'start'}")
    if motions:
        from .motion import motions_summary

        print(f"  {motions_summary(motions)}")
    for motion in motions or ():
        if not motion.feasible:
            print(f"  motion {motion.index} -> {motion.index + 1} not found: {motion.reason}")
    print(f"  written to {args.out}: {len(files.all())} files, viewer {staged.final_path(files.viewer)}")
    if interrupted:
        return EXIT_INTERRUPTED
    if args.view:
        _view(result, scenario, robot, motions or ())
    return EXIT_OK if result.success else EXIT_FAILED


def _batch(args):
    from .batch import read_checks
    from .distributed import solve_many, write_dataset

    checks, solver_options = read_checks(args.file)
    outcomes = solve_many(
        checks, address=args.scheduler, workers=args.workers, solver_options=solver_options, progress=not args.quiet
    )
    path = write_dataset(outcomes, args.out)
    feasible = sum(o.feasible for o in outcomes)
    print(f"{len(outcomes)} checks: {feasible} feasible, {len(outcomes) - feasible} infeasible; written to {path}")
    return EXIT_OK


def _check(args):
    from .planner import PostureOracle, load_scenario

    if args.scenario.endswith(".json") and os.path.isfile(args.scenario):
        # A plan is verified with the options each stance was solved with; --solver-option
        # puts its own over them (a plan saved before an option existed recorded none).
        return _check_plan(args.scenario, args.refine, args.view, _solver_options(args))
    scenario = load_scenario(args.scenario)
    if args.stance not in scenario.stances:
        names = ", ".join(sorted(scenario.stances)) or "(none)"
        problem = "needs --stance" if args.stance is None else f"has no stance {args.stance!r}"
        print(f"cbm check: error: scenario {scenario.name!r} {problem}; stances: {names}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.out is not None and args.out.exists() and not args.out.is_dir():
        # Checked before the solve, which may take seconds.
        print(f"cbm check: error: --out {str(args.out)!r} is a file, not a folder", file=sys.stderr)
        return EXIT_BAD_INPUT
    scenario.check_self_weight()  # a scene at fault is bad input, not an infeasible stance
    robot = _load_robot(args, scenario)
    stance = scenario.stances[args.stance]
    fine = None
    if args.refine is not None:
        from stances.refined_check import soft_robot_surfaces

        # Before the solve, which may take seconds: what cannot be refined says so at once.
        if not soft_robot_surfaces(scenario.scene, stance):
            print(f"cbm check: error: --refine: stance {args.stance!r} has no print on a soft surface: nothing to "
                  "refine", file=sys.stderr)
            return EXIT_BAD_INPUT
        fine = _refined_scenario(scenario, args.refine)
        if fine is None:
            return EXIT_BAD_INPUT
    check = PostureOracle(robot, scenario.scene, solver_options=_solver_options(args))(stance)
    result = check.result
    if check.bad_input:
        # A stance the user wrote that the solver refuses (two prints on the same nodes): bad input.
        print(f"cbm check: error: stance {args.stance!r}: {check.reason}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if result is None:
        print(f"{scenario.name} / {args.stance}: infeasible: {check.reason}")
        return EXIT_FAILED
    verdict = "feasible" if check.feasible else f"infeasible: {check.reason}"
    print(f"{scenario.name} / {args.stance}: {verdict}")
    print(f"  {result.iterations} iterations, {result.solve_time:.2f} s")
    if check.feasible:
        from .report import stance_report

        print("\n".join(stance_report(result, robot, stance)))
    held = True
    if check.feasible and fine is not None:
        from stances import check_refined

        refined = check_refined(robot, scenario, result, args.refine, refined=fine)
        print("\n".join(refined.lines()))
        held = refined.ok
    if args.out is not None:
        path = _check_picture(scenario, robot, stance, result, args)
        print(f"  picture written to {path}")
    if args.view:
        from .plan import Plan, PlannedStance, PlanStatistics

        planned = PlannedStance(stance, result.q, result.point_forces, result.deformations, result, args.stance)
        _view(Plan(check.feasible, verdict, (planned,), PlanStatistics(), scenario.name), scenario, robot)
    return EXIT_OK if check.feasible and held else EXIT_FAILED


def _view(plan, scenario=None, robot=None, motions=()):
    """Open a plan in meshcat and keep its server up until the user is done.

    The server lives in this process: returning at once, as ``Plan.show`` does for a
    Python session, would close the page before anyone opened it. The first stance
    is shown; Enter plays the plan (and its motions), ``q`` then Enter, or the end of
    standard input (a non-interactive run), closes it.
    """
    # Closed from outside (the terminal closed, kill): leave as on Ctrl-C, through the
    # interpreter's exit, which ends the meshcat server this process starts.
    stops = [getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)]
    previous = {stop: signal.signal(stop, _exit_on_signal) for stop in stops}
    try:
        view = plan.show(scenario, robot, motions, play=False)
        print(f"  meshcat: {view.url}")
        while True:
            try:
                answer = input("  Enter: play the plan, q then Enter: close the view > ")
            except EOFError:
                print()
                return
            if answer.strip().lower() in ("q", "quit", "exit"):
                return
            view.play()
    finally:
        for stop, handler in previous.items():
            signal.signal(stop, handler)


def _exit_on_signal(number, frame):
    raise SystemExit(128 + number)


def _refined_scenario(scenario, factor):
    """``environments.refined(scenario, factor)``, or None after saying why it cannot be made."""
    from environments import SceneError, refined

    try:
        return refined(scenario, factor)
    except SceneError as error:
        print(f"cbm check: error: --refine: {error}", file=sys.stderr)
        return None


def _check_plan(path, refine=None, view=False, options=None):
    from .plan import Plan
    from .trajectory import read_trajectory

    plan = Plan.load(path)
    report = plan.check(options=options)
    verdict = "every stance verifies" if report.ok else f"{len(report.problems)} problems"
    over = f" (with {', '.join(f'{k}={v}' for k, v in options.items())} over the recorded options)" if options else ""
    print(f"{path}: plan of {plan.scenario_name!r}, {len(plan.stances)} stances: {verdict}{over}")
    for problem in report.problems:
        print(f"  {problem}")
    arrived = [str(index) for index, planned in enumerate(plan.stances) if planned.arrived_by_motion]
    if arrived:
        print(f"  stance{'s' if len(arrived) > 1 else ''} {', '.join(arrived)} start their kept soft prints where "
              "their motions left them; the motions' samples are not in the file (cbm.motion.verify_motion checks "
              "them as they are planned)")
    code = EXIT_OK if report.ok else EXIT_FAILED
    if report.ok and refine is not None:
        code = _check_plan_refined(plan, refine, options)
    if view:
        # The motions a cbm plan --motion wrote beside the plan, replayed between its stances.
        saved = Path(path).parent / "trajectory.npz"
        _view(plan, motions=read_trajectory(saved).motions() if saved.is_file() else ())
    return code


def _check_plan_refined(plan, factor, options=None):
    """Each stance of a plan with a soft print solved again on its soft meshes ``factor`` times
    finer, with posture ``options`` over those it recorded."""
    from dataclasses import replace

    from stances import check_refined
    from stances.refined_check import soft_robot_surfaces

    scenario = plan.scenario()
    soft = [index for index, planned in enumerate(plan.stances) if soft_robot_surfaces(scenario.scene, planned.stance)]
    if not soft:
        print("cbm check: error: --refine: no stance of the plan has a print on a soft surface: nothing to refine",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    fine = _refined_scenario(scenario, factor)
    if fine is None:
        return EXIT_BAD_INPUT
    robot = plan.robot_model(scenario)
    failed = []
    for index in soft:
        planned = plan.stances[index]
        # What the plan shows is what is checked (as Plan.check does).
        shown = replace(planned.result, q=planned.q, point_forces=planned.point_forces)
        check = check_refined(robot, scenario, shown, factor, refined=fine, **(options or {}))
        if not check.ok:
            failed.append(index)
        print(f"stance {index}:")
        print("\n".join("  " + line for line in check.lines()))
    if failed:
        print(f"meshes refined {factor}x: {len(failed)} of the {len(soft)} stances with a soft print do not hold "
              f"(stance{'s' if len(failed) > 1 else ''} {', '.join(map(str, failed))}): the plan's soft meshes are "
              "too coarse for them; plan again with a finer resolution of those objects")
        return EXIT_FAILED
    print(f"meshes refined {factor}x: every stance with a soft print holds ({len(soft)} of {len(soft)})")
    return EXIT_OK


def _check_picture(scenario, robot, stance, result, args):
    from .display import plan_bounds, scene_edges, stance_display
    from .plan import PlannedStance
    from .render import force_scale, render_stance
    from .robot_mesh import robot_meshes

    planned = PlannedStance(stance, result.q, result.point_forces, result.deformations, result)
    meshes = robot_meshes(robot)
    display = stance_display(planned, scenario.scene, robot, f"{scenario.name}: {args.stance}", meshes)
    bounds = plan_bounds([display])
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"{args.stance}.png"
    render_stance(
        display, path, edges=scene_edges(scenario.scene, bounds), bounds=bounds, scale=force_scale([display]),
        meshes=meshes,
    )
    for obj in scenario.scene.deformable_objects:
        if obj.name in result.deformations:
            obj.write_vtu(args.out / f"{args.stance}_{obj.name}.vtu", result.deformations[obj.name])
    return path


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
