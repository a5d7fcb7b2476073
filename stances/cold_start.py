"""Where a posture solve starts when it is given no posture: the reference posture over the
stance, its links then brought onto their prints by inverse kinematics.

The robot's reference posture stands at the world origin. A stance elsewhere (on a
block, on a cube 0.3 m up, turned) then starts with its feet tens of centimetres from
their prints and its legs inside the supports, where the linearised collision rows
point sideways: measured on step-on-cube's rigid warm start, the SQP's path then
depended on the last bits of its first QPs (its feet crossed in a third of the QP
solver settings tried, and the stance came back infeasible). Moved over its prints,
the same posture needs a few small steps (:func:`initial_configuration`).

A hand still has to reach its print, and every SQP iteration that moves it there
solves a QP over the whole problem (forces, torques, collisions: 5-15 ms on
hand-on-cube). Damped least squares on the placement rows alone (:func:`reach_prints`,
about 0.1 ms a step) gets there first; the SQP then balances the posture.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

_REACH_STEPS = 30  # damped least-squares steps at most (hand-on-cube's palm: 24)
_REACH_DAMPING = 1e-3  # Levenberg-Marquardt damping, squared residual units (m, rad)
_REACH_TOLERANCE = 1e-4  # m or rad: placements nearer than this are reached
_REACH_MAX_DAMPING = 1e6  # damping beyond which no step lowers the residual: stop


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
        stance uses lies over the mid-point of their prints (without a foot in
        the stance: all its feet over all its prints) and turned to their mean
        heading about world z. An empty stance gives the reference posture.
    """
    q = np.array(robot.reference_configuration, dtype=float)
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    feet = robot.surfaces_with_role(robot.support.role)
    contacts = [c for c in stance if c.robot_surface in feet]
    # The same feet on both sides: a quadruped on three feet puts those three
    # over their prints, not the mid-point of all four.
    used = [c.robot_surface for c in contacts] or list(feet)
    contacts = contacts or list(stance)
    if not contacts:
        return q
    reference_feet = np.mean([data.oMf[model.getFrameId(robot.surfaces[s].frame)].translation for s in used], axis=0)
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


def reach_prints(problem, q) -> np.ndarray:
    """Bring the stance's links onto their prints: inverse kinematics from ``q``.

    Levenberg-Marquardt steps ``-(J^T J + mu I)^-1 J^T r`` (damped least squares) on
    the placement residuals ``r`` of the problem's rigid and point contacts
    (:func:`stances.contacts.placement_residual`), base included: each step within
    the SQP's trust region, the joints within the limits the SQP keeps, and kept
    only where it lowers ``|r|^2``. Equilibrium, torques and collisions are left to the SQP that starts
    from the answer. Soft prints are not moved (the SQP places them with their
    indentation).

    Parameters
    ----------
    problem : stances.PostureProblem
    q : (nq,) float
        Start configuration.

    Returns
    -------
    (nq,) float
        The configuration reached: the placements met within 0.1 mm and 0.1 mrad, or
        the last step's when that is not possible (a print out of reach).
    """
    model = problem.robot.model
    data = model.createData()
    held = [c for c in problem.contacts if c.kind == "rigid"]  # rigid and point contacts
    q = np.array(q, dtype=float)
    if not held:
        return q

    def placements(q):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        rows = [c.placement(model, data) for c in held]
        return np.concatenate([r for r, _ in rows]), np.vstack([j for _, j in rows])

    step_bound = problem.options.trust_region
    damping = _REACH_DAMPING
    residual, jacobian = placements(q)
    for _ in range(_REACH_STEPS):
        if np.max(np.abs(residual)) < _REACH_TOLERANCE:
            break
        # A step is kept only if it lowers the squared residual; otherwise the damping
        # grows (shorter, steeper steps) until one does, or it is given up: a print out
        # of reach, where the clamped joints leave no descent.
        while damping <= _REACH_MAX_DAMPING:
            step = -np.linalg.solve(jacobian.T @ jacobian + damping * np.eye(model.nv), jacobian.T @ residual)
            trial = pin.integrate(model, q, np.clip(step, -step_bound, step_bound))
            trial[7:] = np.clip(trial[7:], problem.q_lower, problem.q_upper)
            trial_residual, trial_jacobian = placements(trial)
            if trial_residual @ trial_residual < residual @ residual:
                q, residual, jacobian = trial, trial_residual, trial_jacobian
                damping = max(damping / 10.0, _REACH_DAMPING)
                break
            damping *= 10.0
        else:
            break
    return q


__all__ = ["initial_configuration", "reach_prints"]
