"""A deformable body: mesh, material, fixed base and one factorisation of K_NN."""

from __future__ import annotations

import logging
import os
import warnings
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .assembly import assemble_stiffness, element_strain_matrices
from .errors import BoundaryError, FemError, FemWarning
from .io import write_mesh
from .material import LinearElasticMaterial
from .mesh import TetMesh
from .ordering import nested_dissection, node_adjacency
from .patch import ContactPatch, check_node_ids
from .solvers import SOLVERS, Factorization, factorize

__all__ = ["DeformableBody", "von_mises", "voigt_to_tensor_strain"]

logger = logging.getLogger(__name__)

# Number of right-hand sides solved at once when filling the compliance cache:
# bounds the (free dofs x block) dense workspace to a few hundred MB at 50k nodes.
_SOLVE_BLOCK = 192


def von_mises(stress: np.ndarray) -> np.ndarray:
    """Von Mises equivalent stress of Voigt stresses.

    Parameters
    ----------
    stress : (M, 6) float
        Voigt stresses (11, 22, 33, 12, 13, 23), pascals.

    Returns
    -------
    (M,) float, pascals
    """
    s = np.asarray(stress)
    return np.sqrt(
        0.5 * ((s[:, 0] - s[:, 1]) ** 2 + (s[:, 1] - s[:, 2]) ** 2 + (s[:, 2] - s[:, 0]) ** 2)
        + 3.0 * (s[:, 3] ** 2 + s[:, 4] ** 2 + s[:, 5] ** 2)
    )


def voigt_to_tensor_strain(strain: np.ndarray) -> np.ndarray:
    """Strain tensors from Voigt strains with engineering shears.

    Parameters
    ----------
    strain : (..., 6) float
        (e11, e22, e33, g12, g13, g23), ``g = 2 e`` off the diagonal.

    Returns
    -------
    (..., 3, 3) float, symmetric.
    """
    e = np.asarray(strain, dtype=float)
    tensor = np.empty(e.shape[:-1] + (3, 3))
    tensor[..., [0, 1, 2], [0, 1, 2]] = e[..., :3]
    for v, (i, j) in zip((3, 4, 5), ((0, 1), (0, 2), (1, 2))):
        tensor[..., i, j] = tensor[..., j, i] = 0.5 * e[..., v]
    return tensor


class DeformableBody:
    """A linear elastic solid with a fixed part of its boundary (eq. 28).

    The free-dof stiffness K_NN (N: every dof not fixed, prints included) is factorised
    once, lazily; every contact print then reuses it: the print's condensed stiffness
    is the inverse of the compliance block ``[K_NN^-1]_PP`` (a Schur complement
    identity), so a print costs a few solves, or nothing but a sub-block and a small
    dense inverse after :meth:`precompute_surface_compliance`.

    Parameters
    ----------
    mesh : TetMesh
        The body at rest, metres, body frame.
    material : LinearElasticMaterial
    fixed_nodes : (k,) int or (N,) bool
        Node ids (or mask) held at zero displacement, e.g. the base on the floor.
    solver : {"auto", "cholmod", "scipy"}, optional
        Sparse factorisation of K_NN; ``"auto"`` prefers CHOLMOD (cvxopt) and falls
        back to scipy's SuperLU.

    Raises
    ------
    BoundaryError
        If no node is fixed (the stiffness would be singular), or ids are out of range.
    SolverError
        If the solver name is unknown or unavailable.

    Examples
    --------
    Press a 20 cm square print 1 cm into the top of a soft 1 m cube and read the
    forces the cube exerts on the robot:

    >>> import numpy as np
    >>> from fem import DeformableBody, LinearElasticMaterial, box_mesh, nodes_in_polygon
    >>> mesh = box_mesh((1.0, 1.0, 1.0), (10, 10, 6))
    >>> body = DeformableBody(mesh, LinearElasticMaterial(1e6, 0.4, 1e3),
    ...                       fixed_nodes=np.flatnonzero(mesh.nodes[:, 2] == 0.0))
    >>> square = [[0.4, 0.4, 1.0], [0.6, 0.4, 1.0], [0.6, 0.6, 1.0], [0.4, 0.6, 1.0]]
    >>> patch = body.contact_patch(nodes_in_polygon(mesh, square))
    >>> displacements = np.tile([0.0, 0.0, -0.01], (len(patch.node_ids), 1))
    >>> forces = patch.reaction_forces(displacements)      # (9, 3) newtons, on the robot
    >>> bool(forces[:, 2].sum() > 0)                       # the cube pushes the hand up
    True
    >>> patch.reaction_matrix("consistent").shape          # exact Jacobian d forces / d U_P
    (27, 27)
    """

    def __init__(
        self,
        mesh: TetMesh,
        material: LinearElasticMaterial,
        fixed_nodes: np.ndarray,
        solver: str = "auto",
    ) -> None:
        if not isinstance(mesh, TetMesh):
            raise FemError(f"mesh must be a TetMesh, got {type(mesh).__name__}")
        if not isinstance(material, LinearElasticMaterial):
            raise FemError(f"material must be a LinearElasticMaterial, got {type(material).__name__}")
        if solver not in SOLVERS:
            raise FemError(f"unknown solver {solver!r}; choose one of {SOLVERS}")
        self._mesh = mesh
        self._material = material
        self._solver = solver
        self._fixed = self._check_fixed(mesh, fixed_nodes)
        fixed_mask = np.zeros(mesh.n_nodes, dtype=bool)
        fixed_mask[self._fixed] = True
        fixed_mask.setflags(write=False)
        self._fixed_mask = fixed_mask
        free = np.flatnonzero(np.repeat(~fixed_mask, 3))
        free.setflags(write=False)
        self._free_dofs = free
        self._free_index = np.full(mesh.n_dofs, -1, dtype=np.int64)
        self._free_index[free] = np.arange(free.size)
        self._factor: Factorization | None = None
        # Compliance cache (precompute_surface_compliance): columns of the cached
        # nodes S, rows of the nodes Q of every tet touching S.
        self._cache_cols = np.full(mesh.n_nodes, -1, dtype=np.int64)
        self._cache_rows = np.full(mesh.n_nodes, -1, dtype=np.int64)
        self._cache: np.ndarray | None = None
        self._patches: dict[bytes, ContactPatch] = {}

    @staticmethod
    def _check_fixed(mesh: TetMesh, fixed_nodes) -> np.ndarray:
        fixed = np.asarray(fixed_nodes)
        if fixed.dtype == bool:
            if fixed.shape != (mesh.n_nodes,):
                raise BoundaryError(
                    f"a boolean fixed_nodes mask must have shape ({mesh.n_nodes},), got {fixed.shape}"
                )
            fixed = np.flatnonzero(fixed)
        fixed = check_node_ids(fixed.ravel(), mesh.n_nodes, "fixed_nodes", BoundaryError, unique=False)
        if fixed.size == 0:
            raise BoundaryError(
                "no fixed node: the body could move rigidly and its stiffness is singular; "
                "fix the base, e.g. fixed_nodes=np.flatnonzero(mesh.nodes[:, 2] == mesh.nodes[:, 2].min())"
            )
        fixed = np.unique(fixed)
        fixed.setflags(write=False)
        return fixed

    # ------------------------------------------------------------ properties
    @property
    def mesh(self) -> TetMesh:
        """The mesh at rest."""
        return self._mesh

    @property
    def material(self) -> LinearElasticMaterial:
        """The material."""
        return self._material

    @property
    def fixed_nodes(self) -> np.ndarray:
        """(k,) int sorted ids of the fixed nodes (eq. 28)."""
        return self._fixed

    @property
    def fixed_mask(self) -> np.ndarray:
        """(N,) bool, True at fixed nodes."""
        return self._fixed_mask

    @property
    def free_dofs(self) -> np.ndarray:
        """(3N - 3k,) int sorted dofs ``3 * node + axis`` of the non-fixed nodes."""
        return self._free_dofs

    @cached_property
    def stiffness(self) -> sp.csr_matrix:
        """Unconstrained stiffness K, (3N, 3N) csr, N/m (eq. 17)."""
        return assemble_stiffness(self._mesh, self._material)

    @cached_property
    def _strain_matrices(self) -> np.ndarray:
        return element_strain_matrices(self._mesh.nodes, self._mesh.tets)[0]

    @property
    def factorization(self) -> Factorization:
        """The factorisation of K_NN, computed on first use."""
        if self._factor is None:
            k_nn = self.stiffness[self._free_dofs][:, self._free_dofs]
            self._factor = factorize(k_nn, self._solver, ordering=self._free_dof_ordering())
            logger.debug("factorised K_NN (%d dofs) with %s", k_nn.shape[0], self._factor.name)
        return self._factor

    def _free_dof_ordering(self) -> np.ndarray:
        """Nested-dissection permutation of the free dofs (3 dofs of a node kept together)."""
        free_nodes = np.flatnonzero(~self._fixed_mask)
        graph = node_adjacency(self._mesh.tets, self._mesh.n_nodes)[free_nodes][:, free_nodes]
        order = nested_dissection(self._mesh.nodes[free_nodes], graph)
        return (3 * order[:, None] + np.arange(3)).ravel()

    @property
    def solver(self) -> str:
        """Name of the factorisation in use (``"cholmod"`` or ``"scipy"``); factorises if needed."""
        return self.factorization.name

    # ------------------------------------------------------------ compliance
    def _node_ids(self, node_ids, name: str = "node_ids") -> np.ndarray:
        return check_node_ids(node_ids, self._mesh.n_nodes, name, FemError)

    def compliance_columns(self, node_ids) -> np.ndarray:
        """Columns of the compliance for the dofs of some free nodes.

        Parameters
        ----------
        node_ids : (k,) int
            Non-fixed node ids.

        Returns
        -------
        (3N, 3k) float, m/N
            ``C[:, dofs(node_ids)]`` with ``C = K_NN^-1`` padded by zero rows at fixed
            dofs: column ``3 i + a`` is the displacement of every dof under a unit
            force on axis a of node ``node_ids[i]`` (others loaded by nothing).
        """
        ids = self._node_ids(node_ids)
        if self._fixed_mask[ids].any():
            bad = ids[self._fixed_mask[ids]][0]
            raise BoundaryError(f"node {bad} is fixed: it has no compliance")
        dofs = (3 * ids[:, None] + np.arange(3)).ravel()
        out = np.zeros((self._mesh.n_dofs, dofs.size))
        for start in range(0, dofs.size, _SOLVE_BLOCK):
            cols = dofs[start : start + _SOLVE_BLOCK]
            rhs = np.zeros((self._free_dofs.size, cols.size))
            rhs[self._free_index[cols], np.arange(cols.size)] = 1.0
            out[self._free_dofs, start : start + cols.size] = self.factorization.solve(rhs)
        return out

    def precompute_surface_compliance(self, node_ids=None) -> None:
        """Cache the compliance of a surface region so later prints there cost ~no solve.

        Stores ``C[Q, S]`` where S are the given nodes and Q the nodes of every tet
        touching S; then :meth:`compliance` and the traction method of any print inside
        S are sub-block look-ups. Costs ``3 |S|`` solves once.

        Parameters
        ----------
        node_ids : (s,) int, optional
            Region where prints will land, e.g. the top face; default every non-fixed
            surface node (can be large on fine meshes: give the region).
        """
        if node_ids is None:
            ids = self._mesh.surface_nodes[~self._fixed_mask[self._mesh.surface_nodes]]
        else:
            ids = np.unique(self._node_ids(node_ids))
            ids = ids[~self._fixed_mask[ids]]
        touching = self._mesh.tets[np.isin(self._mesh.tets, ids).any(axis=1)]
        rows = np.unique(np.concatenate([ids, touching.ravel()]))
        columns = self.compliance_columns(ids)
        row_dofs = (3 * rows[:, None] + np.arange(3)).ravel()
        self._cache = columns[row_dofs]
        self._cache_cols[:] = -1
        self._cache_cols[ids] = np.arange(ids.size)
        self._cache_rows[:] = -1
        self._cache_rows[rows] = np.arange(rows.size)
        self._patches.clear()

    def compliance_block(self, row_nodes, col_nodes) -> np.ndarray:
        """Block ``C[dofs(row_nodes), dofs(col_nodes)]`` of the padded compliance, m/N.

        Uses the cache of :meth:`precompute_surface_compliance` when it covers the
        block, otherwise solves for the columns.

        Parameters
        ----------
        row_nodes : (r,) int
        col_nodes : (k,) int, non-fixed

        Returns
        -------
        (3r, 3k) float
        """
        rows = self._node_ids(row_nodes, "row_nodes")
        cols = self._node_ids(col_nodes, "col_nodes")
        if self._cache is not None and (self._cache_cols[cols] >= 0).all() and (self._cache_rows[rows] >= 0).all():
            r = (3 * self._cache_rows[rows][:, None] + np.arange(3)).ravel()
            c = (3 * self._cache_cols[cols][:, None] + np.arange(3)).ravel()
            return self._cache[np.ix_(r, c)]
        row_dofs = (3 * rows[:, None] + np.arange(3)).ravel()
        return self.compliance_columns(cols)[row_dofs]

    def compliance(self, node_ids) -> np.ndarray:
        """Compliance block ``[K_NN^-1]_PP`` of some free nodes.

        Parameters
        ----------
        node_ids : (k,) int

        Returns
        -------
        (3k, 3k) float, m/N, symmetric positive definite; dof ``3 i + axis`` for
        ``node_ids[i]``. Scales as 1/E at fixed nu.
        """
        return self.compliance_block(node_ids, node_ids)

    # ------------------------------------------------------------ prints
    def contact_patch(self, node_ids) -> ContactPatch:
        """The contact print P made of some surface nodes (eq. 27).

        Parameters
        ----------
        node_ids : (p,) int
            Surface, non-fixed, distinct node ids, p >= 3, e.g. from
            :func:`fem.nodes_in_polygon`. Their order sets the row order of every
            displacement and force array of the patch.

        Returns
        -------
        ContactPatch
            Cached: asking twice for the same ids returns the same object.

        Raises
        ------
        PrintError
            Fewer than 3 nodes, duplicates, out of range, not on the surface, or fixed.

        Examples
        --------
        >>> import numpy as np
        >>> from fem import DeformableBody, LinearElasticMaterial, box_mesh
        >>> mesh = box_mesh((1.0, 1.0, 1.0), (4, 4, 4))
        >>> body = DeformableBody(mesh, LinearElasticMaterial(1e6, 0.4), mesh.nodes[:, 2] == 0.0)
        >>> top = np.flatnonzero(mesh.nodes[:, 2] == 1.0)
        >>> body.precompute_surface_compliance(top)      # later prints on top: no solve
        >>> patch = body.contact_patch(top[:10])            # two rows of 5 nodes
        >>> patch.condensed_stiffness.shape, patch.triangles.shape
        ((30, 30), (8, 3))
        """
        ids = np.asarray(node_ids)
        key = ids.tobytes() + str(ids.dtype).encode() if ids.ndim == 1 else None
        if key is not None and key in self._patches:
            return self._patches[key]
        patch = ContactPatch(self, ids)
        if key is not None:
            self._patches[key] = patch
        return patch

    def displacement_under_loads(self, node_ids, forces) -> np.ndarray:
        """Displacement of every node under point loads, from one sparse solve.

        This is the full finite-element system, not a condensed one: it is the
        independent check of any print model built on the compliance.

        Parameters
        ----------
        node_ids : (k,) int
            Distinct non-fixed nodes carrying the loads.
        forces : (k, 3) float
            Forces applied ON the body at those nodes, newtons, body frame.

        Returns
        -------
        (N, 3) float, metres, body frame; 0 at fixed nodes.
        """
        ids = self._node_ids(node_ids)
        if self._fixed_mask[ids].any():
            raise BoundaryError(f"node {ids[self._fixed_mask[ids]][0]} is fixed: a load there does nothing")
        loads = np.asarray(forces, dtype=float)
        if loads.shape != (ids.size, 3) or not np.all(np.isfinite(loads)):
            raise FemError(f"forces must be a finite ({ids.size}, 3) array (one row per node), got shape {loads.shape}")
        rhs = np.zeros(self._mesh.n_dofs)
        rhs[(3 * ids[:, None] + np.arange(3)).ravel()] = loads.ravel()
        u = np.zeros(self._mesh.n_dofs)
        u[self._free_dofs] = self.factorization.solve(rhs[self._free_dofs])
        return u.reshape(-1, 3)

    def displacement_field(self, patch: ContactPatch, displacements: np.ndarray) -> np.ndarray:
        """Displacement of every node when the print is displaced (eqs. 35-36).

        One sparse solve: the print nodes are loaded by ``S_P U_P``, the forces
        that hold them at ``U_P``.

        Parameters
        ----------
        patch : ContactPatch
        displacements : (p, 3) float
            U_P, metres, body frame.

        Returns
        -------
        (N, 3) float, metres
            Exactly ``displacements`` at the print nodes and 0 at fixed nodes.
        """
        u_p = patch._check_displacements(displacements)
        loads = (patch.condensed_stiffness @ u_p.ravel()).reshape(-1, 3)
        u = self.displacement_under_loads(patch.node_ids, loads)
        u[patch.node_ids] = u_p
        return u

    def principal_strains(self, u: np.ndarray) -> np.ndarray:
        """Principal strains of each tet, (M, 3) float, ascending, dimensionless."""
        return np.linalg.eigvalsh(voigt_to_tensor_strain(self.strain(u)))

    def largest_principal_strain(self, u: np.ndarray) -> tuple[float, int]:
        """The largest principal strain magnitude over all tets, and its tet.

        Eigenvalues are computed only where they can be largest: ``|lambda|max`` lies
        between ``|E|_F / sqrt(3)`` and ``|E|_F`` (Frobenius norm), so tets whose norm
        is below the largest norm over sqrt(3) cannot hold the maximum.

        Returns
        -------
        (float, int)
            Strain (dimensionless) and tet index.
        """
        tensors = voigt_to_tensor_strain(self.strain(u))
        norms = np.sqrt(np.einsum("tij,tij->t", tensors, tensors))
        candidates = np.flatnonzero(norms >= norms.max() / np.sqrt(3.0) * (1.0 - 1e-12))
        values = np.abs(np.linalg.eigvalsh(tensors[candidates])).max(axis=1)
        best = int(np.argmax(values))
        return float(values[best]), int(candidates[best])

    # ------------------------------------------------------------ fields
    def _check_field(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.shape != (self._mesh.n_nodes, 3):
            raise FemError(f"displacement field must have shape ({self._mesh.n_nodes}, 3), got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise FemError("displacement field contains NaN or inf")
        return u

    def strain(self, u: np.ndarray) -> np.ndarray:
        """Voigt strain per tet (eq. 24), (M, 6), engineering shears, for u (N, 3) metres."""
        u = self._check_field(u)
        return np.einsum("eij,ej->ei", self._strain_matrices, u[self._mesh.tets].reshape(-1, 12))

    def stress(self, u: np.ndarray) -> np.ndarray:
        """Voigt stress per tet (eq. 58), (M, 6), pascals, for u (N, 3) metres."""
        return self.strain(u) @ self._material.voigt_matrix.T

    def check_small_strain(self, u: np.ndarray, limit: float = 0.05, action: str = "warn") -> float:
        """Check the small-deformation hypothesis of linear elasticity.

        Parameters
        ----------
        u : (N, 3) float
            Displacement field, metres.
        limit : float, optional
            Largest acceptable principal strain magnitude (dimensionless).
        action : {"warn", "raise"}
            Emit a :class:`FemWarning` or raise a :class:`FemError` beyond the limit.

        Returns
        -------
        float
            The largest principal strain magnitude over all tets.
        """
        if action not in ("warn", "raise"):
            raise FemError(f"action must be 'warn' or 'raise', got {action!r}")
        largest, where = self.largest_principal_strain(u)
        if largest > limit:
            message = (
                f"largest strain {largest:.3g} (tet {where}) exceeds the small-strain limit "
                f"{limit:g}: linear elasticity is not valid there; reduce the displacement"
            )
            if action == "raise":
                raise FemError(message)
            warnings.warn(message, FemWarning, stacklevel=2)
        return largest

    def nodal_forces(self, u: np.ndarray) -> np.ndarray:
        """External nodal forces ``K u`` needed to hold the field u, (N, 3) newtons, on the body."""
        u = self._check_field(u)
        return (self.stiffness @ u.ravel()).reshape(-1, 3)

    def fixed_reactions(self, u: np.ndarray) -> np.ndarray:
        """Forces the supports exert on the body at the fixed nodes.

        Parameters
        ----------
        u : (N, 3) float
            Displacement field, metres.

        Returns
        -------
        (k, 3) float, newtons, body frame, rows in :attr:`fixed_nodes` order.
        """
        return self.nodal_forces(u)[self._fixed]

    def write_vtu(self, path: str | os.PathLike, u: np.ndarray, deformed: bool = True) -> None:
        """Write the body for ParaView: displacement, stress and von Mises stress.

        Parameters
        ----------
        path : str or path-like
            Output file (``.vtu``, or any meshio format).
        u : (N, 3) float
            Displacement field, metres.
        deformed : bool, optional
            Write the deformed node positions (rest positions + u); the point field
            ``displacement`` is written either way.
        """
        u = self._check_field(u)
        stress = self.stress(u)
        write_mesh(
            path,
            self._mesh,
            points=self._mesh.nodes + u if deformed else None,
            point_data={"displacement": u},
            cell_data={"stress": stress, "von_mises": von_mises(stress), "strain": self.strain(u)},
        )

    def __repr__(self) -> str:
        return (
            f"DeformableBody({self._mesh!r}, E={self._material.young_modulus:g} Pa, "
            f"nu={self._material.poisson_ratio:g}, fixed nodes={self._fixed.size})"
        )
