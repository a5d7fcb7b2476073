"""Instructions a workload executes, this tree against a baseline commit: a measure the host's noise leaves alone.

On a shared machine the same 60 rigid posture solves took 1.11 to 1.83 s of CPU
within one session, so a change worth 5-10 % cannot be seen in timings alone.
valgrind's instruction count (``cachegrind --cache-sim=no``) of a workload is the
same from run to run on one machine, whatever else runs. It is not time
(vectorised code does more per instruction, memory stalls cost none), so it
backs timings taken side by side, never replaces them.

Each workload runs twice in a fresh process under valgrind: once with its setup
alone (imports, robot, scenes, and for the soft stances a first solve each that
pays the mesh, factorisation and compliance), once with the measured solves too;
the difference is the solves' instructions. The baseline is the same workload on
the library of a git worktree of ``--baseline`` (``PYTHONPATH`` pointing at it). BLAS runs on one
thread (under valgrind, OpenBLAS's spinning threads count billions of
instructions of waiting).

Workloads: ``rigid``, the 60 random stances of ``bench_posture.py``;
``soft``, the six stances of ``bench_deformable.py``, one solve each.

Run from the repository root (valgrind needed; on an AMD EPYC, 2 cores: rigid about 2
minutes for both trees, soft over 20, its scenes' loading and first solves being slow under
valgrind)::

    .venv/bin/python bench/bench_instructions.py --baseline HEAD~1 [--workloads rigid,soft]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from benchmark_info import code_version, write_report  # noqa: E402

WORKLOADS = ("rigid", "soft")


def workload(name, measured):
    """Run one workload in this process (the child valgrind measures); ``measured`` False: its setup only."""
    import numpy as np

    import environments
    import stances

    robot = stances.Robot.load("talos")
    if name == "rigid":
        import bench_posture

        cases = bench_posture.random_stances(robot, np.random.default_rng(bench_posture.SEED))
        if measured:
            for _, scene, stance in cases:
                stances.solve(robot, scene, stance)
    elif name == "soft":
        import bench_deformable

        for scenario_name, stance_name in bench_deformable.STANCES:
            scenario = environments.load(scenario_name)
            stance = scenario.stances[stance_name]
            stances.solve(robot, scenario.scene, stance)  # pays the setup
            if measured:
                stances.solve(robot, scenario.scene, stance)
    else:
        raise SystemExit(f"unknown workload {name!r}; known: {', '.join(WORKLOADS)}")


def count(tree, name, measured):
    """Instructions (valgrind ``I refs``) of a fresh process running a workload on the library
    of ``tree`` (the workloads themselves are this file's, the same for every tree)."""
    environment = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    command = ["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
               sys.executable, str(HERE / "bench_instructions.py"), "--run", name]
    if not measured:
        command.append("--setup-only")
    finished = subprocess.run(command, env=environment, capture_output=True, text=True)
    match = re.search(r"I\s+refs:\s+([\d,]+)", finished.stderr)
    if finished.returncode != 0 or match is None:
        raise RuntimeError(f"{name} in {tree} failed:\n{finished.stderr[-2000:]}")
    return int(match.group(1).replace(",", ""))


def measure(tree, name):
    """Instructions of a workload's measured solves: the full run less its setup."""
    with ThreadPoolExecutor(max_workers=2) as pool:  # one valgrind a core
        setup, full = pool.map(lambda measured: count(tree, name, measured), (False, True))
    return full - setup


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default="HEAD~1", help="git revision to compare with (default HEAD~1)")
    parser.add_argument("--workloads", default=",".join(WORKLOADS), help="comma-separated (default: all)")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "instructions.md")
    parser.add_argument("--run", help=argparse.SUPPRESS)  # the child's workload
    parser.add_argument("--setup-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.run:
        workload(args.run, not args.setup_only)
        return
    names = args.workloads.split(",")
    unknown = sorted(set(names) - set(WORKLOADS))
    if unknown:  # said before a worktree is made and valgrind started
        raise SystemExit(f"unknown workload(s) {unknown}; known: {', '.join(WORKLOADS)}")
    if shutil.which("valgrind") is None:
        raise SystemExit("valgrind is not installed (apt install valgrind)")
    started = time.perf_counter()
    baseline = subprocess.run(["git", "rev-parse", "--short", args.baseline], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip()
    rows = ["| workload | baseline (G instructions) | this tree (G instructions) | this / baseline |",
            "|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as folder:
        worktree = Path(folder) / "baseline"
        subprocess.run(["git", "worktree", "add", "--detach", str(worktree), baseline], cwd=ROOT,
                       capture_output=True, check=True)
        try:
            for name in names:
                before, after = measure(worktree, name), measure(ROOT, name)
                rows.append(f"| {name} | {before / 1e9:.2f} | {after / 1e9:.2f} | {after / before:.3f} |")
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=ROOT, capture_output=True)
    preamble = (
        f"Instructions of each workload's solves (valgrind cachegrind, setup subtracted, one BLAS thread), "
        f"this tree ({code_version()}) against commit {baseline}. Workloads: rigid, the 60 random stances "
        f"of bench_posture.py; soft, the six stances of bench_deformable.py, one solve each after one that "
        f"pays the setup. A count is not a time: read it beside timings taken side by side."
    )
    write_report(str(args.out), "Instruction counts against a baseline", started, preamble, rows)


if __name__ == "__main__":
    main()
