"""Quasi-static motion between consecutive stances of a plan.

Two consecutive stances differ by one contact: the robot adds it (a limb
reaches a new print) or removes it (a limb leaves one). Every other contact,
the *support*, is held throughout. A motion is a sequence of postures, each a
posture problem of the support alone (:func:`stances.solve`: static
equilibrium, torque and joint limits, friction cones, collision avoidance, the
soft bodies' FEM forces) with one more constraint: the moving limb's contact
frame sits on a waypoint of a path from where it is in the first stance to
where it is in the second, lifted along the print's normal by a clearance so
that it leaves and reaches its print squarely instead of sliding over it.
Each sample is solved warm-started from the previous one (small steps of a
continuation) and verified by :func:`stances.verify` as a stance of the
support; the motion starts at the first stance's posture and ends at the
second's.

What is not sampled: touch-down and lift-off themselves, the last few
millimetres where the limb meets its print and the load moves onto it (or off
it). Those happen between the stance's own posture, verified with the
contact, and the nearest lifted sample, verified without it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from stances.blocks import PLACEMENT_ACCURACY, equality
from stances.contacts import placement_residual

from .errors import CbmError

__all__ = [
    "FramePlacementConstraint",
    "Motion",
    "MotionError",
    "keep_clear",
    "lifted_path",
    "plan_motion",
    "plan_motions",
    "verify_motion",
]

logger = logging.getLogger(__name__)

#: A sample's frame may miss its waypoint by this much (m and rad), as
#: stances.verify's placements: the SQP meets these rows to PLACEMENT_ACCURACY (1e-7).
PATH_TOLERANCE = 1e-6
#: Fraction of a step's path spent rising (and falling), straight above its ends.
RAMP = 0.25


class MotionError(CbmError):
    """Stances that no motion joins (not differing by one contact, no posture)."""


@dataclass(frozen=True, eq=False)
class FramePlacementConstraint:
    """A robot frame placed at a target (6 equality rows), as a posture-problem constraint.

    Parameters
    ----------
    frame : str
        Frame of ``robot.model``.
    transform_frame_to_world : (4, 4) float
        Where the frame must be, world frame, metres.
    label : str
        Names the rows in an infeasible answer's reason.
    """

    frame: str
    transform_frame_to_world: np.ndarray
    label: str = "path"

    def __post_init__(self):
        transform = np.array(self.transform_frame_to_world, dtype=float)
        if transform.shape != (4, 4):
            raise MotionError(f"transform_frame_to_world must be (4, 4), got {transform.shape}")
        transform.setflags(write=False)
        object.__setattr__(self, "transform_frame_to_world", transform)

    def blocks(self, problem, iterate):
        """Rows ``log6(target^-1 frame) = 0`` and their Jacobian (as a rigid contact's placement)."""
        model, data = problem.robot.model, problem.data
        frame_id = model.getFrameId(self.frame)
        residual, jlog = placement_residual(data, frame_id, pin.SE3(self.transform_frame_to_world))
        jacobian = np.zeros((6, problem.n_step))
        jacobian[:, : model.nv] = jlog @ pin.getFrameJacobian(model, data, frame_id, pin.LOCAL)
        labels = [f"{self.label} ({axis})" for axis in ("x", "y", "z", "roll", "pitch", "yaw")]
        return [equality("frame path", residual, jacobian, 1e-2, labels, PLACEMENT_ACCURACY)]

    def error(self, robot, q):
        """Largest translation (m) or rotation (rad) error of the frame at ``q``."""
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
        error = pin.SE3(self.transform_frame_to_world).actInv(data.oMf[robot.model.getFrameId(self.frame)])
        residual = pin.log6(error).vector
        return float(max(np.linalg.norm(residual[:3]), np.linalg.norm(residual[3:])))


def lifted_path(start, end, normal, clearance, samples, approach=0.015, ramp=RAMP):
    """Waypoints of a step from one placement to another: up, across, down.

    Along ``normal`` the path rises from the start to ``clearance`` above the
    higher end, crosses at that height and comes down to the end (a step onto
    a block clears its edge); across it moves only at the top. The first and
    last waypoints sit ``approach`` straight above the ends (lift-off and
    touch-down). Between them, ``samples`` waypoints at s = k / (samples + 1):
    rising for s < ``ramp``, falling for s > 1 - ``ramp``. Orientations follow
    the geodesic of SO(3), turning with the motion across.

    Parameters
    ----------
    start, end : (4, 4) float
        Placements at s = 0 and s = 1, world frame, metres.
    normal : (3,) float
        Lift direction, world frame (normalised here).
    clearance : float
        Height of the crossing above the higher end, metres.
    samples : int
        Waypoints between the two approach waypoints.
    approach : float
        Lift of the first and last waypoints, metres.
    ramp : float
        Fraction of the path spent going up (and down).

    Returns
    -------
    (samples + 2, 4, 4) float
        Placements, world frame; the ends themselves are not included.

    Examples
    --------
    >>> import numpy as np
    >>> start, end = np.eye(4), np.eye(4)
    >>> end[:3, 3] = [0.3, 0.0, 0.1]  # onto a 10 cm block
    >>> path = lifted_path(start, end, [0, 0, 1], 0.05, 3, approach=0.01, ramp=0.3)
    >>> np.round(path[:, :3, 3], 3).tolist()
    [[0.0, 0.0, 0.01], [0.0, 0.0, 0.125], [0.15, 0.0, 0.15], [0.3, 0.0, 0.142], [0.3, 0.0, 0.11]]
    """
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    normal = np.asarray(normal, dtype=float)
    normal = normal / np.linalg.norm(normal)
    height_start, height_end = start[:3, 3] @ normal, end[:3, 3] @ normal
    top = max(height_start, height_end) + clearance
    s = np.arange(samples + 2) / (samples + 1)
    across = np.clip((s - ramp) / (1.0 - 2.0 * ramp), 0.0, 1.0)
    height = np.where(s < 0.5, height_start + (top - height_start) * np.minimum(s / ramp, 1.0),
                      height_end + (top - height_end) * np.minimum((1.0 - s) / ramp, 1.0))
    height[[0, -1]] = height_start + approach, height_end + approach
    turn = pin.log3(start[:3, :3].T @ end[:3, :3])
    path = np.tile(np.eye(4), (samples + 2, 1, 1))
    for k in range(samples + 2):
        point = (1.0 - across[k]) * start[:3, 3] + across[k] * end[:3, 3]
        path[k, :3, 3] = point + (height[k] - point @ normal) * normal
        path[k, :3, :3] = start[:3, :3] @ pin.exp3(across[k] * turn)
    return path


@dataclass(frozen=True, eq=False)
class Motion:
    """A quasi-static motion from stance ``index`` of a plan to the next.

    Parameters
    ----------
    index : int
        The stance the motion leaves.
    moving_surface : str
        Robot surface that reaches or leaves its print.
    support : environments Stance
        The contacts held throughout (those both stances share).
    configurations : (k, nq) float
        Postures, the first stance's ``q`` first and the second's last;
        between them, one per waypoint (fewer if the motion failed).
    targets : (k - 2, 4, 4) float
        Where the moving surface's frame is held at each interior sample, world
        (the path's waypoints, and any halfway waypoints the solves needed).
    results : tuple of stances PostureResult
        The support's posture solve of each interior sample.
    feasible : bool
        Whether every waypoint was reached by a verified posture.
    reason : str
        Why not (empty when feasible).
    """

    index: int
    moving_surface: str
    support: object
    configurations: np.ndarray
    targets: np.ndarray
    results: tuple
    feasible: bool
    reason: str = ""

    def __post_init__(self):
        for name in ("configurations", "targets"):
            array = np.array(getattr(self, name), dtype=float)
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    def durations(self, joint_speed=0.5, base_speed=0.1):
        """Time between consecutive samples, seconds, at nominal speeds.

        The motion is quasi-static: any slower timing keeps it balanced.

        Parameters
        ----------
        joint_speed : float
            Largest joint speed, rad/s.
        base_speed : float
            Largest speed of the base, m/s.

        Returns
        -------
        (k - 1,) float
        """
        q = self.configurations
        joints = np.abs(np.diff(q[:, 7:], axis=0)).max(axis=1, initial=0.0) / joint_speed
        base = np.linalg.norm(np.diff(q[:, :3], axis=0), axis=1) / base_speed
        return np.maximum(np.maximum(joints, base), 0.05)


def _moving_contact(before, after):
    """The contact two stances do not share, and the support they share."""
    a, b = set(before.contacts), set(after.contacts)
    if len(a ^ b) != 1:
        raise MotionError(
            f"a motion joins stances that differ by exactly one contact; these differ by {len(a ^ b)}: "
            f"{sorted(c.robot_surface for c in a ^ b)}"
        )
    (moving,) = a ^ b
    support = before if len(before) < len(after) else after
    return moving, support


def _frame_placement(robot, q, frame):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return data.oMf[robot.model.getFrameId(frame)].homogeneous


def _options_of(planned):
    """The posture options a planned stance was solved with (its result records them)."""
    statistics = getattr(planned.result, "statistics", None) or {}
    return dict(statistics.get("options", {}))


def keep_clear(path, points, normal, distance):
    """Push waypoints away from points, across the normal, to at least a distance.

    The swing foot of a step passes beside the stance foot, not through it: a
    waypoint closer than ``distance`` to a support print's origin (measured in
    the plane across ``normal``) moves straight away from it in that plane.

    Parameters
    ----------
    path : (k, 4, 4) float
        Waypoints, world frame.
    points : (p, 3) float
        Origins of the prints to keep clear of, world frame.
    normal : (3,) float
        Lift direction, world frame.
    distance : float
        Metres.

    Returns
    -------
    (k, 4, 4) float

    Examples
    --------
    >>> import numpy as np
    >>> path = np.tile(np.eye(4), (1, 1, 1))
    >>> path[0, :3, 3] = [0.1, 0.05, 0.05]
    >>> keep_clear(path, [[0.1, 0.0, 0.0]], [0, 0, 1], 0.2)[0, :3, 3].round(3).tolist()
    [0.1, 0.2, 0.05]
    """
    path = np.array(path, dtype=float)
    normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    for point in np.asarray(points, dtype=float).reshape(-1, 3):
        offset = path[:, :3, 3] - point
        across = offset - np.outer(offset @ normal, normal)
        length = np.linalg.norm(across, axis=1)
        near = (length < distance) & (length > 1e-9)
        path[near, :3, 3] += across[near] * ((distance - length[near]) / length[near])[:, None]
    return path


def plan_motion(plan, index, scenario, robot, *, samples=6, clearance=0.05, clear_distance=0.2, max_splits=2,
                solver_options=None):
    """The quasi-static motion from stance ``index`` of a plan to stance ``index + 1``.

    Parameters
    ----------
    plan : cbm.Plan
    index : int
        Stance the motion leaves.
    scenario : environments Scenario
    robot : stances Robot
    samples : int
        Waypoints of the moving limb across (:func:`lifted_path`; two more,
        straight above each end, make ``samples + 2`` interior postures).
    clearance : float
        Lift of the moving limb off its print, metres, along the print's normal.
    clear_distance : float
        While crossing, the moving frame keeps this far (metres, across the
        normal) from the origin of each support print (:func:`keep_clear`):
        0.2 m lets a Talos sole pass beside the other.
    max_splits : int
        Waypoints no posture reaches from the previous sample are retried from
        a waypoint halfway (a shorter continuation step), at most this many
        times per motion.
    solver_options : dict, optional
        Posture options; default those the arriving stance was solved with.

    Returns
    -------
    Motion
        Solved sample after sample; it stops at the first waypoint no verified
        posture reaches (``feasible`` False and the solver's ``reason``).

    Raises
    ------
    MotionError
        If ``index`` does not name a pair of stances, or they do not differ by
        exactly one contact.
    """
    from .planner import posture_api

    if not 0 <= index < len(plan.stances) - 1:
        raise MotionError(f"stance {index} has no next stance: the plan has {len(plan.stances)} stances")
    before, after = plan.stances[index], plan.stances[index + 1]
    moving, support = _moving_contact(before.stance, after.stance)
    frame = robot.surface(moving.robot_surface).frame
    start = _frame_placement(robot, before.q, frame)
    end = _frame_placement(robot, after.q, frame)
    normal = scenario.scene.transform_print_to_world(moving.contact_print)[:3, 2]
    targets = lifted_path(start, end, normal, clearance, samples)
    # Only the waypoints that move across: those above either end stay where they are.
    s = np.arange(samples + 2) / (samples + 1)
    crossing = (s > RAMP) & (s < 1.0 - RAMP)
    support_points = [scenario.scene.transform_print_to_world(c.contact_print)[:3, 3] for c in support]
    targets[crossing] = keep_clear(targets[crossing], support_points, normal, clear_distance)
    options = _options_of(after) if solver_options is None else dict(solver_options)
    solve, verify = posture_api()
    q, configurations, results, reached, reason = before.q, [before.q], [], [], ""
    pending, last, splits = list(targets), start, 0
    while pending:
        target = pending[0]
        constraint = FramePlacementConstraint(frame, target, f"path of {moving.robot_surface} (sample {len(results) + 1})")
        result = solve(robot, scenario.scene, support, q_init=q, constraints=(constraint,), **options)
        if result.feasible:
            verification = verify(robot, scenario.scene, support, result, **options)
            if not verification.ok:
                result = replace(result, feasible=False, reason="; ".join(map(str, verification.reasons)))
        if result.feasible:
            q, last = result.q, pending.pop(0)
            configurations.append(q)
            results.append(result)
            reached.append(target)
        elif splits < max_splits:
            # A shorter step of the continuation: the waypoint halfway from the last one reached.
            pending.insert(0, _halfway(last, target))
            splits += 1
        else:
            reason = f"sample {len(results) + 1} (of {len(targets)} waypoints, {splits} halved): {result.reason}"
            logger.info("motion %d -> %d stops at %s", index, index + 1, reason)
            break
    feasible = not reason
    if feasible:
        configurations.append(after.q)
    return Motion(index, moving.robot_surface, support, np.array(configurations),
                  np.array(reached).reshape(-1, 4, 4), tuple(results), feasible, reason)


def _halfway(first, second):
    """(4, 4) float: the placement halfway between two, along the SE(3) geodesic."""
    step = pin.log6(pin.SE3(first).actInv(pin.SE3(second)))
    return (pin.SE3(first) * pin.exp6(0.5 * step)).homogeneous


def plan_motions(plan, scenario, robot, **options):
    """The motion between every pair of consecutive stances of a plan.

    Parameters
    ----------
    plan, scenario, robot
        As :func:`plan_motion`.
    **options
        Keyword arguments of :func:`plan_motion`.

    Returns
    -------
    tuple of Motion
        ``len(plan.stances) - 1`` motions, in order.
    """
    return tuple(plan_motion(plan, i, scenario, robot, **options) for i in range(len(plan.stances) - 1))


def verify_motion(motion, plan, scenario, robot, solver_options=None):
    """Check a motion again, sample by sample, independently of its solves.

    Parameters
    ----------
    motion : Motion
    plan : cbm.Plan
        The plan it joins two stances of.
    scenario : environments Scenario
    robot : stances Robot
    solver_options : dict, optional
        As given to :func:`plan_motion`.

    Returns
    -------
    list of str
        Problems, one line each; empty if the motion starts and ends on its
        stances' postures, every interior sample verifies as a stance of the
        support (:func:`stances.verify`) and holds its frame on its waypoint.
    """
    from .planner import posture_api

    verify = posture_api()[1]
    after = plan.stances[motion.index + 1]
    options = _options_of(after) if solver_options is None else dict(solver_options)
    problems = []
    ends = [(0, plan.stances[motion.index].q)] + ([(-1, after.q)] if motion.feasible else [])
    for position, q in ends:
        if not np.array_equal(motion.configurations[position], q):
            problems.append(f"sample {position} is not the posture of its stance")
    frame = robot.surface(motion.moving_surface).frame
    for k, (result, target) in enumerate(zip(motion.results, motion.targets)):
        if not np.array_equal(result.q, motion.configurations[k + 1]):
            problems.append(f"sample {k + 1}: its result is not its posture")
        verification = verify(robot, scenario.scene, motion.support, result, **options)
        if not verification.ok:
            problems.append(f"sample {k + 1}: " + "; ".join(map(str, verification.reasons)))
        error = FramePlacementConstraint(frame, target).error(robot, result.q)
        if error > PATH_TOLERANCE:
            problems.append(f"sample {k + 1}: {motion.moving_surface} is {error:.3g} m or rad off its path")
    return problems
