"""Where a posture solve starts when it is given no posture: the reference posture over the stance.

The robot's reference posture stands at the world origin. A stance elsewhere (on a
block, on a cube 0.3 m up, turned) then starts with its feet tens of centimetres from
their prints and its legs inside the supports, where the linearised collision rows
point sideways: measured on step-on-cube's rigid warm start, the SQP's path then
depended on the last bits of its first QPs (its feet crossed in a third of the QP
solver settings tried, and the stance came back infeasible). Moved over its prints,
the same posture needs a few small steps.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


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


def starting_configuration(problem, q_init) -> np.ndarray:
    """Where a solve of ``problem`` starts: ``q_init`` checked by the problem
    (:meth:`~stances.PostureProblem.check_configuration`), or, when it is None, the
    :func:`initial_configuration` of the problem's stance."""
    if q_init is None:
        q_init = initial_configuration(problem.robot, problem.scene, problem.stance)
    return problem.check_configuration(q_init)


__all__ = ["initial_configuration", "starting_configuration"]
