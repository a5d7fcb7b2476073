"""Geometric nested-dissection ordering of mesh nodes for sparse Cholesky.

CHOLMOD as shipped with cvxopt orders with AMD only (no METIS); on 3-D meshes AMD
leaves several times more fill than nested dissection. Nodes have coordinates, so a
geometric dissection (split at the median of the widest axis, the separator is the
layer of nodes of one half touching the other) is cheap; on a 24k-node cube it made
CHOLMOD's factorisation about 3x faster than with AMD (measured, see bench/results).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["nested_dissection", "node_adjacency"]

_LEAF = 64


def node_adjacency(tets: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """Node-to-node adjacency of a tet mesh, (N, N) csr bool, no diagonal."""
    rows = np.repeat(tets, 4, axis=1).ravel()
    cols = np.tile(tets, (1, 4)).ravel()
    keep = rows != cols
    a = sp.csr_matrix((np.ones(keep.sum(), dtype=np.int8), (rows[keep], cols[keep])), shape=(n_nodes, n_nodes))
    a.data[:] = 1
    return a


def nested_dissection(points: np.ndarray, adjacency: sp.csr_matrix) -> np.ndarray:
    """Fill-reducing ordering of nodes: parts first, separators last, recursively.

    Parameters
    ----------
    points : (n, 3) float
        Node positions, metres.
    adjacency : (n, n) sparse
        Node graph (nodes sharing an element).

    Returns
    -------
    (n,) int permutation: eliminate ``order[0]`` first.
    """
    n = points.shape[0]
    adjacency = sp.csr_matrix(adjacency)
    order = np.empty(n, dtype=np.int64)
    side = np.zeros(n, dtype=bool)
    # Explicit stack of (node subset, first slot, last slot) instead of recursion.
    stack = [(np.arange(n), 0)]
    while stack:
        nodes, start = stack.pop()
        if nodes.size <= _LEAF:
            order[start : start + nodes.size] = nodes
            continue
        x = points[nodes]
        axis = int(np.ptp(x, axis=0).argmax())
        median = np.median(x[:, axis])
        left = x[:, axis] <= median
        if left.all() or not left.any():
            order[start : start + nodes.size] = nodes
            continue
        side[nodes[~left]] = True
        left_nodes = nodes[left]
        touches = (adjacency[left_nodes] @ side.astype(np.int8)) > 0
        side[nodes[~left]] = False
        separator = left_nodes[touches]
        part_a = left_nodes[~touches]
        part_b = nodes[~left]
        order[start + part_a.size + part_b.size : start + nodes.size] = separator
        stack.append((part_a, start))
        stack.append((part_b, start + part_a.size))
    return order
