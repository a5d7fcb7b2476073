"""Second-order information of the constraints: the curvature part of the Lagrangian's Hessian.

The SQP's QP Hessian is, without this module, the objective's (Gauss-Newton)
Hessian alone; the iterations then converge linearly, at a rate set by the
constraints' curvature times their multipliers (hand-on-table: 0.63 per
iteration). Adding

    sum_i y_i d^2 c_i(q (+) dq) / d dq^2     at dq = 0,  (nv, nv)

with the multipliers ``y`` of the previous QP gives the Lagrangian's Hessian,
the model Newton's method needs.

How it is computed: a block of rows that models its curvature carries a
``second_order`` function (:class:`~stances.blocks.ConstraintBlock`): given
pinocchio data holding the kinematics and joint Jacobians of any configuration
q', it returns ``sum_i y_i grad c_i(q')``, the rows' weighted Jacobian in the
tangent space at q' (a collision row measures its pair again there: new witness
points and normal). The Hessian is the forward difference of that gradient
along each tangent direction, chained through ``pin.dIntegrate`` so that it is
the Hessian of ``dq -> sum_i y_i c_i(q (+) dq)``, the function the QP models.
Each block is differenced only along the columns it moves with (the free flyer
and the joints above its link): one kinematics pass per column, 1-3 ms per
Hessian on Talos's rigid stances. Pinocchio's kinematic Hessians
(``computeJointKinematicHessians``, 8 us on Talos) give the frames' second
derivatives but not those of ``log6`` the placement rows go through, nor the
turning of a collision pair's normal, so the difference is used for all rows
alike. Its accuracy: within 3e-8 of a second difference of the rows' values
(placement, hand-on-table), 1e-5 for a self-collision distance.

Convexification: :func:`bounded_below` cuts the curvature where it would
bring the QP's Hessian below a fraction of a positive definite reference (the
objective's Hessian, made large across the active rows); see
:func:`stances.sqp._with_curvature` for the reference and what was measured.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import scipy.linalg

__all__ = ["ConstraintCurvature", "bounded_below"]

# Forward-difference step along a tangent direction, rad or m. Truncation error:
# about step * third derivative (1.5e-6 on hand-on-table's placement rows);
# rounding: 1e-16 / step. Not smaller: where a distance between hulls has a kink
# (parallel faces), a difference across it reads jump / step, and 1e-7 gave
# curvatures of 17 where the distance's are 0.04.
_STEP = 1e-5
_SUPPORT = 1e-10  # Jacobian entries below this fraction of a block's largest are rounding


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
        # Each block is differenced along the columns its weighted rows move
        # with (a row that does not move with a joint has no curvature along
        # it; a self-collision distance does not change with the free flyer,
        # whose columns then hold rounding specks only).
        columns = []
        for block, weight in used:
            rows = np.abs(block.jacobian[weight != 0.0, :nv])
            columns.append(np.any(rows > _SUPPORT * rows.max(initial=0.0), axis=0))
        columns = np.array(columns)
        self._kinematics(q)
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
        return 0.5 * (hessian + hessian.T)

    def _kinematics(self, q) -> None:
        pin.computeJointJacobians(self.model, self.data, q)  # also the joint placements
        pin.updateFramePlacements(self.model, self.data)


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
