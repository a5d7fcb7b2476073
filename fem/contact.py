"""Frictional contact of rigid indenters on a print: Signorini-Coulomb on the condensed compliance.

A print's nodes are pressed by points of rigid indenters (robot links). Each node
either sticks to its indenter point, slips along the surface with its force on
the friction bound, or lifts off with no force. On the print's compliance
``C = [K_NN^-1]_PP`` the conditions read, per node, in its frame (t1, t2, n: the
outward normal):

    r = U + C phi                      relative motion of the indenter point w.r.t. the node
    phi_n >= 0,  r_n >= 0,  phi_n r_n = 0                      (Signorini: push, no penetration)
    |phi_ti| <= b = mu' phi_n;  |phi_ti| < b  =>  r_ti = 0;
    |phi_ti| = b  =>  phi_ti r_ti <= 0                         (Coulomb, per tangent axis)

with ``phi`` the force ON THE INDENTER and ``U`` the indenter points' displacement
from rest. The friction law is the inner pyramid ``mu' = mu / sqrt(2)`` per
tangent axis, so every force lies inside the exact cone ``|phi_t| <= mu phi_n``.
The normal and tangential laws are not associated (a slipping node does not
open a gap), as Coulomb's law wants.

The problem is solved exactly by a primal-dual active-set iteration: guess each
node's mode, solve the linear system the modes define, update the modes from the
complementarity functions, repeat until they stop changing. For fixed modes the
forces are linear in U, ``phi = L U``: L is the exact Jacobian wherever the
contact set does not change, and ``L = -C^-1`` (the bonded answer) when every
node sticks. As friction grows every node sticks (bonded); with zero friction
the tangential forces vanish (frictionless).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.linalg

from .errors import FemError

__all__ = [
    "PrintContact", "PrintContactSystem", "solve_print_contact", "print_contact_with_modes", "STICK", "SLIP", "LIFT",
]

STICK, SLIP, LIFT = 0, 1, 2
_PYRAMID = 1.0 / np.sqrt(2.0)
_MAX_ITERATIONS = 60


@dataclass(frozen=True)
class PrintContact:
    """The contact state of a print under imposed indenter motions.

    Attributes
    ----------
    forces : (p, 3) float
        Forces of the nodes ON THE INDENTERS, newtons, body frame.
    relative : (p, 3) float
        Motion of each indenter point relative to its node, ``U - u``, metres, body frame.
    modes : (p, 2) int
        Per node and tangent axis: ``STICK``, ``SLIP`` or ``LIFT``.
    signs : (p, 2) float
        Direction of each slipping force (+1 or -1 along the tangent), 0 otherwise.
    iterations : int
        Active-set iterations used (0: the modes were given).
    """

    forces: np.ndarray
    relative: np.ndarray
    modes: np.ndarray
    signs: np.ndarray
    iterations: int
    _system: tuple = field(repr=False, compare=False)

    @property
    def admissible(self) -> bool:
        """Whether these forces and motions obey Signorini and Coulomb (the modes settled)."""
        return self._system[3]

    def jacobian_dot(self, matrix) -> np.ndarray:
        """``L @ matrix`` for the mode-fixed Jacobian ``L = d forces / d U``, body frame.

        Parameters
        ----------
        matrix : (3p, k) float
            Displacement directions, metres, body frame.

        Returns
        -------
        (3p, k) float, newtons per unit of ``matrix``.
        """
        factor, select, frames, _ = self._system
        local = _to_nodes(frames, np.asarray(matrix, dtype=float))
        return _to_body(frames, -scipy.linalg.lu_solve(factor, select[:, None] * local, check_finite=False))

    @cached_property
    def jacobian(self) -> np.ndarray:
        """(3p, 3p) float ``d forces / d U`` with the modes held fixed, N/m, body frame."""
        return self.jacobian_dot(np.eye(self.forces.size))

    @property
    def n_stick(self) -> int:
        """Nodes sticking on both tangent axes."""
        return int(np.sum((self.modes == STICK).all(axis=1)))

    @property
    def n_lift(self) -> int:
        """Nodes lifted off."""
        return int(np.sum(self.modes[:, 0] == LIFT))


def _to_nodes(frames: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Stacked body-frame vectors (3p,) or (3p, k) in the node frames (rows t1, t2, n)."""
    p = frames.shape[0]
    return np.einsum("pij,pj...->pi...", frames, vectors.reshape(p, 3, *vectors.shape[1:])).reshape(vectors.shape)


def _to_body(frames: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_to_nodes`."""
    p = frames.shape[0]
    return np.einsum("pji,pj...->pi...", frames, vectors.reshape(p, 3, *vectors.shape[1:])).reshape(vectors.shape)


class PrintContactSystem:
    """Signorini-Coulomb contact of one print system, solved for many indenter motions.

    The compliance, the node frames and the friction of a print system do not
    change while a posture solver moves the links: only the indenter motions U
    do. Each contact set (the modes of the nodes) defines one linear system,
    whose LU factorisation is kept, so that a solver holding the modes, or
    coming back to a set it met, pays a triangular solve instead of a
    factorisation (measured: a 26 ms factorisation per linearisation on two
    soles of the cross-two-mats scene).

    Parameters
    ----------
    compliance : (3p, 3p) float
        The print's compliance ``[K_NN^-1]_PP``, m/N, body frame, symmetric
        positive definite (all prints on the body together).
    frames : (p, 3, 3) float
        Rows t1, t2, n of each node's frame, body frame; n the outward normal.
    friction : (p,) float
        Coulomb coefficient mu of each node (>= 0; ``np.inf`` for bonded).
    kept : int
        Factorisations kept (the most recently used).

    Raises
    ------
    FemError
        On shapes that do not match or a negative friction coefficient.
    """

    def __init__(self, compliance, frames, friction, kept=8):
        c = np.asarray(compliance, dtype=float)
        frames = np.asarray(frames, dtype=float)
        p = frames.shape[0] if frames.ndim == 3 else -1
        if c.shape != (3 * p, 3 * p) or frames.shape != (p, 3, 3):
            raise FemError(
                f"shapes do not match: compliance {c.shape}, frames {frames.shape} (expected (3p, 3p), (p, 3, 3))"
            )
        mu = np.broadcast_to(np.asarray(friction, dtype=float), (p,)) * _PYRAMID
        if np.any(mu < 0) or np.any(np.isnan(mu)):
            raise FemError("friction coefficients must be >= 0")
        self.n_nodes = p
        self.frames = frames
        # R C R^T block by block (R block diagonal): F_i C_ij F_j^T.
        blocks = np.einsum("iab,ibjc->iajc", frames, c.reshape(p, 3, p, 3))
        self.c_local = np.einsum("iajc,jdc->iajd", blocks, frames).reshape(3 * p, 3 * p)
        self.mu = mu
        # Complementarity scales: the diagonal stiffness of each dof.
        self.scale = 1.0 / np.diag(self.c_local).reshape(p, 3)
        self._kept = kept
        self._factors = OrderedDict()

    def solve(self, displacements, initial_modes=None, initial_signs=None) -> PrintContact:
        """The contact state under indenter motions U, modes found (see :func:`solve_print_contact`)."""
        u_local = self._local_motion(displacements)
        p = self.n_nodes
        modes = (
            np.zeros((p, 2), dtype=int) if initial_modes is None else np.array(initial_modes, dtype=int).reshape(p, 2)
        )
        signs = np.zeros((p, 2)) if initial_signs is None else np.array(initial_signs, dtype=float).reshape(p, 2)
        result = self._active_set(u_local, modes, signs)
        if result is None:
            # The active set cycled (seen on prints where many nodes sit at the
            # stick/slip boundary): projected Gauss-Seidel finds the contact state,
            # then the active set restarts from its modes.
            modes, signs = _modes_of(_gauss_seidel(self.c_local, u_local, self.mu), self.mu)
            result = self._active_set(u_local, modes, signs)
            if result is None:
                raise FemError(
                    "the print's contact did not settle, even from a Gauss-Seidel solution; "
                    "this is a bug worth reporting with the print's compliance and displacements"
                )
        phi, r, modes, signs, iteration = result
        return self._state(phi, r, modes, signs, iteration, True)

    def with_modes(self, displacements, modes, signs) -> PrintContact:
        """The contact state with every node's mode imposed (see :func:`print_contact_with_modes`)."""
        u_local = self._local_motion(displacements)
        modes, signs = np.asarray(modes, dtype=int), np.asarray(signs, dtype=float)
        phi, r = self._forces(u_local, modes, signs)
        new_modes, new_signs = _update_modes(phi, r, self.scale, self.mu)
        settled = bool(np.array_equal(new_modes, modes) and np.array_equal(new_signs, signs))
        return self._state(phi, r, modes, signs, 0, settled)

    def _local_motion(self, displacements) -> np.ndarray:
        u = np.asarray(displacements, dtype=float)
        if u.shape != (self.n_nodes, 3):
            raise FemError(f"displacements must have shape ({self.n_nodes}, 3), got {u.shape}")
        return _to_nodes(self.frames, u.ravel()).reshape(-1, 3)

    def _factor(self, modes, signs):
        """LU factor and selector of the mode system, kept for the next time."""
        key = modes.tobytes() + signs.tobytes()
        if key in self._factors:
            self._factors.move_to_end(key)
            return self._factors[key]
        matrix, select = _mode_system(self.c_local, modes, signs, self.mu)
        entry = (scipy.linalg.lu_factor(matrix, check_finite=False), select)
        self._factors[key] = entry
        if len(self._factors) > self._kept:
            self._factors.popitem(last=False)
        return entry

    def _forces(self, u_local, modes, signs):
        """Node forces and relative motions (node frames) for fixed modes."""
        factor, select = self._factor(modes, signs)
        phi = scipy.linalg.lu_solve(factor, -(select * u_local.ravel()), check_finite=False).reshape(-1, 3)
        r = (u_local.ravel() + self.c_local @ phi.ravel()).reshape(-1, 3)
        return phi, r

    def _active_set(self, u_local, modes, signs):
        """Primal-dual active-set iterations from given modes; None if they cycle."""
        seen = set()
        for iteration in range(1, _MAX_ITERATIONS + 1):
            phi, r = self._forces(u_local, modes, signs)
            new_modes, new_signs = _update_modes(phi, r, self.scale, self.mu)
            if np.array_equal(new_modes, modes) and np.array_equal(new_signs, signs):
                return phi, r, modes, signs, iteration
            key = new_modes.tobytes() + new_signs.tobytes()
            if key in seen:
                return None
            seen.add(key)
            modes, signs = new_modes, new_signs
        return None

    def _state(self, phi, r, modes, signs, iterations, settled) -> PrintContact:
        factor, select = self._factor(modes, signs)
        forces = _to_body(self.frames, phi.ravel()).reshape(-1, 3)
        relative = _to_body(self.frames, r.ravel()).reshape(-1, 3)
        return PrintContact(forces, relative, modes, signs, iterations, (factor, select, self.frames, settled))


def solve_print_contact(compliance, displacements, frames, friction, initial_modes=None, initial_signs=None) -> PrintContact:
    """Signorini-Coulomb contact of a print under imposed indenter motions.

    Parameters
    ----------
    compliance : (3p, 3p) float
        The print's compliance ``[K_NN^-1]_PP``, m/N, body frame, symmetric
        positive definite (all prints on the body together).
    displacements : (p, 3) float
        Displacement U of the indenter point at each node from its rest position,
        metres, body frame (negative along the normal presses in).
    frames : (p, 3, 3) float
        Rows t1, t2, n of each node's frame, body frame; n the outward normal.
    friction : (p,) float
        Coulomb coefficient mu of each node (>= 0; ``np.inf`` for bonded).
    initial_modes : (p, 2) int, optional
        Modes to start from (e.g. the previous call's): warm start.
    initial_signs : (p, 2) float, optional
        Slip directions going with ``initial_modes``.

    Returns
    -------
    PrintContact

    Raises
    ------
    FemError
        On shapes that do not match, or when the active set cycles (not seen in
        practice; the message gives the iteration count).

    See Also
    --------
    PrintContactSystem : the same for many motions of one print system, with
        its factorisations kept.

    Examples
    --------
    A print pressed straight down with infinite friction is the bonded answer:

    >>> import numpy as np
    >>> c = np.diag([2e-5, 2e-5, 1e-5] * 2)
    >>> frames = np.tile(np.eye(3), (2, 1, 1))
    >>> state = solve_print_contact(c, [[0, 0, -1e-3], [0, 0, 1e-3]], frames, [np.inf, np.inf])
    >>> state.forces[0].round(6).tolist(), state.modes[1].tolist()   # the second node lifts off
    ([0.0, 0.0, 100.0], [2, 2])
    """
    c = np.asarray(compliance, dtype=float)
    u = np.asarray(displacements, dtype=float)
    p = u.shape[0] if u.ndim == 2 else -1
    frames = np.asarray(frames, dtype=float)
    if u.shape != (p, 3) or c.shape != (3 * p, 3 * p) or frames.shape != (p, 3, 3):
        raise FemError(
            f"shapes do not match: compliance {c.shape}, displacements {u.shape}, frames {frames.shape} "
            "(expected (3p, 3p), (p, 3), (p, 3, 3))"
        )
    return PrintContactSystem(c, frames, friction).solve(u, initial_modes, initial_signs)


def print_contact_with_modes(compliance, displacements, frames, friction, modes, signs) -> PrintContact:
    """The contact state with every node's mode imposed: linear in U, no mode update.

    A solver that has found which nodes stick, slip and lift can hold that set while it
    converges (the forces are then smooth in U), and check at the end with
    :func:`solve_print_contact` that the set still holds (:attr:`PrintContact.admissible`
    says whether it does here).

    Parameters
    ----------
    compliance, displacements, frames, friction
        As :func:`solve_print_contact`.
    modes : (p, 2) int
    signs : (p, 2) float
        As returned by :func:`solve_print_contact`.

    Returns
    -------
    PrintContact
    """
    return PrintContactSystem(compliance, frames, friction).with_modes(displacements, modes, signs)


def _gauss_seidel(c_local, u_local, mu, sweeps=500, tolerance=1e-12):
    """Projected Gauss-Seidel on the nodes: normal push, then tangential friction box.

    Returns (p, 3) forces in node frames. Each sweep solves every dof for its own
    relative motion with the others held, and projects on its admissible set.
    """
    p = u_local.shape[0]
    phi = np.zeros(3 * p)
    r = u_local.ravel().copy()
    diagonal = np.diag(c_local)
    for _ in range(sweeps):
        largest = 0.0
        for k in range(p):
            n = 3 * k + 2
            new = max(0.0, phi[n] - r[n] / diagonal[n])
            if new != phi[n]:
                r += c_local[:, n] * (new - phi[n])
                largest = max(largest, abs(new - phi[n]))
                phi[n] = new
            bound = mu[k] * phi[n] if phi[n] > 0.0 else 0.0
            for t in (3 * k, 3 * k + 1):
                new = float(np.clip(phi[t] - r[t] / diagonal[t], -bound, bound))
                if new != phi[t]:
                    r += c_local[:, t] * (new - phi[t])
                    largest = max(largest, abs(new - phi[t]))
                    phi[t] = new
        if largest <= tolerance * max(np.abs(phi).max(), 1e-300):
            break
    return phi.reshape(p, 3)


def _modes_of(phi, mu):
    """Modes and slip signs read off a contact solution."""
    p = phi.shape[0]
    modes = np.full((p, 2), STICK)
    signs = np.zeros((p, 2))
    bound = _friction_bound(phi[:, 2], mu)
    for axis in range(2):
        slipping = np.abs(phi[:, axis]) >= bound * (1.0 - 1e-9)
        modes[slipping, axis] = SLIP
        signs[slipping, axis] = np.sign(phi[slipping, axis])
    lifted = phi[:, 2] <= 0.0
    modes[lifted] = LIFT
    signs[lifted] = 0.0
    return modes, signs


def _mode_system(c_local, modes, signs, mu):
    """The linear system ``matrix @ phi = -select * U`` (node frames) of fixed modes.

    Returns the (3p, 3p) matrix and the (3p,) 0/1 selector of the rows that
    hold a relative motion to zero (sticking and touching dofs).
    """
    p = modes.shape[0]
    lifted = modes[:, 0] == LIFT
    # Rows (3p,): which law each dof obeys.
    mode_of_dof = np.where(lifted[:, None], LIFT, np.column_stack([modes, np.full(p, STICK)])).ravel()
    motion_rows = mode_of_dof == STICK  # r = 0: the compliance row
    matrix = np.where(motion_rows[:, None], c_local, 0.0)
    others = np.flatnonzero(~motion_rows)
    matrix[others, others] = 1.0  # lifted: phi = 0; slipping: phi_t - s mu' phi_n = 0
    slipping = np.flatnonzero(mode_of_dof == SLIP)
    node = slipping // 3
    matrix[slipping, 3 * node + 2] = -signs.ravel()[slipping - node] * mu[node]
    return matrix, motion_rows.astype(float)


def _friction_bound(normal, mu):
    """``mu' phi_n`` of pushing nodes, 0 elsewhere (and no NaN from ``inf * 0``)."""
    pushing = normal > 0.0
    return np.where(pushing, mu * np.where(pushing, normal, 1.0), 0.0)


def _update_modes(phi, r, scale, mu):
    """Modes from the complementarity functions of Signorini and Coulomb."""
    p = phi.shape[0]
    modes = np.zeros((p, 2), dtype=int)
    signs = np.zeros((p, 2))
    # Contact where the normal force minus the scaled gap is not negative (a
    # node exactly at the surface touches: its bonded Jacobian tells a solver
    # that pressing makes force).
    contact = phi[:, 2] - scale[:, 2] * r[:, 2] >= 0.0
    bound = _friction_bound(phi[:, 2], mu)
    for axis in range(2):
        trial = phi[:, axis] - scale[:, axis] * r[:, axis]
        slipping = np.abs(trial) > bound
        modes[:, axis] = np.where(slipping, SLIP, STICK)
        signs[:, axis] = np.where(slipping, np.sign(trial), 0.0)
    modes[~contact] = LIFT
    signs[~contact] = 0.0
    # A bound of zero with infinite friction never arises; mu = inf means stick.
    modes[np.isinf(mu) & contact] = STICK
    signs[np.isinf(mu) & contact] = 0.0
    return modes, signs
