"""Finding the surface nodes under a robot's contact polygon (the print P of eq. 27).

:func:`nodes_in_polygon` gives the nodes inside the polygon (the paper's print).
:func:`print_coverage` gives every node whose shape function the polygon covers, even
in part, with the covered share: a print whose edges cross cells at any place,
as a robot's prints do, is then held by its true area rather than by the node rows
that happen to lie inside it (see :class:`fem.ContactPatch`'s ``coverage``).
"""

from __future__ import annotations

import weakref

import numpy as np

from .errors import PrintError
from .mesh import TetMesh

__all__ = ["clip_polygon", "coverage_reach", "nodes_in_polygon", "print_coverage", "split_shared_nodes"]

# The prints met most recently on each mesh, by polygon: a planner asks for the same
# print in every stance that keeps it, and a solve in each of its stages.
_COVERAGE_CACHE: "weakref.WeakKeyDictionary[TetMesh, dict]" = weakref.WeakKeyDictionary()
_COVERAGE_CACHE_SIZE = 256

#: Nodes whose shape function the polygon covers less than this are left out of a print
#: (:func:`print_coverage`'s default): they would carry about a hundredth of a full node's
#: share, and their large coupling compliance only adds rounding to the contact solve.
MINIMUM_COVERAGE = 0.01


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
    centre, normal, basis, v = _polygon_frame(polygon_in_body, tolerance)
    candidates = mesh.surface_nodes
    rel = mesh.nodes[candidates] - centre
    on_plane = np.abs(rel @ normal) <= tolerance
    candidates, rel = candidates[on_plane], rel[on_plane]
    p = rel @ basis  # (n, 2)
    # Only nodes within the polygon's bounding box, widened by twice the tolerance, can
    # be inside or near its boundary: the tests below, of every node against every edge,
    # then run on a print's nodes rather than on the whole face's (15 of 1,968 surface
    # nodes for a palm on hand-on-cube's cube: 0.66 ms a print before). Each node's
    # numbers are its own, so the answer is the same.
    near = np.all((p >= v.min(axis=0) - 2.0 * tolerance) & (p <= v.max(axis=0) + 2.0 * tolerance), axis=1)
    candidates, p = candidates[near], p[near]
    a, b = v, np.roll(v, -1, axis=0)
    # Crossing-number test against every edge at once: (n, k) arrays.
    px, py = p[:, :1], p[:, 1:]
    straddles = (a[:, 1] > py) != (b[:, 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = (straddles & (px < x_cross)).sum(axis=1) % 2 == 1
    # Distance to each edge segment, so boundary nodes count within tolerance.
    on_boundary = (_edge_distances(p, v) <= tolerance).any(axis=1)
    return np.sort(candidates[inside | on_boundary])


def coverage_reach(mesh: TetMesh, polygon_in_body, tolerance: float = 1e-6) -> float:
    """How far outside a convex polygon the nodes of its :func:`print_coverage` lie.

    A partly covered node may lie up to a cell's diagonal outside the polygon (its
    shape function reaching in); its force acts there. This is the largest such
    distance, in the polygon's plane.

    Parameters
    ----------
    mesh, polygon_in_body, tolerance
        As :func:`print_coverage`.

    Returns
    -------
    float
        Metres; 0 when every node lies in the polygon.

    Raises
    ------
    PrintError
        As :func:`print_coverage`.
    """
    ids, _ = print_coverage(mesh, polygon_in_body, tolerance)
    centre, _, basis, v = _polygon_frame(polygon_in_body, tolerance)
    p = (mesh.nodes[ids] - centre) @ basis  # (n, 2)
    side = _cross(np.roll(v, -1, axis=0) - v, p[:, None, :] - v)  # (n, k)
    inside = (side >= 0.0).all(axis=1) | (side <= 0.0).all(axis=1)  # a convex polygon, either orientation
    return float(np.where(inside, 0.0, _edge_distances(p, v).min(axis=1)).max(initial=0.0))


def _edge_distances(points: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n, k) distances of 2-D points (n, 2) to each edge segment of a polygon (k, 2)."""
    edge = np.roll(v, -1, axis=0) - v
    t = np.clip(((points[:, None, :] - v) * edge).sum(axis=2) / (edge**2).sum(axis=1), 0.0, 1.0)
    nearest = v + t[:, :, None] * edge
    return np.linalg.norm(points[:, None, :] - nearest, axis=2)


def print_coverage(mesh: TetMesh, polygon_in_body, tolerance: float = 1e-6,
                   minimum: float = MINIMUM_COVERAGE) -> tuple[np.ndarray, np.ndarray]:
    """Surface nodes whose shape function a convex planar polygon covers, and the share covered.

    A surface node's coverage is the part of its linear shape function's integral over
    the surface that lies inside the polygon, ``w_i = int_P N_i dA / int_S N_i dA``:
    the row sums of the mortar matrix between the print and the surface, lumped. A
    uniform pressure on the polygon puts on each node the force ``p w_i int_S N_i``, and
    ``sum_i w_i int_S N_i dA`` is the polygon's area. Only the triangles on the polygon's
    plane count (within ``tolerance``, facing along its normal), so a node on the
    face's rim stands for its part of that face. The covered part of each triangle is
    clipped exactly, so the coverage changes continuously as the polygon moves.

    Until 2026-12-06 (session u) a node stood for its median-dual cell (the node, its
    edges' midpoints and its triangles' centroids): a print's edge within half a cell of
    its last row inside then left the row beyond it out, though that row's shape
    functions carry the pressure there. Against converged Q2 forces for twelve solved
    prints (``bench/bench_print_coupling.py``) the shape functions' coverage is within
    3.2 % on the default meshes (the median-dual cells: 5.3 %) and 1.0 % refined twice
    (1.7 %).

    Parameters
    ----------
    mesh : TetMesh
    polygon_in_body : (k, 3) float
        Vertices of a convex planar polygon, in order, metres, body frame.
    tolerance : float, optional
        Metres: largest distance of a surface triangle's vertices to the polygon's
        plane for the triangle to count.
    minimum : float, optional
        The least coverage of a node kept, in (0, 1]: ``MINIMUM_COVERAGE`` by default.

    Returns
    -------
    node_ids : (p,) int
        Sorted ids of the nodes whose coverage is at least ``minimum``.
    coverage : (p,) float
        Covered share of each node's shape function, in (0, 1]; 1 for a node well
        inside. Both read-only: the answers for the 256 polygons last asked on a mesh
        are kept.

    Raises
    ------
    PrintError
        As :func:`nodes_in_polygon`, a polygon that is not convex, or ``minimum`` out of (0, 1].

    Examples
    --------
    >>> from fem import box_mesh
    >>> mesh = box_mesh((1, 1, 1), (4, 4, 4))     # top nodes every 0.25 m
    >>> ids, coverage = print_coverage(mesh, [[0.25, 0.25, 1], [0.75, 0.25, 1], [0.75, 0.75, 1], [0.25, 0.75, 1]])
    >>> ids.size, round(float(coverage.max()), 3)   # the centre node's whole support lies inside
    (9, 1.0)
    """
    if not (isinstance(minimum, (int, float, np.floating)) and 0.0 < minimum <= 1.0):
        raise PrintError(f"a print's least coverage must be in (0, 1], got {minimum!r}")
    key = (np.asarray(polygon_in_body, dtype=float).tobytes(), float(tolerance), float(minimum))
    cached = _COVERAGE_CACHE.setdefault(mesh, {})
    if key in cached:
        return cached[key]
    ids, coverage = _print_coverage(mesh, polygon_in_body, tolerance, minimum)
    ids.setflags(write=False)
    coverage.setflags(write=False)
    if len(cached) >= _COVERAGE_CACHE_SIZE:
        cached.pop(next(iter(cached)))  # the oldest
    cached[key] = (ids, coverage)
    return ids, coverage


def split_shared_nodes(ids, coverage, other_ids, other_coverage) -> tuple[np.ndarray, np.ndarray]:
    """Which nodes two prints keep where their coverages share nodes.

    Prints closer than a cell cover some nodes' shape functions both; a node belongs to
    one print (one link's motion imposed on it), so each such node follows the print
    covering more of it and the other's share of it is dropped (ties to ``other``).

    Parameters
    ----------
    ids, other_ids : (p,) int, (q,) int
        Sorted node ids of two prints (:func:`print_coverage`).
    coverage, other_coverage : (p,) float, (q,) float
        Their coverages.

    Returns
    -------
    keep, other_keep : (p,) bool, (q,) bool
        The nodes each print keeps.

    Examples
    --------
    >>> keep, other_keep = split_shared_nodes([1, 2, 3], [1.0, 0.4, 0.01], [3, 4], [0.2, 1.0])
    >>> keep.tolist(), other_keep.tolist()
    ([True, True, False], [True, True])
    """
    ids, other_ids = np.asarray(ids), np.asarray(other_ids)
    _, here, there = np.intersect1d(ids, other_ids, return_indices=True)
    mine = np.asarray(coverage)[here] > np.asarray(other_coverage)[there]
    keep, other_keep = np.ones(len(ids), dtype=bool), np.ones(len(other_ids), dtype=bool)
    keep[here[~mine]] = False
    other_keep[there[mine]] = False
    return keep, other_keep


def _print_coverage(mesh, polygon_in_body, tolerance, minimum):
    """:func:`print_coverage`, computed."""
    centre, normal, basis, v = convex_polygon_frame(polygon_in_body, tolerance)
    twice_area = float(_cross(v, np.roll(v, -1, axis=0)).sum())
    keep, flat = plane_triangles(mesh, centre, normal, basis, tolerance)
    triangles = mesh.surface_triangles[keep]  # (T', 3), flat (T', 3, 2)
    # int_S N_i dA: a third of each triangle around the node.
    support = np.zeros(mesh.n_nodes)
    np.add.at(support, triangles.ravel(), np.repeat(mesh.surface_areas[keep] / 3.0, 3))
    near = meeting_bounds(flat, v)
    triangles, flat = triangles[near], flat[near]
    clockwise = _cross(flat[:, 1] - flat[:, 0], flat[:, 2] - flat[:, 0]) < 0.0
    flat[clockwise] = flat[clockwise][:, ::-1]  # counter-clockwise, like the polygon
    triangles = np.where(clockwise[:, None], triangles[:, ::-1], triangles)
    # A corner is inside when it lies left of every edge (counter-clockwise polygon).
    edge_start, edge = v, np.roll(v, -1, axis=0) - v
    side = _cross(edge[None, None], flat[:, :, None, :] - edge_start[None, None])  # (T, 3, k)
    slack = 1e-12 * abs(twice_area)
    outside = (side < -slack).all(axis=1).any(axis=1)  # all corners beyond one edge
    inside = (side >= -slack).all(axis=(1, 2))
    # int_P N_i dA: N_i is linear, so over the covered part Q of a triangle it is
    # area(Q) times N_i at Q's centroid; a whole triangle gives a third to each node.
    covered = np.zeros(mesh.n_nodes)
    np.add.at(covered, triangles[inside].ravel(), np.repeat(_polygon_area(flat[inside]) / 3.0, 3))
    corners = [(float(x), float(y)) for x, y in v]
    for t in np.flatnonzero(~inside & ~outside):
        covered[triangles[t]] += _covered_shares(flat[t].tolist(), corners)
    with np.errstate(invalid="ignore", divide="ignore"):
        coverage = np.where(support > 0.0, covered / support, 0.0)
    ids = np.flatnonzero(coverage >= minimum)
    return ids, np.minimum(coverage[ids], 1.0)


def convex_polygon_frame(polygon_in_body, tolerance: float = 1e-6):
    """Centre (3,), unit normal (3,), in-plane axes (3, 2) and counter-clockwise in-plane
    vertices (k, 2) of a checked convex planar polygon (body frame, metres).

    Raises
    ------
    PrintError
        As :func:`nodes_in_polygon`, or a polygon that is not convex.
    """
    centre, normal, basis, v = _polygon_frame(polygon_in_body, tolerance)
    twice_area = float(_cross(v, np.roll(v, -1, axis=0)).sum())
    if twice_area < 0.0:
        v = v[::-1]  # counter-clockwise in the plane's axes
    turns = _cross(np.roll(v, -1, axis=0) - v, np.roll(v, -2, axis=0) - np.roll(v, -1, axis=0))
    if (turns < -1e-12 * abs(twice_area)).any():
        raise PrintError("polygon is not convex; a print's coverage needs a convex contact polygon")
    return centre, normal, basis, v


def plane_triangles(mesh: TetMesh, centre, normal, basis, tolerance: float = 1e-6):
    """The surface triangles facing along ``normal`` whose corners lie within ``tolerance``
    of the plane through ``centre``: their (T',) indices into ``mesh.surface_triangles`` and
    their corners in the plane's axes ``basis`` (T', 3, 2), metres from ``centre``."""
    rel = mesh.nodes[mesh.surface_triangles] - centre  # (T, 3, 3)
    facing = np.abs(mesh.surface_normals @ normal) >= 1.0 - 1e-6
    keep = np.flatnonzero(facing & (np.abs(rel @ normal) <= tolerance).all(axis=1))
    return keep, rel[keep] @ basis


def meeting_bounds(flat, v) -> np.ndarray:
    """(T,) bool: the triangles (T, 3, 2) whose bounding boxes meet the polygon's (k, 2),
    the only ones it can cover."""
    return np.all((flat.max(axis=1) >= v.min(axis=0)) & (flat.min(axis=1) <= v.max(axis=0)), axis=1)


def _polygon_frame(polygon_in_body, tolerance):
    """Centre (3,), unit normal (3,), in-plane axes (3, 2) and in-plane vertices (k, 2)
    of a checked planar, simple polygon."""
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
    return centre, normal, basis, v


def _polygon_area(polygons: np.ndarray) -> np.ndarray:
    """(n,) areas of (n, m, 2) counter-clockwise polygons (shoelace)."""
    if polygons.shape[1] < 3:
        return np.zeros(len(polygons))
    return 0.5 * _cross(polygons, np.roll(polygons, -1, axis=1)).sum(axis=1)


def _covered_shares(triangle: list, corners: list) -> tuple[float, float, float]:
    """The integrals of a triangle's three shape functions (barycentric coordinates) over
    its part inside a convex counter-clockwise polygon: :func:`clip_polygon`, then the
    shoelace formulas for that part's area A and centroid c, each integral being
    ``A N_i(c)`` since ``N_i`` is linear. On Python floats, as :func:`clip_polygon`.

    Parameters
    ----------
    triangle : (3, 2) float
        Counter-clockwise.
    corners : (k, 2) float
        The polygon, convex and counter-clockwise, same frame.
    """
    points = clip_polygon(triangle, corners)
    if len(points) < 3:
        return 0.0, 0.0, 0.0
    twice_area = cx = cy = 0.0
    for (x0, y0), (x1, y1) in zip(points, points[1:] + points[:1]):
        cross = x0 * y1 - x1 * y0
        twice_area += cross
        cx += (x0 + x1) * cross
        cy += (y0 + y1) * cross
    if twice_area <= 0.0:
        return 0.0, 0.0, 0.0
    cx, cy = cx / (3.0 * twice_area), cy / (3.0 * twice_area)
    (ax, ay), (bx, by), (qx, qy) = triangle
    determinant = (bx - ax) * (qy - ay) - (qx - ax) * (by - ay)
    l1 = ((cx - ax) * (qy - ay) - (qx - ax) * (cy - ay)) / determinant
    l2 = ((bx - ax) * (cy - ay) - (cx - ax) * (by - ay)) / determinant
    area = 0.5 * twice_area
    return area * (1.0 - l1 - l2), area * l1, area * l2


def clip_polygon(subject, corners) -> list:
    """The part of a polygon inside a convex counter-clockwise one (Sutherland-Hodgman).

    On Python floats: the polygons have a handful of vertices, where numpy's
    per-call overhead would dominate.

    Parameters
    ----------
    subject : (m, 2) float
        The polygon clipped, in order.
    corners : (k, 2) float
        Convex, counter-clockwise: the clipping polygon, same frame.

    Returns
    -------
    list of (x, y)
        The clipped polygon's vertices, in ``subject``'s order; fewer than three
        when the polygons do not overlap with an area.
    """
    points = [(float(x), float(y)) for x, y in subject]
    corners = [(float(x), float(y)) for x, y in corners]
    for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1]):
        if not points:
            return []
        ex, ey = bx - ax, by - ay
        kept = []
        px, py = points[-1]
        s_previous = ex * (py - ay) - ey * (px - ax)
        for cx, cy in points:
            s_current = ex * (cy - ay) - ey * (cx - ax)
            if s_current >= 0.0:
                if s_previous < 0.0:
                    t = s_previous / (s_previous - s_current)
                    kept.append((px + (cx - px) * t, py + (cy - py) * t))
                kept.append((cx, cy))
            elif s_previous >= 0.0:
                t = s_previous / (s_previous - s_current)
                kept.append((px + (cx - px) * t, py + (cy - py) * t))
            px, py, s_previous = cx, cy, s_current
        points = kept
    return points


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
