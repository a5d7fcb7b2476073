"""A rigid sphere pressed into an elastic layer bonded to a rigid base: the continuum's force.

What a mesh cannot give when the contact is smaller than its cells (a ball foot 1-2.5 mm
deep in foam meshed at 10 mm touches one node), the continuum gives in closed form up to
one quadrature: the sphere's own contact on a half-space (Segedin's exact-profile
solution, Hertz's as the ball sinks little) and the layer's far field, the compliance of a
layer of thickness t bonded to a rigid base less a half-space's, for the contact's
Hertzian pressure. The contact radius a solves

    d = delta_0(a) + F_0(a) (dc(a) + a dc'(a) / 6)

(first order in the far field; the a dc'/6 term from the contact's complementary energy),
and the force is F_0(a). Frictionless; friction 0.7 adds 0.2-0.8 % at these depths. Against
a ring-discretised continuum solution of the same layer it agrees to 0.1 % (41.76 N at 2.5 mm
and 9.88 N at 1 mm for ANYmal's 31 mm ball in 50 mm of foam at E = 1e6 Pa, nu = 0.4), and the
library's FEM with node contact converges to it (``docs/ball-subgrid.md``).

The first-order far field holds while the contact is small beside the thickness, and errs
low beyond: against an exact continuum solution of the same layer (a review's own ring
solver, 2026-12-04), -0.2 % at a = 0.5 t, -0.5 % at 0.6 t (-1.0 % for nu = 0.49), -3 % at 0.9 t,
-8 % at 1.2 t, -21 % at 1.8 t. :data:`VALID_CONTACT_SHARE` is the bound verify reads it within.
The formula's layer is laterally infinite. A free side face at distance L from the ball
softens a box: an independent FEM (``bench/results/audit-thick-boxes-2026-12-05.md``: its own
hexahedra refined everywhere, exact-sphere Signorini contact, within 0.02 % of this law on a
5 cm mat; boxes 0.05, 0.15 and 0.3 m thick) found each face lowering the force by about
``SIDE_DROP a t / L^2`` (a = sqrt(R d)), and the law times :func:`side_factor`, the product of
those drops' complements over the four side faces, within 0.6 % of all its 20 one-face and
centre cases (the 0.3 m cube's centre -1.0 % at 2.5 mm, a corner +1.4 %) from L = 5.7 a and
L = t / 6. Another (``bench/results/audit-near-sides-2026-12-05.md``, one side and corners
at L = 0.17-0.6 t of a 5 cm mat and a 12 cm block, 1-4 mm deep) put it within 0.8 % from a
quarter of the thickness and 2.8 contact radii (a corner's -0.8 %), off by up to 1.5 % (2.2 %
in a corner) at 1.8 radii, and low by 2.4-9.9 % nearer than a quarter of the thickness at
1.1-3.6 radii (the true drop levels off there while ``a t / L^2`` grows):
:func:`side_contact_limit` keeps a ball within those ranges. Past half a thickness the true
drop decays faster than the formula's, which then takes up to 0.7 point too much (a force
low, a sinking deep): 1.32 against 0.66 % one thickness from a 5 cm mat's side at 2.5 mm.
Tested for t <= 0.3 m (t / a <= 54) only: the formula cannot hold as t grows without bound
(the quarter-space limit). A support that is not a box on a held base is outside it
(the posture solver reads a convex top face's edges over a held base as free sides only
where their drop is small, a bound on what a bevel or an attached block could move).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from .errors import FemError

__all__ = ["VALID_CONTACT_SHARE", "SIDE_DROP", "SIDE_REACH", "NEAR_SIDE_REACH", "NEAR_SIDE_SHARE", "NEAREST_SIDE_SHARE",
           "BallOnLayer", "widest_contact", "side_reach", "side_contact_limit", "check_positive", "check_poisson_ratio",
           "sphere_on_half_space", "layer_correction", "side_factor", "side_softening", "sphere_on_layer_force"]

#: Contact radius over thickness up to which the first-order far field is within 0.5 % of the
#: continuum (nu = 0.4; 1 % at nu = 0.49), always low (module docstring).
VALID_CONTACT_SHARE = 0.6

#: A free side face at distance L lowers a ball's force by about ``SIDE_DROP sqrt(R d) t / L^2``
#: (module docstring): 2.2 / 3.5 % by the formula against 2.2 / 3.4 % by the audit's FEM 0.075 m
#: from the side of a 0.3 m cube, 1 / 2.5 mm deep.
SIDE_DROP = 0.075

#: Contact radii a side face stands away at least for :func:`side_factor` once it is
#: :data:`NEAR_SIDE_SHARE` of the thickness away or more (an audit of 2026-12-05, its own FEM
#: of one side and corners at L = 0.17-0.6 t on a 5 cm mat and a 12 cm block,
#: ``bench/results/audit-near-sides-2026-12-05.md``: within 0.8 % of its converged forces there,
#: 1.5 % at 1.8 contact radii, -3.8 % at 1.1): a ball's table ends at the contact radius its
#: sides allow (:func:`side_contact_limit`), and :func:`sphere_on_layer_force` refuses a deeper
#: ball.
SIDE_REACH = 2.8

#: Contact radii a side face nearer than :data:`NEAR_SIDE_SHARE` of the thickness stands away
#: at least: the thick-box audit's nearest at L = t / 6 (within 0.6 %); the near-side audit
#: found -2.4 % at 3.6 contact radii t / 6 from a 12 cm block's side, -3.5 % at 1.8 t / 5 from a
#: 5 cm mat's.
NEAR_SIDE_REACH = 5.6

#: Share of the thickness from which a side face needs only :data:`SIDE_REACH` contact radii.
NEAR_SIDE_SHARE = 0.25

#: Share of the thickness a side face stands away at least for :func:`side_factor`: the
#: audit's nearest, t / L = 6 (nearer, a box's side is no longer a small change of a layer).
NEAREST_SIDE_SHARE = 1.0 / 6.0

# Contact radii the force's search spans, in thicknesses: past 3 the formula is 40 % low and
# more, and a search over a thin layer's whole sphere radius built quadratures of thousands of
# panels (a 0.1 mm layer under a 31 mm ball).
_SEARCHED_SHARE = 3.0

# Gauss-Legendre panels on x = xi t in [0, _X_MAX]: the layer's kernel K(x) - 1 falls as
# exp(-2 x), 1e-13 of its value at 0 by x = 18 and no more read past _X_MAX. One panel of 64
# nodes gives the correction to 1e-11 while the contact radius is at most twice the
# thickness (256 nodes agree); wider contacts, whose pressure transform oscillates faster in
# x, take one more panel per two thicknesses.
_X_MAX = 24.0
_NODES = 64

# BallOnLayer's table: contact radii on a cosine grid (dense where the contact is small and
# the force grows fastest), and the share of the sphere's radius it stops at (the exact
# profile's approach grows without bound as a -> R; indentation bounds stop far before).
_TABLE_POINTS = 65
_TABLE_RADIUS_SHARE = 0.7


def check_positive(**values) -> None:
    """Raise :class:`FemError` naming the first of ``values`` (name=value) not finite and > 0."""
    for name, value in values.items():
        if not (np.isfinite(value) and value > 0.0):
            raise FemError(f"{name} must be finite and > 0, got {value!r}")


def check_poisson_ratio(poisson_ratio: float) -> None:
    """Raise :class:`FemError` unless ``poisson_ratio`` lies in [0, 0.5)."""
    if not 0.0 <= poisson_ratio < 0.5:
        raise FemError(f"poisson_ratio must lie in [0, 0.5), got {poisson_ratio!r}")


def sphere_on_half_space(a, radius: float, effective_modulus: float):
    """A rigid sphere's approach and force on an elastic half-space at contact radius ``a``.

    Segedin's solution for the sphere's exact profile: ``delta = a/2 L``,
    ``F = E*/2 ((a^2 + R^2) L - 2 a R)`` with ``L = ln((R + a)/(R - a))``; Hertz's
    ``a^2 / R`` and ``4 E* a^3 / (3 R)`` as a / R -> 0.

    Parameters
    ----------
    a : float or array
        Contact radius, metres, 0 <= a < radius.
    radius : float
        Sphere radius R, metres.
    effective_modulus : float
        ``E* = E / (1 - nu^2)``, pascals.

    Returns
    -------
    delta, force : float or array
        Metres and newtons.
    """
    a = np.asarray(a, dtype=float)
    log = np.log((radius + a) / (radius - a))
    return 0.5 * a * log, 0.5 * effective_modulus * ((a * a + radius * radius) * log - 2.0 * a * radius)


def _approach(a: float, radius: float, thickness: float, effective_modulus: float, poisson_ratio: float):
    """The sphere's approach (metres) and force (newtons) at contact radius ``a`` on the
    layer: ``d = delta_0 + F_0 (dc + a dc' / 6)``, ``F = F_0`` (module docstring)."""
    delta, force = sphere_on_half_space(a, radius, effective_modulus)
    correction, slope = _correction(a, thickness, effective_modulus, poisson_ratio)
    return float(delta + force * (correction + a * slope / 6.0)), float(force)


def _kernel(x, poisson_ratio: float):
    """The layer-on-rigid-base kernel K(x), x = xi t: the ratio of the layer's surface
    displacement under a harmonic pressure of wavenumber xi to a half-space's (-> 1 as x
    grows, ~ x (1 - 2 nu) / (2 (1 - nu)^2) as x -> 0)."""
    kappa = 3.0 - 4.0 * poisson_ratio
    x = np.asarray(x, dtype=float)
    out = np.ones_like(x)
    small = x < 18.0  # past it K - 1 is under 1e-13 (and cosh would overflow far out)
    xs = x[small]
    out[small] = (2.0 * kappa * np.sinh(2.0 * xs) - 4.0 * xs) / (
        2.0 * kappa * np.cosh(2.0 * xs) + 1.0 + kappa * kappa + 4.0 * xs * xs
    )
    return out


@functools.lru_cache(maxsize=16)
def _rule(poisson_ratio: float, panels: int):
    """Quadrature nodes x (n,) and weights times K(x) - 1 (n,) on [0, _X_MAX]: ``panels``
    equal panels of :data:`_NODES` Gauss-Legendre nodes each."""
    x, w = np.polynomial.legendre.leggauss(_NODES)
    width = _X_MAX / panels
    starts = width * np.arange(panels)
    x = (starts[:, None] + 0.5 * width * (x + 1.0)).ravel()
    w = np.tile(0.5 * width * w, panels)
    return x, w * (_kernel(x, poisson_ratio) - 1.0)


def _pressure_transform(s):
    """2 pi times the Hankel transform of a unit-force Hertzian pressure of radius a, at
    s = xi a, and its derivative in s: ``3 (sin s - s cos s) / s^3`` (1 at s = 0)."""
    s = np.asarray(s, dtype=float)
    value, slope = np.empty_like(s), np.empty_like(s)
    # Below 0.05 the closed forms lose digits to cancellation (the slope 0.3 % at 1e-3):
    # their series there, 1 - s^2/10 + s^4/280 - s^6/15120, to 1e-16.
    big = s > 0.05
    sb = s[big]
    sine, cosine = np.sin(sb), np.cos(sb)
    value[big] = 3.0 * (sine - sb * cosine) / sb**3
    slope[big] = 3.0 * sine / sb**2 - 9.0 * (sine - sb * cosine) / sb**4
    small = s[~big]
    value[~big] = 1.0 - 0.1 * small**2 + small**4 / 280.0 - small**6 / 15120.0
    slope[~big] = -0.2 * small + small**3 / 70.0 - small**5 / 2520.0
    return value, slope


def _correction(a: float, thickness: float, effective_modulus: float, poisson_ratio: float):
    """:func:`layer_correction` at one contact radius, and its derivative in it (m/N, N^-1)."""
    ratio = a / thickness
    x, weights = _rule(float(poisson_ratio), max(1, int(np.ceil(ratio / 2.0))))
    value, slope = _pressure_transform(ratio * x)
    scale = np.pi * effective_modulus * thickness
    return float(value**2 @ weights) / scale, float((2.0 * value * slope * x) @ weights) / (scale * thickness)


def layer_correction(a, thickness: float, effective_modulus: float, poisson_ratio: float):
    """The layer's far field: its compliance less a half-space's for a unit-force
    Hertzian pressure of radius ``a``, weighted by that pressure, m/N (negative: the
    layer is stiffer).

    ``dc = 1 / (pi E* t) int_0^inf Pbar(x a / t)^2 (K(x) - 1) dx``, ``Pbar`` the pressure's
    transform (:func:`_pressure_transform`); by a Gauss-Legendre rule.

    Parameters
    ----------
    a : float or array
        Contact radius, metres.
    thickness : float
        Layer thickness t, metres.
    effective_modulus : float
        ``E*``, pascals.
    poisson_ratio : float

    Returns
    -------
    float or array
        m/N.
    """
    values = [_correction(float(r), thickness, effective_modulus, poisson_ratio)[0] for r in np.ravel(a)]
    return np.reshape(values, np.shape(a)) if np.ndim(a) else values[0]


def widest_contact(radius: float, thickness: float) -> float:
    """Metres: the widest contact radius a ball's law is read for on a laterally infinite
    layer, :data:`VALID_CONTACT_SHARE` of the thickness or 0.7 of the ball's radius (the exact
    profile's approach grows without bound as the contact nears the ball's radius)."""
    return min(VALID_CONTACT_SHARE * thickness, _TABLE_RADIUS_SHARE * radius)


def side_reach(distance: float, thickness: float) -> float:
    """Contact radii a side face ``distance`` metres away must stand from a ball's contact for
    :func:`side_factor`: :data:`SIDE_REACH`, or :data:`NEAR_SIDE_REACH` nearer than
    :data:`NEAR_SIDE_SHARE` of the layer's ``thickness``."""
    return SIDE_REACH if distance >= NEAR_SIDE_SHARE * thickness else NEAR_SIDE_REACH


def side_contact_limit(thickness: float, side_distances=()) -> float:
    """The widest contact radius :func:`side_factor` holds for beside these sides.

    Parameters
    ----------
    thickness : float
        The layer's, metres.
    side_distances : sequence of float
        Metres from the print's centre to each free side face.

    Returns
    -------
    float
        Metres: the least of each side's distance over its :func:`side_reach` (the nearest
        side's; infinite with no side). Measured for one side; a corner within it was +1.0 to
        +1.4 % off in the thick-box audit (module docstring).
    """
    return min((d / side_reach(d, thickness) for d in side_distances), default=np.inf)


def check_side_distances(side_distances, thickness: float) -> tuple:
    """``side_distances`` as a tuple of floats; :class:`FemError` naming a distance that is not
    finite or is under :data:`NEAREST_SIDE_SHARE` of ``thickness``."""
    distances = tuple(float(d) for d in np.ravel(np.asarray(side_distances, dtype=float)))
    for distance in distances:
        if not (np.isfinite(distance) and distance >= (NEAREST_SIDE_SHARE - 1e-9) * thickness):
            raise FemError(f"a side face {distance!r} m from the ball is nearer than a sixth of the layer's thickness "
                           f"({NEAREST_SIDE_SHARE * thickness:g} m), where the side correction was not tested: "
                           "contact there needs the mesh (node contact)")
    return distances


def side_factor(depth, radius: float, thickness: float, side_distances=()):
    """How much a box's free side faces lower a ball's force on its layer at a depth:
    ``prod_i (1 - SIDE_DROP sqrt(R d) t / L_i^2)`` (module docstring).

    Parameters
    ----------
    depth : float or array
        The ball's sinking, metres, >= 0.
    radius, thickness : float
        The ball's radius R and the layer's thickness t, metres.
    side_distances : sequence of float
        Metres from the print's centre to each free side face (none: a laterally infinite layer).

    Returns
    -------
    float or array
        1 at no depth or with no side, less as the ball sinks; above 0.7 while the contact
        is within :func:`side_contact_limit` and every side at least
        :data:`NEAREST_SIDE_SHARE` of the thickness away (the formula's range: past it the
        factor falls on, to 0 and below).
    """
    return side_softening(np.sqrt(radius * np.asarray(depth, dtype=float)), thickness, side_distances)[0]


def side_softening(contact_radius, thickness: float, side_distances=()):
    """:func:`side_factor` as a function of the contact's radius ``a`` (``sqrt(R d)``), and its
    derivative in it: ``prod_i (1 - SIDE_DROP a t / L_i^2)``.

    Parameters
    ----------
    contact_radius : float or array
        Metres, >= 0.
    thickness : float
        The layer's, metres.
    side_distances : sequence of float
        Metres from the print's centre to each free side face.

    Returns
    -------
    factor, slope : float or array
        The factor (1 with no side, less as the contact widens; in its range, above 0.7:
        :func:`side_factor`) and its derivative in the contact radius, per metre.
    """
    a = np.asarray(contact_radius, dtype=float)
    factor, slope = np.ones_like(a), np.zeros_like(a)
    for distance in side_distances:
        rate = SIDE_DROP * thickness / (distance * distance)
        # (f g)' = f' g + f g' over the faces, one at a time.
        slope = slope * (1.0 - rate * a) - factor * rate
        factor = factor * (1.0 - rate * a)
    if np.ndim(factor):
        return factor, slope
    return float(factor), float(slope)


def sphere_on_layer_force(depth: float, radius: float, thickness: float, young_modulus: float, poisson_ratio: float,
                          side_distances=()):
    """The force a rigid sphere pressed ``depth`` into an elastic layer needs, and its
    contact radius (the continuum's, frictionless; module docstring).

    Parameters
    ----------
    depth : float
        The sphere's sinking below the layer's surface at rest, metres, >= 0.
    radius, thickness : float
        Metres, > 0.
    young_modulus : float
        Pascals, > 0.
    poisson_ratio : float
        In [0, 0.5).
    side_distances : sequence of float, optional
        Metres from the print's centre to each free side face of a box, each at least
        :data:`NEAREST_SIDE_SHARE` of the thickness: the force is the layer's times
        :func:`side_factor` (none: a laterally infinite layer).

    Returns
    -------
    force, contact_radius : float
        Newtons and metres (0 and 0 at depth 0). Within 0.5 % of the continuum while the
        contact radius is at most :data:`VALID_CONTACT_SHARE` of the thickness, low and
        falling further below it past that (module docstring): read it there only; with
        sides, within 0.8 % of two audits' FEM beside one side while the contact is within
        :func:`side_contact_limit` (a corner +1.0 to +1.4 %). The contact radius is the layer's.

    Raises
    ------
    FemError
        On a bad argument; a depth of the sphere's radius or the layer's thickness or more;
        a contact wider than three thicknesses, where the formula is 40 % low or worse; with
        sides, a contact (``sqrt(R d)``) wider than :func:`side_contact_limit`.
    """
    check_positive(radius=radius, thickness=thickness, young_modulus=young_modulus)
    if not (np.isfinite(depth) and depth >= 0.0):
        raise FemError(f"depth must be finite and >= 0 metres, got {depth!r}")
    check_poisson_ratio(poisson_ratio)
    side_distances = check_side_distances(side_distances, thickness)
    if np.sqrt(radius * depth) > side_contact_limit(thickness, side_distances):
        nearest = min(side_distances)
        raise FemError(f"a ball {depth:g} m deep (contact radius about {np.sqrt(radius * depth):.3g} m) is within "
                       f"{side_reach(nearest, thickness):g} contact radii of a side face {nearest:g} m away: the "
                       "side correction does not hold there")
    if depth >= min(radius, thickness):
        raise FemError(f"a sphere of radius {radius:g} m cannot be pressed {depth:g} m into a layer {thickness:g} m "
                       "thick: that is its radius or the layer's thickness or more")
    if depth == 0.0:
        return 0.0, 0.0
    modulus = young_modulus / (1.0 - poisson_ratio**2)

    def residual(a):
        return _approach(a, radius, thickness, modulus, poisson_ratio)[0] - depth

    low, high = 1e-9 * radius, min((1.0 - 1e-9) * radius, _SEARCHED_SHARE * thickness)
    if not residual(high) > 0.0:
        raise FemError(f"a sphere of radius {radius:g} m pressed {depth:g} m into a layer {thickness:g} m thick "
                       f"touches it over more than {_SEARCHED_SHARE:g} thicknesses, beyond the formula")
    a = brentq(residual, low, high, xtol=1e-15, rtol=1e-13)
    force = float(sphere_on_half_space(a, radius, modulus)[1])
    return force * side_factor(depth, radius, thickness, side_distances), float(a)


@dataclass(frozen=True)
class BallOnLayer:
    """A rigid ball's sinking into an elastic layer as a function of its force, tabulated
    for a posture solver: :func:`sphere_on_layer_force`'s law inverted, smooth, with its
    derivative, in microseconds.

    The law is parametric in the contact radius a (``depth(a)``, ``F(a)``, module
    docstring): on a grid of a it is exact, and between the grid's points a cubic spline
    interpolates ``H(v) = depth / F^(2/3)`` in ``v = F^(1/3)``, smooth and finite at 0 where
    Hertz's ``depth = (3 F / (4 E* sqrt(R)))^(2/3)`` holds (the sides' factor, 1 - O(v) there,
    keeps it so). The table ends at the contact radius :data:`VALID_CONTACT_SHARE` of the
    thickness, 0.7 of the ball's radius or the sides' :func:`side_contact_limit`, whichever is
    smallest: :attr:`force_limit`; past it the sinking goes
    on along the last slope, a smooth extension for a solver's trial steps, not the law
    (bound the force there).

    Parameters
    ----------
    radius, thickness : float
        The ball's radius and the layer's thickness, metres, > 0.
    young_modulus : float
        Pascals, > 0.
    poisson_ratio : float
        In [0, 0.5).
    side_distances : tuple of float, optional
        Metres from the print's centre to each free side face of a box, each at least
        :data:`NEAREST_SIDE_SHARE` of the thickness (:func:`side_factor`); none: a laterally
        infinite layer.

    Examples
    --------
    >>> law = BallOnLayer(0.031, 0.05, 1e6, 0.4)
    >>> print(f"{law.sinking(41.76)[0] * 1e3:.3f} mm")  # the continuum's 41.76 N at 2.5 mm
    2.500 mm
    """

    radius: float
    thickness: float
    young_modulus: float
    poisson_ratio: float
    side_distances: tuple = ()
    _table: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        check_positive(radius=self.radius, thickness=self.thickness, young_modulus=self.young_modulus)
        check_poisson_ratio(self.poisson_ratio)
        sides = check_side_distances(self.side_distances, self.thickness)
        object.__setattr__(self, "side_distances", sides)
        modulus = self.young_modulus / (1.0 - self.poisson_ratio**2)
        largest = min(widest_contact(self.radius, self.thickness), side_contact_limit(self.thickness, sides))
        radii = largest * 0.5 * (1.0 - np.cos(np.linspace(0.0, np.pi, _TABLE_POINTS)))[1:]
        law = np.array([_approach(a, self.radius, self.thickness, modulus, self.poisson_ratio) for a in radii])
        depths = law[:, 0]
        forces = law[:, 1] * side_factor(depths, self.radius, self.thickness, sides)
        if not (np.all(np.diff(depths) > 0.0) and np.all(np.diff(forces) > 0.0)):
            raise FemError(f"a ball of radius {self.radius:g} m on a layer {self.thickness:g} m thick: its law is "
                           "not monotone on the table's contact radii; the formula does not hold there")
        v = np.concatenate([[0.0], np.cbrt(forces)])
        hertz = (3.0 / (4.0 * modulus * np.sqrt(self.radius))) ** (2.0 / 3.0)
        h = np.concatenate([[hertz], depths / forces ** (2.0 / 3.0)])
        # The contact radius for a field's pressure: a / F^(1/3), Hertz's (3 R / (4 E*))^(1/3) at 0.
        r = np.concatenate([[(3.0 * self.radius / (4.0 * modulus)) ** (1.0 / 3.0)], radii / v[1:]])
        object.__setattr__(self, "_table", (CubicSpline(v, h), CubicSpline(v, r), float(forces[-1]), float(depths[-1]),
                                            float(largest)))

    @property
    def force_limit(self) -> float:
        """Newtons: the largest force the law is read for (the table's end)."""
        return self._table[2]

    @property
    def depth_limit(self) -> float:
        """Metres: the sinking at :attr:`force_limit`."""
        return self._table[3]

    @property
    def largest_contact_radius(self) -> float:
        """Metres: the contact radius at :attr:`force_limit`, the widest the law is read for."""
        return self._table[4]

    def sinking(self, force: float) -> tuple[float, float]:
        """The ball's sinking under a normal force, and its derivative.

        Parameters
        ----------
        force : float
            Newtons; 0 and below sink nothing.

        Returns
        -------
        depth : float
            Metres below the layer's surface at rest.
        slope : float
            d depth / d force, m/N; infinite at 0 (Hertz: depth ~ F^(2/3)), so a caller's
            Jacobian should hold the force above 0.
        """
        spline, _, limit, depth_at_limit, _ = self._table
        if force <= 0.0:
            return 0.0, np.inf
        if force > limit:
            _, slope = self.sinking(limit)
            return float(depth_at_limit + slope * (force - limit)), slope
        v = float(np.cbrt(force))
        h, dh = float(spline(v)), float(spline(v, 1))
        # depth = h(v) v^2, dv/dF = 1 / (3 v^2)
        return h * v * v, dh / 3.0 + 2.0 * h / (3.0 * v)

    def contact_radius(self, force: float) -> float:
        """Metres: the contact's radius under ``force`` newtons (0 at 0; the table's last
        beyond :attr:`force_limit`)."""
        return self.contact_radius_and_slope(force)[0]

    def contact_radius_and_slope(self, force: float) -> tuple[float, float]:
        """The contact's radius under ``force`` (metres) and its derivative in the force
        (m/N; 0 beyond :attr:`force_limit`, infinite at 0: Hertz's a ~ F^(1/3))."""
        if force <= 0.0:
            return 0.0, np.inf
        v = float(np.cbrt(min(force, self._table[2])))
        spline = self._table[1]
        radius, slope = float(spline(v)), float(spline(v, 1))
        # a = r(v) v, dv/dF = 1 / (3 v^2)
        return radius * v, (0.0 if force > self._table[2] else (slope * v + radius) / (3.0 * v * v))
