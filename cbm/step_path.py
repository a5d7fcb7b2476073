"""The path of a moving limb between two placements: up, across, down.

Pure geometry on SE(3) placements (world frame, metres), used by
:mod:`cbm.motion` for the waypoints its postures hold the limb on.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

__all__ = ["RAMP", "lifted_path", "halfway"]

#: Fraction of a step's path spent rising (and falling), straight above its ends.
RAMP = 0.25


def lifted_path(start, end, normal, clearance, samples, approach=0.015, ramp=RAMP, retreat=None):
    """Waypoints of a step from one placement to another: up, across, down.

    Along ``normal`` the path rises from the start to ``clearance`` above the
    higher end, crosses at that height and comes down to the end (a step onto
    a block clears its edge); across it moves only at the top. The first and
    last waypoints sit ``approach`` straight above the ends (lift-off and
    touch-down). Between them, ``samples`` waypoints at s = k / (samples + 1):
    rising for s < ``ramp``, falling for s > 1 - ``ramp``. Orientations follow
    the geodesic of SO(3), turning with the motion across. With ``retreat``, the
    path moves by that offset as it rises (none at the approach waypoint, all of it
    at the top) and takes it back as it crosses, or, given for the end, mirrored: a
    detour for a limb that hangs beside the support it reaches for.

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
    retreat : tuple of two (3,) float or None, optional
        Offsets (world, metres) reached at the top of the rise from the start and
        kept from the top of the fall to the end; None for none at either end.

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
    away = [np.zeros(3) if offset is None else np.asarray(offset, dtype=float) for offset in (retreat or (None, None))]
    path = np.tile(np.eye(4), (samples + 2, 1, 1))
    for k in range(samples + 2):
        point = (1.0 - across[k]) * start[:3, 3] + across[k] * end[:3, 3]
        path[k, :3, 3] = point + (height[k] - point @ normal) * normal
        if retreat is not None:
            path[k, :3, 3] += away[0] * min(s[k] / ramp, 1.0) * (1.0 - across[k])
            path[k, :3, 3] += away[1] * min((1.0 - s[k]) / ramp, 1.0) * across[k]
        path[k, :3, :3] = start[:3, :3] @ pin.exp3(across[k] * turn)
    return path


def halfway(first, second):
    """(4, 4) float: the placement halfway between two, along the SE(3) geodesic."""
    step = pin.log6(pin.SE3(first).actInv(pin.SE3(second)))
    return (pin.SE3(first) * pin.exp6(0.5 * step)).homogeneous
