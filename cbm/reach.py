"""Reach model: which prints a robot's limbs can reach from the contacts it holds.

The planner prunes candidate prints before any posture solve with a cheap
geometric model. Every length in it comes from the robot's own kinematics at
its reference posture, measured once per robot (:meth:`ReachModel.of` caches
it):

- each limb's root (hip, shoulder) relative to the *support frame*, the
  mid-point of the feet with x along their mean heading and z up;
- each limb's stretched length: the sum of the segment lengths from its root
  joint to its contact frame, an upper bound of its reach;
- the feet's sizes (their polygons), for the feet not to overlap;
- where each leg's foot stands relative to the others at the reference
  posture: a quadruped's feet at opposite corners of its body are farther apart
  than a step, so a foot's step is measured from where the reference posture
  puts it relative to such a foot (a biped's feet, less than a step apart,
  are stepped from directly).

Only dimensionless ratios and angles, :class:`ReachLimits`, are planning
choices; their defaults are those the planner was tuned with on Talos
(a 0.4 m step, 0.3 m step height, 0.65 m arm reach), written relative to the
robot's dimensions so that they scale to another robot.

Surfaces are told apart by their role (foot or hand) and limb, never by name.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from .errors import CbmError

__all__ = ["ReachLimits", "LimbReach", "ReachModel", "support_frame", "limb_length"]

# Metres: prints sit on grids, so limits are often met exactly; float noise
# must not decide.
_EPS = 1e-9


@dataclass(frozen=True)
class ReachLimits:
    """Planning ratios applied to the robot's own dimensions.

    Parameters
    ----------
    limb_extension : float
        Fraction of a hand limb's stretched length a print may lie from the
        limb's root (a stretched arm pushes nothing; Talos: 0.85 x 0.774 m =
        0.658 m).
    step_length : float
        Largest horizontal distance between two foot prints, in lengths of
        the stepping leg (Talos: 0.5 x 0.812 m = 0.406 m).
    step_height : float
        Largest height difference between two foot prints, in leg lengths
        (Talos: 0.37 x 0.812 m = 0.300 m).
    foot_lateral : float
        Smallest lateral offset of a foot from another, towards its own side,
        in lateral distances between the two legs' roots: the legs never cross
        (Talos: 0.3 x 0.170 m = 0.051 m).
    foot_clearance : float
        Metres added to a foot's length and width: two foot prints are at
        least that far apart forward or sideways (no overlap).
    max_foot_yaw_difference : float
        Largest angle between two feet's x axes, radians.
    """

    limb_extension: float = 0.85
    step_length: float = 0.5
    step_height: float = 0.37
    foot_lateral: float = 0.3
    foot_clearance: float = 0.01
    max_foot_yaw_difference: float = math.radians(45.0)

    def __post_init__(self):
        for name, value in self.__dict__.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value >= 0):
                raise CbmError(f"ReachLimits.{name} must be a finite non-negative number, got {value!r}")


@dataclass(frozen=True)
class LimbReach:
    """One limb's reach, measured on the robot at its reference posture.

    Parameters
    ----------
    limb : str
        Limb name.
    root_in_support : (3,) float
        Origin of the limb's root joint, metres, support frame.
    length : float
        Stretched length from the root joint to the farthest contact frame of
        the limb, metres.
    foot_in_support : (3,) float or None
        Mean origin of the limb's support surfaces at the reference posture,
        metres, support frame; None for a limb without any.
    """

    limb: str
    root_in_support: np.ndarray = field(repr=False)
    length: float
    foot_in_support: np.ndarray | None = field(default=None, repr=False)


def support_frame(origins, x_axes):
    """Support frames over sets of foot prints: mid-point, mean horizontal heading.

    Parameters
    ----------
    origins : (..., s, 3) float
        Foot print origins, metres, world frame.
    x_axes : (..., s, 3) float
        Foot print x axes, world frame.

    Returns
    -------
    origin : (..., 3) float
        Mean of the origins, metres, world frame.
    rotation : (..., 3, 3) float
        Support frame axes as columns: x the mean heading made horizontal
        (world x if the feet have none), z world up.
    """
    origin = np.mean(origins, axis=-2)
    heading = np.mean(x_axes, axis=-2) * np.array([1.0, 1.0, 0.0])
    norm = np.linalg.norm(heading, axis=-1, keepdims=True)
    heading = np.where(norm > 1e-9, heading / np.maximum(norm, 1e-9), np.array([1.0, 0.0, 0.0]))
    leftward = np.stack([-heading[..., 1], heading[..., 0], np.zeros_like(heading[..., 0])], axis=-1)
    up = np.broadcast_to(np.array([0.0, 0.0, 1.0]), heading.shape)
    return origin, np.stack([heading, leftward, up], axis=-1)


def limb_length(model, data, root_joint: int, frame_id: int) -> float:
    """Stretched length of a chain: segment lengths from a root joint to a frame, summed.

    Parameters
    ----------
    model, data : pinocchio Model and Data
        ``data`` holds the placements of a forward kinematics pass.
    root_joint : int
        First joint of the chain.
    frame_id : int
        End frame, below ``root_joint``.

    Returns
    -------
    float
        Metres; the distance from the root joint to the frame can reach it
        only with every segment aligned.
    """
    points = [data.oMf[frame_id].translation]
    joint = model.frames[frame_id].parentJoint
    while True:
        points.append(data.oMi[joint].translation)
        if joint == root_joint or joint == 0:
            break
        joint = model.parents[joint]
    return float(np.linalg.norm(np.diff(np.array(points), axis=0), axis=1).sum())


_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


@dataclass(frozen=True, eq=False)
class ReachModel:
    """A robot's reach: limb roots and lengths, foot sizes, support rule, planning ratios.

    Build it with :meth:`ReachModel.of`.

    Parameters
    ----------
    roles : dict of str to str
        Robot surface -> role (``"foot"`` or ``"hand"``).
    limbs_of : dict of str to str
        Robot surface -> limb.
    limbs : dict of str to LimbReach
        Limb -> its reach.
    foot_size : (2,) float
        Largest length and width of the feet's polygons, metres.
    support_role : str
        Role of the surfaces a stance must keep down.
    support_keep : int
        How many of them at least.
    limits : ReachLimits
        Planning ratios.
    """

    roles: dict
    limbs_of: dict
    limbs: dict
    foot_size: np.ndarray
    support_role: str = "foot"
    support_keep: int = 1
    limits: ReachLimits = ReachLimits()

    @classmethod
    def of(cls, robot, limits=ReachLimits()) -> "ReachModel":
        """The reach model of a robot, measured once per robot and set of limits.

        Parameters
        ----------
        robot : stances Robot
            Its surfaces (roles, limbs, polygons, frames), limbs' root joints
            and reference posture.
        limits : ReachLimits

        Returns
        -------
        ReachModel

        Raises
        ------
        CbmError
            If the robot has no surface of its support role.

        Examples
        --------
        >>> import stances
        >>> reach = ReachModel.of(stances.Robot.load("talos"))
        >>> round(reach.limbs["left_arm"].length, 3), reach.limbs["left_arm"].root_in_support.round(2).tolist()
        (0.774, [0.01, 0.16, 1.32])
        """
        per_robot = _CACHE.setdefault(robot, {})
        if limits not in per_robot:
            per_robot[limits] = cls._measure(robot, limits)
        return per_robot[limits]

    @classmethod
    def _measure(cls, robot, limits):
        model = robot.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, np.asarray(robot.reference_configuration, dtype=float))
        feet = [name for name, surface in robot.surfaces.items() if surface.role == robot.support.role]
        if not feet:
            raise CbmError(f"robot {robot.name!r} has no {robot.support.role} surface to stand on")
        frames = {name: robot.frame_id(surface.frame) for name, surface in robot.surfaces.items()}
        origin, rotation = support_frame(
            np.array([data.oMf[frames[name]].translation for name in feet]),
            np.array([data.oMf[frames[name]].rotation[:, 0] for name in feet]),
        )
        limbs = {}
        for limb, root_name in robot.limbs.items():
            root = model.getJointId(root_name)
            lengths = [
                limb_length(model, data, root, frames[name]) for name, s in robot.surfaces.items() if s.limb == limb
            ]
            root_in_support = rotation.T @ (data.oMi[root].translation - origin)
            root_in_support.setflags(write=False)
            own_feet = [name for name in feet if robot.surfaces[name].limb == limb]
            foot_in_support = None
            if own_feet:
                foot_in_support = rotation.T @ (np.mean([data.oMf[frames[n]].translation for n in own_feet], axis=0) - origin)
                foot_in_support.setflags(write=False)
            limbs[limb] = LimbReach(limb, root_in_support, max(lengths, default=0.0), foot_in_support)
        foot_size = np.max([np.ptp(robot.surfaces[name].polygon, axis=0) for name in feet], axis=0)
        foot_size.setflags(write=False)
        return cls(
            roles={name: surface.role for name, surface in robot.surfaces.items()},
            limbs_of={name: surface.limb for name, surface in robot.surfaces.items()},
            limbs=limbs,
            foot_size=foot_size,
            support_role=robot.support.role,
            support_keep=robot.support.keep,
            limits=limits,
        )

    @property
    def step_length(self) -> float:
        """The longest step of the shortest leg (a limb carrying a support-role surface), metres."""
        legs = [self.limbs[limb].length for name, limb in self.limbs_of.items() if self.roles[name] == self.support_role]
        return self.limits.step_length * min(legs)

    def supports(self, robot_surfaces) -> list:
        """The surfaces among ``robot_surfaces`` that hold the robot up (its support role)."""
        return [name for name in robot_surfaces if self.roles.get(name) == self.support_role]

    def may_lift(self, robot_surface, in_contact) -> bool:
        """Whether lifting ``robot_surface`` from the contacts ``in_contact`` keeps the support rule."""
        if self.roles.get(robot_surface) != self.support_role:
            return True
        return len(self.supports(in_contact)) > self.support_keep

    def _limb_roots_in_world(self, limb, support_origins, support_x_axes):
        """(..., 3) world positions of a limb's root over sets of support prints."""
        origin, rotation = support_frame(support_origins, support_x_axes)
        return origin + rotation @ self.limbs[limb].root_in_support

    def _within_limb_reach(self, limb, points, support_origins, support_x_axes):
        roots = self._limb_roots_in_world(limb, support_origins, support_x_axes)
        reach = self.limits.limb_extension * self.limbs[limb].length
        return np.linalg.norm(points - roots, axis=-1) <= reach + _EPS

    def _step_mask(self, limb, origins, x_axes, other_limb, other_origin, other_x):
        """Candidate foot prints of ``limb`` within a step of one placed foot of ``other_limb``."""
        limits = self.limits
        leg = self.limbs[limb].length
        delta = origins - other_origin
        # Measured from where the reference posture puts this foot relative to the
        # other, when that is beyond a step (a quadruped's diagonal or opposite feet).
        mine, theirs = self.limbs[limb].foot_in_support, self.limbs[other_limb].foot_in_support
        nominal = np.zeros(3) if mine is None or theirs is None else (mine - theirs) * np.array([1.0, 1.0, 0.0])
        step_delta = delta
        if np.linalg.norm(nominal) > limits.step_length * leg:
            _, rotation = support_frame(other_origin[None], other_x[None])
            step_delta = delta - rotation @ nominal
        mask = np.hypot(step_delta[:, 0], step_delta[:, 1]) <= limits.step_length * leg + _EPS
        mask &= np.abs(delta[:, 2]) <= limits.step_height * leg + _EPS
        mask &= _horizontal_cosine(x_axes, other_x) >= math.cos(limits.max_foot_yaw_difference) - _EPS
        other_left = np.array([-other_x[1], other_x[0], 0.0])
        other_left /= max(np.linalg.norm(other_left), 1e-9)
        lateral = delta @ other_left
        forward = delta @ (other_x * np.array([1.0, 1.0, 0.0])) / max(np.linalg.norm(other_x[:2]), 1e-9)
        # Which side of the other leg this leg is on, from the hips at the reference posture.
        roots_apart = self.limbs[limb].root_in_support[1] - self.limbs[other_limb].root_in_support[1]
        if abs(roots_apart) > _EPS:
            mask &= np.sign(roots_apart) * lateral >= limits.foot_lateral * abs(roots_apart) - _EPS
        length, width = self.foot_size + limits.foot_clearance
        mask &= (np.abs(forward) >= length - _EPS) | (np.abs(lateral) >= width - _EPS)
        return mask

    def reachable_mask(self, print_set, contacts_in_world):
        """Which candidate prints of one robot surface the current contacts can reach.

        Parameters
        ----------
        print_set : cbm.sampling.PrintSet
            Candidates for the robot surface being added (n prints).
        contacts_in_world : mapping of str to tuple ((3,) float, (3,) float)
            The other contacts of the stance: robot surface -> (print origin,
            print x axis), metres, world frame.

        Returns
        -------
        (n,) bool
            For a foot: within a step of every foot in contact (length,
            height, yaw, on its own side, not overlapping it), and every hand
            in contact still within reach of its limb's root over the new set
            of feet. For a hand: within reach of its limb's root over the feet.
            Without any foot in contact, nothing is reachable.
        """
        origins, x_axes = print_set.origins_in_world, print_set.x_axes_in_world
        n = len(print_set)
        adding = print_set.robot_surface
        limb = self.limbs_of[adding]
        feet = {rs: placed for rs, placed in contacts_in_world.items() if self.roles.get(rs) == self.support_role}
        others = {rs: placed for rs, placed in contacts_in_world.items() if rs not in feet}
        if not feet or n == 0:
            return np.zeros(n, dtype=bool)
        foot_origins = np.array([placed[0] for placed in feet.values()])
        foot_x_axes = np.array([placed[1] for placed in feet.values()])
        if self.roles[adding] != self.support_role:
            return self._within_limb_reach(limb, origins, foot_origins, foot_x_axes)
        mask = np.ones(n, dtype=bool)
        for other, (other_origin, other_x) in feet.items():
            mask &= self._step_mask(limb, origins, x_axes, self.limbs_of[other], other_origin, other_x)
        # Support frames over the feet after the step: one per candidate.
        after_origins = np.concatenate([origins[:, None], np.broadcast_to(foot_origins, (n, *foot_origins.shape))], axis=1)
        after_x_axes = np.concatenate([x_axes[:, None], np.broadcast_to(foot_x_axes, (n, *foot_x_axes.shape))], axis=1)
        for other, (other_origin, _) in others.items():
            mask &= self._within_limb_reach(self.limbs_of[other], other_origin, after_origins, after_x_axes)
        return mask


def _horizontal_cosine(vectors, reference):
    """Cosine of the angle between horizontal projections, (n,)."""
    a = np.asarray(vectors, dtype=float)[:, :2]
    b = np.asarray(reference, dtype=float)[:2]
    norms = np.linalg.norm(a, axis=1) * max(np.linalg.norm(b), 1e-12)
    return (a @ b) / np.maximum(norms, 1e-12)
