"""Finding the surface nodes under a robot's contact polygon (the print P of eq. 27)."""

from __future__ import annotations

import numpy as np

from .errors import PrintError
from .mesh import TetMesh

__all__ = ["nodes_in_polygon"]


def nodes_in_polygon(mesh: TetMesh, polygon_in_body, tolerance: float = 1e-6) -> np.ndarray:
    """Surface nodes lying on a planar polygon.

    Parameters
    ----------
    mesh : TetMesh
    polygon_in_body : (k, 3) float
        Vertices of a planar polygon (convex or not, not self-intersecting) in order,
        metres, body frame: the robot's contact surface placed on the body surface.
    tolerance : float, optional
        Metres: largest distance of a node to the polygon's plane, and of a node
        outside the polygon to its boundary, for the node to count.

    Returns
    -------
    (p,) int
        Sorted ids of the surface nodes on the plane and inside (or on the boundary
        of) the polygon.

    Raises
    ------
    PrintError
        Fewer than 3 vertices, NaN, degenerate (collinear) or non-planar polygon,
        repeated consecutive vertices, or a self-intersecting polygon (edges that
        cross, touch or fold back), whose inside is not defined.

    Examples
    --------
    >>> from fem import box_mesh
    >>> mesh = box_mesh((1, 1, 1), (2, 2, 2))
    >>> nodes_in_polygon(mesh, [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]).size
    9
    """
    poly = np.asarray(polygon_in_body, dtype=float)
    if poly.ndim != 2 or poly.shape[1] != 3 or poly.shape[0] < 3:
        raise PrintError(f"polygon must have shape (k >= 3, 3), got {poly.shape}")
    if not np.all(np.isfinite(poly)):
        raise PrintError("polygon contains NaN or inf")
    centre = poly.mean(axis=0)
    _, singular, vt = np.linalg.svd(poly - centre)
    if singular[1] <= 1e-12 * max(singular[0], 1e-300):
        raise PrintError("polygon is degenerate: its vertices are collinear or coincident")
    normal = vt[2]
    off_plane = np.abs((poly - centre) @ normal)
    if off_plane.max() > tolerance:
        raise PrintError(
            f"polygon is not planar: vertex {int(off_plane.argmax())} is {off_plane.max():.3g} m "
            f"off its best-fit plane (tolerance {tolerance:g} m)"
        )
    basis = vt[:2].T  # (3, 2) in-plane axes
    v = (poly - centre) @ basis  # (k, 2)
    _check_simple_polygon(v)
    candidates = mesh.surface_nodes
    rel = mesh.nodes[candidates] - centre
    on_plane = np.abs(rel @ normal) <= tolerance
    candidates, rel = candidates[on_plane], rel[on_plane]
    p = rel @ basis  # (n, 2)
    a, b = v, np.roll(v, -1, axis=0)
    # Crossing-number test against every edge at once: (n, k) arrays.
    px, py = p[:, :1], p[:, 1:]
    straddles = (a[:, 1] > py) != (b[:, 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = (straddles & (px < x_cross)).sum(axis=1) % 2 == 1
    # Distance to each edge segment, so boundary nodes count within tolerance.
    edge = b - a
    t = np.clip(((p[:, None, :] - a) * edge).sum(axis=2) / (edge**2).sum(axis=1), 0.0, 1.0)
    nearest = a + t[:, :, None] * edge
    on_boundary = (np.linalg.norm(p[:, None, :] - nearest, axis=2) <= tolerance).any(axis=1)
    return np.sort(candidates[inside | on_boundary])


def _cross(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    return u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]


def _check_simple_polygon(v: np.ndarray) -> None:
    """Refuse a polygon whose boundary meets itself (the crossing-number test would
    then count a node "inside" by parity alone, e.g. in the empty middle of a bow tie).

    Parameters
    ----------
    v : (k, 2) float
        Vertices in order, metres, in the polygon's plane.

    Raises
    ------
    PrintError
        Naming the first repeated vertex, folded-back vertex or pair of meeting edges.
    """
    k = v.shape[0]
    a, b = v, np.roll(v, -1, axis=0)
    edge = b - a
    scale = float(np.ptp(v, axis=0).max())
    length_tol = 1e-9 * scale
    # Cross products are areas: compare them with length_tol times the polygon size.
    area_tol = length_tol * scale
    short = np.flatnonzero(np.linalg.norm(edge, axis=1) <= length_tol)
    if short.size:
        i = int(short[0])
        raise PrintError(f"polygon vertices {i} and {(i + 1) % k} coincide; remove the repeated vertex")
    following = np.roll(edge, -1, axis=0)
    folded = np.flatnonzero((np.abs(_cross(edge, following)) <= area_tol * 1e3) & ((edge * following).sum(axis=1) < 0))
    if folded.size:
        i = int((folded[0] + 1) % k)
        raise PrintError(
            f"polygon folds back on itself at vertex {i} (its two edges overlap); give the vertices in "
            "order around the print, without spikes"
        )
    first, second = np.triu_indices(k, 2)
    keep = ~((first == 0) & (second == k - 1))  # edges k-1 and 0 share vertex 0
    first, second = first[keep], second[keep]
    if first.size == 0:
        return
    p1, p2, q1, q2 = a[first], b[first], a[second], b[second]

    def side(origin, direction, point):
        value = _cross(direction - origin, point - origin)
        return np.where(np.abs(value) <= area_tol, 0.0, np.sign(value))

    def on_segment(start, end, point):
        low, high = np.minimum(start, end) - length_tol, np.maximum(start, end) + length_tol
        return np.all((point >= low) & (point <= high), axis=1)

    s1, s2 = side(q1, q2, p1), side(q1, q2, p2)
    s3, s4 = side(p1, p2, q1), side(p1, p2, q2)
    meet = (s1 * s2 < 0) & (s3 * s4 < 0)
    meet |= (s1 == 0) & on_segment(q1, q2, p1)
    meet |= (s2 == 0) & on_segment(q1, q2, p2)
    meet |= (s3 == 0) & on_segment(p1, p2, q1)
    meet |= (s4 == 0) & on_segment(p1, p2, q2)
    if meet.any():
        i, j = int(first[meet][0]), int(second[meet][0])
        raise PrintError(
            f"polygon is self-intersecting: edge {i}-{(i + 1) % k} meets edge {j}-{(j + 1) % k}; "
            "give the vertices in order around the print"
        )
