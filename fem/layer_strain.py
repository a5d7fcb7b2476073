"""The strain a ball foot leaves in an elastic layer bonded to a rigid base, from a converged field.

A mesh whose cells are as wide as a ball's contact gets the strain under it too low: under
a ball 2.55 mm deep in quadruped-foam's 10 mm foam mesh, the largest 20 mm mean is 2.19 %
where a converged field gives 2.60 % (an independent audit's own FEM, 2026-12-04: 2.62 %).
A ball alone on a wide layer leaves an axisymmetric field, and that field is cheap to
converge: bilinear quadrilaterals in (r, z) (:func:`axisymmetric_layer_field`), a twelfth
of the contact radius wide under the ball, at most a twenty-fifth of the averaging radius
over the means' reach, growing by 1.15 beyond it, twenty thicknesses wide, the base bonded,
the top loaded by the ball's Hertzian pressure ``p = 3 F / (2 pi a^2) sqrt(1 - r^2 / a^2)``
(the pressure :func:`fem.hertz_load_shares` spreads on a mesh). The means of that field over
balls of radius rho clipped by the layer (what :class:`fem.strain_average.BallAverages`
takes on a mesh) are exact ring integrals (:meth:`AxisymmetricField.ball_means`), and
:func:`largest_ball_mean` searches their largest principal magnitude over the layer: on
quadruped-foam's foam (5 cm, 20 mm means) it lies on the axis at the surface; on a layer
thinner than the averaging ball, at the base, off the axis. Linear elasticity makes it the
force times a function of the contact radius over Young's modulus: :class:`LayerBallStrain`
tabulates that function (3-4 s on a loaded 2-core host the first time, then from the disk cache).

One ball, its normal force and its sideways force (the first Fourier harmonic of the same
mesh, under a traction proportional to the pressure); another ball's far field and the
body's own weight are not in it (a mesh's field carries those). An independent audit
(2026-12-05: its own axisymmetric FEM, quadratic elements, the exact sphere) put
quadruped-foam's balls at a 1 % bound, 0.37 of their load sideways, at 1.148-1.168 %: this
module gives 1.148-1.167 % for the same forces (0.998 % without the sideways force).
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from scipy.interpolate import CubicSpline, RectBivariateSpline

from .cache import cache_digest, default_cache
from .errors import FemError
from .layer_contact import check_poisson_ratio, check_positive
from .solvers import available_solvers, factorize

__all__ = ["AxisymmetricField", "axisymmetric_layer_field", "largest_ball_mean", "LayerBallStrain"]

# The mesh (module docstring): element widths under the contact and over the means' reach,
# their growth beyond, and the layer's modelled width (its far edge free).
_CONTACT_CELLS = 12.0
_AVERAGING_CELLS = 25.0
_GROWTH = 1.15
_WIDTH = 20.0
# Sub-cells per element side where the ball means' rings are sampled (the clipping
# sphere cuts elements; 4 and 8 agree to 0.05 %).
_SUB = 4
# The finest cells: this share of the contact radius (a mean over a ball much smaller than the
# contact needs no finer: it is the pointwise strain there, which cells of a / 12 give).
_FINEST_CELLS = 48.0
# The largest mean's search (largest_ball_mean): a grid of centres over the layer's depth and
# out to (contact radius + averaging radius) from the axis, then finer grids around the best.
_SEARCH_GRID = (9, 13)
_SEARCH_REFINEMENTS = 3
# LayerBallStrain's table: contact radii between its ends, squared sideways ratios from 0.
_TABLE_POINTS = 7
_RATIO_POINTS = 7


@dataclass(frozen=True)
class AxisymmetricField:
    """A layer's displacement under a ball's pressure of 1 N, Young's modulus 1 Pa.

    Attributes
    ----------
    radii : (nr,) float
        Node distances from the axis, metres, ascending from 0.
    depths : (nz,) float
        Node depths below the surface, metres, ascending from 0 to the thickness.
    displacement : (nz, nr, 2) or (nz, nr, 3) float
        Under the pressure (``sideways`` False): radial and vertical (up) displacement of each
        node. Under the sideways traction along x (``sideways`` True): the amplitudes
        ``(U_r, U_z, U_theta)`` of ``u_r = U_r cos(theta)``, ``u_z = U_z cos(theta)``,
        ``u_theta = -U_theta sin(theta)``, theta from x. Metres per (N / Pa).
    sideways : bool
        Which load: the Hertzian pressure, or a traction along x proportional to it.
    """

    radii: np.ndarray
    depths: np.ndarray
    displacement: np.ndarray
    sideways: bool = False

    def ball_means(self, radius: float, centres) -> np.ndarray:
        """Mean strain tensors over balls of ``radius`` clipped by the layer.

        Parameters
        ----------
        radius : float
            Metres, > 0.
        centres : (k, 2) float
            Each ball's centre: distance from the axis (along x) and depth below the surface, metres.

        Returns
        -------
        (k, 3, 3) float
            Cartesian strain tensors (shears halved), axes x (from the axis to the centre), y, z (up).
            A sideways field's: its traction along +x, the centres on the +x side of the axis
            (a centre on the other side: the same tensor with its xx, yy and zz negated,
            :func:`largest_ball_mean`).
        """
        centres = np.asarray(centres, dtype=float).reshape(-1, 2)
        samples = self._samples()
        arc_sums = _sideways_arc_sums if self.sideways else _pressure_arc_sums
        out = []
        for distance, depth in centres:
            r, z, *strains, weight = _near(samples, radius, distance, depth)
            # Each sample is a ring; the ball holds the arc |theta| <= theta_0 of it.
            theta = self._arcs(radius, distance, depth, r, z)
            # Sums, not BLAS dot products: a thread pool busy elsewhere made each of those 15 ms.
            volume = float(np.sum(weight * 2.0 * theta))
            if volume <= 0.0:
                raise FemError(f"a ball of radius {radius:g} m centred {depth:g} m deep holds no part of the layer")
            out.append(arc_sums(strains, weight, theta) / volume)
        return np.array(out)

    @staticmethod
    def _arcs(radius, distance, depth, r, z) -> np.ndarray:
        """Half-angle of each sample ring's arc inside the ball of ``radius`` centred
        ``distance`` from the axis along x, ``depth`` deep (0 outside it, pi all of it)."""
        left = radius * radius - (z - depth) ** 2
        if distance == 0.0:
            return np.where(r * r <= left, np.pi, 0.0)
        cosine = (r * r + distance * distance - left) / (2.0 * r * distance)
        return np.where(left > 0.0, np.arccos(np.clip(cosine, -1.0, 1.0)), 0.0)

    def _samples(self):
        """Strains at sub-cell centres of every element and each sub-cell's ring weight per radian.

        Under the pressure ``(r, depth, e_rr, e_zz, e_tt, g_rz, weight)``; under the sideways
        traction the amplitudes of ``e_rr, e_zz, e_tt, g_rz`` (times cos theta) and of
        ``g_rt = (U_r - U_theta) / r + dU_theta/dr``, ``g_tz = dU_theta/dz + U_z / r`` (times
        -sin theta) before the weight. Each a ``((nz - 1) s, (nr - 1) s)`` array (s sub-cells
        a side), the sub-cells' tensor grid: depth ascending down its rows, r along its
        columns, so that the samples near a ball are a block of it (:func:`_near`).
        """
        known = self.__dict__.get("_sampled")
        if known is not None:
            return known
        r0, r1 = self.radii[:-1], self.radii[1:]
        d0, d1 = self.depths[:-1], self.depths[1:]
        u = self.displacement
        # Corners (depth index j, radius index i): 00, 01, 11, 10 in (xi along r, eta along depth).
        corners = np.stack([u[:-1, :-1], u[:-1, 1:], u[1:, 1:], u[1:, :-1]], axis=2)  # (nz-1, nr-1, 4, 2)
        hr = 0.5 * (r1 - r0)[None, :]
        hz = 0.5 * (d1 - d0)[:, None]
        points = (np.arange(_SUB) + 0.5) / _SUB * 2.0 - 1.0
        samples = []
        for eta in points:
            for xi in points:
                shape, d_xi, d_eta = _shape(xi, eta)
                r = r0[None, :] + (1.0 + xi) * hr + 0.0 * hz
                depth = d0[:, None] + (1.0 + eta) * hz + 0.0 * hr
                u_r, u_z = corners[..., 0], corners[..., 1]
                u_t = corners[..., 2] if self.sideways else 0.0 * u_r
                e_rr = (u_r @ d_xi) / hr
                e_tt = ((u_r - u_t) @ shape) / r
                # eta runs down (depth): d/dz = -d/d depth, z up.
                e_zz = -(u_z @ d_eta) / hz
                g_rz = -(u_r @ d_eta) / hz + (u_z @ d_xi) / hr
                weight = r * (hr * hz) * (4.0 / _SUB**2)
                if not self.sideways:
                    samples.append((r, depth, e_rr, e_zz, e_tt, g_rz, weight))
                    continue
                g_rt = e_tt + (u_t @ d_xi) / hr
                g_tz = -(u_t @ d_eta) / hz + (u_z @ shape) / r
                samples.append((r, depth, e_rr, e_zz, e_tt, g_rz, g_rt, g_tz, weight))
        # (eta, xi, depth row, radius column) -> (depth row, eta, radius column, xi): sub-cells
        # in the order of their depths and radii.
        nz, nr = len(self.depths) - 1, len(self.radii) - 1
        sampled = tuple(
            np.stack([s[k] for s in samples]).reshape(_SUB, _SUB, nz, nr).transpose(2, 0, 3, 1).reshape(nz * _SUB, nr * _SUB)
            for k in range(len(samples[0])))
        object.__setattr__(self, "_sampled", sampled)
        return sampled


def _pressure_arc_sums(strains, weight, theta) -> np.ndarray:
    """(3, 3) the pressure's field's Cartesian strain summed over each sample ring's arc
    ``|theta| <= theta_0`` (times its weight): ``e_rr``, ``e_tt`` turned by the arc's angle,
    ``e_zz`` and ``g_rz`` (:meth:`AxisymmetricField._samples`)."""
    e_rr, e_zz, e_tt, g_rz = strains
    sc = np.sin(theta) * np.cos(theta)
    cos2, sin2, cos1 = theta + sc, theta - sc, 2.0 * np.sin(theta)
    sums = np.zeros((3, 3))
    sums[0, 0] = np.sum(weight * (e_rr * cos2 + e_tt * sin2))
    sums[1, 1] = np.sum(weight * (e_rr * sin2 + e_tt * cos2))
    sums[2, 2] = np.sum(weight * e_zz * 2.0 * theta)
    sums[0, 2] = sums[2, 0] = np.sum(weight * 0.5 * g_rz * cos1)
    return sums


def _sideways_arc_sums(strains, weight, theta) -> np.ndarray:
    """:func:`_pressure_arc_sums` of a sideways field.

    With ``c = cos(theta)``, ``s = sin(theta)`` a sample's Cartesian strain is
    ``xx = A c^3 + (B + 2 E') c s^2``, ``yy = (A - 2 E') c s^2 + B c^3``, ``zz = C c``,
    ``xz = D c^2 + F s^2`` (xy and yz odd in theta: no part in a mean over an arc symmetric
    about x), A..F its amplitudes (:meth:`AxisymmetricField._samples`); the arc
    ``|theta| <= theta_0`` integrates those powers exactly.
    """
    e_rr, e_zz, e_tt, g_rz, g_rt, g_tz = strains
    sine, cosine = np.sin(theta), np.cos(theta)
    cos3 = 2.0 * (sine - sine**3 / 3.0)
    cos_sin2 = 2.0 * sine**3 / 3.0
    cos2, sin2 = theta + sine * cosine, theta - sine * cosine
    sums = np.zeros((3, 3))
    sums[0, 0] = np.sum(weight * (e_rr * cos3 + (e_tt + g_rt) * cos_sin2))
    sums[1, 1] = np.sum(weight * ((e_rr - g_rt) * cos_sin2 + e_tt * cos3))
    sums[2, 2] = np.sum(weight * e_zz * 2.0 * sine)
    sums[0, 2] = sums[2, 0] = np.sum(weight * 0.5 * (g_rz * cos2 + g_tz * sin2))
    return sums


def _near(samples, radius, distance, depth):
    """The samples whose rings may cross the ball of ``radius`` centred ``distance`` from the
    axis, ``depth`` deep (the others hold no arc of it): those within ``radius`` of it in depth
    and in r, a block of the sub-cells' grid (:meth:`AxisymmetricField._samples`), views."""
    radii, depths = samples[0][0], samples[1][:, 0]
    rows = slice(np.searchsorted(depths, depth - radius, "left"), np.searchsorted(depths, depth + radius, "right"))
    columns = slice(np.searchsorted(radii, distance - radius, "left"), np.searchsorted(radii, distance + radius, "right"))
    return [values[rows, columns] for values in samples]


def _shape(xi: float, eta: float):
    """Bilinear shape functions of corners 00, 01, 11, 10 and their derivatives in xi and eta."""
    shape = 0.25 * np.array([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta), (1 + xi) * (1 + eta), (1 - xi) * (1 + eta)])
    d_xi = 0.25 * np.array([-(1 - eta), (1 - eta), (1 + eta), -(1 + eta)])
    d_eta = 0.25 * np.array([-(1 - xi), -(1 + xi), (1 + xi), (1 - xi)])
    return shape, d_xi, d_eta


def _graded(contact_radius: float, fine: float, cap: float, capped: float, total: float) -> np.ndarray:
    """Node coordinates from 0 to ``total``: ``fine`` apart under the contact (to 1.5 a), then
    growing by _GROWTH, at most ``cap`` apart up to ``capped``."""
    nodes = list(np.arange(0.0, min(1.5 * contact_radius, total) + 1e-15 * total, fine))
    step = fine
    while nodes[-1] < total * (1.0 - 1e-12):
        step *= _GROWTH
        if nodes[-1] < capped:
            step = min(step, cap)
        nodes.append(min(nodes[-1] + step, total))
    return np.array(nodes)


def axisymmetric_layer_field(contact_radius: float, thickness: float, poisson_ratio: float,
                             averaging_radius: float, sideways: bool = False) -> AxisymmetricField:
    """The layer's field under a ball's Hertzian pressure of 1 N, Young's modulus 1 Pa, or
    under a sideways traction of 1 N along x proportional to that pressure.

    The sideways field is the first Fourier harmonic of the same (r, z) mesh: amplitudes
    ``(U_r, U_z, U_theta)`` at each node, strains ``e_rr, e_zz, e_tt = (U_r - U_theta) / r,
    g_rz`` varying as cos(theta) and ``g_rt, g_tz`` as -sin(theta), each group's energy
    integrating cos^2 or sin^2 to pi over the circle; on the axis ``U_z = 0`` and ``U_theta =
    U_r`` (a single-valued displacement there). The traction ``q(r)`` (1 N in all) loads
    ``U_r`` and ``U_theta`` alike, ``pi int N q r dr``. A sideways force ``T`` with a normal
    force ``F`` is the pressure's field times ``F`` plus this one times ``T``: a traction
    proportional to the pressure leaves each point of the contact the resultant's ratio
    (an independent audit found the largest mean moved 0.3 % between three such spreads).

    Parameters
    ----------
    contact_radius : float
        The pressure's radius a, metres, > 0.
    thickness : float
        The layer's, metres, > 0; its base is bonded (no displacement).
    poisson_ratio : float
        In [0, 0.5).
    averaging_radius : float
        Metres, >= 0: the mesh is fine enough over it for the ball means of that radius.
    sideways : bool
        The sideways traction's field instead of the pressure's.

    Returns
    -------
    AxisymmetricField
        Displacements per newton and pascal: a force F and a modulus E scale them by F / E.
    """
    check_positive(contact_radius=contact_radius, thickness=thickness)
    check_poisson_ratio(poisson_ratio)
    if not (np.isfinite(averaging_radius) and averaging_radius >= 0.0):
        raise FemError(f"averaging_radius must be finite and >= 0, got {averaging_radius!r}")
    a = float(contact_radius)
    fine = a / _CONTACT_CELLS
    if averaging_radius > 0.0:
        fine = min(fine, max(averaging_radius / _AVERAGING_CELLS, a / _FINEST_CELLS))
    # Over the means' reach (largest_ball_mean's centres and their balls, which a thin layer's
    # base holds), cells of at most a twenty-fifth of the averaging radius.
    cap, reach = max(averaging_radius / _AVERAGING_CELLS, fine), 1.5 * a + 3.0 * averaging_radius
    radii = _graded(a, fine, cap, reach, _WIDTH * thickness)
    depths = _graded(a, fine, cap, reach, thickness)
    nr, nz = len(radii), len(depths)
    node = np.arange(nr * nz).reshape(nz, nr)
    # Elasticity in (e_rr, e_zz, e_tt, g_rz), E = 1: its shear part integrated at 2 x 2
    # points, its Lame part at the centre (selective reduced integration: full integration
    # locks as nu nears 1/2, 2-3 % stiff at 0.49 against Hertz's field).
    lame = poisson_ratio / ((1.0 + poisson_ratio) * (1.0 - 2.0 * poisson_ratio))
    shear = 1.0 / (2.0 * (1.0 + poisson_ratio))
    # Strain (e_rr, e_zz, e_tt, g_rz[, g_rt, g_tz]); dofs a node (u_r, u_z[, u_theta]).
    strains, per_node = (6, 3) if sideways else (4, 2)
    shear_part = np.diag([2.0 * shear] * 3 + [shear] * (strains - 3))
    lame_part = np.zeros((strains, strains))
    lame_part[:3, :3] = lame
    corners = np.stack([node[:-1, :-1], node[:-1, 1:], node[1:, 1:], node[1:, :-1]], axis=2).reshape(-1, 4)
    hr = np.broadcast_to(0.5 * np.diff(radii)[None, :], (nz - 1, nr - 1)).ravel()
    hz = np.broadcast_to(0.5 * np.diff(depths)[:, None], (nz - 1, nr - 1)).ravel()
    r0 = np.broadcast_to(radii[None, :-1], (nz - 1, nr - 1)).ravel()
    size_e = 4 * per_node
    stiffness = np.zeros((len(corners), size_e, size_e))
    # The circle's share of the energy: 2 pi for the pressure's field, pi for each cos^2 or sin^2 group.
    circle = np.pi if sideways else 2.0 * np.pi
    gauss = np.array([-1.0, 1.0]) / np.sqrt(3.0)
    rule = [(xi, eta, 1.0, shear_part) for xi in gauss for eta in gauss] + [(0.0, 0.0, 4.0, lame_part)]
    for xi, eta, weight, elasticity in rule:
        shape, d_xi, d_eta = _shape(xi, eta)
        r = r0 + (1.0 + xi) * hr
        along_r, along_z, over_r = d_xi[None] / hr[:, None], -d_eta[None] / hz[:, None], shape[None] / r[:, None]
        b = np.zeros((len(corners), strains, size_e))
        u_r, u_z = slice(0, None, per_node), slice(1, None, per_node)
        b[:, 0, u_r] = along_r
        b[:, 1, u_z] = along_z
        b[:, 2, u_r] = over_r
        b[:, 3, u_r] = along_z
        b[:, 3, u_z] = along_r
        if sideways:
            u_t = slice(2, None, per_node)
            b[:, 2, u_t] = -over_r
            b[:, 4, u_r] = over_r
            b[:, 4, u_t] = along_r - over_r
            b[:, 5, u_t] = along_z
            b[:, 5, u_z] = over_r
        stiffness += (b.transpose(0, 2, 1) @ elasticity @ b) * (weight * circle * r * hr * hz)[:, None, None]
    dofs = np.stack([per_node * corners + k for k in range(per_node)], axis=2).reshape(-1, size_e)
    size = per_node * nr * nz
    matrix = scipy.sparse.csr_matrix(
        (stiffness.ravel(), (np.repeat(dofs, size_e, axis=1).ravel(), np.tile(dofs, (1, size_e)).ravel())),
        shape=(size, size))
    load = np.zeros(size)
    # The load's consistent nodal values on the surface's edges, Gauss-Legendre on each (its
    # square-root edge is where the contact's last edge ends): the pressure on u_z (down), or
    # the traction on u_r and u_theta.
    points, weights = np.polynomial.legendre.leggauss(12)
    peak = 3.0 / (2.0 * np.pi * a * a)
    loaded = (0, 2) if sideways else (1,)
    sign = 1.0 if sideways else -1.0
    for i in range(nr - 1):
        start, stop = radii[i], radii[i + 1]
        if start >= a:
            break
        end = min(stop, a)
        s = start + 0.5 * (points + 1.0) * (end - start)
        w = sign * 0.5 * weights * (end - start) * peak * np.sqrt(np.maximum(1.0 - (s / a) ** 2, 0.0)) * circle * s
        for k in loaded:
            load[per_node * node[0, i] + k] += w @ ((stop - s) / (stop - start))
            load[per_node * node[0, i + 1] + k] += w @ ((s - start) / (stop - start))
    fixed = np.zeros(size, dtype=bool)
    for k in range(per_node):
        fixed[per_node * node[-1] + k] = True  # the bonded base
    axis = per_node * node[:, 0]
    if not sideways:
        fixed[axis] = True  # the axis: no radial displacement
        free = np.flatnonzero(~fixed)
        displacement = np.zeros(size)
        displacement[free] = _spd_solve(matrix[free][:, free], load[free])
        return AxisymmetricField(radii, depths, displacement.reshape(nz, nr, 2))
    # The axis: u_z = 0, u_theta tied to u_r (its column merged into u_r's).
    fixed[axis + 1] = True
    merged = np.arange(size)
    merged[axis + 2] = axis
    fixed[axis + 2] = True
    kept = np.flatnonzero(~fixed)
    column = np.full(size, -1)
    column[kept] = np.arange(len(kept))
    tied = np.flatnonzero(column[merged] >= 0)
    transfer = scipy.sparse.csr_matrix((np.ones(len(tied)), (tied, column[merged[tied]])), shape=(size, len(kept)))
    reduced = (transfer.T @ matrix @ transfer).tocsc()
    displacement = transfer @ _spd_solve(reduced, transfer.T @ load)
    return AxisymmetricField(radii, depths, displacement.reshape(nz, nr, 3), sideways=True)


def _spd_solve(matrix, rhs) -> np.ndarray:
    """``matrix^-1 rhs`` for the layer's symmetric positive definite stiffness: CHOLMOD's
    sparse Cholesky (:func:`fem.solvers.factorize`) where cvxopt is installed, 3.6-5 times
    faster than SuperLU's general LU on these (r, z) meshes (31k-46k dofs: 0.25 -> 0.07 s,
    0.86 -> 0.17 s), the same field to 3e-14; else that LU (SuperLU in symmetric mode, the
    library's other factorisation, took 5-7 s on the larger ones: its ordering does not
    suit them)."""
    matrix = scipy.sparse.csc_matrix(matrix)
    if "cholmod" in available_solvers():
        return factorize(matrix, "cholmod").solve(rhs)
    return scipy.sparse.linalg.spsolve(matrix, rhs)


def largest_ball_mean(field: AxisymmetricField, radius: float, contact_radius: float,
                      sideways: AxisymmetricField | None = None, ratio: float = 0.0) -> float:
    """The largest principal strain magnitude of the field's ball means of ``radius``, per
    newton and pascal, over centres anywhere in the layer out to ``contact_radius + radius``
    from the axis; with ``sideways`` (the same layer's sideways field) and ``ratio``, of the
    field under a normal force of 1 N and a sideways one of ``ratio`` N.

    A grid of centres over the layer's depth (its base included: on a layer thinner than the
    ball, the strain gathers where the base holds it) is searched, then finer grids around the
    best. With a sideways force the centres lie in the plane of the two forces, on either
    side of the axis (behind the ball: the sideways field's xx, yy and zz means change sign,
    the pressure's xz mean does, which leaves the principal magnitudes of ``M0 - ratio M1``);
    an independent audit's FEM (2026-12-05) found the largest there, 8-10 mm ahead of
    quadruped-foam's balls. A ball smaller than two of the finest cells takes the pointwise
    strains' largest instead: no mean's magnitude exceeds it (the magnitude is a norm, and
    convex), and cells that small are the field's own resolution.
    """
    ratio = float(ratio) if sideways is not None else 0.0
    return float(_largest_means_at(field, sideways, radius, contact_radius, np.array([ratio]))[0])


def _largest_means_at(field, sideways, radius, contact_radius, ratios) -> np.ndarray:
    """:func:`largest_ball_mean` at each sideways ratio of ``ratios`` (the first grid's
    means computed once for all of them)."""
    cell = min(float(np.diff(field.radii)[0]), float(np.diff(field.depths)[0]))
    if radius < 2.0 * cell:
        return np.array([_largest_pointwise(field, sideways, ratio) for ratio in ratios])
    thickness = float(field.depths[-1])
    reach = contact_radius + radius
    pulled = sideways is not None and np.any(ratios != 0.0)

    known = {}  # centre -> its means: the ratios' refined grids share many centres (420 -> 273 on a mat)

    def means(centres):
        new = [c for c in map(tuple, centres.tolist()) if c not in known]
        if new:
            normal = field.ball_means(radius, new)
            pull = sideways.ball_means(radius, new) if pulled else [None] * len(new)
            known.update(zip(new, zip(normal, pull)))
        both = [known[c] for c in map(tuple, centres.tolist())]
        return np.array([n for n, _ in both]), np.array([q for _, q in both]) if pulled else None

    def magnitudes(both, ratio):
        normal, pull = both
        stacked = normal if not ratio else np.concatenate([normal + ratio * pull, normal - ratio * pull])
        eigenvalues = np.linalg.eigvalsh(stacked)
        return np.maximum(eigenvalues[:, -1], -eigenvalues[:, 0]).reshape(2 if ratio else 1, -1).max(axis=0)

    xs0, zs0 = np.linspace(0.0, reach, _SEARCH_GRID[0]), np.linspace(0.0, thickness, _SEARCH_GRID[1])
    first_centres = np.array([(u, v) for u in xs0 for v in zs0])
    first = means(first_centres)
    out = []
    for ratio in ratios:
        xs, zs, centres, both = xs0, zs0, first_centres, first
        best, (x, z) = -1.0, (0.0, 0.0)
        for refinement in range(_SEARCH_REFINEMENTS + 1):
            if refinement:
                centres = np.array([(u, v) for u in xs for v in zs])
                both = means(centres)
            found = magnitudes(both, float(ratio))
            k = int(np.argmax(found))
            if found[k] > best:
                best, (x, z) = float(found[k]), centres[k]
            # A grid half as wide around the best, within the layer and the reach.
            dx, dz = xs[1] - xs[0] if len(xs) > 1 else 0.0, zs[1] - zs[0] if len(zs) > 1 else 0.0
            xs = np.unique(np.clip(x + np.linspace(-dx, dx, 5), 0.0, reach))
            zs = np.unique(np.clip(z + np.linspace(-dz, dz, 5), 0.0, thickness))
        out.append(best)
    return np.array(out)


def _largest_pointwise(field, sideways, ratio) -> float:
    """The largest principal strain magnitude over the field's samples (with ``ratio`` N of
    ``sideways``'s along x: in the plane of the forces, theta 0 and pi)."""
    _, _, e_rr, e_zz, e_tt, g_rz, _ = field._samples()
    parts = [(e_rr, e_zz, e_tt, g_rz)]
    if ratio:
        _, _, s_rr, s_zz, s_tt, s_rz, _, _, _ = sideways._samples()
        parts = [(e_rr + sign * ratio * s_rr, e_zz + sign * ratio * s_zz, e_tt + sign * ratio * s_tt,
                  g_rz + sign * ratio * s_rz) for sign in (1.0, -1.0)]
    largest = 0.0
    for rr, zz, tt, rz in parts:
        centre, half = 0.5 * (rr + zz), np.hypot(0.5 * (rr - zz), 0.5 * rz)
        largest = max(largest, float(np.max(np.maximum.reduce([np.abs(tt), np.abs(centre + half), np.abs(centre - half)]))))
    return largest


@dataclass(frozen=True)
class LayerBallStrain:
    """The largest mean strain a ball leaves in a layer, per newton of its normal force, as a
    function of its contact radius and of its sideways force's ratio to the normal one:
    ``strain = F * per_force(a, Q / F) / E``, tabulated.

    The table holds :func:`largest_ball_mean` of :func:`axisymmetric_layer_field` (and, with
    ``largest_ratio``, of its sideways field) at contact radii cosine-spaced from ``smallest``
    to ``largest`` and at ratios evenly spaced to ``largest_ratio`` (7 of each); a cubic spline
    interpolates it (within 0.3 % of a fresh field between its points, the tests), held at
    its ends beyond them. In the squared ratio: the strain is even in the sideways force
    (a ball pulled the other way leaves the mirrored field), so smooth in its square, and its
    derivative is zero with no sideways force.

    Parameters
    ----------
    thickness : float
        The layer's, metres, > 0.
    poisson_ratio : float
        In [0, 0.5).
    averaging_radius : float
        The ball means' radius, metres, >= 0 (an object's ``strain_radius``).
    smallest, largest : float
        The contact radii the table spans, metres, 0 < smallest <= largest.
    largest_ratio : float, optional
        The largest sideways-to-normal force ratio the table spans (a ball's friction
        coefficient: its pyramid holds it there), >= 0; 0 (the default): normal forces only.
    """

    thickness: float
    poisson_ratio: float
    averaging_radius: float
    smallest: float
    largest: float
    largest_ratio: float = 0.0
    _spline: object = field(init=False, repr=False, compare=False)
    _sizes: tuple = field(init=False, repr=False, compare=False)  # (contact radii, squared ratios) tabulated

    def __post_init__(self) -> None:
        if not (np.isfinite(self.smallest) and 0.0 < self.smallest <= self.largest and np.isfinite(self.largest)):
            raise FemError(f"the contact radii must satisfy 0 < smallest <= largest, got {self.smallest!r} and "
                           f"{self.largest!r}")
        if not (np.isfinite(self.largest_ratio) and self.largest_ratio >= 0.0):
            raise FemError(f"largest_ratio must be finite and >= 0, got {self.largest_ratio!r}")
        # Cosine-spaced: the means fall fastest as the contact nears the table's widest.
        shares = 0.5 * (1.0 - np.cos(np.linspace(0.0, np.pi, _TABLE_POINTS)))
        radii = np.unique(self.smallest + shares * (self.largest - self.smallest))
        # Evenly spaced in the ratio (in its square the first steps are short: the strain turns
        # there, and on a thin layer its largest mean moves between the surface and the base).
        squares = ((self.largest_ratio * np.linspace(0.0, 1.0, _RATIO_POINTS)) ** 2 if self.largest_ratio > 0.0
                   else np.zeros(1))
        values = _largest_means(self.thickness, self.poisson_ratio, self.averaging_radius, radii, np.sqrt(squares))
        if len(radii) == 1:
            spline = CubicSpline(squares, values[0]) if len(squares) > 1 else float(values[0, 0])
        elif len(squares) == 1:
            spline = CubicSpline(radii, values[:, 0])
        else:
            spline = RectBivariateSpline(radii, squares, values, kx=3, ky=3)
        object.__setattr__(self, "_spline", spline)
        object.__setattr__(self, "_sizes", (len(radii), len(squares)))

    def per_force(self, contact_radius: float, ratio: float = 0.0) -> tuple[float, float, float]:
        """The largest mean principal strain magnitude per newton of normal force (times
        Young's modulus in pascals), and its derivatives in the contact radius (per metre)
        and in the squared ratio.

        Parameters
        ----------
        contact_radius : float
            Metres.
        ratio : float
            The sideways force over the normal one (its magnitude), >= 0; held at
            ``largest_ratio`` beyond it.

        Returns
        -------
        value : float
            The largest mean principal strain magnitude per newton, times Young's modulus.
        d_radius : float
            Its derivative in the contact radius, per metre; 0 beyond the table's radii.
        d_square : float
            Its derivative in the squared ratio; 0 beyond ``largest_ratio`` (at it, the
            slope from inside: a pyramid's edge has that ratio, to rounding).
        """
        if not (np.isfinite(contact_radius) and np.isfinite(ratio)):
            raise FemError(f"contact_radius and ratio must be finite, got {contact_radius!r} and {ratio!r}")
        a = float(np.clip(contact_radius, self.smallest, self.largest))
        top = self.largest_ratio**2
        square = float(np.clip(ratio * ratio, 0.0, top))
        # The table's ends count as inside (to rounding): the slope there is the one from inside.
        inside_a = self.smallest * (1.0 - 1e-12) <= contact_radius <= self.largest * (1.0 + 1e-12)
        inside_s = ratio * ratio <= top * (1.0 + 1e-9)
        spline, (n_radii, n_squares) = self._spline, self._sizes
        if n_radii == 1 and n_squares == 1:
            return spline, 0.0, 0.0
        if n_radii == 1:
            return float(spline(square)), 0.0, float(spline(square, 1)) if inside_s else 0.0
        if n_squares == 1:
            return float(spline(a)), float(spline(a, 1)) if inside_a else 0.0, 0.0
        value = float(spline(a, square)[0, 0])
        d_a = float(spline(a, square, dx=1)[0, 0]) if inside_a else 0.0
        d_s = float(spline(a, square, dy=1)[0, 0]) if inside_s else 0.0
        return value, d_a, d_s


def _largest_means(thickness: float, poisson_ratio: float, averaging_radius: float, radii: np.ndarray,
                   ratios: np.ndarray) -> np.ndarray:
    """(len(radii), len(ratios)) :func:`largest_ball_mean` at each contact radius and
    sideways ratio, from the disk cache when it has them (:func:`fem.cache.default_cache`: a
    table takes seconds, and a planner meets it at its first stance)."""
    cache = default_cache()
    if cache is not None:
        digest = cache_digest({"radii": radii, "ratios": ratios},
                              {"kind": "layer ball strain", "thickness": float(thickness),
                               "poisson_ratio": float(poisson_ratio), "averaging_radius": float(averaging_radius),
                               "source": _source()})
        entry = cache.load(digest, "largest-means")
        if entry is not None and entry.get("values", np.zeros(0)).shape == (len(radii), len(ratios)):
            return entry["values"]
    values = np.zeros((len(radii), len(ratios)))
    for i, a in enumerate(radii):
        normal = axisymmetric_layer_field(a, thickness, poisson_ratio, averaging_radius)
        sideways = (axisymmetric_layer_field(a, thickness, poisson_ratio, averaging_radius, sideways=True)
                    if np.any(ratios > 0.0) else None)
        values[i] = _largest_means_at(normal, sideways, averaging_radius, a, ratios)
    if cache is not None:
        cache.store(digest, "largest-means", {"values": values})
    return values


@functools.lru_cache(maxsize=1)
def _source() -> str:
    """SHA-256 of this module's source: a cached table is this code's."""
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()
