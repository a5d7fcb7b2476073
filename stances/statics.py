"""Joint torques of a robot holding still under point forces, and their derivatives.

A posture problem's forces are *point forces*: a force vector given in the
world frame, applied at a point rigidly attached to a link. Rigid-contact forces
keep a world-fixed direction (the print's friction-cone generators); the
application point moves with the link. The static joint torques are

    tau(q, f) = g(q) - sum_k J_k(q)^T f_k                                (47, 49)

where ``J_k`` is the translational world-aligned Jacobian of point ``k``. The
first six rows (free flyer) must vanish for static equilibrium (49); the other
rows must stay within the torque limits (47).

Pinocchio's ``computeStaticTorqueDerivatives`` differentiates ``tau`` with the
external forces held fixed *in the joint frames*. A world-fixed force rotates
in its joint frame when the joint rotates; :func:`static_torque_derivatives`
adds that term, so the result is the exact derivative for world-fixed forces.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin


@dataclass(frozen=True)
class PointLoads:
    """Where point forces act on the robot, independent of their values.

    Parameters
    ----------
    joints : (k,) int
        Pinocchio joint index carrying each point.
    points_in_joint : (k, 3) float
        Application points, metres, in their joint's frame.
    """

    joints: np.ndarray
    points_in_joint: np.ndarray

    def __post_init__(self) -> None:
        joints = np.asarray(self.joints, dtype=int).reshape(-1)
        points = np.asarray(self.points_in_joint, dtype=float).reshape(-1, 3)
        if len(joints) != len(points):
            raise ValueError(f"{len(joints)} joints for {len(points)} points")
        for array in (joints, points):
            array.setflags(write=False)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "points_in_joint", points)

    def __len__(self) -> int:
        return len(self.joints)

    @cached_property
    def groups(self) -> tuple:
        """``(joint, take, skews, levers)`` of each loaded joint, ascending, made once (every
        linearisation and evaluation reads them):

        - ``take`` selects the joint's points (a slice where they are consecutive, as
          each contact's are; else their sorted indices);
        - ``skews``, (n, 3, 3): their cross-product matrices ``[p]x``;
        - ``levers``, (3, 3n): the same side by side, so that ``levers @ f.ravel()`` sums
          ``p x f`` over the joint's points.
        """
        out = []
        for joint in np.unique(self.joints).tolist():
            rows = np.flatnonzero(self.joints == joint)
            consecutive = rows[-1] - rows[0] == len(rows) - 1
            take = slice(int(rows[0]), int(rows[-1]) + 1) if consecutive else rows
            skews = _skews(self.points_in_joint[rows])
            levers = np.ascontiguousarray(skews.transpose(1, 0, 2).reshape(3, -1))
            for array in (rows, skews, levers):
                array.setflags(write=False)
            out.append((joint, take, skews, levers))
        return tuple(out)

    @staticmethod
    def concatenate(loads) -> "PointLoads":
        """Stack several :class:`PointLoads` into one, in order."""
        loads = list(loads)
        if not loads:
            return PointLoads(np.zeros(0, dtype=int), np.zeros((0, 3)))
        return PointLoads(
            np.concatenate([load.joints for load in loads]),
            np.concatenate([load.points_in_joint for load in loads]),
        )


def points_in_world(data: pin.Data, loads: PointLoads) -> np.ndarray:
    """World positions of the application points.

    Parameters
    ----------
    data : pinocchio.Data
        After forward kinematics at the configuration of interest.
    loads : PointLoads

    Returns
    -------
    (k, 3) float
        Points, metres, world frame.
    """
    out = np.empty((len(loads), 3))
    # One product per joint: a deformable print puts dozens of points on one link.
    for joint, take, _, _ in loads.groups:
        placement = data.oMi[joint]
        out[take] = loads.points_in_joint[take] @ placement.rotation.T + placement.translation
    return out


def _external_forces(model, data, loads: PointLoads, forces_in_world: np.ndarray):
    """Per-joint spatial forces (local frames) and the local force vectors."""
    # Vectorised per joint: a soft print has hundreds of point loads, and a
    # per-point loop of small numpy calls cost 17 % of a soft posture solve.
    forces_in_world = np.asarray(forces_in_world, dtype=float)
    forces_local = np.empty_like(forces_in_world)
    # Zero wrenches on every joint but the loaded ones.
    fext = zero_wrenches(model.njoints)
    for joint, take, _, levers in loads.groups:
        local = forces_in_world[take] @ data.oMi[joint].rotation  # R^T f, row-wise
        forces_local[take] = local
        # sum p x R^T f in one product with the points' cross-product matrices (a
        # column_stack of the three components cost a tenth of a rigid linearisation).
        fext[joint] = pin.Force(local.sum(axis=0), levers @ local.ravel())
    return fext, forces_local


_ZERO_FORCES: dict = {}


def zero_wrenches(count: int):
    """A new ``pin.StdVec_Force`` of ``count`` zero wrenches: a copy of one made once per
    count (building it wrench by wrench took 11 us a call)."""
    known = _ZERO_FORCES.get(count)
    if known is None:
        known = _ZERO_FORCES[count] = pin.StdVec_Force()
        for _ in range(count):
            known.append(pin.Force.Zero())
    return pin.StdVec_Force(known)


def static_torques(model, data, q, loads: PointLoads, forces_in_world) -> np.ndarray:
    """Generalised torques holding the robot still at ``q`` under the point forces.

    Parameters
    ----------
    model : pinocchio.Model
    data : pinocchio.Data
    q : (nq,) float
        Configuration.
    loads : PointLoads
        Application points.
    forces_in_world : (k, 3) float
        Forces applied ON the robot, newtons, world frame.

    Returns
    -------
    (nv,) float
        ``g(q) - sum_k J_k^T f_k`` (eqs. 47, 49): free-flyer rows are the
        unbalanced wrench, the rest are the joint torques, N m.
    """
    pin.forwardKinematics(model, data, q)
    fext, _ = _external_forces(model, data, loads, np.asarray(forces_in_world).reshape(-1, 3))
    return pin.computeStaticTorque(model, data, q, fext).copy()


def static_torque_derivatives(model, data, q, loads: PointLoads, forces_in_world):
    """Torques and their exact derivatives for world-fixed point forces.

    Parameters
    ----------
    model, data : pinocchio Model and Data
    q : (nq,) float
        Configuration.
    loads : PointLoads
        Application points (fixed on their links).
    forces_in_world : (k, 3) float
        Forces ON the robot, newtons, world frame, held fixed in the world.

    Returns
    -------
    tau : (nv,) float
        Same as :func:`static_torques`.
    dtau_dq : (nv, nv) float
        Derivative with respect to a tangent step ``dq`` (``q (+) dq``).
    dtau_dforces : (nv, 3k) float
        Derivative with respect to the stacked world forces (``-J_k^T``).
    """
    forces_in_world = np.asarray(forces_in_world, dtype=float).reshape(-1, 3)
    pin.computeJointJacobians(model, data, q)
    fext, forces_local = _external_forces(model, data, loads, forces_in_world)
    tau = pin.computeStaticTorque(model, data, q, fext).copy()
    dtau_dq = pin.computeStaticTorqueDerivatives(model, data, q, fext).copy()

    nv = model.nv
    dtau_dforces = np.zeros((nv, 3 * len(loads)))
    # Group forces by joint: the rotation term involves each joint's Jacobian once.
    per_load = dtau_dforces.reshape(nv, len(loads), 3)
    for joint, take, skews, _ in loads.groups:
        jacobian_local = pin.getJointJacobian(model, data, joint, pin.LOCAL)
        rotation = data.oMi[joint].rotation
        points, local = loads.points_in_joint[take], forces_local[take]
        # d(R^T f) = [R^T f]x omega_local; d(p x R^T f) = [p]x [R^T f]x omega_local,
        # summed over the joint's loads with [p]x [f]x = f p^T - (p . f) I.
        x, y, z = local.sum(axis=0).tolist()
        d_wrench = np.empty((6, 3))
        d_wrench[:3] = ((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0))
        np.matmul(local.T, points, out=d_wrench[3:])
        dot = d_wrench[3:].trace()  # sum of p . f
        d_wrench[3, 0] -= dot
        d_wrench[4, 1] -= dot
        d_wrench[5, 2] -= dot
        dtau_dq -= jacobian_local.T @ (d_wrench @ jacobian_local[3:])
        # tau = ... - J^T [R^T f; p x R^T f] for each load.
        linear = jacobian_local[:3].T @ rotation.T  # (nv, 3)
        # angular[v, n, k] = (J_w^T [p_n]x R^T)[v, k]: one matrix product over all the
        # joint's loads (a three-index einsum took 1.5 ms per call on a sole pair's 114
        # print nodes, the largest cost of a soft linearisation).
        levers = (skews @ rotation.T).transpose(1, 0, 2).reshape(3, -1)  # (3, n * 3)
        angular = (jacobian_local[3:].T @ levers).reshape(nv, len(skews), 3)
        per_load[:, take, :] = -(linear[:, None, :] + angular)
    return tau, dtau_dq, dtau_dforces


def _skews(vectors: np.ndarray) -> np.ndarray:
    """(n, 3, 3) cross-product matrices of (n, 3) vectors."""
    out = np.zeros((len(vectors), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -vectors[:, 2], vectors[:, 1]
    out[:, 1, 0], out[:, 1, 2] = vectors[:, 2], -vectors[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -vectors[:, 1], vectors[:, 0]
    return out


def point_jacobians(model, data, loads: PointLoads) -> np.ndarray:
    """Translational world-aligned Jacobians of the application points.

    Requires ``pin.computeJointJacobians`` (or ``static_torque_derivatives``)
    to have run at the current configuration.

    Returns
    -------
    (k, 3, nv) float
        ``d p_k / d q`` for a tangent step, world frame.
    """
    out = np.empty((len(loads), 3, model.nv))
    for joint, take, _, _ in loads.groups:
        jacobian = pin.getJointJacobian(model, data, joint, pin.LOCAL_WORLD_ALIGNED)
        levers = loads.points_in_joint[take] @ data.oMi[joint].rotation.T
        out[take] = jacobian[:3][None] - _skews(levers) @ jacobian[3:]
    return out
