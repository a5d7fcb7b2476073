"""Pressures on a mesh's surface as consistent nodal loads.

:func:`hertz_load_shares`: a ball's Hertzian pressure. :func:`pressure_corners`: the points
whose point loads span every non-negative pressure inside a polygon; :func:`pressure_fit`: how
far given nodal loads are from those of any such pressure.

A ball foot whose contact is smaller than the mesh's cells (:class:`fem.layer_contact.BallOnLayer`
gives its force) still loads the body: to draw its field, bound its strain and check its
nodes, the pressure ``p(rho) = p0 sqrt(1 - rho^2 / a^2)`` over the contact disc of radius a
becomes nodal loads ``f_i = int N_i p dA``, N_i the linear shape functions of the surface
triangles the disc covers (consistent loads, as a traction is in eq. (41)). Each node's load
is a share of the ball's force; the shares add up to 1, are non-negative (the shape functions
are), and a force inside its friction cone gives every node a load inside its own cone.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.optimize
import scipy.spatial

from .errors import FemError
from .mesh import TetMesh
from .prints import clip_polygon, convex_polygon_frame, meeting_bounds, plane_triangles

__all__ = ["hertz_load_shares", "pressure_corners", "pressure_fit"]

# Polar rule on the contact disc: rho = a sin(phi) takes the pressure's square root at the
# edge into a smooth integrand (p rho drho = p0 a^2 cos^2 phi sin phi dphi), Gauss-Legendre in
# phi, three times as many equal angles around. The shares add up to 1 to rounding on any
# mesh. Radii: 8 per smallest cell across the contact's radius, from 8 to 32: on cells 7 times
# finer than the radius (32 x 96 points) each node's share is within 3 % of its pressure times
# its area (16 x 48: 11 %); on cells as large as the contact, 8 x 24 points still put dozens
# in each cell.
_RADII_PER_CELL = 8
_FEWEST_RADII, _MOST_RADII = 8, 32

# Triangles whose centroids are nearest a point of the rule, tried first for the one holding it.
_CANDIDATES = 8

# Surface triangles whose outward normal lies within this of the print's normal face it.
_FACING = 1.0 - 1e-6


@functools.lru_cache(maxsize=None)
def _unit_rule(radii: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) points in the unit disc and (n,) weights of the unit Hertzian pressure,
    adding up to 1: ``radii`` Gauss points in phi, ``3 radii`` angles."""
    x, w = np.polynomial.legendre.leggauss(radii)
    phi = 0.25 * np.pi * (x + 1.0)
    radial = np.sin(phi)
    radial_weight = 0.25 * np.pi * w * np.cos(phi) ** 2 * np.sin(phi)
    count = 3 * radii
    angles = 2.0 * np.pi * (np.arange(count) + 0.5) / count
    points = (radial[:, None, None] * np.stack([np.cos(angles), np.sin(angles)], axis=-1)[None]).reshape(-1, 2)
    weights = np.repeat(radial_weight, count) / count
    weights = weights / weights.sum()
    return points, weights


def hertz_load_shares(mesh: TetMesh, centre, normal, contact_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Each node's share of a ball's force, as consistent loads of its Hertzian pressure.

    Parameters
    ----------
    mesh : TetMesh
    centre : (3,) float
        The contact's centre on the body's surface, metres, body frame.
    normal : (3,) float
        The surface's outward unit normal there, body frame.
    contact_radius : float
        Metres, > 0.

    Returns
    -------
    node_ids : (k,) int
        Sorted surface nodes under the disc.
    shares : (k,) float
        Non-negative, adding up to 1: node i's load is ``shares[i]`` times the ball's force.

    Raises
    ------
    FemError
        If the radius is not positive or a point of the disc lies on no surface triangle
        facing ``normal`` (the disc reaches past the face's edge).
    """
    if not (np.isfinite(contact_radius) and contact_radius > 0.0):
        raise FemError(f"contact_radius must be finite and > 0 metres, got {contact_radius!r}")
    centre = np.asarray(centre, dtype=float)
    normal = np.asarray(normal, dtype=float)
    normal = normal / np.linalg.norm(normal)
    # Two tangents of the face, and the points of the rule on it.
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = np.cross(normal, helper)
    first /= np.linalg.norm(first)
    second = np.cross(normal, first)
    # Facing triangles near the disc (from the mesh's centroid tree), in the same plane coordinates.
    tree, longest = mesh.surface_search
    candidates = np.array(sorted(tree.query_ball_point(centre, contact_radius + longest)), dtype=int)
    candidates = candidates[mesh.surface_normals[candidates] @ normal > _FACING] if len(candidates) else candidates
    triangles = mesh.surface_triangles[candidates]
    corners = mesh.nodes[triangles] - centre  # (t, 3, 3)
    level = np.abs(corners @ normal).max(axis=1)
    planar = np.stack([corners @ first, corners @ second], axis=-1)  # (t, 3, 2)
    reach = np.linalg.norm(planar, axis=2).min(axis=1)
    span = np.linalg.norm(planar - planar[:, [1, 2, 0]], axis=2).max(axis=1)
    near = (level <= 1e-6 * max(contact_radius, span.max(initial=0.0))) & (reach <= contact_radius + span)
    ids, planar = triangles[near], planar[near]
    if not len(ids):
        raise FemError(f"a contact of radius {contact_radius:g} m at {np.round(centre, 4).tolist()} lies on no "
                       "surface facing its normal")
    radii = int(np.clip(np.ceil(_RADII_PER_CELL * contact_radius / span[near].min()), _FEWEST_RADII, _MOST_RADII))
    unit, weights = _unit_rule(radii)
    points = contact_radius * unit  # (n, 2) in (first, second)
    origin = planar[:, 0]
    inverse = np.linalg.inv(np.stack([planar[:, 1] - origin, planar[:, 2] - origin], axis=-1))  # (t, 2, 2)
    # Each point goes to the first triangle holding it among those whose centroids are
    # nearest (a point on a shared edge gives the same loads either way); the rest, if a
    # sliver hid theirs, among all.
    nearest = scipy.spatial.cKDTree(planar.mean(axis=1)).query(points, k=min(_CANDIDATES, len(ids)))[1]
    nearest = nearest.reshape(len(points), -1)
    held, owner = _locate(points, nearest, origin, inverse)
    lost = np.flatnonzero(owner < 0)
    if len(lost):
        every = np.broadcast_to(np.arange(len(ids)), (len(lost), len(ids)))
        held[lost], owner[lost] = _locate(points[lost], every, origin, inverse)
    if (owner < 0).any():
        raise FemError(f"a contact of radius {contact_radius:g} m at {np.round(centre, 4).tolist()} reaches past "
                       "the surface facing its normal: put the ball farther from the face's edge")
    nodes = ids[owner].ravel()
    loads = (held * weights[:, None]).ravel()
    node_ids, where = np.unique(nodes, return_inverse=True)
    shares = np.bincount(where, weights=loads, minlength=len(node_ids))
    return node_ids, shares / shares.sum()


def pressure_corners(mesh: TetMesh, polygon_in_body) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The corners of each surface triangle's part inside a polygon, with the loads a unit
    point load there puts on the triangle's nodes (their shape functions' values).

    A pressure's consistent loads are ``f_i = int N_i p dA``; N_i is linear on each part, so
    a point load anywhere in a part is a non-negative combination of point loads at its
    corners: these points' loads span every non-negative pressure's inside the polygon
    (point loads being the limit of a pressure gathered at a point). Each point's shares
    are non-negative, add up to 1 and reproduce its position (``sum_i N_i(x) x_i = x``).

    Parameters
    ----------
    mesh : TetMesh
    polygon_in_body : (k, 3) float
        A convex planar polygon on the mesh's surface, in order, metres, body frame.

    Returns
    -------
    points : (n, 3) float
        The parts' corners, metres, body frame (a corner shared by parts once per part).
    node_ids : (n, 3) int
        Each point's triangle's nodes.
    shares : (n, 3) float
        Their shape functions' values at the point.

    Raises
    ------
    FemError
        A polygon that covers no surface triangle facing its normal in its plane;
        :class:`PrintError` (a FemError) as :func:`fem.print_coverage` for a polygon that is not a
        convex planar one.

    Examples
    --------
    >>> import numpy as np
    >>> from fem import box_mesh
    >>> mesh = box_mesh((0.4, 0.4, 0.1), (8, 8, 2))    # top nodes every 50 mm
    >>> square = [[0.11, 0.11, 0.1], [0.31, 0.11, 0.1], [0.31, 0.31, 0.1], [0.11, 0.31, 0.1]]
    >>> points, ids, shares = pressure_corners(mesh, square)
    >>> bool(np.allclose(np.einsum("nj,njk->nk", shares, mesh.nodes[ids]), points))
    True
    """
    centre, normal, basis, flat = convex_polygon_frame(polygon_in_body)  # flat: counter-clockwise
    keep, planar = plane_triangles(mesh, centre, normal, basis)
    near = meeting_bounds(planar, flat)
    triangles, planar = mesh.surface_triangles[keep[near]], planar[near]
    columns, owners, corners = [], [], []
    for triangle, points in zip(triangles, planar):
        part = clip_polygon(points, flat)
        if len(part) < 3:
            continue
        inverse = np.linalg.inv(np.stack([points[1] - points[0], points[2] - points[0]], axis=1))
        local = (np.asarray(part) - points[0]) @ inverse.T  # (m, 2)
        columns.append(np.clip(np.column_stack([1.0 - local.sum(axis=1), local]), 0.0, None))
        owners.append(np.broadcast_to(triangle, (len(part), 3)))
        corners.append(np.asarray(part))
    if not columns:
        raise FemError("the polygon covers no surface triangle of the mesh facing its normal in its plane: "
                       "it lies off the mesh, or off its surface")
    return centre + np.concatenate(corners) @ basis.T, np.concatenate(owners), np.concatenate(columns)


def pressure_fit(mesh: TetMesh, polygon_in_body, node_ids, loads) -> float:
    """How far nodal loads are from the consistent loads of a non-negative pressure
    inside a polygon: ``min |A p - f| / |f|`` over ``p >= 0``.

    A pressure's consistent loads are ``f_i = int N_i p dA``; N_i is linear on each part
    of a surface triangle inside the polygon, so a point load anywhere in such a part is a
    non-negative combination of point loads at the part's corners, and those corners'
    loads (their shape functions' values) span every such pressure's: the fit is exact,
    not sampled. A node outside ``node_ids`` that the pressure would load counts with a
    load of 0. A print's node forces that no pressure under the link gives (a link
    pivoting onto partly covered nodes past its edge while the nodes inside lift) read
    some percent; those of a link's face, rounding.

    Parameters
    ----------
    mesh : TetMesh
    polygon_in_body : (k, 3) float
        A convex planar polygon on the mesh's surface, in order, metres, body frame.
    node_ids : (p,) int
        Surface nodes.
    loads : (p,) float
        Their loads along the polygon's inward normal, newtons (pressing: positive).

    Returns
    -------
    float
        The least residual's norm over the loads' norm (0 for no load).

    Raises
    ------
    FemError
        Shapes that do not match, a polygon that covers no surface of the mesh, or a fit
        that does not converge; :class:`PrintError` (a FemError) as :func:`fem.print_coverage` for
        a polygon that is not a convex planar one.

    Examples
    --------
    >>> import numpy as np
    >>> from fem import box_mesh, print_coverage
    >>> mesh = box_mesh((0.4, 0.4, 0.1), (8, 8, 2))    # top nodes every 50 mm
    >>> square = [[0.11, 0.11, 0.1], [0.31, 0.11, 0.1], [0.31, 0.31, 0.1], [0.11, 0.31, 0.1]]
    >>> ids, _ = print_coverage(mesh, square)
    >>> past = np.isclose(mesh.nodes[ids, 0], 0.35)     # the row 40 mm past the right edge
    >>> round(pressure_fit(mesh, square, ids, np.where(past, 1.0, 0.0)), 2)   # loaded alone
    0.93
    """
    loads = np.asarray(loads, dtype=float)
    node_ids = np.asarray(node_ids)
    if node_ids.shape != loads.shape or loads.ndim != 1:
        raise FemError(f"node_ids and loads must be (p,) alike, got {node_ids.shape} and {loads.shape}")
    size = float(np.linalg.norm(loads))
    if size == 0.0:
        convex_polygon_frame(polygon_in_body)  # a bad polygon is refused all the same
        return 0.0
    _, owners, shares = pressure_corners(mesh, polygon_in_body)
    rows = np.union1d(owners.ravel(), node_ids)
    matrix = np.zeros((len(rows), len(shares)))
    np.add.at(matrix, (np.searchsorted(rows, owners.ravel()), np.repeat(np.arange(len(shares)), 3)), shares.ravel())
    target = np.zeros(len(rows))
    target[np.searchsorted(rows, node_ids)] = loads
    try:
        _, residual = scipy.optimize.nnls(matrix, target, maxiter=50 * matrix.shape[1])
    except RuntimeError as error:  # its iteration limit: not seen on prints (it takes a few dozen)
        raise FemError(f"the pressure fit did not converge ({error})") from error
    return float(residual) / size


def _locate(points, candidates, origin, inverse):
    """Barycentric coordinates (n, 3) of each point in the first of its candidate triangles
    (n, k) holding it, and that triangle's index (-1 where none does)."""
    local = np.einsum("nkij,nkj->nki", inverse[candidates], points[:, None, :] - origin[candidates])
    barycentric = np.concatenate([1.0 - local.sum(axis=2, keepdims=True), local], axis=2)  # (n, k, 3)
    inside = barycentric.min(axis=2) >= -1e-9
    first = np.argmax(inside, axis=1)
    found = inside[np.arange(len(points)), first]
    held = np.clip(barycentric[np.arange(len(points)), first], 0.0, None)
    held /= held.sum(axis=1, keepdims=True)
    return held, np.where(found, candidates[np.arange(len(points)), first], -1)
