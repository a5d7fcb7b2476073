"""Tetrahedral mesh value type with validated orientation and its boundary surface."""

from __future__ import annotations

from dataclasses import InitVar, dataclass
from functools import cached_property

import numpy as np
import scipy.spatial

from .errors import MeshError

__all__ = ["TetMesh", "tet_edge_cofactors", "tet_signed_volumes"]

# Faces of a positively oriented tet (a, b, c, d), ordered so that the right-hand
# normal points out of the tet: face k is the one opposite local node k.
_OUTWARD_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])

# A tet is "flat" when |volume| < _FLAT_RATIO * (longest edge)^3; a regular tet has
# volume 0.118 l^3, so 1e-10 is far below any usable element and far above rounding.
_FLAT_RATIO = 1e-10


def tet_edge_cofactors(nodes: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cofactors and determinant of each tet's edge matrix, in closed form.

    With the edges ``e_k = x_k - x_0`` (k = 1, 2, 3) as the rows of E, the columns of
    E^-1 are ``(e2 x e3, e3 x e1, e1 x e2) / det E`` and ``det E = e1 . (e2 x e3)``.
    The cross products are written out over whole arrays: on a 285k-tet body that is
    6x faster than ``np.linalg.inv`` and ``det`` on the stack of 3 x 3 matrices, which
    pay a call per matrix (0.5 s of a 2 s cached setup).

    Parameters
    ----------
    nodes : (N, 3) float
        Node positions, metres.
    tets : (M, 4) int
        Node ids of each tet.

    Returns
    -------
    cofactors : (M, 3, 3) float
        ``cofactors[:, k - 1]`` = the cross product of the two edges other than e_k,
        in the cyclic order above, square metres; ``E^-1 = cofactors^T / det E``.
    determinants : (M,) float
        det E, cubic metres (six times the signed volume).
    """
    e1, e2, e3 = _edges(nodes, tets)
    cofactors = np.stack([_cross(e2, e3), _cross(e3, e1), _cross(e1, e2)], axis=1)
    determinants = np.einsum("mi,mi->m", e1, cofactors[:, 0])
    return cofactors, determinants


def _edges(nodes: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The edges x_k - x_0 (k = 1, 2, 3) of each tet, three (M, 3) arrays, metres."""
    x0 = nodes[tets[:, 0]]
    return tuple(nodes[tets[:, k]] - x0 for k in (1, 2, 3))


def _volumes(e1: np.ndarray, e2: np.ndarray, e3: np.ndarray) -> np.ndarray:
    """(M,) signed volumes ``e1 . (e2 x e3) / 6`` of tets from their edges, cubic metres."""
    return np.einsum("mi,mi->m", e1, _cross(e2, e3)) / 6.0


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (M, 3) arrays (np.cross costs 1.5x this in axis handling)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def tet_signed_volumes(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes of tetrahedra.

    Parameters
    ----------
    nodes : (N, 3) float
        Node positions, metres.
    tets : (M, 4) int
        Node ids of each tet.

    Returns
    -------
    (M,) float
        det([x1 - x0, x2 - x0, x3 - x0]) / 6, cubic metres; > 0 for positive orientation.
    """
    return _volumes(*_edges(nodes, tets))


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class TetMesh:
    """A conforming mesh of linear tetrahedra.

    Parameters
    ----------
    nodes : (N, 3) float
        Node positions, metres, body frame. Copied and made read-only.
    tets : (M, 4) int
        Node ids of each tet, positively oriented (volume > 0). Copied, read-only.
    fix_orientation : bool, optional
        Swap two nodes of every inverted tet instead of raising (init only).

    Raises
    ------
    MeshError
        On NaN/inf, bad shapes, indices out of range, duplicate nodes, repeated
        tets (the same four nodes twice), nodes used by no tet, flat tets or
        (unless ``fix_orientation``) inverted tets; the message names the
        offending index.

    Notes
    -----
    Degrees of freedom are numbered ``3 * node + axis`` everywhere in :mod:`fem`.
    """

    nodes: np.ndarray
    tets: np.ndarray
    fix_orientation: InitVar[bool] = False

    def __post_init__(self, fix_orientation: bool) -> None:
        nodes = np.array(self.nodes, dtype=float, copy=True)
        if nodes.ndim != 2 or nodes.shape[1] != 3 or nodes.shape[0] < 4:
            raise MeshError(f"nodes must have shape (N >= 4, 3), got {nodes.shape}")
        bad = np.flatnonzero(~np.isfinite(nodes).all(axis=1))
        if bad.size:
            raise MeshError(f"node {bad[0]} has a non-finite coordinate {nodes[bad[0]]}")
        tets_in = np.asarray(self.tets)
        if tets_in.ndim != 2 or tets_in.shape[1] != 4 or tets_in.shape[0] < 1:
            raise MeshError(f"tets must have shape (M >= 1, 4), got {tets_in.shape}")
        if not np.issubdtype(tets_in.dtype, np.integer):
            if not np.all(np.isfinite(tets_in)) or np.any(tets_in != np.round(tets_in)):
                raise MeshError("tets must hold integer node ids")
        tets = tets_in.astype(np.int64, copy=True)
        n = nodes.shape[0]
        out = np.flatnonzero((tets < 0).any(axis=1) | (tets >= n).any(axis=1))
        if out.size:
            raise MeshError(
                f"tet {out[0]} has node ids {tets[out[0]].tolist()} outside [0, {n - 1}]"
            )
        self._check_duplicate_nodes(nodes)
        self._check_repeated_tets(tets)
        used = np.zeros(n, dtype=bool)
        used[tets.ravel()] = True
        if not used.all():
            unused = np.flatnonzero(~used)
            raise MeshError(
                f"{unused.size} node(s) belong to no tet (first: node {unused[0]}); "
                "they would make the stiffness singular, remove them"
            )
        e1, e2, e3 = _edges(nodes, tets)
        volumes = _volumes(e1, e2, e3)
        # Edge by edge, not as one (M, 6, 3) gather: a third of the time on 285k tets.
        longest = np.sqrt(np.max([np.einsum("mi,mi->m", e, e) for e in (e1, e2, e3, e2 - e1, e3 - e1, e3 - e2)],
                                 axis=0))
        flat = np.flatnonzero(np.abs(volumes) <= _FLAT_RATIO * longest**3)
        if flat.size:
            k = flat[0]
            raise MeshError(
                f"tet {k} is flat (volume {volumes[k]:.3g} m^3 for a longest edge of "
                f"{longest[k]:.3g} m); remove it or remesh ({flat.size} flat tet(s) in all)"
            )
        inverted = np.flatnonzero(volumes < 0.0)
        if inverted.size:
            if fix_orientation:
                tets[inverted[:, None], [2, 3]] = tets[inverted[:, None], [3, 2]]
                volumes[inverted] *= -1.0
            else:
                k = inverted[0]
                raise MeshError(
                    f"tet {k} is inverted (volume {volumes[k]:.3g} m^3); reorder its nodes "
                    f"or call TetMesh(..., fix_orientation=True) ({inverted.size} inverted "
                    "tet(s) in all)"
                )
        object.__setattr__(self, "nodes", _readonly(nodes))
        object.__setattr__(self, "tets", _readonly(tets))
        self.__dict__["volumes"] = _readonly(volumes)

    @staticmethod
    def _check_duplicate_nodes(nodes: np.ndarray) -> None:
        # Quantise on a grid far finer than any element so coincident nodes collide.
        scale = float(np.ptp(nodes, axis=0).max()) or 1.0
        keys = np.round(nodes / (1e-10 * scale)).astype(np.int64)
        _, first, counts = np.unique(keys, axis=0, return_index=True, return_counts=True)
        if (counts > 1).any():
            dup_key = keys[first[np.flatnonzero(counts > 1)[0]]]
            same = np.flatnonzero((keys == dup_key).all(axis=1))
            raise MeshError(
                f"nodes {same.tolist()} are duplicates (position {nodes[same[0]].tolist()}); "
                "merge them so neighbouring tets share nodes"
            )

    @staticmethod
    def _check_repeated_tets(tets: np.ndarray) -> None:
        # A tet listed twice (in any node order) adds its stiffness twice: the
        # body is silently stiffer there, so refuse it rather than assemble it.
        keys = np.sort(tets, axis=1)
        n = int(keys.max()) + 1
        # Two int64 keys per tet (a n + b, c n + d; exact for n < 3e9): sorting two
        # columns is about twice as fast as sorting four.
        high, low = keys[:, 0] * n + keys[:, 1], keys[:, 2] * n + keys[:, 3]
        order = np.lexsort((low, high))
        high, low = high[order], low[order]
        same = np.flatnonzero((high[1:] == high[:-1]) & (low[1:] == low[:-1]))
        if same.size:
            first, second = sorted((int(order[same[0]]), int(order[same[0] + 1])))
            raise MeshError(
                f"tets {first} and {second} have the same nodes {tets[first].tolist()} "
                f"({same.size} repeated tet(s) in all); remove the repeats"
            )

    # ------------------------------------------------------------------ sizes
    @property
    def n_nodes(self) -> int:
        """Number of nodes N."""
        return self.nodes.shape[0]

    @property
    def n_tets(self) -> int:
        """Number of tets M."""
        return self.tets.shape[0]

    @property
    def n_dofs(self) -> int:
        """Number of degrees of freedom 3 N."""
        return 3 * self.nodes.shape[0]

    @cached_property
    def volumes(self) -> np.ndarray:
        """(M,) float, cubic metres, all > 0."""
        return _readonly(tet_signed_volumes(self.nodes, self.tets))

    @cached_property
    def bounding_box(self) -> np.ndarray:
        """(2, 3) float, metres: minimum corner then maximum corner (read-only; kept, as a
        layer's sites ask for it at every print of every solve)."""
        return _readonly(np.stack([self.nodes.min(axis=0), self.nodes.max(axis=0)]))

    # ---------------------------------------------------------------- surface
    @cached_property
    def _surface(self) -> tuple[np.ndarray, np.ndarray]:
        faces = self.tets[:, _OUTWARD_FACES].reshape(-1, 3)
        keys = np.sort(faces, axis=1)
        n = self.n_nodes
        if n < 2_000_000:
            # One integer per sorted face (a <= b <= c < n, so a n^2 + b n + c keeps
            # the rows' lexicographic order and fits in int64): a 1-D unique is
            # about 5x faster than one over rows, with the same first indices.
            keys = (keys[:, 0] * n + keys[:, 1]) * n + keys[:, 2]
            _, index, counts = np.unique(keys, return_index=True, return_counts=True)
        else:
            _, index, counts = np.unique(keys, axis=0, return_index=True, return_counts=True)
        if (counts > 2).any():
            bad = index[np.flatnonzero(counts > 2)[0]]
            raise MeshError(
                f"face {faces[bad].tolist()} is shared by more than two tets; "
                "the mesh is not a manifold solid"
            )
        boundary = np.sort(index[counts == 1])
        return _readonly(faces[boundary]), _readonly(boundary // 4)

    @property
    def surface_triangles(self) -> np.ndarray:
        """(T, 3) int node ids of boundary faces; right-hand normal points out of the solid."""
        return self._surface[0]

    @property
    def surface_triangle_tets(self) -> np.ndarray:
        """(T,) int: the tet owning each surface triangle (for tractions, eq. 41)."""
        return self._surface[1]

    @cached_property
    def _surface_geometry(self) -> tuple[np.ndarray, np.ndarray]:
        x = self.nodes[self.surface_triangles]
        cross = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        double_area = np.linalg.norm(cross, axis=1)
        return _readonly(cross / double_area[:, None]), _readonly(0.5 * double_area)

    @property
    def surface_normals(self) -> np.ndarray:
        """(T, 3) float unit outward normals of the surface triangles, body frame."""
        return self._surface_geometry[0]

    @property
    def surface_areas(self) -> np.ndarray:
        """(T,) float areas of the surface triangles, square metres."""
        return self._surface_geometry[1]

    @cached_property
    def surface_search(self) -> tuple[scipy.spatial.cKDTree, float]:
        """A k-d tree of the surface triangles' centroids and the longest surface edge,
        metres: every triangle with a point within r of x has its centroid within
        r + that edge of x (a search near a point without a pass over the surface)."""
        x = self.nodes[self.surface_triangles]
        longest = float(np.linalg.norm(x - x[:, [1, 2, 0]], axis=2).max()) if len(x) else 0.0
        return scipy.spatial.cKDTree(x.mean(axis=1)), longest

    @cached_property
    def surface_nodes(self) -> np.ndarray:
        """(S,) int sorted unique ids of the nodes on the boundary surface."""
        return _readonly(np.unique(self.surface_triangles))

    @cached_property
    def is_surface_node(self) -> np.ndarray:
        """(N,) bool mask of boundary nodes."""
        mask = np.zeros(self.n_nodes, dtype=bool)
        mask[self.surface_nodes] = True
        return _readonly(mask)

    def __repr__(self) -> str:
        return f"TetMesh(n_nodes={self.n_nodes}, n_tets={self.n_tets})"
