"""Material law, element matrices and assembled stiffness: exact properties of linear tets."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from fem import (
    DeformableBody,
    LinearElasticMaterial,
    FemError,
    MaterialError,
    assemble_stiffness,
    box_mesh,
    element_stiffness_matrices,
    element_strain_matrices,
    tensor_mesh,
)
from fem.mesh import tet_edge_cofactors

RNG_SEED = 20240611
MATERIAL = LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4, density=1e3)


@pytest.fixture
def distorted_mesh():
    """A 3x3x3 box whose interior nodes are jiggled (seeded): a non-uniform mesh."""
    mesh = box_mesh((1.0, 1.0, 1.0), (3, 3, 3))
    rng = np.random.default_rng(RNG_SEED)
    nodes = np.array(mesh.nodes)
    interior = ~mesh.is_surface_node
    nodes[interior] += rng.uniform(-0.08, 0.08, size=(interior.sum(), 3))
    return type(mesh)(nodes, mesh.tets)


def rigid_motions(nodes):
    """(3N, 6) displacement fields: 3 translations and 3 infinitesimal rotations."""
    fields = []
    for axis in np.eye(3):
        fields.append(np.tile(axis, (nodes.shape[0], 1)).ravel())
        fields.append(np.cross(axis, nodes - nodes.mean(axis=0)).ravel())
    return np.stack(fields, axis=1)


def test_voigt_matrix_matches_hooke_law_with_engineering_shears():
    m = MATERIAL
    lam, mu = m.lame_lambda, m.lame_mu
    assert lam == pytest.approx(1e6 * 0.4 / (1.4 * 0.2))
    assert mu == pytest.approx(1e6 / 2.8)
    # uniaxial stress: sigma = (1, 0, 0) -> strain (1/E, -nu/E, -nu/E)
    strain = np.linalg.solve(m.voigt_matrix, [1.0, 0, 0, 0, 0, 0])
    assert np.allclose(strain[:3], np.array([1.0, -0.4, -0.4]) / 1e6)
    # pure shear: sigma_12 = mu * gamma_12 with gamma the engineering shear
    assert m.voigt_matrix[3, 3] == pytest.approx(mu)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"young_modulus": 0.0, "poisson_ratio": 0.3}, "young_modulus must be > 0"),
        ({"young_modulus": -5.0, "poisson_ratio": 0.3}, "young_modulus must be > 0"),
        ({"young_modulus": 1e6, "poisson_ratio": 0.5}, r"poisson_ratio must lie in \(-1, 0.5\)"),
        ({"young_modulus": 1e6, "poisson_ratio": -1.0}, r"poisson_ratio must lie in \(-1, 0.5\)"),
        ({"young_modulus": 1e6, "poisson_ratio": 0.3, "density": -1.0}, "density must be >= 0"),
        ({"young_modulus": float("nan"), "poisson_ratio": 0.3}, "young_modulus must be finite"),
    ],
    ids=["zero-E", "negative-E", "incompressible-nu", "nu-minus-one", "negative-density", "nan-E"],
)
def test_invalid_material_raises_material_error(kwargs, message):
    with pytest.raises(MaterialError, match=message):
        LinearElasticMaterial(**kwargs)


def test_strain_matrix_gives_exact_strain_of_affine_field(distorted_mesh):
    rng = np.random.default_rng(RNG_SEED)
    gradient = rng.normal(size=(3, 3))
    u = distorted_mesh.nodes @ gradient.T
    b, volumes = element_strain_matrices(distorted_mesh.nodes, distorted_mesh.tets)
    strain = np.einsum("eij,ej->ei", b, u[distorted_mesh.tets].reshape(-1, 12))
    sym = 0.5 * (gradient + gradient.T)
    expected = [sym[0, 0], sym[1, 1], sym[2, 2], 2 * sym[0, 1], 2 * sym[0, 2], 2 * sym[1, 2]]
    assert np.allclose(strain, expected, atol=1e-12)
    assert np.allclose(volumes, distorted_mesh.volumes)


def test_closed_form_cofactors_invert_each_tets_edge_matrix(distorted_mesh):
    cofactors, determinants = tet_edge_cofactors(distorted_mesh.nodes, distorted_mesh.tets)
    x = distorted_mesh.nodes[distorted_mesh.tets]
    edges = x[:, 1:] - x[:, :1]  # rows x_k - x_0
    np.testing.assert_allclose(determinants, np.linalg.det(edges), rtol=1e-12)
    inverse = np.swapaxes(cofactors, 1, 2) / determinants[:, None, None]
    np.testing.assert_allclose(inverse @ edges, np.broadcast_to(np.eye(3), edges.shape), atol=1e-12)


def test_body_strain_from_shape_gradients_equals_the_strain_matrices(distorted_mesh):
    """DeformableBody.strain (from the (M, 4, 3) gradients) against B_e u_e of eq. (24)."""
    body = DeformableBody(distorted_mesh, MATERIAL, fixed_nodes=np.flatnonzero(distorted_mesh.nodes[:, 2] == 0.0))
    u = 1e-3 * np.random.default_rng(RNG_SEED + 2).normal(size=distorted_mesh.nodes.shape)
    b, _ = element_strain_matrices(distorted_mesh.nodes, distorted_mesh.tets)
    expected = np.einsum("eij,ej->ei", b, u[distorted_mesh.tets].reshape(-1, 12))
    np.testing.assert_allclose(body.strain(u), expected, rtol=0, atol=1e-14)


def test_rigid_motions_produce_no_force(distorted_mesh):
    k = assemble_stiffness(distorted_mesh, MATERIAL)
    forces = k @ rigid_motions(distorted_mesh.nodes)
    assert np.abs(forces).max() < 1e-9 * abs(k).max()


def test_stiffness_is_symmetric_psd_with_six_rigid_modes(distorted_mesh):
    k = assemble_stiffness(distorted_mesh, MATERIAL).toarray()
    assert np.abs(k - k.T).max() < 1e-12 * np.abs(k).max()
    eigenvalues = np.linalg.eigvalsh(k)
    scale = eigenvalues.max()
    assert eigenvalues.min() > -1e-10 * scale
    assert np.sum(eigenvalues < 1e-10 * scale) == 6


def test_free_stiffness_is_positive_definite_once_base_is_fixed(distorted_mesh):
    k = assemble_stiffness(distorted_mesh, MATERIAL).toarray()
    free_nodes = distorted_mesh.nodes[:, 2] > 0.0
    free = np.repeat(free_nodes, 3)
    eigenvalues = np.linalg.eigvalsh(k[np.ix_(free, free)])
    assert eigenvalues.min() > 1e-6 * eigenvalues.max()


def test_assembly_matches_a_plain_scatter_of_element_matrices(distorted_mesh):
    k = assemble_stiffness(distorted_mesh, MATERIAL).toarray()
    ke = element_stiffness_matrices(distorted_mesh, MATERIAL)
    dofs = (3 * distorted_mesh.tets[:, :, None] + np.arange(3)).reshape(-1, 12)
    expected = np.zeros_like(k)
    for e in range(dofs.shape[0]):  # reference loop, small mesh
        expected[np.ix_(dofs[e], dofs[e])] += ke[e]
    assert np.abs(k - expected).max() < 1e-12 * np.abs(k).max()


def test_patch_test_affine_boundary_displacement_gives_uniform_interior_strain(distorted_mesh):
    """Linear tets reproduce any affine field exactly (the FE patch test)."""
    mesh = distorted_mesh
    rng = np.random.default_rng(RNG_SEED + 1)
    gradient = 1e-3 * rng.normal(size=(3, 3))
    exact = mesh.nodes @ gradient.T
    k = assemble_stiffness(mesh, MATERIAL).tocsr()
    boundary = np.repeat(mesh.is_surface_node, 3)
    inner = ~boundary
    u = exact.ravel().copy()
    u[inner] = spla.spsolve(k[inner][:, inner].tocsc(), -k[inner][:, boundary] @ u[boundary])
    b, _ = element_strain_matrices(mesh.nodes, mesh.tets)
    strain = np.einsum("eij,ej->ei", b, u.reshape(-1, 3)[mesh.tets].reshape(-1, 12))
    assert np.abs(strain - strain.mean(axis=0)).max() < 1e-10
    assert np.allclose(u, exact.ravel(), atol=1e-12)


def test_column_on_rollers_under_compression_gives_e_a_d_over_l():
    """Uniaxial compression with free lateral expansion: F = E A d / L to rounding."""
    width, depth, height, d = 0.3, 0.2, 1.5, 1e-3
    mesh = tensor_mesh([0, 0.1, 0.3], [0, 0.05, 0.2], np.linspace(0, height, 5) ** 1.0)
    k = assemble_stiffness(mesh, MATERIAL).tocsr()
    n = mesh.n_nodes
    z = mesh.nodes[:, 2]
    prescribed = np.zeros(3 * n, dtype=bool)
    values = np.zeros(3 * n)
    bottom, top = np.flatnonzero(z == 0), np.flatnonzero(z == height)
    prescribed[3 * bottom + 2] = prescribed[3 * top + 2] = True  # rollers
    values[3 * top + 2] = -d
    corner = bottom[np.argmin(np.linalg.norm(mesh.nodes[bottom], axis=1))]
    x_neighbour = bottom[(mesh.nodes[bottom, 1] == 0) & (mesh.nodes[bottom, 0] > 0)][0]
    prescribed[[3 * corner, 3 * corner + 1, 3 * x_neighbour + 1]] = True  # no rigid drift
    free = ~prescribed
    u = values.copy()
    u[free] = spla.spsolve(k[free][:, free].tocsc(), -k[free][:, prescribed] @ values[prescribed])
    force_on_top = (k @ u)[3 * top + 2].sum()
    assert force_on_top == pytest.approx(-MATERIAL.young_modulus * width * depth * d / height, rel=1e-10)


def test_self_weight_is_carried_by_the_base_exactly(distorted_mesh):
    """The supports carry the body's weight, to rounding, on any mesh: the consistent
    loads sum to rho g V, and the supports' forces are the elastic forces K u at the
    base nodes less the loads lumped there."""
    body = DeformableBody(distorted_mesh, MATERIAL, fixed_nodes=np.flatnonzero(distorted_mesh.nodes[:, 2] == 0.0), cache=False)
    gravity = np.array([0.3, -0.2, -9.81])
    u = body.self_weight_displacement(gravity)
    assert np.all(u[body.fixed_nodes] == 0.0)
    volumes = np.abs(np.linalg.det(np.stack([distorted_mesh.nodes[distorted_mesh.tets[:, k]] - distorted_mesh.nodes[distorted_mesh.tets[:, 0]]
                                             for k in (1, 2, 3)], axis=1))) / 6.0
    on_base = np.isin(distorted_mesh.tets, body.fixed_nodes)
    lumped = MATERIAL.density * (volumes[:, None] * on_base).sum() / 4.0 * gravity
    weight = MATERIAL.density * volumes.sum() * gravity
    np.testing.assert_allclose((body.fixed_reactions(u).sum(axis=0) - lumped), -weight, rtol=1e-10)


def test_self_weight_of_a_block_converges_to_the_uniaxial_solution():
    """A 1 m x 1 m x 0.5 m block (nu = 0) on a fixed base: u_z = -(rho g / E)(L z - z^2 / 2)
    and no sideways motion; linear tets approach it as the mesh is refined."""
    height, material = 0.5, LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.0, density=1e3)
    errors = []
    for cells in (4, 8):
        mesh = tensor_mesh(np.linspace(0, 1, cells + 1), np.linspace(0, 1, cells + 1), np.linspace(0, height, cells + 1))
        body = DeformableBody(mesh, material, fixed_nodes=np.flatnonzero(mesh.nodes[:, 2] == 0.0), cache=False)
        u = body.self_weight_displacement((0.0, 0.0, -9.81))
        z = mesh.nodes[:, 2]
        exact = -(1e3 * 9.81 / 1e6) * (height * z - z**2 / 2)
        errors.append((np.abs(u[:, 2] - exact).max() / np.abs(exact).max(), np.abs(u[:, :2]).max() / np.abs(exact).max()))
    assert errors[1][0] < 0.05 and errors[1][1] < 0.02
    assert errors[1][0] < 0.5 * errors[0][0] and errors[1][1] < 0.5 * errors[0][1]


def test_self_weight_needs_a_density_and_a_gravity_vector(distorted_mesh):
    fixed = np.flatnonzero(distorted_mesh.nodes[:, 2] == 0.0)
    weightless = DeformableBody(distorted_mesh, LinearElasticMaterial(1e6, 0.4), fixed_nodes=fixed, cache=False)
    assert not weightless.self_weight_displacement((0.0, 0.0, -9.81)).any()
    body = DeformableBody(distorted_mesh, MATERIAL, fixed_nodes=fixed, cache=False)
    with pytest.raises(FemError, match=r"gravity must be a finite \(3,\) vector in m/s\^2, got \[0.0, -9.81\]"):
        body.self_weight_displacement((0.0, -9.81))


def test_a_material_error_names_its_field():
    # So that a reader of another format (a scenario's E, nu, rho) can name its own key.
    for values, field in (({"young_modulus": -1.0, "poisson_ratio": 0.3}, "young_modulus"),
                          ({"young_modulus": 1e6, "poisson_ratio": 0.5}, "poisson_ratio"),
                          ({"young_modulus": 1e6, "poisson_ratio": 0.3, "density": -1.0}, "density"),
                          ({"young_modulus": float("inf"), "poisson_ratio": 0.3}, "young_modulus")):
        with pytest.raises(MaterialError) as raised:
            LinearElasticMaterial(**values)
        assert raised.value.field == field and str(raised.value).startswith(field + " ")


def test_a_nearly_incompressible_material_warns_that_linear_tetrahedra_lock():
    import warnings

    from fem.errors import FemWarning

    with pytest.warns(FemWarning, match=r"poisson_ratio 0.49 is above 0.45: linear tetrahedra lock"):
        LinearElasticMaterial(1e6, 0.49)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        LinearElasticMaterial(1e6, 0.45)  # at the bound: no warning
        LinearElasticMaterial(1e6, 0.4)


def test_poisson_ratio_near_half_locks_a_coarse_box_as_the_warning_says():
    # The locking the warning names, on a small case: a square print pressed 1 mm into a
    # 4-layer box; the force on a mesh twice as fine changes by far more at nu = 0.49
    # than at 0.3 (the coarse mesh too stiff).
    import warnings

    def force(nu, divisions):
        mesh = box_mesh((1.0, 1.0, 0.4), divisions)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            material = LinearElasticMaterial(1e6, nu)
        body = DeformableBody(mesh, material, mesh.nodes[:, 2] == 0.0)
        top = np.flatnonzero((mesh.nodes[:, 2] == 0.4) & (np.abs(mesh.nodes[:, 0] - 0.5) <= 0.17)
                             & (np.abs(mesh.nodes[:, 1] - 0.5) <= 0.17))
        patch = body.contact_patch(top)
        return patch.reaction_forces(np.tile([0.0, 0.0, -1e-3], (patch.n_nodes, 1)))[:, 2].sum()

    change = {nu: abs(force(nu, (6, 6, 2)) / force(nu, (12, 12, 4)) - 1.0) for nu in (0.3, 0.49)}
    assert change[0.49] > 2.0 * change[0.3]
