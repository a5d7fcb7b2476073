"""Contact print: condensed stiffness and reaction forces on the robot (eqs. 27, 36-44)."""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from .assembly import element_strain_matrices
from .dense import single_threaded_blas
from .errors import FemError, PrintError
from .strain_average import frobenius_norms

if TYPE_CHECKING:  # pragma: no cover
    from .body import DeformableBody

__all__ = ["ContactPatch", "check_node_ids", "VOIGT_TO_TENSOR"]

METHODS = ("consistent", "traction")

# ContactPatch.strained_centres bounds the ball means through the hot tets' columns of
# the averaging weights while those columns hold at most this share of the weights'
# stored entries (a count of entries, not of weight), else through the product of every
# column with the tets' norms.
_HOT_SHARE = 0.125

# VOIGT_TO_TENSOR[i, j, v]: sigma_ij = sum_v VOIGT_TO_TENSOR[i, j, v] {sigma}_v; the
# duplication matrix D of eq. (51) reshaped to (3, 3, 6).
VOIGT_TO_TENSOR = np.zeros((3, 3, 6))
for _v, (_i, _j) in enumerate(((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))):
    VOIGT_TO_TENSOR[_i, _j, _v] = VOIGT_TO_TENSOR[_j, _i, _v] = 1.0
VOIGT_TO_TENSOR.setflags(write=False)


def check_node_ids(node_ids, n_nodes: int, name: str, error: type[FemError], unique: bool = True) -> np.ndarray:
    """Validate node ids: 1-D integers in ``[0, n_nodes)``, distinct if ``unique``.

    Returns
    -------
    (k,) int64 copy.
    """
    ids = np.asarray(node_ids)
    if ids.ndim != 1:
        raise error(f"{name} must be a 1-D array of node ids, got shape {ids.shape}")
    if ids.size and not np.issubdtype(ids.dtype, np.integer):
        raise error(f"{name} must hold integer node ids, got dtype {ids.dtype}")
    ids = ids.astype(np.int64)
    out = np.flatnonzero((ids < 0) | (ids >= n_nodes))
    if out.size:
        raise error(f"{name} has node id {ids[out[0]]} outside [0, {n_nodes - 1}]")
    if unique and np.unique(ids).size != ids.size:
        values, counts = np.unique(ids, return_counts=True)
        raise error(f"{name} has duplicate node ids {values[counts > 1].tolist()}")
    return ids


def _skew(v: np.ndarray) -> np.ndarray:
    """(..., 3) vectors to (..., 3, 3) cross-product matrices: skew(a) @ b = a x b."""
    s = np.zeros(v.shape[:-1] + (3, 3))
    s[..., 0, 1], s[..., 0, 2] = -v[..., 2], v[..., 1]
    s[..., 1, 0], s[..., 1, 2] = v[..., 2], -v[..., 0]
    s[..., 2, 0], s[..., 2, 1] = -v[..., 1], v[..., 0]
    return s


class ContactPatch:
    """The contact print P on a deformable body: a set of surface nodes (eq. 27).

    Everything is linear in the print displacements U_P, so each method of computing
    forces reduces to one dense (3p, 3p) matrix R, computed once and cached:
    ``forces_on_robot.ravel() = R @ U_P.ravel()``, and R is the exact Jacobian.

    Sign convention: forces are those each print node exerts ON THE ROBOT, the
    opposite of the forces the robot applies to the body. Pressing a print down into
    the top face gives forces along +z.

    Build it with :meth:`DeformableBody.contact_patch`.

    Coverage (a print whose edges cross surface cells, :func:`fem.print_coverage`): a
    node whose shape function the robot's polygon covers by a share ``w < 1`` is coupled to
    the robot through a series compliance ``(1 - w) / w`` times its own compliance
    block ``C_ii``: fully covered nodes follow the robot, barely covered ones carry
    almost nothing, and the print's force changes continuously as it moves over the
    mesh. Measured on soft boxes (bench/results/mesh_convergence.md): a print's force
    varies by under 1 % with its placement on the default mesh, where the nodes
    inside the polygon alone vary by 3-19 %. The consistent reaction is then
    ``-(C + D)^-1``, D the block-diagonal coupling (:attr:`link_compliance`).

    Parameters
    ----------
    body : DeformableBody
    node_ids : (p,) int
        Distinct, non-fixed surface nodes, p >= 3.
    coverage : (p,) float, optional
        Covered share of each node's shape function, in (0, 1]; all 1 by default (every
        node follows the robot: the paper's print).
    """

    def __init__(self, body: DeformableBody, node_ids, coverage=None) -> None:
        mesh = body.mesh
        ids = check_node_ids(node_ids, mesh.n_nodes, "print node_ids", PrintError)
        if ids.size < 3:
            raise PrintError(
                f"a print needs at least 3 nodes, got {ids.size}; enlarge the contact polygon "
                "or refine the mesh under it"
            )
        off = ids[~mesh.is_surface_node[ids]]
        if off.size:
            raise PrintError(
                f"print node {off[0]} (at {mesh.nodes[off[0]].tolist()}) is not on the body surface; "
                "a print is made of surface nodes (see fem.nodes_in_polygon)"
            )
        fixed = ids[body.fixed_mask[ids]]
        if fixed.size:
            raise PrintError(f"print node {fixed[0]} is fixed; a print cannot overlap the fixed base")
        ids.setflags(write=False)
        if coverage is not None:
            coverage = np.array(coverage, dtype=float)
            if coverage.shape != ids.shape:
                raise PrintError(f"coverage must have shape {ids.shape}, one fraction per print node, got {coverage.shape}")
            if not np.all((coverage > 0.0) & (coverage <= 1.0)):
                raise PrintError("coverage fractions must lie in (0, 1]; leave out nodes the print does not cover")
            coverage = None if np.all(coverage == 1.0) else coverage
            if coverage is not None:
                coverage.setflags(write=False)
        self._body = body
        self._ids = ids
        self._coverage = coverage
        local = np.full(mesh.n_nodes, -1, dtype=np.int64)
        local[ids] = np.arange(ids.size)
        self._local = local
        self._tet_maps = {}  # ((radius, also), tet in the strain set) -> (12, 3p) map of its nodes (_member_map)
        self._strain_sets = {}  # (radius, also) -> what neighbour_strains needs (_strain_set)
        self._weight_csc = {}  # (radius, also) -> a strain set's averaging weights by column
        # eqs. (38)-(39): surface triangles whose three nodes are all in P.
        inside = (local[mesh.surface_triangles] >= 0).all(axis=1)
        self._tri_global = np.flatnonzero(inside)
        self._cache: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------ geometry
    @property
    def body(self) -> DeformableBody:
        """The body the print lies on."""
        return self._body

    @property
    def node_ids(self) -> np.ndarray:
        """(p,) int global node ids; row i of every (p, 3) array is node ``node_ids[i]``."""
        return self._ids

    @property
    def n_nodes(self) -> int:
        """Number of print nodes p."""
        return self._ids.size

    @property
    def coverage(self) -> np.ndarray:
        """(p,) float: the covered share of each node's shape function (all 1 for the paper's print)."""
        return np.ones(self._ids.size) if self._coverage is None else self._coverage

    @property
    def points(self) -> np.ndarray:
        """(p, 3) float rest positions of the print nodes, metres, body frame."""
        return self._body.mesh.nodes[self._ids]

    @property
    def triangles(self) -> np.ndarray:
        """(T, 3) int LOCAL indices (into ``node_ids``) of the print triangles (eqs. 38-39)."""
        return self._local[self._body.mesh.surface_triangles[self._tri_global]]

    @property
    def triangle_tets(self) -> np.ndarray:
        """(T,) int the tet owning each print triangle."""
        return self._body.mesh.surface_triangle_tets[self._tri_global]

    @property
    def triangle_normals(self) -> np.ndarray:
        """(T, 3) float unit outward normals n_e at rest, body frame."""
        return self._body.mesh.surface_normals[self._tri_global]

    @property
    def triangle_areas(self) -> np.ndarray:
        """(T,) float areas alpha_e, square metres."""
        return self._body.mesh.surface_areas[self._tri_global]

    @cached_property
    def spacing(self) -> float:
        """Metres: the mesh's spacing under the print, the median edge of its triangles
        (eqs. 38-39: a cell's sides and diagonal, on a regular grid about its side), or, where
        its nodes make none (a ball pressing a few), of the surface triangles touching them.
        Under the print only: on a graded mesh the cells around it grow."""
        mesh = self._body.mesh
        triangles = mesh.surface_triangles[self._tri_global]
        if not len(triangles):
            triangles = mesh.surface_triangles[np.isin(mesh.surface_triangles, self._ids).any(axis=1)]
        corners = mesh.nodes[triangles]  # (t, 3, 3)
        return float(np.median(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)))

    # ------------------------------------------------------------ matrices
    @cached_property
    def neighbour_tets(self) -> np.ndarray:
        """(T',) int ids of every tet with a node in the print, where strain peaks."""
        touching = np.isin(self._body.mesh.tets, self._ids).any(axis=1)
        return np.flatnonzero(touching)

    def link_solve(self, rhs) -> np.ndarray:
        """``(C + D)^-1 rhs`` (:attr:`link_stiffness` times a few columns) through the
        Cholesky factor of :attr:`link_compliance`, kept: a solver that needs the link
        stiffness on six columns a print (the compliance form's rigid modes) pays one
        factorisation, a third of the inverse's work.

        Parameters
        ----------
        rhs : (3p,) or (3p, k) float

        Returns
        -------
        ndarray
            Of the shape of ``rhs``: N/m times its units.

        Raises
        ------
        PrintError
            If the compliance is not positive definite.
        """
        factor = self._link_factor
        with single_threaded_blas():
            return scipy.linalg.cho_solve(factor, np.asarray(rhs, dtype=float), check_finite=False)

    @cached_property
    def _link_factor(self):
        """scipy's Cholesky factor of :attr:`link_compliance` (one BLAS thread)."""
        with single_threaded_blas():
            try:
                return scipy.linalg.cho_factor(self.link_compliance, lower=False, check_finite=False)
            except np.linalg.LinAlgError as exc:
                raise PrintError("the print compliance is not positive definite") from exc

    @cached_property
    def _compliance_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Rows of C[:, P] at the nodes of every tet touching the print.

        One set of solves serves the consistent and traction methods and the
        strain map (the print triangles' tets touch the print).
        """
        rows = np.unique(np.concatenate([self._ids, self._body.mesh.tets[self.neighbour_tets].ravel()]))
        block = self._body.compliance_block(rows, self._ids)
        position = np.full(self._body.mesh.n_nodes, -1, dtype=np.int64)
        position[rows] = np.arange(rows.size)
        return block.reshape(rows.size, 3, -1), position

    @cached_property
    def compliance(self) -> np.ndarray:
        """Compliance block ``[K_NN^-1]_PP``, (3p, 3p) float, m/N."""
        block, position = self._compliance_rows
        c = block[position[self._ids]].reshape(3 * self.n_nodes, -1)
        c = 0.5 * (c + c.T)
        c.setflags(write=False)
        return c

    @cached_property
    def condensed_stiffness(self) -> np.ndarray:
        """Condensed stiffness ``S_P = K_PP - K_PF K_FF^-1 K_FP``, (3p, 3p) float, N/m.

        Computed as the inverse of :attr:`compliance`: with N = P + F (F: free nodes
        outside the print), the PP block of ``K_NN^-1`` is the inverse of the Schur
        complement of K_FF. Symmetric positive definite. ``S_P @ U_P`` are the forces
        the robot applies to the body to impose U_P.
        """
        # A Cholesky check, then numpy's general inverse, on one BLAS thread. LAPACK's
        # potri (spd_inverse) takes a third of the work but rounds otherwise, and
        # those last bits sent a stiff support's Coulomb solve (step-on-cube at
        # E = 1e10) to a posture with the soft sole unloaded; measured, not understood.
        with single_threaded_blas():
            try:
                np.linalg.cholesky(self.compliance)
            except np.linalg.LinAlgError as exc:
                raise PrintError("the print compliance is not positive definite") from exc
            s = np.linalg.inv(self.compliance)
        s = 0.5 * (s + s.T)
        s.setflags(write=False)
        return s

    @property
    def coupling_compliance(self) -> np.ndarray:
        """D: each partly covered node's series compliance ``(1 - w) / w C_ii``, (3p, 3p)
        float, m/N, block diagonal (zero for a fully covered print); its blocks are
        :attr:`coupling_blocks` (made on each call: a dense matrix of blocks the solver
        never reads whole)."""
        p = self.n_nodes
        d = np.zeros((3 * p, 3 * p))
        nodes = np.arange(p)
        d.reshape(p, 3, p, 3)[nodes, :, nodes, :] = self.coupling_blocks
        d.setflags(write=False)
        return d

    @cached_property
    def coupling_blocks(self) -> np.ndarray:
        """(p, 3, 3) float, m/N: the diagonal blocks of :attr:`coupling_compliance`, node by
        node (what a product with D needs: 9 p numbers instead of 9 p^2)."""
        p = self.n_nodes
        if self._coverage is None:
            blocks = np.zeros((p, 3, 3))
        else:
            nodes = np.arange(p)
            c = self.compliance.reshape(p, 3, p, 3)
            blocks = c[nodes, :, nodes, :] * ((1.0 - self._coverage) / self._coverage)[:, None, None]
        blocks.setflags(write=False)
        return blocks

    @cached_property
    def link_compliance(self) -> np.ndarray:
        """``C + D``, (3p, 3p) float, m/N: the motion of the robot's points under the
        forces they apply (the node's own motion plus its coupling's). Symmetric
        positive definite; :attr:`compliance` for a fully covered print."""
        if self._coverage is None:
            return self.compliance
        c = self.compliance + self.coupling_compliance
        c = 0.5 * (c + c.T)
        c.setflags(write=False)
        return c

    @cached_property
    def link_stiffness(self) -> np.ndarray:
        """``(C + D)^-1``, (3p, 3p) float, N/m: :attr:`condensed_stiffness` for a
        fully covered print. ``link_stiffness @ U`` are the forces the robot applies
        to impose U on its points."""
        if self._coverage is None:
            return self.condensed_stiffness
        with single_threaded_blas():
            s = np.linalg.inv(self.link_compliance)
        s = 0.5 * (s + s.T)
        s.setflags(write=False)
        return s

    def _tet_displacement_map(self, tet_ids: np.ndarray) -> np.ndarray:
        """Displacements of some tets' nodes per unit print displacement (eq. 36).

        Returns
        -------
        (T, 12, 3p) float, dimensionless
            ``u_e = map[t] @ U_P.ravel()`` with ``u = C[:, P] S_P U_P``: exactly U_P at
            the print nodes and 0 at fixed nodes. Independent of the Young modulus.
        """
        g, rows = self._node_displacement_map(tet_ids)
        return g[rows].reshape(rows.shape[0], 12, -1)

    def _strain_matrices(self, tet_ids) -> np.ndarray:
        """(T, 6, 12) strain matrices B_e of some of the body's tets (eq. 24), 1/m: built
        for the few tets near a print only (the body's 285k on a fine cube took 0.8 s)."""
        mesh = self._body.mesh
        return element_strain_matrices(mesh.nodes, mesh.tets[tet_ids])[0]

    def _columns_at(self, nodes: np.ndarray) -> np.ndarray:
        """(q, 3, 3p) rows of ``C[:, P]`` at some nodes: from :attr:`_compliance_rows`
        when they hold them (the nodes of tets touching the print), else read again."""
        block, position = self._compliance_rows
        at = position[nodes]
        known = at >= 0
        if known.all():
            return block[at]
        # Only the rows it does not hold are gathered (a ball's nodes include the
        # touching tets' ones).
        out = np.empty((nodes.size, 3, block.shape[2]))
        out[known] = block[at[known]]
        missing = nodes[~known]
        out[~known] = self._body.compliance_block(missing, self._ids).reshape(missing.size, 3, -1)
        return out

    def strain_centres(self, radius: float = 0.0, also=None) -> np.ndarray:
        """(C,) ids of the tets whose ball means of radius ``radius`` the strain rows
        read: the :attr:`neighbour_tets` and every tet whose centroid lies within
        twice ``radius`` of one of theirs (``neighbour_tets`` at radius 0), and the
        tets ``also`` names (sorted ids, or None; e.g. where the body's own weight
        strains it already). The largest mean under a sole can sit below the tets
        touching it: on step-on-cube with a 0.3 % bound, 3.5 cm under the top, which
        centres within one radius missed (the answer then failed verify, which looks
        at every tet)."""
        return self._strain_set(radius, also)[0]

    @staticmethod
    def _set_key(radius: float, also) -> tuple:
        """The key of a strain set: the radius and the bytes of ``also`` (None for none)."""
        return float(radius), None if also is None else np.asarray(also, dtype=np.int64).tobytes()

    def _strain_set(self, radius: float, also=None, key=None):
        """What the ball means of :meth:`strain_centres` are computed from, without the
        (3q, 3p) map of the q nodes (a 30 ms product on a sole pair, more than a
        planner's whole use of it): the centres (C,), the tets in their balls (E,), the
        (C, E) averaging weights, (q, 3, 3p) rows of ``C[:, P]`` at the balls' nodes, (E,
        4) each tet's nodes as rows of them, (E, 6, 12) the tets' strain matrices, (q,)
        each node's index in the print (-1 outside it) and (q,) which nodes are fixed.
        Kept per radius and ``also`` (``key``: their :meth:`_set_key`, when known)."""
        key = self._set_key(radius, also) if key is None else key
        known = self._strain_sets.get(key)
        if known is None:
            body = self._body
            centres = body.strain_averages.near(self.neighbour_tets, 2.0 * key[0])
            if also is not None:
                also = np.asarray(also, dtype=np.int64)
                if also.size and (also.min() < 0 or also.max() >= body.mesh.n_tets):
                    raise FemError(f"strain centres must be tet ids in [0, {body.mesh.n_tets}), got {also.min()}..{also.max()}")
                centres = np.union1d(centres, also)
            members, weights = body.strain_averages.weights(centres, key[0])
            nodes, rows = np.unique(body.mesh.tets[members], return_inverse=True)
            known = (centres, members, weights, self._columns_at(nodes), rows.reshape(members.size, 4),
                     self._strain_matrices(members), self._local[nodes], body.fixed_mask[nodes])
            self._strain_sets[key] = known
        return known

    def neighbour_strains(self, displacements, radius: float = 0.0, also=None) -> np.ndarray:
        """Voigt strains at the :meth:`strain_centres` under print displacements (eq. 24),
        each averaged over a ball of ``radius`` (:class:`fem.strain_average.BallAverages`).

        With ``radius`` 0, those of the :attr:`neighbour_tets`, equal to ``strain_map @
        U_P.ravel()``. Computed through the tets' nodes: the nodes move by ``C[:, P] S_P
        U_P`` (eq. 36; exactly U_P at the print nodes, 0 at fixed ones), the force ``S_P
        U_P`` computed first, so that no (3q, 3p) map is formed (it runs at every
        evaluation of a traction model's stance; the compliance form's read
        :meth:`neighbour_strains_under_loads`).

        Parameters
        ----------
        displacements : (3p,) float
            Print node displacements U_P, metres, body frame.
        radius : float, optional
            Metres; 0: each tet's own strain.
        also : (n,) int, optional
            Further centres, as :meth:`strain_centres`.

        Returns
        -------
        (C, 6) float
            Voigt strains (engineering shears), dimensionless.
        """
        strain_set = self._strain_set(radius, also)
        return _ball_means(strain_set[2], strain_set[5], self._set_nodal(strain_set, displacements, "displacement"), strain_set[4])

    def neighbour_strains_under_loads(self, loads, radius: float = 0.0, also=None) -> np.ndarray:
        """Voigt strains at the :meth:`strain_centres` under loads on the print nodes,
        each averaged over a ball of ``radius``: :meth:`neighbour_strains` of the print
        displacements ``C_PP loads``, without the condensed stiffness.

        The nodes of the balls' tets move by ``C[:, P] loads`` (the compliance's columns
        are the full system's answers to unit loads: 0 at fixed nodes): a solver that
        knows the print's forces (the compliance form) needs no ``S_P``, whose inverse
        cost 6-10 ms at every new print on a foam mat.

        Parameters
        ----------
        loads : (3p,) float
            Forces ON the body at the print nodes, newtons, body frame.
        radius, also : optional
            As :meth:`neighbour_strains`.

        Returns
        -------
        (C, 6) float
            Voigt strains (engineering shears), dimensionless.
        """
        strain_set = self._strain_set(radius, also)
        return _ball_means(strain_set[2], strain_set[5], self._set_nodal(strain_set, loads, "load"), strain_set[4])

    def strained_centres(self, u, floor: float, radius: float = 0.0, also=None, per: str = "load", offset=None):
        """The :meth:`strain_centres` whose ball-mean strain can reach a Frobenius norm of
        ``floor``, and their means: what :meth:`neighbour_strains_under_loads` (or
        :meth:`neighbour_strains`) gives at every centre, read where it can matter.

        A mean's Frobenius norm is at most the mean of its tets' norms (a norm is
        convex), and that mean at most ``m + sum_hot w_s (n_s - m)``, the ``hot`` tets
        those whose norm n_s is at least half of ``floor`` and m the largest of the
        others': a product with the weights' columns of the few hot tets replaces the
        product with every column (under a ball foot on a 10 mm foam mesh, 2,700
        centres of 144 tets each: the tet under the ball is strained to 0.07-0.17, the
        largest 2 cm mean to 0.006-0.016, and the means were 70 % of a strain block's
        time). Where the hot columns hold more than :data:`_HOT_SHARE` of the weights'
        stored entries (5 mm cells under a ball), the bound is the mean of the norms, one
        product with a single column. Each centre kept is averaged as in the product over
        every centre: the same bits.

        Parameters
        ----------
        u : (3p,) float
            Loads on the print nodes (``per="load"``, newtons) or their displacements
            (``per="displacement"``, metres), body frame.
        floor : float
            Dimensionless, >= 0.
        radius, also : optional
            As :meth:`neighbour_strains`.
        per : {"load", "displacement"}
        offset : (C, 6) float, optional
            Voigt strains added to every centre's mean (e.g. the body's own weight's);
            their norms enter the bound.

        Returns
        -------
        positions : (k,) int
            Sorted positions in :meth:`strain_centres` of every centre whose mean (plus
            ``offset``) has a Frobenius norm of at least ``floor``, and perhaps of a few
            below it.
        voigt : (k, 6) float
            Their ball-mean Voigt strains (engineering shears), plus ``offset``.
        """
        if per not in ("displacement", "load"):
            raise PrintError(f"per must be 'displacement' or 'load', got {per!r}")
        key = self._set_key(radius, also)
        strain_set = self._strain_set(radius, also, key)
        weights, b, rows = strain_set[2], strain_set[5], strain_set[4]
        if offset is not None:
            offset = np.asarray(offset, dtype=float)
            if offset.shape != (weights.shape[0], 6):
                raise PrintError(f"offset must be ({weights.shape[0]}, 6) Voigt strains, one row a strain "
                                 f"centre, got shape {offset.shape}")
        nodal = self._set_nodal(strain_set, u, per)
        tets = _tet_strains(b, nodal, rows)
        norms = frobenius_norms(tets)
        # A NaN norm counts as hot, so that it reaches the bound rather than the cold max.
        hot = ~(norms < 0.5 * floor)
        cold = float(norms[~hot].max()) if not hot.all() else 0.0
        indptr, centres, shares = self._weight_columns(key, weights)
        hot = np.flatnonzero(hot)
        starts, counts = indptr[hot], indptr[hot + 1] - indptr[hot]
        if counts.sum() <= _HOT_SHARE * shares.size:
            # The hot tets' columns of the weights, gathered from their CSC arrays (scipy's
            # column indexing cost 0.4 ms a call here).
            entries = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
            bound = cold + np.bincount(centres[entries], shares[entries] * np.repeat(norms[hot] - cold, counts),
                                       minlength=weights.shape[0])
        else:
            # Strained broadly (5 mm cells under a ball: most tets hot): the mean of
            # every ball's norms, one product with a single column.
            bound = weights @ norms
        if offset is not None:
            bound = bound + frobenius_norms(offset)
        # The bound can be tight (a ball of one tet, a uniform field, an offset along the
        # mean), and then the mean computed below can exceed it by rounding (7e-14
        # relative measured): the slack covers that rounding.
        # A NaN bound (a NaN strain in its ball) keeps its centre, whose mean is then NaN as
        # the product over every centre gives it: a NaN is shown, never screened out.
        positions = np.flatnonzero(~(bound < floor * (1.0 - 1e-9)))
        if positions.size == 0:
            return positions, np.zeros((0, 6))
        voigt = weights[positions] @ tets
        if offset is not None:
            voigt = voigt + offset[positions]
        return positions, voigt

    def _weight_columns(self, key: tuple, weights) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The averaging weights of a strain set (its :meth:`_set_key` ``key``) by column:
        the CSC arrays (indptr, row indices, values), made once."""
        known = self._weight_csc.get(key)
        if known is None:
            columns = weights.tocsc()
            known = self._weight_csc[key] = (columns.indptr.astype(np.int64), columns.indices, columns.data)
        return known

    def _set_nodal(self, strain_set, u, per: str) -> np.ndarray:
        """(q, 3) displacements of a strain set's nodes (:meth:`_strain_set`) under print
        node displacements ``u`` (``per="displacement"``: they move by ``C[:, P] S_P u``,
        exactly u at the print nodes, 0 at fixed ones) or loads on them (``per="load"``:
        by ``C[:, P] u``), (3p,) float."""
        _, _, _, block, _, _, in_print, fixed = strain_set
        u = np.asarray(u, dtype=float)
        if per == "load":
            return (block.reshape(-1, block.shape[2]) @ u).reshape(-1, 3)
        nodal = (block.reshape(-1, block.shape[2]) @ (self.condensed_stiffness @ u)).reshape(-1, 3)
        printed = in_print >= 0
        nodal[printed] = u.reshape(-1, 3)[in_print[printed]]
        nodal[fixed] = 0.0
        return nodal

    def field_strains(self, field, radius: float = 0.0, also=None) -> np.ndarray:
        """Voigt strains at the :meth:`strain_centres` of a whole displacement field
        (e.g. the body's own weight), each averaged over a ball of ``radius``, as
        :meth:`neighbour_strains` gives them for print displacements.

        Parameters
        ----------
        field : (N, 3) float
            Displacement of every node, metres, body frame.
        radius, also : optional
            As :meth:`neighbour_strains`.

        Returns
        -------
        (C, 6) float
            Voigt strains (engineering shears), dimensionless.
        """
        _, members, weights, _, _, b, _, _ = self._strain_set(radius, also)
        return _ball_means(weights, b, np.asarray(field, dtype=float), self._body.mesh.tets[members])

    def neighbour_strain_row(self, weights, tet: int, radius: float = 0.0, also=None, per: str = "displacement") -> np.ndarray:
        """``weights @ strain_map[tet]`` without :attr:`strain_map`: a combination of the
        Voigt strains at one of the :meth:`strain_centres` (averaged over a ball of
        ``radius``) per unit print displacement, or per unit load.

        Parameters
        ----------
        weights : (6,) float
            Weights of the Voigt strains (e.g. a principal strain's derivative).
        tet : int
            Position of the centre in :meth:`strain_centres` (at radius 0, in
            :attr:`neighbour_tets`).
        radius, also : optional
            As :meth:`neighbour_strains`.
        per : {"displacement", "load"}
            The derivative of :meth:`neighbour_strains` (in U_P, 1/m) or of
            :meth:`neighbour_strains_under_loads` (in the loads, 1/N).

        Returns
        -------
        (3p,) float
        """
        if per not in ("displacement", "load"):
            raise PrintError(f"per must be 'displacement' or 'load', got {per!r}")
        key = self._set_key(radius, also)
        _, _, averaging, block, rows, b, _, _ = self._strain_set(radius, also, key)
        weights = np.asarray(weights, dtype=float)
        start, stop = averaging.indptr[tet], averaging.indptr[tet + 1]
        members, shares = averaging.indices[start:stop], averaging.data[start:stop]
        if per == "load":
            # Per load, the tets' nodes move by their rows of C[:, P] as they are: each
            # node's weight summed over the ball's tets first, then one product with its
            # rows (a loop over the tets cost 4 ms a row on a 10 mm foam mesh, hundreds
            # of tets to a 20 mm ball: 15 of a plan's 43 s).
            coefficients = shares[:, None] * np.einsum("j,kjm->km", weights, b[members])  # (K, 12)
            node_weights = np.zeros((block.shape[0], 3))
            np.add.at(node_weights, rows[members].ravel(), coefficients.reshape(-1, 3))
            used = np.unique(rows[members])
            return np.einsum("nj,njm->m", node_weights[used], block[used])
        row = np.zeros(3 * self._ids.size)
        for k, share in zip(members, shares):
            row += share * ((weights @ b[k]) @ self._member_map(key, int(k), also))
        return row

    def _member_map(self, set_key: tuple, k: int, also=None) -> np.ndarray:
        """(12, 3p) displacements of the nodes of tet ``k`` of a strain set (its
        position there, the set named by its :meth:`_set_key`) per unit print
        displacement (eq. 36), from the set's rows of ``C[:, P]``; kept: a solve's
        strain rows come back to the same few tets."""
        key = (set_key, k)
        known = self._tet_maps.get(key)
        if known is None:
            _, _, _, block, rows, _, in_print, fixed = self._strain_set(set_key[0], also, set_key)
            nodes = rows[k]
            known = self._displacement_rows(block[nodes], in_print[nodes], fixed[nodes]).reshape(12, -1)
            known.setflags(write=False)
            self._tet_maps[key] = known
        return known

    def _node_displacement_map(self, tet_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q, 3, 3p) displacements of some tets' q nodes per unit print displacement
        (eq. 36), and (T, 4) each tet's nodes as rows of it."""
        body = self._body
        tets = body.mesh.tets[tet_ids]
        nodes, rows = np.unique(tets, return_inverse=True)
        rows = rows.reshape(tets.shape)
        return self._displacement_rows(self._columns_at(nodes), self._local[nodes], body.fixed_mask[nodes]), rows

    def _displacement_rows(self, columns, in_print, fixed) -> np.ndarray:
        """(q, 3, 3p) displacements of q nodes per unit print displacement (eq. 36), from
        their (q, 3, 3p) rows of ``C[:, P]``, each node's index in the print (-1
        outside it) and whether it is fixed: exact identity rows at the print nodes,
        zero rows at fixed ones."""
        g = columns @ self.condensed_stiffness
        idx = np.flatnonzero(in_print >= 0)
        g[idx, :, :] = 0.0
        for axis in range(3):
            g[idx, axis, 3 * in_print[idx] + axis] = 1.0
        g[fixed] = 0.0
        return g

    @cached_property
    def strain_map(self) -> np.ndarray:
        """Strain of each of :attr:`neighbour_tets` per unit print displacement (eq. 24).

        Returns
        -------
        (T', 6, 3p) float, 1/m
            Voigt strains (engineering shears) ``{epsilon_e} = strain_map[t] @ U_P.ravel()``;
            independent of the Young modulus, so well scaled for stiff bodies too.
        """
        g_e = self._tet_displacement_map(self.neighbour_tets)
        b = self._strain_matrices(self.neighbour_tets)  # (T', 6, 12)
        out = np.einsum("tik,tkp->tip", b, g_e)
        out.setflags(write=False)
        return out

    @cached_property
    def stress_map(self) -> np.ndarray:
        """Stress of each print triangle's tet per unit print displacement (eqs. 58-59).

        Returns
        -------
        (T, 6, 3p) float, Pa/m
            ``{sigma_e} = stress_map[t] @ U_P.ravel()``, with the tet displacements of
            eq. (36) (``u = C[:, P] S_P U_P``, exactly U_P at P and 0 at fixed nodes).
        """
        if self._tri_global.size == 0:
            raise PrintError(
                "the print holds no complete surface triangle, so the traction method "
                "(eqs. 41-44) has nothing to integrate; use method='consistent' or a larger print"
            )
        body = self._body
        g_e = self._tet_displacement_map(self.triangle_tets)  # (T, 12, 3p)
        b = self._strain_matrices(self.triangle_tets)  # (T, 6, 12)
        ab = np.einsum("ij,tjk->tik", body.material.voigt_matrix, b)
        out = np.einsum("tik,tkp->tip", ab, g_e)
        out.setflags(write=False)
        return out

    def reaction_matrix(self, method: str = "consistent", normals=None) -> np.ndarray:
        """Jacobian R of the forces on the robot with respect to U_P.

        Parameters
        ----------
        method : {"consistent", "traction"}
            ``"consistent"``: R = -S_P, the exact nodal forces of the discrete system
            (``-(C + D)^-1`` with coverage, U_P then the robot's points' motion).
            ``"traction"``: eqs. (41)-(44): each print triangle e gives
            ``-alpha_e / 3 sigma_e n_e`` to each of its 3 vertices.
        normals : (T, 3) float, optional
            ``traction`` only: the print triangles' normals, body frame (e.g.
            turned with the robot link, eq. 63); the rest normals by default.

        Returns
        -------
        (3p, 3p) float, N/m, read-only
            ``forces_on_robot.ravel() = R @ U_P.ravel()``; cached for the
            rest normals.
        """
        self._check_method(method)
        if normals is not None:
            if method != "traction":
                raise PrintError("normals only apply to method='traction'")
            r = self._traction_matrix(self._check_normals(normals))
            r.setflags(write=False)
            return r
        if method not in self._cache:
            if method == "consistent":
                r = -self.link_stiffness
            else:
                r = self._traction_matrix(self.triangle_normals)
            r = np.array(r)
            r.setflags(write=False)
            self._cache[method] = r
        return self._cache[method]

    def _traction_matrix(self, normals: np.ndarray) -> np.ndarray:
        # sigma_e n_e = (n^T (x) I) D {sigma_e} (eqs. 55-57), then eq. (43).
        traction = np.einsum("ijv,tj,tvp->tip", VOIGT_TO_TENSOR, normals, self.stress_map)
        per_vertex = -(self.triangle_areas / 3.0)[:, None, None] * traction  # (T, 3, 3p)
        return self._scatter(per_vertex).reshape(3 * self.n_nodes, -1)

    def _scatter(self, per_triangle: np.ndarray) -> np.ndarray:
        """Add a per-triangle (T, ...) value to each of its 3 vertices -> (p, ...)."""
        out = np.zeros((self.n_nodes,) + per_triangle.shape[1:])
        triangles = self.triangles
        for k in range(3):
            np.add.at(out, triangles[:, k], per_triangle)
        return out

    # ------------------------------------------------------------ evaluation
    def _check_method(self, method: str) -> None:
        if method not in METHODS:
            raise PrintError(f"unknown method {method!r}; choose one of {METHODS}")
        if method == "traction" and self._coverage is not None:
            raise PrintError(
                "the traction method (eqs. 41-44) integrates whole print triangles and takes no coverage; "
                "use method='consistent', or a print of the nodes inside the polygon (fem.nodes_in_polygon)"
            )

    def _check_displacements(self, displacements) -> np.ndarray:
        u = np.asarray(displacements, dtype=float)
        if u.shape != (self.n_nodes, 3):
            raise PrintError(
                f"displacements must have shape ({self.n_nodes}, 3) (one row per print node, "
                f"metres, body frame), got {u.shape}"
            )
        if not np.all(np.isfinite(u)):
            raise PrintError("displacements contain NaN or inf")
        return u

    def _check_normals(self, normals) -> np.ndarray:
        n = np.asarray(normals, dtype=float)
        t = self._tri_global.size
        if n.shape != (t, 3):
            raise PrintError(f"normals must have shape ({t}, 3), one per print triangle, got {n.shape}")
        if not np.all(np.isfinite(n)):
            raise PrintError("normals contain NaN or inf")
        return n

    def triangle_stresses(self, displacements) -> np.ndarray:
        """Stress tensor of each print triangle's tet, (T, 3, 3) float, pascals (eq. 58)."""
        u = self._check_displacements(displacements)
        voigt = self.stress_map @ u.ravel()  # (T, 6)
        return np.einsum("ijv,tv->tij", VOIGT_TO_TENSOR, voigt)

    def reaction_forces(self, displacements, method: str = "consistent", normals=None) -> np.ndarray:
        """Forces each print node exerts on the robot.

        Parameters
        ----------
        displacements : (p, 3) float
            U_P, metres, body frame, rows in :attr:`node_ids` order.
        method : {"consistent", "traction"}
            See :meth:`reaction_matrix`.
        normals : (T, 3) float, optional
            Traction method only: the triangle normals n_e to use in eq. (44), body
            frame (the posture solver rotates the rest normals with the link);
            default the rest normals.

        Returns
        -------
        (p, 3) float, newtons, body frame.

        Raises
        ------
        PrintError
            Wrong shape, NaN/inf, unknown method, or normals with the consistent method.
        """
        self._check_method(method)
        u = self._check_displacements(displacements)
        if normals is None:
            return (self.reaction_matrix(method) @ u.ravel()).reshape(-1, 3)
        if method != "traction":
            raise PrintError("normals are only used by method='traction'")
        n = self._check_normals(normals)
        per_vertex = -(self.triangle_areas / 3.0)[:, None] * np.einsum(
            "tij,tj->ti", self.triangle_stresses(u), n
        )
        return self._scatter(per_vertex)

    def traction_normal_derivative(self, displacements) -> np.ndarray:
        """Derivative of the traction forces with respect to the triangle normals (eq. 63).

        Parameters
        ----------
        displacements : (p, 3) float
            U_P, metres, body frame.

        Returns
        -------
        (T, 3, 3) float, newtons
            ``-alpha_e / 3 sigma_e``: each of triangle e's 3 vertex forces changes by
            ``result[e] @ dn_e`` when its normal changes by ``dn_e``.
        """
        return -(self.triangle_areas / 3.0)[:, None, None] * self.triangle_stresses(displacements)

    def traction_rotation_jacobian(self, displacements) -> np.ndarray:
        """Derivative of each node's traction force under a rotation of all normals.

        The posture solver rotates the print normals with the link: ``dn_e = omega x n_e``
        for a small rotation vector omega (radians, body frame).

        Parameters
        ----------
        displacements : (p, 3) float
            U_P, metres, body frame.

        Returns
        -------
        (p, 3, 3) float, newtons per radian
            ``d f_i = result[i] @ omega``, at the rest normals.
        """
        derivative = self.traction_normal_derivative(displacements)  # (T, 3, 3)
        # d(sigma n) = sigma (omega x n) = -sigma skew(n) omega
        per_triangle = -np.einsum("tij,tjk->tik", derivative, _skew(self.triangle_normals))
        return self._scatter(per_triangle)

    def __repr__(self) -> str:
        return f"ContactPatch({self.n_nodes} nodes, {self._tri_global.size} triangles)"


def _ball_means(weights, b, nodal, rows) -> np.ndarray:
    """(C, 6) ball means of the tets' Voigt strains ``B_e u_e``: ``weights`` (C, E)
    averaging, ``b`` (E, 6, 12) strain matrices, ``nodal`` (q, 3) node displacements and
    ``rows`` (E, 4) each tet's nodes as rows of ``nodal``."""
    return weights @ _tet_strains(b, nodal, rows)


def _tet_strains(b, nodal, rows) -> np.ndarray:
    """(E, 6) Voigt strains ``B_e u_e`` of tets: ``b`` (E, 6, 12) strain matrices, ``nodal``
    (q, 3) node displacements, ``rows`` (E, 4) each tet's nodes as rows of ``nodal``."""
    return np.einsum("tik,tk->ti", b, np.take(nodal, rows, axis=0).reshape(rows.shape[0], 12))
