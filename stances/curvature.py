"""Second-order information of the constraints: the curvature part of the Lagrangian's Hessian.

The SQP's QP Hessian is, without this module, the objective's (Gauss-Newton)
Hessian alone; the iterations then converge linearly, at a rate set by the
constraints' curvature times their multipliers (hand-on-table: 0.63 per
iteration). Adding

    sum_i y_i d^2 c_i(q (+) dq) / d dq^2     at dq = 0,  (nv, nv)

with the multipliers ``y`` of the previous QP gives the Lagrangian's Hessian,
the model Newton's method needs.

How it is computed. A block of rows that models its curvature carries a
``second_order`` function (:class:`~stances.blocks.ConstraintBlock`): given
pinocchio data holding the kinematics and joint Jacobians of any configuration
q', it returns ``sum_i y_i grad c_i(q')``, the rows' weighted Jacobian in the
tangent space at q' (a collision row measures its pair again there: new witness
points and normal). The Hessian is the forward difference of that gradient
along each tangent direction, chained through ``pin.dIntegrate`` so that it is
the Hessian of ``dq -> sum_i y_i c_i(q (+) dq)``, the function the QP models.
Each block is differenced only along the columns it moves with (the free flyer
and the joints above its link): one kinematics pass per column.

Rows that are a function of one frame's placement (a rigid contact's placement,
``log6`` of the frame against its print; a point foot's centre) also carry a
``curvature`` function, used instead: with ``G`` the function's gradient for a
motion of the frame in its own axes, its Hessian along the joints' motions is
``J^T dG J + G . dJ`` (:func:`frame_curvature`; ``dJ`` from pinocchio's kinematic
Hessians, ``dG`` by central differences on SE(3), six pairs of cheap calls), plus
the configuration space's own term (the free flyer's ``dIntegrate`` moves with
the step). Measured on foot-on-block's two soles: 0.22 ms a Hessian against
0.56 ms by differences, equal to 1.2e-6 (the differences' truncation error).
The collision rows (the normal turns, witness points slide) keep the
differences: within 1e-5 of a second difference for a self-collision distance.

Convexification: :func:`bounded_below` cuts the curvature where it would
bring the QP's Hessian below a fraction of a positive definite reference (the
objective's Hessian, made large across the active rows); see
:func:`stances.sqp._with_curvature` for the reference and what was measured.
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin
import scipy.linalg

__all__ = ["ConstraintCurvature", "bounded_below", "frame_curvature"]

# Forward-difference step along a tangent direction, rad or m. Truncation error:
# about step * third derivative (1.5e-6 on hand-on-table's placement rows);
# rounding: 1e-16 / step. Not smaller: where a distance between hulls has a kink
# (parallel faces), a difference across it reads jump / step, and 1e-7 gave
# curvatures of 17 where the distance's are 0.04.
_STEP = 1e-5
_SUPPORT = 1e-10  # Jacobian entries below this fraction of a block's largest are rounding
# Central-difference step of a frame function's local gradient on SE(3) (frame_curvature):
# its error, step^2 times a third derivative of order one, against rounding 1e-16 / step.
_GROUP_STEP = 1e-5
_GROUP_STEPS = [(pin.exp6(step), pin.exp6(-step)) for step in _GROUP_STEP * np.eye(6)]


class ConstraintCurvature:
    """Hessians of weighted constraint rows in the tangent step, by differences
    of their analytic Jacobians.

    Parameters
    ----------
    model : pinocchio.Model
        The robot (or any) model the rows are written on; a private
        ``Data`` is kept so the problem's own is left as it is.
    """

    def __init__(self, model):
        self.model = model
        self.data = pin.Data(model)
        self._curved, self._integration = _integration_curvature(model)

    def hessian(self, q, blocks, weights) -> np.ndarray:
        """``d^2 / d dq^2 sum_b weights_b . c_b(q (+) dq)`` at ``dq = 0``.

        Parameters
        ----------
        q : (nq,) float
            Configuration of the linearisation the blocks come from.
        blocks : sequence of ConstraintBlock
            Blocks without ``second_order`` are taken as linear (they add nothing).
        weights : sequence of (r_b,) float or None
            One per block: the rows' multipliers, in the rows' own units (row
            value times weight is in the objective's units); None or zeros skip it.

        Returns
        -------
        (nv, nv) float
            Symmetric.
        """
        model, data = self.model, self.data
        nv = model.nv
        used = [
            (block, np.asarray(weight, float))
            for block, weight in zip(blocks, weights)
            if block.second_order is not None and weight is not None and np.any(weight != 0.0)
        ]
        hessian = np.zeros((nv, nv))
        if not used:
            return hessian
        self._kinematics(q)
        direct = [(block, weight) for block, weight in used if block.curvature is not None]
        if direct:
            pin.computeJointKinematicHessians(model, data)
            gradient = np.zeros(nv)
            for block, weight in direct:
                hessian += block.curvature(model, data, weight)
                gradient += weight @ block.jacobian[:, :nv]
            # The configuration space's own term: a step dq integrates through
            # pin.integrate, whose differential moves with dq on the free flyer.
            hessian[:, self._curved] += np.einsum("kij,i->jk", self._integration, gradient)
        differenced = [(block, weight) for block, weight in used if block.curvature is None]
        if differenced:
            hessian += self._differences(q, differenced)
        return 0.5 * (hessian + hessian.T)

    def _differences(self, q, used) -> np.ndarray:
        """The blocks' Hessian by forward differences of their ``second_order``, the
        kinematics at ``q`` already in :attr:`data`."""
        model, data = self.model, self.data
        nv = model.nv
        hessian = np.zeros((nv, nv))
        # Each block is differenced along the columns its weighted rows move
        # with (a row that does not move with a joint has no curvature along
        # it; a self-collision distance does not change with the free flyer,
        # whose columns then hold rounding specks only).
        columns = []
        for block, weight in used:
            rows = np.abs(block.jacobian[weight != 0.0, :nv])
            columns.append(np.any(rows > _SUPPORT * rows.max(initial=0.0), axis=0))
        columns = np.array(columns)
        base = np.array([block.second_order(model, data, weight) for block, weight in used])
        direction = np.zeros(nv)
        for k in np.flatnonzero(columns.any(axis=0)):
            direction[k] = _STEP
            self._kinematics(pin.integrate(model, q, direction))
            # The gradient at q' lives in q''s tangent space; dIntegrate maps it
            # back to the step dq at q.
            chain = pin.dIntegrate(model, q, direction, pin.ARG1)
            moving = np.flatnonzero(columns[:, k])
            moved = sum(used[b][0].second_order(model, data, used[b][1]) for b in moving)
            hessian[:, k] = (chain.T @ moved - base[moving].sum(axis=0)) / _STEP
            direction[k] = 0.0
        return hessian

    def _kinematics(self, q) -> None:
        pin.computeJointJacobians(self.model, self.data, q)  # also the joint placements
        pin.updateFramePlacements(self.model, self.data)


def _integration_curvature(model):
    """The tangent directions along which ``pin.dIntegrate(model, q, dq, ARG1)`` moves at
    ``dq = 0``, and its derivative along each: ``(k,)`` int and ``(k, nv, nv)`` float,
    read-only.

    Only the joints on a curved group (the free flyer's SE(3), a spherical joint's
    SO(3)) have one, and it does not depend on q there (the derivative of the
    group's exponential's Jacobian at the identity): it is taken once per kind of
    model (its joints' types, in order: 2 nv calls of ``dIntegrate`` and an (nv, nv,
    nv) array, once a solve when made per curvature object), by central differences,
    exact to rounding for these maps (their Jacobians are even in dq up to the odd
    term read here).
    """
    key = tuple(joint.shortname() for joint in model.joints)
    known = _INTEGRATION_CURVATURES.get(key)
    if known is None:
        known = _INTEGRATION_CURVATURES[key] = _integration_curvature_of(model)
    return known


_INTEGRATION_CURVATURES: dict = {}  # joint types -> _integration_curvature's answer


def _integration_curvature_of(model):
    q, nv = pin.neutral(model), model.nv
    step = 1e-4
    derivatives = np.zeros((nv, nv, nv))
    for k in range(nv):
        direction = np.zeros(nv)
        direction[k] = step
        derivatives[k] = (pin.dIntegrate(model, q, direction, pin.ARG1)
                          - pin.dIntegrate(model, q, -direction, pin.ARG1)) / (2.0 * step)
    curved = np.flatnonzero(np.abs(derivatives).max(axis=(1, 2)) > 1e-9)
    derivatives = derivatives[curved]
    for array in (curved, derivatives):
        array.setflags(write=False)
    return curved, derivatives


def frame_curvature(model, data, frame_id, local_gradient) -> np.ndarray:
    """Second derivative of ``dq -> phi(oMf(q (+) dq))`` along the joints' motions.

    For a function ``phi`` of a frame's placement with local gradient ``G(M)`` (its
    derivative for a motion ``M exp(v)``, ``v`` a twist in the frame, (6,)): ``J^T
    dG J + G . dJ``, with ``J`` the frame's local Jacobian and ``dJ`` its derivative
    (pinocchio's kinematic Hessian of the parent joint, moved to the frame). The
    configuration space's own term (:func:`_integration_curvature`) is added by
    :meth:`ConstraintCurvature.hessian`.

    Parameters
    ----------
    model, data : pinocchio Model and Data
        Frame placements, joint Jacobians and kinematic Hessians computed.
    frame_id : int
    local_gradient : callable
        ``pin.SE3 -> (6,)``, ``G`` (linear then angular part). Its own derivative
        ``dG`` is taken by central differences on the group (6 pairs of calls).

    Returns
    -------
    (nv, nv) float
        Not symmetrised (it is symmetric once the configuration space's term is in).
    """
    frame = model.frames[frame_id]
    placement = data.oMf[frame_id]
    jacobian = pin.getFrameJacobian(model, data, frame_id, pin.LOCAL)
    gradient = local_gradient(placement)
    derivative = np.empty((6, 6))
    for c, (forward, backward) in enumerate(_GROUP_STEPS):
        derivative[:, c] = (local_gradient(placement * forward) - local_gradient(placement * backward)) / (2.0 * _GROUP_STEP)
    joint_hessian = _kinematic_hessian(model, data, frame.parentJoint)
    # The frame's Jacobian is the joint's moved by the constant fMj = jMf^-1.
    at_joint = frame.placement.inverse().action.T @ gradient
    return jacobian.T @ derivative @ jacobian + np.einsum("r,rjk->jk", at_joint, joint_hessian)


def _kinematic_hessian(model, data, joint_id) -> np.ndarray:
    """(6, nv, nv) ``[:, j, k]``: the derivative of the joint's local Jacobian column j
    along tangent direction k (:func:`pinocchio.getJointKinematicHessian`).

    pinocchio's binding (3.x) hands over the tensor's column-major buffer with
    row-major strides (read as (6, nv, nv) it mixes the indices); how to read it is
    found once per process (:func:`_kinematic_hessian_order`), so a binding that
    hands it over right is read right too.
    """
    nv = model.nv
    raw = np.asarray(pin.getJointKinematicHessian(model, data, joint_id, pin.LOCAL))
    return raw.reshape(-1).reshape((6, nv, nv), order=_kinematic_hessian_order())


@functools.lru_cache(maxsize=1)
def _kinematic_hessian_order() -> str:
    """"C" or "F": the order in which pinocchio's kinematic Hessian buffer reads as
    ``[:, j, k] = d J_j / d q_k``, told by central differences of a sample arm's
    Jacobian (a few milliseconds, once)."""
    model = pin.buildSampleModelManipulator()
    data = model.createData()
    q = pin.integrate(model, pin.neutral(model), np.linspace(0.3, -0.4, model.nv))
    joint = model.njoints - 1
    pin.computeJointJacobians(model, data, q)
    pin.computeJointKinematicHessians(model, data)
    raw = np.asarray(pin.getJointKinematicHessian(model, data, joint, pin.LOCAL)).reshape(-1)
    step = 1e-6

    def jacobian(configuration):
        moved = model.createData()
        pin.computeJointJacobians(model, moved, configuration)
        return pin.getJointJacobian(model, moved, joint, pin.LOCAL)

    expected = np.stack([(jacobian(pin.integrate(model, q, e)) - jacobian(pin.integrate(model, q, -e))) / (2 * step)
                         for e in step * np.eye(model.nv)], axis=2)
    for order in ("F", "C"):
        if np.abs(raw.reshape((6, model.nv, model.nv), order=order) - expected).max() < 1e-6:
            return order
    raise RuntimeError(
        f"pinocchio {pin.__version__}: getJointKinematicHessian reads as no derivative of the joint Jacobian; "
        "stances.curvature cannot use it (report this with the pinocchio version)"
    )


def bounded_below(curvature, reference, floor):
    """The largest part of ``curvature`` that keeps ``reference + curvature >= floor * reference``.

    ``curvature`` acts on the first ``k`` variables only (the configuration
    block). Over the others, ``v^T reference v`` is least at the Schur
    complement ``S = R_11 - R_12 R_22^-1 R_21``, so the condition is
    ``(1 - floor) S + C >= 0`` on the first block alone. With ``S = L L^T``,
    the eigenvalues of ``L^-1 C L^-T`` below ``floor - 1`` are raised to it:
    curvature the reference already carries may be cancelled down to ``floor``
    of it, never further (an SQP step then stays within ``1 / floor`` of the
    reference's along any direction), and ``C`` is returned as it is when it
    already complies.

    Parameters
    ----------
    curvature : (k, k) float
        Symmetric.
    reference : (n, n) float
        Symmetric positive definite, ``n >= k``.
    floor : float
        In (0, 1].

    Returns
    -------
    (k, k) float
        Symmetric.
    """
    k = len(curvature)
    schur = reference[:k, :k]
    if k < len(reference):
        coupling = reference[:k, k:]
        schur = schur - coupling @ np.linalg.solve(reference[k:, k:], coupling.T)
    lower = np.linalg.cholesky(0.5 * (schur + schur.T))
    inverse = scipy.linalg.solve_triangular(lower, np.eye(k), lower=True)
    relative = inverse @ curvature @ inverse.T
    values, vectors = np.linalg.eigh(0.5 * (relative + relative.T))
    if values[0] >= floor - 1.0:
        return curvature
    root = lower @ vectors
    bounded = (root * np.maximum(values, floor - 1.0)) @ root.T
    return 0.5 * (bounded + bounded.T)
