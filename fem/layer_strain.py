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

Frictionless, one ball: a sideways force, another ball's far field and the body's own
weight are not in it (a mesh's field carries those).
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from scipy.interpolate import CubicSpline

from .cache import cache_digest, default_cache
from .errors import FemError
from .layer_contact import check_poisson_ratio, check_positive

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
# LayerBallStrain's table: contact radii between its ends.
_TABLE_POINTS = 7


@dataclass(frozen=True)
class AxisymmetricField:
    """A layer's displacement under a ball's pressure of 1 N, Young's modulus 1 Pa.

    Attributes
    ----------
    radii : (nr,) float
        Node distances from the axis, metres, ascending from 0.
    depths : (nz,) float
        Node depths below the surface, metres, ascending from 0 to the thickness.
    displacement : (nz, nr, 2) float
        Radial and vertical (up) displacement of each node, metres per (N / Pa).
    """

    radii: np.ndarray
    depths: np.ndarray
    displacement: np.ndarray

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
        """
        centres = np.asarray(centres, dtype=float).reshape(-1, 2)
        samples = self._samples()
        # Only the rings some ball reaches (near the axis: the layer is twenty thicknesses wide).
        reach = (samples[0] <= centres[:, 0].max() + radius) & (samples[1] <= centres[:, 1].max() + radius)
        r, z, e_rr, e_zz, e_tt, g_rz, weight = (values[reach] for values in samples)
        out = []
        for distance, depth in centres:
            # Each sample is a ring; the ball holds the arc |theta| <= theta_0 of it.
            left = radius * radius - (z - depth) ** 2
            if distance == 0.0:
                theta = np.where(r * r <= left, np.pi, 0.0)
            else:
                cosine = (r * r + distance * distance - left) / (2.0 * r * distance)
                theta = np.where(left > 0.0, np.arccos(np.clip(cosine, -1.0, 1.0)), 0.0)
            sc = np.sin(theta) * np.cos(theta)
            cos2, sin2, cos1 = theta + sc, theta - sc, 2.0 * np.sin(theta)
            # Sums, not BLAS dot products: a thread pool busy elsewhere made each of those 15 ms.
            volume = float(np.sum(weight * 2.0 * theta))
            if volume <= 0.0:
                raise FemError(f"a ball of radius {radius:g} m centred {depth:g} m deep holds no part of the layer")
            mean = np.zeros((3, 3))
            mean[0, 0] = np.sum(weight * (e_rr * cos2 + e_tt * sin2))
            mean[1, 1] = np.sum(weight * (e_rr * sin2 + e_tt * cos2))
            mean[2, 2] = np.sum(weight * e_zz * 2.0 * theta)
            mean[0, 2] = mean[2, 0] = np.sum(weight * 0.5 * g_rz * cos1)
            out.append(mean / volume)
        return np.array(out)

    def _samples(self):
        """Strains at sub-cell centres of every element and each sub-cell's ring weight per radian."""
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
        for xi in points:
            for eta in points:
                shape, d_xi, d_eta = _shape(xi, eta)
                r = r0[None, :] + (1.0 + xi) * hr + 0.0 * hz
                depth = d0[:, None] + (1.0 + eta) * hz + 0.0 * hr
                u_r, u_z = corners[..., 0], corners[..., 1]
                e_rr = (u_r @ d_xi) / hr
                e_tt = (u_r @ shape) / r
                # eta runs down (depth): d/dz = -d/d depth, z up.
                e_zz = -(u_z @ d_eta) / hz
                g_rz = -(u_r @ d_eta) / hz + (u_z @ d_xi) / hr
                weight = r * (hr * hz) * (4.0 / _SUB**2)
                samples.append((r, depth, e_rr, e_zz, e_tt, g_rz, weight))
        sampled = tuple(np.concatenate([s[k].ravel() for s in samples]) for k in range(7))
        object.__setattr__(self, "_sampled", sampled)
        return sampled


def _shape(xi: float, eta: float):
    """Bilinear shape functions of corners 00, 01, 11, 10 and their derivatives in xi and eta."""
    shape = 0.25 * np.array([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta), (1 + xi) * (1 + eta), (1 - xi) * (1 + eta)])
    d_xi = 0.25 * np.array([-(1 - eta), (1 - eta), (1 + eta), -(1 + eta)])
    d_eta = 0.25 * np.array([-(1 - xi), -(1 + xi), (1 + xi), (1 - xi)])
    return shape, d_xi, d_eta


def _graded(contact_radius: float, fine: float, cap: float, capped: float, total: float) -> np.ndarray:
    """Node coordinates from 0 to ``total``: ``fine`` apart under the contact (to 1.5 a), then
    growing by _GROWTH, at most ``cap`` apart up to ``capped``."""
    nodes = list(np.arange(0.0, 1.5 * contact_radius + 1e-15 * total, fine))
    step = fine
    while nodes[-1] < total * (1.0 - 1e-12):
        step *= _GROWTH
        if nodes[-1] < capped:
            step = min(step, cap)
        nodes.append(min(nodes[-1] + step, total))
    return np.array(nodes)


def axisymmetric_layer_field(contact_radius: float, thickness: float, poisson_ratio: float,
                             averaging_radius: float) -> AxisymmetricField:
    """The layer's field under a ball's Hertzian pressure of 1 N, Young's modulus 1 Pa.

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
    shear_part = np.diag([2.0 * shear, 2.0 * shear, 2.0 * shear, shear])
    lame_part = np.zeros((4, 4))
    lame_part[:3, :3] = lame
    corners = np.stack([node[:-1, :-1], node[:-1, 1:], node[1:, 1:], node[1:, :-1]], axis=2).reshape(-1, 4)
    hr = np.broadcast_to(0.5 * np.diff(radii)[None, :], (nz - 1, nr - 1)).ravel()
    hz = np.broadcast_to(0.5 * np.diff(depths)[:, None], (nz - 1, nr - 1)).ravel()
    r0 = np.broadcast_to(radii[None, :-1], (nz - 1, nr - 1)).ravel()
    stiffness = np.zeros((len(corners), 8, 8))
    gauss = np.array([-1.0, 1.0]) / np.sqrt(3.0)
    rule = [(xi, eta, 1.0, shear_part) for xi in gauss for eta in gauss] + [(0.0, 0.0, 4.0, lame_part)]
    for xi, eta, weight, elasticity in rule:
        shape, d_xi, d_eta = _shape(xi, eta)
        r = r0 + (1.0 + xi) * hr
        b = np.zeros((len(corners), 4, 8))
        b[:, 0, 0::2] = d_xi[None] / hr[:, None]
        b[:, 1, 1::2] = -d_eta[None] / hz[:, None]
        b[:, 2, 0::2] = shape[None] / r[:, None]
        b[:, 3, 0::2] = -d_eta[None] / hz[:, None]
        b[:, 3, 1::2] = d_xi[None] / hr[:, None]
        stiffness += (b.transpose(0, 2, 1) @ elasticity @ b) * (weight * 2.0 * np.pi * r * hr * hz)[:, None, None]
    dofs = np.stack([2 * corners, 2 * corners + 1], axis=2).reshape(-1, 8)
    size = 2 * nr * nz
    matrix = scipy.sparse.csr_matrix(
        (stiffness.ravel(), (np.repeat(dofs, 8, axis=1).ravel(), np.tile(dofs, (1, 8)).ravel())), shape=(size, size))
    load = np.zeros(size)
    # The pressure's consistent loads on the surface's edges, Gauss-Legendre on each (its
    # square-root edge is where the contact's last edge ends).
    points, weights = np.polynomial.legendre.leggauss(12)
    pressure_peak = 3.0 / (2.0 * np.pi * a * a)
    for i in range(nr - 1):
        start, stop = radii[i], radii[i + 1]
        if start >= a:
            break
        end = min(stop, a)
        s = start + 0.5 * (points + 1.0) * (end - start)
        w = 0.5 * weights * (end - start) * pressure_peak * np.sqrt(np.maximum(1.0 - (s / a) ** 2, 0.0)) * 2.0 * np.pi * s
        load[2 * node[0, i] + 1] -= w @ ((stop - s) / (stop - start))
        load[2 * node[0, i + 1] + 1] -= w @ ((s - start) / (stop - start))
    fixed = np.zeros(size, dtype=bool)
    fixed[2 * node[-1]] = fixed[2 * node[-1] + 1] = True  # the bonded base
    fixed[2 * node[:, 0]] = True  # the axis: no radial displacement
    free = np.flatnonzero(~fixed)
    displacement = np.zeros(size)
    displacement[free] = scipy.sparse.linalg.spsolve(matrix[free][:, free].tocsc(), load[free])
    return AxisymmetricField(radii, depths, displacement.reshape(nz, nr, 2))


def largest_ball_mean(field: AxisymmetricField, radius: float, contact_radius: float) -> float:
    """The largest principal strain magnitude of the field's ball means of ``radius``, per
    newton and pascal, over centres anywhere in the layer out to ``contact_radius + radius``
    from the axis.

    A grid of centres over the layer's depth (its base included: on a layer thinner than the
    ball, the strain gathers where the base holds it) is searched, then finer grids around the
    best. A ball smaller than two of the finest cells takes the pointwise strains' largest
    instead: no mean's magnitude exceeds it (the magnitude is a norm, and convex), and cells
    that small are the field's own resolution.
    """
    cell = min(float(np.diff(field.radii)[0]), float(np.diff(field.depths)[0]))
    if radius < 2.0 * cell:
        _, _, e_rr, e_zz, e_tt, g_rz, _ = field._samples()
        centre, half = 0.5 * (e_rr + e_zz), np.hypot(0.5 * (e_rr - e_zz), 0.5 * g_rz)
        return float(np.max(np.maximum.reduce([np.abs(e_tt), np.abs(centre + half), np.abs(centre - half)])))
    thickness = float(field.depths[-1])
    reach = contact_radius + radius
    xs, zs = np.linspace(0.0, reach, _SEARCH_GRID[0]), np.linspace(0.0, thickness, _SEARCH_GRID[1])
    best, (x, z) = -1.0, (0.0, 0.0)
    for _ in range(_SEARCH_REFINEMENTS + 1):
        centres = np.array([(u, v) for u in xs for v in zs])
        eigenvalues = np.linalg.eigvalsh(field.ball_means(radius, centres))
        magnitudes = np.maximum(eigenvalues[:, -1], -eigenvalues[:, 0])
        k = int(np.argmax(magnitudes))
        if magnitudes[k] > best:
            best, (x, z) = float(magnitudes[k]), centres[k]
        # A grid half as wide around the best, within the layer and the reach.
        dx, dz = xs[1] - xs[0] if len(xs) > 1 else 0.0, zs[1] - zs[0] if len(zs) > 1 else 0.0
        xs = np.unique(np.clip(x + np.linspace(-dx, dx, 5), 0.0, reach))
        zs = np.unique(np.clip(z + np.linspace(-dz, dz, 5), 0.0, thickness))
    return best


@dataclass(frozen=True)
class LayerBallStrain:
    """The largest mean strain a ball leaves in a layer, per newton, as a function of its
    contact radius: ``strain = F * per_force(a) / E``, tabulated.

    The table holds :func:`largest_ball_mean` of :func:`axisymmetric_layer_field` at contact
    radii cosine-spaced from ``smallest`` to ``largest``; a cubic spline interpolates it
    (within 0.3 % of a fresh field between its points, the tests), held at its ends beyond them.

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
    """

    thickness: float
    poisson_ratio: float
    averaging_radius: float
    smallest: float
    largest: float
    _spline: object = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.smallest) and 0.0 < self.smallest <= self.largest and np.isfinite(self.largest)):
            raise FemError(f"the contact radii must satisfy 0 < smallest <= largest, got {self.smallest!r} and "
                           f"{self.largest!r}")
        # Cosine-spaced: the means fall fastest as the contact nears the table's widest.
        shares = 0.5 * (1.0 - np.cos(np.linspace(0.0, np.pi, _TABLE_POINTS)))
        radii = np.unique(self.smallest + shares * (self.largest - self.smallest))
        values = _largest_means(self.thickness, self.poisson_ratio, self.averaging_radius, radii)
        spline = CubicSpline(radii, values) if len(radii) > 1 else float(values[0])
        object.__setattr__(self, "_spline", spline)

    def per_force(self, contact_radius: float) -> tuple[float, float]:
        """The largest mean principal strain magnitude per newton (times Young's modulus in
        pascals), and its derivative in the contact radius (per metre).

        Parameters
        ----------
        contact_radius : float
            Metres.

        Returns
        -------
        (float, float)
        """
        if not isinstance(self._spline, CubicSpline):
            return self._spline, 0.0
        a = float(np.clip(contact_radius, self.smallest, self.largest))
        value = float(self._spline(a))
        if not self.smallest < contact_radius < self.largest:
            return value, 0.0
        return value, float(self._spline(a, 1))


def _largest_means(thickness: float, poisson_ratio: float, averaging_radius: float, radii: np.ndarray) -> np.ndarray:
    """:func:`largest_ball_mean` at each contact radius, from the disk cache when it has them
    (:func:`fem.cache.default_cache`: a table takes seconds, and a planner meets it at its first stance)."""
    cache = default_cache()
    if cache is not None:
        digest = cache_digest({"radii": radii}, {"kind": "layer ball strain", "thickness": float(thickness),
                                                 "poisson_ratio": float(poisson_ratio),
                                                 "averaging_radius": float(averaging_radius), "source": _source()})
        entry = cache.load(digest, "largest-means")
        if entry is not None and entry.get("values", np.zeros(0)).shape == radii.shape:
            return entry["values"]
    values = np.array([largest_ball_mean(axisymmetric_layer_field(a, thickness, poisson_ratio, averaging_radius),
                                         averaging_radius, a) for a in radii])
    if cache is not None:
        cache.store(digest, "largest-means", {"values": values})
    return values


@functools.lru_cache(maxsize=1)
def _source() -> str:
    """SHA-256 of this module's source: a cached table is this code's."""
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()
