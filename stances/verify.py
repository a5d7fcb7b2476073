"""Independent verification of a posture: is it what the solver claims?

Verification shares nothing with the solver's linearisation but the model: it
recomputes placements from forward kinematics, the free-flyer wrench balance
and the joint torques with pinocchio's RNEA (with the reported point forces as
external forces), friction-cone margins, joint limits and collision distances,
and, for deformable supports, the FEM reaction forces from the link placement.
A stance is called feasible only when every check here passes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from environments.geometry import axes_across

from .collision import CollisionChecker, contact_exclusions
from .problem import PostureOptions, build_problem
from .results import Verification
from .statics import points_in_world, zero_wrenches


@dataclass(frozen=True)
class VerificationTolerances:
    """Thresholds of :func:`verify` (SI units)."""

    equilibrium: float = 1e-6  # N and N m
    placement: float = 1e-6  # m and rad
    torque: float = 1e-6  # N m beyond the limit
    cone: float = 1e-6  # N outside the friction cone
    joint_limit: float = 1e-9  # rad
    penetration: float = 1e-4  # m of collision depth tolerated
    deformable_force: float = 1e-6  # relative error of recomputed FEM forces (traction)
    deformable_placement: float = 1e-6  # m between print nodes under the reported forces and their link
    # Share of a stiff print's node forces off those of any pressure under its face (fem.pressure_fit):
    # the 15 built-in soft stances' and the stiff answers' read under 1e-6, a palm pivoting onto the
    # nodes past its edge 7.5 %.
    pressure_fit: float = 0.01


def _external_forces(model, data, point_forces, forces=None, points=None):
    """Each joint's spatial force (local frame) from the reported point forces.

    Summed in the world frame about the world origin, then moved to each joint's
    frame (``oMi.actInv``): a way of its own (the solver sums local forces at local points,
    :mod:`stances.statics`), and one numpy pass for the hundreds of a soft print's
    points (a loop over them was 8 ms of a two-mat stance's check). ``forces`` and
    ``points``: the point forces' (k, 3) forces and points, if the caller has them.
    """
    joints = np.zeros(len(point_forces), dtype=np.int64)
    parents = {}
    for i, point_force in enumerate(point_forces):
        if point_force.frame not in parents:
            parents[point_force.frame] = model.frames[model.getFrameId(point_force.frame)].parentJoint
        joints[i] = parents[point_force.frame]
    if forces is None:
        forces = np.array([p.force for p in point_forces], dtype=float).reshape(-1, 3)
    if points is None:
        points = np.array([p.point for p in point_forces], dtype=float).reshape(-1, 3)
    moments = np.cross(points, forces)  # about the world origin
    fext = zero_wrenches(model.njoints)
    for joint in np.unique(joints).tolist():
        # The world-frame wrench about the world origin, seen from the joint's frame:
        # (R^T f, R^T (m - o x f)), one pinocchio call (np.cross on one vector cost
        # about 20 times as much); the joints that carry nothing keep a zero wrench.
        mine = joints == joint
        fext[joint] = data.oMi[joint].actInv(pin.Force(forces[mine].sum(axis=0), moments[mine].sum(axis=0)))
    return fext


def verify_problem(
    problem, result, tolerances: VerificationTolerances | None = None, deformed_surfaces: bool = False,
    fields: dict | None = None,
) -> Verification:
    """Check a result against the problem it claims to solve.

    Parameters
    ----------
    problem : stances.problem.PostureProblem
    result : stances.PostureResult
    tolerances : VerificationTolerances, optional
    deformed_surfaces : bool
        Also check the displacement fields ``result.deformations`` shows
        (finite, and those its forces make) and that no link but the
        contacting one penetrates a deformed support (exact, on the deformed
        boundary mesh). It needs the whole-body displacement fields, a few
        hundred milliseconds on a large mesh, so the solver's own check
        (against the rest shape) leaves it out.
    fields : dict, optional
        Filled with the displacement field this check solves for each soft
        body under the reported forces (object name -> (N, 3) float, metres,
        body frame), for a caller that shows them too.

    Returns
    -------
    Verification
    """
    tolerances = tolerances or VerificationTolerances()
    robot = problem.robot
    model = robot.model
    data = pin.Data(model)
    q = np.asarray(result.q)
    reasons = []
    measures = {}

    if not np.all(np.isfinite(q)):
        return Verification(False, ("q has non-finite entries",), {})
    # Every check below compares with `>`, which a NaN passes: refuse them first. The
    # forces and points are read into arrays once, for this and every check below (a
    # soft stance reports some sixty: tested one by one, 0.4 ms of its check).
    all_forces = np.array([p.force for p in result.point_forces], dtype=float).reshape(-1, 3)
    all_points = np.array([p.point for p in result.point_forces], dtype=float).reshape(-1, 3)
    finite = np.isfinite(all_forces).all(axis=1) & np.isfinite(all_points).all(axis=1)
    if not finite.all():
        return Verification(False, (f"a contact force on {result.point_forces[int(np.argmin(finite))].frame} is not finite",), {})
    # The forces act where the file says: one per application point of the stance's
    # contacts, each on its contact's link. A force on another frame moves its load
    # to another joint's torque; one more than the contacts have (a hook in the
    # sky) would be checked by no contact's cone or placement.
    frames = [frame for contact in problem.contacts for frame in contact.load_frames]
    shown = [p.frame for p in result.point_forces]
    if len(shown) != len(frames):
        return Verification(
            False, (f"{len(shown)} contact forces reported for the {len(frames)} application points of the stance's contacts",), {}
        )
    wrong = next((i for i, (a, b) in enumerate(zip(shown, frames)) if a != b), None)
    if wrong is not None:
        return Verification(False, (f"contact force {wrong} acts on {shown[wrong]}, not on its contact's {frames[wrong]}",), {})
    pin.framesForwardKinematics(model, data, q)

    # Joint limits.
    below = model.lowerPositionLimit[7:] - q[7:]
    above = q[7:] - model.upperPositionLimit[7:]
    worst = float(max(below.max(initial=0.0), above.max(initial=0.0)))
    measures["joint_limit_violation"] = worst
    if worst > tolerances.joint_limit:
        reasons.append(f"joint limit exceeded by {worst:.3g} rad")

    # Equilibrium and torques with RNEA and the reported forces as external forces.
    fext = _external_forces(model, data, result.point_forces, all_forces, all_points)
    tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv), fext)
    residual = float(np.max(np.abs(tau[:6])))
    measures["equilibrium_residual"] = residual
    if residual > tolerances.equilibrium:
        reasons.append(f"free-flyer wrench unbalanced by {residual:.3g} N (N m)")
    excess = np.abs(tau[6:]) - robot.effort_limits
    worst_joint = int(np.argmax(excess))
    measures["torque_margin"] = float(-excess.max(initial=-np.inf))
    if excess[worst_joint] > tolerances.torque:
        reasons.append(
            f"torque limit of {robot.actuated_joint_names[worst_joint]} exceeded by "
            f"{excess[worst_joint]:.3g} N m"
        )

    # Each contact: placement, cones, and (deformable) the FEM forces themselves. A soft
    # body's field under the reported forces (one sparse solve) serves both its contact's
    # check and the check of the field the result shows.
    made = {} if fields is None else fields
    for contact, loads in zip(problem.contacts, problem.load_slices):
        forces, points = all_forces[loads].copy(), all_points[loads].copy()
        if contact.deformable_object is not None:
            made[contact.deformable_object.name] = field = np.asarray(contact.displacement_field(model, data, forces))
            # The slips a soft print's answer shows (None: not recorded, as before plan version 6).
            shown = {"shown_slips": getattr(result, "slips", None)} if contact.kind == "deformable" else {}
            reasons.extend(contact.verify(model, data, points, forces, tolerances, measures, field=field, **shown))
        else:
            reasons.extend(contact.verify(model, data, points, forces, tolerances, measures))

    if deformed_surfaces:
        # The displacement fields the result shows are those its forces make.
        shown, mismatches = _shown_deformations(result, made, tolerances, measures)
        reasons.extend(mismatches)
        # Links other than the contacting one keep clear of each deformed surface.
        if problem.collision_checker is not None and shown is not None:
            reasons.extend(_deformed_surface_clearance(problem, shown, data, tolerances, measures))

    # Collisions, measured afresh.
    if problem.collision_checker is not None:
        least, deep = problem.collision_checker.clearance(model, data, tolerances.penetration)
        measures["closest_distance"] = least
        for (name_a, name_b), distance in deep:
            reasons.append(f"collision between {name_a} and {name_b} (depth {-distance:.3g} m)")
    return Verification(not reasons, tuple(reasons), measures)


def verify(robot, scene, stance, result, **options) -> Verification:
    """Independently check that a posture result holds its stance.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance
    result : stances.PostureResult
        Its ``q``, ``point_forces`` (one per application point of the stance's
        contacts, on its contact's frame) and ``deformations`` are checked;
        nothing else is trusted but its ``held_slips`` (an input: where the stance
        before left each kept soft print's link points, which its law starts from).
    **options
        Posture options to check with, over those the result records it was solved
        with (``result.statistics.options``, the ones off their defaults: e.g. a
        ``ball_contact`` or ``contact_law``, which decide the model its forces are
        checked against); give one to check more strictly (``max_indentation=0.01``).
        Deformable supports are checked against their deformed surface.

    Returns
    -------
    Verification
        ``ok`` with the measured residuals, or the list of failed checks.
    """
    # A result checked against another contact model than its own fails for that alone
    # (a ball's node forces are not its layer law's): the recorded options come first.
    recorded = (getattr(result, "statistics", None) or {}).get("options") or {}
    # Each kept print's law is read from where the stance before left it (its held slips).
    problem = build_problem(robot, scene, stance, PostureOptions(**{**recorded, **options}),
                            held_slips=getattr(result, "held_slips", None) or None)
    return verify_problem(problem, result, deformed_surfaces=True)


def _shown_deformations(result, made, tolerances, measures):
    """Each soft support's field as shown by ``result``, checked against the one its
    forces make (``made``: object name -> (N, 3) float, body frame).

    Returns
    -------
    fields : dict of str to (N, 3) float, or None
        Body-frame displacements by object name: the shown field where the
        result has one, else the one its forces make. None if a shown field is
        not finite or not of the body's shape (nothing to check clearance on).
    reasons : list of str
        Shown fields that are not the forces' own, by how far (metres).
    """
    fields, reasons = {}, []
    for name, expected in made.items():
        if name not in result.deformations:
            fields[name] = expected
            continue
        shown = np.asarray(result.deformations[name], dtype=float)
        if shown.shape != expected.shape or not np.all(np.isfinite(shown)):
            return None, [f"the deformation of {name} is not a finite {expected.shape[0]} x 3 field"]
        error = float(np.abs(shown - expected).max(initial=0.0))
        measures[f"deformation error of {name}"] = error
        if error > tolerances.deformable_placement:
            reasons.append(f"the deformation of {name} is off the one its forces make by {error:.3g} m")
        fields[name] = shown
    return fields, reasons


def _deformed_surface_clearance(problem, fields, data, tolerances, measures) -> list:
    """Penetrations of robot links into the deformed supports (the links resting on them
    excluded), and of the prints held rigid on them, point by point."""
    reasons = []
    for contact in problem.contacts:
        if contact.deformable_object is None:
            continue
        obj = contact.deformable_object
        name = f"{obj.name} (deformed)"
        # A print held rigid on the body (PostureOptions.rigid_prints: a limb touching it
        # unloaded) rests on it like the soft prints: its link is left out of the meshes'
        # check, and its points are checked against the surface the other prints deform.
        held = [c for c in problem.contacts if c.kind == "rigid" and c.support_surface is not None
                and c.support_surface.object_name == obj.name]
        frames = [problem.robot.model.frames[i].name for i in contact.frame_ids] + [
            problem.robot.model.frames[c.frame_id].name for c in held]
        checker = CollisionChecker(
            problem.robot,
            [(name, obj.deformed_collision_object(fields[obj.name]))],
            margin=0.0,
            exclude=[pair for frame in frames for pair in contact_exclusions(problem.robot, frame, name)],
            self_collision=False,
        )
        triangles = obj.deformed_surface(fields[obj.name]) if held else None
        for rigid in held:
            normal = rigid.print_placement.rotation[:, 2]
            points = points_in_world(data, rigid.loads) - getattr(rigid, "radius", 0.0) * normal
            depth = float(np.max(depths_below_surface(points, normal, triangles)))
            measures[f"depth of {rigid.label} (held rigid) in deformed {obj.name}"] = depth
            if depth > tolerances.penetration:
                reasons.append(f"{rigid.label}, held rigid, lies {depth:.3g} m inside the deformed {obj.name}")
        pairs = checker.pairs(problem.robot.model, data)
        deepest = min((p.distance for p in pairs), default=np.inf)
        measures[f"clearance to deformed {obj.name}"] = float(deepest)
        for pair in pairs:
            if pair.distance < -tolerances.penetration:
                reasons.append(f"{pair.name_a} penetrates the deformed {obj.name} by {-pair.distance:.3g} m")
    return reasons


def depths_below_surface(points, normal, triangles, reach=0.05):
    """How far each point lies below a surface, measured along ``normal``.

    Parameters
    ----------
    points : (p, 3) float
        Metres, world frame.
    normal : (3,) float
        Unit vector out of the body (a print's normal).
    triangles : (T, 3, 3) float
        The body's boundary, world frame.
    reach : float
        Metres: faces farther than this along ``normal`` are not the surface there.

    Returns
    -------
    (p,) float
        Metres: positive inside the body (under the face above the point that faces
        along ``normal``), negative above it, ``-inf`` where no such face lies over or
        under the point.
    """
    normal = np.asarray(normal, dtype=float)
    axes = axes_across(normal)
    facing = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]) @ normal > 0.0
    corners = triangles[facing]
    depths = np.full(len(points), -np.inf)
    for k, point in enumerate(np.asarray(points, dtype=float)):
        planar = (corners - point) @ axes.T  # (T, 3, 2): the faces seen along the normal from the point
        heights = (corners - point) @ normal  # (T, 3)
        a, b, c = planar[:, 0], planar[:, 1], planar[:, 2]
        area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        # Barycentric weights of the point (the origin) in each projected face.
        w_b = (a[:, 1] * c[:, 0] - a[:, 0] * c[:, 1]) / area
        w_c = (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / area
        w_a = 1.0 - w_b - w_c
        over = (np.abs(area) > 1e-18) & (w_a >= -1e-9) & (w_b >= -1e-9) & (w_c >= -1e-9)
        height = w_a * heights[:, 0] + w_b * heights[:, 1] + w_c * heights[:, 2]
        near = over & (np.abs(height) <= reach)
        if np.any(near):
            depths[k] = float(np.max(height[near]))
    return depths
