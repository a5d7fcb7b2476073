"""Ball feet on a soft layer: each ball sinks by the continuum's law under its own force.

A ball foot (radius R, a few millimetres deep) presses a contact smaller than a soft
mat's cells: the mesh's nodes under it give a force that moves by tens of percent with
where the ball stands against them (``docs/ball-subgrid.md``). Where the body is a layer held
on its base (a box, or a convex top face over nothing but the base: :func:`layer_under`), the
ball on the opposite face inside its sides by a sixth of the thickness, 1.5
strain radii and so far that no side cuts the law short of the load the body's strain bound
allows (:func:`layer_site`: 32 mm on quadruped-foam's mat for ANYmal's ball), the continuum
gives the force instead: :class:`fem.BallOnLayer`, a rigid sphere on an elastic layer bonded
to a rigid base (within 0.5 % of an exact solution while the contact's radius is at most 0.6
of the thickness), times the softening of the box's free side faces
(:func:`fem.layer_contact.side_factor`: within 0.8 % of three independent FEMs of mats, a
block, a wide 0.15 m box and a 0.3 m cube beside one side, the cube's centre -1.0 %, a corner
+1.4 %). Each ball is then a point contact (:class:`stances.contacts.PointContact`) whose
normal placement gives way by the layer's sinking under its normal force, the compliance form
of contact:

    R_p^T (c - o_p) - (0, 0, r) + (0, 0, delta(f_n)) = 0,    f_n = n . f

(as E grows, delta -> 0: the rigid point contact). Its force is a friction pyramid's, as on
a rigid support; the pyramid lies inside the Coulomb cone, and so does every node's load
(below). The force is bounded where the law stops holding: the contact's radius at 0.6 of
the thickness (0.7 of the ball's radius, what its sides allow:
:func:`fem.layer_contact.side_contact_limit`) and the sinking at the indentation bound.

The body's field (the pictures, the files, the strain bound) is the mesh's under the
ball's Hertzian pressure, as consistent nodal loads (:func:`fem.hertz_load_shares`): each
node carries a share of the ball's force, so each node's load is in its cone when the
force is. A mesh as coarse as the contact strains too little under a ball (10 mm cells:
2.19 % for a 20 mm mean where the converged field gives 2.60 %), so each ball's strain is
also bounded on the layer's own field under it, converged
(:class:`fem.LayerBallStrain`: an axisymmetric FEM of the layer under the ball's normal
force and its first harmonic under the sideways one, its largest mean, divided by the sides'
softening near a box's side, the body's own weight's largest added), one row a ball; the
mesh's rows keep what that field leaves out (the other balls, where the weight strains most).
The balls on one body are coupled only through the far field, which this leaves out: under
quadruped-foam's 5 cm mat another ball 0.2 m away changes a ball's force by 0.02 % (an
independent audit's finite-mat FEM; a half-space's Boussinesq bound, 1 % at 0.4 m, is far
above what a layer on a rigid base passes on), on a 12 cm block by 0.1-0.2 % (another audit's
superposition estimate, 2026-12-05), 0.03 % at 0.4 m. `stances.verify` checks each ball's
sinking against the law solved afresh (:func:`fem.sphere_on_layer_force`), its cone, its
nodes' cones, its converged strain and the body's strain on the mesh.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import weakref

import numpy as np
import scipy.linalg
import scipy.spatial
from scipy.optimize import brentq

import fem
from fem.layer_contact import NEAREST_SIDE_SHARE, SIDE_DROP, BallOnLayer, side_softening, widest_contact

from .blocks import PLACEMENT_ACCURACY, ConstraintBlock, equality
from .contacts import PointContact
from .errors import StanceError
from .statics import PointLoads, points_in_world

__all__ = ["LayerBalls", "largest_ball_load", "layer_site", "layer_sites", "layer_under"]

# The sinking's slope in the force is infinite at no force (Hertz: depth ~ F^(2/3)): a
# linearisation takes it at no less than this share of the robot's weight.
_SLOPE_FLOOR = 1e-3

# Gauss-Legendre points of the stored energy's integral (deformation_energy).
_ENERGY_POINTS = 8

# The strain rows: each ball's field per newton is tabulated at the contact radii of these
# shares of the robot's weight (and the law's largest force), and interpolated in the radius
# (the 20 mm means under a ball fall by 10 % as its contact widens from 4 to 16 mm on
# quadruped-foam's foam). The tets whose means are bounded: centroids within this many strain
# radii of a print.
_STRAIN_SHARES = (0.01, 0.03, 0.1, 0.2, 0.35, 0.6, 1.0)
_STRAIN_REACH = 2.0
_STRAIN_MARGIN = 2e-3  # of the bound, kept by the rows (their interpolation's error, a tenth of it)
# A ball's strain is read on the layer's field (divided by its sides' softening) this many
# strain radii inside a box's sides and more: nearer, a mat's free side bulges and its 20 mm
# means at the side's top edge pass the field's (an independent FEM, 2026-12-05,
# bench/results/audit-near-sides-2026-12-05.md: 0.86-0.97 of its strain 20 mm = 1 strain radius
# from a 5 cm mat's side, 0.59-0.84 at 10-15 mm; 0.99-1.02 at 30 mm, a corner's included; 1.03-1.11
# on a 12 cm block from 20 mm).
_STRAIN_SIDE_REACH = 1.5
_AUDITED_STRAIN_RADIUS = 0.02  # m: the audit's means; a smaller radius keeps the 30 mm it measured
# A layer whose sides are no free vertical faces (layer_under): where free faces would lower a
# ball's force by at most this in all, whatever lies there moves it by no more.
_UNCHECKED_SIDES_DROP = 0.02
_SMALLEST_STRAIN_SHARE = 0.05  # the converged strain's table starts at this share of the widest contact

@functools.lru_cache(maxsize=256)
def _law(radius: float, thickness: float, young_modulus: float, poisson_ratio: float,
         side_distances: tuple = ()) -> BallOnLayer:
    """The layer's law, tabulated once per ball, layer and place on it (6 ms; a planner asks
    for it at every solve, at the few places its print grid has on a body)."""
    return BallOnLayer(radius, thickness, young_modulus, poisson_ratio, side_distances)


def _site_law(radius: float, site: tuple, deformable_object) -> BallOnLayer:
    """The law of a ball of ``radius`` metres at ``site`` (the thickness and side distances of
    :func:`layer_under`) on the object's material."""
    material = deformable_object.body.material
    thickness, sides = site
    return _law(float(radius), float(thickness), float(material.young_modulus), float(material.poisson_ratio), sides)


def _without_sides(law: BallOnLayer) -> BallOnLayer:
    """The same ball and layer, laterally infinite: what the strain table is read for (the
    field under a ball is the layer's; one table a ball and layer, not one a place)."""
    return _law(law.radius, law.thickness, law.young_modulus, law.poisson_ratio)


@functools.lru_cache(maxsize=64)
def _ball_strain(law: BallOnLayer, strain_radius: float, friction: float) -> fem.LayerBallStrain:
    """The converged strain per newton of a ball on the layer, tabulated once per ball, layer,
    averaging radius and friction coefficient (seven contact radii by seven sideways ratios:
    14 axisymmetric fields, 15 s on a loaded 2-core host, then from the disk cache) over the
    contact radii the law reads, from a twentieth of its widest (below it the mean is flat in
    the radius: 0.4 % from 1.2 to 5 mm on quadruped-foam's foam), and the sideways ratios its
    friction pyramid allows. ``law`` without sides (:func:`_without_sides`): its widest contact
    is the widest any place on the layer reads."""
    widest = law.contact_radius(law.force_limit)
    return fem.LayerBallStrain(law.thickness, law.poisson_ratio, strain_radius, _SMALLEST_STRAIN_SHARE * widest, widest,
                               largest_ratio=friction)


@functools.lru_cache(maxsize=64)
def _force_limit(law: BallOnLayer, depth: float) -> float:
    """Newtons: the largest force the law is read for with the sinking bounded by ``depth``."""
    if law.depth_limit <= depth:
        return law.force_limit
    return fem.sphere_on_layer_force(depth, law.radius, law.thickness, law.young_modulus, law.poisson_ratio,
                                     law.side_distances)[0]


# Each body's _UnitStrains by its balls' prints, laws and bounds (LayerBalls._unit_strains),
# the most recently used of them: a set of prints a plan meets, it meets again in its next
# stances; thousands of plans in one process would otherwise keep gigabytes.
_KEPT_STRAIN_TABLES = 16
_UNIT_STRAINS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _indentation_bound(options, thickness: float) -> float:
    """Metres a ball may sink into a layer ``thickness`` thick: ``max_indentation``, else
    ``indentation_limit`` of the thickness."""
    if options.max_indentation is not None:
        return float(options.max_indentation)
    return float(options.indentation_limit * thickness)


def _strain_on_layer(law: BallOnLayer, deformable_object, force: float, contact_radius: float, friction: float,
                     d_radius: float = 0.0, sideways: float = 0.0, floor: float = 0.0) -> tuple[float, float, float]:
    """A ball's strain on its layer's converged field, ``F g(a, Q / F) / (E s(a))`` plus the
    largest its body's own weight gives (:class:`fem.LayerBallStrain`), F its normal force, Q
    its sideways force's magnitude, s the sides' softening at its contact radius a
    (:func:`fem.layer_contact.side_softening`, 1 on a laterally infinite layer); and its
    derivatives in F (Q held, the contact radius moving ``d_radius`` a newton) and in Q^2. The
    ratio is taken at no less than ``floor`` newtons of F (a pyramid's force has ``Q <= mu F``:
    none at no load).

    Near a free side the body strains more under the same force than the layer's field says:
    an independent FEM of a 12 cm block (2026-12-05) found the largest 20 mm mean 1.9 % above
    it 5 cm from a side, 4.8-5.0 % 3-5 cm from one side and 4 cm from another, where the
    force's softening is 2.7 and 6.3-7.4 %: dividing by it stays above. (The softening is read
    at the layer's contact radius, 1-6 % wider than the force's ``sqrt(R d)`` on such layers: a
    little more of it, on the safe side.)"""
    table = _ball_strain(_without_sides(law), float(deformable_object.strain_radius), float(friction))
    base = max(float(force), float(floor), 1e-12)
    square = (sideways / base) ** 2
    per_force, d_radius_term, d_square = table.per_force(contact_radius, float(np.sqrt(square)))
    softening, d_softening = side_softening(contact_radius, law.thickness, law.side_distances)
    scale = 1.0 / (law.young_modulus * softening)
    ball = force * per_force * scale
    d_force = ((per_force + force * d_radius_term * d_radius - (2.0 * square * d_square if force >= floor else 0.0))
               * scale - ball * d_softening * d_radius / softening)
    return ball + deformable_object.largest_strain_at_rest, d_force, force * d_square * scale / (base * base)


def layer_sites(robot, deformable_object, prints, options) -> tuple | None:
    """Each print's :func:`layer_site` where a soft body's prints sink by the layer's law
    (``ball_contact="layer"``: ball feet only, each where the body is a layer), else None.

    Parameters
    ----------
    robot : stances.Robot
    deformable_object : environments.DeformableObject
    prints : sequence of stances.deformable.PrintSpec
        Every print on the body.
    options : stances.PostureOptions
    """
    if options.ball_contact != "layer":
        return None
    sites = []
    for spec in prints:
        surface = robot.surface(spec.robot_surface)
        site = (layer_site(deformable_object, spec.transform_print_to_world, surface.radius, spec.surface.friction)
                if surface.is_point else None)
        if site is None:
            return None
        sites.append(site)
    return tuple(sites)


def largest_ball_load(radius: float, site: tuple, deformable_object, options, friction: float) -> float:
    """Newtons: the largest normal force a ball carries on a layer by its law: within the
    law's table and indentation bound (:attr:`LayerBalls.force_limits`) and with its strain on
    the layer's converged field within the object's bound (:meth:`LayerBalls.ball_strain`,
    less its rows' margin, with no sideways force); 0 if the body's own weight leaves it no
    strain to spend.

    Parameters
    ----------
    radius : float
        The ball's, metres.
    site : (float, tuple of float)
        The layer's thickness and its side faces' distances under the print, metres
        (:func:`layer_site`).
    deformable_object : environments.DeformableObject
    options : stances.PostureOptions
        ``max_indentation`` / ``indentation_limit``.
    friction : float
        The print surface's friction coefficient (the strain table the solver will read
        spans the sideways ratios it allows).
    """
    law = _site_law(radius, site, deformable_object)
    return _strain_bound_load(law, deformable_object, friction, _force_limit(law, _indentation_bound(options, site[0])))


def _strain_bound_load(law: BallOnLayer, deformable_object, friction: float, top: float) -> float:
    """Newtons: the largest normal force up to ``top`` whose strain on the layer's converged
    field (no sideways force) is within the object's bound less the rows' margin; 0 if the
    body's own weight leaves no strain to spend."""
    bound = (1.0 - _STRAIN_MARGIN) * float(deformable_object.strain_limit)

    # Normal force alone (a sideways force strains more): the largest load any stance may put there.
    def excess(force):
        return _strain_on_layer(law, deformable_object, force, law.contact_radius(force), float(friction))[0] - bound

    if excess(0.0) >= 0.0:
        return 0.0
    return top if excess(top) <= 0.0 else float(brentq(excess, 0.0, top, xtol=1e-9 * top))


def layer_site(deformable_object, transform_print_to_world, radius: float, friction: float) -> tuple | None:
    """The body's thickness under a ball's print and the distances of its side faces, if the
    body is a layer there for the ball's law, else None.

    A layer: held on its base under the print (:func:`layer_under`: a box, or a convex top face
    over nothing but the base), the print inside its side faces by at least
    :data:`fem.layer_contact.NEAREST_SIDE_SHARE` of the thickness (nearer, the sides'
    softening was not tested) and 1.5 strain radii, 20 mm at least (nearer,
    a mat's side strains more than the layer's field says: ``_STRAIN_SIDE_REACH``), and so far
    that no side cuts the law's table (:func:`fem.layer_contact.side_contact_limit`) short of
    the load the object's strain bound allows there (:func:`_covers_strain_bound`): nearer, the
    law would bound the ball's force below what the mesh's nodes carry (a review, 2026-12-05:
    with the table cut at the nearest side over 5, 19 N 2.5 cm from a 5 cm mat's side, where
    ANYmal's front feet carry 63 N). For ANYmal's ball under a 5 % bound: 32 mm inside
    quadruped-foam's mat, 34 mm inside a 12 cm block, 67 mm inside a 0.3 m cube.

    Parameters
    ----------
    deformable_object : environments.DeformableObject
    transform_print_to_world : (4, 4) float
        The print frame (z: the surface's outward normal), world.
    radius : float
        The ball's, metres.
    friction : float
        The print surface's friction coefficient (the strain table's sideways ratios).

    Returns
    -------
    (float, tuple of float) or None
        The thickness and the side faces' distances from the print's origin, metres.
    """
    site = layer_under(deformable_object, transform_print_to_world, radius)
    if site is None:
        return None
    strain_reach = _STRAIN_SIDE_REACH * max(float(deformable_object.strain_radius), _AUDITED_STRAIN_RADIUS)
    if min(site[1]) < (1.0 - 1e-9) * strain_reach:
        return None
    law = _site_law(radius, site, deformable_object)
    return site if _covers_strain_bound(law, deformable_object, float(friction)) else None


def layer_under(deformable_object, transform_print_to_world, radius: float) -> tuple | None:
    """The body's thickness under a ball's print and the distances of its side faces, if the
    body is a layer held on its base there, else None. Where the layer's force formula holds,
    whatever the strain (:func:`layer_site` asks more of a ball that sinks by it).

    A layer: the print's normal along one of the body's axes and the print on the body's
    extreme face that way, the nodes of the opposite face exactly the body's fixed nodes, and
    either

    - a box (its tets fill its bounding box), the print inside its other faces by at least
      :data:`fem.layer_contact.NEAREST_SIDE_SHARE` of the thickness (the sides' softening's
      range, measured on boxes); or
    - a body whose top face there is a convex polygon with nothing but the base under it (no
      boundary of the body inside the polygon's prism but that face and the base: a pad with
      bevelled edges, the top of a block of a step). Its sides are taken as the polygon's
      edges, though what lies beyond them (a bevel, attached blocks) is no free vertical face.
      The body then lies between the prism over its top face with free vertical sides and the
      laterally infinite layer held on its base, so a frictionless ball's force lies between
      the law with those sides and the law without any (an independent FEM of a bevelled pad,
      ``bench/results/audit-bevelled-pad-2026-12-05.md``: -0.10 to -1.07 % of its converged
      force, the truth nearer the infinite layer): the print must lie where free faces there
      would lower the force by under :data:`_UNCHECKED_SIDES_DROP` in all at the ball's widest
      contact, whatever they are, and the law reads at most that low there.

    Parameters
    ----------
    deformable_object : environments.DeformableObject
    transform_print_to_world : (4, 4) float
        The print frame (z: the surface's outward normal), world.
    radius : float
        The ball's, metres.

    Returns
    -------
    (float, tuple of float) or None
        The thickness and the side faces' distances from the print's origin, metres (a box's
        four; a polygon's edges, one each).
    """
    body = deformable_object.body
    to_world = np.asarray(deformable_object.transform_body_to_world, dtype=float)
    placement = np.asarray(transform_print_to_world, dtype=float)
    normal = to_world[:3, :3].T @ placement[:3, 2]  # body frame
    axis = int(np.argmax(np.abs(normal)))
    if not abs(normal[axis]) > 1.0 - 1e-9:
        return None
    low, high = body.mesh.bounding_box
    extent = high - low
    origin = to_world[:3, :3].T @ (placement[:3, 3] - to_world[:3, 3])
    face, base_face = (high, low) if normal[axis] > 0.0 else (low, high)
    thickness = float(extent[axis])
    on_face = abs(origin[axis] - face[axis]) <= 1e-6 * thickness
    base = np.abs(body.mesh.nodes[:, axis] - base_face[axis]) <= 1e-9 * thickness
    if not (on_face and np.array_equal(base, body.fixed_mask)):
        return None
    if abs(float(np.sum(body.mesh.volumes)) / float(np.prod(extent)) - 1.0) < 1e-9:  # a box
        sides = tuple(float(d) for k in range(3) if k != axis for d in (origin[k] - low[k], high[k] - origin[k]))
        return (thickness, sides) if min(sides) >= (1.0 - 1e-9) * NEAREST_SIDE_SHARE * thickness else None
    edges = _top_face_edges(body.mesh, axis, 1 if normal[axis] > 0.0 else -1)
    if edges is None:
        return None
    in_plane = [k for k in range(3) if k != axis]
    distances = edges[:, 2] - edges[:, :2] @ origin[in_plane]  # inside the polygon: all > 0
    if not distances.min() >= (1.0 - 1e-9) * NEAREST_SIDE_SHARE * thickness:
        return None
    contact = widest_contact(float(radius), thickness)
    if SIDE_DROP * contact * thickness * float(np.sum(1.0 / distances**2)) > _UNCHECKED_SIDES_DROP:
        return None
    return thickness, tuple(float(d) for d in distances)


# Each mesh's top faces (layer_under), by (axis, sign): its convex polygon's edges, or None.
_TOP_FACES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _top_face_edges(mesh, axis: int, sign: int):
    """The body's face at its extreme along ``axis`` (``sign``: which end) as a convex polygon
    over nothing but the base, or None: (k, 3) rows ``(n_1, n_2, c)`` of its edges' lines,
    ``n . x <= c`` inside (n a unit vector in the two other axes' plane, body frame).

    None where the face's triangles do not fill their convex hull, or where any other
    boundary triangle of the body (but the base's, at the opposite end) has a corner strictly
    inside the hull: a step, a hole, a slot or a cavity under the face (the sides and bevels
    through the hull's edges have none).
    """
    cached = _TOP_FACES.setdefault(mesh, {})
    if (axis, sign) in cached:
        return cached[(axis, sign)]
    nodes, triangles = mesh.nodes, mesh.surface_triangles
    low, high = mesh.bounding_box
    thickness = float(high[axis] - low[axis])
    top, bottom = (high[axis], low[axis]) if sign > 0 else (low[axis], high[axis])
    in_plane = [k for k in range(3) if k != axis]
    heights = nodes[triangles][:, :, axis]  # (T, 3)
    on_top = np.all(np.abs(heights - top) <= 1e-9 * thickness, axis=1)
    on_base = np.all(np.abs(heights - bottom) <= 1e-9 * thickness, axis=1)
    result = None
    if on_top.any():
        corners = nodes[np.unique(triangles[on_top])][:, in_plane]
        hull = scipy.spatial.ConvexHull(corners)
        area = float(np.sum(mesh.surface_areas[on_top]))
        if abs(area / hull.volume - 1.0) < 1e-6:  # (a 2-D hull's volume is its area)
            lines = np.column_stack([hull.equations[:, :2], -hull.equations[:, 2]])  # n . x <= c
            others = nodes[np.unique(triangles[~(on_top | on_base)])][:, in_plane]  # the other faces' corners
            # Strictly inside the hull (by a millionth of the thickness): a side face's corner on an edge is not.
            inside = np.all(others @ lines[:, :2].T - lines[:, 2] < -1e-6 * thickness, axis=1)
            result = None if inside.any() else _merged_lines(lines, thickness)
    cached[(axis, sign)] = result
    return result


def _merged_lines(lines: np.ndarray, thickness: float) -> np.ndarray:
    """A convex hull's facets, (k, 3) ``(n_1, n_2, c)``, with those on one line kept once:
    qhull splits an edge at its collinear points, and at points a mesher left a few
    nanometres off it (gmsh, an STL's float32 vertices) into facets whose normals differ by
    about that over the edge's length; normals within 1e-5 and offsets within 1e-5 of the
    thickness are one edge (each kept edge counts as a free side)."""
    kept = []
    for line in lines:
        if not any(np.abs(line[:2] - other[:2]).max() <= 1e-5 and abs(line[2] - other[2]) <= 1e-5 * thickness
                   for other in kept):
            kept.append(line)
    return np.array(kept)


# _covers_strain_bound's answers, by object (weakly: a kept object would keep its mesh and its
# factorisation alive, hundreds of megabytes on a fine mesh, in a process planning many scenes).
_COVERED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _covers_strain_bound(law: BallOnLayer, deformable_object, friction: float) -> bool:
    """Whether the law's table reaches the load the object's strain bound allows: its end is
    the widest contact a laterally infinite layer reads (:func:`fem.layer_contact.widest_contact`),
    or its strain there is at the bound or past it. (A side :data:`fem.layer_contact.SIDE_REACH`
    times the widest contact away, 61 mm for ANYmal's ball, cuts nothing; quadruped-foam's 5 %
    bound takes a ball to about 250 N, a 11.6 mm contact, so the law holds to 32 mm from the
    mat's side.) Conservative where the indentation bound ends the force before the table
    (the table's end is asked for), and true where the body's own weight leaves no strain to
    spend (no load is allowed: the stance fails on its strain). Kept by law, object and
    friction: a planner asks at the same few prints at every solve (0.3 ms a brentq)."""
    kept = _COVERED.setdefault(deformable_object, {})
    key = (law, float(friction))
    if key not in kept:
        kept[key] = bool(
            law.largest_contact_radius >= (1.0 - 1e-9) * widest_contact(law.radius, law.thickness)
            or _strain_bound_load(law, deformable_object, friction, law.force_limit) < law.force_limit)
    return kept[key]


class LayerBalls:
    """Every ball foot on one soft layer, each sinking by the layer's law.

    Parameters
    ----------
    robot : stances.Robot
    deformable_object : environments.DeformableObject
        The layer: :func:`layer_site` must hold under every print.
    prints : sequence of stances.deformable.PrintSpec
        Point feet only, in stance order.
    options : stances.PostureOptions
        ``indentation_limit`` / ``max_indentation``.

    Raises
    ------
    StanceError
        A print is not a point foot's, or the body is not a layer under it.
    """

    kind = "layer"
    application = "its balls' centres"

    def __init__(self, robot, deformable_object, prints, options):
        self.deformable_object = deformable_object
        self.prints = list(prints)
        self.label = " and ".join(p.label for p in self.prints)
        self.rotation_body = np.asarray(deformable_object.transform_body_to_world, dtype=float)[:3, :3]
        balls, laws, thicknesses = [], [], []
        for spec in self.prints:
            if not robot.surface(spec.robot_surface).is_point:
                raise StanceError(f"{spec.label}: only ball feet sink by a layer's law; a polygon presses the mesh")
            ball = PointContact(robot, spec.robot_surface, spec.transform_print_to_world, spec.surface.friction,
                                spec.label, surface=spec.surface)
            site = layer_site(deformable_object, spec.transform_print_to_world, ball.radius, ball.friction)
            if site is None:
                raise StanceError(f"{spec.label}: {deformable_object.name} is not a layer under this print "
                                  "(a box or a convex top face over nothing but its held base, the print inside its "
                                  "sides by a sixth of its thickness, "
                                  f"{_STRAIN_SIDE_REACH:g} strain radii and far enough that no side cuts the law short "
                                  "of the load its strain bound allows)")
            balls.append(ball)
            thicknesses.append(site[0])
            laws.append(_site_law(ball.radius, site, deformable_object))
        self.balls, self.laws, self.thicknesses = tuple(balls), tuple(laws), tuple(thicknesses)
        self.frame_ids = tuple(b.frame_id for b in balls)
        self._last_loads = None  # (forces' bytes, ball_loads of them)
        self._strain_outlier = None  # the tet of the last verify's strain failure outside the rows
        self.extra_strain_tets = ()  # such tets, rows of their nearest ball since (take_strain_outlier)
        # The law's force bound: its table's end or the indentation bound, whichever comes first.
        self.max_indentation = tuple(_indentation_bound(options, t) for t in thicknesses)
        self.force_limits = np.array([_force_limit(law, depth) for law, depth in zip(laws, self.max_indentation)])
        self.max_strain_rows = int(options.max_strain_rows)  # rows a ball, 0 none (verify checks every tet)
        self.robot_weight = float(robot.weight)
        self.slope_floor = _SLOPE_FLOOR * self.robot_weight
        self.loads = PointLoads(np.concatenate([b.loads.joints for b in balls]),
                                np.concatenate([b.loads.points_in_joint for b in balls]))
        self.load_frames = tuple(frame for b in balls for frame in b.load_frames)
        self.generators = scipy.linalg.block_diag(*[b.generators for b in balls])
        self.n_variables = self.generators.shape[1]
        self.variable_lower = np.zeros(self.n_variables)
        self.print_labels = tuple(b.label for b in balls)
        self.print_surfaces = tuple(b.robot_surface for b in balls)
        self.load_prints = np.arange(len(balls))
        self.load_normals = np.array([b.print_placement.rotation[:, 2] for b in balls])
        # Each ball's normal force is _normal_rows[i] @ its pyramid coefficients (_pyramid[i] of lambda).
        self._pyramid = [slice(sum(b.n_variables for b in balls[:i]), sum(b.n_variables for b in balls[: i + 1]))
                         for i in range(len(balls))]
        self._normal_rows = [self.load_normals[i] @ b.generators for i, b in enumerate(balls)]

    # -- the problem builder's interface (stances.contacts) --------------------
    def forces(self, model, data, lam) -> np.ndarray:
        """(L, 3) world forces on the robot at the balls' centres, newtons."""
        return (self.generators @ lam).reshape(-1, 3)

    def force_jacobians(self, model, data, lam):
        """Derivatives of the stacked forces: zero in q, ``generators`` in lambda."""
        return np.zeros((self.generators.shape[0], model.nv)), self.generators

    def force_curvature(self, model, data, lam):
        """None: the forces are linear in the variables."""
        return None

    def normal_forces(self, lam) -> np.ndarray:
        """(L,) each ball's normal force, newtons."""
        return np.array([row @ lam[s] for row, s in zip(self._normal_rows, self._pyramid)])

    def blocks(self, model, data, lam, columns, offset, derivatives=True):
        """Each ball's centre on its print, its normal row sunk by the law (3 rows a ball);
        each ball's normal force within the law's bound (1 row a ball).

        Parameters
        ----------
        columns : int
            Width of the step vector (nv + m).
        offset : int
            Column of this contact's first variable.
        derivatives : bool
            False: the rows' values only, ``jacobian`` None.
        """
        lam = np.asarray(lam, dtype=float)
        normal = self.normal_forces(lam)
        residuals, jacobians, labels = [], [], []
        force_rows = np.zeros((len(self.balls), columns)) if derivatives else None
        for i, (ball, law) in enumerate(zip(self.balls, self.laws)):
            depth, _ = law.sinking(float(normal[i]))
            columns_i = slice(offset + self._pyramid[i].start, offset + self._pyramid[i].stop)
            if derivatives:
                residual, jacobian_q = ball._placement(model, data)
                jacobian = np.zeros((3, columns))
                jacobian[:, : model.nv] = jacobian_q
                # The slope at no less than a small load: infinite at none.
                jacobian[2, columns_i] = law.sinking(max(float(normal[i]), self.slope_floor))[1] * self._normal_rows[i]
                jacobians.append(jacobian)
                force_rows[i, columns_i] = self._normal_rows[i]
            else:
                residual = ball._placement_residual(data)
            residuals.append(residual + np.array([0.0, 0.0, depth]))
            labels.extend(f"placement of {ball.label} ({axis})" for axis in ("x", "y", "z"))
        placement = equality(
            "placement", np.concatenate(residuals), np.vstack(jacobians) if derivatives else None, 1e-2, labels,
            PLACEMENT_ACCURACY, self._weighted_placement, self._placement_curvature,
        )
        bound = ConstraintBlock(
            "layer law bound", normal, force_rows, -np.inf, self.force_limits, 10.0,
            tuple(f"force of {b.label} within its layer's law" for b in self.balls),
        )
        if not self.max_strain_rows:
            return [placement, bound]
        return [placement, bound, self._ball_strain_block(lam, normal, columns, offset, derivatives),
                self._strain_block(lam, normal, columns, offset, derivatives)]

    def ball_strain(self, i: int, normal_force: float, sideways: float = 0.0) -> tuple[float, float, float]:
        """Ball i's strain on its layer's converged field under it: the largest principal
        magnitude of its means (the object's strain radius) under its normal and sideways
        forces, plus the largest its body's own weight gives; and its derivatives in the normal
        force (per newton, the sideways one held) and in the sideways force's square (per N^2).

        Parameters
        ----------
        i : int
            The ball's index in :attr:`balls`.
        normal_force : float
            Newtons, >= 0.
        sideways : float
            The sideways force's magnitude, newtons, >= 0 (at most the friction coefficient
            times the normal force: the ball's pyramid).

        Returns
        -------
        strain : float
            The largest principal magnitude, its body's own weight's included.
        d_normal : float
            Per newton of normal force, the sideways force held.
        d_square : float
            Per N^2 of the sideways force's square.
        """
        law = self.laws[i]
        # The contact's radius at no less than a small load (its slope is infinite at none).
        floored = normal_force < self.slope_floor
        radius, d_radius = law.contact_radius_and_slope(self.slope_floor if floored else float(normal_force))
        return _strain_on_layer(law, self.deformable_object, normal_force, radius, self.balls[i].friction,
                                0.0 if floored else d_radius, sideways, self.slope_floor)

    def _ball_strain_block(self, lam, normal, columns, offset, derivatives) -> ConstraintBlock:
        """Each ball's converged strain (:meth:`ball_strain`) within the object's bound.

        Its sideways force Q enters as Q^2 (the strain is even in it): with no sideways
        force the row's gradient has no part along the print, and a QP would swing the
        force across (quadruped-foam at a 1 % bound: 91 SQP iterations, the objective
        alternating). The block gives each row's curvature along the print,
        ``2 (d strain / d Q^2) (I - n n^T)`` in the ball's force, to the SQP's Hessian
        (:attr:`~stances.blocks.ConstraintBlock.variable_curvature`; the terms in the normal
        force left out).
        """
        values, rows = np.zeros(len(self.balls)), np.zeros((len(self.balls), columns)) if derivatives else None
        curvatures = []  # (the ball's columns, its row's curvature in its pyramid's variables)
        for i, ball in enumerate(self.balls):
            force = ball.generators @ lam[self._pyramid[i]]
            sideways = force - self.load_normals[i] * normal[i]  # along the print, world frame
            values[i], d_normal, d_square = self.ball_strain(i, float(normal[i]), float(np.linalg.norm(sideways)))
            if derivatives:
                where = slice(offset + self._pyramid[i].start, offset + self._pyramid[i].stop)
                rows[i, where] = d_normal * self._normal_rows[i] + d_square * 2.0 * sideways @ ball.generators
                along = ball.generators - np.outer(self.load_normals[i], self._normal_rows[i])  # (I - n n^T) G
                curvatures.append((where, 2.0 * max(d_square, 0.0) * (along.T @ along)))

        def variable_curvature(weights):
            out = np.zeros((columns, columns))
            for weight, (where, matrix) in zip(weights, curvatures):
                out[where, where] += weight * matrix
            return out

        limit = float(self.deformable_object.strain_limit)
        return ConstraintBlock("ball strain", values, rows, -np.inf, (1.0 - _STRAIN_MARGIN) * limit, limit,
                               tuple(f"strain under {b.label} ({self.deformable_object.name}'s converged field)"
                                     for b in self.balls),
                               variable_curvature=variable_curvature if derivatives else None)

    def _strain_block(self, lam, normal, columns, offset, derivatives) -> ConstraintBlock:
        """Each ball's largest principal strain (mean over the object's strain radius, its
        own weight's included) over the tets near it, at most the object's bound: the field
        is the balls' unit fields times their forces (:attr:`_unit_strains`)."""
        table = self._unit_strains
        limit = float(self.deformable_object.strain_limit)
        radii, slopes = zip(*(law.contact_radius_and_slope(float(max(f, self.slope_floor)))
                              for law, f in zip(self.laws, normal)))
        # Each ball's force on the robot in the body frame, and its derivative in its pyramid.
        forces = [self.rotation_body.T @ (ball.generators @ lam[s]) for ball, s in zip(self.balls, self._pyramid)]
        d_forces = [self.rotation_body.T @ ball.generators for ball in self.balls]
        values, rows, labels = [], [], []
        for i, ball in enumerate(self.balls):
            strain = table.weight[i].copy()  # (n, 6) the body's own weight's means at ball i's rows' tets
            terms = []
            for j in range(len(self.balls)):
                unit, d_unit = table.at(i, j, radii[j])  # (3, n, 6) per newton along each body axis
                strain += np.einsum("c,cnk->nk", forces[j], unit)
                terms.append((unit, np.einsum("c,cnk->nk", forces[j], d_unit) * slopes[j]))
            # Each tet's largest principal strain magnitude, stretch or compression; one row
            # for each of the most strained (a max over them would be a kink the line search
            # stalls on; where the most strained lie moves with the ball's sideways force).
            eigenvalues, eigenvectors = np.linalg.eigh(fem.voigt_to_tensor_strain(strain))
            magnitude = np.maximum(eigenvalues[:, 2], -eigenvalues[:, 0])
            for t in np.sort(np.argsort(-magnitude, kind="stable")[:self.max_strain_rows]).tolist():
                which, sign = (2, 1.0) if eigenvalues[t, 2] >= -eigenvalues[t, 0] else (0, -1.0)
                values.append(sign * eigenvalues[t, which])
                labels.append(f"strain under {ball.label} (tet {table.tets[i][t]})")
                if not derivatives:
                    continue
                v = eigenvectors[t, :, which]

                def along(voigt):  # d lambda = v^T dE v (a simple eigenvalue), E's shears halved
                    return sign * float(v @ fem.voigt_to_tensor_strain(voigt) @ v)

                row = np.zeros(columns)
                for j, (unit, radius_term) in enumerate(terms):
                    row[offset + self._pyramid[j].start: offset + self._pyramid[j].stop] += (
                        np.array([along(unit[c, t]) for c in range(3)]) @ d_forces[j]
                        + along(radius_term[t]) * self._normal_rows[j])
                rows.append(row)
        # The rows keep a hair under the bound: their unit strains are interpolated in the
        # contact radius, which verify's field is not (0.05002 against 0.05 at 1e6 Pa with 7 radii).
        return ConstraintBlock("strain", np.array(values), np.array(rows).reshape(len(values), columns) if derivatives
                               else None, -np.inf, (1.0 - _STRAIN_MARGIN) * limit, limit, tuple(labels))

    @functools.cached_property
    def _unit_strains(self) -> "_UnitStrains":
        """The balls' strain means per newton near each ball (built on the first linearisation,
        kept with the body for the same balls: a planner solves many stances on the same prints)."""
        kept = _UNIT_STRAINS.setdefault(self.deformable_object.body, collections.OrderedDict())
        key = (tuple(np.concatenate([b.print_placement.homogeneous.ravel() for b in self.balls]).tolist()),
               self.laws, tuple(self.force_limits.tolist()), self.robot_weight, self.extra_strain_tets,
               float(self.deformable_object.strain_radius))
        if key in kept:
            kept.move_to_end(key)
        else:
            kept[key] = _UnitStrains.of(self)
            if len(kept) > _KEPT_STRAIN_TABLES:  # about 2 MB each for two balls on a 10 mm mesh
                kept.popitem(last=False)
        return kept[key]

    def solver_state(self) -> tuple:
        """What a solve leaves behind that the next one starts from (the strain rows verify
        added): for :meth:`restore_solver_state`."""
        return self._strain_outlier, self.extra_strain_tets

    def restore_solver_state(self, state) -> None:
        """Back to a :meth:`solver_state`: a solve abandoned leaves no trace in the next."""
        self._strain_outlier, self.extra_strain_tets = state

    def take_strain_outlier(self) -> bool:
        """Make the tet of the last verify's strain failure a strain row of its nearest
        ball, if it lay outside the rows; True if it did (the SQP then goes on)."""
        tet, self._strain_outlier = self._strain_outlier, None
        if tet is None:
            return False
        self.extra_strain_tets = self.extra_strain_tets + (int(tet),)
        self.__dict__.pop("_unit_strains", None)
        return True

    def _weighted_placement(self, model, data, weights) -> np.ndarray:
        """(nv,) ``weights @ jacobian`` of the placement rows in the configuration columns (the
        sinking depends on the forces only)."""
        return sum(ball._weighted_placement(model, data, weights[3 * i : 3 * i + 3])
                   for i, ball in enumerate(self.balls))

    def _placement_curvature(self, model, data, weights) -> np.ndarray:
        """(nv, nv) the placement rows' curvature along the joints' motions: each ball's
        centre rows' (the sinking is constant in q)."""
        return sum(ball._placement_curvature(model, data, weights[3 * i : 3 * i + 3])
                   for i, ball in enumerate(self.balls))

    def cost(self, model, data, lam, options, columns, offset, derivatives=True):
        """No objective term of its own (lambda's is the problem's force term)."""
        return None

    # -- the body's field ------------------------------------------------------
    def ball_loads(self, forces) -> list:
        """Each pressing ball's Hertzian pressure on the body as consistent nodal loads.

        Parameters
        ----------
        forces : (L, 3) float
            The balls' forces on the robot, world frame, newtons.

        Returns
        -------
        list of (ball index, node_ids (k,) int, loads (k, 3) float)
            Forces on the body, newtons, body frame; the balls that press only.
        """
        forces = np.asarray(forces, dtype=float).reshape(-1, 3)
        # verify asks for the field's loads and then its own check's: the last is kept.
        key = forces.tobytes()
        if self._last_loads is not None and self._last_loads[0] == key:
            return self._last_loads[1]
        body = self.deformable_object.body
        origin = np.asarray(self.deformable_object.transform_body_to_world, dtype=float)[:3, 3]
        out = []
        for i, (ball, law, force) in enumerate(zip(self.balls, self.laws, forces)):
            normal = float(ball.print_placement.rotation[:, 2] @ force)
            if normal <= 0.0:
                continue
            centre = self.rotation_body.T @ (ball.print_placement.translation - origin)
            node_ids, shares = fem.hertz_load_shares(
                body.mesh, centre, self.rotation_body.T @ ball.print_placement.rotation[:, 2], law.contact_radius(normal))
            out.append((i, node_ids, shares[:, None] * (-(force @ self.rotation_body))[None]))
        self._last_loads = (key, out)
        return out

    def displacement_field(self, model, data, forces) -> np.ndarray:
        """(N, 3) displacement of every node of the body under the balls' pressures, metres,
        body frame (one sparse solve; zero where no ball presses)."""
        return self.deformable_object.body.displacement_under_loads(*self.field_loads(forces))

    def field_loads(self, forces):
        """``(node_ids, loads)``, (k,) int and (k, 3) float newtons, body frame: the balls'
        pressures' nodal loads, whose field is :meth:`displacement_field`'s (none where no
        ball presses)."""
        pressed = self.ball_loads(forces)
        if not pressed:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
        node_ids, where = np.unique(np.concatenate([ids for _, ids, _ in pressed]), return_inverse=True)
        loads = np.zeros((len(node_ids), 3))
        np.add.at(loads, where, np.concatenate([load for _, _, load in pressed]))
        return node_ids, loads

    # -- independent check -----------------------------------------------------
    def verify(self, model, data, points, forces, tolerances, measures, field=None) -> list:
        """Each ball on its print, sunk as the layer's law solved afresh gives for its force
        (:func:`fem.sphere_on_layer_force`, not the solver's table), within the law's
        bounds and its friction cone; every node's load in its cone; the body's strain.

        Parameters
        ----------
        points, forces : (L, 3) float
            Reported application points and forces, world frame.
        field : (N, 3) float, optional
            :meth:`displacement_field` of these forces (computed here otherwise).
        """
        name = self.deformable_object.name
        expected = points_in_world(data, self.loads)
        if len(points) != len(expected) or np.abs(points - expected).max() > tolerances.placement:
            return [f"forces of {self.label} are not applied at {self.application}"]
        reasons = []
        for ball, law, bound, force in zip(self.balls, self.laws, self.max_indentation, forces):
            reasons.extend(self._verify_ball(data, ball, law, bound, force, tolerances, measures))
        # The body's indentation is its deepest ball's sinking (the mesh under a ball sinks less).
        measures[f"indentation of {name}"] = max(max(measures[f"sinking of {b.label}"] for b in self.balls), 0.0)
        for i, _, loads in self.ball_loads(forces):
            # Every node's load on the robot in its ball's cone: read back from the loads
            # themselves (non-negative shares keep the resultant's ratio).
            ball = self.balls[i]
            local = -loads @ (self.rotation_body.T @ ball.print_placement.rotation)
            margin = np.minimum(local[:, 2], ball.friction * local[:, 2] - np.linalg.norm(local[:, :2], axis=1))
            measures[f"node cone margin of {ball.label}"] = float(margin.min())
            if margin.min() < -tolerances.cone:
                reasons.append(f"a node under {ball.label} leaves its friction cone by {-margin.min():.3g} N")
        field = self.displacement_field(model, data, forces) if field is None else field
        body = self.deformable_object.body
        measures[f"deformation energy of {name}"] = float(sum(
            self._stored_energy(law, float(ball.print_placement.rotation[:, 2] @ force))
            for ball, law, force in zip(self.balls, self.laws, forces)))
        strain, tet = body.largest_principal_strain(field + self.deformable_object.self_weight_field,
                                                    self.deformable_object.strain_radius)
        measures[f"largest strain of {name}"] = strain
        self._strain_outlier = None
        if strain > self.deformable_object.strain_limit + 1e-6:
            if not any(tet in tets for tets in self._unit_strains.tets):
                self._strain_outlier = tet
            centre = self.deformable_object.points_in_world(body.mesh.nodes[body.mesh.tets[tet]].mean(axis=0)[None])[0]
            reasons.append(
                f"strain {strain:.3g} of {name} (its own weight's included) at ({centre[0]:.3f}, {centre[1]:.3f}, "
                f"{centre[2]:.3f}) m (mean over {1e3 * self.deformable_object.strain_radius:g} mm) exceeds its bound "
                f"{self.deformable_object.strain_limit:g}: linear elasticity does not hold there"
            )
        return reasons

    def _verify_ball(self, data, ball, law, bound, force, tolerances, measures) -> list:
        """One ball: on its print, sunk by the law (solved afresh), within bounds and cone."""
        rotation = ball.print_placement.rotation
        offset = rotation.T @ (data.oMf[ball.frame_id].translation - ball.print_placement.translation)
        sinking = ball.radius - float(offset[2])
        local = rotation.T @ np.asarray(force, dtype=float)
        normal, tangential = float(local[2]), float(np.hypot(local[0], local[1]))
        label, reasons = ball.label, []
        side = float(np.abs(offset[:2]).max())
        measures[f"placement error of {label}"] = side
        if side > tolerances.placement:
            reasons.append(f"{label} is off its print by {side:.3g} m along the surface")
        measures[f"sinking of {label}"] = sinking
        margin = min(normal, ball.friction * normal - tangential)
        measures[f"cone margin of {label}"] = margin
        if margin < -tolerances.cone:
            reasons.append(f"the force of {label} leaves its friction cone by {-margin:.3g} N")
        if sinking > bound + tolerances.placement:
            reasons.append(f"{label} sinks {sinking:.3g} m, beyond its indentation bound {bound:.3g} m")
            return reasons
        if sinking <= 0.0:
            if normal > tolerances.cone:
                reasons.append(f"{label} carries {normal:.3g} N without touching its layer ({-sinking:.3g} m above it)")
            return reasons
        try:
            expected, contact = fem.sphere_on_layer_force(sinking, ball.radius, law.thickness, law.young_modulus,
                                                          law.poisson_ratio, law.side_distances)
        except fem.FemError as error:
            return reasons + [f"{label}: the layer's law does not hold at its sinking ({error})"]
        measures[f"layer force of {label}"] = expected
        # The sinking's tolerance, as a force: the placement's times the law's stiffness there.
        stiffness = 1.0 / law.sinking(max(expected, self.slope_floor))[1]
        allowed = tolerances.cone + stiffness * tolerances.placement
        measures[f"layer law error of {label}"] = normal - expected
        if abs(normal - expected) > allowed:
            reasons.append(f"{label} carries {normal:.6g} N where its layer's law gives {expected:.6g} N at its "
                           f"sinking of {sinking:.4g} m")
        if contact > (1.0 + 1e-6) * law.largest_contact_radius:
            reasons.append(f"{label}'s contact radius {contact:.3g} m is past the law's validity "
                           f"({law.largest_contact_radius:.3g} m: 0.6 of the layer's thickness, 0.7 of the ball's "
                           "radius or what its sides allow, whichever is least)")
        # Its strain on the layer's converged field (the mesh's under a ball is too low).
        obj = self.deformable_object
        strain = _strain_on_layer(law, obj, max(normal, 0.0), contact, ball.friction, sideways=tangential,
                                  floor=self.slope_floor)[0]
        measures[f"strain under {label}"] = strain
        if strain > obj.strain_limit + 1e-6:
            reasons.append(f"strain {strain:.3g} under {label} (its layer's converged field under the ball's normal and "
                           f"sideways forces, its own "
                           f"weight's included, mean over {1e3 * obj.strain_radius:g} mm) exceeds its bound "
                           f"{obj.strain_limit:g}: linear elasticity does not hold there")
        return reasons

    @staticmethod
    def _stored_energy(law, force: float) -> float:
        """Joules the ball's sinking stores in the layer: ``int_0^d F dd = F d - int_0^F d(F') dF'``,
        the integral taken in ``F' = F x^3`` (smooth there) by Gauss-Legendre."""
        if force <= 0.0:
            return 0.0
        x, w = np.polynomial.legendre.leggauss(_ENERGY_POINTS)
        x, w = 0.5 * (x + 1.0), 0.5 * w
        work = sum(wi * law.sinking(force * xi**3)[0] * 3.0 * force * xi**2 for xi, wi in zip(x, w))
        return float(force * law.sinking(force)[0] - work)


@dataclasses.dataclass(frozen=True)
class _UnitStrains:
    """Strain means (Voigt, object's strain radius) near each ball of a :class:`LayerBalls`,
    per newton of each ball's force, tabulated in its contact radius.

    ``weight[i]``: (n_i, 6) the body's own weight's means at the tets near ball i;
    ``unit[i][j]``: (g, 3, n_i, 6) ball j's field there per newton of its force on the robot
    along each body axis (its pressure and a traction in proportion), at contact radii
    ``radii[j]`` (g,).
    """

    weight: tuple
    unit: tuple
    radii: tuple
    tets: tuple

    def at(self, i: int, j: int, radius: float):
        """Ball j's means per newton near ball i at a contact radius, and their derivative
        in it (linear between the table's radii, held beyond)."""
        radii, table = self.radii[j], self.unit[i][j]
        if len(radii) == 1:
            return table[0], np.zeros_like(table[0])
        k = int(np.clip(np.searchsorted(radii, radius) - 1, 0, len(radii) - 2))
        step = (table[k + 1] - table[k]) / (radii[k + 1] - radii[k])
        if radius <= radii[0]:
            return table[0], np.zeros_like(step)
        if radius >= radii[-1]:
            return table[-1], np.zeros_like(step)
        return table[k] + (radius - radii[k]) * step, step

    @staticmethod
    def of(contact: LayerBalls) -> "_UnitStrains":
        """Tabulate a contact's balls: one field per ball and radius, each a superposition
        of the body's compliance columns (:meth:`fem.DeformableBody.displacement_under_loads`)."""
        obj = contact.deformable_object
        body, strain_radius = obj.body, float(obj.strain_radius)
        averages = body.strain_averages
        origin = np.asarray(obj.transform_body_to_world, dtype=float)[:3, 3]
        centres = [contact.rotation_body.T @ (b.print_placement.translation - origin) for b in contact.balls]
        normals = [contact.rotation_body.T @ b.print_placement.rotation[:, 2] for b in contact.balls]
        extras = np.array(contact.extra_strain_tets, dtype=np.int64)
        nearest = (np.argmin([np.linalg.norm(averages.centroids[extras] - c, axis=1) for c in centres], axis=0)
                   if extras.size else extras)
        weights, centre_tets = [], []
        for i, centre in enumerate(centres):
            near = np.flatnonzero(np.linalg.norm(averages.centroids - centre, axis=1) <= _STRAIN_REACH * strain_radius)
            near = np.union1d(near, extras[nearest == i])
            centre_tets.append(near)
            weights.append(averages.weights(near, strain_radius))
        weight = tuple(matrix @ body.strain(obj.self_weight_field, members) for members, matrix in weights)
        every = np.unique(np.concatenate([members for members, _ in weights]))
        corners = np.unique(body.mesh.tets[every])  # the nodes those strains read
        field = np.zeros((body.mesh.n_nodes, 3))

        def strain(ids, loads):  # the strain of ``every`` under point loads, from its corners' field
            field[corners] = body.displacement_at(corners, ids, loads)
            return body.strain(field, every)

        radii, fields = [], []
        for law, limit, centre, normal in zip(contact.laws, contact.force_limits, centres, normals):
            forces = [share * contact.robot_weight for share in _STRAIN_SHARES] + [float(limit)]
            ball_radii = np.unique([law.contact_radius(min(f, float(limit))) for f in forces])
            radii.append(ball_radii)
            strains = []  # per radius: (3, len(every), 6), a newton on the robot along each body axis
            for a in ball_radii:
                ids, shares = fem.hertz_load_shares(body.mesh, centre, normal, float(a))
                strains.append(np.stack([strain(ids, -shares[:, None] * axis[None]) for axis in np.eye(3)]))
            fields.append(strains)
        rows = [np.searchsorted(every, members) for members, _ in weights]
        unit = [[np.stack([np.stack([matrix @ strain[c, row] for c in range(3)]) for strain in fields[j]])
                 for j in range(len(fields))]
                for (members, matrix), row in zip(weights, rows)]
        unit = tuple(tuple(per_ball) for per_ball in unit)
        tets = tuple(centre_tets)
        return _UnitStrains(weight, unit, tuple(radii), tets)
