"""Element strain matrices and vectorised assembly of the global stiffness (eqs. 17, 24)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .errors import MaterialError
from .material import LinearElasticMaterial
from .mesh import TetMesh, tet_edge_cofactors

__all__ = ["shape_gradients", "element_strain_matrices", "element_stiffness_matrices", "assemble_stiffness"]


def shape_gradients(nodes: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradients of the 4 linear shape functions of each tet.

    Parameters
    ----------
    nodes : (N, 3) float
        Node positions, metres.
    tets : (M, 4) int
        Node ids of each tet.

    Returns
    -------
    gradients : (M, 4, 3) float
        ``gradients[e, k]`` = grad N_k on tet e, 1/metres.
    volumes : (M,) float
        Signed volumes, cubic metres.
    """
    # x = x0 + E^T a (E's rows the edges x_k - x0), so grad a_k is column k of E^-1.
    cofactors, determinants = tet_edge_cofactors(nodes, tets)
    grads = np.empty((tets.shape[0], 4, 3))
    grads[:, 1:, :] = cofactors / determinants[:, None, None]
    grads[:, 0, :] = -grads[:, 1:, :].sum(axis=1)
    return grads, determinants / 6.0


def element_strain_matrices(nodes: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Constant strain-displacement matrices B_e of linear tets (eq. 24).

    Parameters
    ----------
    nodes : (N, 3) float
        Node positions, metres.
    tets : (M, 4) int
        Node ids of each tet.

    Returns
    -------
    B : (M, 6, 12) float, 1/metres
        Voigt strain ``{eps} = B_e U_e`` (order 11, 22, 33, 2*12, 2*13, 2*23, eq. 23)
        with element dofs ordered ``3 * local_node + axis``.
    volumes : (M,) float
        Signed volumes, cubic metres.
    """
    grads, volumes = shape_gradients(np.asarray(nodes, dtype=float), np.asarray(tets))
    m = grads.shape[0]
    b = np.zeros((m, 6, 4, 3))
    gx, gy, gz = grads[:, :, 0], grads[:, :, 1], grads[:, :, 2]
    b[:, 0, :, 0] = gx
    b[:, 1, :, 1] = gy
    b[:, 2, :, 2] = gz
    b[:, 3, :, 0], b[:, 3, :, 1] = gy, gx
    b[:, 4, :, 0], b[:, 4, :, 2] = gz, gx
    b[:, 5, :, 1], b[:, 5, :, 2] = gz, gy
    return b.reshape(m, 6, 12), volumes


def element_stiffness_matrices(mesh: TetMesh, material: LinearElasticMaterial) -> np.ndarray:
    """Element stiffness matrices ``K_e = V_e B_e^T A B_e`` (eq. 17), (M, 12, 12) N/m."""
    b, volumes = element_strain_matrices(mesh.nodes, mesh.tets)
    return np.einsum("e,eai,ab,ebj->eij", volumes, b, material.voigt_matrix, b, optimize=True)


def assemble_stiffness(mesh: TetMesh, material: LinearElasticMaterial) -> sp.csr_matrix:
    """Global stiffness matrix of the unconstrained body.

    All elements at once: the (M, 12, 12) element matrices are viewed as 3x3 blocks
    per pair of nodes, summed per node pair (one sort of the ``16 M`` pair keys instead of
    ``144 M`` scalar entries) and converted once through a block-sparse matrix.

    Parameters
    ----------
    mesh : TetMesh
    material : LinearElasticMaterial

    Returns
    -------
    scipy.sparse.csr_matrix, (3N, 3N) float, N/m
        Symmetric positive semi-definite (six rigid modes); dof ``3 * node + axis``.

    Raises
    ------
    MaterialError
        If an entry of the stiffness overflows (non-finite).

    Examples
    --------
    >>> from fem import box_mesh, LinearElasticMaterial
    >>> K = assemble_stiffness(box_mesh((1, 1, 1), (2, 2, 2)), LinearElasticMaterial(1e6, 0.4, 1e3))
    >>> K.shape
    (81, 81)
    """
    n = mesh.n_nodes
    ke = element_stiffness_matrices(mesh, material)
    m = ke.shape[0]
    blocks = ke.reshape(m, 4, 3, 4, 3).transpose(0, 1, 3, 2, 4).reshape(m * 16, 3, 3)
    rows = np.repeat(mesh.tets, 4, axis=1).ravel()
    cols = np.tile(mesh.tets, (1, 4)).ravel()
    keys = rows * n + cols
    unique_keys, slot = np.unique(keys, return_inverse=True)
    data = np.empty((unique_keys.size, 3, 3))
    flat = blocks.reshape(-1, 9)
    for c in range(9):  # 9 bincounts over the block entries: small fixed loop
        data.reshape(-1, 9)[:, c] = np.bincount(slot, weights=flat[:, c], minlength=unique_keys.size)
    block_rows = unique_keys // n
    indices = (unique_keys % n).astype(np.int32)
    indptr = np.searchsorted(block_rows, np.arange(n + 1)).astype(np.int32)
    if not np.all(np.isfinite(data)):
        # Only reachable with extreme but finite inputs (a huge E on large tets, tiny
        # slivers): refuse here, or every force computed from K comes back NaN.
        raise MaterialError(
            f"the stiffness of this mesh has non-finite entries with young_modulus "
            f"{material.young_modulus:g} Pa; use a smaller modulus or rescale the mesh (metres)"
        )
    k = sp.bsr_matrix((data, indices, indptr), shape=(3 * n, 3 * n))
    return k.tocsr()
