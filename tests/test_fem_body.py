"""Deformable body and contact prints: forces, Jacobians, equilibrium, errors."""

import re

import numpy as np
import pytest

from fem import (
    BoundaryError,
    DeformableBody,
    FemError,
    FemWarning,
    LinearElasticMaterial,
    MeshError,
    PrintError,
    TetMesh,
    box_mesh,
    nodes_in_polygon,
    read_mesh,
    von_mises,
    write_pvd,
)

RNG_SEED = 7
MATERIAL = LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4, density=1e3)
TOP_SQUARE = [[0.2, 0.2, 1.0], [0.6, 0.2, 1.0], [0.6, 0.6, 1.0], [0.2, 0.6, 1.0]]


def make_body(mesh, material=MATERIAL, solver="auto"):
    return DeformableBody(mesh, material, np.flatnonzero(mesh.nodes[:, 2] == 0.0), solver=solver)


@pytest.fixture(scope="module")
def cube_mesh():
    """Unit cube, 5x5 cells in x, y, graded toward the top."""
    return box_mesh((1.0, 1.0, 1.0), (5, 5, 4), grading=2.0)


@pytest.fixture(scope="module")
def cube(cube_mesh):
    return make_body(cube_mesh)


@pytest.fixture(scope="module")
def patch(cube):
    return cube.contact_patch(nodes_in_polygon(cube.mesh, TOP_SQUARE))


@pytest.fixture
def displacements(patch):
    """A press with some shear and tilt, seeded."""
    rng = np.random.default_rng(RNG_SEED)
    u = np.tile([0.002, -0.001, -0.01], (patch.n_nodes, 1))
    return u + 1e-3 * rng.normal(size=u.shape)


def assert_rows_match(fd, exact, rtol=1e-6):
    """Central differences against a derivative, row by row: each row within ``rtol``
    of its own largest entry, plus a round-off floor 1e-10 of the whole matrix (the
    forces repeat to ~1e-16 of their size, over a 1e-6 step: ~1e-13 of the entries),
    so a wrong small row cannot hide under the large ones."""
    fd, exact = np.atleast_2d(fd), np.atleast_2d(exact)
    error = np.abs(fd - exact).max(axis=1)
    tolerance = rtol * np.abs(exact).max(axis=1) + 1e-10 * np.abs(exact).max()
    worst = int(np.argmax(error - tolerance))
    assert np.all(error <= tolerance), f"row {worst} off by {error[worst]:.3g} (tolerance {tolerance[worst]:.3g})"


def rotate(vectors, omega):
    """Rotate (T, 3) vectors by the rotation vector omega (Rodrigues)."""
    angle = np.linalg.norm(omega)
    axis = omega / angle
    return (
        vectors * np.cos(angle)
        + np.cross(axis, vectors) * np.sin(angle)
        + np.outer(vectors @ axis, axis) * (1 - np.cos(angle))
    )


# ---------------------------------------------------------------- the print
def test_print_geometry_is_the_square_on_top(patch):
    assert patch.n_nodes == 9
    assert np.all(patch.points[:, 2] == 1.0)
    assert np.allclose(patch.triangle_normals, [0, 0, 1])
    assert patch.triangle_areas.sum() == pytest.approx(0.4 * 0.4)
    assert patch.triangles.max() < patch.n_nodes


def test_condensed_stiffness_is_symmetric_positive_definite(patch):
    s = patch.condensed_stiffness
    assert np.allclose(s, s.T, rtol=0, atol=1e-12 * np.abs(s).max())
    assert np.linalg.eigvalsh(s).min() > 0


def test_condensed_stiffness_equals_explicit_schur_complement(cube, patch):
    k = cube.stiffness.toarray()
    free_nodes = np.flatnonzero(~cube.fixed_mask)
    p_dofs = (3 * patch.node_ids[:, None] + np.arange(3)).ravel()
    others = np.setdiff1d(free_nodes, patch.node_ids)
    f_dofs = (3 * others[:, None] + np.arange(3)).ravel()
    schur = k[np.ix_(p_dofs, p_dofs)] - k[np.ix_(p_dofs, f_dofs)] @ np.linalg.solve(
        k[np.ix_(f_dofs, f_dofs)], k[np.ix_(f_dofs, p_dofs)]
    )
    assert np.abs(patch.condensed_stiffness - schur).max() < 1e-8 * np.abs(schur).max()


def test_pressing_down_pushes_the_robot_up(patch):
    press = np.tile([0.0, 0.0, -0.01], (patch.n_nodes, 1))
    for method in ("consistent", "traction"):
        forces = patch.reaction_forces(press, method=method)
        assert forces[:, 2].sum() > 0
        assert np.all(forces[:, 2] > 0)


def test_displacement_field_matches_print_and_base(cube, patch, displacements):
    u = cube.displacement_field(patch, displacements)
    assert np.array_equal(u[patch.node_ids], displacements)
    assert np.all(u[cube.fixed_nodes] == 0.0)


def test_the_displacement_at_some_nodes_is_the_full_fields_rows_bit_for_bit():
    """``displacement_at`` superposes only the rows it is asked for, from the columns or, past
    256 loaded nodes, one solve: the same bits as those rows of the full field; bad nodes
    are refused with their range."""
    body = make_body(box_mesh((1.0, 1.0, 1.0), (8, 8, 6)))
    rng = np.random.default_rng(RNG_SEED)
    free = np.flatnonzero(~np.isin(np.arange(body.mesh.n_nodes), body.fixed_nodes))
    at = np.sort(rng.choice(body.mesh.n_nodes, 17, replace=False))
    for loaded in (free[:12], free[:300]):
        forces = rng.normal(size=(loaded.size, 3))
        full = body.displacement_under_loads(loaded, forces)
        assert np.array_equal(body.displacement_at(at, loaded, forces), full[at])
    with pytest.raises(FemError, match=re.escape(f"nodes has node id {body.mesh.n_nodes} outside [0, {body.mesh.n_nodes - 1}]")):
        body.displacement_at([body.mesh.n_nodes], free[:2], np.zeros((2, 3)))
    with pytest.raises(FemError, match="nodes must hold integer node ids, got dtype float64"):
        body.displacement_at([1.7, 2.2], free[:2], np.zeros((2, 3)))


def test_global_equilibrium_of_print_and_base_forces(cube, patch, displacements):
    u = cube.displacement_field(patch, displacements)
    on_body_from_print = -patch.reaction_forces(displacements)
    from_base = cube.fixed_reactions(u)
    points = np.vstack([cube.mesh.nodes[patch.node_ids], cube.mesh.nodes[cube.fixed_nodes]])
    forces = np.vstack([on_body_from_print, from_base])
    scale = np.abs(on_body_from_print).sum()
    assert np.abs(forces.sum(axis=0)).max() < 1e-8 * scale
    assert np.abs(np.cross(points, forces).sum(axis=0)).max() < 1e-8 * scale
    # and the consistent print forces are exactly the nodal forces K u at the print
    assert np.allclose(cube.nodal_forces(u)[patch.node_ids], on_body_from_print, rtol=0, atol=1e-8 * scale)


def test_forces_scale_linearly_with_young_modulus_and_compliance_inversely(cube_mesh, displacements):
    soft = make_body(cube_mesh, LinearElasticMaterial(1e5, 0.4, 1e3))
    stiff = make_body(cube_mesh, LinearElasticMaterial(3e5, 0.4, 1e3))
    ids = nodes_in_polygon(cube_mesh, TOP_SQUARE)
    p_soft, p_stiff = soft.contact_patch(ids), stiff.contact_patch(ids)
    for method in ("consistent", "traction"):
        ratio = p_stiff.reaction_forces(displacements, method) / p_soft.reaction_forces(displacements, method)
        assert np.allclose(ratio, 3.0, rtol=1e-9)
    assert np.allclose(soft.compliance(ids), 3.0 * stiff.compliance(ids), rtol=1e-9, atol=0)


def test_scipy_and_cholmod_solvers_agree(cube_mesh, patch, displacements):
    scipy_body = make_body(cube_mesh, solver="scipy")
    assert scipy_body.solver == "scipy"
    forces = scipy_body.contact_patch(patch.node_ids).reaction_forces(displacements)
    assert np.allclose(forces, patch.reaction_forces(displacements), rtol=1e-9, atol=1e-9)


def test_precomputed_surface_compliance_gives_same_print_matrices(cube_mesh, patch, displacements):
    body = make_body(cube_mesh)
    top = np.flatnonzero(cube_mesh.nodes[:, 2] == 1.0)
    body.precompute_surface_compliance(top)
    cached = body.contact_patch(patch.node_ids)
    for method in ("consistent", "traction"):
        assert np.allclose(cached.reaction_matrix(method), patch.reaction_matrix(method), rtol=1e-9, atol=1e-6)


def test_a_body_keeps_its_most_recent_patches_only(cube_mesh):
    """Patches asked for again are the same objects, but a body holds at most _PATCHES_KEPT
    of them (a plan asks for a new node set at almost every stance: held unbounded, a
    user's 100-expansion plan kept 878 MB of them)."""
    from fem.body import _PATCHES_KEPT

    body = make_body(cube_mesh)
    top = np.flatnonzero(cube_mesh.nodes[:, 2] == 1.0)
    sets = [top[k : k + 3] for k in range(_PATCHES_KEPT + 4)]
    patches = [body.contact_patch(ids) for ids in sets]
    assert len(body._patches) == _PATCHES_KEPT
    assert body.contact_patch(sets[-1]) is patches[-1]  # recent: kept
    assert body.contact_patch(sets[0]) is not patches[0]  # the oldest was dropped, made again
    assert np.array_equal(body.contact_patch(sets[0]).compliance, patches[0].compliance)
    assert len(body._patches) == _PATCHES_KEPT


# ---------------------------------------------------------------- derivatives
@pytest.mark.parametrize("method", ["consistent", "traction"])
def test_reaction_matrix_matches_finite_differences(patch, displacements, method):
    r = patch.reaction_matrix(method)
    step = 1e-6
    fd = np.empty_like(r)
    for j in range(r.shape[1]):
        du = np.zeros(r.shape[1])
        du[j] = step
        du = du.reshape(-1, 3)
        plus = patch.reaction_forces(displacements + du, method)
        minus = patch.reaction_forces(displacements - du, method)
        fd[:, j] = (plus - minus).ravel() / (2 * step)
    assert_rows_match(fd, r)


def test_traction_normal_derivative_matches_finite_differences(patch, displacements):
    rng = np.random.default_rng(RNG_SEED)
    normals = patch.triangle_normals
    direction = rng.normal(size=normals.shape)
    step = 1e-6
    plus = patch.reaction_forces(displacements, "traction", normals=normals + step * direction)
    minus = patch.reaction_forces(displacements, "traction", normals=normals - step * direction)
    fd = (plus - minus) / (2 * step)
    derivative = patch.traction_normal_derivative(displacements)  # (T, 3, 3)
    per_triangle = np.einsum("tij,tj->ti", derivative, direction)
    predicted = np.zeros_like(fd)
    for k in range(3):
        np.add.at(predicted, patch.triangles[:, k], per_triangle)
    assert_rows_match(fd, predicted)


def test_traction_rotation_jacobian_matches_rotating_the_normals(patch, displacements):
    jacobian = patch.traction_rotation_jacobian(displacements)  # (p, 3, 3)
    step = 1e-6
    for axis in np.eye(3):
        plus = patch.reaction_forces(displacements, "traction", normals=rotate(patch.triangle_normals, step * axis))
        minus = patch.reaction_forces(displacements, "traction", normals=rotate(patch.triangle_normals, -step * axis))
        fd = (plus - minus) / (2 * step)
        assert_rows_match(fd, jacobian @ axis)


def test_traction_forces_with_rest_normals_match_reaction_matrix(patch, displacements):
    direct = patch.reaction_forces(displacements, "traction", normals=patch.triangle_normals)
    assert np.allclose(direct, patch.reaction_forces(displacements, "traction"), rtol=1e-12, atol=1e-9)


# ---------------------------------------------------------------- traction vs consistent
def print_forces(cells):
    mesh = box_mesh((1.0, 1.0, 1.0), (cells, cells, cells))
    body = make_body(mesh)
    patch = body.contact_patch(nodes_in_polygon(mesh, [[0.25, 0.25, 1], [0.75, 0.25, 1], [0.75, 0.75, 1], [0.25, 0.75, 1]]))
    press = np.tile([0.0, 0.0, -0.01], (patch.n_nodes, 1))
    return patch.reaction_forces(press, "consistent"), patch.reaction_forces(press, "traction")


def test_traction_and_consistent_total_forces_agree_better_on_finer_meshes():
    # The print's edges lie on odd node rows (1, 3 and 5 cells in): rows of the same kind
    # (the mesh's cells alternate), so the meshes differ in cell size only.
    # Measured 0.42, 0.24, 0.19 (0.49, 0.39, 0.33 at 8, 16, 24 cells).
    gaps = []
    for cells in (4, 12, 20):
        consistent, traction = print_forces(cells)
        gaps.append(abs(traction[:, 2].sum() / consistent[:, 2].sum() - 1.0))
    assert gaps[0] > gaps[1] > gaps[2]


# ---------------------------------------------------------------- fields and files
def test_strain_check_warns_or_raises_beyond_small_deformations(cube, patch):
    u = cube.displacement_field(patch, np.tile([0, 0, -0.2], (patch.n_nodes, 1)))
    with pytest.warns(FemWarning, match="exceeds the small-strain limit"):
        largest = cube.check_small_strain(u)
    assert largest > 0.05
    with pytest.raises(FemError, match=r"largest strain .* exceeds"):
        cube.check_small_strain(u, action="raise")
    small = cube.displacement_field(patch, np.tile([0, 0, -1e-4], (patch.n_nodes, 1)))
    assert cube.check_small_strain(small) < 0.05


def test_written_vtu_holds_displacement_and_stress(tmp_path, cube, patch, displacements):
    import meshio

    u = cube.displacement_field(patch, displacements)
    path = tmp_path / "deformed.vtu"
    cube.write_vtu(path, u, deformed=True)
    raw = meshio.read(path)
    assert np.allclose(raw.point_data["displacement"], u)
    assert np.allclose(raw.points, cube.mesh.nodes + u)
    assert np.allclose(raw.cell_data["stress"][0], cube.stress(u))
    assert read_mesh(path).n_tets == cube.mesh.n_tets
    # By default at rest, so that ParaView's Warp By Vector adds u once.
    cube.write_vtu(path, u)
    np.testing.assert_array_equal(meshio.read(path).points, cube.mesh.nodes)


def test_vtu_written_in_another_frame_is_the_body_meshed_there(tmp_path, cube, patch, displacements):
    """Placed by a rigid transform, the file holds what the same body meshed in that frame gives."""
    import meshio

    u = cube.displacement_field(patch, displacements)
    rotation = rotate(np.eye(3), np.array([0.3, -0.5, 0.9])).T  # columns: the turned axes
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = rotation, [1.0, -2.0, 0.5]
    path = tmp_path / "placed.vtu"
    cube.write_vtu(path, u, transform_body_to_output=transform)
    raw = meshio.read(path)
    placed = DeformableBody(TetMesh(cube.mesh.nodes @ rotation.T + transform[:3, 3], cube.mesh.tets), MATERIAL,
                            np.flatnonzero(cube.fixed_mask))
    u_placed = u @ rotation.T
    np.testing.assert_allclose(raw.points, placed.mesh.nodes, atol=1e-12)
    np.testing.assert_allclose(raw.point_data["displacement"], u_placed, atol=1e-15)
    scale = np.abs(cube.stress(u)).max()
    np.testing.assert_allclose(raw.cell_data["stress"][0], placed.stress(u_placed), atol=1e-9 * scale)
    np.testing.assert_allclose(raw.cell_data["strain"][0], placed.strain(u_placed), atol=1e-12)
    np.testing.assert_allclose(raw.cell_data["von_mises"][0], von_mises(cube.stress(u)), atol=1e-9 * scale)


def test_vtu_refuses_a_transform_that_is_not_rigid(tmp_path, cube):
    with pytest.raises(FemError, match="must be a rigid transform"):
        cube.write_vtu(tmp_path / "x.vtu", np.zeros_like(cube.mesh.nodes), transform_body_to_output=2.0 * np.eye(4))


def test_pvd_lists_each_file_at_its_time_and_part(tmp_path):
    import xml.etree.ElementTree as ElementTree

    write_pvd(tmp_path / "series.pvd", [(0, 0, tmp_path / "a0.vtu"), (0, 1, tmp_path / "b0.vtu"), (1.5, 0, "/elsewhere/a1.vtu")])
    entries = [e.attrib for e in ElementTree.parse(tmp_path / "series.pvd").getroot().iter("DataSet")]
    assert entries == [
        {"timestep": "0", "part": "0", "file": "a0.vtu"},
        {"timestep": "0", "part": "1", "file": "b0.vtu"},
        {"timestep": "1.5", "part": "0", "file": "/elsewhere/a1.vtu"},
    ]
    with pytest.raises(MeshError, match="part must be a non-negative integer, got -1"):
        write_pvd(tmp_path / "bad.pvd", [(0, -1, "a.vtu")])


# ---------------------------------------------------------------- bad input
def test_body_without_fixed_nodes_is_rejected(cube_mesh):
    with pytest.raises(BoundaryError, match="no fixed node.*fix the base"):
        DeformableBody(cube_mesh, MATERIAL, np.array([], dtype=int))
    with pytest.raises(BoundaryError, match="outside"):
        DeformableBody(cube_mesh, MATERIAL, np.array([0, cube_mesh.n_nodes]))


@pytest.mark.parametrize(
    "which, message",
    [
        ("two-nodes", "at least 3 nodes"),
        ("interior-node", "not on the body surface"),
        ("fixed-node", "is fixed"),
        ("duplicates", "duplicate node ids"),
    ],
)
def test_invalid_print_raises_print_error(cube, patch, which, message):
    ids = list(patch.node_ids)
    if which == "two-nodes":
        ids = ids[:2]
    elif which == "interior-node":
        ids = ids + [int(np.flatnonzero(~cube.mesh.is_surface_node)[0])]
    elif which == "fixed-node":
        ids = ids + [int(cube.fixed_nodes[0])]
    else:
        ids = ids + ids[:1]
    with pytest.raises(PrintError, match=message):
        cube.contact_patch(np.array(ids))


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.zeros((4, 3)), r"must have shape \(9, 3\)"),
        (np.zeros(27), r"must have shape \(9, 3\)"),
        (np.full((9, 3), np.nan), "NaN"),
    ],
    ids=["too-few-rows", "flat-vector", "nan"],
)
def test_invalid_displacements_raise_print_error(patch, bad, message):
    with pytest.raises(PrintError, match=message):
        patch.reaction_forces(bad)


def test_unknown_method_and_bad_normals_are_rejected(patch, displacements):
    with pytest.raises(PrintError, match="unknown method"):
        patch.reaction_matrix("penalty")
    with pytest.raises(PrintError, match="normals must have shape"):
        patch.reaction_forces(displacements, "traction", normals=np.zeros((2, 3)))


def test_traction_matrix_for_turned_normals_matches_the_forces(patch, displacements):
    """reaction_matrix('traction', normals) is the exact linear map of eq. (44) with those normals."""
    normals = rotate(patch.triangle_normals, np.array([0.05, -0.03, 0.2]))
    matrix = patch.reaction_matrix("traction", normals=normals)
    forces = patch.reaction_forces(displacements, method="traction", normals=normals)
    assert np.allclose(matrix @ displacements.ravel(), forces.ravel(), rtol=1e-12, atol=1e-9)
    with pytest.raises(PrintError, match="normals only apply to method='traction'"):
        patch.reaction_matrix("consistent", normals=normals)
