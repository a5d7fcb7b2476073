"""Cheap rejection before a posture solve: links that a rigid print places inside something.

A rigid polygon contact fixes its link's pose completely: the robot surface's
frame lies on the print frame (:class:`stances.contacts.RigidContact`'s six
placement equalities, verified to 1e-6 m and rad). So the link's collision
geometries are known before any solve, and if one of them sinks into another
scene object (a foot on a firm mat overhanging the soft mat next to it) or into
another placed link (a palm on a foot's print), no posture can hold the stance.

The check asks the solver's own :class:`stances.collision.CollisionChecker`,
with the exclusions the posture problem uses (each contact geometry may touch
its own support), at those fixed link poses. The solver keeps every other pair
``collision_distance`` apart (5 mm; 0.1 mm of it may be eaten, and the pairs
``PostureOptions.touching`` names keep 0 m: :func:`stances.terms.kept_distance`),
so a fixed link nearer than that to the scene or to another fixed link, by more
than :data:`PLACED` (what the placement tolerance can move a geometry), has no
posture the solver accepts: a sole set down a few millimetres from the corner of
a mat lying next to its print is refused here, with that distance, instead of
failing its solve on the sole's placement. Soft prints (their links move with the
body) and point feet (they turn freely) place nothing and are left to the solver.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from stances.terms import COLLISION_SLACK, kept_distance

__all__ = ["PrintCollisionFilter", "PLACED", "PRINTS_COLLIDE"]

#: Metres a fixed link's geometry may lie off its print pose in an accepted posture,
#: bounded well above the placement tolerance (1e-6 m and rad, a metre from the print).
PLACED = 1e-5

#: How every rejection's reason starts (cbm.rejections files it under collision).
PRINTS_COLLIDE = "collision of a placed link"

# Where geometries of links that no print fixes are put: out of every pair's
# reach, 100 m from each other (so the broad phase drops their pairs too).
_FAR_AWAY, _APART = np.array([0.0, 0.0, 1e4]), np.array([100.0, 0.0, 0.0])


class PrintCollisionFilter:
    """Rejects stances whose rigid prints put a link into the scene or into another placed link.

    Parameters
    ----------
    robot : stances Robot
    scene : environments Scene
    options : stances PostureOptions, optional
        The options ``stances.solve`` runs with (default: its defaults):
        ``self_collision`` and ``deformable_as_rigid`` are read.

    Examples
    --------
    >>> import environments, stances
    >>> scenario = environments.load("step-on-cube")
    >>> check = PrintCollisionFilter(stances.Robot.load(scenario.robot), scenario.scene)
    >>> check(scenario.stance("step-on-cube"))
    ''
    """

    def __init__(self, robot, scene, options=None):
        from stances.collision import CollisionChecker
        from stances.problem import PostureOptions, touching_pairs

        self.options = options if options is not None else PostureOptions()
        self.robot = robot
        self.scene = scene
        self._checker = CollisionChecker(robot, scene.collision_objects(), margin=self.options.collision_distance,
                                         self_collision=self.options.self_collision)
        # The pairs the solve lets touch keep less than the others.
        self._touching = touching_pairs(robot, scene, self.options)
        geometries = robot.collision_model.geometryObjects
        self._joints = np.array([g.parentJoint for g in geometries], dtype=int)
        self._in_joint = np.array([g.placement.homogeneous for g in geometries]).reshape(-1, 4, 4)

    def __call__(self, stance) -> str:
        """``""`` if no fixed link collides, else the deepest collision (starting with :data:`PRINTS_COLLIDE`).

        Raises
        ------
        environments.SceneError, stances.StanceError
            For a print on an unknown surface or an unknown robot surface.
        """
        from stances.collision import contact_exclusions

        model = self.robot.model
        joint_to_world = {}
        excluded = []
        for contact in stance:
            surface = self.scene.surface(contact.contact_print.surface)
            robot_surface = self.robot.surface(contact.robot_surface)
            excluded.extend(contact_exclusions(self.robot, robot_surface.frame, surface.object_name))
            if robot_surface.is_point or (surface.deformable and not self.options.deformable_as_rigid):
                continue
            p = contact.contact_print
            print_to_world = pin.SE3(surface.transform_print_to_world(p.x, p.y, p.theta))
            frame = model.frames[self.robot.frame_id(robot_surface.frame)]
            joint_to_world[frame.parentJoint] = (print_to_world * frame.placement.inverse()).homogeneous
        if not joint_to_world:
            return ""
        placements = np.tile(np.eye(4), (len(self._joints), 1, 1))
        placements[:, :3, 3] = _FAR_AWAY + np.arange(len(self._joints))[:, None] * _APART
        for joint, transform in joint_to_world.items():
            rows = self._joints == joint
            placements[rows] = transform @ self._in_joint[rows]
        pairs = self._checker.with_exclusions(excluded).pairs(model, None, geometry_placements=placements)
        fixed = set(joint_to_world)
        colliding = [
            pair
            for pair in pairs
            if pair.joint_a in fixed and (pair.joint_b == 0 or pair.joint_b in fixed)
            and pair.distance < self._least((pair.name_a, pair.name_b)) - PLACED
        ]
        if not colliding:
            return ""
        deepest = min(colliding, key=lambda pair: pair.distance)
        if deepest.distance < 0.0:
            return (
                f"{PRINTS_COLLIDE}: at its print, {deepest.name_a} sinks {-deepest.distance:.3g} m into "
                f"{deepest.name_b} whatever the posture"
            )
        kept = self._least((deepest.name_a, deepest.name_b))
        return (
            f"{PRINTS_COLLIDE}: at its print, {deepest.name_a} comes within {1e3 * deepest.distance:.3g} mm of "
            f"{deepest.name_b} whatever the posture, where the solver keeps every link {1e3 * kept:.3g} mm away"
        )

    def _least(self, pair) -> float:
        """The least distance of a pair in a posture the solve accepts, metres (:func:`stances.terms.kept_distance`)."""
        return kept_distance(pair, self.options.collision_distance, self._touching) - COLLISION_SLACK
