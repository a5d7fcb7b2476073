"""What the planner's warm starts cost: each oracle call's warm attempt, and its cold retry.

The planner's oracle (:class:`cbm.planner.PostureOracle`) solves a stance from its
parent's posture first and, if that fails, once more from
:func:`stances.initial_configuration`. A warm attempt that fails is CPU spent for
nothing when the cold retry then succeeds, and CPU spent twice on a stance no start
holds. For each scene and seed this plans with an oracle that records every attempt and
prints, per scene, how the warm attempts ended and what the failed ones cost against the
plans' CPU (the baseline they are a share of). A change to the warm-start policy is judged
by these counts and by the plans' CPU in one run.

Writes ``bench/results/warm_starts.md``. Run from the repository root, one run at a time
on a shared machine::

    .venv/bin/python bench/bench_warm_starts.py --seeds 0-9 quadruped-foam climb-with-soft-support
"""

from __future__ import annotations

import argparse
import os
import sys
import time
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, ".."), HERE]

import stances  # noqa: E402
from bench_suite import scene_source  # noqa: E402
from benchmark_info import code_version, machine  # noqa: E402

from cbm.planner import PostureOracle, load_scenario, plan  # noqa: E402

SCENES = ("quadruped-foam", "quadruped-walk", "climb-with-soft-support", "turn", "two-mats", "rail-over-gap")


class RecordingOracle(PostureOracle):
    """The planner's oracle, recording each call's attempts: ``calls`` holds, per stance
    solved, ``(warm, attempts)`` with ``attempts`` a list of ``(feasible, CPU seconds,
    SQP iterations)`` in the order tried (the warm start first when ``warm``)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.calls = []
        self._attempts = []

    def __call__(self, stance, parent=None, parent_check=None):
        self._attempts = []
        check = super().__call__(stance, parent, parent_check)
        if self._attempts:  # not rejected by the prefilter
            self.calls.append((parent_check is not None and parent_check.result is not None, self._attempts))
        return check

    def _solve(self, stance, q_init, history=None):
        start = time.process_time()
        check = super()._solve(stance, q_init, history)
        iterations = check.result.iterations if check.result is not None else 0
        self._attempts.append((check.feasible, time.process_time() - start, iterations))
        return check


def count_attempts(calls) -> dict:
    """How the warm attempts of :attr:`RecordingOracle.calls` ended: ``calls`` (stances
    solved), ``warm`` (attempts from a parent's posture), ``warm_ok``, ``retry_ok`` and
    ``retry_failed`` (a failed warm attempt's cold retry), and the failed warm attempts'
    ``failed_warm_cpu`` (s) and ``failed_warm_iterations``."""
    counts = {"calls": len(calls), "warm": 0, "warm_ok": 0, "retry_ok": 0, "retry_failed": 0,
              "failed_warm_cpu": 0.0, "failed_warm_iterations": 0}
    for warm, attempts in calls:
        if not warm:
            continue
        counts["warm"] += 1
        feasible, cpu, iterations = attempts[0]
        if feasible:
            counts["warm_ok"] += 1
            continue
        counts["failed_warm_cpu"] += cpu
        counts["failed_warm_iterations"] += iterations
        if len(attempts) > 1:
            counts["retry_ok" if attempts[1][0] else "retry_failed"] += 1
    return counts


def measure(name: str, seeds) -> dict:
    """:func:`count_attempts` summed over the plans of one scene, with ``plans``, ``found``
    (plans that reached the goal) and ``plan_cpu`` (s)."""
    scenario = load_scenario(scene_source(name))
    robot = stances.Robot.load(scenario.robot)
    totals = {"plans": 0, "found": 0, "plan_cpu": 0.0, **count_attempts([])}
    for seed in seeds:
        oracle = RecordingOracle(robot, scenario.scene)  # as plan() makes it, without its deadline
        start = time.process_time()
        result = plan(scenario, robot=robot, seed=seed, oracle=oracle)
        totals["plan_cpu"] += time.process_time() - start
        totals["plans"] += 1
        totals["found"] += bool(result.success)
        for key, value in count_attempts(oracle.calls).items():
            totals[key] += value
    return totals


def table(rows) -> list:
    lines = ["| scene | plans found | stances solved | warm attempts | warm ok | warm failed, cold ok | "
             "warm failed, cold failed | failed warm attempts: CPU s (SQP iterations) | plans' CPU s | share |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, t in rows:
        lines.append(
            f"| {name} | {t['found']} of {t['plans']} | {t['calls']} | {t['warm']} | {t['warm_ok']} | {t['retry_ok']} | "
            f"{t['retry_failed']} | {t['failed_warm_cpu']:.1f} ({t['failed_warm_iterations']}) | {t['plan_cpu']:.1f} | "
            f"{t['failed_warm_cpu'] / t['plan_cpu']:.0%} |")
    return lines


def seed_range(text: str) -> list:
    """``'0-9'`` or ``'0,3,5'``: the seeds."""
    if "-" in text:
        low, high = (int(part) for part in text.split("-"))
        return list(range(low, high + 1))
    return [int(part) for part in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--seeds", default="0-4", help="'0-9' or '0,3,5' (default 0-4)")
    parser.add_argument("--output", default=os.path.join(HERE, "results", "warm_starts.md"))
    arguments = parser.parse_args()
    seeds = seed_range(arguments.seeds)
    rows = []
    for name in arguments.scenes:
        rows.append((name, measure(name, seeds)))
        print(f"{name} done", file=sys.stderr, flush=True)
    lines = table(rows)
    header = [
        "# Warm starts of the planner's oracle (`bench/bench_warm_starts.py`)", "",
        f"{code_version()}; {machine()}; seeds {arguments.seeds}.", "",
        "Per scene, over its plans: the stances the oracle solved (the prefilter's rejections left out), the warm "
        "attempts (from the parent's posture) and how they ended, the CPU of the warm attempts that failed "
        "(`time.process_time` of each solve, its verification included) and its share of the plans' CPU.", "",
    ]
    text = "\n".join(header + lines) + "\n"
    print(text)
    with open(arguments.output, "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    main()
