"""Linearised constraint rows, the common currency between contacts, problem and solver.

Every constraint of the posture problem reduces to a :class:`ConstraintBlock`:
rows ``lower <= value + jacobian @ step <= upper`` valid to first order around
the current iterate, where ``step`` stacks the tangent configuration step ``dq``
(nv,) and the force-variable step ``dlambda`` (m,). Equalities have
``lower == upper``. Each row has a label a user can read ("torque limit of
leg_right_4_joint"), so the solver can say *which* constraint makes a stance
infeasible.

Rows carry a ``scale``: the size of a violation that matters (metres for
placement, newtons for equilibrium, the effort limit for a torque). The solver
compares violations divided by their scale, so one elastic variable can relax
rows of different units fairly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ConstraintBlock:
    """Linearised rows ``lower <= value + jacobian @ step <= upper``.

    Parameters
    ----------
    name : str
        Family of the rows ("placement", "equilibrium", "torque limit", ...).
    value : (r,) float
        Constraint function at the current iterate.
    jacobian : (r, n) float or None
        Derivative with respect to the step (dq, dlambda); None for rows
        evaluated without it (:meth:`stances.problem.PostureProblem.evaluate`,
        the line search's trials).
    lower, upper : (r,) float
        Bounds; ``-inf`` / ``inf`` where one-sided; equal for equalities.
    scale : (r,) float
        Violation size that matters, in the rows' units (> 0).
    labels : tuple of str
        One readable label per row.
    slack : float
        Violation tolerated before a row counts as violated, in the rows'
        units. Zero but for nonsmooth rows (collision distances, whose witness
        points jump), where demanding 1e-9 m would only stall the solver.
    accuracy : float
        Violation, in the rows' units, within which the SQP may stop on these
        rows (its scaled feasibility tolerance when that is looser). Unlike
        ``slack`` it leaves the violation, hence the merit function, as it is:
        only the stopping test reads it.
    second_order : callable, optional
        ``second_order(model, data, weights) -> (nv,)``: the rows' weighted
        Jacobian ``sum_i weights_i grad c_i`` in the configuration columns, at
        whatever configuration ``data`` holds (kinematics, joint Jacobians and
        frame placements computed), with the rows' own geometry held as at this
        linearisation. :mod:`stances.curvature` differences it into the rows'
        second derivatives. None: the rows' curvature is left out of the SQP's
        Hessian.
    curvature : callable, optional
        ``curvature(model, data, weights) -> (nv, nv)``: the rows' weighted second
        derivative ``sum_i weights_i d^2 c_i`` along the joints' motions, computed
        directly at the configuration ``data`` holds (kinematics, joint Jacobians,
        frame placements and kinematic Hessians computed); :mod:`stances.curvature`
        adds the configuration space's own term and then skips the differences of
        ``second_order``, which such a block still gives.
    variable_curvature : callable, optional
        ``variable_curvature(weights) -> (n, n)``: the rows' weighted second derivative
        ``sum_i weights_i d^2 c_i`` in the step's force-variable columns (zero elsewhere),
        at this linearisation, positive semidefinite for ``weights >= 0`` (convex rows). The
        SQP adds it, weighted by the last QP's multipliers, to every QP's Hessian once those
        are known: a row whose gradient vanishes where it is curved (a ball's strain in its
        sideways force, which enters squared) otherwise lets each QP swing that force across.
    """

    name: str
    value: np.ndarray
    jacobian: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    scale: np.ndarray
    labels: tuple
    slack: float = 0.0
    accuracy: float = 0.0
    second_order: object = None
    curvature: object = None
    variable_curvature: object = None

    def __post_init__(self) -> None:
        rows = len(self.value)
        for attribute in ("lower", "upper", "scale"):
            given = getattr(self, attribute)
            # np.broadcast_to costs ten times these (a linearisation makes some
            # thirty blocks, a solve thousands of them).
            if isinstance(given, np.ndarray) and given.dtype == float and given.shape == (rows,):
                array = given.view()
                array.setflags(write=False)
            elif np.ndim(given) == 0:
                array = np.full(rows, float(given))
                array.setflags(write=False)
            else:
                array = np.broadcast_to(np.asarray(given, dtype=float), (rows,))
            object.__setattr__(self, attribute, array)
        if (self.jacobian is not None and self.jacobian.shape[0] != rows) or len(self.labels) != rows:
            raise ValueError(
                f"block {self.name!r}: {rows} values, jacobian "
                f"{None if self.jacobian is None else self.jacobian.shape}, {len(self.labels)} labels"
            )

    def __len__(self) -> int:
        return len(self.value)

    def violation(self) -> np.ndarray:
        """(r,) float, read-only: how far each row is outside its bounds, in units of ``scale``.

        Computed once (the SQP reads it several times per iterate: the stopping
        tests, the worst row, the penalty rule); a block's arrays do not change.
        """
        known = self.__dict__.get("_violation")
        if known is None:
            below = np.maximum(self.lower - self.value - self.slack, 0.0)
            above = np.maximum(self.value - self.upper - self.slack, 0.0)
            known = (below + above) / self.scale
            known.setflags(write=False)
            object.__setattr__(self, "_violation", known)
        return known

    def met(self, tolerance: float) -> bool:
        """Whether every row is within ``tolerance`` (scaled) or its own ``accuracy``."""
        violation = self.violation()
        if not self.accuracy:
            # The largest row against the tolerance alone (a NaN row fails either way):
            # the SQP asks this of some thirty blocks a linearisation, three times.
            return not len(violation) or bool(violation.max() <= tolerance)
        return bool(np.all(violation <= np.maximum(tolerance, self.accuracy / self.scale)))


#: Placement rows (metres and radians) are met within this: a tenth of what
#: :func:`stances.verify` accepts (1e-6). With the uniform scaled tolerance they
#: had to reach 1e-9 m, and the SQP, converging linearly, spent its last
#: iterations there (hand-on-table: 9 of 19 between 1e-7 and 1e-9 m).
PLACEMENT_ACCURACY = 1e-7


def equality(name, value, jacobian, scale, labels, accuracy=0.0, second_order=None, curvature=None,
             variable_curvature=None) -> ConstraintBlock:
    """Rows ``value + jacobian @ step = 0``, met within ``accuracy`` (rows' units)."""
    zeros = np.zeros(len(value))
    return ConstraintBlock(
        name, np.asarray(value, float), jacobian, zeros, zeros, scale, tuple(labels), accuracy=accuracy,
        second_order=second_order, curvature=curvature, variable_curvature=variable_curvature,
    )


def stack(blocks):
    """Stack blocks into arrays.

    Returns
    -------
    value, jacobian, lower, upper, scale : arrays
        Row-stacked.
    labels : list of str
    """
    blocks = [block for block in blocks if len(block)]
    if not blocks:
        return (np.zeros(0), None, np.zeros(0), np.zeros(0), np.zeros(0), [])
    return (
        np.concatenate([b.value for b in blocks]),
        np.vstack([b.jacobian for b in blocks]),
        np.concatenate([b.lower for b in blocks]),
        np.concatenate([b.upper for b in blocks]),
        np.concatenate([b.scale for b in blocks]),
        [label for b in blocks for label in b.labels],
    )
