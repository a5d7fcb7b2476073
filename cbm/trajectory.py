"""A plan's motion as one joint trajectory, written as CSV and NPZ for replay elsewhere."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import CbmError

__all__ = [
    "INTERPOLATION", "JointTrajectory", "ReplayedMotion", "plan_trajectory", "read_trajectory", "write_trajectory",
]

#: How a replay goes from one sample to the next: what the motions' checks between
#: samples (collisions, held contacts' strays) assumed.
INTERPOLATION = ("pinocchio.interpolate between consecutive samples: joints linearly, the free flyer "
                 "along the SE(3) screw motion between its two placements (not position and "
                 "quaternion apart)")


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """Postures in time: the stances of a plan and the motions between them.

    Between two consecutive samples a replay interpolates as :data:`INTERPOLATION`
    says: a motion's samples are placed so that this interpolation keeps clear of
    collisions and keeps every held contact within :data:`cbm.motion.HELD_DRIFT`
    of its line (a failed motion's jump excepted; interpolating the base's
    position and orientation apart strays up to 2.6 mm on built-in plans).

    Parameters
    ----------
    names : tuple of str
        Coordinate names of ``q`` (``Plan.robot["configuration_names"]``):
        the free flyer's x, y, z (m, world), quaternion qx, qy, qz, qw, then
        one angle per joint (rad).
    times : (k,) float
        Seconds from the first stance, increasing.
    q : (k, nq) float
        Configurations.
    stance : (k,) int
        Index of the plan's stance a sample is the posture of, -1 between stances.
    segment : (k,) int
        Index of the stance a sample leaves (its motion), or is.
    locked_joints : dict of str to tuple of float
        Joints held at fixed values, not in ``q`` (the robot's full URDF
        configuration adds them).
    """

    names: tuple
    times: np.ndarray
    q: np.ndarray
    stance: np.ndarray
    segment: np.ndarray
    locked_joints: dict

    def __post_init__(self):
        for name, dtype in (("times", float), ("q", float), ("stance", int), ("segment", int)):
            array = np.array(getattr(self, name), dtype=dtype)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        if self.q.ndim != 2 or self.q.shape[1] != len(self.names) or len(self.times) != len(self.q):
            raise CbmError(
                f"a trajectory needs q of shape (k, {len(self.names)}) and k times; got q {self.q.shape} and "
                f"{len(self.times)} times"
            )
        if np.any(np.diff(self.times) <= 0):
            raise CbmError("trajectory times must increase")

    def motions(self) -> tuple:
        """The motions between stances this trajectory holds, as :class:`ReplayedMotion`
        (a step whose motion was not found has no samples, and no entry)."""
        stance_rows = {int(s): row for row, s in enumerate(self.stance) if s >= 0}
        found = []
        for index in range(len(stance_rows) - 1):
            between = np.flatnonzero((self.segment == index) & (self.stance < 0))
            if between.size:
                rows = [stance_rows[index], *between.tolist(), stance_rows[index + 1]]
                found.append(ReplayedMotion(index, self.q[rows]))
        return tuple(found)


@dataclass(frozen=True)
class ReplayedMotion:
    """A motion between two stances as a saved trajectory holds it: enough to replay it
    (:class:`cbm.live.LiveView` reads ``index``, ``feasible`` and ``configurations``).

    Parameters
    ----------
    index : int
        The stance it leaves.
    configurations : (k, nq) float
        That stance's posture, the motion's samples, the next stance's posture.
    feasible : bool
        Always True: a saved trajectory keeps the samples of found motions only.
    """

    index: int
    configurations: np.ndarray
    feasible: bool = True


def read_trajectory(path) -> "JointTrajectory":
    """A trajectory written by :func:`write_trajectory`, from its ``.npz``.

    Raises
    ------
    CbmError
        If the file lacks an entry a trajectory needs.
    """
    with np.load(path, allow_pickle=False) as data:
        try:
            return JointTrajectory(
                tuple(str(name) for name in data["names"]), data["times"], data["q"], data["stance"],
                data["segment"], {name: tuple(values) for name, values in json.loads(str(data["locked_joints"])).items()},
            )
        except KeyError as error:
            raise CbmError(f"{path}: not a trajectory written by cbm (no entry {error})") from None


def plan_trajectory(plan, motions, **speeds):
    """Join a plan's stances and the motions between them into one trajectory.

    A motion that failed (``feasible`` False) adds none of its samples: the
    trajectory jumps from its stance to the next one there.

    Parameters
    ----------
    plan : cbm.Plan
    motions : sequence of cbm.motion.Motion
        One per pair of consecutive stances, in order.
    **speeds
        Keyword arguments of :meth:`cbm.motion.Motion.durations`.

    Returns
    -------
    JointTrajectory
    """
    if len(motions) != max(len(plan.stances) - 1, 0):
        raise CbmError(f"{len(plan.stances)} stances need {len(plan.stances) - 1} motions, got {len(motions)}")
    q, stance, segment, steps = [plan.stances[0].q], [0], [0], []
    for index, motion in enumerate(motions):
        if motion.feasible:
            samples = motion.configurations[1:]
            steps.extend(motion.durations(**speeds))
        else:
            samples = np.array([plan.stances[index + 1].q])
            steps.append(1.0)
        q.extend(samples)
        stance.extend([-1] * (len(samples) - 1) + [index + 1])
        segment.extend([index] * (len(samples) - 1) + [index + 1])
    times = np.concatenate([[0.0], np.cumsum(steps)])
    names = tuple(plan.robot.get("configuration_names") or (f"q{i}" for i in range(len(q[0]))))
    locked = {name: tuple(values) for name, values in plan.robot.get("locked_joints", {}).items()}
    return JointTrajectory(names, times, np.array(q), stance, segment, locked)


def write_trajectory(trajectory, stem):
    """Write a trajectory as ``<stem>.csv`` and ``<stem>.npz``.

    The CSV has one header row ``time, stance, segment, <names...>, <locked...>`` and
    one row per sample: the locked joints at their fixed values last (a joint of
    several coordinates as ``name[i]``), so that a row is the robot's whole URDF
    configuration; the NPZ holds ``times``, ``q``, ``stance``, ``segment``,
    ``names``, ``locked_joints`` (a JSON string) and ``interpolation`` (how to
    replay between samples, :data:`INTERPOLATION`), readable without pickle.

    Parameters
    ----------
    trajectory : JointTrajectory
    stem : path-like
        Path without suffix.

    Returns
    -------
    tuple of Path
        The CSV and the NPZ.
    """
    stem = Path(stem)
    csv_path, npz_path = stem.with_suffix(".csv"), stem.with_suffix(".npz")
    with open(csv_path, "w", newline="") as stream:
        writer = csv.writer(stream)
        locked = [(name if len(values) == 1 else f"{name}[{i}]", float(value))
                  for name, values in trajectory.locked_joints.items() for i, value in enumerate(values)]
        writer.writerow(["time", "stance", "segment", *trajectory.names, *(name for name, _ in locked)])
        fixed = [repr(value) for _, value in locked]
        for t, s, g, q in zip(trajectory.times, trajectory.stance, trajectory.segment, trajectory.q):
            writer.writerow([f"{t:.6f}", int(s), int(g), *(repr(float(v)) for v in q), *fixed])
    np.savez(
        npz_path, times=trajectory.times, q=trajectory.q, stance=trajectory.stance, segment=trajectory.segment,
        names=np.array(trajectory.names), locked_joints=np.array(json.dumps(trajectory.locked_joints)),
        interpolation=np.array(INTERPOLATION),
    )
    return csv_path, npz_path
