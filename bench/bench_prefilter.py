"""Benchmark the cheap checks before posture solves (cbm.prefilter): on and off.

For each scenario, ``cbm.plan`` with the prefilter on and off, same budgets:
oracle answers, stances rejected by each check, posture solves actually run
(retries included), wall and CPU time, and whether the two plans are the same
sequence of moves. With ``--audit SCENARIO`` it also plans once more with an
oracle that solves every stance AND runs the prefilter on it, and counts the
stances the prefilter rejects but the solver accepts (must be 0).

Writes a markdown table to ``bench/results/prefilter.md`` (with the load
average). Run from the repository root, one run at a time on a shared machine::

    nice -n 10 .venv/bin/python bench/bench_prefilter.py --time-limit 120 --audit cross-two-mats
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))

import environments  # noqa: E402
import stances  # noqa: E402
# A floor and a rigid wall whose sides are contact surfaces (friction 0.3): random
# stances there put feet into the wall, palms alone on it, feet on its sides.
from test_cbm_prefilter import WALL_SCENE  # noqa: E402

from cbm.planner import PostureOracle, plan  # noqa: E402
from cbm.prefilter import Prefilter  # noqa: E402

SCENARIOS = ("cross-soft-block", "climb-with-soft-support", "cross-two-mats")


def run(scenario_name, robot, prefilter, time_limit, max_expansions):
    scenario = environments.load(scenario_name)
    oracle = PostureOracle(robot, scenario.scene, deadline=time.perf_counter() + time_limit, prefilter=prefilter)
    result = plan(scenario, robot=robot, time_limit=time_limit, max_expansions=max_expansions, oracle=oracle)
    s = result.statistics
    return {
        "scenario": scenario_name,
        "prefilter": "on" if prefilter else "off",
        "success": "yes" if result.success else f"no ({result.reason})",
        "stances": len(result.stances),
        "moves": tuple(p.move for p in result.stances),
        "expanded": s.expanded,
        "answers": s.solver_calls,
        "rejected": ", ".join(f"{n} {name}" for name, n in s.prefiltered.items()) or "0",
        "solves": oracle.solves,
        "time": s.time,
        "cpu": s.cpu_time,
    }


class AuditOracle:
    """Solves every stance (prefilter off) and also asks the prefilter; records disagreements."""

    def __init__(self, robot, scene, deadline):
        self.oracle = PostureOracle(robot, scene, deadline=deadline, prefilter=False)
        self.prefilter = Prefilter(robot, scene)
        self.rejected, self.wrongly_rejected = [], []

    def __call__(self, stance, parent=None, parent_check=None):
        rejection = self.prefilter(stance)
        check = self.oracle(stance, parent, parent_check)
        if rejection is not None:
            self.rejected.append((stance, rejection, check.feasible, check.reason))
            if check.feasible:
                self.wrongly_rejected.append((stance, rejection))
        return check


def audit(scenario_name, robot, time_limit, max_expansions):
    scenario = environments.load(scenario_name)
    oracle = AuditOracle(robot, scenario.scene, time.perf_counter() + time_limit)
    result = plan(scenario, robot=robot, time_limit=time_limit, max_expansions=max_expansions, oracle=oracle)
    return result, oracle


def random_wall_stances(count, seed):
    """Random stances of Talos on WALL_SCENE: each surface in contact with probability 1/2."""
    import numpy as np
    from environments import Contact, ContactPrint, Stance

    rng = np.random.default_rng(seed)
    stances_made = []
    while len(stances_made) < count:
        contacts = []
        for name in ("left_sole", "right_sole", "left_palm", "right_palm"):
            if rng.random() < 0.5:
                continue
            on_wall = rng.random() < (0.3 if name.endswith("sole") else 0.7)
            if on_wall:
                spot = ContactPrint("wall_back", rng.uniform(-0.5, 0.5), rng.uniform(-0.7, 0.2))
            else:
                spot = ContactPrint("floor", rng.uniform(-0.3, 0.55), rng.uniform(-0.3, 0.3))
            contacts.append(Contact(name, spot))
        if contacts:
            stances_made.append(Stance(tuple(contacts)))
    return stances_made


def audit_random(robot, count, seed, time_budget):
    """Solve every random wall stance the prefilter rejects; list (stance, rejection, solver answer)."""
    scene = environments.load_string(WALL_SCENE, name="wall").scene
    prefilter = Prefilter(robot, scene)
    oracle = PostureOracle(robot, scene, solver_options={"time_budget": time_budget}, prefilter=False)
    rows, filter_time, solve_time = [], 0.0, 0.0
    for stance in random_wall_stances(count, seed):
        started = time.perf_counter()
        rejection = prefilter(stance)
        filter_time += time.perf_counter() - started
        if rejection is not None:
            started = time.perf_counter()
            rows.append((stance, rejection, oracle(stance)))
            solve_time += time.perf_counter() - started
    return rows, filter_time, solve_time


def table(rows):
    columns = ("scenario", "prefilter", "success", "stances", "expanded", "answers", "rejected", "solves", "time", "cpu")
    lines = [
        "| scenario | prefilter | success | stances | expanded | oracle answers | rejected before solving | posture solves | wall s | CPU s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        cells = [f"{row[c]:.1f}" if c in ("time", "cpu") else str(row[c]) for c in columns]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time-limit", type=float, default=120.0)
    parser.add_argument("--max-expansions", type=int, default=200)
    parser.add_argument("--scenarios", nargs="*", default=list(SCENARIOS))
    parser.add_argument("--audit", default=None, metavar="SCENARIO")
    parser.add_argument("--random-stances", type=int, default=0, help="also audit this many random wall stances")
    parser.add_argument("--out", type=Path, default=Path("bench/results/prefilter.md"))
    args = parser.parse_args()
    rows, same = [], {}
    for name in args.scenarios:
        robot = stances.Robot.load(environments.load(name).robot)
        pair = []
        for prefilter in (True, False):
            load = os.getloadavg()[0]
            row = run(name, robot, prefilter, args.time_limit, args.max_expansions)
            row["load"] = load
            print(row)
            pair.append(row)
        same[name] = pair[0]["moves"] == pair[1]["moves"]
        rows.extend(pair)
    text = [
        "# Cheap checks before posture solves (cbm.prefilter), on and off",
        "",
        f"`python bench/bench_prefilter.py --time-limit {args.time_limit:g} --max-expansions {args.max_expansions}`, "
        f"{platform.python_implementation()} {platform.python_version()}, {os.cpu_count()} cores shared; "
        "1-minute load average before each run: " + ", ".join(f"{r['scenario']} {r['prefilter']} {r['load']:.2f}" for r in rows) + ".",
        "",
        "Oracle answers are the search's `solver_calls` (every stance checked); posture solves are the "
        "`stances.solve` calls actually run (a cold retry after a failed warm start counts twice).",
        "",
        table(rows),
        "",
        "Same sequence of moves with and without the prefilter: "
        + ", ".join(f"{name} {'yes' if ok else 'no'}" for name, ok in same.items())
        + " (a plan that hit its time limit can differ: the filtered run gets further in the same time).",
    ]
    if args.audit:
        robot = stances.Robot.load(environments.load(args.audit).robot)
        result, oracle = audit(args.audit, robot, args.time_limit, args.max_expansions)
        text += [
            "",
            f"Audit on {args.audit} (every stance solved, prefilter asked too; {result.statistics.solver_calls} "
            f"stances, {result.reason}): the prefilter rejected {len(oracle.rejected)}, of which the solver "
            f"accepted {len(oracle.wrongly_rejected)}.",
        ]
        for stance, rejection, feasible, reason in oracle.rejected:
            text.append(f"- {rejection.rejected_by}: {rejection.reason} | solver: {'feasible' if feasible else reason[:160]}")
    if args.random_stances:
        robot = stances.Robot.load("talos")
        audited, filter_time, solve_time = audit_random(robot, args.random_stances, 0, 30.0)
        accepted = [row for row in audited if row[2].feasible]
        by_check = {}
        for _, rejection, _ in audited:
            by_check[rejection.rejected_by] = by_check.get(rejection.rejected_by, 0) + 1
        text += [
            "",
            f"Audit on {args.random_stances} random stances of Talos by a rigid wall (seed 0, `WALL_SCENE`): the "
            f"prefilter rejected {len(audited)} ({', '.join(f'{n} by {k}' for k, n in sorted(by_check.items()))}); "
            f"each was solved anyway (time budget 30 s): the solver accepted {len(accepted)}. The prefilter took "
            f"{filter_time:.2f} s for all {args.random_stances} stances ({1e3 * filter_time / args.random_stances:.0f} ms "
            f"each); solving the {len(audited)} it rejects took {solve_time:.1f} s (load average "
            f"{os.getloadavg()[0]:.2f} at the end).",
        ]
        for stance, rejection, check in audited:
            text.append(f"- {rejection.reason[:110]} | solver: {'FEASIBLE' if check.feasible else check.reason[:100]}")
    args.out.write_text("\n".join(text) + "\n")
    print("\n".join(text))


if __name__ == "__main__":
    main()
