"""Mesh convergence of a ball foot's force on foam: Hertz's contact on the mesh.

Run as ``.venv/bin/python bench/bench_ball_foot.py``; prints a markdown table and writes it
to ``bench/results/ball_foot.md``.

ANYmal's ball foot (radius 31 mm) pressed straight down into quadruped-foam's foam (its
material: E = 1e6 Pa until 2026-12-03, 3e6 Pa since, and at a fixed depth every force
scales with E; nu = 0.4, 50 mm thick, base fixed, friction 0.7) by a fixed depth: 2.5 mm (quadruped-foam's
planned stances press it 2.4-3.9 mm deep) and 1 mm. The print's nodes lie the
ball's profile below it (``stances.deformable.ball_gaps``) and the Signorini-Coulomb contact
is solved on their condensed compliance, as the posture solver does. The study's block is
0.2 x 0.2 m (the scene's foam is 0.4 x 1.0 m; a first row compares the two at the default
spacing) meshed by ``soft_box_coordinates`` at the scene's spacing h = 10 mm within 30 mm
of the ball and at h / 2 and h / 4 (the meshes nest there). The ball stands on a node
("on a node") or a quarter and half a pitch of h off it; the converged force does not depend
on where it stands.

Richardson from the three meshes of the ball on a node: order p = log2((F_h - F_h/2) /
(F_h/2 - F_h/4)) and limit F_0 = F_h/4 - (F_h/2 - F_h/4) / (2^p - 1). "error" is each
force's against F_0, or against the finest mesh's force on a node where the three are
not monotone (p undefined). Hertz's half-space force and the flat punch of the ball's radius (every
node under the ball following it, the model of point feet until 2026-12-03) at the
default spacing are given for scale. "CPU for the mesh": meshing, factorising and both depths' solves.
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
from test_ball_contact import FOAM, RADIUS, ball_body, ball_force, hertz_force, top_nodes_near  # noqa: E402
from test_mesh_convergence import richardson  # noqa: E402

import environments  # noqa: E402
import fem  # noqa: E402

SPACING = 0.010  # m, quadruped-foam's resolution
BLOCK = (0.2, 0.2, 0.05)  # m
MARGIN = 0.03  # m, the refined square's half side around the ball
DEPTHS = (0.0025, 0.001)  # m
OFFSETS = ((0.0, 0.0), (0.25, 0.1), (0.5, 0.5))  # pitches of h, along x and y
LEVELS = (1, 2, 4)
# m: the nodes a ball may touch at the deepest depth (gap at most 1.5 times it); a mesh's
# pitch is added, and a pressed node past that would stop the run.
REACH = float(np.sqrt(2 * 0.031 * 1.5 * max(DEPTHS)))


def scene_row(body, depth: float) -> list:
    """The ball on the scene's own foam ``body`` (its full size and refined region) at h, on a
    node; its force also at the block's E (at a fixed depth every force scales with E)."""
    # A node of the refined region near the front prints' (-0.1, 0.2) of the top frame
    # (body frame: centred, base at z = 0).
    near = top_nodes_near(body, (-0.1, 0.2), SPACING)
    node = near[np.argmin(np.linalg.norm(body.mesh.nodes[near, :2] - [-0.1, 0.2], axis=1))]
    force, pressed, _ = ball_force(body, body.mesh.nodes[node, :2], depth, reach=REACH + SPACING)
    scale = FOAM.young_modulus / body.material.young_modulus
    return [f"| scene's foam 0.4 x 1.0 m, E = {body.material.young_modulus:.3g} Pa | {1e3 * depth:g} | {1e3 * SPACING:g} | "
            f"on a node | {body.mesh.n_nodes} | {pressed.size} | {force:.2f} ({force * scale:.2f} at the block's E) | | "
            f"{force * scale / continuum(depth) - 1:+.1%} | |"]


def continuum(depth: float) -> float:
    """The continuum's force on the block's foam, a layer of its thickness on a rigid base,
    frictionless (fem.sphere_on_layer_force; friction 0.7 adds 0.2-0.8 % here)."""
    return fem.sphere_on_layer_force(depth, RADIUS, BLOCK[2], FOAM.young_modulus, FOAM.poisson_ratio)[0]


def main() -> None:
    started = time.perf_counter()
    lines = [
        "| body | depth (mm) | h (mm) | ball | nodes | pressed nodes | force (N) | error vs reference | vs the continuum | CPU for the mesh (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    notes = []
    forces = {}
    for level in LEVELS:
        tic = time.process_time()
        spacing = SPACING / level
        body = ball_body(BLOCK, spacing, (0.0, 0.0), MARGIN)
        reach = REACH + spacing
        # One compliance for every offset's nodes (a 63k-node mesh's columns take seconds each).
        union = np.unique(np.concatenate([top_nodes_near(body, SPACING * np.asarray(o), reach) for o in OFFSETS]))
        known = (union, body.compliance(union))
        for depth in DEPTHS:
            for offset in OFFSETS:
                centre = SPACING * np.asarray(offset)
                force, pressed, _ = ball_force(body, centre, depth, reach=reach, known=known)
                spread = np.linalg.norm(body.mesh.nodes[pressed, :2] - centre, axis=1).max()
                if spread > reach - spacing:  # a node that could touch was left out
                    raise RuntimeError(f"pressed nodes reach {spread:.4f} m, past the nodes kept ({reach:.4f} m)")
                forces[depth, level, offset] = (force, pressed.size, body.mesh.n_nodes)
        forces[level, "time"] = time.process_time() - tic
        if level == 1:
            default_body = body  # the flat punch's, below
        print(level, forces, flush=True)
    foam = environments.load("quadruped-foam").scene.deformable_of_surface("foam_top").body
    for depth in DEPTHS:
        lines += scene_row(foam, depth)
        order, limit = richardson([forces[depth, level, OFFSETS[0]][0] for level in LEVELS])
        reference = "Richardson limit"
        if not np.isfinite(limit):  # not monotone: the finest mesh's force on a node serves
            limit, reference = forces[depth, LEVELS[-1], OFFSETS[0]][0], f"h / {LEVELS[-1]} on a node (not monotone)"
        for level in LEVELS:
            for offset in OFFSETS:
                force, pressed, nodes = forces[depth, level, offset]
                where = "on a node" if offset == (0.0, 0.0) else f"off by ({offset[0]:g}, {offset[1]:g}) h"
                lines.append(
                    f"| block 0.2 x 0.2 m | {1e3 * depth:g} | {1e3 * SPACING / level:g} | {where} | {nodes} | {pressed} | "
                    f"{force:.2f} | {force / limit - 1:+.1%} | {force / continuum(depth) - 1:+.1%} | {forces[level, 'time']:.1f} |"
                )
        flat, _, _ = ball_force(default_body, (0.0, 0.0), depth, flat=True)
        notes.append(
            f"At {1e3 * depth:g} mm: order p = {order:.2f}, reference {limit:.2f} N ({reference}); Hertz's half-space "
            f"{hertz_force(depth):.2f} N (the 50 mm layer on its fixed base is stiffer); the flat punch at h = "
            f"{1e3 * SPACING:g} mm {flat:.1f} N ({flat / limit:.1f} times the limit); the continuum (a laterally infinite "
            f"layer, frictionless: fem.sphere_on_layer_force) {continuum(depth):.2f} N."
        )
    write_report(
        os.path.join(os.path.dirname(__file__), "results", "ball_foot.md"),
        "Mesh convergence of a ball foot's force on foam", started, "\n\n".join(__doc__.split("\n\n")[2:4] + notes), lines,
    )


if __name__ == "__main__":
    main()
