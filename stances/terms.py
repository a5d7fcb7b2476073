"""The posture problem's costs and constraints, one small piece each.

Every piece reads an :class:`Iterate`, the quantities of one ``(q, lambda)``
computed once per linearisation (kinematics, contact forces, static torques and
their Jacobians), and returns its value with its exact Jacobian in the step
``x = (dq, dlambda)`` (n,):

- a cost returns ``(value, gradient (n,), Gauss-Newton Hessian (n, n))``;
- a constraint returns :class:`~stances.blocks.ConstraintBlock` rows.

An iterate built without derivatives (``Iterate.derivatives`` False, what
:meth:`~stances.problem.PostureProblem.evaluate` gives a line search's trial
points) asks for values only: a cost returns ``(value, None, None)``, a
constraint its rows with ``jacobian`` None, each skipping the work its
Jacobian alone needs. The values are the same numbers either way.

:meth:`stances.problem.PostureProblem.linearize` only builds the iterate and
stacks the pieces; the contact models (rigid, deformable) add their own rows
and costs through the same two calls. Equation numbers are the paper's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .blocks import ConstraintBlock, equality
from .errors import StanceError

__all__ = [
    "Iterate",
    "PostureCost",
    "ForceCost",
    "TorqueUsageCost",
    "ContactCosts",
    "EquilibriumConstraint",
    "TorqueLimitConstraint",
    "NormalLoadConstraint",
    "print_normal_loads",
    "ContactConstraints",
    "CollisionConstraint",
    "COLLISION_SLACK",
    "kept_distance",
    "CentreOfMassBounds",
]

# Torque usage (fraction of the limit) that TorqueUsageCost leaves free.
FREE_USAGE = 0.5
#: Metres of a collision row's clearance the SQP may leave unmet (ConstraintBlock slack).
COLLISION_SLACK = 1e-4


@dataclass(frozen=True)
class Iterate:
    """What every term reads at one ``(q, lambda)``, computed once.

    Attributes
    ----------
    q : (nq,) float
        Configuration; ``problem.data`` holds its kinematics and joint Jacobians.
    lam : (m,) float
        Force variables.
    forces : (k, 3) float
        Contact forces ON the robot, world frame, newtons.
    force_jacobian : (3k, n) float or None
        Their derivative in the step (None: values only).
    tau : (nv,) float
        ``g(q) - sum J^T f``: free-flyer wrench residual, then joint torques, N m.
    tau_jacobian : (nv, n) float or None
        Its derivative in the step (None: values only).
    tau_force_jacobian : (nv, 3k) float or None
        ``d tau / d forces`` (``-J^T``) at fixed q (None: values only).
    force_curvatures : tuple of (slice, slice, callable)
        The contacts whose forces curve in their variables: each one's rows in the
        stacked forces (of 3k), its columns in the force variables, and what its
        ``force_curvature`` returned there (a soft Coulomb contact's:
        :meth:`stances.deformable.DeformableContact.force_curvature`).
    """

    q: np.ndarray
    lam: np.ndarray
    forces: np.ndarray
    force_jacobian: np.ndarray | None
    tau: np.ndarray
    tau_jacobian: np.ndarray | None
    tau_force_jacobian: np.ndarray | None = None
    force_curvatures: tuple = ()

    @property
    def derivatives(self) -> bool:
        """Whether the pieces must return Jacobians (False: values only)."""
        return self.tau_jacobian is not None


@dataclass(frozen=True)
class PostureCost:
    """Half the weighted squared distance to the reference posture (Gauss-Newton
    through ``pin.difference``); the base translation is free."""

    def evaluate(self, problem, iterate):
        model, n = problem.robot.model, problem.n_step
        nv = model.nv
        error = pin.difference(model, problem.reference, iterate.q)
        value = 0.5 * float(error @ (problem.posture_weights * error))
        if not iterate.derivatives:
            return value, None, None
        d_error = pin.dDifference(model, problem.reference, iterate.q, pin.ARG1)
        weights = problem.posture_weights
        gradient, hessian = np.zeros(n), np.zeros((n, n))
        gradient[:nv] = d_error.T @ (weights * error)
        hessian[:nv, :nv] = d_error.T @ (weights[:, None] * d_error)
        return value, gradient, hessian


@dataclass(frozen=True)
class ForceCost:
    """Half the weighted squared force variables (spreads rigid-contact forces).

    Parameters
    ----------
    weight : float
        Per N^2; each variable's own factor is ``problem.force_weights``.
    """

    weight: float

    def evaluate(self, problem, iterate):
        n, nv = problem.n_step, problem.robot.model.nv
        weights = self.weight * problem.force_weights
        value = 0.5 * float(iterate.lam @ (weights * iterate.lam))
        if not iterate.derivatives:
            return value, None, None
        gradient, hessian = np.zeros(n), np.zeros((n, n))
        gradient[nv:] = weights * iterate.lam
        hessian[nv:, nv:] = np.diag(weights)
        return value, gradient, hessian


@dataclass(frozen=True)
class TorqueUsageCost:
    """Half the weighted squared torque usage beyond half of each limit,
    ``sum_i max(|tau_i| / tau_max_i - 1/2, 0)^2`` (Gauss-Newton).

    Joints that carry little are left to the posture term; the cost, and its
    curvature (which slowed palm stances 2.7x when it weighed every joint), acts
    only where a joint nears its limit, moving load where the robot is strong.

    Parameters
    ----------
    weight : float
    """

    weight: float

    def evaluate(self, problem, iterate):
        limits = problem.effort_limits
        usage = iterate.tau[6:] / limits
        excess = np.sign(usage) * np.maximum(np.abs(usage) - FREE_USAGE, 0.0)
        value = 0.5 * self.weight * float(excess @ excess)
        if not iterate.derivatives:
            return value, None, None
        d_excess = (excess != 0.0)[:, None] * iterate.tau_jacobian[6:] / limits[:, None]
        return (
            value,
            self.weight * (d_excess.T @ excess),
            self.weight * (d_excess.T @ d_excess),
        )


@dataclass(frozen=True)
class ContactCosts:
    """Each contact model's own cost (e.g. the deformation term of soft prints)."""

    def evaluate(self, problem, iterate):
        model, data, n, nv = problem.robot.model, problem.data, problem.n_step, problem.robot.model.nv
        derivatives = iterate.derivatives
        value = 0.0
        gradient, hessian = (np.zeros(n), np.zeros((n, n))) if derivatives else (None, None)
        for contact, s in zip(problem.contacts, problem.variable_slices):
            term = contact.cost(model, data, iterate.lam[s], problem.options, n, nv + s.start, derivatives)
            if term is not None:
                value += term[0]
                if derivatives:
                    gradient += term[1]
                    hessian += term[2]
        return value, gradient, hessian


def tau_curvature(problem, iterate, rows):
    """The ``variable_curvature`` of the rows ``rows`` of tau (:class:`Iterate`), or None
    where no contact's forces curve in their variables.

    At fixed q, tau is linear in the forces (``d tau / d f = -J^T``), so its rows' weighted
    curvature in the force variables is that of the forces weighted by ``-J w``: each
    curved contact's ``force_curvature`` at those weights, in its own columns.

    Parameters
    ----------
    problem : PostureProblem
    iterate : Iterate
        With derivatives (``tau_force_jacobian``, ``force_curvatures``).
    rows : slice
        Rows of tau (0-5: the free flyer's wrench, static equilibrium; 6-: joint torques).

    Returns
    -------
    callable or None
        ``weights (r,) -> (n, n)`` in the step's columns (zero outside the force variables).
    """
    if not iterate.force_curvatures or iterate.tau_force_jacobian is None:
        return None
    n, nv = problem.n_step, problem.robot.model.nv

    def curvature(weights):
        on_forces = iterate.tau_force_jacobian[rows].T @ np.asarray(weights, dtype=float)
        out = np.zeros((n, n))
        for force_rows, variables, of in iterate.force_curvatures:
            columns = slice(nv + variables.start, nv + variables.stop)
            out[columns, columns] += of(on_forces[force_rows])
        return out

    return curvature


_EQUILIBRIUM_LABELS = tuple(f"static equilibrium ({a})" for a in ("fx", "fy", "fz", "mx", "my", "mz"))


@dataclass(frozen=True)
class EquilibriumConstraint:
    """Static equilibrium of the free flyer (49): six rows, scale 10 N or N m, so
    that a violation that matters is O(1) and the QP's one elastic variable stays
    well scaled."""

    def blocks(self, problem, iterate):
        jacobian = iterate.tau_jacobian[:6] if iterate.derivatives else None
        return [equality("equilibrium", iterate.tau[:6], jacobian, 10.0, _EQUILIBRIUM_LABELS,
                         variable_curvature=tau_curvature(problem, iterate, slice(0, 6)))]


@dataclass(frozen=True)
class TorqueLimitConstraint:
    """Torque limits (47), less the effort margin (``problem.effort``).

    Parameters
    ----------
    labels : tuple of str
        One per actuated joint (:meth:`for_robot`): made once, not at every
        linearisation.
    """

    labels: tuple

    @classmethod
    def for_robot(cls, robot, effort_margin: float) -> "TorqueLimitConstraint":
        """The constraint with its rows' labels, for ``robot`` and a margin (fraction of the limits)."""
        suffix = f" less its {100 * effort_margin:g} % margin" if effort_margin else ""
        return cls(tuple(f"torque limit of {name}{suffix}" for name in robot.actuated_joint_names))

    def blocks(self, problem, iterate):
        jacobian = iterate.tau_jacobian[6:] if iterate.derivatives else None
        return [
            ConstraintBlock("torque limit", iterate.tau[6:], jacobian, -problem.effort, problem.effort, 1.0, self.labels,
                            variable_curvature=tau_curvature(problem, iterate, slice(6, None)))
        ]


@dataclass(frozen=True)
class NormalLoadConstraint:
    """Each print's load along its normal, at least its ``minimum``.

    Parameters
    ----------
    minimum : (k,) float
        Newtons, one per print in the order of :func:`print_normal_loads`.
    """

    minimum: np.ndarray

    def blocks(self, problem, iterate):
        if not len(iterate.forces):
            return []
        labels, value, jacobian = print_normal_loads(problem, iterate)
        count = len(value)
        return [
            ConstraintBlock(
                "normal load", value, jacobian, np.asarray(self.minimum, float), np.full(count, np.inf), 1.0,
                tuple(f"normal load of {label}" for label in labels),
            )
        ]


def print_normal_loads(problem, iterate, only=None):
    """Each print's load along its normal: the sum of its load points' ``n . f``.

    Parameters
    ----------
    problem : PostureProblem
    iterate : Iterate
    only : str, optional
        One print's label (``"<robot surface> on <surface>"``): that print alone.

    Returns
    -------
    labels : list of str
        The prints' labels, in the problem's order.
    value : (k,) float
        Newtons, positive when the print pushes on the robot.
    jacobian : (k, n_step) float or None
        Their derivative in the step (None without derivatives).
    """
    labels, value, jacobian = [], [], []
    for contact, loads in zip(problem.contacts, problem.load_slices):
        normals = contact.load_normals
        if iterate.derivatives:
            rows = iterate.force_jacobian[3 * loads.start : 3 * loads.stop].reshape(len(normals), 3, -1)
        for i, label in enumerate(contact.print_labels):
            if only is not None and label != only:
                continue
            mine = contact.load_prints == i
            labels.append(label)
            value.append(float(np.einsum("pj,pj->", normals[mine], iterate.forces[loads][mine])))
            if iterate.derivatives:
                jacobian.append(np.einsum("pj,pjc->c", normals[mine], rows[mine]))
    jacobian = np.array(jacobian).reshape(len(value), problem.n_step) if iterate.derivatives else None
    return labels, np.array(value), jacobian


@dataclass(frozen=True)
class ContactConstraints:
    """Each contact model's own rows (placement, cones, the soft-contact rows)."""

    def blocks(self, problem, iterate):
        model, data, n, nv = problem.robot.model, problem.data, problem.n_step, problem.robot.model.nv
        out = []
        for contact, s in zip(problem.contacts, problem.variable_slices):
            out.extend(contact.blocks(model, data, iterate.lam[s], n, nv + s.start, iterate.derivatives))
        return out


@dataclass(frozen=True)
class CollisionConstraint:
    """Distances of the closest pairs, at least ``distance``, padded to ``rows``.

    0.1 mm of the clearance may be eaten (the rows' slack): the robot still keeps
    ``distance - 0.1 mm`` away, and verify checks real contact.

    Parameters
    ----------
    checker : stances.collision.CollisionChecker
    distance : float
        Metres.
    rows : int
        At most this many closest pairs enter a QP (a fixed number of rows: the
        QP's shape does not change between iterations).
    touching : frozenset of (str, str), optional
        ``(robot geometry, object)`` pairs that may touch: kept 0.1 mm (the rows'
        slack) apart instead of ``distance`` (``PostureOptions.touching``).
    """

    checker: object
    distance: float
    rows: int
    touching: frozenset = frozenset()

    def blocks(self, problem, iterate):
        model, data = problem.robot.model, problem.data
        jacobian, second_order = None, None
        if iterate.derivatives:
            pairs = self.checker.closest(model, data, self.rows)
            distances, names, count = pairs.distances, pairs.names, len(pairs)
            jacobian = np.zeros((self.rows, problem.n_step))
            if count:
                jacobian[:count, : model.nv] = self.checker.jacobian_rows(model, data, pairs)
                checker = self.checker

                def second_order(model, moved, weights):
                    # Only the pairs that weigh are measured again (a few of the 20).
                    used = np.flatnonzero(weights[:count])
                    return weights[used] @ checker.remeasured_rows(model, moved, [pairs.pair(i) for i in used.tolist()])
        else:
            # Distances alone: no witness points (line-search trials).
            distances, names = self.checker.closest_distances(model, data, self.rows)
        value = np.zeros(self.rows)
        lower = np.full(self.rows, -np.inf)
        labels = ["(inactive collision row)"] * self.rows
        value[: len(distances)] = distances
        lower[: len(distances)] = [self._lower(pair) for pair in names]
        labels[: len(names)] = [f"collision between {a} and {b}" for a, b in names]
        return [
            ConstraintBlock(
                "collision", value, jacobian, lower, np.full(self.rows, np.inf), 1e-2, tuple(labels),
                slack=COLLISION_SLACK, second_order=second_order,
            )
        ]

    def _lower(self, pair) -> float:
        """The distance a ``(name_a, name_b)`` pair keeps, metres: a touching pair the
        rows' slack, so that eating it leaves the pair touching, not inside."""
        return kept_distance(pair, self.distance, self.touching)


def kept_distance(pair, distance: float, touching=frozenset()) -> float:
    """The distance the collision rows keep a ``(name_a, name_b)`` pair at, metres:
    ``distance``, or the rows' slack for a pair ``touching`` names (eating it leaves the
    pair touching, not inside). The rows accept down to this less :data:`COLLISION_SLACK`."""
    return COLLISION_SLACK if tuple(pair) in touching else distance


class CentreOfMassBounds:
    """The robot's centre of mass within a box of the world frame: extra rows for
    :func:`stances.solve`'s ``constraints`` (a robot held leaning, its weight kept over part
    of its support).

    Its rows are the centre of mass's world coordinates on the bounded axes, scale 1 cm,
    labelled ``"<label> (x)"`` and so on; their Jacobian is pinocchio's
    ``jacobianCenterOfMass`` (m per unit of the configuration's tangent). :func:`stances.verify`
    does not know them: a caller checks them on the answer itself (:meth:`position`).

    Parameters
    ----------
    lower, upper : (3,) float, optional
        World x, y, z bounds, metres; ``-inf`` / ``inf`` (the defaults) where an axis has none.
    label : str, optional
        What the rows are called in a solve's reason.

    Raises
    ------
    StanceError
        A bound that is not three numbers, NaN, lower above upper, or no bound at all.

    Examples
    --------
    >>> import math
    >>> CentreOfMassBounds(lower=(0.1, -math.inf, -math.inf), label="ahead").labels
    ('ahead (x)',)
    """

    def __init__(self, lower=(-np.inf, -np.inf, -np.inf), upper=(np.inf, np.inf, np.inf), label="centre of mass"):
        bounds = []
        for name, given in (("lower", lower), ("upper", upper)):
            try:
                value = np.array(given, dtype=float)
            except (TypeError, ValueError):
                raise StanceError(f"CentreOfMassBounds {name} must be three numbers (x, y, z, metres), got {given!r}") from None
            if value.shape != (3,) or np.isnan(value).any():
                raise StanceError(f"CentreOfMassBounds {name} must be three numbers (x, y, z, metres; -inf / inf "
                                  f"where an axis has no bound), got {given!r}")
            bounds.append(value)
        lower, upper = bounds
        if np.any(lower > upper):
            axis = "xyz"[int(np.argmax(lower > upper))]
            raise StanceError(f"CentreOfMassBounds: the lower bound on {axis} is above the upper one "
                              f"({lower.tolist()} against {upper.tolist()})")
        self.axes = np.flatnonzero(np.isfinite(lower) | np.isfinite(upper))
        if not self.axes.size:
            raise StanceError("CentreOfMassBounds needs a finite bound on at least one axis (x, y or z)")
        self.lower, self.upper = lower[self.axes], upper[self.axes]
        self.labels = tuple(f"{label} ({'xyz'[a]})" for a in self.axes)
        # id of a pinocchio model -> (that model, its Data): the rows' own Data, not the
        # problem's (whose kinematics the other pieces read); the model kept so that its id
        # is not another model's.
        self._data = {}

    def position(self, model, q) -> np.ndarray:
        """(3,) float: the centre of mass of ``model`` at ``q``, world frame, metres (the rows' numbers)."""
        data = self._model_data(model)
        pin.jacobianCenterOfMass(model, data, np.asarray(q, dtype=float))
        return np.array(data.com[0])

    def blocks(self, problem, iterate):
        model = problem.robot.model
        data = self._model_data(model)
        # jacobianCenterOfMass whether or not the Jacobian is asked: its centre of mass differs
        # from centerOfMass's in the last bits, and a line search's trials and linearisations
        # must read the same numbers.
        full = pin.jacobianCenterOfMass(model, data, iterate.q)
        value = np.array(data.com[0])[self.axes]
        jacobian = None
        if iterate.derivatives:
            jacobian = np.zeros((self.axes.size, problem.n_step))
            jacobian[:, : model.nv] = full[self.axes]
        return [ConstraintBlock("centre of mass", value, jacobian, self.lower, self.upper, 1e-2, self.labels)]

    def _model_data(self, model):
        entry = self._data.get(id(model))
        if entry is None or entry[0] is not model:
            entry = self._data[id(model)] = (model, model.createData())
        return entry[1]
