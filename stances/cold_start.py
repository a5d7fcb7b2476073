"""Where a posture solve starts when it is given no posture: the reference posture over the stance.

The robot's reference posture stands at the world origin. A stance elsewhere (on a
block, on a cube 0.3 m up, turned) then starts with its feet tens of centimetres from
their prints and its legs inside the supports, where the linearised collision rows
point sideways: measured on step-on-cube's rigid warm start, the SQP's path then
depended on the last bits of its first QPs (its feet crossed in a third of the QP
solver settings tried, and the stance came back infeasible). Moved over its prints,
the same posture needs a few small steps.

From there a few damped least-squares steps on the contacts' placements alone
(:func:`reaching_configuration`) bring the feet and hands onto their prints: the SQP
then starts where its placement rows hold, and the 60 random rigid stances of
``bench/bench_posture.py`` took 338 SQP iterations instead of 387. Such a start can
bend a limb somewhere the SQP does not come back from (a palm turned 20-30 degrees on
hand-on-cube's cube, reached from the reference posture); the solve then
solves again from the reference posture over the prints.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .contacts import placement_residual, point_placement_residual


def initial_configuration(robot, scene, stance) -> np.ndarray:
    """A cold-start posture: the reference posture moved over the stance's feet.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance

    Returns
    -------
    (nq,) float
        ``robot.reference_configuration`` with its free flyer translated so
        that the mid-point of the feet (surfaces of its support role) the
        stance uses lies over the mid-point of their prints, at the height of
        the highest of them (without a foot in the stance: all its feet over
        all its prints, at the highest print's height), and turned to their
        mean heading about world z. An empty stance gives the reference posture.
    """
    q = np.array(robot.reference_configuration, dtype=float)
    feet = robot.surfaces_with_role(robot.support.role)
    contacts = [c for c in stance if c.robot_surface in feet]
    # The same feet on both sides: a quadruped on three feet puts those three
    # over their prints, not the mid-point of all four.
    used = [c.robot_surface for c in contacts] or list(feet)
    contacts = contacts or list(stance)
    if not contacts:
        return q
    reference_feet = np.mean([robot.reference_position(robot.surfaces[s].frame) for s in used], axis=0)
    transforms = [scene.transform_print_to_world(c.contact_print) for c in contacts]
    target = np.mean([t[:3, 3] for t in transforms], axis=0)
    # At the highest print's height: every foot starts at or above its support,
    # none inside one, where the collision rows point the wrong way (measured on
    # foot-on-block's 20 perturbed stances: 8.4 SQP iterations on average from
    # here, 8.9 from the prints' mean height and 9.75 from the lowest).
    target[2] = max(t[2, 3] for t in transforms)
    heading = np.mean([t[:3, 0] for t in transforms], axis=0)
    yaw = float(np.arctan2(heading[1], heading[0])) if np.linalg.norm(heading[:2]) > 1e-9 else 0.0
    rotation = pin.utils.rotate("z", yaw)
    base = pin.XYZQUATToSE3(q[:7])
    offset = base.translation - reference_feet
    base.translation = target + rotation @ offset
    base.rotation = rotation @ base.rotation
    q[:7] = pin.SE3ToXYZQUAT(base)
    return q


# Damped least squares (the Levenberg-Marquardt step of inverse kinematics):
REACH_STEPS = 5  # at most this many steps
REACH_DAMPING = 1e-2  # d in J^T (J J^T + d^2 I)^-1: metres (radians) below which a row stops steering
REACH_STEP = 0.3  # rad or m: the largest change of one coordinate in one step
REACH_NEAR = (0.05, 0.05)  # m, rad: every placement this near its print already, no step


def placement_errors(robot, scene, stance, data):
    """The placement error of every contact of a stance against its print, stacked.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance
    data : pinocchio.Data
        Frame placements and joint Jacobians computed.

    Returns
    -------
    residual : (r,) float
        Each contact's rows in stance order: a surface's 6 (translation in metres,
        rotation in radians, print frame: :func:`stances.contacts.placement_residual`), a
        point foot's 3 (its centre's offset from the point its radius above the print,
        :func:`stances.contacts.point_placement_residual`); a soft print's as if it were
        rigid (its sinking is millimetres).
    rotational : (r,) bool
        Which rows are angles.
    jacobian : (r, nv) float
        Their derivative for a tangent step.
    """
    model = robot.model
    residuals, rotational, jacobians = [], [], []
    for contact in stance:
        surface = robot.surface(contact.robot_surface)
        frame_id = robot.frame_id(surface.frame)
        placement = pin.SE3(scene.transform_print_to_world(contact.contact_print))
        if surface.is_point:
            residual, jacobian = point_placement_residual(model, data, frame_id, placement, surface.radius)
            rotational.extend([False] * 3)
        else:
            residual, jacobian = placement_residual(model, data, frame_id, placement)
            rotational.extend([False] * 3 + [True] * 3)
        residuals.append(residual)
        jacobians.append(jacobian)
    if not residuals:
        return np.zeros(0), np.zeros(0, dtype=bool), np.zeros((0, model.nv))
    return np.concatenate(residuals), np.array(rotational, dtype=bool), np.vstack(jacobians)


def reaching_configuration(robot, scene, stance, q) -> np.ndarray:
    """``q`` moved by damped least-squares steps until the stance's contacts lie on their prints.

    At most :data:`REACH_STEPS` steps ``dq = -J^T (J J^T + d^2 I)^-1 r`` on the placement
    rows alone (:func:`placement_errors`; ``d`` = :data:`REACH_DAMPING`), each scaled so
    that no coordinate moves more than :data:`REACH_STEP`, the joints then clipped to
    their limits; none once every translation error is within ``REACH_NEAR[0]`` metres and
    every rotation error within ``REACH_NEAR[1]`` radians. Collisions, balance and
    torques are the SQP's: this only brings the contacts near where its placement rows
    hold.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance
    q : (nq,) float
        Where to start (e.g. :func:`initial_configuration`).

    Returns
    -------
    (nq,) float
        A new array; ``q``'s values when no step was taken.
    """
    model = robot.model
    data = model.createData()
    q = np.array(q, dtype=float)
    lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    near = np.array(REACH_NEAR)
    for _ in range(REACH_STEPS):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        residual, rotational, jacobian = placement_errors(robot, scene, stance, data)
        if not len(residual) or np.all(np.abs(residual) <= near[rotational.astype(int)]):
            break
        gram = jacobian @ jacobian.T + REACH_DAMPING**2 * np.eye(len(residual))
        step = -jacobian.T @ np.linalg.solve(gram, residual)
        step *= min(1.0, REACH_STEP / np.max(np.abs(step)))
        q = pin.integrate(model, q, step)
        q[7:] = np.clip(q[7:], lower, upper)
    return q


def starting_configuration(problem, q_init) -> np.ndarray:
    """Where a solve of ``problem`` starts: ``q_init`` checked by the problem
    (:meth:`~stances.PostureProblem.check_configuration`), or, when it is None, the
    :func:`initial_configuration` of the problem's stance."""
    if q_init is None:
        q_init = initial_configuration(problem.robot, problem.scene, problem.stance)
    return problem.check_configuration(q_init)


__all__ = ["initial_configuration", "placement_errors", "reaching_configuration", "starting_configuration"]
