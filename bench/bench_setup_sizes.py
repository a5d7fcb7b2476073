"""Setup and cached setup of a soft body at about 8k and 50k nodes, and the solve on it.

Run as ``.venv/bin/python bench/bench_setup_sizes.py``; prints a markdown table and
writes it to ``bench/results/setup_sizes.md``.

The stance ``hand-on-cube`` (right palm on the 1 m cube) with the cube meshed at
spacings giving about 8,600 and 52,000 nodes (and the default, 13,125, between them).
Setup (mesh, assembly, factorisation, the print's compliance) is measured as in
``bench_deformable.py``: two fresh processes sharing a new, empty disk cache, each loading
the scenario and solving twice; setup = load + first solve - second solve, CPU seconds.
The first process fills the cache, the second reads it (a second ``cbm plan`` on the
same scene). Then the solve itself: median of 3 solves in this process after a first
one, CPU seconds, one BLAS thread.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
os.environ["SOFTCBM_CACHE"] = "off"

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from bench_deformable import setup_seconds, timed_solve  # noqa: E402
from benchmark_info import scenario_at_resolution, write_report  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402

SPACINGS = (0.026, 0.0225, 0.0135)  # metres: about 8.6k, 13k (default) and 52k nodes
RESULT = os.path.join(os.path.dirname(__file__), "results", "setup_sizes.md")


def main() -> None:
    started = time.perf_counter()
    robot = stances.Robot.load("talos")
    lines = [
        "| cube spacing h (m) | nodes | setup s: no cache | setup s: disk cache | cache MB | solve CPU s (median of 3) "
        "| iterations | verified |",
        "|---|---|---|---|---|---|---|---|",
    ]
    with tempfile.TemporaryDirectory() as directory:
        for spacing in SPACINGS:
            path = scenario_at_resolution("hand-on-cube", spacing, directory)
            fresh, cached, megabytes = setup_seconds(path, "hand-on-cube")
            scenario = environments.load(path)
            stance = scenario.stance("hand-on-cube")
            timed_solve(robot, scenario.scene, stance)  # pays the setup
            runs = [timed_solve(robot, scenario.scene, stance) for _ in range(3)]
            result = runs[-1][1]
            nodes = scenario.scene.deformable("cube").mesh.nodes.shape[0]
            lines.append(
                f"| {spacing} | {nodes:,} | {fresh:.2f} | {cached:.2f} | {megabytes:.0f} "
                f"| {statistics.median(r[0] for r in runs):.2f} | {result.iterations} "
                f"| {'yes' if result.feasible else 'no: ' + result.reason[:60]} |"
            )
            print(lines[-1], flush=True)
    write_report(
        RESULT,
        "Setup of a soft body at about 8k and 50k nodes",
        started,
        "Stance `hand-on-cube` with the 1 m cube meshed at the spacing h (refined where the palm lands).",
        lines,
    )

if __name__ == "__main__":
    main()
