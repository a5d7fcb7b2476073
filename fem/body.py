"""A deformable body: mesh, material, fixed base and one factorisation of K_NN."""

from __future__ import annotations

import logging
import os
import warnings
from collections import OrderedDict
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .assembly import assemble_stiffness, shape_gradients
from .cache import DiskCache, cache_digest, default_cache
from .deadline import check_deadline
from .errors import BoundaryError, FemError, FemWarning
from .io import write_mesh
from .material import LinearElasticMaterial
from .mesh import TetMesh, tet_signed_volumes
from .ordering import nested_dissection, node_adjacency
from .patch import ContactPatch, check_node_ids
from .solvers import SOLVERS, Factorization, factorize, resolve_solver
from .strain_average import BallAverages, voigt_to_tensor_strain

__all__ = ["DeformableBody", "von_mises", "voigt_to_tensor_strain", "rotate_voigt"]

logger = logging.getLogger(__name__)

# Full compliance columns kept in memory (3N x 3 floats per node: 0.9 MB at 13k
# nodes, so about 280 nodes, a dozen palm prints); older ones are dropped and read
# back from the disk cache, or solved again, when asked for.
_COLUMN_MEMORY_BYTES = 256 * 2**20

# Contact patches kept for prints asked for again (contact_patch), least recently used
# dropped: each holds its dense compliance, factors and strain sets (6-10 MB on a 2k-node
# rubber mat), and a plan meets a new node set at almost every stance (a user's mat: 98
# patches asked for in 100 expansions, 86 of them distinct, 878 MB held unbounded and
# kept after the plan; 16 kept: 6 more built, each from compliance columns in memory).
_PATCHES_KEPT = 16

# Loads on at most this many nodes are applied through the nodes' compliance
# columns (a product, after 3 solves per node that prints have usually paid and the
# disk cache keeps); more nodes take one sparse solve with the factorisation.
_COLUMN_LOAD_LIMIT = 256


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


def rotate_voigt(voigt: np.ndarray, rotation: np.ndarray, engineering_shears: bool) -> np.ndarray:
    """Symmetric tensors in Voigt form expressed in a rotated frame, ``R T R^T``.

    Parameters
    ----------
    voigt : (M, 6) float
        (11, 22, 33, 12, 13, 23) in the original frame.
    rotation : (3, 3) float
        Rotation from the original frame to the new one.
    engineering_shears : bool
        True for strains whose shears are ``g = 2 e`` (as :meth:`DeformableBody.strain`),
        False for stresses.

    Returns
    -------
    (M, 6) float, the same convention, new frame.

    Examples
    --------
    >>> quarter_turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    >>> rotate_voigt(np.array([[1.0, 2.0, 3.0, 0.0, 0.0, 0.0]]), quarter_turn, False).tolist()
    [[2.0, 1.0, 3.0, 0.0, 0.0, 0.0]]
    """
    shear_scale = 1.0 if engineering_shears else 2.0
    values = np.array(voigt, dtype=float)
    values[:, 3:] *= shear_scale  # to engineering shears, voigt_to_tensor_strain's input
    tensor = voigt_to_tensor_strain(values)
    turned = np.einsum("ij,mjk,lk->mil", rotation, tensor, rotation)
    rows, columns = (0, 0, 1), (1, 2, 2)
    return np.concatenate(
        [turned[:, [0, 1, 2], [0, 1, 2]], 2.0 * turned[:, rows, columns] / shear_scale], axis=1
    )


class DeformableBody:
    """A linear elastic solid with a fixed part of its boundary (eq. 28).

    The free-dof stiffness K_NN (N: every dof not fixed, prints included) is factorised
    once, lazily; every contact print then reuses it: the print's condensed stiffness
    is the inverse of the compliance block ``[K_NN^-1]_PP`` (a Schur complement
    identity), so a print costs a few solves, or nothing but a sub-block and a small
    dense inverse after :meth:`precompute_surface_compliance`.

    The compliance columns of each node a print uses (three solves, one per axis) are
    kept, in memory and in a disk cache (:mod:`fem.cache`) shared by every process
    working on the same body, together with the assembled stiffness; a body met
    again needs neither assembly nor factorisation for those nodes. Each node's
    columns come from their own solve, so cached and freshly solved values are the
    same bits.

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
    cache : bool or DiskCache, optional
        Disk cache of the stiffness and compliance columns: True (default) for
        :func:`fem.cache.default_cache` (``$SOFTCBM_CACHE_DIR`` or ``~/.cache/softcbm``,
        ``SOFTCBM_CACHE=off`` turns it off), False for none, or a given cache.

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
        cache: bool | DiskCache = True,
    ) -> None:
        if not isinstance(mesh, TetMesh):
            raise FemError(f"mesh must be a TetMesh, got {type(mesh).__name__}")
        if not isinstance(material, LinearElasticMaterial):
            raise FemError(f"material must be a LinearElasticMaterial, got {type(material).__name__}")
        if solver not in SOLVERS:
            raise FemError(f"unknown solver {solver!r}; choose one of {SOLVERS}")
        if cache is True:
            cache = default_cache()
        elif cache is False:
            cache = None
        elif not isinstance(cache, DiskCache):
            raise FemError(f"cache must be True, False or a fem.cache.DiskCache, got {type(cache).__name__}")
        self._disk_cache = cache
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
        self._patches: OrderedDict[bytes, ContactPatch] = OrderedDict()  # least recently used first
        # Full compliance columns per node, least recently used first.
        self._columns: OrderedDict[int, np.ndarray] = OrderedDict()
        # The last displacement_under_loads: (its loaded nodes' and loads' bytes, field).
        self._last_field: tuple[bytes, np.ndarray] | None = None
        # Self-weight fields by entry name (density and gravity).
        self._self_weight: dict[str, np.ndarray] = {}

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

    @property
    def disk_cache(self) -> DiskCache | None:
        """The disk cache of this body's stiffness and compliance columns, or None."""
        return self._disk_cache

    @cached_property
    def cache_key(self) -> str:
        """Digest of everything the cached values depend on (see :func:`fem.cache.cache_digest`).

        Mesh arrays, elasticity matrix, fixed nodes and the factorisation in use.
        """
        return cache_digest(
            {
                "nodes": self._mesh.nodes,
                "tets": self._mesh.tets,
                "elasticity": self._material.voigt_matrix,
                "fixed": self._fixed,
            },
            {"solver": resolve_solver(self._solver)},
        )

    @cached_property
    def mesh_key(self) -> str:
        """Digest of the mesh alone: what depends on its geometry only (the strain's ball
        means), shared by every material and fixed set on it (a stiffness sweep)."""
        return cache_digest({"nodes": self._mesh.nodes, "tets": self._mesh.tets}, {})

    def _load_entry(self, name: str, key: str | None = None) -> dict[str, np.ndarray] | None:
        if self._disk_cache is None:
            return None
        return self._disk_cache.load(self.cache_key if key is None else key, name)

    def _store_entry(self, name: str, arrays: dict[str, np.ndarray], key: str | None = None) -> None:
        if self._disk_cache is not None:
            self._disk_cache.store(self.cache_key if key is None else key, name, arrays)

    @cached_property
    def stiffness(self) -> sp.csr_matrix:
        """Unconstrained stiffness K, (3N, 3N) csr, N/m (eq. 17); read from the disk cache if there."""
        known = self._load_csr("stiffness", self._mesh.n_dofs)
        if known is not None:
            return known
        k = assemble_stiffness(self._mesh, self._material)
        self._store_csr("stiffness", k)
        return k

    def _load_csr(self, name: str, n: int, key: str | None = None) -> sp.csr_matrix | None:
        """An (n, n) csr matrix from the disk cache (under ``key``, :attr:`cache_key` by default), or None."""
        entry = self._load_entry(name, key)
        if entry is None or not {"data", "indices", "indptr"} <= set(entry):
            return None
        data, indices, indptr = entry["data"], entry["indices"], entry["indptr"]
        # The digest names the inputs; the shapes guard against an entry that
        # passed its checks but does not describe an (n, n) matrix.
        if (
            data.dtype == np.float64
            and indptr.shape == (n + 1,)
            and indptr[0] == 0
            and bool(np.all(np.diff(indptr) >= 0))
            and data.shape == indices.shape == (int(indptr[-1]),)
            and (indices.size == 0 or (0 <= indices.min() and indices.max() < n))
        ):
            # Writable copies: scipy may sort or sum entries in place.
            return sp.csr_matrix((data.copy(), indices.copy(), indptr.copy()), shape=(n, n))
        return None

    def _store_csr(self, name: str, matrix: sp.csr_matrix, key: str | None = None) -> None:
        self._store_entry(name, {"data": matrix.data, "indices": matrix.indices, "indptr": matrix.indptr}, key)

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

    def _check_free(self, ids: np.ndarray) -> None:
        if self._fixed_mask[ids].any():
            bad = ids[self._fixed_mask[ids]][0]
            raise BoundaryError(f"node {bad} is fixed: it has no compliance")

    def _solve_node_columns(self, node: int) -> np.ndarray:
        """The 3 compliance columns of one node from one solve with 3 right-hand sides.

        One node per solve, whatever the caller asks for: the values then do not
        depend on which other nodes are solved with them (SuperLU rounds a block of
        right-hand sides differently from its columns one by one), so columns read
        from the disk cache are the bits a fresh solve gives.
        """
        dofs = 3 * node + np.arange(3)
        rhs = np.zeros((self._free_dofs.size, 3))
        rhs[self._free_index[dofs], np.arange(3)] = 1.0
        out = np.zeros((self._mesh.n_dofs, 3))
        out[self._free_dofs] = self.factorization.solve(rhs)
        return out

    def _node_columns(self, ids: np.ndarray) -> list[np.ndarray]:
        """Full compliance columns ``C[:, dofs(node)]``, (3N, 3) read-only, of free nodes.

        From memory, else the disk cache, else solved (and then stored in both).
        """
        found: list[np.ndarray | None] = [None] * ids.size
        for i, node in enumerate(ids.tolist()):
            if node in self._columns:
                self._columns.move_to_end(node)
                found[i] = self._columns[node]
        for i, node in enumerate(ids.tolist()):
            if found[i] is not None:
                continue
            entry = self._load_entry(f"columns-{node}")
            columns = None if entry is None else entry["columns"]
            # The digest names the inputs; the checks guard against an entry that
            # passed them but is not a node's columns.
            if columns is not None and not (
                columns.shape == (self._mesh.n_dofs, 3)
                and columns.dtype == np.float64
                and int(entry["node"]) == node
            ):
                columns = None
            if columns is None:
                ready = sum(entry is not None for entry in found)
                check_deadline(f"the compliance columns of {ids.size} nodes of a print ({ready} ready)")
                columns = self._solve_node_columns(node)
                self._store_entry(f"columns-{node}", {"columns": columns, "node": np.int64(node)})
            columns.setflags(write=False)
            found[i] = columns
            self._remember_columns(node, columns)
        return found

    def _remember_columns(self, node: int, columns: np.ndarray) -> None:
        self._columns[node] = columns
        while len(self._columns) > 1 and len(self._columns) * columns.nbytes > _COLUMN_MEMORY_BYTES:
            self._columns.popitem(last=False)

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
        self._check_free(ids)
        if ids.size == 0:
            return np.zeros((self._mesh.n_dofs, 0))
        return np.hstack(self._node_columns(ids))

    def precompute_surface_compliance(self, node_ids=None) -> None:
        """Cache the compliance of a surface region so later prints there cost ~no solve.

        Stores ``C[Q, S]`` in memory, where S are the given nodes and Q the nodes of
        every tet touching S; then :meth:`compliance` and the traction method of any
        print inside S are sub-block look-ups. Costs ``3 |S|`` solves once (0.1 s
        per node on a 13k-node body); prints alone fill the disk cache lazily,
        only with the nodes they use.

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
        row_dofs = (3 * rows[:, None] + np.arange(3)).ravel()
        # Solved node by node without keeping full columns: only the Q rows stay.
        cache = np.empty((row_dofs.size, 3 * ids.size))
        for i, node in enumerate(ids.tolist()):
            cache[:, 3 * i : 3 * i + 3] = self._solve_node_columns(node)[row_dofs]
        self._cache = cache
        self._cache_cols[:] = -1
        self._cache_cols[ids] = np.arange(ids.size)
        self._cache_rows[:] = -1
        self._cache_rows[rows] = np.arange(rows.size)
        self._patches.clear()

    def compliance_block(self, row_nodes, col_nodes) -> np.ndarray:
        """Block ``C[dofs(row_nodes), dofs(col_nodes)]`` of the padded compliance, m/N.

        Uses the cache of :meth:`precompute_surface_compliance` when it covers the
        block, otherwise the nodes' columns (memory, disk cache, or solves).

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
        self._check_free(cols)
        # Each column node's (N, 3, 3) rows gathered whole, into contiguous memory, then
        # laid out once: 3.6x faster than a fancy index per node on dof rows (a foam
        # mat's 171 print nodes against 1,037 ball nodes: 35 -> 10 ms), the same numbers.
        n = self._mesh.n_nodes
        stacked = np.empty((cols.size, rows.size, 3, 3))
        for i, columns in enumerate(self._node_columns(cols)):
            np.take(columns.reshape(n, 3, 3), rows, axis=0, out=stacked[i], mode="clip")  # rows checked above: no buffer
        return stacked.transpose(1, 2, 0, 3).reshape(3 * rows.size, 3 * cols.size)

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
    def contact_patch(self, node_ids, coverage=None) -> ContactPatch:
        """The contact print P made of some surface nodes (eq. 27).

        Parameters
        ----------
        node_ids : (p,) int
            Surface, non-fixed, distinct node ids, p >= 3, e.g. from
            :func:`fem.nodes_in_polygon`. Their order sets the row order of every
            displacement and force array of the patch.
        coverage : (p,) float, optional
            Covered share of each node's shape function (:func:`fem.print_coverage`); see
            :class:`ContactPatch`.

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
        if key is not None and coverage is not None:
            key += b"coverage" + np.asarray(coverage, dtype=float).tobytes()
        if key is not None and key in self._patches:
            self._patches.move_to_end(key)
            return self._patches[key]
        patch = ContactPatch(self, ids, coverage)
        if key is not None:
            self._patches[key] = patch
            while len(self._patches) > _PATCHES_KEPT:
                self._patches.popitem(last=False)
        return patch

    def displacement_under_loads(self, node_ids, forces) -> np.ndarray:
        """Displacement of every node under point loads, from one sparse solve.

        This is the full finite-element system, not a condensed one: it is the
        independent check of any print model built on the compliance. Loads on up
        to 256 nodes are superposed from the nodes' full compliance columns (each
        the exact solution of the full system under a unit load; read from the disk
        cache when there, so a body met again needs no factorisation); more nodes
        take one sparse solve.

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
        ids, loads = self._point_loads(node_ids, forces)
        # A posture solver's check and its result's field ask for the same loads in turn:
        # the last field is kept (a copy is returned, callers may write into theirs).
        key = ids.astype(np.int64).tobytes() + np.ascontiguousarray(loads).tobytes()
        last = self._last_field  # read once: another thread may replace it
        if last is not None and last[0] == key:
            return last[1].copy()
        field = self._superposed(ids, loads, None)
        self._last_field = (key, field.copy())
        return field

    def displacement_at(self, nodes, node_ids, forces) -> np.ndarray:
        """:meth:`displacement_under_loads` at ``nodes`` only, the same bits, in a fraction
        of its time where few loads are superposed (a strain near a ball reads a few
        hundred of a mat's 15k nodes).

        Parameters
        ----------
        nodes : (m,) int
            The nodes whose displacement is wanted.
        node_ids, forces
            As :meth:`displacement_under_loads`.

        Returns
        -------
        (m, 3) float, metres, body frame.
        """
        ids, loads = self._point_loads(node_ids, forces)
        return self._superposed(ids, loads, check_node_ids(nodes, self._mesh.n_nodes, "nodes", FemError, unique=False))

    def _point_loads(self, node_ids, forces) -> tuple[np.ndarray, np.ndarray]:
        """Checked ``(ids, loads)`` of :meth:`displacement_under_loads`'s arguments."""
        ids = self._node_ids(node_ids)
        if self._fixed_mask[ids].any():
            raise BoundaryError(f"node {ids[self._fixed_mask[ids]][0]} is fixed: a load there does nothing")
        loads = np.asarray(forces, dtype=float)
        if loads.shape != (ids.size, 3) or not np.all(np.isfinite(loads)):
            raise FemError(f"forces must be a finite ({ids.size}, 3) array (one row per node), got shape {loads.shape}")
        return ids, loads

    def _superposed(self, ids, loads, at) -> np.ndarray:
        """The field under ``loads`` at ``ids``, (N, 3), or its rows ``at`` (m, 3)."""
        rows = None if at is None else (3 * at[:, None] + np.arange(3)).ravel()
        u = np.zeros(self._mesh.n_dofs if rows is None else rows.size)
        if ids.size <= _COLUMN_LOAD_LIMIT:
            # Elementwise sums in a fixed order (no BLAS reduction), so the field is
            # the same bits whichever path gave the columns, and at any of its rows.
            for columns, load in zip(self._node_columns(ids), loads):
                if rows is not None:
                    columns = columns[rows]
                for axis in range(3):
                    u += columns[:, axis] * load[axis]
        else:
            rhs = np.zeros(self._mesh.n_dofs)
            rhs[(3 * ids[:, None] + np.arange(3)).ravel()] = loads.ravel()
            full = np.zeros(self._mesh.n_dofs)
            full[self._free_dofs] = self.factorization.solve(rhs[self._free_dofs])
            u = full if rows is None else full[rows]
        return u.reshape(-1, 3)

    def self_weight_displacement(self, gravity) -> np.ndarray:
        """Displacement of every node under the body's own weight (eqs. 2 and 6 with
        ``rho f = rho g``), from one sparse solve; kept, and in the disk cache.

        The body force enters eq. (6) through the consistent loads of linear tets:
        ``rho g V_e / 4`` at each corner of tet e. The posture problem leaves it out
        (eq. 31): a scene's soft body is meshed as it rests under its own weight, and
        by superposition its weight then changes no print force. What it does change
        is the strain the body already holds, which this field gives.

        Parameters
        ----------
        gravity : (3,) float
            Acceleration of gravity, m/s^2, body frame (e.g. ``(0, 0, -9.81)``).

        Returns
        -------
        (N, 3) float, metres, body frame; 0 at fixed nodes, 0 everywhere if the
        material's density is 0.
        """
        g = np.asarray(gravity, dtype=float) + 0.0  # + 0.0: -0.0 and 0.0 name one entry
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise FemError(f"gravity must be a finite (3,) vector in m/s^2, got {np.asarray(gravity).tolist()!r}")
        density = self._material.density
        if density == 0.0 or not g.any():
            return np.zeros((self._mesh.n_nodes, 3))
        # The density and gravity name the entry; the mesh, elasticity and fixed set the digest.
        name = "self_weight_" + cache_digest({"g": g}, {"density": repr(float(density))})[:16]
        known = self._self_weight.get(name)
        if known is None:
            entry = self._load_entry(name)
            known_u = None if entry is None else entry.get("u")
            if known_u is not None and known_u.dtype == np.float64 and known_u.shape == (self._mesh.n_nodes, 3):
                known = known_u.copy()
            else:
                volumes = np.abs(tet_signed_volumes(self._mesh.nodes, self._mesh.tets))
                loads = np.zeros(self._mesh.n_nodes)
                np.add.at(loads, self._mesh.tets.ravel(), np.repeat(density * volumes / 4.0, 4))
                rhs = (loads[:, None] * g).ravel()
                u = np.zeros(self._mesh.n_dofs)
                u[self._free_dofs] = self.factorization.solve(rhs[self._free_dofs])
                known = u.reshape(-1, 3)
                self._store_entry(name, {"u": known})
            known.setflags(write=False)
            self._self_weight[name] = known
        return known.copy()

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

    def largest_principal_strain(self, u: np.ndarray, radius: float = 0.0) -> tuple[float, int]:
        """The largest principal strain magnitude over all tets, and its tet.

        Parameters
        ----------
        u : (N, 3) float
            Displacement field, metres.
        radius : float, optional
            Metres: the strain of each tet is the volume-weighted mean over the
            tets whose centroids lie within ``radius`` of its own
            (:class:`fem.strain_average.BallAverages`); 0 (default) each tet's own.
            Under a rigid print's edge the tets' own strain grows without bound as
            the mesh is refined; the mean over a fixed ball converges.

        Returns
        -------
        (float, int)
            Strain (dimensionless) and the (centre) tet's index.
        """
        return self.strain_averages.largest_principal(self.strain(u), radius)

    @cached_property
    def strain_averages(self) -> BallAverages:
        """Ball means of per-tet values over this mesh (built on first use); the matrix of
        every ball mean is kept in the disk cache (a planner's process meets a body anew
        at every plan: 0.07-0.3 s a plan to build it again, 2.4 s on quadruped-foam's
        banded foam), under the mesh's own key: a stiffness sweep built it at every E."""
        n = self._mesh.n_tets
        return BallAverages(
            self._mesh.nodes, self._mesh.tets,
            cache=(lambda radius: self._load_csr(f"ball_means_{radius!r}", n, self.mesh_key),
                   lambda radius, matrix: self._store_csr(f"ball_means_{radius!r}", matrix, self.mesh_key)),
        )

    # ------------------------------------------------------------ fields
    def _check_field(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.shape != (self._mesh.n_nodes, 3):
            raise FemError(f"displacement field must have shape ({self._mesh.n_nodes}, 3), got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise FemError("displacement field contains NaN or inf")
        return u

    def strain(self, u: np.ndarray, tets=None) -> np.ndarray:
        """Voigt strain per tet (eq. 24), (M, 6), engineering shears, for u (N, 3) metres;
        of the given tets only (k,) int, (k, 6), when ``tets`` is given."""
        u = self._check_field(u)
        corners, gradients = self._strain_operands
        if tets is not None:
            tets = np.asarray(tets, dtype=np.int64)
            corners, gradients = corners[:, tets], gradients[:, :, tets]
        # (3, 4, M): u_k,i of each tet's corner k; np.take on rows laid out contiguously (fancy
        # indexing of u.T gathered the same numbers in five times the time: 1.2 ms on 34,086 tets).
        nodal = np.take(np.ascontiguousarray(u.T), corners, axis=1)
        # Displacement gradient du_i/dx_j = sum_k u_k,i dN_k/dx_j, then its symmetric part,
        # one component at a time over all tets (contiguous arrays), the corners summed in
        # turn: the same bits as einsum("eki,ekj->eij") in a third of its time (8.6 against
        # 23 ms on 55,296 tets).
        def g(i, j):
            total = nodal[i, 0] * gradients[0, j]
            for k in range(1, 4):
                total += nodal[i, k] * gradients[k, j]
            return total

        return np.stack([g(0, 0), g(1, 1), g(2, 2), g(0, 1) + g(1, 0), g(0, 2) + g(2, 0), g(1, 2) + g(2, 1)], axis=1)

    @cached_property
    def _strain_operands(self) -> tuple[np.ndarray, np.ndarray]:
        """The tets' corners (4, M) and shape-function gradients (4, 3, M), laid out for :meth:`strain`.

        The gradients, not the (M, 6, 12) strain matrices: 9x less to build and hold
        (164 MB on a 285k-tet body), and the strain needs no more.
        """
        gradients = shape_gradients(self._mesh.nodes, self._mesh.tets)[0]  # (M, 4, 3)
        return np.ascontiguousarray(self._mesh.tets.T), np.ascontiguousarray(gradients.transpose(1, 2, 0))

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

    def write_vtu(
        self,
        path: str | os.PathLike,
        u: np.ndarray,
        deformed: bool = False,
        transform_body_to_output: np.ndarray | None = None,
    ) -> None:
        """Write the body for ParaView: displacement, stress, strain and von Mises stress.

        By default the points are the rest positions and ``displacement`` a point
        field, ParaView's convention: its Warp By Vector filter then shows the
        deformed body once (on deformed points it would add the displacement twice).

        Parameters
        ----------
        path : str or path-like
            Output file (``.vtu``, or any meshio format).
        u : (N, 3) float
            Displacement field, metres, body frame.
        deformed : bool, optional
            Write the deformed node positions (rest positions + u) instead; the point
            field ``displacement`` is written either way.
        transform_body_to_output : (4, 4) float, optional
            Rigid placement of the body frame in the frame the file is written in
            (e.g. the world): points are placed by it, the displacement (N, 3) and
            the Voigt stress and strain (M, 6; strain with engineering shears) are
            rotated by it. Default: the body frame itself.
        """
        u = self._check_field(u)
        stress, strain = self.stress(u), self.strain(u)
        points = self._mesh.nodes + u if deformed else np.asarray(self._mesh.nodes)
        if transform_body_to_output is not None:
            transform = np.asarray(transform_body_to_output, dtype=float)
            if transform.shape != (4, 4):
                raise FemError(f"transform_body_to_output must be a (4, 4) matrix, got shape {transform.shape}")
            rotation = transform[:3, :3]
            if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0.0:
                raise FemError("transform_body_to_output must be a rigid transform (a rotation and a translation)")
            points = points @ rotation.T + transform[:3, 3]
            u = u @ rotation.T
            stress = rotate_voigt(stress, rotation, engineering_shears=False)
            strain = rotate_voigt(strain, rotation, engineering_shears=True)
        write_mesh(
            path,
            self._mesh,
            points=points,
            point_data={"displacement": u},
            cell_data={"stress": stress, "von_mises": von_mises(stress), "strain": strain},
        )

    def __repr__(self) -> str:
        return (
            f"DeformableBody({self._mesh!r}, E={self._material.young_modulus:g} Pa, "
            f"nu={self._material.poisson_ratio:g}, fixed nodes={self._fixed.size})"
        )
