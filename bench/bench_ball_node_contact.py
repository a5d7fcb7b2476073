"""Does the number of nodes a ball presses say its node contact's force is converged?

Run as ``.venv/bin/python bench/bench_ball_node_contact.py``; prints a markdown table and
writes it to ``bench/results/ball_node_contact.md``.

Where a soft body is no layer under a ball foot, no continuum estimate of the ball's force
exists and the ball presses mesh nodes (``stances.deformable``). Until 2026-12-05 (session l)
such a ball was accepted once it pressed 9 nodes or more (``RESOLVED_BALL_NODES``), from 5 mm
cells under balls 1-2.5 mm deep that came within 2.3 % of a 2.5 mm mesh. This bench asks the
question on a body where the answer is known: ANYmal's ball (radius 31 mm) pressed 1-4 mm
straight down into the study's 0.2 x 0.2 x 0.05 m foam block (E = 1e6 Pa, nu = 0.4, base
fixed, friction 0.7 at the nodes), a layer, whose converged force is the continuum's law
(``fem.sphere_on_layer_force``, frictionless; within 0.5 % of independent converged FEMs,
friction adds 0.2-0.8 %; the block's sides 2 thicknesses away move it by under 0.3 %). The
meshes: the soft box's own grading with its fine cells within 30 mm of the ball (h = 10, 5
and 3.75 mm: every cell halves with h, in depth too) and ``refine_lines`` bands through the
ball (5 mm cells 15 and 30 mm either side, 2.5 mm cells 15 mm either side; the top layer the
bands' cell, the layers under it growing by 1.5). The ball stands on a node, off it by
(0.25, 0.1), (0.5, 0.5) and (0.5, 0) of the pitch.
"""

from __future__ import annotations

import os
import sys
import time

# One BLAS thread, set before numpy loads (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))

from benchmark_info import write_report  # noqa: E402
from bench_ball_foot import BLOCK, continuum  # noqa: E402 (the study's block and its continuum force)
from test_ball_contact import FOAM, RADIUS, ball_force, top_nodes_near  # noqa: E402

import fem  # noqa: E402
from environments.deformable import RefineLines, soft_box_coordinates  # noqa: E402

DEPTHS = (0.001, 0.0015, 0.0025, 0.004)  # m
OFFSETS = ((0.0, 0.0), (0.25, 0.1), (0.5, 0.5), (0.5, 0.0))  # pitches, along x and y
# m: the top nodes a ball may touch (its gap at the deepest depth, 1.5 times over, plus a cell).
REACH = float(np.sqrt(2 * RADIUS * 1.5 * max(DEPTHS))) + 0.01
AROUND = [[-0.03, -0.03], [0.03, 0.03]]  # m, the fine square of the graded meshes
MESHES = (
    ("graded, h = 10 mm within 30 mm", dict(resolution=0.010, refine=AROUND)),
    ("graded, h = 5 mm within 30 mm", dict(resolution=0.005, refine=AROUND)),
    ("graded, h = 3.75 mm within 30 mm", dict(resolution=0.00375, refine=AROUND)),
    ("5 mm bands, 15 mm either side", dict(resolution=0.010, refine_lines=RefineLines((0.0,), (0.0,), 0.015, 0.005))),
    ("5 mm bands, 30 mm either side", dict(resolution=0.010, refine_lines=RefineLines((0.0,), (0.0,), 0.030, 0.005))),
    ("2.5 mm bands, 15 mm either side", dict(resolution=0.010, refine_lines=RefineLines((0.0,), (0.0,), 0.015, 0.0025))),
)


def main() -> None:
    started = time.perf_counter()
    lines = [
        "| mesh | nodes | pitch under the ball (mm) | ball | depth (mm) | pressed nodes | force (N) | continuum (N) | error |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    errors = []  # (pressed nodes, error)
    for name, keywords in MESHES:
        mesh = fem.tensor_mesh(*soft_box_coordinates(BLOCK, **keywords))
        body = fem.DeformableBody(mesh, FOAM, np.flatnonzero(mesh.nodes[:, 2] < 1e-12), cache=False)
        pitch = float(np.min(np.diff(np.unique(mesh.nodes[:, 0].round(12)))))
        for offset in OFFSETS:
            centre = pitch * np.asarray(offset)
            ids = top_nodes_near(body, centre, REACH)
            known = (ids, body.compliance(ids))
            where = "on a node" if offset == (0.0, 0.0) else f"off by ({offset[0]:g}, {offset[1]:g})"
            for depth in DEPTHS:
                force, pressed, _ = ball_force(body, centre, depth, reach=REACH, known=known)
                error = force / continuum(depth) - 1.0
                errors.append((pressed.size, error))
                lines.append(f"| {name} | {mesh.n_nodes} | {1e3 * pitch:.2f} | {where} | {1e3 * depth:g} | {pressed.size} "
                             f"| {force:.2f} | {continuum(depth):.2f} | {error:+.1%} |")
        print(name, flush=True)
    counts, values = np.array([e[0] for e in errors]), np.array([e[1] for e in errors])
    summary = []
    for low, high in ((1, 8), (9, 15), (16, 30), (31, 100)):
        chosen = values[(counts >= low) & (counts <= high)]
        if chosen.size:
            summary.append(f"- {low}-{high} pressed nodes: {chosen.size} cases, error {chosen.min():+.1%} to "
                           f"{chosen.max():+.1%}, {np.count_nonzero(np.abs(chosen) > 0.05)} beyond 5 %")
    preamble = __doc__.split("\n\n")[2] + "\n\nBy pressed nodes:\n\n" + "\n".join(summary)
    write_report(os.path.join(os.path.dirname(__file__), "results", "ball_node_contact.md"),
                 "A ball's node contact against the continuum, by pressed nodes", started, preamble, lines)


if __name__ == "__main__":
    main()
