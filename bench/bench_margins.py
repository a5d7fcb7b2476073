"""Margins of every built-in stance: how close each accepted posture comes to its limits.

Issue 9's done-when asks that every built-in posture keep its margins. The test suite
checks ten stances (on coarse meshes, to stay fast); this solves every stance of every
built-in scenario at its default meshes, with its own robot, and reports per stance:
verified or not, the largest torque usage (|tau| over the full limit) and its joint, the
smallest joint clearance (distance to a position limit over the joint's range) and its
joint, and the joints the result names on their margin (``result.limits["at_margin"]``).
A stance fails the check when it is not verified, when a torque passes 1 - effort_margin
of its limit, or when a joint comes nearer a limit than joint_margin of its range.

Run from the repository root (about 1-2 minutes with a warm disk cache)::

    .venv/bin/python bench/bench_margins.py

Prints a markdown table and writes it to ``bench/results/margins.md``.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmark_info import write_report  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402
from stances.problem import PostureOptions  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def stance_margins(robot, scenario, stance_name):
    """One row's numbers: (verified, CPU s, torque usage, its joint, clearance, its joint, at margin,
    reason), read from the result's ``limits`` (:meth:`stances.problem.PostureProblem.limit_usage`;
    tests/test_stances_solve.py recomputes them from q and the torques on ten stances)."""
    tic = time.process_time()
    result = stances.solve(robot, scenario.scene, scenario.stance(stance_name))
    seconds = time.process_time() - tic
    limits = result.limits  # empty where the solve stopped before a posture (a spent budget)
    return (result.feasible, seconds, limits.get("torque_usage", float("nan")), limits.get("torque_joint", "-"),
            limits.get("joint_clearance", float("nan")), limits.get("clearance_joint", "-"),
            tuple(limits.get("at_margin", ())), result.reason)


def main():
    started = time.perf_counter()
    options = PostureOptions()
    robots = {}
    rows, failures = [], []
    for scenario_name in environments.scenario.scenario_names():
        scenario = environments.load(scenario_name)
        if scenario.robot not in robots:
            robots[scenario.robot] = stances.Robot.load(scenario.robot)
        robot = robots[scenario.robot]
        for stance_name in sorted(scenario.stances):
            verified, seconds, usage, torque_joint, clearance, clearance_joint, at_margin, reason = stance_margins(
                robot, scenario, stance_name)
            holds = (verified and usage <= 1.0 - options.effort_margin + 1e-6
                     and clearance >= options.joint_margin - 1e-9)
            if not holds:
                failures.append(f"- {scenario_name}/{stance_name}: {reason or 'past a margin'}")
            rows.append(
                f"| {scenario_name}/{stance_name} | {robot.name} | {'yes' if verified else 'no'} | {seconds:.2f} "
                f"| {100 * usage:.1f} % ({torque_joint}) | {100 * clearance:.2f} % ({clearance_joint}) "
                f"| {'; '.join(at_margin) or '-'} |"
            )
            print(rows[-1], flush=True)
    preamble = (
        f"Every stance of every built-in scenario, default meshes, `stances.solve` with default options "
        f"(effort margin {options.effort_margin:.0%}, joint margin {options.joint_margin:.0%} of each range). "
        f"Torque usage is |tau| over the full limit; clearance is the distance to the nearer position limit "
        f"over the joint's range. {len(rows) - len(failures)} of {len(rows)} stances verified and within both "
        f"margins." + ("\n\nFailures:\n\n" + "\n".join(failures) if failures else "")
    )
    lines = [
        "| stance | robot | verified | CPU s | largest torque usage | smallest joint clearance | named on a margin |",
        "|---|---|---|---|---|---|---|",
        *rows,
    ]
    write_report(str(RESULTS / "margins.md"), "Margins of the built-in stances", started, preamble, lines)


if __name__ == "__main__":
    main()
