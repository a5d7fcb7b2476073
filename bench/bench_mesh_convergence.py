"""Mesh convergence of a rigid print's force on soft boxes, and the cost of the scenes' meshes.

Run as ``.venv/bin/python bench/bench_mesh_convergence.py [--max-nodes N]``; prints
markdown tables and writes them to ``bench/results/mesh_convergence.md``.

Study (fem only, no robot): a rigid rectangular print pressed 5 mm straight down (the
same displacement on every print node) into a soft box meshed by
``environments.deformable.soft_box_coordinates`` at the default spacing h and at
h / 2, h / 4 where the mesh has at most ``--max-nodes`` nodes (a direct factorisation
of 270k nodes took 17 GB here). Prints and refined regions lie on a lattice of pitch
h, so that the meshes are nested in the refined region and every mesh's print covers
the same rectangle (see tests/test_mesh_convergence.py): palm 5 x 3 pitches
(0.1125 x 0.0675 m), sole 9 x 5 (0.2025 x 0.1125 m). The force comes from one
Dirichlet solve, equal to ``ContactPatch.reaction_forces`` (tested).

Richardson extrapolation: from three meshes, the observed order p = log2((F_h - F_h/2)
/ (F_h/2 - F_h/4)) and F_0 = F_h/4 - (F_h/2 - F_h/4) / (2^p - 1); from two, the order
observed on the three-mesh cases is assumed. "default error" is F_h / F_0 - 1.

Second table: the same prints placed off the lattice (rotated 30 degrees, shifted by
0, 1/6, ..., 5/6 of a pitch), at h and h / 2 where the mesh has at most
``--placement-max-nodes`` nodes: the mean, spread and error of the force against the
first table's extrapolated limit of the same rectangle. The lattice-aligned print of
the first table is the worst placement: its edges lie on node rows, which all enter the
print.

Third table: the covered prints the posture solver uses (every node whose shape function
the polygon covers, coupled by the covered share), aligned and placed, at h and h / 2.

Fourth table: each built-in scenario's soft boxes at their own resolution, with the
time to factorise K_NN and to build a palm print's condensed stiffness (3 solves per
print node) at the top centre, which is what a new print costs the planner.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import sys
import time

# One BLAS thread, set before numpy loads: threaded OpenBLAS spins on the cores other
# processes hold on this shared 2-core machine (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))

from benchmark_info import code_version, machine  # noqa: E402
from test_mesh_convergence import (  # noqa: E402
    CUBE_PALM,
    CUBE_SOLE,
    DEFAULT,
    MAT_PALM,
    MAT_SOLE,
    PLACEMENT_ANGLE,
    PLACEMENT_OFFSETS,
    TARGET,
    covered_print_force,
    indentation_force,
    richardson,
    richardson_two,
)

import environments  # noqa: E402
import fem  # noqa: E402

STUDIES = (MAT_SOLE, MAT_PALM, CUBE_PALM, CUBE_SOLE)
LEVELS = (0, 1, 2)
PALM_HALF = (0.05, 0.035)  # metres, the Talos palm


def study_rows(study, max_nodes: int, log) -> dict:
    """Forces of one study at each level that fits, and its depth-only refinement."""
    forces, rows = [], []
    for level in LEVELS:
        xs, ys, zs = study.coordinates(level)
        nodes = xs.size * ys.size * zs.size
        if nodes > max_nodes:
            log(f"{study.body} {study.print_name} h/{2**level}: {nodes} nodes > --max-nodes, skipped")
            break
        start = time.perf_counter()
        force, print_nodes = indentation_force(study.body_at(level), study.polygon_in_body)
        seconds = time.perf_counter() - start
        if print_nodes != study.expected_print_nodes(level):
            raise RuntimeError(f"{study.print_name} is not on grid lines at level {level}: {print_nodes} nodes")
        forces.append(force)
        rows.append({"level": level, "nodes": nodes, "grid": (xs.size, ys.size, zs.size), "print_nodes": print_nodes,
                     "force": force, "seconds": seconds})
        log(f"{study.body} {study.print_name} h/{2**level}: {nodes} nodes, {force:.1f} N, {seconds:.1f} s")
    depth_only = indentation_force(study.body_at(0, depth_level=1), study.polygon_in_body)[0]
    return {"study": study, "rows": rows, "forces": forces, "depth_only": depth_only}


def convergence_table(results) -> tuple[str, float]:
    """Markdown table of every study, and the order assumed where only two meshes fit."""
    orders = [richardson(r["forces"])[0] for r in results if len(r["forces"]) >= 3]
    assumed = float(np.mean(orders)) if orders else 1.0
    header = ("| body | print | resolution h (m) | grid | nodes | print nodes | force (N) | change from previous | "
              "order p | Richardson estimate (N) | default error | time (s) |")
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for result in results:
        study, rows, forces = result["study"], result["rows"], result["forces"]
        if len(forces) >= 3:
            order, limit = richardson(forces[:3])
            order_text = f"{order:.2f}"
        elif len(forces) < 2:
            order, limit, order_text = math.nan, math.nan, "(one mesh)"
        else:
            order, limit = assumed, richardson_two(forces[:2], assumed)
            order_text = f"{assumed:.2f} (assumed)"
        for row, previous in zip(rows, [None] + forces):
            change = "" if previous is None else f"{row['force'] / previous - 1:+.1%}"
            first = row["level"] == 0
            lines.append(
                f"| {study.body} | {study.print_name} | {DEFAULT / 2 ** row['level']:.5g} | "
                f"{'x'.join(map(str, row['grid']))} | {row['nodes']} | {row['print_nodes']} | {row['force']:.1f} | "
                f"{change} | {order_text if first else ''} | {f'{limit:.1f}' if first else ''} | "
                f"{f'{forces[0] / limit - 1:+.1%}' if first else ''} | {row['seconds']:.1f} |"
            )
        lines.append(
            f"| {study.body} | {study.print_name} | {DEFAULT:.5g}, layers at h/2 | | | | {result['depth_only']:.1f} | "
            f"{result['depth_only'] / forces[0] - 1:+.1%} (depth only) | | | | |"
        )
    return "\n".join(lines), assumed


def _limit(forces, assumed: float) -> float:
    """The aligned print's extrapolated force: from three meshes, or two with the assumed order."""
    return richardson(forces[:3])[1] if len(forces) >= 3 else richardson_two(forces[:2], assumed)


def _bodies_that_fit(study, max_nodes: int):
    """``(level, body)`` at h and h / 2, while the mesh has at most ``max_nodes`` nodes."""
    for level in LEVELS[:2]:
        xs, ys, zs = study.coordinates(level)
        if xs.size * ys.size * zs.size > max_nodes:
            return
        yield level, study.body_at(level)


def placement_table(results, assumed: float, max_nodes: int, log) -> str:
    """Markdown table of the placed prints' forces at each level that fits, against the limit."""
    header = ("| body | print | resolution h (m) | nodes | print nodes | mean force (N) | min - max (N) | scatter | "
              "mean change from previous | mean vs limit | aligned vs limit |")
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for result in results:
        study, forces = result["study"], result["forces"]
        limit = _limit(forces, assumed)
        previous = None
        for level, body in _bodies_that_fit(study, max_nodes):
            placed = [indentation_force(body, study.placed_polygon(o, PLACEMENT_ANGLE)) for o in PLACEMENT_OFFSETS]
            values = np.array([force for force, _ in placed])
            counts = [nodes for _, nodes in placed]
            mean = values.mean()
            change = "" if previous is None else f"{mean / previous - 1:+.1%}"
            aligned = f"{forces[level] / limit - 1:+.1%}" if level < len(forces) else ""
            lines.append(
                f"| {study.body} | {study.print_name} | {DEFAULT / 2 ** level:.5g} | {body.mesh.n_nodes} | "
                f"{min(counts)}-{max(counts)} | {mean:.1f} | {values.min():.1f} - {values.max():.1f} | "
                f"{np.ptp(values) / mean:.1%} | {change} | {mean / limit - 1:+.1%} | {aligned} |"
            )
            log(f"{study.body} {study.print_name} placed, h/{2**level}: mean {mean:.1f} N, limit {limit:.1f} N")
            previous = mean
    return "\n".join(lines)


def covered_table(results, assumed: float, max_nodes: int, log) -> str:
    """Markdown table of the covered prints (the consistent model's, fem.print_coverage):
    the aligned rectangle and the six placements, at each level that fits."""
    header = ("| body | print | resolution h (m) | nodes | print nodes | aligned (N) | placed, min - max (N) | "
              "scatter (all 7) | largest change from previous, print by print | aligned vs limit | placed mean vs limit |")
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for result in results:
        study, forces = result["study"], result["forces"]
        limit = _limit(forces, assumed)
        polygons = [study.polygon_in_body] + [study.placed_polygon(o, PLACEMENT_ANGLE) for o in PLACEMENT_OFFSETS]
        previous = None
        for level, body in _bodies_that_fit(study, max_nodes):
            values = np.array([covered_print_force(body, polygon) for polygon in polygons])
            counts = [fem.print_coverage(body.mesh, polygon)[0].size for polygon in polygons]
            change = "" if previous is None else f"{np.abs(values / previous - 1).max():.1%}"
            lines.append(
                f"| {study.body} | {study.print_name} | {DEFAULT / 2 ** level:.5g} | {body.mesh.n_nodes} | "
                f"{min(counts)}-{max(counts)} | {values[0]:.1f} | {values[1:].min():.1f} - {values[1:].max():.1f} | "
                f"{np.ptp(values) / values.mean():.1%} | {change} | {values[0] / limit - 1:+.1%} | "
                f"{values[1:].mean() / limit - 1:+.1%} |"
            )
            log(f"{study.body} {study.print_name} covered, h/{2**level}: {values.round(1)} N, limit {limit:.1f} N")
            previous = values
    return "\n".join(lines)


def scenario_table(log) -> str:
    """Node counts and factorisation / new-print times of every built-in scenario's soft boxes."""
    lines = [
        "| scenario | object | size (m) | grid | nodes | factorise K_NN (s) | palm print nodes | new palm print (s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in environments.scenario_names():
        scenario = environments.load(name)
        for obj in scenario.scene.deformable_objects:
            body, mesh = obj.body, obj.mesh
            grid = [np.unique(mesh.nodes[:, axis]).size for axis in range(3)]
            size = np.ptp(mesh.nodes, axis=0)
            body.stiffness  # noqa: B018 - assemble first: time the factorisation alone
            start = time.perf_counter()
            body.factorization  # noqa: B018 - computed on first use, with the body's ordering
            factor_seconds = time.perf_counter() - start
            top = size[2]
            on_top = mesh.nodes[:, 2] == top
            centre = mesh.nodes[on_top, :2].mean(axis=0)
            hx, hy = PALM_HALF
            polygon = [[centre[0] + sx * hx, centre[1] + sy * hy, top] for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            ids = fem.nodes_in_polygon(mesh, polygon)
            start = time.perf_counter()
            try:
                body.contact_patch(ids).condensed_stiffness  # noqa: B018
                print_seconds = f"{time.perf_counter() - start:.2f}"
            except fem.PrintError:  # a deliberately coarse mesh (the paper's): too few nodes under a palm
                print_seconds = "(under 3 nodes)"
            lines.append(
                f"| {name} | {obj.name} | {' x '.join(f'{s:g}' for s in size)} | {'x'.join(map(str, grid))} | "
                f"{mesh.n_nodes} | {factor_seconds:.2f} | {ids.size} | {print_seconds} |"
            )
            log(f"{name} {obj.name}: {mesh.n_nodes} nodes, factor {factor_seconds:.2f} s")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--max-nodes", type=int, default=150_000, help="skip meshes with more nodes (memory)")
    parser.add_argument("--placement-max-nodes", type=int, default=20_000,
                        help="placed prints (6 solves per mesh) only on meshes up to this many nodes")
    parser.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "mesh_convergence.md"))
    args = parser.parse_args(argv)

    def log(message):
        print(message, file=sys.stderr, flush=True)

    start = time.perf_counter()
    results = [study_rows(study, args.max_nodes, log) for study in STUDIES]
    table, assumed = convergence_table(results)
    placements = placement_table(results, assumed, args.placement_max_nodes, log)
    covered = covered_table(results, assumed, args.placement_max_nodes, log)
    scenarios = scenario_table(log)
    total = time.perf_counter() - start
    text = f"""# Mesh convergence of a print's force on soft boxes

{datetime.date.today()}, {code_version()}; {machine()}. Total run time {total:.0f} s.

A rigid print pressed 5 mm straight down, base of the box fixed, nu = 0.4; meshes from
`soft_box_coordinates` at h = {DEFAULT} m (the default) and h / 2, h / 4 when at most
{args.max_nodes} nodes. Prints and refined regions on a lattice of pitch h so that all
meshes' prints cover the same rectangle: palm 5 x 3 pitches (0.1125 x 0.0675 m), sole
9 x 5 (0.2025 x 0.1125 m); refined margins around the print 4 pitches (cube) or 1-4
(mat). Order p and Richardson estimate from three meshes where they fit, else with
the order assumed from the three-mesh cases (mean {assumed:.2f}). "depth only": the
default in-plane grid with the layers of h / 2. Target of the issue: change from h to
h / 2 below {TARGET:.0%}.

{table}

## Prints placed off the lattice

The same rectangles rotated by {PLACEMENT_ANGLE:g} degrees about their centre and shifted
by {', '.join(f'{o:.3g}' for o in PLACEMENT_OFFSETS)} pitches along x (half that along y),
on meshes of at most {args.placement_max_nodes} nodes. "limit": the extrapolated force of
the first table (the converged force of a rectangle does not depend on the lattice);
"scatter": (max - min) / mean over the placements; "aligned vs limit": the first table's
lattice-aligned print on the same mesh, the worst placement.

{placements}

## Covered prints (the posture solver's consistent model)

Every node whose shape function the print covers, coupled by the covered share w
through a series compliance `(1 - w) / w C_ii` (`fem.print_coverage`,
`fem.ContactPatch(coverage=...)`): the aligned rectangle and the same six placements.
"largest change from previous": max over the seven prints of |F_h/2 / F_h - 1|, the
issue's target print by print. Limits as above (those of the nodes-inside prints: the
same rectangle's continuum force).

{covered}

## Built-in scenarios' soft boxes at their own resolution

Factorisation: `DeformableBody.factorization` (CHOLMOD, nested-dissection ordering); a new
palm print (0.10 x 0.07 m at the top centre) costs 3 solves per print node.

{scenarios}
"""
    print(text)
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    main()
