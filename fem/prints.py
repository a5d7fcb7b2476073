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
        Fewer than 3 vertices, NaN, degenerate (collinear) or non-planar polygon.

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
    candidates = mesh.surface_nodes
    rel = mesh.nodes[candidates] - centre
    on_plane = np.abs(rel @ normal) <= tolerance
    candidates, rel = candidates[on_plane], rel[on_plane]
    basis = vt[:2].T  # (3, 2) in-plane axes
    p = rel @ basis  # (n, 2)
    v = (poly - centre) @ basis  # (k, 2)
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
