"""Throughput of batch stance checks (checks per second) on a local Dask cluster of 1 and 2 workers.

The checks: every named stance of three built-in scenarios (rigid floor,
rigid table, soft foam block), repeated to ``--repeat`` copies. Each run
starts its own local cluster; the time reported covers starting it, solving
every check and gathering the answers (what ``cbm batch`` costs), and the
throughput without the start is given too. With ``--ray`` the same checks run
as Ray tasks (``ray`` installed), for the choice of engine in
``cbm/distributed.py``.

Run: ``python bench/bench_batch.py [--repeat 4] [--ray] [--out bench/results/batch.md]``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

SCENARIOS = ("stand", "hand-on-table", "cross-soft-block")
SOLVER_OPTIONS = {"max_iterations": 40}


def batch_checks(repeat):
    """The benchmark's checks: every named stance of :data:`SCENARIOS`, ``repeat`` times."""
    import environments

    from cbm.batch import Check

    checks = []
    for name in SCENARIOS:
        scenario = environments.load(name)
        for stance_name, stance in scenario.stances.items():
            for copy in range(repeat):
                checks.append(
                    Check(f"{name}/{stance_name}/{copy}", scenario.text, str(scenario.path), stance.to_dict(), scenario.robot)
                )
    return checks


def run_dask(checks, workers):
    """(total seconds, seconds after the cluster was up, outcomes)."""
    from distributed import Client, LocalCluster

    from cbm.batch import run_check

    started = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            client.wait_for_workers(workers)
            up = time.perf_counter()
            futures = [client.submit(run_check, check, SOLVER_OPTIONS, pure=False) for check in checks]
            outcomes = client.gather(futures)
    done = time.perf_counter()
    return done - started, done - up, outcomes


def run_ray(checks, workers):
    """As :func:`run_dask`, with Ray tasks."""
    import ray

    from cbm.batch import run_check

    started = time.perf_counter()
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray.remote(num_cpus=1)(run_check)
        ray.get([ray.remote(lambda: None).remote() for _ in range(workers)])  # workers up
        up = time.perf_counter()
        outcomes = ray.get([remote.remote(check, SOLVER_OPTIONS) for check in checks])
    finally:
        ray.shutdown()
    done = time.perf_counter()
    return done - started, done - up, outcomes


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=4)
    parser.add_argument("--ray", action="store_true", help="also run the checks as Ray tasks")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "batch.md")
    args = parser.parse_args(argv)
    checks = batch_checks(args.repeat)
    engines = [("Dask distributed", run_dask)] + ([("Ray", run_ray)] if args.ray else [])
    rows, reference = [], None
    for engine, run in engines:
        for workers in (1, 2):
            total, solving, outcomes = run(checks, workers)
            answers = [(o.feasible, o.q.tobytes()) for o in outcomes]
            reference = answers if reference is None else reference
            rows.append(
                f"| {engine} | {workers} | {len(checks)} | {sum(o.feasible for o in outcomes)} | {total:.1f} | "
                f"{len(checks) / total:.2f} | {len(checks) / solving:.2f} | {'yes' if answers == reference else 'NO'} |"
            )
            print(rows[-1], flush=True)
    load = os.getloadavg()
    text = "\n".join(
        [
            "# Batch checks benchmark",
            "",
            f"`bench/bench_batch.py --repeat {args.repeat}`, {platform.machine()} with {os.cpu_count()} CPUs "
            f"(shared: load average {load[0]:.1f} at the end), Python {platform.python_version()}; "
            f"solver options {SOLVER_OPTIONS}. Checks: every named stance of {', '.join(SCENARIOS)}, "
            f"{args.repeat} copies each, solved cold. Total time: starting the local cluster, solving, "
            "gathering; 'solving only' leaves the start out. 'same answers': feasibility and q bits equal "
            "to the first run's.",
            "",
            "| engine | workers | checks | feasible | total (s) | checks/s | checks/s, solving only | same answers |",
            "|---|---|---|---|---|---|---|---|",
            *rows,
            "",
        ]
    )
    args.out.write_text(text)
    print(f"written to {args.out}")


if __name__ == "__main__":
    main()
