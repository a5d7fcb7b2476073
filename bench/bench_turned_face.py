"""The soft prints' contact law against the exact plane contact of the turned face (issue 8.3).

Run as ``.venv/bin/python bench/bench_turned_face.py``; prints a markdown table and writes it to
``bench/results/turned_face.md`` (about a minute).

The library solves each print node's Signorini-Coulomb contact in the print's rest frame: the
gap and the friction cone about the rest normal, each node tied to the link point that lay on
it at rest (``stances.deformable``; cones narrowed by ``tilt_allowance``). The face that
presses is the link's, turned by the tilt t; a node that slips by s relative to its link
point sits against the face where the face is s tan(t) higher or lower than at its link
point, which the rest-normal gap does not see. The exact plane contact of a rigid flat face,
the same linear elastic body (the same compliance), puts each node's frame on the turned face:
gap along the face's normal, slip and cone in its plane, the surface's own mu
(:func:`fem.solve_print_contact` with the node frames turned with the link). Both are solved
here at the posture the library answered, the same link motion, and their resultants compared:
what an independent check with the exact law would find off in the stance's equilibrium.

Baseline: the same stances solved with ``tilt_allowance=0`` (the linear model's cones, as
before 2026-12-06).
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
ALLOWANCES = (PostureOptions().tilt_allowance, 0.0)


def print_rows(robot, scenario, stance, allowance):
    """Per soft flat print at the library's answer: (label, tilt rad, largest slip m, library
    resultant (3,), exact resultant (3,)), body frame, newtons."""
    result = stances.solve(robot, scenario.scene, stance, tilt_allowance=allowance)
    if not result.feasible:
        return [(f"(infeasible: {result.reason[:60]})", np.nan, np.nan, np.full(3, np.nan), np.full(3, np.nan))]
    problem = build_problem(robot, scenario.scene, stance, PostureOptions(tilt_allowance=allowance))
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
        library = fem.solve_print_contact(compliance, motion, contact.node_frames, contact.node_mu)
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
        f"# Soft prints: the library's contact law against the exact plane contact of the turned face "
        f"({datetime.date.today()}, {code_version()})",
        "",
        f"Machine: {machine()}.",
        "",
        "At the posture each answer has: the print's resultant under the library's law (rest-normal gap "
        "and cones, mu narrowed by the tilt allowance) and under the exact plane contact of the turned "
        "face (node frames turned with the link, the surface's mu), the same link motion and compliance. "
        "Body frame, N. Baseline: `tilt_allowance=0`.",
        "",
        "| stance | print | tilt_allowance (deg) | tilt (deg) | largest slip (mm) | library (N) | exact (N) | "
        "normal force, library vs exact | resultant difference (N, % of exact) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    print("\n".join(lines), flush=True)
    robots = {}
    for name, stance_name in STANCES:
        scenario = environments.load(name)
        robot = robots.setdefault(scenario.robot, stances.Robot.load(scenario.robot))
        for allowance in ALLOWANCES:
            for label, tilt, slip, library, exact in print_rows(robot, scenario, scenario.stance(stance_name), allowance):
                difference = float(np.linalg.norm(library - exact))
                line = (f"| {name}/{stance_name} | {label} | {np.degrees(allowance):g} | {np.degrees(tilt):.2f} | "
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
