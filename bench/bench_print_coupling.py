"""Benchmark: a print's force on the default mesh against independent converged references.

Run as ``.venv/bin/python bench/bench_print_coupling.py [--factors 2]``; prints a markdown
table and writes it to ``bench/results/print_coupling.md``.

Issue 8.2 asks that a print's force, for a fixed imposed motion, lie within 5 % of a
converged mesh's. ``bench/references/print_forces.json`` holds such converged forces, from
independent finite elements (Q2 hexahedra with lines on the print's edges, refined to
150k-300k dofs, Richardson), each for a print's solved motion in a stance: four palms
(sessions o and p) and eight soles (session t). Here the
library's own print model answers for the same motions (a body's prints pressed at
once): the nodes whose shape function the print's polygon covers (``fem.print_coverage``), coupled by their covered share
(``fem.ContactPatch``), Coulomb contact at every node (``fem.solve_print_contact``), on the
body's default mesh (the scenario's, or ``soft_box_coordinates``'s for a box), and on
meshes ``factor`` times finer in every direction (``environments.refined``). The baseline
is the reference itself; the columns give the library's normal force, its sideways force's
magnitude (each against its reference), the sideways force's vector error as a share of
the normal force (a sole's net sideways force is the small remainder of its nodes' shear
forces, 1.5-3.5 % of its load), and the frictionless normal force (the same nodes, mu = 0)
against its reference.
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

sys.path[:0] = [os.path.join(os.path.dirname(__file__), ".."), os.path.dirname(os.path.abspath(__file__))]

from benchmark_info import write_report  # noqa: E402

import environments  # noqa: E402
import fem  # noqa: E402
from environments.deformable import RESOLUTIONS, soft_box_coordinates  # noqa: E402

REFERENCES = os.path.join(os.path.dirname(__file__), "references", "print_forces.json")
OUT = os.path.join(os.path.dirname(__file__), "results", "print_coupling.md")


def case_body(case: dict, factor: int = 1):
    """The case's soft body at ``factor`` times the default mesh's resolution, a
    ``fem.DeformableBody`` (body frame: the top faces' normal +z)."""
    spec = case["body"]
    if "box" in spec:
        size = np.asarray(spec["box"], dtype=float)
        material = fem.LinearElasticMaterial(case["young_modulus"], case["poisson_ratio"], 0.0)
        mesh = fem.tensor_mesh(*soft_box_coordinates(size, RESOLUTIONS["default"] / factor))
        return fem.DeformableBody(mesh, material, np.flatnonzero(np.asarray(mesh.nodes)[:, 2] <= 1e-9 * size[2]))
    scenario = environments.load(spec["scenario"])
    if factor > 1:
        scenario = environments.refined(scenario, factor)
    body = next(o.body for o in scenario.scene.deformable_objects if o.name == spec["object"])
    if (body.material.young_modulus, body.material.poisson_ratio) != (case["young_modulus"], case["poisson_ratio"]):
        raise RuntimeError(f"{spec['scenario']}: {spec['object']}'s material is no longer the reference's; "
                           "update bench/references/print_forces.json")
    return body


def print_forces(body, prints, friction: float) -> tuple:
    """The library's print model for the prints' motions, all pressed at once: each print's
    total force with ``friction`` and with none, (k, 3) newtons on the robot, body frame;
    and each print's number of nodes."""
    covered = [fem.print_coverage(body.mesh, np.c_[np.asarray(p["polygon"]), np.full(len(p["polygon"]), p["top"])])
               for p in prints]
    for k in range(len(covered)):  # nodes two prints share go to one, as in stances.DeformableContact
        for j in range(k):
            keep, other_keep = fem.split_shared_nodes(*covered[k], *covered[j])
            covered[k], covered[j] = tuple(a[keep] for a in covered[k]), tuple(a[other_keep] for a in covered[j])
    ids = np.concatenate([i for i, _ in covered])
    patch = body.contact_patch(ids, np.concatenate([c for _, c in covered]))
    owner = np.repeat(np.arange(len(prints)), [len(i) for i, _ in covered])
    points = np.asarray(body.mesh.nodes)[ids]
    imposed = np.concatenate([np.c_[points[owner == k, :2], np.ones(np.sum(owner == k))] @ np.asarray(p["motion"])
                              for k, p in enumerate(prints)])
    frames = np.tile(np.eye(3), (len(ids), 1, 1))
    totals = []
    for mu in (friction, 0.0):
        forces = np.asarray(fem.solve_print_contact(patch.link_compliance, imposed, frames, np.full(len(ids), mu)).forces)
        totals.append(np.array([forces[owner == k].sum(axis=0) for k in range(len(prints))]))
    return totals[0], totals[1], [len(i) for i, _ in covered]


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
        "| case | print | mesh | nodes | print nodes | normal (N) | vs reference | sideways (N) | vs reference "
        "| sideways off, of the normal | frictionless normal vs reference | reference: normal, sideways (N) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    worst = {}  # (kind, factor) -> largest |normal error|
    for case in cases:
        for factor in factors:
            body = case_body(case, factor)
            coulomb, frictionless, nodes = print_forces(body, case["prints"], case["friction"])
            for k, p in enumerate(case["prints"]):
                reference = np.asarray(p["coulomb"])
                sideways, sideways_reference = float(np.hypot(*coulomb[k, :2])), float(np.hypot(*reference[:2]))
                kind = "palms" if "palm" in p["link"] else "soles"
                worst[kind, factor] = max(worst.get((kind, factor), 0.0), abs(coulomb[k, 2] / reference[2] - 1.0))
                lines.append(
                    f"| {case['name']} | {p['link']} | {'default' if factor == 1 else f'h / {factor}'} "
                    f"| {body.mesh.n_nodes} | {nodes[k]} | {coulomb[k, 2]:.2f} | {percent(coulomb[k, 2], reference[2])} "
                    f"| {sideways:.2f} | {percent(sideways, sideways_reference)} "
                    f"| {100.0 * np.linalg.norm(coulomb[k, :2] - reference[:2]) / reference[2]:.1f} % "
                    f"| {percent(frictionless[k, 2], p['frictionless_normal'])} "
                    f"| {reference[2]:.2f} +- {p['coulomb_error'][2]:.2f}, {sideways_reference:.2f} |"
                )
    largest = "; ".join(f"{kind} {'default' if factor == 1 else f'h / {factor}'} {100.0 * value:.1f} %"
                        for (kind, factor), value in sorted(worst.items(), key=lambda item: (item[0][1], item[0][0])))
    preamble = (__doc__.split("\n\n", 2)[2].strip() + "\n\n"
                f"Largest normal force error (issue 8.2: 5 %): {largest}.\n\n"
                "Sources of the references: " + "; ".join(f"{c['name']}: {c['source']}" for c in cases) + ".")
    write_report(args.out, "A print's force against converged references", started, preamble, lines)


if __name__ == "__main__":
    main()
