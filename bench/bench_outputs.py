"""A plan's output files: how long writing them takes, the pictures against matplotlib's own crop.

Run as ``.venv/bin/python bench/bench_outputs.py [--rounds 3]``; prints a markdown table and
writes it to ``bench/results/outputs.md``.

The default scenario is planned once; then ``cbm.output.write_outputs`` writes its files
(plan, .vtu meshes, viewer page, one PNG a stance) in rounds, three ways in turn:

- ``cbm``: as ``cbm plan`` does (each picture drawn once, :func:`cbm.render._save`);
- ``tight``: the baseline, each picture saved with matplotlib's ``bbox_inches="tight"``
  (the same crop, its layout pass drawing every triangle again), as before a315814;
- ``no pictures``: ``pictures=False`` (``cbm plan --no-pictures``).

CPU seconds (``time.process_time``, one BLAS thread), the least over the rounds beside each
round's figures. The pictures of ``cbm`` and ``tight`` are compared pixel by pixel.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import write_report  # noqa: E402

import stances  # noqa: E402
from cbm import render  # noqa: E402
from cbm.cli import DEFAULT_SCENARIO  # noqa: E402
from cbm.output import write_outputs  # noqa: E402
from cbm.planner import load_scenario, plan  # noqa: E402

RESULT = os.path.join(os.path.dirname(__file__), "results", "outputs.md")
ROUNDS = 3


def matplotlib_tight(figure, path, heavy):
    """The baseline picture: matplotlib's own tight crop (two draws)."""
    figure.savefig(path, bbox_inches="tight", pad_inches=0.15)


def timed(result, scenario, robot, folder, pictures=True):
    """CPU seconds of one ``write_outputs`` into ``folder``, and its files."""
    tic = time.process_time()
    files = write_outputs(result, scenario, robot, folder, pictures=pictures)
    return time.process_time() - tic, files


def main(rounds: int = ROUNDS) -> None:
    started = time.perf_counter()
    scenario = load_scenario(DEFAULT_SCENARIO)
    robot = stances.Robot.load(scenario.robot)
    result = plan(scenario, robot=robot)
    if not result.success:
        raise SystemExit(f"the default plan failed: {result.reason}")
    ours = render._save
    times = {"cbm": [], "tight": [], "no pictures": []}
    with tempfile.TemporaryDirectory() as folder:
        timed(result, scenario, robot, os.path.join(folder, "warm"))  # imports, mesh loading
        for index in range(rounds):
            seconds, mine = timed(result, scenario, robot, os.path.join(folder, f"cbm{index}"))
            times["cbm"].append(seconds)
            render._save = matplotlib_tight
            try:
                seconds, reference = timed(result, scenario, robot, os.path.join(folder, f"tight{index}"))
            finally:
                render._save = ours
            times["tight"].append(seconds)
            seconds, _ = timed(result, scenario, robot, os.path.join(folder, f"none{index}"), pictures=False)
            times["no pictures"].append(seconds)
            same = all(np.array_equal(plt.imread(a), plt.imread(b)) for a, b in zip(mine.pictures, reference.pictures))
            if not same:
                raise SystemExit("the pictures differ from matplotlib's tight crop: fix cbm.render._save")
    count = len(mine.pictures)
    lines = [
        "| round | `cbm` (s) | `tight` (s) | no pictures (s) | a picture, `cbm` (s) | a picture, `tight` (s) |",
        "|---|---|---|---|---|---|",
    ]
    for index in range(rounds):
        base = times["no pictures"][index]
        lines.append(
            f"| {index + 1} | {times['cbm'][index]:.2f} | {times['tight'][index]:.2f} | {base:.2f} | "
            f"{(times['cbm'][index] - base) / count:.2f} | {(times['tight'][index] - base) / count:.2f} |"
        )
    least = {name: min(values) for name, values in times.items()}
    lines += [
        "",
        f"Least over the rounds: `cbm` {least['cbm']:.2f} s, `tight` {least['tight']:.2f} s "
        f"(ratio {least['cbm'] / least['tight']:.2f}), without pictures {least['no pictures']:.2f} s; "
        f"the {count} pictures the same pixel for pixel in every round.",
    ]
    preamble = (
        f"`bench/bench_outputs.py`: `write_outputs` of the `{DEFAULT_SCENARIO}` plan ({len(result.stances)} stances, "
        f"{count} pictures; Talos drawn from its visual meshes), CPU seconds a round. `cbm`: as `cbm plan` "
        "writes them (each picture drawn once); `tight`: the same pictures saved with matplotlib's "
        "`bbox_inches=\"tight\"` (the baseline); no pictures: `--no-pictures`."
    )
    write_report(RESULT, "A plan's output files", started, preamble, lines)


if __name__ == "__main__":
    arguments = sys.argv[1:]
    main(int(arguments[arguments.index("--rounds") + 1]) if "--rounds" in arguments else ROUNDS)
