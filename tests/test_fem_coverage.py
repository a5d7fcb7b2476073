"""A print's coverage of the surface nodes, and the coupling of partly covered nodes.

:func:`fem.print_coverage` gives every surface node whose shape function a convex
polygon covers, with the covered share of its integral; :class:`fem.ContactPatch` couples
a partly covered node through a series compliance ``(1 - w) / w C_ii``. Checked
here with quantities the library does not compute the same way: the covered areas
add up to the polygon's area, coverage moves continuously with the polygon, and
the coupled forces load the full FEM system so that each link point moves by its
node's motion (a sparse solve of the whole body) plus its coupling's stretch.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fem
from fem.prints import MINIMUM_COVERAGE

TOP = 0.1


@pytest.fixture(scope="module")
def pad():
    """A 0.4 x 0.4 x 0.1 m pad (top nodes every 25 mm), base fixed."""
    mesh = fem.box_mesh((0.4, 0.4, TOP), (16, 16, 4))
    body = fem.DeformableBody(mesh, fem.LinearElasticMaterial(1e6, 0.45), np.flatnonzero(mesh.nodes[:, 2] == 0.0))
    return body


def _rectangle(centre, half, angle_deg):
    a = math.radians(angle_deg)
    rotation = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * np.asarray(half) @ rotation.T + np.asarray(centre)
    return np.column_stack([corners, np.full(4, TOP)])


def _top_supports(mesh):
    """Each node's shape function integral on the top face (a third of each top triangle)."""
    top = np.isclose(mesh.nodes[mesh.surface_triangles][:, :, 2], TOP).all(axis=1)
    areas = np.zeros(mesh.n_nodes)
    np.add.at(areas, mesh.surface_triangles[top].ravel(), np.repeat(mesh.surface_areas[top] / 3.0, 3))
    return areas


@pytest.mark.parametrize("angle", [0.0, 17.0, 30.0])
@pytest.mark.parametrize("shift", [0.0, 0.004, 0.0125])
def test_covered_shares_add_up_to_the_polygon_area(pad, angle, shift):
    polygon = _rectangle((0.2 + shift, 0.2 + 0.5 * shift), (0.1, 0.06), angle)
    ids, coverage = fem.print_coverage(pad.mesh, polygon)
    covered = float((coverage * _top_supports(pad.mesh)[ids]).sum())
    # Left out: nodes whose shape function is covered by less than MINIMUM_COVERAGE,
    # a few dozen at most along the perimeter.
    assert covered == pytest.approx(0.2 * 0.12, abs=40 * MINIMUM_COVERAGE * 0.025**2)
    assert covered <= 0.2 * 0.12 + 1e-15


def test_a_lower_least_coverage_keeps_the_same_nodes_and_the_barely_covered_ones(pad):
    # Its right edge 3 mm past a row of nodes: the next row's shape functions covered by
    # 0.0055 (0.0019 at the ends), under MINIMUM_COVERAGE.
    polygon = _rectangle((0.2 + 0.003, 0.2), (0.1, 0.06), 0.0)
    ids, coverage = fem.print_coverage(pad.mesh, polygon)
    more, more_coverage = fem.print_coverage(pad.mesh, polygon, minimum=1e-3)
    kept = np.isin(more, ids)
    np.testing.assert_array_equal(more[kept], ids)
    np.testing.assert_array_equal(more_coverage[kept], coverage)
    assert kept.sum() < len(more) and (more_coverage[~kept] < MINIMUM_COVERAGE).all()
    assert (more_coverage[~kept] >= 1e-3).all()
    covered = lambda i, w: float((w * _top_supports(pad.mesh)[i]).sum())
    assert covered(ids, coverage) < covered(more, more_coverage) <= 0.2 * 0.12 + 1e-15
    for minimum in (0.0, -0.1, 1.5, float("nan")):
        with pytest.raises(fem.PrintError, match=r"a print's least coverage must be in \(0, 1\], got"):
            fem.print_coverage(pad.mesh, polygon, minimum=minimum)


def test_nodes_inside_are_fully_covered_and_the_ring_partly(pad):
    polygon = _rectangle((0.2, 0.2), (0.1, 0.06), 17.0)
    ids, coverage = fem.print_coverage(pad.mesh, polygon)
    inside = fem.nodes_in_polygon(pad.mesh, polygon)
    position = {int(n): i for i, n in enumerate(ids)}
    assert set(inside.tolist()) < set(ids.tolist())  # the ring adds nodes
    # A node at least a cell's reach (25 mm diagonal 35 mm) inside the edges is fully covered.
    deep = fem.nodes_in_polygon(pad.mesh, _rectangle((0.2, 0.2), (0.1 - 0.04, 0.06 - 0.04), 17.0))
    assert np.all(coverage[[position[int(n)] for n in deep]] == 1.0)
    ring = np.setdiff1d(ids, inside)
    assert np.all(coverage[[position[int(n)] for n in ring]] < 0.5)
    assert np.all((coverage > 0.0) & (coverage <= 1.0))


def test_coverage_moves_continuously_with_the_polygon(pad):
    # Exact clipping: a 1 um move changes no node's coverage by more than the sliver it
    # sweeps (perimeter x 1 um over a cell, far below 1e-3), where the nodes inside a
    # polygon change by whole nodes.
    before = fem.print_coverage(pad.mesh, _rectangle((0.2, 0.2), (0.1, 0.06), 30.0))
    after = fem.print_coverage(pad.mesh, _rectangle((0.2 + 1e-6, 0.2), (0.1, 0.06), 30.0))
    common, i, j = np.intersect1d(before[0], after[0], return_indices=True)
    assert np.abs(before[1][i] - after[1][j]).max() < 1e-3
    changed = np.setxor1d(before[0], after[0])
    assert changed.size == 0 or max(before[1].min(), after[1].min()) < 2e-3


def test_the_reach_is_how_far_outside_the_polygon_its_covered_nodes_lie(pad):
    # Top nodes every 25 mm; a node's shape function reaches a pitch along the axes. x
    # from 0.11 to 0.31: the nodes at x = 0.10 lie 10 mm outside, those at 0.325 reach
    # 10 mm into it and lie 15 mm outside; y from 0.14 to 0.26: the rows at 0.125 and
    # 0.275 reach 10 mm into it, 15 mm outside; the corner nodes (0.325, 0.125) and
    # (0.325, 0.275) reach the corners (covered by 0.016, over MINIMUM_COVERAGE):
    # 15 sqrt(2) mm out.
    rectangle = np.array([[0.11, 0.14, TOP], [0.31, 0.14, TOP], [0.31, 0.26, TOP], [0.11, 0.26, TOP]])
    assert fem.coverage_reach(pad.mesh, rectangle) == pytest.approx(0.015 * math.sqrt(2.0), abs=1e-12)
    assert fem.coverage_reach(pad.mesh, rectangle[::-1]) == pytest.approx(0.015 * math.sqrt(2.0), abs=1e-12)
    narrower = rectangle + [[0, 0.002, 0], [0, 0.002, 0], [0, -0.002, 0], [0, -0.002, 0]]  # y 0.142 to 0.258
    assert fem.coverage_reach(pad.mesh, narrower) == pytest.approx(math.hypot(0.015, 0.017), abs=1e-12)
    on_nodes = np.array([[0.1, 0.15, TOP], [0.3, 0.15, TOP], [0.3, 0.25, TOP], [0.1, 0.25, TOP]])
    assert fem.coverage_reach(pad.mesh, on_nodes) == pytest.approx(0.0, abs=1e-12)  # every covered node on or in it
    # Turned, the ring lies up to a cell's diagonal out.
    assert 0.0 < fem.coverage_reach(pad.mesh, _rectangle((0.2, 0.2), (0.1, 0.06), 17.0)) < 0.025 * math.sqrt(2.0) + 1e-12


def test_a_concave_polygon_is_refused(pad):
    arrow = np.array([[0.1, 0.1, TOP], [0.3, 0.1, TOP], [0.2, 0.15, TOP], [0.3, 0.3, TOP], [0.1, 0.3, TOP]])
    with pytest.raises(fem.PrintError, match="not convex"):
        fem.print_coverage(pad.mesh, arrow)


def test_coupled_forces_load_the_full_system_to_the_link_motion(pad):
    polygon = _rectangle((0.2, 0.2), (0.1, 0.06), 30.0)
    ids, coverage = fem.print_coverage(pad.mesh, polygon)
    patch = pad.contact_patch(ids, coverage)
    rng = np.random.default_rng(0)
    motion = np.tile([0.0005, -0.0002, -0.004], (len(ids), 1)) + 1e-4 * rng.standard_normal((len(ids), 3))
    forces = patch.reaction_forces(motion)  # on the robot, body frame
    nodes = pad.displacement_under_loads(ids, -forces)[ids]  # the whole body, one sparse solve
    stretch = (patch.coupling_compliance @ -forces.ravel()).reshape(-1, 3)
    np.testing.assert_allclose(nodes + stretch, motion, atol=1e-9 * np.abs(motion).max())
    # Its blocks, node by node, are the whole of D (what the solver multiplies by).
    by_blocks = np.einsum("pij,pj->pi", patch.coupling_blocks, -forces)
    np.testing.assert_allclose(by_blocks, stretch, rtol=0.0, atol=1e-12 * np.abs(stretch).max())
    off_diagonal = patch.coupling_compliance.reshape(len(ids), 3, len(ids), 3).copy()
    off_diagonal[np.arange(len(ids)), :, np.arange(len(ids)), :] = 0.0
    assert not off_diagonal.any()
    # Fully covered nodes follow the link; the coupling stretches only where cells are cut.
    full = coverage == 1.0
    np.testing.assert_allclose(nodes[full], motion[full], atol=1e-9 * np.abs(motion).max())
    assert np.abs(stretch[~full]).max() > 1e-6


def test_a_fully_covered_print_is_the_papers_print_bit_for_bit(pad):
    ids = fem.nodes_in_polygon(pad.mesh, _rectangle((0.2, 0.2), (0.1, 0.06), 0.0))
    plain = pad.contact_patch(ids).reaction_matrix()
    covered = pad.contact_patch(ids, np.ones(len(ids))).reaction_matrix()
    assert np.array_equal(plain, covered)


def test_the_print_force_barely_depends_on_where_the_print_lies_on_the_mesh(pad):
    # The same rectangle anywhere on the lattice: the nodes inside it take whole rows
    # (aligned: one more row on each side), the covered shape functions take its area.
    forces_inside, forces_covered = [], []
    press = np.array([0.0, 0.0, -0.002])
    for shift in (0.0, 0.005, 0.0125, 0.02):
        polygon = _rectangle((0.2 + shift, 0.2 + shift), (0.1, 0.05), 0.0)
        inside = fem.nodes_in_polygon(pad.mesh, polygon)
        forces_inside.append(pad.contact_patch(inside).reaction_forces(np.tile(press, (len(inside), 1)))[:, 2].sum())
        ids, coverage = fem.print_coverage(pad.mesh, polygon)
        patch = pad.contact_patch(ids, coverage)
        forces_covered.append(patch.reaction_forces(np.tile(press, (len(ids), 1)))[:, 2].sum())
    spread = lambda values: np.ptp(values) / np.mean(values)  # noqa: E731
    # Measured 2.7 % against 33 % for the nodes inside (a print 8 x 4 cells wide); 3.2 %
    # over shifts spanning two pitches, the period of the mirrored cells (by median-dual
    # cells before 2026-12-06: 4.2 and 5.1 %; one diagonal everywhere, before
    # 2026-12-03: 2.7 and 4.1 %).
    assert spread(forces_covered) < 0.04
    assert spread(forces_inside) > 5 * spread(forces_covered)


def test_bad_coverage_is_refused_and_the_traction_method_takes_none(pad):
    ids, coverage = fem.print_coverage(pad.mesh, _rectangle((0.2, 0.2), (0.1, 0.06), 30.0))
    with pytest.raises(fem.PrintError, match=r"coverage must have shape"):
        pad.contact_patch(ids, coverage[:-1])
    with pytest.raises(fem.PrintError, match=r"coverage fractions must lie in \(0, 1\]"):
        pad.contact_patch(ids, np.where(coverage < 1.0, 0.0, 1.0))
    with pytest.raises(fem.PrintError, match="traction method"):
        pad.contact_patch(ids, coverage).reaction_matrix("traction")


@pytest.mark.parametrize("sides", [5, 6, 8])
def test_convex_polygons_of_any_vertex_count_are_covered_by_their_area(pad, sides):
    # A point foot's print is an octagon: every vertex count must pass the convexity check.
    angles = 2 * np.pi * np.arange(sides) / sides + 0.1
    polygon = np.column_stack([0.2 + 0.07 * np.cos(angles), 0.2 + 0.07 * np.sin(angles), np.full(sides, TOP)])
    ids, coverage = fem.print_coverage(pad.mesh, polygon)
    area = 0.5 * sides * 0.07**2 * np.sin(2 * np.pi / sides)
    covered = float((coverage * _top_supports(pad.mesh)[ids]).sum())
    assert covered == pytest.approx(area, abs=40 * MINIMUM_COVERAGE * 0.025**2)


def test_nodes_in_a_concave_polygon_leave_out_its_notch(pad):
    # An L: a node in the notch lies left of two of the polygon's edges (two crossings).
    ell = np.array([[0.1, 0.1], [0.3, 0.1], [0.3, 0.2], [0.2, 0.2], [0.2, 0.3], [0.1, 0.3]])
    ids = fem.nodes_in_polygon(pad.mesh, np.column_stack([ell, np.full(6, TOP)]))
    points = pad.mesh.nodes[ids, :2]
    notch = (points[:, 0] > 0.2 + 1e-9) & (points[:, 1] > 0.2 + 1e-9)
    assert not notch.any()
    top = np.flatnonzero(np.isclose(pad.mesh.nodes[:, 2], TOP))
    grid = pad.mesh.nodes[top, :2]
    in_box = np.all((grid >= 0.1 - 1e-9) & (grid <= 0.3 + 1e-9), axis=1)
    in_notch = (grid[:, 0] > 0.2 + 1e-9) & (grid[:, 1] > 0.2 + 1e-9)
    assert set(ids.tolist()) == set(top[in_box & ~in_notch].tolist())


def _counter_clockwise(corners):
    """(k, 2) corners of a convex polygon, counter-clockwise."""
    a, b = corners[1] - corners[0], corners[2] - corners[1]
    return corners if a[0] * b[1] - a[1] * b[0] > 0.0 else corners[::-1]


def _inside_convex(points, polygon):
    """(n,) bool: 2-D points inside a convex counter-clockwise polygon (k, 2)."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    rel = points[:, None, :] - polygon[None]
    return (edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0] >= 0.0).all(axis=1)


@pytest.mark.parametrize("centre, half, turned, reverse", [
    ((0.204, 0.202), (0.1, 0.06), 17.0, False),
    ((0.204, 0.202), (0.1, 0.06), 17.0, True),  # the other way round: the triangles seen clockwise
    ((0.07, 0.2), (0.06, 0.04), 17.0, False),  # reaching the pad's rim (x = 0), whose nodes the side faces share
], ids=["turned", "reversed", "at-the-rim"])
def test_each_nodes_covered_share_is_what_sampling_finds(pad, centre, half, turned, reverse):
    """Sampling the top face on a fine lattice, no clipping: a point of a triangle
    weighs for each vertex by its barycentric coordinate, the vertex's shape function
    there. The sampled covered share of every partly covered node's shape function
    (over the top face only) matches fem's exact clipping, and every node kept is covered
    at least MINIMUM_COVERAGE."""
    polygon = _rectangle(centre, half, turned)
    if reverse:
        polygon = polygon[::-1]
    ids, coverage = fem.print_coverage(pad.mesh, polygon)
    mesh = pad.mesh
    top = np.isclose(mesh.nodes[mesh.surface_triangles][:, :, 2], TOP).all(axis=1)
    triangles = mesh.surface_triangles[top]
    near = np.abs(mesh.nodes[triangles][:, :, :2].mean(axis=1) - centre).max(axis=1) < max(half) + 0.06
    # Cells whose every top triangle is sampled.
    sampled = np.bincount(triangles[near].ravel(), minlength=mesh.n_nodes)
    whole = (sampled > 0) & (sampled == np.bincount(triangles.ravel(), minlength=mesh.n_nodes))
    triangles = triangles[near]
    # A shifted square lattice folded onto the triangle (u + v > 1 -> 1 - u, 1 - v): a
    # uniform density whose points never tie two barycentric coordinates (the shifts
    # 0.31 and 0.57 keep u = v, 2u + v = 1 and u + 2v = 1 off the lattice), 100^2 points
    # a triangle (triangles have equal areas on this grid).
    n = 100
    u, v = np.meshgrid((np.arange(n) + 0.31) / n, (np.arange(n) + 0.57) / n, indexing="ij")
    folded = u + v > 1.0
    u, v = np.where(folded, 1.0 - u, u).ravel(), np.where(folded, 1.0 - v, v).ravel()
    barycentric = np.broadcast_to(np.stack([1.0 - u - v, u, v], axis=1), (len(triangles), u.size, 3))
    points = np.einsum("tsk,tkj->tsj", barycentric, mesh.nodes[triangles][:, :, :2]).reshape(-1, 2)
    inside = _inside_convex(points, _counter_clockwise(polygon[:, :2])).reshape(len(triangles), -1)
    # Each node's sampled integral of its shape function, over the polygon and in all.
    covered, total = np.zeros(mesh.n_nodes), np.zeros(mesh.n_nodes)
    np.add.at(covered, triangles.ravel(), np.einsum("ts,tsk->tk", inside, barycentric).ravel())
    np.add.at(total, triangles.ravel(), barycentric.sum(axis=1).ravel())
    checked = 0
    for node, w in zip(ids.tolist(), coverage):
        if not whole[node]:
            continue
        sampled_w = covered[node] / total[node]
        assert sampled_w >= MINIMUM_COVERAGE - 0.002
        if w < 1.0:
            assert sampled_w == pytest.approx(w, abs=0.003)
            checked += 1
    assert checked >= 20  # the partly covered ring of a 0.2 x 0.12 m (0.12 x 0.08 m) print on 25 mm cells
    # Nodes whose shape function the polygon misses are left out.
    for node in np.setdiff1d(np.flatnonzero(whole), ids).tolist():
        assert covered[node] / total[node] < MINIMUM_COVERAGE + 0.002


def _consistent_loads(mesh, polygon, pressure, samples=400, seed=0):
    """Monte Carlo consistent loads ``int N_i p dA`` of a pressure ``p(x, y)`` over a
    rectangle (its corners 0 and 2), by sampling points and their triangles' shape
    functions with scipy's Delaunay of the top nodes (not the library's code)."""
    import scipy.spatial

    top = np.flatnonzero(np.isclose(mesh.nodes[:, 2], TOP))
    delaunay = scipy.spatial.Delaunay(mesh.nodes[top, :2])
    rng = np.random.default_rng(seed)
    low, high = np.asarray(polygon)[0, :2], np.asarray(polygon)[2, :2]
    points = low + rng.random((samples * samples // 10, 2)) * (high - low)
    simplex = delaunay.find_simplex(points)
    transform = delaunay.transform[simplex]
    local = np.einsum("nij,nj->ni", transform[:, :2], points - transform[:, 2])
    shares = np.column_stack([local, 1.0 - local.sum(axis=1)])
    loads = np.zeros(mesh.n_nodes)
    np.add.at(loads, top[delaunay.simplices[simplex]].ravel(), (shares * pressure(points)[:, None]).ravel())
    return loads


def test_a_pressure_fit_is_zero_for_a_pressures_loads_and_not_for_a_pivot_past_the_edge(pad):
    """fem.pressure_fit on the pad (top nodes every 25 mm), a 0.2 x 0.12 m print whose right edge
    lies 5 mm past a row of nodes: the consistent loads of a non-negative pressure inside it (a
    uniform one, one rising toward the right edge; Monte Carlo over the top's own Delaunay
    triangulation, which may split cells the other way, so to 2 %) fit; loads on the row past the
    edge with the row inside it unloaded, as a link pivoting onto that row gives, do not."""
    polygon = _rectangle((0.2, 0.2), (0.1, 0.06), 0.0) + np.array([0.005, 0.0, 0.0])
    ids, _ = fem.print_coverage(pad.mesh, polygon, minimum=1e-3)
    for pressure in (lambda p: np.ones(len(p)), lambda p: np.clip(p[:, 0] - 0.25, 0.0, None)):
        loads = _consistent_loads(pad.mesh, polygon, pressure)[ids]
        assert fem.pressure_fit(pad.mesh, polygon, ids, loads) < 0.02
    x = pad.mesh.nodes[ids, 0]
    pivot = np.where(np.isclose(x, 0.325), 1.0, 0.0) + np.where(x < 0.29, 0.5, 0.0)  # the row at 0.3 lifted
    assert fem.pressure_fit(pad.mesh, polygon, ids, pivot) > 0.05
    assert fem.pressure_fit(pad.mesh, polygon, ids, np.zeros(len(ids))) == 0.0


def test_a_pressure_fit_refuses_shapes_that_do_not_match_and_a_polygon_off_the_mesh(pad):
    polygon = _rectangle((0.2, 0.2), (0.1, 0.06), 0.0)
    ids, _ = fem.print_coverage(pad.mesh, polygon)
    with pytest.raises(fem.FemError, match=r"node_ids and loads must be \(p,\) alike, got \(\d+,\) and \(3,\)"):
        fem.pressure_fit(pad.mesh, polygon, ids, np.ones(3))
    with pytest.raises(fem.PrintError, match=r"polygon must have shape \(k >= 3, 3\), got \(2, 3\)"):
        fem.pressure_fit(pad.mesh, polygon[:2], ids, np.ones(len(ids)))
    with pytest.raises(fem.FemError, match="the polygon covers no surface triangle of the mesh facing its normal"):
        fem.pressure_fit(pad.mesh, polygon + np.array([0.0, 0.0, 0.01]), ids, np.ones(len(ids)))  # 1 cm above the top
    with pytest.raises(fem.PrintError, match=r"a print's least coverage must be in \(0, 1\], got None"):
        fem.print_coverage(pad.mesh, polygon, minimum=None)


def test_pressure_corners_are_points_of_the_polygon_whose_loads_span_a_pressures(pad):
    """fem.pressure_corners on a turned print on the pad: each point lies in the polygon, its
    shares are non-negative, add up to 1 and give back its position from its triangle's
    nodes, and its loads go to nodes the polygon covers; any non-negative combination of the
    points' loads fits a pressure to rounding (fem.pressure_fit, whose own test checks it
    against Monte Carlo consistent loads); a bad polygon is refused as for print_coverage."""
    polygon = _rectangle((0.2, 0.21), (0.1, 0.06), 17.0)
    points, ids, shares = fem.pressure_corners(pad.mesh, polygon)
    assert points.shape == (len(ids), 3) and ids.shape == shares.shape == (len(points), 3)
    assert np.allclose(points[:, 2], TOP) and (shares >= 0.0).all() and np.allclose(shares.sum(axis=1), 1.0)
    assert np.allclose(np.einsum("nj,njk->nk", shares, pad.mesh.nodes[ids]), points, atol=1e-12)
    edges = polygon[[1, 2, 3, 0], :2] - polygon[:, :2]
    outward = np.column_stack([edges[:, 1], -edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
    past = np.einsum("ek,nek->ne", outward, points[:, None, :2] - polygon[None, :, :2])
    assert past.max() < 1e-12  # inside every edge (counter-clockwise corners)
    covered, _ = fem.print_coverage(pad.mesh, polygon, minimum=1e-6)
    rng = np.random.default_rng(3)
    loads = np.zeros(pad.mesh.n_nodes)
    np.add.at(loads, ids.ravel(), (shares * rng.random(len(points))[:, None]).ravel())
    assert set(np.flatnonzero(loads)) <= set(covered.tolist())
    assert fem.pressure_fit(pad.mesh, polygon, covered, loads[covered]) < 1e-12
    with pytest.raises(fem.PrintError, match="polygon is self-intersecting: edge 0-1 meets edge 2-3"):
        fem.pressure_corners(pad.mesh, polygon[[0, 2, 1, 3]])
    with pytest.raises(fem.FemError, match="the polygon covers no surface triangle of the mesh facing its normal"):
        fem.pressure_corners(pad.mesh, polygon + np.array([0.0, 0.0, 0.01]))


def test_shared_nodes_follow_the_print_covering_more_of_them_and_ties_the_other():
    keep, other_keep = fem.split_shared_nodes([4, 5, 6], [0.3, 0.5, 0.2], [5, 6, 7], [0.5, 0.1, 1.0])
    assert keep.tolist() == [True, False, True] and other_keep.tolist() == [True, False, True]
    keep, other_keep = fem.split_shared_nodes([1], [0.5], [2], [0.5])  # nothing shared
    assert keep.tolist() == [True] and other_keep.tolist() == [True]
