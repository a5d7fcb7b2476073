"""An independent reference for condensed print forces: the full FEM system solved directly."""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla


def direct_reactions(body, node_ids, displacements):
    """Reactions at prescribed nodes from the full system (no condensation, no cache).

    Parameters
    ----------
    body : fem.DeformableBody
    node_ids : (p,) int
        Nodes whose displacement is prescribed.
    displacements : (p, 3) float
        Their displacements, metres, body frame.

    Returns
    -------
    reactions : (p, 3) float
        ``K u`` at the prescribed nodes: the forces the body needs there, N.
    field : (N, 3) float
        The full displacement field, metres.
    """
    k = body.stiffness.tocsr()
    n_dofs = body.mesh.n_dofs
    prescribed = np.zeros(n_dofs)
    dofs = (3 * node_ids[:, None] + np.arange(3)).ravel()
    prescribed[dofs] = displacements.ravel()
    known = np.zeros(n_dofs, dtype=bool)
    known[dofs] = True
    known[(3 * body.fixed_nodes[:, None] + np.arange(3)).ravel()] = True
    free = np.flatnonzero(~known)
    u = prescribed.copy()
    u[free] = spla.spsolve(k[free][:, free].tocsc(), -(k[free] @ prescribed))
    return (k @ u)[dofs].reshape(-1, 3), u.reshape(-1, 3)
