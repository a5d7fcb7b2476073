"""Strain averaged over a ball: a measure of a body's strain that does not depend on its mesh.

Under the edge of a rigid print the linear-elastic strain is singular (it grows as
the inverse square root of the distance to the edge), so the largest strain of any
tet there grows as the mesh is refined: pressed 5 mm, a palm on the foam mat gives
0.121 on the default mesh and 0.182 on the mesh refined twice, and a bound on it
would let a print carry less and less load on finer meshes. The volume-weighted
mean strain over a ball of fixed radius around each tet's centroid converges
instead (the same palm: 0.076 on both meshes with a 20 mm ball), and is the strain
at the scale where the question "does linear elasticity hold?" is asked (a
control-volume average, as in the strain-energy-density criteria for notches).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .errors import FemError
from .mesh import tet_signed_volumes

__all__ = ["BallAverages", "frobenius_norms", "voigt_to_tensor_strain"]

# Ball means of largest Frobenius norm whose principal strains bound the largest one from
# below (BallAverages.largest_principal), so that only means at least that strained are
# decomposed.
_BOUND_CENTRES = 64

# Meshes up to this many tets take every ball mean at once (BallAverages.mean_matrix: 0.13 s
# and 4.5 MB for a 1 m cube's 68,544 tets); finer ones screen centres instead (the same
# cube refined twice, 494,910 tets: 7-8 s, 192 MB and about 1 GB at the peak to build the
# matrix, 0.04-0.13 s to screen, for a check that runs once).
_MEAN_MATRIX_TETS = 150_000

# Weights of the squared Voigt strains in a strain tensor's squared Frobenius norm (shears halved).
_FROBENIUS_WEIGHTS = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])


class BallAverages:
    """Volume-weighted averages of per-tet values over balls around tet centroids.

    The ball of radius r around tet t holds every tet whose centroid lies within
    r of t's centroid (t itself always): ``mean_t = sum_s V_s x_s / sum_s V_s``.
    Radius 0 gives each tet's own value.

    Parameters
    ----------
    nodes : (N, 3) float
        Metres.
    tets : (M, 4) int
    cache : (load, store), optional
        Where the matrix of every ball mean (:meth:`mean_matrix`) is kept between
        processes: ``load(radius)`` returns it or None, ``store(radius, matrix)`` keeps it.
    """

    def __init__(self, nodes, tets, cache=None) -> None:
        nodes = np.asarray(nodes, dtype=float)
        tets = np.asarray(tets)
        self.centroids = nodes[tets].mean(axis=1)
        self.volumes = np.abs(tet_signed_volumes(nodes, tets))
        self._tree = cKDTree(self.centroids)
        self._mean_matrices: dict[float, sp.csr_matrix] = {}
        self._questions: dict[float, int] = {}  # screened answers per radius (_all_means)
        self._cache = cache

    def weights(self, centres, radius: float) -> tuple[np.ndarray, sp.csr_matrix]:
        """The averaging weights of some centre tets.

        Parameters
        ----------
        centres : (c,) int
            Tet ids.
        radius : float
            Metres, >= 0.

        Returns
        -------
        members : (e,) int
            Sorted ids of every tet in one of the balls.
        weights : (c, e) scipy.sparse.csr_matrix
            ``weights @ values[members]`` are the centres' ball means; rows sum to 1.
        """
        radius = _checked_radius(radius)
        centres = np.asarray(centres, dtype=np.int64)
        every = self._mean_matrices.get(radius) if radius > 0.0 else None
        if every is not None:
            # Those rows of every ball's weights, once known (a planner's new prints ask
            # for thousands of balls: 5 -> 1 ms on a foam mat): the same pairs, summed in
            # the same order, so the same bits.
            rows = every[centres]
            members, columns = _distinct(rows.indices, self.volumes.size)
            return members, sp.csr_matrix((rows.data, columns, rows.indptr), shape=(centres.size, members.size))
        owner, flat = self._pairs(centres, radius)
        members, columns = _distinct(flat, self.volumes.size)
        counts = np.bincount(owner, minlength=centres.size)
        data = self.volumes[flat]
        indptr = np.concatenate([[0], np.cumsum(counts)])
        totals = np.add.reduceat(data, indptr[:-1]) if data.size else np.zeros(0)
        data = data / np.repeat(totals, counts)
        return members, sp.csr_matrix((data, columns, indptr), shape=(centres.size, members.size))

    def near(self, tets, radius: float) -> np.ndarray:
        """(n,) sorted ids of the given tets and of every tet whose centroid lies within
        ``radius`` of one of theirs (the centres whose balls reach them)."""
        radius = _checked_radius(radius)
        tets = np.unique(np.asarray(tets, dtype=np.int64))
        if radius == 0.0 or tets.size == 0:
            return tets
        # Asked the other way round: which tets near the given ones' bounds have one of
        # them within the radius (a count per tet, no list per ball: a foam mat's print,
        # a thousand balls of hundreds of tets each, 2x faster; the same set).
        points = self.centroids[tets]
        # The box only preselects (widened past its rounding); the tree's test decides.
        pad = radius * (1.0 + 1e-9)
        low, high = points.min(axis=0) - pad, points.max(axis=0) + pad
        around = np.flatnonzero(np.all((self.centroids >= low) & (self.centroids <= high), axis=1))
        reached = cKDTree(points).query_ball_point(self.centroids[around], radius, return_length=True) > 0
        return np.union1d(tets, around[reached])

    def _pairs(self, centres, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Every (centre position, tet id) whose centroids lie within ``radius``, sorted by
        centre position, then tet id: (e,) int each.

        One tree-against-tree query over the centres (scipy's
        ``sparse_distance_matrix``) instead of a ball query per centre: the strain
        sets of a planner's new prints and every verification read thousands of balls,
        and the per-centre lists cost twice the query itself (measured on a foam mat:
        20 ms against 11 ms for 3,485 balls). :meth:`near` needs only their union: a
        count per nearby tet gives it.
        """
        if radius == 0.0:
            return np.arange(centres.size, dtype=np.int64), centres
        if centres.size == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        near = cKDTree(self.centroids[centres]).sparse_distance_matrix(self._tree, radius, output_type="ndarray")
        # Sorted by one integer key, owner then tet (the order np.lexsort gives, 3-4 times
        # faster: 0.13 s -> 0.03 s for a million pairs; no overflow below 3e9 tets).
        key = near["i"].astype(np.int64) * self.volumes.size + near["j"].astype(np.int64)
        key.sort()
        return np.divmod(key, self.volumes.size)

    def mean_matrix(self, radius: float) -> sp.csr_matrix:
        """(M, M) averaging weights of every tet's ball: ``mean_matrix(r) @ values`` are
        all the ball means. Built on first use per radius (0.13 s for the 68,544 tets
        of a 1 m cube, 283,548 entries) and kept.
        """
        radius = _checked_radius(radius)
        known = self._mean_matrices.get(radius)
        if known is None:
            known = self._cached_matrix(radius)
        if known is None:
            members, known = self.weights(np.arange(self.volumes.size), radius)
            if members.size != self.volumes.size:  # every tet lies in its own ball
                raise FemError("a tet is missing from the ball means; the mesh has NaN centroids")
            self._mean_matrices[radius] = known
            if self._cache is not None:
                self._cache[1](radius, known)
        return known

    def _cached_matrix(self, radius: float):
        """The matrix of every ball mean at ``radius`` from the cache (kept), or None."""
        known = None if self._cache is None else self._cache[0](radius)
        if known is not None:
            self._mean_matrices[radius] = known
        return known

    def largest_principal(self, voigt, radius: float) -> tuple[float, int]:
        """The largest principal strain magnitude of the ball means over all tets, and its centre tet.

        A principal strain is at most its Frobenius norm, and a mean's norm at most the
        mean of its tets' norms (a norm is convex): with :meth:`mean_matrix` known, one
        product of the tets' norms bounds every mean, the means of the
        :data:`_BOUND_CENTRES` centres with the largest bounds give a largest principal
        strain to beat, and only the centres whose bound reaches it are averaged and
        decomposed (a 1 m cube's 34,086 tets under a palm: 15 centres; 0.6 ms against
        2.6 ms for every mean and its norm). Where the means are not taken at once
        (:meth:`_all_means`), the bound is the largest mean around the most strained
        tets, and only the centres with a tet at least that strained in their ball are
        averaged (:meth:`_reaching`). (Before, means were taken only around the most
        strained tets, a screen a broad field defeats: with a body's own weight, whose
        strain spreads through it, step-on-cube's check, the tets' strains included,
        went from 4.8 to 12.4 ms.) Each mean is summed in tet order: the same bits as a
        mean taken alone, or all at once.

        Parameters
        ----------
        voigt : (M, 6) float
            Voigt strains per tet (engineering shears).
        radius : float
            Metres, >= 0.

        Returns
        -------
        (float, int)
        """
        voigt = np.asarray(voigt, dtype=float)
        norms = frobenius_norms(voigt)
        if self._all_means(radius):
            bounds, means_at = self._mean_bounds(voigt, radius, norms)
            bound = _principal(means_at(_most_strained(bounds))).max()
            centres = np.flatnonzero(bounds >= bound * (1.0 - 1e-12))
            return _largest(means_at(centres), centres)
        members, weights = self.weights(_most_strained(norms), radius)
        bound = _principal(weights @ voigt[members]).max()
        centres, candidates = self._reaching(voigt, radius, norms, bound * (1.0 - 1e-12))
        return _largest(candidates, centres)

    def centres_above(self, voigt, radius: float, threshold: float) -> np.ndarray:
        """(n,) sorted ids of the tets whose ball mean's largest principal strain
        magnitude is at least ``threshold``.

        Means and eigenvalues only where a bound on the mean's Frobenius norm, which
        bounds its principal strains, reaches the threshold (see :meth:`largest_principal`).

        Parameters
        ----------
        voigt, radius
            As :meth:`largest_principal`.
        threshold : float
            Dimensionless, > 0.
        """
        voigt = np.asarray(voigt, dtype=float)
        if not threshold > 0.0:
            raise FemError(f"threshold must be a strain > 0, got {threshold!r}")
        norms = frobenius_norms(voigt)
        if self._all_means(radius, question=False):
            bounds, means_at = self._mean_bounds(voigt, radius, norms)
            centres = np.flatnonzero(bounds >= threshold)
            candidates = means_at(centres)
        else:
            centres, candidates = self._reaching(voigt, radius, norms, threshold)
        return centres[_principal(candidates) >= threshold] if centres.size else centres

    def _mean_bounds(self, voigt, radius: float, norms):
        """With every ball mean at hand (:meth:`_all_means`): (M,) upper bounds of the
        means' Frobenius norms, from the tets' ``norms`` (M,), and ``means_at(centres)``,
        the (c, 6) means of some centres (at radius 0, the tets' own strains and norms)."""
        if _checked_radius(radius) == 0.0:
            return norms, lambda centres: voigt[centres]
        matrix = self.mean_matrix(radius)
        # The rows of the matrix kept as they are: each mean summed as in the whole product.
        return matrix @ norms, lambda centres: matrix[centres] @ voigt

    def _reaching(self, voigt, radius: float, norms, floor: float):
        """The centres whose ball mean's Frobenius norm (which bounds its principal
        strains) can reach ``floor``, (n,) sorted, and their means, (n, 6), from the tets'
        own ``norms`` (M,): those with a tet in their ball whose norm does, a mean's norm
        being at most the largest in its ball; only they are averaged, each in tet order
        (the same bits as every mean at once)."""
        centres = self.near(np.flatnonzero(norms >= floor), radius)
        if centres.size == 0:
            return centres, np.zeros((0, 6))
        members, weights = self.weights(centres, radius)
        return centres, weights @ voigt[members]

    def _all_means(self, radius: float, question: bool = True) -> bool:
        """Whether to take every ball mean (:meth:`mean_matrix`) rather than screen: at
        radius 0, once the matrix is built or found in the cache, and from the second
        question at a radius, on meshes of at most :data:`_MEAN_MATRIX_TETS` tets. A
        process that asks once (a stance check) does not build the matrix (0.13-0.3 s on
        the 1 m cube and the foam bodies); one that asks again (a planner's checks)
        builds and stores it. Both ways give the same bits. ``question`` False: a
        one-off use that does not count (and screens unless the matrix is there)."""
        radius = _checked_radius(radius)
        if radius == 0.0 or radius in self._mean_matrices:
            return True
        if self.volumes.size > _MEAN_MATRIX_TETS:
            return False
        if self._questions.get(radius, 0) == 0 and self._cached_matrix(radius) is not None:
            return True
        if not question:
            return False
        self._questions[radius] = self._questions.get(radius, 0) + 1
        return self._questions[radius] >= 2


def _checked_radius(radius) -> float:
    radius = float(radius)
    if not (np.isfinite(radius) and radius >= 0.0):
        raise FemError(f"strain averaging radius must be >= 0 metres (0: each tet's own strain), got {radius!r}")
    return radius


def _distinct(ids: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """The sorted distinct values of (n,) ids in [0, size) and each id's position among
    them, (k,) and (n,) int: ``np.unique(ids, return_inverse=True)`` from a mask instead
    of a sort (1.6 million ball pairs on a 167,700-tet foam mesh: 7 ms against 70 ms)."""
    present = np.zeros(size, dtype=bool)
    present[ids] = True
    members = np.flatnonzero(present)
    # A lookup written only at the members: a cumulative sum over every tet costs 5 ms
    # on a 495k-tet mesh for a ball of 64 ids.
    lookup = np.empty(size, dtype=np.intp)
    lookup[members] = np.arange(members.size)
    return members, lookup[ids]


def _most_strained(norms: np.ndarray) -> np.ndarray:
    """(k,) sorted ids of the :data:`_BOUND_CENTRES` largest of (T,) norms."""
    count = min(_BOUND_CENTRES, norms.size)
    return np.sort(np.argpartition(norms, norms.size - count)[norms.size - count:])


def _largest(means: np.ndarray, centres: np.ndarray) -> tuple[float, int]:
    """The largest principal strain magnitude of (c, 6) Voigt means and its centre
    among (c,) ``centres`` (the first on a tie)."""
    values = _principal(means)
    best = int(np.argmax(values))
    return float(values[best]), int(centres[best])


def frobenius_norms(voigt: np.ndarray) -> np.ndarray:
    """(T,) Frobenius norms of the strain tensors of (T, 6) Voigt strains (shears halved).

    One matrix-vector product of the squares (numpy's sums along a row of six took ten
    times as long: 1.9 ms on 34,086 tets)."""
    return np.sqrt((voigt * voigt) @ _FROBENIUS_WEIGHTS)


def _principal(voigt: np.ndarray) -> np.ndarray:
    """(T,) largest principal strain magnitudes of (T, 6) Voigt strains."""
    return np.abs(np.linalg.eigvalsh(voigt_to_tensor_strain(voigt))).max(axis=1)


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
