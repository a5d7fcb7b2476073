"""The built-in soft stances solved again on their soft meshes refined twice.

Run as ``.venv/bin/python bench/bench_refined_check.py``; prints a markdown table and
writes it to ``bench/results/refined_check.md``.

Each stance is solved on its scenario's default meshes, then
``stances.check_refined(factor=2)`` meshes every soft object with half the spacing
(in plane and in depth, about 6-8x the nodes) and solves the stance there from the
answer's posture and contact variables. The table says how far the default-mesh
answer is from holding on the finer meshes (its most violated row, in that row's
units), whether the re-solve is feasible and verified, its iterations, how far the
posture moves and how much each soft print's force changes: what an independent
computation on a twice finer mesh says of the library's answer. CPU seconds with
one BLAS thread; "check s" includes meshing and factorising the refined bodies.
"""

from __future__ import annotations

import os
import sys
import time

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
# Refined bodies are measured from scratch, not read from a cache of an earlier run.
os.environ["SOFTCBM_CACHE"] = "off"

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import write_report  # noqa: E402
from bench_deformable import STANCES  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402

RESULT = os.path.join(os.path.dirname(__file__), "results", "refined_check.md")


def row(robot, name, stance_name) -> str:
    scenario = environments.load(name)
    result = stances.solve(robot, scenario.scene, scenario.stance(stance_name))
    if not result.feasible:
        return f"| {name}/{stance_name} | default answer infeasible: {result.reason} |" + " |" * 7
    tic = time.process_time()
    check = stances.check_refined(robot, scenario, result)
    seconds = time.process_time() - tic
    nodes = ", ".join(f"{n} {a:,} -> {b:,}" for n, a, b in check.nodes)
    solved = check.result
    verdict = "yes" if check.ok else f"no: {solved.reason[:160]}"
    forces = "; ".join(
        f"{surface} {np.linalg.norm(coarse):.1f} -> {np.linalg.norm(fine):.1f}" for surface, coarse, fine in check.print_forces
    )
    return (
        f"| {name}/{stance_name} | {nodes} | {check.start_row}: {check.start_violation:.2g} | {verdict} | "
        f"{solved.iterations} | {check.joint_change:.2g} | {forces} | {100 * check.force_change:.1f} % | {seconds:.1f} |"
    )


def main() -> None:
    robot = stances.Robot.load("talos")
    header = (
        "| stance | soft nodes, default -> refined | default answer on the refined meshes: worst row, off by (m, rad, N) | "
        "re-solved feasible and verified | iterations | posture moved (rad or m) | soft print forces (N), default -> "
        "refined | largest force change / soft load | check s |\n|---|---|---|---|---|---|---|---|---|"
    )
    rows = []
    start = time.perf_counter()
    for name, stance_name in STANCES:
        rows.append(row(robot, name, stance_name))
        print(rows[-1], file=sys.stderr, flush=True)
    intro = (
        "Each built-in soft stance solved on its default meshes, then again on the same scenario with every soft "
        "mesh refined twice (`stances.check_refined`, factor 2), started from the default answer."
    )
    write_report(RESULT, "Soft stances on meshes refined twice", start, intro, [header, *rows])


if __name__ == "__main__":
    main()
