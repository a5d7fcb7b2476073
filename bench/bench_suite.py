"""Benchmark suite of the planner: scenes of issue 11, each against its rigid twin.

Each scene (a file of ``bench/scenes/`` or a built-in scenario) is planned
with ``cbm.plan`` for several seeds, and so is its rigid twin
(:func:`environments.rigid_twin.rigid_twin`: every soft object made rigid,
all else equal), the baseline of the soft scene. A scene without soft objects
is its own twin and is planned once per seed. Per scene the table gives the
success rate, median and 90th percentile of the plan time (wall and CPU time
of this process), solver calls and stances in the plan, for the scene and its
twin, and the ratio of their median wall times. Every posture solve a plan makes
is timed (:func:`timed_solves`): the longest, over all plans, is judged against
issue 9's "no single solve over 1 s".

Plan time is the time of ``cbm.plan`` on the loaded scenario with a loaded
robot: loading the scene (meshing, FEM factorisations) is timed apart. The
raw runs go to ``bench/results/suite.json`` (one record per plan, written
after each), the table to ``bench/results/suite.md``. Runs go seed by seed
over all scenes, so an interrupted suite still covers every scene.

Run from the repository root::

    nice -n 10 .venv/bin/python bench/bench_suite.py [--seeds N] [--scenes a,b] [--time-limit S]
    .venv/bin/python bench/bench_suite.py --table-only    # the table of suite.json again
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

import environments
import stances
from environments.rigid_twin import rigid_twin

import cbm
import cbm.planner

sys.path.insert(0, str(Path(__file__).resolve().parent))
from benchmark_info import code_version, machine  # noqa: E402

SCENE_DIRECTORY = Path(__file__).resolve().parent / "scenes"
RESULTS = Path(__file__).resolve().parent / "results"

#: The suite, in the order of the issue: a file stem of bench/scenes or a built-in scenario.
SCENES = (
    "stairs-10cm",
    "stairs-15cm",
    "stairs-soft-step",
    "block-field",
    "two-mats",
    "three-mats",
    "turn",
    "rail-over-gap",
    "climb-with-soft-support",
    "long-walk",
    "quadruped-foam",
    "quadruped-soft-block",
)

#: Issue 11's targets on a quiet 2-core machine.
TARGET_SUCCESS = 0.95
TARGET_MEDIAN_SECONDS = 10.0
TARGET_SOFT_OVER_RIGID = 2.0
#: Issue 9's: no single posture solve over this, CPU seconds, on the built-in scenes.
TARGET_LONGEST_SOLVE = 1.0


def scene_source(name):
    """The file of a suite scene, or the built-in name."""
    path = SCENE_DIRECTORY / f"{name}.yaml"
    return str(path) if path.is_file() else name


def load_scene(name, defaults=False):
    """``(scenario, seconds to load it)``; with ``defaults``, its planner options dropped."""
    started = time.perf_counter()
    scenario = environments.load(scene_source(name))
    if defaults:
        scenario = dataclasses.replace(scenario, options={})
    return scenario, time.perf_counter() - started


@contextlib.contextmanager
def timed_solves():
    """Within it, every posture solve the planner makes (through ``cbm.planner.posture_api``,
    where it looks its solver up) is timed: yields the list of ``(CPU s, wall s, stance,
    SQP iterations)`` it fills, the iterations those of every stage of the solve (its
    warm starts' too; None when the solve raised): a count the host's load does not move,
    to compare two versions of the solver by. Solves in worker processes are not seen
    (the suite plans in one process)."""
    solves = []
    solve, verify = cbm.planner.posture_api()

    def timed(*args, **kwargs):
        cpu, wall = time.process_time(), time.perf_counter()
        result = None
        try:
            result = solve(*args, **kwargs)
            return result
        finally:
            stance = kwargs.get("stance", args[2] if len(args) > 2 else None)
            iterations = None if result is None else (
                result.iterations + result.statistics.get("rigid_warm_start_iterations", 0))
            solves.append((time.process_time() - cpu, time.perf_counter() - wall, stance, iterations))

    original = cbm.planner.posture_api
    cbm.planner.posture_api = lambda: (timed, verify)
    try:
        yield solves
    finally:
        cbm.planner.posture_api = original


def run_once(scenario, robot, seed, time_limit):
    """One plan: a plain-data record of its outcome and costs."""
    load = os.getloadavg()[0]
    with timed_solves() as solves:
        wall, cpu = time.perf_counter(), time.process_time()
        result = cbm.plan(scenario, robot=robot, seed=seed, time_limit=time_limit)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    longest = max(solves, key=lambda entry: entry[0], default=(0.0, 0.0, None, None))
    return {
        "seed": seed,
        "success": bool(result.success),
        "reason": str(result.reason),
        "wall": wall,
        "cpu": cpu,
        "solver_calls": result.statistics.solver_calls,
        "expanded": result.statistics.expanded,
        "stances": len(result.stances),
        "rejections": {cause: entry["count"] for cause, entry in result.rejections.items()},
        "rejection_examples": {cause: entry["example"][:200] for cause, entry in result.rejections.items()},
        "load_before": load,
        "load_after": os.getloadavg()[0],
        # Issue 9: the plan's longest posture solve (CPU and wall seconds, its stance).
        "longest_solve_cpu": longest[0],
        "longest_solve_wall": longest[1],
        "longest_solve_stance": "" if longest[2] is None else json.dumps(longest[2].to_dict()),
        "longest_solve_iterations": longest[3],
        # Every solve's SQP iterations, warm starts included (raised solves left out).
        "solver_iterations": sum(entry[3] for entry in solves if entry[3] is not None),
        "code": code_version(),
    }


def run_suite(names, seeds, time_limit, records, save, defaults=False):
    """Plan every scene and its twin for each seed, skipping runs already in ``records``."""
    robots = {}
    loaded = {}
    done = {(r["scene"], r["variant"], r["seed"]) for r in records}
    planned = set()
    for seed in seeds:
        for name in names:
            if name not in loaded:
                scenario, seconds = load_scene(name, defaults)
                twin = rigid_twin(scenario) if scenario.scene.deformable_objects else None
                loaded[name] = (scenario, twin, seconds)
            scenario, twin, seconds = loaded[name]
            robot = robots.get(scenario.robot)
            if robot is None:
                robot = robots[scenario.robot] = stances.Robot.load(scenario.robot)
            variants = [("scene", scenario)] + ([("twin", twin)] if twin is not None else [])
            for variant, which in variants:
                if (name, variant, seed) in done:
                    continue
                record = run_once(which, robot, seed, time_limit)
                # The first plan of a soft scene in this process computes the compliance
                # columns its prints need (or reads them from fem's disk cache); later
                # seeds reuse them: recorded, so the two can be told apart.
                first = (name, variant) not in planned
                planned.add((name, variant))
                record.update(scene=name, variant=variant, load_seconds=seconds, time_limit=time_limit,
                              options=sorted(scenario.options), soft=twin is not None, first_in_process=first)
                records.append(record)
                save(records)
                print(
                    f"{name:24s} {variant:5s} seed {seed}: {'ok ' if record['success'] else 'FAIL'} "
                    f"{record['wall']:7.1f} s wall {record['cpu']:7.1f} s cpu, {record['solver_calls']} solves, "
                    f"{record['stances']} stances, load {record['load_before']:.1f}"
                    + ("" if record["success"] else f" ({record['reason'][:100]})"),
                    flush=True,
                )
    return records


def summary(runs):
    """Success rate, median and p90 wall and CPU time, median solver calls and stances of some runs."""
    if not runs:
        return None
    wall = np.array([r["wall"] for r in runs])
    cpu = np.array([r["cpu"] for r in runs])
    ok = [r for r in runs if r["success"]]
    return {
        "n": len(runs),
        "success": len(ok) / len(runs),
        "wall_median": float(np.median(wall)),
        "wall_p90": float(np.percentile(wall, 90)),
        "cpu_median": float(np.median(cpu)),
        "cpu_p90": float(np.percentile(cpu, 90)),
        "solver_calls": float(np.median([r["solver_calls"] for r in runs])),
        "stances": float(np.median([r["stances"] for r in ok])) if ok else float("nan"),
    }


def _cells(s):
    if s is None:
        return ["-"] * 5
    return [
        f"{100 * s['success']:.0f} % of {s['n']}",
        f"{s['wall_median']:.1f} / {s['wall_p90']:.1f}",
        f"{s['cpu_median']:.1f} / {s['cpu_p90']:.1f}",
        f"{s['solver_calls']:.0f}",
        "-" if np.isnan(s["stances"]) else f"{s['stances']:.0f}",
    ]


def table(records, names):
    """Markdown table: each scene beside its rigid twin (the baseline), and the time ratio."""
    header = (
        "| scene | soft | success | wall median / p90 (s) | CPU median / p90 (s) | solver calls | stances "
        "| twin success | twin wall median / p90 (s) | twin CPU median / p90 (s) | twin solver calls | twin stances "
        "| soft / rigid median, wall (CPU) |"
    )
    lines = [header, "|" + "---|" * 13]
    for name in names:
        runs = [r for r in records if r["scene"] == name]
        if not runs:
            continue
        soft = runs[0]["soft"]
        scene = summary([r for r in runs if r["variant"] == "scene"])
        twin = summary([r for r in runs if r["variant"] == "twin"]) if soft else scene
        ratio = "-" if not soft or twin is None else (
            f"{scene['wall_median'] / twin['wall_median']:.2f} ({scene['cpu_median'] / twin['cpu_median']:.2f})"
        )
        twin_cells = _cells(twin) if soft else ["(itself)"] + [""] * 4
        if not soft:
            ratio = "1 (rigid)"
        lines.append("| " + " | ".join([name, "yes" if soft else "no", *_cells(scene), *twin_cells, ratio]) + " |")
    return "\n".join(lines)


def targets(records, names):
    """Lines saying which of issue 11's targets the runs meet, naming the scenes that miss."""
    scene_runs = [r for r in records if r["variant"] == "scene" and r["scene"] in names]
    if not scene_runs:
        return []
    rate = np.mean([r["success"] for r in scene_runs])
    slow, costly = [], []
    for name in names:
        scene = summary([r for r in scene_runs if r["scene"] == name])
        twin = summary([r for r in records if r["scene"] == name and r["variant"] == "twin"])
        if scene is None:
            continue
        if scene["wall_median"] > TARGET_MEDIAN_SECONDS:
            slow.append(f"{name} ({scene['wall_median']:.1f} s)")
        if twin is not None and scene["wall_median"] > TARGET_SOFT_OVER_RIGID * twin["wall_median"]:
            costly.append(f"{name} ({scene['wall_median'] / twin['wall_median']:.1f}x)")
    return [
        f"- success over all scenes and seeds: {100 * rate:.0f} % ({sum(r['success'] for r in scene_runs)} of "
        f"{len(scene_runs)}; target >= {100 * TARGET_SUCCESS:.0f} %)",
        f"- median plan > {TARGET_MEDIAN_SECONDS:.0f} s: {', '.join(slow) or 'none'}",
        f"- soft scene > {TARGET_SOFT_OVER_RIGID:.0f}x its rigid twin: {', '.join(costly) or 'none'}",
        *longest_solve(records, names),
    ]


def longest_solve(records, names):
    """The line on issue 9's "no single solve over 1 s": the longest posture solve of
    every plan (scenes and twins), where it was; none for runs recorded without it."""
    timed = [r for r in records if r["scene"] in names and "longest_solve_cpu" in r]
    if not timed:
        return []
    worst = max(timed, key=lambda r: r["longest_solve_cpu"])
    over = sum(r["longest_solve_cpu"] > TARGET_LONGEST_SOLVE for r in timed)
    counted = [r for r in timed if "solver_iterations" in r]
    iterations = ""
    if counted:
        iterations = (f"; SQP iterations of every solve, warm starts included: {sum(r['solver_iterations'] for r in counted)} "
                      f"over {len(counted)} plans (the longest solve's: {worst.get('longest_solve_iterations')})")
    return [
        f"- longest posture solve over the {len(timed)} plans (scenes and twins, "
        f"{sum(r['solver_calls'] for r in timed)} solver calls): {worst['longest_solve_cpu']:.2f} s CPU "
        f"({worst['longest_solve_wall']:.2f} s wall), {worst['scene']} ({worst['variant']}) seed {worst['seed']}; "
        f"plans with a solve over {TARGET_LONGEST_SOLVE:g} s CPU (issue 9): {over}{iterations}",
    ]


def failures(records, names):
    """One line per failed run: the scene, seed, reason and the rejection causes."""
    lines = []
    for r in records:
        if r["scene"] in names and not r["success"]:
            causes = ", ".join(f"{count} {cause}" for cause, count in r["rejections"].items()) or "none"
            lines.append(f"- {r['scene']} ({r['variant']}), seed {r['seed']}: {r['reason'][:160]}; rejected: {causes}")
    return lines


def report(records, names, header):
    """The markdown of suite.md."""
    loads = [r["load_before"] for r in records] + [r["load_after"] for r in records]
    options = {r["scene"]: r["options"] for r in records}
    needing = [f"{name} ({', '.join(options[name])})" for name in names if options.get(name)]
    # Runs resumed from an older results file may be of other code than the header's.
    codes = sorted({r.get("code", "code not recorded") for r in records})
    mixed = [f"**Runs of several code versions** in these records: {'; '.join(codes)}."] if len(codes) > 1 else []
    return "\n".join([
        "# Planner benchmark suite (issue 11 item 8)",
        "",
        header,
        *mixed,
        f"Load average (1 min) over the runs: {min(loads):.1f} to {max(loads):.1f}, mean {np.mean(loads):.1f}.",
        "",
        "Times are of `cbm.plan` on the loaded scenario (loading and meshing excluded), wall and CPU "
        "time of this process (`time.process_time`, all its threads). The twin is the same scene with every "
        "soft object made rigid (`environments.rigid_twin`); a rigid scene is its own twin. "
        f"Scenes that set planner options: {', '.join(needing) or 'none'}.",
        "",
        table(records, names),
        "",
        "Targets of issue 11 (quiet 2-core machine):",
        "",
        *targets(records, names),
        "",
        "Failed runs:",
        "",
        *(failures(records, names) or ["- none"]),
        "",
    ])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 per scene and twin (default 10)")
    parser.add_argument("--scenes", default=",".join(SCENES), help="comma-separated scene names (default: all)")
    parser.add_argument("--time-limit", type=float, default=60.0, help="seconds per plan (default 60)")
    parser.add_argument("--results", type=Path, default=RESULTS / "suite.json",
                        help="raw runs, read to resume and written after each run")
    parser.add_argument("--out", type=Path, default=RESULTS / "suite.md")
    parser.add_argument("--fresh", action="store_true", help="ignore the runs already in --results")
    parser.add_argument("--table-only", action="store_true", help="write the table of --results, plan nothing")
    parser.add_argument("--defaults", action="store_true",
                        help="drop every scene's planner options (use other --results and --out files)")
    args = parser.parse_args(argv)
    names = [n for n in args.scenes.split(",") if n]
    unknown = [n for n in names if scene_source(n) == n and n not in environments.scenario_names()]
    if unknown:
        parser.error(f"unknown scenes {unknown}; suite scenes: {', '.join(SCENES)}")
    records, saved_header = [], None
    if args.results.is_file() and not args.fresh:
        saved = json.loads(args.results.read_text())
        records, saved_header = saved["runs"], saved.get("header")
    header = f"`bench/bench_suite.py{' --defaults' if args.defaults else ''}`, {code_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {machine()}."
    if args.table_only and saved_header is not None:
        header = saved_header  # the runs' own commit, date and load, not this call's

    def save(runs):
        args.results.parent.mkdir(parents=True, exist_ok=True)
        args.results.write_text(json.dumps({"header": header, "runs": runs}, indent=1))

    if not args.table_only:
        records = run_suite(names, range(args.seeds), args.time_limit, records, save, args.defaults)
    text = report(records, names, header)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print()
    print(text)
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
