"""Where the soft palm's stiff limit stands against the rigid support (issue 8, item 5).

Run as ``.venv/bin/python bench/bench_palm_limit.py [--fine]``; prints markdown tables and
writes them to ``bench/results/palm_limit.md``.

``hand-on-cube``: both soles on the floor, the right palm on a cube made weightless and
steel-stiff (E = 1e10 Pa, where the stiffness sweep of ``bench_deformable.py --sweeps`` has
long settled), against the same stance on the cube held rigid. The palm is 100 x 70 mm; y
below is across it, in its contact frame, its edges at +-35 mm.

1. Mesh: the cube meshed with a spacing of 22.5 mm where prints land (the default), 15 mm
   and, with ``--fine`` (about four more minutes, its setup), 10 mm. For each: the palm's
   force, its difference to the rigid answer's, the palm's centre of pressure across it and
   the outermost print node's position; the same without the stiff limit
   (``stiff_limit=False``, the soft prints' own variables W, as before 2026-12-05). In its
   stiff limit the palm is the rigid one with its centre of pressure where the nodes reach:
   its difference follows the gap between the outermost nodes and the palm's edge (the load
   split below), and where they reach the edge it is the friction margin's.
2. The load split: the rigid palm with the +y edge of its polygon moved in, so that its
   centre of pressure cannot pass it: the posture problem's objective and the palm's force
   as the edge comes in, against the soft answer on the default mesh.
3. Reach: whether any of the soft print's own 6 force variables W gives Coulomb forces whose
   wrench is the rigid answer's palm wrench (least squares from 8 starts; the default mesh).
4. The print's variables: at the soft answer, the Jacobian of the wrench the Coulomb forces
   carry with respect to W (contact modes fixed, as the SQP linearises them), its singular
   values, and the change of W that moves the palm's centre of pressure 1 mm outwards.
"""

from __future__ import annotations

import dataclasses
import datetime
import os
import sys
import time

# One BLAS thread, set before numpy loads (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
import scipy.optimize  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import code_version, machine  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402
from stances.description import read_description  # noqa: E402
from stances.problem import PostureOptions, build_problem  # noqa: E402

SCENARIO = "hand-on-cube"
PALM, PALM_FRAME = "right_palm", "right_palm_contact"
YOUNG_MODULUS = 1e10  # Pa
SPACINGS = (0.0225, 0.015)  # m, fine node spacing where prints land ("default" is 0.0225)
FINE_SPACING = 0.010
EDGES = (0.035, 0.0326, 0.030, 0.028, 0.026, 0.0255)  # m, the rigid palm's +y edge (0.035: its own)
STARTS = 8


def scenario_text(spacing=None) -> str:
    """The scenario's YAML with the cube weightless at YOUNG_MODULUS (and meshed at ``spacing``)."""
    text = environments.builtin_scenario_path(SCENARIO).read_text()
    text = text.replace("E: 1.0e+6", f"E: {YOUNG_MODULUS:.1e}").replace("rho: 1.0e+3", "rho: 0.0")
    if spacing is not None:
        text = text.replace("resolution: default", f"resolution: {spacing}")
    return text


def palm_points_and_forces(robot, result):
    """(k, 3) points and (k, 3) forces of the palm's point forces, palm frame (about its origin)."""
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(result.q))
    frame = data.oMf[model.getFrameId(PALM_FRAME)]
    on_palm = [p for p in result.point_forces if p.frame == PALM_FRAME]
    points = np.array([p.point for p in on_palm]) - frame.translation
    return points @ frame.rotation, np.array([p.force for p in on_palm]) @ frame.rotation


def palm_wrench(robot, result) -> np.ndarray:
    """(6,) force and moment of the palm's point forces, palm frame, about its origin."""
    points, forces = palm_points_and_forces(robot, result)
    return np.r_[forces.sum(axis=0), np.cross(points, forces).sum(axis=0)]


def outermost_node(robot, result) -> float:
    """The largest y of the palm's print nodes (where their forces act), palm frame, m."""
    return float(palm_points_and_forces(robot, result)[0][:, 1].max())


def objective(robot, scene, stance, result, **options) -> float:
    """The posture problem's objective at a result's answer."""
    problem = build_problem(robot, scene, stance, PostureOptions(**options))
    return problem.evaluate(np.asarray(result.q), np.asarray(result.statistics["lambda"])).objective


def difference(force, reference) -> float:
    return float(np.linalg.norm(force - reference) / np.linalg.norm(reference))


def mesh_table(robot, rigid_force, spacings):
    rows = ["| node spacing (mm) | print nodes | outermost node y (mm) | CPU s (first solve, with setup) | "
            "palm force (N) | difference to the rigid support | centre of pressure y (mm) | "
            "without the stiff limit: difference | centre of pressure y (mm) |",
            "|---|---|---|---|---|---|---|---|---|"]
    for spacing in spacings:
        scenario = environments.load_string(scenario_text(spacing), name=SCENARIO)
        tic = time.process_time()
        result = stances.solve(robot, scenario.scene, scenario.stance(SCENARIO))
        seconds = time.process_time() - tic
        # The soft prints' own variables W throughout (PostureOptions.stiff_limit=False): before 2026-12-05.
        plain = stances.solve(robot, scenario.scene, scenario.stance(SCENARIO), stiff_limit=False)
        wrench, plain_wrench = palm_wrench(robot, result), palm_wrench(robot, plain)
        nodes = sum(p.frame == PALM_FRAME for p in result.point_forces)
        limit = "" if "stiff_limit" in result.statistics else " (not in its stiff limit)"
        rows.append(f"| {1e3 * spacing:g} | {nodes} | {1e3 * outermost_node(robot, result):.1f} | {seconds:.1f} | "
                    f"{np.round(wrench[:3], 2).tolist()} | {difference(wrench[:3], rigid_force):.2%}"
                    f"{'' if result.feasible else ' (not verified)'}{limit} | {1e3 * wrench[3] / wrench[2]:.1f} | "
                    f"{difference(plain_wrench[:3], rigid_force):.2%}{'' if plain.feasible else ' (not verified)'} | "
                    f"{1e3 * plain_wrench[3] / plain_wrench[2]:.1f} |")
        print(rows[-1], flush=True)
    return rows


def robot_with_palm_edge(edge) -> stances.Robot:
    """Talos with its right palm's polygon cut at y = ``edge`` (palm frame, m)."""
    description = read_description("talos")
    surfaces = tuple(
        dataclasses.replace(s, polygon=np.minimum(s.polygon, [np.inf, edge])) if s.name == PALM else s
        for s in description.surfaces
    )
    return stances.Robot.from_description(dataclasses.replace(description, surfaces=surfaces))


def split_table(scene, stance, soft_wrench, soft_objective):
    rows = ["| rigid palm's +y edge (mm) | objective | palm force (N) | centre of pressure y (mm) | "
            "difference to the soft palm (default mesh, W) | difference to the rigid support |",
            "|---|---|---|---|---|---|"]
    own = None  # the rigid palm's force with its own edge (EDGES[0])
    for edge in EDGES:
        robot = robot_with_palm_edge(edge)
        result = stances.solve(robot, scene, stance, deformable_as_rigid=True)
        wrench = palm_wrench(robot, result)
        own = wrench[:3] if own is None else own
        rows.append(f"| {1e3 * edge:g} | {objective(robot, scene, stance, result, deformable_as_rigid=True):.5f} | "
                    f"{np.round(wrench[:3], 2).tolist()} | {1e3 * wrench[3] / wrench[2]:.1f} | "
                    f"{difference(wrench[:3], soft_wrench[:3]):.2%} | {difference(wrench[:3], own):.2%} |")
        print(rows[-1], flush=True)
    rows.append(f"| soft palm, default mesh | {soft_objective:.5f} | {np.round(soft_wrench[:3], 2).tolist()} | "
                f"{1e3 * soft_wrench[3] / soft_wrench[2]:.1f} | | {difference(soft_wrench[:3], own):.2%} |")
    return rows


def reach_rows(robot, scene, stance, rigid):
    """Least squares over the soft print's W for the rigid answer's palm wrench."""
    rigid_problem = build_problem(robot, scene, stance, PostureOptions(deformable_as_rigid=True))
    problem = build_problem(robot, scene, stance, PostureOptions())
    contact = next(c for c in problem.contacts if c.kind == "deformable")
    columns = next(s for c, s in zip(problem.contacts, problem.variable_slices) if c is contact)
    variables = problem.variables_from_rigid(rigid_problem, rigid.statistics["lambda"], rigid.point_forces)
    target = variables[columns]  # the rigid palm wrench, body frame, about the print's origin
    problem.evaluate(np.asarray(rigid.q), variables)  # kinematics at the rigid posture

    def wrench(w):
        return carried_wrench(contact, problem, w)

    rng = np.random.default_rng(0)
    best = None
    for start in range(STARTS):
        guess = target if start == 0 else target * (1.0 + 0.5 * rng.standard_normal(6))
        fit = scipy.optimize.least_squares(lambda w: wrench(w) - target, guess, x_scale=[10, 10, 10, 0.5, 0.5, 0.5],
                                           xtol=1e-12, ftol=1e-12, gtol=1e-12)
        best = fit if best is None or fit.cost < best.cost else best
    miss = wrench(best.x) - target
    return [f"The rigid answer's palm wrench (body frame, about the print's origin): {np.round(target, 3).tolist()}.",
            f"Its W gives Coulomb forces of wrench {np.round(wrench(target), 3).tolist()}; the best of {STARTS} "
            f"least-squares fits misses by {np.round(miss, 3).tolist()} (N, N m), with W = {np.round(best.x, 1).tolist()}."]


def carried_wrench(contact, problem, w, derivative=False):
    """The wrench the print's forces carry, (6,), body frame, moments about the print's origin
    (the problem's kinematics at the iterate); with ``derivative``, also its derivative in W,
    (6, 6), the contact modes fixed (the problem's joint Jacobians computed)."""
    model, data = problem.robot.model, problem.data
    origin, rotation = contact.print_placements[0].translation, contact.rotation_body
    levers = contact.link_points_at_rest - origin  # (p, 3) world
    forces = contact.forces(model, data, w)
    wrench = np.r_[rotation.T @ forces.sum(axis=0), rotation.T @ np.cross(levers, forces).sum(axis=0)]
    if not derivative:
        return wrench
    d_forces = contact.force_jacobians(model, data, w)[1].reshape(len(levers), 3, -1)  # (p, 3, 6) world
    d_moments = np.einsum("pij,pjk->ik", np.array([pin.skew(v) for v in levers]), d_forces)
    return wrench, np.vstack([rotation.T @ d_forces.sum(axis=0), rotation.T @ d_moments])


def variables_rows(robot, scene, stance, soft):
    """The soft print's W against the wrench its forces carry, at the soft answer."""
    problem = build_problem(robot, scene, stance, PostureOptions())
    contact = next(c for c in problem.contacts if c.kind == "deformable")
    columns = next(s for c, s in zip(problem.contacts, problem.variable_slices) if c is contact)
    q, variables = np.asarray(soft.q), np.asarray(soft.statistics["lambda"])
    problem.evaluate(q, variables)
    pin.computeJointJacobians(robot.model, problem.data, q)
    w = variables[columns]
    wrench, jacobian = carried_wrench(contact, problem, w, derivative=True)
    left, singular, _ = np.linalg.svd(jacobian)
    weakest = left[:, -1]
    # 1 mm further out across the palm (y) at the same force: the moment about x grows by f_z * 1 mm.
    target = np.zeros(6)
    target[3] = 1e-3 * wrench[2]
    step = np.linalg.lstsq(jacobian, target, rcond=None)[0]
    # First-order change of the force term (force_weight / 2 W^T M W): on W, as the soft print
    # weighs it, and on the carried wrench itself, as the same metric would.
    weight = PostureOptions().force_weight
    on_w = weight * float(contact.force_metric @ w @ step)
    on_carried = weight * float(contact.force_metric @ wrench @ target)
    return [f"At the soft answer (default mesh) W = {np.round(w, 3).tolist()}; its Coulomb forces carry "
            f"{np.round(wrench, 3).tolist()} (N, N m).",
            f"Singular values of d(carried wrench)/dW: {np.round(singular, 4).tolist()}; the weakest carried "
            f"direction {np.round(weakest, 3).tolist()} (force, moment).",
            f"Moving the centre of pressure 1 mm outwards (the moment about x by {target[3]:.4f} N m) takes W's moment "
            f"about x by {step[3]:.3f} N m (|dW| = {np.linalg.norm(step):.3f}); the force term changes by {on_w:.2e} "
            f"(on W, as the soft print weighs it) against {on_carried:.2e} (the same metric on the carried wrench)."]


def main():
    robot = stances.Robot.load("talos")
    spacings = SPACINGS + ((FINE_SPACING,) if "--fine" in sys.argv[1:] else ())
    base = environments.load_string(scenario_text(), name=SCENARIO)
    stance = base.stance(SCENARIO)
    rigid = stances.solve(robot, base.scene, stance, deformable_as_rigid=True)
    # Sections 2-4 study the soft prints' own variables W (the stiff limit off).
    soft = stances.solve(robot, base.scene, stance, stiff_limit=False)
    rigid_wrench, soft_wrench = palm_wrench(robot, rigid), palm_wrench(robot, soft)
    lines = [
        f"# The soft palm's stiff limit ({datetime.date.today()}, {code_version()})",
        "",
        f"Machine: {machine()}.",
        "",
        f"`{SCENARIO}`, the cube weightless at E = {YOUNG_MODULUS:.0e} Pa. Rigid support: palm force "
        f"{np.round(rigid_wrench[:3], 2).tolist()} N, centre of pressure y {1e3 * rigid_wrench[3] / rigid_wrench[2]:.1f} mm "
        f"(the palm's edge: 35 mm), objective {objective(robot, base.scene, stance, rigid, deformable_as_rigid=True):.5f}.",
        "",
        "## Mesh",
        "",
    ]
    print("\n".join(lines), flush=True)
    lines += mesh_table(robot, rigid_wrench[:3], spacings)
    lines += ["", "## The load split", ""]
    lines += ["Sections 2-4: the soft prints' own variables W (`stiff_limit=False`).", ""]
    lines += split_table(base.scene, stance, soft_wrench, objective(robot, base.scene, stance, soft))
    lines += ["", "## Reach", ""]
    lines += reach_rows(robot, base.scene, stance, rigid)
    lines += ["", "## The print's variables", ""]
    lines += variables_rows(robot, base.scene, stance, soft)
    text = "\n".join(lines) + "\n"
    print(text[text.index("## Reach"):], flush=True)
    with open(os.path.join(os.path.dirname(__file__), "results", "palm_limit.md"), "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    main()
