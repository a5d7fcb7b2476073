"""The paper's coarse cube against converged meshes: what a 180-node mesh gets wrong.

Run as ``.venv/bin/python bench/bench_paper_mesh.py``; prints a markdown table and
writes it to ``bench/results/paper_mesh.md``.

The paper (section IV) meshes its 1 m cube with 166 nodes and 570 tets. The scenario
``hand-on-coarse-cube`` does the same with 180 nodes (6 x 6 x 5 grid lines, two on
each edge of the palm's print so that its corners are mesh nodes). The same stance,
Talos's right palm on the cube (paper Fig. 4), is solved on that mesh, on the default
mesh (``hand-on-cube``, 13,125 nodes) and on the default mesh refined twice
(resolution h / 2). Two comparisons:

- **Fixed print motion** (fem only): every node of the palm's print pressed 5 mm
  straight down, the vertical reaction on the palm: the covered print the solver uses
  (``fem.print_coverage``) and the nodes inside the palm only. It isolates the body's stiffness
  under the palm from the posture.
- **Stance** (``stances.solve``, Coulomb contact at every node, and the paper's bonded
  model): the palm's load, the print's depth (its deepest node), and how far the palm
  and the posture move from the refined mesh's answer.

CPU seconds with one BLAS thread; the setup (mesh, factorisation, print compliance)
is paid by a first solve and not counted.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time

# One BLAS thread, set before numpy loads (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import scenario_at_resolution, write_report  # noqa: E402

import environments  # noqa: E402
from environments.deformable import RESOLUTIONS  # noqa: E402
import fem  # noqa: E402
import stances  # noqa: E402

PRESS = 0.005  # metres, straight down, for the fixed-motion comparison
STANCE = "hand-on-cube"
PALM = "right_palm"
RESULT = os.path.join(os.path.dirname(__file__), "results", "paper_mesh.md")


def meshes(directory: str) -> list:
    """(label, scenario) for the coarse, default and refined meshes of the same cube."""
    refined = scenario_at_resolution("hand-on-cube", RESOLUTIONS["default"] / 2, directory)
    return [
        ("paper-like, 6 x 6 x 5 grid lines", environments.load("hand-on-coarse-cube")),
        ("default (h = 22.5 mm)", environments.load("hand-on-cube")),
        ("refined twice (h / 2)", environments.load(refined)),
    ]


def palm_print_nodes(robot, scenario) -> tuple:
    """The cube's fem body and the ids of its nodes under the palm's print."""
    cube = scenario.scene.deformable("cube")
    contact = next(c for c in scenario.stance(STANCE).contacts if c.robot_surface == PALM)
    placement = scenario.scene.transform_print_to_world(contact.contact_print)
    vertices = robot.surface(PALM).vertices_in_frame @ placement[:3, :3].T + placement[:3, 3]
    body_pose = cube.transform_body_to_world
    in_body = (vertices - body_pose[:3, 3]) @ body_pose[:3, :3]
    return cube.body, np.asarray(fem.nodes_in_polygon(cube.body.mesh, in_body)), in_body


def pressed_force(body, nodes, coverage=None) -> float:
    """Vertical force (N) on a palm whose print nodes all move PRESS straight down
    (partly covered nodes through their coupling when ``coverage`` is given)."""
    patch = body.contact_patch(nodes, coverage)
    press = np.tile([0.0, 0.0, -PRESS], (len(nodes), 1))
    return float(patch.reaction_forces(press)[:, 2].sum())


def solved(robot, scenario, law: str) -> dict:
    """Solve the stance twice (the first pays the setup); the second's numbers."""
    stance = scenario.stance(STANCE)
    stances.solve(robot, scenario.scene, stance, contact_law=law)
    start = time.process_time()
    result = stances.solve(robot, scenario.scene, stance, contact_law=law)
    seconds = time.process_time() - start
    palm_frame = robot.surface(PALM).frame
    palm_force = sum((f.force for f in result.forces_on(palm_frame)), np.zeros(3))
    deformation = result.deformations.get("cube")
    depth = float(-deformation[:, 2].min()) if deformation is not None and len(deformation) else float("nan")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, result.q)
    palm_position = data.oMf[robot.frame_id(palm_frame)].translation.copy()
    return {
        "feasible": result.feasible,
        "reason": result.reason,
        "iterations": result.iterations,
        "seconds": seconds,
        "palm_force": palm_force,
        "depth": depth,
        "palm": palm_position,
        "q": np.asarray(result.q),
        "strain": (result.verification.measures.get("largest strain of cube") if result.verification else float("nan")),
    }


def main() -> None:
    started = time.perf_counter()
    robot = stances.Robot.load("talos")
    lines = []
    with tempfile.TemporaryDirectory() as directory:
        studied = meshes(directory)
        rows = []
        for label, scenario in studied:
            body, nodes, in_body = palm_print_nodes(robot, scenario)
            covered_nodes, coverage = fem.print_coverage(body.mesh, in_body)
            force = pressed_force(body, covered_nodes, coverage)
            inside_force = pressed_force(body, nodes)
            answers = {law: solved(robot, scenario, law) for law in ("coulomb", "bonded")}
            rows.append((label, body.mesh.nodes.shape[0], body.mesh.tets.shape[0],
                         f"{len(covered_nodes)} ({len(nodes)} inside)", force, inside_force, answers))
    reference_force, reference_inside = rows[-1][4], rows[-1][5]
    reference = rows[-1][6]
    lines.append(
        "| mesh | nodes | tets | palm print nodes | 5 mm press: force (N) | vs h / 2 | nodes inside only: force (N) "
        "| vs h / 2 | contact law | feasible "
        "| palm load (N) [x, y, z] | vs h / 2 | print depth (mm) | palm moved vs h / 2 (mm) | max abs dq vs h / 2 (rad or m) "
        "| largest strain | iterations | CPU s |"
    )
    lines.append("|---" * 18 + "|")
    for label, n_nodes, n_tets, n_print, force, inside_force, answers in rows:
        for law, answer in answers.items():
            ref = reference[law]
            load_change = np.linalg.norm(answer["palm_force"] - ref["palm_force"]) / max(np.linalg.norm(ref["palm_force"]), 1e-12)
            lines.append(
                f"| {label} | {n_nodes} | {n_tets} | {n_print} | {force:.1f} | {100 * (force / reference_force - 1):+.1f} % "
                f"| {inside_force:.1f} | {100 * (inside_force / reference_inside - 1):+.1f} % "
                f"| {law} | {'yes' if answer['feasible'] else 'no: ' + answer['reason']} "
                f"| [{', '.join(f'{v:.1f}' for v in answer['palm_force'])}] | {100 * load_change:.1f} % "
                f"| {1e3 * answer['depth']:.2f} | {1e3 * np.linalg.norm(answer['palm'] - ref['palm']):.1f} "
                f"| {np.abs(answer['q'] - ref['q']).max():.3g} | {answer['strain']:.2g} | {answer['iterations']} "
                f"| {answer['seconds']:.2f} |"
            )
    write_report(
        RESULT,
        "The paper's coarse cube against converged meshes",
        started,
        "Stance `hand-on-cube` (paper Fig. 4): both soles on the floor, right palm on the 1 m cube (E = 1e6 Pa, "
        "nu = 0.4). \"vs h / 2\": relative to the mesh refined twice. The 5 mm press moves every print node the "
        "same 5 mm down (fem only), with the covered print the solver uses (every node whose cell the palm covers, "
        "partly covered ones coupled by their covered fraction) and with the nodes inside the palm only; the stance "
        "columns are `stances.solve`'s verified answers.",
        lines,
    )

if __name__ == "__main__":
    main()
