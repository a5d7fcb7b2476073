"""Frictional contact of rigid indenters on a print: Signorini-Coulomb on the condensed compliance.

A print's nodes are pressed by points of rigid indenters (robot links). Each node
either sticks to its indenter point, slips along the surface with its force on
the friction bound against its slip, or lifts off with no force. On the print's
compliance ``C = [K_NN^-1]_PP`` (the posture solver passes ``C + D``, D the series
coupling of partly covered nodes: :attr:`fem.ContactPatch.link_compliance`) the
conditions read, per node, in its frame (t1, t2, n: the outward normal):

    r = U + C phi                      relative motion of the indenter point w.r.t. the node
    phi_n >= 0,  r_n >= 0,  phi_n r_n = 0                      (Signorini: push, no penetration)
    |phi_t| <= mu phi_n;  |phi_t| < mu phi_n  =>  r_t = 0;
    |phi_t| = mu phi_n  =>  phi_t = -mu phi_n r_t / |r_t|      (Coulomb, isotropic)

with ``phi`` the force ON THE INDENTER, ``phi_t`` its tangential part and ``U``
the indenter points' displacement from rest. The cone is the exact circular one,
and a slipping node's friction is exactly opposite its slip (maximum
dissipation). The normal and tangential laws are not associated (a slipping node
does not open a gap), as Coulomb's law wants.

Written as fixed points of projections (Alart and Curnier), with scales s (the normal
dof's own; one per node, the mean of its two tangential ones, for the friction disc),
``phi_n = max(0, phi_n - s r_n)`` and ``phi_t = proj_{|.| <= mu phi_n}(phi_t - s r_t)``,
the problem is solved by a semismooth Newton method (a primal-dual active set):
read each node's mode from the current iterate, solve the law linearised there,
repeat until the modes repeat and every slipping node's friction is on its bound.
The law is positively homogeneous in (phi, U), so each linearised law is linear
in U: for fixed modes the forces satisfy ``M phi = -B U``, and ``L = -M^-1 B``
taken at the answer is the exact Jacobian ``d phi / d U`` wherever the contact
set does not change. ``L = -C^-1`` (the bonded answer) when every node sticks. As
friction grows every node sticks (bonded); with zero friction the tangential
forces vanish (frictionless).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
import scipy.linalg

from .dense import block_diagonal_product, spd_inverse
from .errors import ContactStateError, FemError

__all__ = [
    "PrintContact", "PrintContactSystem", "solve_print_contact", "print_contact_with_modes", "STICK", "SLIP", "LIFT",
]

STICK, SLIP, LIFT = 0, 1, 2
_MAX_ITERATIONS = 60
# A held-mode solve (PrintContactSystem._held) is on a cycle of two steps when its slip
# directions (unit vectors) come back within _CYCLE_RETURN of the step before last, having
# swung by _CYCLE_SWING or more in between.
_CYCLE_RETURN, _CYCLE_SWING = 1e-9, 1e-3
# Newton steps of a solve for a carried wrench (solve_loaded): the built-in soft stances'
# 270 solves took 5 (median) to 12; a wrench out of reach makes the modes cycle.
_LOADED_ITERATIONS = 20
# A warm-started semismooth Newton that comes into one set of modes more than this many
# times (the starting set not counted) is taken to cycle, and the cold start follows
# (climb's palm on its platform: two sets in turn from the third step to the sixtieth, 2-3
# ms of a 20-node print's steps thrown away before the fallback).
_SET_ENTRIES = 2
# Friction from which the active set may find no contact state (a node needing a tangential
# force with almost no normal force): ContactStateError, which a posture solver steps around.
# Below it a contact that does not settle is a bug, a FemError. No built-in soft stance
# met one at mu = 0.1-15 (a probe, 2026-12-06); three did at mu = 20-50.
HIGH_FRICTION = 3.0
# Projected Gauss-Seidel (the fallback where the active set does not settle) gives up once
# _GS_STALLED_WINDOWS windows in a row of _GS_WINDOW sweeps each shrink its largest change
# less than _GS_PROGRESS times.
_GS_WINDOW = 50
_GS_PROGRESS = 2.0
_GS_STALLED_WINDOWS = 2
# Slipping nodes have settled when their friction is mu phi_n along their trial direction to
# _SLIP_SETTLED of the largest force; or, with the modes repeating, to _SLIP_FLOOR once a
# Newton step no longer halves that residual: its rounding floor. On a body of E = 1e12 Pa
# (compliances 1e-11 to 1e-8 m/N, motions of nanometres) a palm's quadratic convergence went
# 3e-3, 1e-5, 9e-10 and then wandered at 4e-10 to 1.6e-9 (climb-with-soft-support's
# left-on-platform through W: FemError after 60 steps in one set of modes).
_SLIP_SETTLED, _SLIP_FLOOR = 1e-10, 1e-8
# A sticking node whose trial force lies on its cone's edge to this share of the bound goes on
# sticking (its force then on the cone to that share; a slipping node slips while its trial is
# over the bound at all: _update_modes): a node that slipped to where it now just holds, as
# the next small step of an incremental load meets it (a motion's samples, each from where the
# one before left the prints), sits there to rounding, and read as slipping wherever its trial
# was 1e-16 to 1e-12 over the bound, the active set cycled among such nodes (a palm's 13 nodes
# on the coarse foam, two of them on their cones' edges: 60 steps, then Gauss-Seidel's modes
# cycling too, a FemError; sticking, the first step settles).
_CONE_EDGE = 1e-10
# Its wrench's relative accuracy: on a body of E = 1e11 Pa the residual sits at 1e-11 to
# 1e-10 of the wrench once the modes have settled (the forces are the compliance's solve
# of nanometres), so 1e-11 never came (hand-on-cube's palm); 1e-9 of 80 N is 8e-8 N.
_LOADED_TOLERANCE = 1e-9
# Low-rank (Woodbury) factorisations where at most this fraction of the rows differ
# from the compliance's: its cost grows as r^2 n against n^3 / 3 for LU. Measured
# (factorisation, then one refined solve): n = 300, 128 rows 0.18 + 0.09 ms against
# 1.2 + 0.02 ms dense, 170 rows 0.28 + 0.10 against 1.3; n = 738, 400 rows 1.9 + 0.3 against
# 11.6. At 0.25 the sole and palm on foot-and-hand-on-foam's foam (n = 300, 77-128 rows
# replaced where nodes both slip and lift) took the dense path 20 times a solve: at 0.6
# that solve runs 14 % fewer instructions (1.11 -> 0.95 G).
_LOW_RANK_ROWS = 0.6
# Below this reciprocal condition number of the capacitance matrix the dense factorisation
# serves. Measured on 897 factorisations of five scenes' plans (turn, rail-over-gap,
# two-mats, foot-and-hand-on-foam, hand-on-cube): 8.9e-4 at worst, solving for a vector of
# ones to 1e-13. (Before, that solve itself was the test: 0.4 ms, more than the factorisation.)
_LOW_RANK_RCOND = 1e-7


class _LawParameters(NamedTuple):
    """What a contact state's law was solved with (:meth:`PrintContact.derivatives` reads it)."""

    compliance: np.ndarray  # (3p, 3p) C (the coupling included), node frames, m/N
    friction: np.ndarray  # (p,) mu
    scale: np.ndarray  # (p, 3) the complementarity scales, N/m
    turns: np.ndarray | None  # (p, 3, 3) the turned frames in node-frame coordinates, or None


@dataclass(frozen=True)
class PrintContact:
    """The contact state of a print under imposed indenter motions.

    Attributes
    ----------
    forces : (p, 3) float
        Forces of the nodes ON THE INDENTERS, newtons, body frame.
    relative : (p, 3) float
        Motion of each indenter point relative to its node, ``U - u``, metres, body frame.
    modes : (p,) int
        Per node: ``STICK``, ``SLIP`` or ``LIFT``.
    directions : (p, 2) float
        Unit direction (t1, t2) of each slipping node's friction on the indenter,
        opposite its slip; 0 for the other nodes.
    iterations : int
        Newton (active-set) iterations used (0: the modes were given).
    """

    forces: np.ndarray
    relative: np.ndarray
    modes: np.ndarray
    directions: np.ndarray
    iterations: int
    _system: tuple = field(repr=False, compare=False)
    _law: "_LawParameters | None" = field(default=None, repr=False, compare=False)

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
        factor, blocks, frames, _ = self._system
        local = _to_nodes(frames, np.asarray(matrix, dtype=float))
        return _to_body(frames, -factor.solve(block_diagonal_product(blocks, local)))

    def derivatives(self, d_motion, dd_motion, d_turns=None, dd_turns=None):
        """First and second derivatives of the forces along a parameter's directions, the
        modes held: the indenters move by ``U(x)`` and the contact frames turn by ``Q(x)``.

        The law of fixed modes ``R(phi, U, Q) = 0`` (stick ``r = 0``, lift ``phi = 0``, slip
        ``s_n q_n . r = 0`` and ``phi'_t - mu phi'_n d(tau) = 0``, ``phi' = Q phi``,
        ``tau = phi'_t - s (Q r)_t``, ``d = tau / |tau|``) is differentiated implicitly: its
        matrix in ``phi`` is the kept factorisation's, so ``phi_a = -M^-1 R_a`` and
        ``phi_ab = -M^-1 R_ab`` with ``R_a``, ``R_ab`` the law's derivatives at fixed
        ``phi`` (``phi_a`` inside ``R_ab``). The slip direction's curvature
        ``d_ab = -[P tau_a (d . tau_b) + P tau_b (d . tau_a) + d (tau_a . P tau_b)] / |tau|^2``
        (``P = I - d d^T``) is what makes a slipping print's forces curve in the motion.

        Parameters
        ----------
        d_motion : (3p, m) float
            ``dU / dx``, metres per unit of x, body frame.
        dd_motion : (3p, m, m) float
            ``d^2 U / dx^2``, symmetric in its last two axes.
        d_turns : (p, m, 3, 3) float, optional
            ``dQ / dx`` of each node's turned frame (the solve's ``turns``, in its node frame's
            coordinates); None where the frames do not turn with x.
        dd_turns : (p, m, m, 3, 3) float, optional
            ``d^2 Q / dx^2``.

        Returns
        -------
        first : (3p, m) float
            ``d forces / dx``, body frame (:meth:`jacobian_dot` of ``d_motion`` where the
            frames do not turn).
        second : (3p, m, m) float
            ``d^2 forces / dx^2``, body frame, symmetric in its last two axes.
        """
        if self._law is None:
            raise FemError("derivatives need a contact state solved by a PrintContactSystem (solve, with_modes, "
                           "solve_loaded): this one does not carry its law")
        factor, _, frames, _ = self._system
        c, mu, scale, turns = self._law
        p = self.modes.size
        d_motion, dd_motion = np.asarray(d_motion, dtype=float), np.asarray(dd_motion, dtype=float)
        m = d_motion.shape[1] if d_motion.ndim == 2 else -1
        expected = {"d_motion": (d_motion, (3 * p, m)), "dd_motion": (dd_motion, (3 * p, m, m)),
                    "d_turns": (d_turns, (p, m, 3, 3)), "dd_turns": (dd_turns, (p, m, m, 3, 3))}
        for name, (value, shape) in expected.items():
            if value is not None and (m < 0 or np.shape(value) != shape):
                raise FemError(f"{name} must have shape {shape} for a print of {p} nodes and m directions "
                               f"(d_motion (3p, m)), got {np.shape(value)}")
        phi = _to_nodes(frames, self.forces.ravel()).reshape(p, 3)
        r = _to_nodes(frames, self.relative.ravel()).reshape(p, 3)
        du = _to_nodes(frames, d_motion).reshape(p, 3, m)
        ddu = _to_nodes(frames, dd_motion).reshape(p, 3, m, m)
        q = np.broadcast_to(np.eye(3), (p, 3, 3)) if turns is None else turns
        dq = np.zeros((p, m, 3, 3)) if d_turns is None else np.asarray(d_turns, dtype=float)
        ddq = np.zeros((p, m, m, 3, 3)) if dd_turns is None else np.asarray(dd_turns, dtype=float)
        slip = np.flatnonzero(self.modes == SLIP)
        in_contact = self.modes != LIFT

        # The slipping nodes' law at the answer, in their turned frames.
        qs = q[slip]
        phi_turned = np.einsum("kij,kj->ki", qs, phi[slip])
        r_turned = np.einsum("kij,kj->ki", qs, r[slip])
        s_t = 0.5 * (scale[slip, 0] + scale[slip, 1])
        # (solved in the node frames, a slipping node's normal row is C's, unscaled)
        s_n = scale[slip, 2] if turns is not None else np.ones(slip.size)
        tau = _trial(phi_turned, r_turned, scale[slip])
        size = np.hypot(tau[:, 0], tau[:, 1])
        # A node held slipping with no trial friction (tau = 0, seen only with its mode
        # held) keeps its direction, as the factorisation's law does (gain 0): no curvature.
        has_trial = size > 0.0
        d = np.where(has_trial[:, None], tau / np.where(has_trial, size, 1.0)[:, None], self.directions[slip])
        inverse = np.where(has_trial, 1.0 / np.where(has_trial, size, 1.0), 0.0)
        projector = np.eye(2) - np.einsum("ki,kj->kij", d, d)
        friction = mu[slip]

        def law_rows(x1, y1):
            """The slipping nodes' rows at fixed phi, (k, 3, n), from the turned force's and
            motion's derivatives x1, y1 (k, 3, n), the direction's own curvature left out."""
            t1 = x1[:, :2] - s_t[:, None, None] * y1[:, :2]
            rows = np.empty_like(x1)
            rows[:, :2] = x1[:, :2] - friction[:, None, None] * (
                d[:, :, None] * x1[:, 2][:, None]
                + (phi_turned[:, 2] * inverse)[:, None, None] * np.einsum("kij,kjn->kin", projector, t1))
            rows[:, 2] = s_n[:, None] * y1[:, 2]
            return rows

        def solve(motion_rows, slip_rows):
            """``-M^-1`` of the law's rows at fixed phi: a sticking node's motion, a slipping node's law."""
            rows = np.zeros(motion_rows.shape)
            rows[in_contact] = motion_rows[in_contact]
            rows[slip] = slip_rows
            return -factor.solve(rows.reshape(3 * p, -1)).reshape(rows.shape)

        def product_rule(turn, vector, rotation=None, moved=None):
            """``dQ v`` (k, 3, n) for turns (k, n, 3, 3) and v (k, 3), plus ``Q dv`` for dv (k, 3, n)."""
            out = np.einsum("knij,kj->kin", turn, vector)
            return out if moved is None else out + np.einsum("kij,kjn->kin", rotation, moved)

        # First derivatives: phi_a = -M^-1 R_a.
        dqs = dq[slip]
        dphi = solve(du, law_rows(product_rule(dqs, phi[slip]), product_rule(dqs, r[slip], qs, du[slip])))
        dr = du + (c @ dphi.reshape(3 * p, m)).reshape(p, 3, m)

        # Second derivatives, each pair (a, b) with a <= b once: phi_ab = -M^-1 R_ab.
        ia, ib = np.triu_indices(m)
        xa = product_rule(dqs, phi[slip], qs, dphi[slip])  # (k, 3, m)
        ya = product_rule(dqs, r[slip], qs, dr[slip])
        ta = xa[:, :2] - s_t[:, None, None] * ya[:, :2]
        pair_turns = ddq[slip][:, ia, ib]  # (k, P, 3, 3)
        x2 = (product_rule(pair_turns, phi[slip]) + np.einsum("kPij,kjP->kiP", dqs[:, ia], dphi[slip][:, :, ib])
              + np.einsum("kPij,kjP->kiP", dqs[:, ib], dphi[slip][:, :, ia]))
        y2 = (product_rule(pair_turns, r[slip], qs, ddu[slip][:, :, ia, ib])
              + np.einsum("kPij,kjP->kiP", dqs[:, ia], dr[slip][:, :, ib])
              + np.einsum("kPij,kjP->kiP", dqs[:, ib], dr[slip][:, :, ia]))
        rows = law_rows(x2, y2)
        # ... and the products of first derivatives: the normal force's times the direction's,
        # and the direction's own curvature.
        tau_a, tau_b = ta[:, :, ia], ta[:, :, ib]  # tau's derivatives along each pair's two directions
        across_a = np.einsum("kij,kjP->kiP", projector, tau_a)  # P tau_a
        across_b = np.einsum("kij,kjP->kiP", projector, tau_b)
        along_a, along_b = np.einsum("ki,kiP->kP", d, tau_a), np.einsum("ki,kiP->kP", d, tau_b)  # d . tau_a
        curvature = -(across_a * along_b[:, None] + across_b * along_a[:, None]
                      + d[:, :, None] * np.einsum("kiP,kiP->kP", tau_a, across_b)[:, None]) * inverse[:, None, None] ** 2
        rows[:, :2] -= friction[:, None, None] * (
            (xa[:, 2][:, None, ia] * across_b + xa[:, 2][:, None, ib] * across_a) * inverse[:, None, None]
            + phi_turned[:, 2][:, None, None] * curvature)
        ddphi_pairs = solve(ddu[:, :, ia, ib], rows)  # (p, 3, P)
        ddphi = np.zeros((p, 3, m, m))
        ddphi[:, :, ia, ib] = ddphi_pairs
        ddphi[:, :, ib, ia] = ddphi_pairs
        return (_to_body(frames, dphi.reshape(3 * p, m)),
                _to_body(frames, ddphi.reshape(3 * p, m, m)))

    @cached_property
    def jacobian(self) -> np.ndarray:
        """(3p, 3p) float ``d forces / d U`` with the modes held fixed, N/m, body frame."""
        return self.jacobian_dot(np.eye(self.forces.size))

    @property
    def n_stick(self) -> int:
        """Nodes sticking."""
        return int(np.sum(self.modes == STICK))

    @property
    def n_slip(self) -> int:
        """Nodes slipping."""
        return int(np.sum(self.modes == SLIP))

    @property
    def n_lift(self) -> int:
        """Nodes lifted off."""
        return int(np.sum(self.modes == LIFT))


def _to_nodes(frames: np.ndarray | None, vectors: np.ndarray) -> np.ndarray:
    """Stacked body-frame vectors (3p,) or (3p, k) in the node frames (rows t1, t2, n);
    ``frames`` None: the node frames are the body's axes (a copy of the vectors, -0.0
    made 0.0 as the rotation made it)."""
    if frames is None:
        return vectors + 0.0
    p = frames.shape[0]
    return np.einsum("pij,pj...->pi...", frames, vectors.reshape(p, 3, *vectors.shape[1:])).reshape(vectors.shape)


def _to_body(frames: np.ndarray | None, vectors: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_to_nodes`."""
    if frames is None:
        return vectors + 0.0
    p = frames.shape[0]
    return np.einsum("pji,pj...->pi...", frames, vectors.reshape(p, 3, *vectors.shape[1:])).reshape(vectors.shape)


def _in_frames(frames: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``R M R^T`` for R block diagonal with the (p, 3, 3) ``frames``: block by block
    ``F_i M_ij F_j^T``, (3p, 3p), through two batched matrix products (a two-index
    einsum took 10 ms on two soles' 738 rows, these 4 ms)."""
    p = frames.shape[0]
    left = np.matmul(frames, matrix.reshape(p, 3, 3 * p))  # F_i M_i., (p, 3, 3p)
    both = np.matmul(left.reshape(3 * p, p, 3).transpose(1, 0, 2), frames.transpose(0, 2, 1))  # (p_j, 3p, 3)
    return both.transpose(1, 0, 2).reshape(3 * p, 3 * p)


class _DenseFactor:
    """LU factorisation of a linearised law's matrix, its rows scaled by ``row_scale``.

    C's rows are metres per newton, the replaced rows (``phi = 0``, a slipping node's
    friction) about one: their ratio is the body's stiffness, so on a stiff body the LU
    loses that many digits of the forces (E = 1e11 Pa: 1e-5 of 27 N, a condition number
    of 3.6e10, 52 once equilibrated). Scaling each replaced row by its dof's compliance
    (a power of two: exact) keeps the forces to round-off at any stiffness.
    """

    def __init__(self, matrix, row_scale=None):
        self._row_scale = row_scale
        self._lu = _lu_factor(matrix if row_scale is None else row_scale[:, None] * matrix)

    def solve(self, rhs):
        if self._row_scale is not None:
            rhs = (self._row_scale if rhs.ndim == 1 else self._row_scale[:, None]) * rhs
        return _lu_solve(self._lu, rhs)


def _lu_factor(matrix):
    """``scipy.linalg.lu_factor``'s answer from LAPACK ``getrf`` directly (the same bits,
    without the wrappers' checks: 7 us of a 60-row print's 36 us); a singular matrix is
    left to ``lu_factor``, which warns as it always did."""
    lu, pivots, info = scipy.linalg.lapack.dgetrf(matrix)
    return (lu, pivots) if info == 0 else scipy.linalg.lu_factor(matrix, check_finite=False)


def _lu_solve(factor, rhs):
    """``scipy.linalg.lu_solve`` by LAPACK ``getrs`` directly (the same bits; 2 us
    instead of 9 for a 60-row print's vector)."""
    x, info = scipy.linalg.lapack.dgetrs(*factor, rhs)
    if info != 0:
        raise FemError(f"LAPACK getrs failed (info {info}); this is a bug worth reporting")
    return x


class _LowRankFactor:
    """A linearised law's matrix as the compliance with a few rows replaced (Woodbury).

    ``A = C + E V``, ``E`` the (n, r) columns of the identity at the replaced
    rows ``R``, ``V = A[R] - C[R]``; with ``S = C^-1`` known,
    ``A^-1 b = S b - S[:, R] (I + V S[:, R])^-1 V S b``: an (r, r)
    factorisation instead of an (n, n) one (a sole on a mat: r = 52 of n = 369).

    The replaced rows are C's rows turned by a node's 2 x 2 block (3 x 3 in turned frames)
    plus a few entries (:class:`_LawRows`), so with ``C S = I`` neither product with ``V`` needs C:
    the capacitance ``I + V S[:, R] = A[R] S[:, R]`` is read off ``S``'s rows at the
    replaced and slipping nodes' dofs, and ``V y = A[R] y - b[R]`` for ``y = S b``
    (measured on the turn scene's soles on foam: 0.35 ms a factorisation with the
    (r, n) by (n, r) product, most of a Newton step of the contact solve).
    """

    def __init__(self, compliance, inverse, law):
        """
        Parameters
        ----------
        compliance : (n, n) float
            C, in node frames.
        inverse : (n, n) float
            S = C^-1, exactly symmetric (:func:`fem.dense.spd_inverse`): its rows at R
            are read as its columns.
        law : _LawRows
            The replaced rows.

        Attributes
        ----------
        reciprocal_condition : float
            LAPACK ``gecon``'s estimate of the capacitance matrix's reciprocal
            condition number in the 1-norm (1.0 when no row is replaced).
        """
        self._compliance = compliance  # C: A is never formed
        self._inverse = inverse
        self._law = law
        rows = law.layout.rows
        # S is exactly symmetric (spd_inverse): its rows at R are its columns, read contiguously.
        self._columns = np.ascontiguousarray(inverse[rows].T)  # S E, (n, r)
        if rows.size:
            unit = np.zeros((compliance.shape[0], rows.size))
            unit[rows, np.arange(rows.size)] = 1.0  # C S E = E
            capacitance = law.values(self._columns, unit)
            self._lu = _lu_factor(capacitance)
            self.reciprocal_condition = float(
                scipy.linalg.lapack.dgecon(self._lu[0], np.abs(capacitance).sum(axis=0).max(), norm="1")[0])
        else:
            self._lu = None
            self.reciprocal_condition = 1.0

    def product(self, x):
        """``A x``, x a vector: C's rows, and the replaced ones."""
        y = self._compliance @ x
        y[self._law.layout.rows] = self._law.values(x, y)
        return y

    def solve(self, rhs):
        """``A^-1 rhs``; a vector (the forces) gets one step of iterative refinement.

        Multiplying by an explicit inverse is not backward stable: without the
        step, forces lose about cond(C) * eps of their size, which the finite
        differences of a print's forces (steps of 1e-9 m) see.
        """
        x = self._apply(rhs)
        if np.ndim(rhs) == 1:
            x = x + self._apply(rhs - self.product(x))
        return x

    def _apply(self, rhs):
        y = self._inverse @ rhs
        if self._lu is None:
            return y  # every node sticks: A = C
        law = self._law
        return y - self._columns @ _lu_solve(self._lu, law.values(y, rhs) - rhs[law.layout.rows])


class PrintContactSystem:
    """Signorini-Coulomb contact of one print system, solved for many indenter motions.

    The compliance, the node frames and the friction of a print system do not
    change while a posture solver moves the links: only the indenter motions U
    do. A contact set without slipping nodes defines one linear system, whose LU
    factorisation is kept, so that a solver holding the set, or coming back to
    it, pays a triangular solve instead of a factorisation (measured: a 26 ms
    factorisation per linearisation on two soles of the cross-two-mats scene).
    Slipping nodes make the system depend on their slip directions, so sets with
    slip are factorised at each solve; where few rows differ from the
    compliance's (few nodes slip or lift), through the compliance's inverse,
    computed once, and a factorisation of the size of those rows only
    (measured: 1.3 ms an LU of 369 rows against 0.1 ms with 52 rows replaced).

    Parameters
    ----------
    compliance : (3p, 3p) float
        The print's compliance ``[K_NN^-1]_PP``, m/N, body frame, symmetric
        positive definite (all prints on the body together).
    frames : (p, 3, 3) float
        Rows t1, t2, n of each node's frame, body frame; n the outward normal.
    friction : (p,) float
        Coulomb coefficient mu of each node (>= 0; ``np.inf``: sticks wherever it presses, see
        :func:`solve_print_contact`).
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
        mu = np.array(np.broadcast_to(np.asarray(friction, dtype=float), (p,)))
        if np.any(mu < 0) or np.any(np.isnan(mu)):
            raise FemError("friction coefficients must be >= 0")
        self.n_nodes = p
        self.frames = frames
        # Node frames that are the body's axes (a print on a box's top: every built-in
        # soft stance) leave every vector and C as they are: no rotation at all.
        self._frames = None if np.array_equal(frames, np.broadcast_to(np.eye(3), frames.shape)) else frames
        # R C R^T (R block diagonal): F_i C_ij F_j^T.
        # (Only a read-only C that owns its numbers is kept as it is, such as a print's
        # compliance: one that could change later, through it or its base, is copied.)
        owned = not c.flags.writeable and c.base is None
        self.c_local = (c if owned else c.copy()) if self._frames is None else _in_frames(frames, c)
        self.mu = mu
        # Complementarity scales: the diagonal stiffness of each dof.
        diagonal = np.diag(self.c_local)
        self.scale = 1.0 / diagonal.reshape(p, 3)
        # A replaced row's scale in a dense factorisation (_dense_factor): its dof's compliance,
        # rounded to a power of two so that the scaling is exact.
        self._row_powers = np.exp2(np.round(np.log2(diagonal)))
        self._kept = kept
        self._factors = OrderedDict()
        self._inverse = None  # C^-1 in node frames, (3p, 3p), computed on the first low-rank factorisation
        self._layout = None  # the _ModeLayout of the modes last linearised
        self._turns = None  # the current solve's turned frames (solve's ``turns``), or None
        self._infinite_friction = bool(np.isinf(mu).any())

    def solve(self, displacements, initial_modes=None, initial_directions=None, turns=None) -> PrintContact:
        """The contact state under indenter motions U, modes found (see :func:`solve_print_contact`).

        ``turns`` : (p, 3, 3) float, optional
            Per node, the rotation from its frame to the frame its contact is solved in
            (rows t1, t2, n of the turned frame, in the node frame's coordinates): the
            indenter's face turned from the node frames (a tilted palm). The gap is then
            measured along the turned normal, the slip and the cone in the turned plane;
            forces, motions and the Jacobian stay in the body frame, and ``directions`` are
            in the turned tangents. None: the node frames themselves.
        """
        self._set_turns(turns)
        u_local = self._local_motion(displacements)
        p = self.n_nodes
        modes = np.full(p, STICK) if initial_modes is None else np.array(initial_modes, dtype=int).reshape(p)
        directions = (
            np.zeros((p, 2)) if initial_directions is None else np.array(initial_directions, dtype=float).reshape(p, 2)
        )
        # A warm start (modes other than every node sticking) can put the active set on a
        # cycle that the cold start does not meet: climb's palm on its platform, nodes at the
        # brink of lifting, cycled between two sets from the previous linearisation's modes
        # and settled in 6 steps from sticking. Such a start gives up on a cycle at once
        # (_SET_ENTRIES) and the cold start follows, with the whole budget: a run that comes
        # back to a set while its slip directions converge is no cycle (a review's synthetic
        # prints: 6 of 10,000 warm starts stopped so, and one of them settled from sticking
        # in another admissible state: Coulomb's contact need not be unique).
        warm = bool(np.any(modes != STICK))
        result = self._newton(u_local, modes, directions, give_up_on_cycles=warm)
        if result is None and warm:
            result = self._newton(u_local, np.full(p, STICK), np.zeros((p, 2)))
        if result is None:
            # The active set did not settle from sticking (seen on prints where many nodes
            # sit at the stick/slip boundary): projected Gauss-Seidel finds the contact
            # state, then the semismooth Newton restarts from its modes.
            c_seen, u_seen = self.c_local, u_local  # in the frames the contact is solved in
            if self._turns is not None:
                c_seen, u_seen = _in_frames(self._turns, self.c_local), np.einsum("pij,pj->pi", self._turns, u_local)
            modes, directions = _modes_of(_gauss_seidel(c_seen, u_seen, self.mu)[0], self.mu)
            result = self._newton(u_local, modes, directions)
            if result is None and np.isinf(self.mu).any():
                # As mu grows, a node can keep a finite tangential force while its
                # normal force goes to zero; with mu = inf no contact state exists.
                raise ContactStateError(
                    "with infinite friction this motion has no contact state: a node would hold a tangential "
                    "force with no normal force (it slips at any finite friction); give a finite friction coefficient"
                )
            if result is None:
                # As mu grows a node's normal force can fall toward zero while its friction
                # stays (the state tends to the one mu = inf has not): seen on a two-node
                # print from mu = 10, and on a palm's converged (Q2) compliance at mu = 100.
                # With moderate friction no such state is known: a bug, raised as one.
                error = ContactStateError if np.max(self.mu) >= HIGH_FRICTION else FemError
                raise error(
                    "the print's contact did not settle, even from a Gauss-Seidel solution: with friction as "
                    f"high as mu = {float(np.max(self.mu)):g} a node can need a tangential force with almost no "
                    "normal force, where the active set finds no state (try a smaller coefficient); with "
                    "moderate friction this is a bug worth reporting with the print's compliance and displacements"
                )
        phi, r, modes, directions, system, iterations = result
        return self._state(phi, r, modes, directions, system, iterations, True)

    def with_modes(self, displacements, modes, directions, turns=None) -> PrintContact:
        """The contact state with every node's mode imposed (see :func:`print_contact_with_modes`;
        ``turns`` as :meth:`solve`)."""
        self._set_turns(turns)
        u_local = self._local_motion(displacements)
        modes = np.asarray(modes, dtype=int).reshape(self.n_nodes)
        directions = np.asarray(directions, dtype=float).reshape(self.n_nodes, 2)
        phi, r, directions, system = self._held(u_local, modes, directions)
        new_modes, new_directions, _ = _update_modes(*self._seen(phi, r), self.scale, self.mu, modes)
        settled = bool(np.array_equal(new_modes, modes))
        return self._state(phi, r, modes, directions, system, 0, settled)

    def solve_loaded(self, basis, wrench, motion, start, initial_modes=None, initial_directions=None, turns=None):
        """The contact state whose forces carry a given wrench, and the indenters' motion.

        The inverse of :meth:`solve` at fixed contact geometry: the indenters move with m
        parameters ``xi`` (a link's rigid motion), their points by ``U(xi)``, and the
        forces must carry ``basis^T phi = wrench``. Solved by the same semismooth Newton
        as :meth:`solve`, the modes read at each step, with ``xi`` among the unknowns: for
        fixed modes the law is linear in U, and U is linearised in ``xi`` at the iterate,
        so each step solves the law for the m columns of dU/dxi and an (m, m) system
        ``K step = wrench - basis^T phi``, ``K = basis^T L dU/dxi``.

        Parameters
        ----------
        basis : (3p, m) float
            The carried wrench's rows: ``basis^T phi`` (phi: the forces on the
            indenters, body frame, stacked).
        wrench : (m,) float
            The wrench to carry.
        motion : callable
            ``xi -> (U (p, 3), dU/dxi (3p, m))``, metres, body frame.
        start : (m,) float
            ``xi`` to start from.
        initial_modes, initial_directions
            As :meth:`solve` (an earlier answer's, for a nearby wrench).
        turns : callable, optional
            ``xi -> (p, 3, 3)`` turned frames (:meth:`solve`'s ``turns``) of the indenters
            moved by ``xi``, read at each step (their derivative left out of ``K``: the
            steps converge as long as the turns are small, as where a stiff body holds).

        Returns
        -------
        (state, xi) : (PrintContact, (m,) float)
            At ``U(xi)``. Or None when the Newton steps do not settle within
            ``_LOADED_ITERATIONS``, or settle where K is singular (every node touching
            on one line, at the point of sliding off): no motion carries the wrench (a
            centre of pressure beyond the nodes, a sideways force at which the contact
            would slide off), or none was found from ``start``.
        """
        self._set_turns(None)
        basis_local = _to_nodes(self._frames, np.asarray(basis, dtype=float))
        wrench = np.asarray(wrench, dtype=float)
        p = self.n_nodes
        modes = np.full(p, STICK) if initial_modes is None else np.array(initial_modes, dtype=int).reshape(p)
        directions = (
            np.zeros((p, 2)) if initial_directions is None else np.array(initial_directions, dtype=float).reshape(p, 2)
        )
        gains = np.zeros(p)
        xi = np.array(start, dtype=float)
        size = max(float(np.abs(wrench).max()), 1e-300)
        for iteration in range(1, _LOADED_ITERATIONS + 1):
            if self._infinite_friction and np.isinf(self.mu[modes == SLIP]).any():
                return None
            u, du = motion(xi)
            self._set_turns(None if turns is None else turns(xi))
            u_local = self._local_motion(u).ravel()
            du_local = _to_nodes(self._frames, np.asarray(du, dtype=float))
            factor, blocks = system = self._system(modes, directions, gains)
            phi = -factor.solve(block_diagonal_product(blocks, u_local))
            d_phi = -factor.solve(block_diagonal_product(blocks, du_local))  # L dU/dxi, node frames
            stiffness = basis_local.T @ d_phi
            residual = wrench - basis_local.T @ phi
            settled = np.abs(residual).max() <= _LOADED_TOLERANCE * size
            if not (settled and iteration > 1):
                # Modes whose K is singular (every touching node slipping, a line of
                # nodes left) are passed through on the least-squares step.
                step = np.linalg.lstsq(stiffness, residual, rcond=1e-13)[0]
                phi = phi + d_phi @ step
                u_local = u_local + du_local @ step
                xi = xi + step
            phi, r = phi.reshape(-1, 3), (u_local + self.c_local @ phi).reshape(-1, 3)
            seen = self._seen(phi, r)
            new_modes, new_directions, new_gains = _update_modes(*seen, self.scale, self.mu, modes)
            slip_ok = _slip_settled(*seen, self.scale, new_modes, self.mu, new_directions)
            if settled and np.array_equal(new_modes, modes) and slip_ok:
                if not np.linalg.cond(stiffness) < 1e13:
                    return None  # at the point of sliding off: the motion is not fixed by the wrench
                return self._state(phi, r, modes, new_directions, system, iteration, True), xi
            modes, directions, gains = new_modes, new_directions, new_gains
        return None

    def _local_motion(self, displacements) -> np.ndarray:
        u = np.asarray(displacements, dtype=float)
        if u.shape != (self.n_nodes, 3):
            raise FemError(f"displacements must have shape ({self.n_nodes}, 3), got {u.shape}")
        return _to_nodes(self._frames, u.ravel()).reshape(-1, 3)

    def _set_turns(self, turns):
        """Hold the solve's turned frames (None where every turn is the identity)."""
        if turns is not None:
            turns = np.asarray(turns, dtype=float)
            if turns.shape != (self.n_nodes, 3, 3):
                raise FemError(f"turns must have shape ({self.n_nodes}, 3, 3), got {turns.shape}")
            if np.array_equal(turns, np.broadcast_to(np.eye(3), turns.shape)):
                turns = None
        self._turns = turns

    def _seen(self, phi, r):
        """(p, 3) forces and relative motions in the frames the contact is solved in."""
        if self._turns is None:
            return phi, r
        return np.einsum("pij,pj->pi", self._turns, phi), np.einsum("pij,pj->pi", self._turns, r)

    def _system(self, modes, directions, gains):
        """LU factor and right-hand-side blocks of the linearised law (kept when no node slips:
        sticking and lifted nodes' rows are those of any frame, so turns leave them as they are)."""
        turned = self._turns is not None
        if self._layout is None or self._layout.key != modes.tobytes() + (b"t" if turned else b""):
            self._layout = _mode_layout(modes, turned)
        layout = self._layout
        slipping = bool(layout.nodes.size)
        key = modes.tobytes()  # (a set without slip has the same rows turned or not)
        if not slipping and key in self._factors:
            self._factors.move_to_end(key)
            return self._factors[key]
        law, rhs_blocks = _mode_rows(modes, directions, gains, self.mu, self.scale, layout, self._turns)
        entry = (self._factor(law), rhs_blocks)
        if not slipping:
            self._factors[key] = entry
            if len(self._factors) > self._kept:
                self._factors.popitem(last=False)
        return entry

    def _factor(self, law):
        """A factorisation of a linearised law's matrix (C with the rows of ``law``, a
        :class:`_LawRows`, replaced): low rank where few rows differ from C.

        Sets without slip are factorised once and kept (dense LU). Sets with slip
        are factorised at every solve, through ``C^-1`` (computed once, about two
        LU factorisations), without forming the matrix. The choice depends on the
        modes alone, never on what the system solved before: the same motion gives
        the same bits.
        """
        n = self.c_local.shape[0]
        if not law.layout.normal.size or law.layout.rows.size > _LOW_RANK_ROWS * n:  # no slip, or too many rows
            return self._dense_factor(law)
        if self._inverse is None:
            self._inverse = spd_inverse(self.c_local, "the print's compliance")
        factor = _LowRankFactor(self.c_local, self._inverse, law)
        # Woodbury is exact in exact arithmetic; a badly conditioned capacitance (not
        # seen) would lose digits, and the dense factorisation then serves (so does a
        # NaN estimate). C's own conditioning is the compliance's: its inverse comes from
        # a Cholesky factor, and a force vector gets a step of iterative refinement.
        if not factor.reciprocal_condition >= _LOW_RANK_RCOND:
            return self._dense_factor(law)
        return factor

    def _dense_factor(self, law):
        """The dense factorisation of C with ``law``'s rows replaced, those rows equilibrated."""
        rows = law.layout.rows
        if not rows.size:
            return _DenseFactor(self.c_local)
        row_scale = np.ones(self.c_local.shape[0])
        row_scale[rows] = self._row_powers[rows]
        return _DenseFactor(_replace_rows(self.c_local, law), row_scale)

    def _forces(self, u_local, system):
        """Node forces and relative motions (node frames) of one linearised law."""
        factor, rhs_blocks = system
        phi = factor.solve(-block_diagonal_product(rhs_blocks, u_local.ravel()))
        r = u_local.ravel() + self.c_local @ phi
        return phi.reshape(-1, 3), r.reshape(-1, 3)

    def _newton(self, u_local, modes, directions, give_up_on_cycles=False):
        """Semismooth Newton (primal-dual active set) from given modes; None if it does not
        settle within ``_MAX_ITERATIONS`` steps, or, with ``give_up_on_cycles``, once it
        comes into one set of modes more than ``_SET_ENTRIES`` times (the starting set not
        counted).

        Each step solves the law linearised at the current iterate, with the modes
        read from it; it stops when the modes repeat and every slipping node's
        friction has reached its bound against its slip (to ``_SLIP_SETTLED`` of the
        largest force, or ``_SLIP_FLOOR`` once a step no longer halves it), then
        polishes the answer with one more step.
        """
        gains = np.zeros(self.n_nodes)
        entries = {}  # how many times the iteration has come into each set of modes
        before = np.inf  # the slip residual of the step before, in the same modes
        for iteration in range(1, _MAX_ITERATIONS + 1):
            if self._infinite_friction and np.isinf(self.mu[modes == SLIP]).any():
                # Slipping needs |t| = mu n: with mu = inf no such state (the law's
                # rows would hold inf); the caller says so.
                return None
            system = self._system(modes, directions, gains)
            phi, r = self._forces(u_local, system)
            seen = self._seen(phi, r)
            new_modes, new_directions, new_gains = _update_modes(*seen, self.scale, self.mu, modes)
            same = np.array_equal(new_modes, modes)
            residual = _slip_residual(*seen, self.scale, new_modes, self.mu, new_directions) if same else np.inf
            if residual <= _SLIP_SETTLED or _SLIP_FLOOR >= residual > 0.5 * before:
                # Linearised at the answer itself: L below is the exact Jacobian.
                system = self._system(new_modes, new_directions, new_gains)
                phi, r, new_directions = self._polished(u_local, new_modes, new_directions, system, phi, r)
                return phi, r, new_modes, new_directions, system, iteration
            if give_up_on_cycles and not same:
                key = new_modes.tobytes()
                entries[key] = entries.get(key, 0) + 1
                if entries[key] > _SET_ENTRIES:
                    return None  # the active set cycles: the caller starts elsewhere
            modes, directions, gains, before = new_modes, new_directions, new_gains, residual
        return None

    def _held(self, u_local, modes, directions):
        """Forces with the modes held: Newton on the slip directions only.

        It stops unsettled on a cycle of two steps (every slip direction back where it was
        two steps before, to 1e-9, and some 1e-3 from where it was one step before): held
        modes can admit no Coulomb state (a slipping node that pulls, its bound ``mu phi_n``
        negative, flips its direction at every step), where it ran all ``_MAX_ITERATIONS``
        (both soles on an 11 mm mesh, 520 nodes: 60 factorisations, 0.7 s a call). Held
        solves that settle can take 40 steps, with no progress for ten of them (climb's
        plans), so no rule on the residual's progress stops them.
        """
        gains = np.zeros(self.n_nodes)
        before = None  # the directions of two steps ago
        for _ in range(_MAX_ITERATIONS):
            system = self._system(modes, directions, gains)
            phi, r = self._forces(u_local, system)
            seen = self._seen(phi, r)
            new_directions, new_gains = _slip_directions(*seen, self.scale, self.mu, modes, directions)
            if _slip_settled(*seen, self.scale, modes, self.mu):
                system = self._system(modes, new_directions, new_gains)
                phi, r, new_directions = self._polished(u_local, modes, new_directions, system, phi, r)
                return phi, r, new_directions, system
            if (before is not None and np.abs(new_directions - before).max() <= _CYCLE_RETURN
                    and np.abs(new_directions - directions).max() >= _CYCLE_SWING):
                break
            before, directions, gains = directions, new_directions, new_gains
        return phi, r, directions, system

    def _polished(self, u_local, modes, directions, system, phi, r):
        """One more Newton step from a settled answer with slipping nodes.

        Settling stops at _SLIP_SETTLED (or _SLIP_FLOOR) of the largest force; the Newton step from there
        (quadratic) leaves round-off, so that finite differences of the forces
        through solves at nearby motions see their derivative, not the tolerance.
        """
        if not np.any(modes == SLIP):
            return phi, r, directions
        new_phi, new_r = self._forces(u_local, system)
        new_directions, _ = _slip_directions(*self._seen(new_phi, new_r), self.scale, self.mu, modes, directions)
        return new_phi, new_r, new_directions

    def _state(self, phi, r, modes, directions, system, iterations, settled) -> PrintContact:
        factor, rhs_blocks = system
        forces = _to_body(self._frames, phi.ravel()).reshape(-1, 3)
        relative = _to_body(self._frames, r.ravel()).reshape(-1, 3)
        return PrintContact(forces, relative, modes, directions, iterations, (factor, rhs_blocks, self._frames, settled),
                            _LawParameters(self.c_local, self.mu, self.scale, self._turns))


def solve_print_contact(compliance, displacements, frames, friction, initial_modes=None, initial_directions=None,
                        turns=None) -> PrintContact:
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
        Coulomb coefficient mu of each node (>= 0; ``np.inf``: the node sticks
        wherever it presses, bonded; a motion that would leave a node a tangential
        force with no normal force then has no contact state, a ``FemError``).
    initial_modes : (p,) int, optional
        Modes to start from (e.g. the previous call's): warm start.
    initial_directions : (p, 2) float, optional
        Slip directions going with ``initial_modes``.
    turns : (p, 3, 3) float, optional
        Each node's contact frame in its frame's coordinates (an indenter face turned from
        ``frames``; :meth:`PrintContactSystem.solve`).

    Returns
    -------
    PrintContact

    Raises
    ------
    FemError
        On shapes that do not match.
    ContactStateError
        When the active set finds no contact state (with very high friction a node can
        need a tangential force with almost no normal force; with infinite friction a
        node that would slip has no state at all).

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
    >>> state.forces[0].round(6).tolist(), int(state.modes[1]) == LIFT   # the second node lifts off
    ([0.0, 0.0, 100.0], True)
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
    return PrintContactSystem(c, frames, friction).solve(u, initial_modes, initial_directions, turns)


def print_contact_with_modes(compliance, displacements, frames, friction, modes, directions, turns=None) -> PrintContact:
    """The contact state with every node's mode imposed: smooth in U, no mode update.

    A solver that has found which nodes stick, slip and lift can hold that set while it
    converges (the forces are then smooth in U), and check at the end with
    :func:`solve_print_contact` that the set still holds (:attr:`PrintContact.admissible`
    says whether it does here).

    Parameters
    ----------
    compliance, displacements, frames, friction, turns
        As :func:`solve_print_contact`.
    modes : (p,) int
    directions : (p, 2) float
        As returned by :func:`solve_print_contact`; slipping nodes' directions are
        a starting guess (they follow U).

    Returns
    -------
    PrintContact
    """
    return PrintContactSystem(compliance, frames, friction).with_modes(displacements, modes, directions, turns)


def _gauss_seidel(c_local, u_local, mu, sweeps=500, tolerance=1e-12):
    """Projected Gauss-Seidel on the nodes: normal push, then tangential friction disc.

    Returns (p, 3) forces in node frames and the sweeps made. Each sweep solves every dof for its own
    relative motion with the others held, and projects each node's tangential
    force on its disc ``|phi_t| <= mu phi_n``. It stops at ``tolerance`` (the largest
    change of a sweep relative to the largest force), or once ``_GS_STALLED_WINDOWS``
    windows of ``_GS_WINDOW`` sweeps in a row have not shrunk that change
    ``_GS_PROGRESS`` times: at very
    high friction, where the contact may have no state, the sweeps cycle (iCub's palm at
    mu = 50: each sweep moving the forces by 65 % of the largest, for 2,000 sweeps), and
    500 sweeps in pure Python cost 0.3 s on foot-and-hand-on-foam's two prints (at mu = 50:
    54 calls, 16 s of a 19 s solve; 4.3 s in all with a one-window rule). Reaching the
    tolerance within ``sweeps`` needs 16 times a window on average; a run slow until its
    contact set settles can still stop short (a review's 7 random nodes at mu = 1, 1.9
    times over its second window: a one-window rule stopped it at 19 % of its forces), and
    the Newton restart from its modes then decides.
    """
    p = u_local.shape[0]
    phi = np.zeros(3 * p)
    r = u_local.ravel().copy()
    diagonal = np.diag(c_local)
    window_start = np.inf  # the relative change at the start of the current window
    stalled = 0  # windows in a row that did not shrink it _GS_PROGRESS times
    for sweep in range(sweeps):
        largest = 0.0
        for k in range(p):
            n = 3 * k + 2
            new = max(0.0, phi[n] - r[n] / diagonal[n])
            if new != phi[n]:
                r += c_local[:, n] * (new - phi[n])
                largest = max(largest, abs(new - phi[n]))
                phi[n] = new
            bound = mu[k] * phi[n] if phi[n] > 0.0 else 0.0
            # One step length for both tangents (the larger compliance): the
            # fixed point of a disc projection is then Coulomb's, friction against slip.
            step = 1.0 / max(diagonal[3 * k], diagonal[3 * k + 1])
            tangential = phi[3 * k : 3 * k + 2] - step * r[3 * k : 3 * k + 2]
            size = float(np.hypot(*tangential))
            if size > bound:
                tangential *= bound / size
            for axis, t in enumerate((3 * k, 3 * k + 1)):
                if tangential[axis] != phi[t]:
                    r += c_local[:, t] * (tangential[axis] - phi[t])
                    largest = max(largest, abs(tangential[axis] - phi[t]))
                    phi[t] = tangential[axis]
        change = largest / max(np.abs(phi).max(), 1e-300)
        if change <= tolerance:
            break
        if sweep % _GS_WINDOW == 0:
            stalled = stalled + 1 if change > window_start / _GS_PROGRESS else 0
            if stalled == _GS_STALLED_WINDOWS:
                break
            window_start = change
    return phi.reshape(p, 3), sweep + 1


def _modes_of(phi, mu):
    """Modes and slip directions read off a contact solution."""
    p = phi.shape[0]
    modes = np.full(p, STICK)
    directions = np.zeros((p, 2))
    size = np.hypot(phi[:, 0], phi[:, 1])
    slipping = (size >= _friction_bound(phi[:, 2], mu) * (1.0 - 1e-9)) & (size > 0.0)
    modes[slipping] = SLIP
    directions[slipping] = phi[slipping, :2] / size[slipping, None]
    modes[phi[:, 2] <= 0.0] = LIFT
    directions[modes == LIFT] = 0.0
    return modes, directions


def _replace_rows(c_local, law):
    """C with the rows of a :class:`_LawRows` replaced, (3p, 3p): ``law.values`` of the
    identity, its few nonzero entries placed rather than multiplied out (a product with
    the whole identity was most of this: 45 us of a 60-row print's factorisation)."""
    matrix = c_local.copy()
    layout = law.layout
    rows = np.zeros((layout.rows.size, c_local.shape[0]))
    rows[layout.lifted, layout.lifted_dofs] = 1.0
    if layout.normal.size and layout.turned:
        turned = np.einsum("kij,kj...->ki...", law.projected, c_local[layout.dofs])  # (k, 3, 3p)
        nodes = np.arange(layout.normal.size)
        for j in range(3):
            turned[nodes, :, layout.dofs[:, j]] += law.own[:, :, j]
        rows[layout.at] = turned
    elif layout.normal.size:
        turned = np.einsum("kij,kj...->ki...", law.projected, c_local[layout.tangential])  # (k, 2, 3p)
        nodes = np.arange(layout.normal.size)
        for j in range(2):
            turned[nodes, :, layout.tangential[:, j]] += law.own[:, :, j]
        turned[nodes, :, layout.normal] -= law.friction
        rows[layout.at] = turned
    matrix[layout.rows] = rows
    return matrix


@dataclass(frozen=True, eq=False)
class _ModeLayout:
    """What a linearised law takes from the modes alone: the rows it replaces, the lifted
    and slipping nodes' dofs, and the right-hand side's blocks but the slipping nodes' own.

    A contact solve meets the same modes again and again (the Newton steps while only
    the slip directions move, the polishing step, the next linearisation's solve: 611
    of the 734 laws of the built-in soft stances' solves had the modes of the one
    before), so :class:`PrintContactSystem` keeps the last layout.

    Attributes
    ----------
    key : bytes
        The modes' bytes.
    nodes : (k,) int
        The slipping nodes.
    rows : (r,) int
        The replaced rows, ascending.
    lifted_dofs : (a,) int
        The lifted nodes' dofs.
    lifted : (a,) int
        Their positions in ``rows``.
    tangential : (k, 2) int
        The slipping nodes' tangential dofs.
    normal : (k,) int
        Their normal dofs.
    dofs : (k, 3) int
        Their three dofs (tangential and normal).
    at : (k, 2) int, or (k, 3)
        Positions in ``rows`` of the tangential dofs (and, turned, the normal one).
    blocks : (p, 3, 3) float, read-only
        The identity at every node that does not lift off, 0 at those that do.
    turned : bool
        Whether the slipping nodes' contact is solved in turned frames: all three of
        their rows are replaced (their normal row too), else the tangential two.
    """

    key: bytes
    nodes: np.ndarray
    rows: np.ndarray
    lifted_dofs: np.ndarray
    lifted: np.ndarray
    tangential: np.ndarray
    normal: np.ndarray
    dofs: np.ndarray
    at: np.ndarray
    blocks: np.ndarray
    turned: bool = False


def _mode_layout(modes, turned=False) -> _ModeLayout:
    """The :class:`_ModeLayout` of (p,) int modes (``turned``: see its attribute)."""
    p = modes.shape[0]
    lifted, slipping = modes == LIFT, modes == SLIP
    rows = np.flatnonzero(~_compliance_rows(modes, turned))
    blocks = np.zeros((p, 3, 3))
    blocks[~lifted] = np.diag([1.0, 1.0, 1.0])
    blocks.setflags(write=False)
    nodes = np.flatnonzero(slipping)
    lifted_dofs = np.flatnonzero(np.repeat(lifted, 3))
    dofs = 3 * nodes[:, None] + np.arange(3)  # (k, 3)
    tangential = dofs[:, :2]
    replaced = dofs if turned else tangential
    return _ModeLayout(
        key=modes.tobytes() + (b"t" if turned else b""),
        nodes=nodes,
        rows=rows,
        lifted_dofs=lifted_dofs,
        lifted=np.searchsorted(rows, lifted_dofs),
        tangential=tangential,
        normal=dofs[:, 2],
        dofs=dofs,
        at=np.searchsorted(rows, replaced.ravel()).reshape(replaced.shape),
        blocks=blocks,
        turned=turned,
    )


@dataclass(frozen=True, eq=False)
class _LawRows:
    """The rows of a linearised law that are not rows of C, kept by their structure.

    A lifted node's three rows read ``phi = 0``; a slipping node's two tangential
    rows read ``P C[t] phi + O phi_t - mu d phi_n`` (P, O 2 x 2 blocks, d its slip
    direction): each row is C's row turned by a node's block plus at most three
    entries, so that products with them cost what the nodes do, not what C does. In
    turned frames (a node's contact frame Q times its node frame) a slipping node's three
    rows are ``[P Q_t; s_n q_n] C[node] phi + [O Q_t - mu d q_n; 0] phi_node`` (Q_t, q_n: Q's
    tangent rows and normal row, s_n the node's normal scale): ``projected`` and ``own`` are
    then (k, 3, 3) and ``friction`` is folded into ``own``.

    Attributes
    ----------
    layout : _ModeLayout
        What the modes alone fix: the replaced rows, the lifted and slipping nodes' dofs.
    projected : (k, 2, 2) float, or (k, 3, 3) turned
        P, on C's tangential rows (turned: ``[P Q_t; s_n q_n]`` on the node's three C rows).
    own : (k, 2, 2) float, or (k, 3, 3) turned
        O, on the node's tangential forces (turned: ``[O Q_t - mu d q_n; 0]`` on its three).
    friction : (k, 2) float
        ``mu d``, against the node's normal force.
    """

    layout: _ModeLayout
    projected: np.ndarray
    own: np.ndarray
    friction: np.ndarray

    def values(self, x, cx):
        """``A[R] x`` from ``x`` and ``C x``, (r,) or (r, m) for x (3p,) or (3p, m)."""
        layout = self.layout
        out = np.empty((layout.rows.size,) + x.shape[1:])
        out[layout.lifted] = x[layout.lifted_dofs]
        if layout.normal.size and layout.turned:
            out[layout.at] = (np.einsum("kij,kj...->ki...", self.projected, cx[layout.dofs])
                              + np.einsum("kij,kj...->ki...", self.own, x[layout.dofs]))
        elif layout.normal.size:
            turned = np.einsum("kij,kj...->ki...", self.projected, cx[layout.tangential])
            turned += np.einsum("kij,kj...->ki...", self.own, x[layout.tangential])
            turned -= self.friction.reshape(self.friction.shape + (1,) * (x.ndim - 1)) * x[layout.normal][:, None]
            out[layout.at] = turned
        return out


def _mode_rows(modes, directions, gains, mu, scale, layout=None, turns=None):
    """The law of fixed modes, linearised: ``matrix @ phi = -blocks * U`` (node frames),
    the matrix being C with a few rows replaced (:func:`_replace_rows` forms it).

    Sticking nodes: ``r = U + C phi = 0`` (C's rows); lifted: ``phi = 0``; slipping:
    ``r_n = 0`` and ``phi_t = mu phi_n d(tau)``, ``tau = phi_t - s r_t``, linearised
    about the iterate's direction ``d`` with gain ``k = mu phi_n / |tau|``: the exact
    (semismooth) Newton step, which is linear in (phi, U) because the law is
    positively homogeneous. ``layout``: the modes' :class:`_ModeLayout`, if known.

    Returns
    -------
    law : _LawRows
        The replaced rows: a lifted node's three, a slipping node's two tangential
        ones, in order.
    blocks : (p, 3, 3) float
        The right-hand side's blocks.
    """
    layout = _mode_layout(modes, turns is not None) if layout is None else layout
    nodes = layout.nodes
    blocks = layout.blocks.copy()
    d = directions[nodes]  # (k, 2)
    outer = np.einsum("ki,kj->kij", d, d)
    weight = gains[nodes] * 0.5 * (scale[nodes, 0] + scale[nodes, 1])  # k s per node
    projected = weight[:, None, None] * (np.eye(2) - outer)  # (k, 2, 2)
    own = (1.0 - gains[nodes])[:, None, None] * np.eye(2) + gains[nodes][:, None, None] * outer
    friction = mu[nodes][:, None] * d
    if turns is not None:
        # The law in the turned frame, phi' = Q phi and r' = Q r: O phi'_t + P r'_t - mu d phi'_n = 0
        # and r'_n = 0, rows over the node's three dofs of the node frames.
        q = turns[nodes]  # (k, 3, 3)
        tangents, normal = q[:, :2, :], q[:, 2, :]
        # The normal row scaled by the node's normal stiffness, as the tangential rows are by
        # theirs: unscaled (size 1 against 1/C) it left the low-rank capacitance 1/C worse
        # conditioned (a review: rcond 2e-6 against 7e-2, the Jacobian 5e-8 off).
        projected = np.concatenate([np.matmul(projected, tangents), (scale[nodes, 2][:, None] * normal)[:, None, :]],
                                   axis=1)  # (k, 3, 3)
        own = np.concatenate([np.matmul(own, tangents) - np.einsum("ki,kj->kij", friction, normal),
                              np.zeros((len(nodes), 1, 3))], axis=1)
        blocks[nodes] = projected
    else:
        blocks[nodes, :2, :2] = projected
    law = _LawRows(layout=layout, projected=projected, own=own, friction=friction)
    return law, blocks


def _compliance_rows(modes, turned=False) -> np.ndarray:
    """(3p,) bool: the rows of a linearised law that are rows of C, ``r = 0`` on that
    dof (a sticking node's, a slipping node's normal unless turned); the others are replaced."""
    motion_rows = np.repeat(modes != LIFT, 3)
    motion_rows.reshape(-1, 3)[modes == SLIP, : 3 if turned else 2] = False
    return motion_rows




def _friction_bound(normal, mu):
    """``mu phi_n`` of pushing nodes, 0 elsewhere (and no NaN from ``inf * 0``)."""
    pushing = normal > 0.0
    return np.where(pushing, mu * np.where(pushing, normal, 1.0), 0.0)


def _trial(phi, r, scale):
    """Per node the trial friction ``tau = phi_t - s r_t`` (one scale s per node: isotropic)."""
    s = 0.5 * (scale[:, 0] + scale[:, 1])
    return phi[:, :2] - s[:, None] * r[:, :2]


def _slip_directions(phi, r, scale, mu, modes, directions):
    """Slip directions and Newton gains ``mu phi_n / |tau|`` of slipping nodes (others: unchanged, 0)."""
    tau = _trial(phi, r, scale)
    size = np.hypot(tau[:, 0], tau[:, 1])
    moving = (modes == SLIP) & (size > 0.0)
    new = np.where(moving[:, None], tau / np.where(moving, size, 1.0)[:, None], directions)
    gains = np.where(moving, mu * phi[:, 2] / np.where(moving, size, 1.0), 0.0)
    gains = np.where(np.isfinite(gains), gains, 0.0)
    return new, gains


def _update_modes(phi, r, scale, mu, current):
    """Modes, slip directions and Newton gains from the complementarity functions of Signorini and
    Coulomb; ``current``: the modes ``phi`` and ``r`` were solved with (a node slipping there
    goes on slipping while its trial is over the bound, one sticking starts to slip only past
    ``_CONE_EDGE`` over it)."""
    # Contact where the normal force minus the scaled gap is not negative (a
    # node exactly at the surface touches: its bonded Jacobian tells a solver
    # that pressing makes force).
    contact = phi[:, 2] - scale[:, 2] * r[:, 2] >= 0.0
    bound = _friction_bound(phi[:, 2], mu)
    tau = _trial(phi, r, scale)
    size = np.hypot(tau[:, 0], tau[:, 1])
    # mu = inf means stick (a bound of inf is never exceeded); a sticking node on the cone's
    # edge too (_CONE_EDGE). The edge is one-sided: a band read as slipping from sticking and
    # as sticking from slipping would cycle (a sticking node over the bound by d slips, and
    # slipping it is over by d s / K, K its stiffness with the others stuck, K >= s).
    edge = np.where(np.asarray(current) == SLIP, bound, bound * (1.0 + _CONE_EDGE))
    slipping = contact & (size > edge)
    modes = np.where(contact, np.where(slipping, SLIP, STICK), LIFT)
    directions = np.where(slipping[:, None], tau / np.where(slipping, size, 1.0)[:, None], 0.0)
    gains = np.where(slipping, bound / np.where(slipping, size, 1.0), 0.0)
    return modes, directions, gains


def _slip_settled(phi, r, scale, modes, mu, directions=None) -> bool:
    """Whether every slipping node's friction is ``mu phi_n`` along its trial direction (to
    ``_SLIP_SETTLED`` of the largest force): :func:`_slip_residual`."""
    return _slip_residual(phi, r, scale, modes, mu, directions) <= _SLIP_SETTLED


def _slip_residual(phi, r, scale, modes, mu, directions=None) -> float:
    """The largest gap of a slipping node's friction to ``mu phi_n`` along its trial direction,
    as a share of the largest force (0 where none slips).

    With the modes from that same trial (``|tau| > mu phi_n``) this is Coulomb's
    slip: on the bound, against the relative motion ``r_t = -(|tau| - mu phi_n) / s * tau / |tau|``.
    ``directions``: the (p, 2) trial directions :func:`_update_modes` read off these
    ``phi`` and ``r`` with these modes (the same numbers: a node slips there only where
    ``|tau| > 0``), else computed here.
    """
    slipping = modes == SLIP
    if not slipping.any():
        return 0.0
    if directions is None:
        tau = _trial(phi, r, scale)[slipping]
        size = np.hypot(tau[:, 0], tau[:, 1])
        direction = tau / np.where(size > 0.0, size, 1.0)[:, None]
    else:
        direction = directions[slipping]
    residual = phi[slipping, :2] - (mu[slipping] * phi[slipping, 2])[:, None] * direction
    return float(np.abs(residual).max()) / max(float(np.abs(phi).max()), 1e-300)
