"""Benchmark: a print's force on the default mesh against independent converged references.

Run as ``.venv/bin/python bench/bench_print_coupling.py [--factors 2]``; prints a markdown
table and writes it to ``bench/results/print_coupling.md``.

Issue 8.2 asks that a print's force, for a fixed imposed motion, lie within 5 % of a
converged mesh's. ``bench/references/print_forces.json`` holds such converged forces, from
independent finite elements (Q2 hexahedra with lines on the print's edges, refined to
150k-300k dofs, Richardson), each for a print's solved motion in a stance. Here the
library's own print model answers for the same motion: the nodes whose surface cell the
print's polygon covers (``fem.print_coverage``), coupled by their covered fraction
(``fem.ContactPatch``), Coulomb contact at every node (``fem.solve_print_contact``), on the
body's default mesh (the scenario's, or ``soft_box_coordinates``'s for a box), and on
meshes ``factor`` times finer in every direction (``environments.refined``). The baseline
is the reference itself; the columns give the library's normal force, its sideways force's
magnitude, and the frictionless normal force (the same nodes, mu = 0), each against its
reference.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

# One BLAS thread, set before numpy loads (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import write_report  # noqa: E402

import environments  # noqa: E402
import fem  # noqa: E402
from environments.deformable import RESOLUTIONS, soft_box_coordinates  # noqa: E402

REFERENCES = os.path.join(os.path.dirname(__file__), "references", "print_forces.json")
OUT = os.path.join(os.path.dirname(__file__), "results", "print_coupling.md")


def case_body(case: dict, factor: int = 1):
    """The case's soft body at ``factor`` times the default mesh's resolution: a
    ``fem.DeformableBody`` (body frame: the top face's normal +z) and its top face's height."""
    spec = case["body"]
    if "box" in spec:
        size = np.asarray(spec["box"], dtype=float)
        material = fem.LinearElasticMaterial(case["young_modulus"], case["poisson_ratio"], 0.0)
        mesh = fem.tensor_mesh(*soft_box_coordinates(size, RESOLUTIONS["default"] / factor))
        body = fem.DeformableBody(mesh, material, np.flatnonzero(np.asarray(mesh.nodes)[:, 2] <= 1e-9 * size[2]))
        return body, float(size[2])
    scenario = environments.load(spec["scenario"])
    if factor > 1:
        scenario = environments.refined(scenario, factor)
    body = next(o.body for o in scenario.scene.deformable_objects if o.name == spec["object"])
    if (body.material.young_modulus, body.material.poisson_ratio) != (case["young_modulus"], case["poisson_ratio"]):
        raise RuntimeError(f"{spec['scenario']}: {spec['object']}'s material is no longer the reference's; "
                           "update bench/references/print_forces.json")
    return body, float(np.asarray(body.mesh.nodes)[:, 2].max())


def print_forces(body, top: float, polygon, motion, friction: float) -> tuple:
    """The library's print model for the case's motion: (total force with ``friction``, with
    none), each (3,) newtons on the robot, body frame; and the number of print nodes."""
    polygon = np.asarray(polygon, dtype=float)
    ids, coverage = fem.print_coverage(body.mesh, np.c_[polygon, np.full(len(polygon), top)])
    patch = body.contact_patch(ids, coverage)
    points = np.asarray(body.mesh.nodes)[ids]
    imposed = np.c_[points[:, :2], np.ones(len(ids))] @ np.asarray(motion, dtype=float)
    frames = np.tile(np.eye(3), (len(ids), 1, 1))
    totals = [np.asarray(fem.solve_print_contact(patch.link_compliance, imposed, frames,
                                                 np.full(len(ids), mu)).forces).sum(axis=0)
              for mu in (friction, 0.0)]
    return totals[0], totals[1], len(ids)


def percent(value: float, reference: float) -> str:
    return f"{100.0 * (value / reference - 1.0):+.1f} %"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--factors", default="2", help="comma-separated refinement factors besides the default mesh")
    parser.add_argument("--out", default=OUT)
    args = parser.parse_args()
    factors = [1] + [int(f) for f in args.factors.split(",") if f]
    started = time.perf_counter()
    with open(REFERENCES) as handle:
        cases = json.load(handle)["cases"]
    lines = [
        "| print | mesh | nodes | print nodes | normal (N) | vs reference | sideways (N) | vs reference "
        "| frictionless normal vs reference | reference (N) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    worst = 0.0
    for case in cases:
        reference = np.asarray(case["coulomb"])
        sideways_reference = float(np.hypot(*reference[:2]))
        for factor in factors:
            body, top = case_body(case, factor)
            coulomb, frictionless, nodes = print_forces(body, top, case["polygon"], case["motion"], case["friction"])
            sideways = float(np.hypot(*coulomb[:2]))
            if factor == 1:
                worst = max(worst, abs(coulomb[2] / reference[2] - 1.0))
            lines.append(
                f"| {case['name']} | {'default' if factor == 1 else f'h / {factor}'} | {body.mesh.n_nodes} | {nodes} "
                f"| {coulomb[2]:.2f} | {percent(coulomb[2], reference[2])} | {sideways:.2f} "
                f"| {percent(sideways, sideways_reference)} | {percent(frictionless[2], case['frictionless_normal'])} "
                f"| {reference[2]:.2f} +- {case['coulomb_error'][2]:.2f}; {sideways_reference:.2f} |"
            )
    preamble = (__doc__.split("\n\n", 2)[2].strip() + "\n\n"
                f"Largest normal force error on the default meshes: {100.0 * worst:.1f} % (issue 8.2: 5 %).\n\n"
                "Sources of the references: " + "; ".join(f"{c['name']}: {c['source']}" for c in cases) + ".")
    write_report(args.out, "A print's force against converged references", started, preamble, lines)


if __name__ == "__main__":
    main()
