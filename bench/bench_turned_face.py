"""The soft prints' contact against the exact plane contact of the turned face (issue 8.3).

Run as ``.venv/bin/python bench/bench_turned_face.py``; prints a markdown table and writes it to
``bench/results/turned_face.md`` (about a minute).

Since 2026-12-06 the library solves each print node's Signorini-Coulomb contact in its print's
frame turned with the link's face (``contact_frames="turned"``, ``docs/turned-face.md``). Before,
it used the rest frame (``"rest"``): the gap and the cone about the rest normal, each node tied
to the link point that lay on it at rest; a node that slips by s past that point meets the face,
turned by t, s tan(t) away from where the rest-normal gap puts it. Here each answer's forces are
set against the exact plane contact of the turned face at the answer's posture (the same link
motion and compliance; node frames turned with the link, the surface's own mu,
:func:`fem.solve_print_contact`): what an independent check with the exact law would find off
in the stance's equilibrium.

Rows: the default (the turned frames), and as baselines the rest frames alone and with a 1 degree
tilt allowance (narrowed cones, the tilt bounded: session p's first answer).
"""

from __future__ import annotations

import datetime
import os
import sys

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import code_version, machine  # noqa: E402

import environments  # noqa: E402
import fem  # noqa: E402
import stances  # noqa: E402
from stances.problem import PostureOptions, build_problem  # noqa: E402

STANCES = (
    ("hand-on-coarse-cube", "hand-on-cube"), ("hand-on-soft-cube", "hand-on-soft-cube"), ("hand-on-cube", "hand-on-cube"),
    ("romeo-hand-on-soft-cube", "hand-on-soft-cube"), ("icub-hand-on-soft-cube", "hand-on-soft-cube"),
    ("climb-with-soft-support", "hand-on-cube"), ("climb-with-soft-support", "left-on-platform"),
    ("foot-and-hand-on-foam", "foot-and-hand"), ("step-on-cube", "step-on-cube"), ("cross-soft-block", "both-on-foam"),
)
VARIANTS = (("turned", {}), ("rest", {"contact_frames": "rest"}),
            ("rest, 1 deg allowance", {"contact_frames": "rest", "tilt_allowance": np.radians(1.0)}))


def print_rows(robot, scenario, stance, options):
    """Per soft flat print at the library's answer: (label, tilt rad, largest slip m, library
    resultant (3,), exact resultant (3,)), body frame, newtons."""
    result = stances.solve(robot, scenario.scene, stance, **options)
    if not result.feasible:
        return [(f"(infeasible: {result.reason[:60]})", np.nan, np.nan, np.full(3, np.nan), np.full(3, np.nan))]
    problem = build_problem(robot, scenario.scene, stance, PostureOptions(**options))
    model, data = robot.model, problem.data
    q = np.asarray(result.q)
    pin.framesForwardKinematics(model, data, q)
    rows = []
    for contact in problem.contacts:
        if contact.kind != "deformable":
            continue
        motion = contact.displacements(model, data) + contact.gaps
        compliance = contact.patch.link_compliance
        to_body = contact.rotation_body
        turns = [to_body.T @ data.oMf[f].rotation @ p.rotation.T @ to_body
                 for f, p in zip(contact.frame_ids, contact.print_placements)]
        turned = np.array([frame @ turns[i].T for frame, i in zip(contact.node_frames, contact.print_of_node)])
        mu = np.array([contact.friction[i] for i in contact.print_of_node])
        own = turned if contact.turned_frames else contact.node_frames
        library = fem.solve_print_contact(compliance, motion, own, contact.node_mu)
        exact = fem.solve_print_contact(compliance, motion, turned, mu)
        for i, label in enumerate(contact.print_labels):
            if i in contact.point_prints:
                continue
            nodes = contact.print_of_node == i
            normal = contact.node_frames[np.flatnonzero(nodes)[0], 2]
            tilt = float(np.arccos(np.clip(normal @ turns[i] @ normal, -1.0, 1.0)))
            slip = float(np.linalg.norm(library.relative[nodes] - (library.relative[nodes] @ normal)[:, None] * normal,
                                        axis=1).max())
            rows.append((label, tilt, slip, library.forces[nodes].sum(axis=0), exact.forces[nodes].sum(axis=0)))
    return rows


def main():
    lines = [
        f"# Soft prints: the library's contact against the exact plane contact of the turned face "
        f"({datetime.date.today()}, {code_version()})",
        "",
        f"Machine: {machine()}.",
        "",
        "At the posture each answer has: the print's resultant under the library's contact (in the "
        "answer's own frames and mu) and under the exact plane contact of the turned face (node frames "
        "turned with the link, the surface's mu), the same link motion and compliance. Body frame, N. "
        "Baselines: the rest frames (before 2026-12-06), alone and with a 1 degree tilt allowance.",
        "",
        "| stance | print | frames | tilt (deg) | largest slip (mm) | library (N) | exact (N) | "
        "normal force, library vs exact | resultant difference (N, % of exact) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    print("\n".join(lines), flush=True)
    robots = {}
    for name, stance_name in STANCES:
        scenario = environments.load(name)
        robot = robots.setdefault(scenario.robot, stances.Robot.load(scenario.robot))
        for variant, options in VARIANTS:
            for label, tilt, slip, library, exact in print_rows(robot, scenario, scenario.stance(stance_name), options):
                difference = float(np.linalg.norm(library - exact))
                line = (f"| {name}/{stance_name} | {label} | {variant} | {np.degrees(tilt):.2f} | "
                        f"{1e3 * slip:.2f} | {np.round(library, 2).tolist()} | {np.round(exact, 2).tolist()} | "
                        f"{100 * (library[2] / exact[2] - 1):+.2f} % | {difference:.3f} ({100 * difference / np.linalg.norm(exact):.2f} %) |")
                lines.append(line)
                print(line, flush=True)
    path = os.path.join(os.path.dirname(__file__), "results", "turned_face.md")
    with open(path, "w") as out:
        out.write("\n".join(lines) + "\n")
    print(f"written to {path}")


if __name__ == "__main__":
    main()
