"""Rigid flat punch on a thick block: mesh convergence toward Sneddon's half-space stiffness.

Reference: a rigid circular punch of radius a pressed into an elastic half-space has
the vertical stiffness k = 2 a E / (1 - nu^2) (Sneddon 1965, frictionless). Our square
print of side 2c is compared with the circle of equal area, a = 2c / sqrt(pi). Two
corrections are below 1 % and ignored: a rigid square is ~0.6 % stiffer than the
equal-area circle (Gazetas 1991 fit), and our print nodes are bonded (no lateral slip),
which for nu = 0.4 adds (1 - nu) ln(3 - 4 nu) / (1 - 2 nu) - 1 = 0.9 %. The block
(half-width and depth 10 c, base fixed, sides free) is not a half-space either: the
fixed base stiffens it by a few percent. Displacement-based elements are too stiff
and the rigid-punch edge is singular, so the stiffness converges from above at a rate
near h^(1/2); we assert a monotone decrease of the error and a positive fitted rate,
not a tight tolerance. The longer table is in bench/results/fem.md.
"""

import numpy as np

from fem import DeformableBody, LinearElasticMaterial, nodes_in_polygon, tensor_mesh

E, NU = 1e6, 0.4
HALF_SIDE = 0.05  # c, metres
DEPTH = 1e-4  # imposed uniform indentation, metres


def growing(start: float, first: float, stop: float, ratio: float = 1.3) -> np.ndarray:
    """Coordinates from start to stop, the first cell ``first`` long, growing by ``ratio``."""
    steps = [first]
    while start + sum(steps) < stop:
        steps.append(steps[-1] * ratio)
    coords = start + np.cumsum(steps)
    coords[-1] = stop  # the last cell absorbs the overshoot
    if coords.size > 1 and coords[-1] - coords[-2] < steps[-2] * 0.5:
        coords = np.delete(coords, -2)
    return np.concatenate([[start], coords])


def punch_mesh(level: int):
    """Cells of side c / level under the punch and around its edge, growing outside."""
    c = HALF_SIDE
    h = c / level
    inner = np.linspace(-c, c, 2 * level + 1)
    outer = growing(c, h, 10 * c)
    xs = np.concatenate([-outer[::-1], inner[1:-1], outer])
    zs = -growing(0.0, h, 10 * c)[::-1]
    return tensor_mesh(xs, xs, zs)


def punch_stiffness(level: int, methods=("consistent",)) -> tuple[int, list[float]]:
    """(number of nodes, [vertical force / depth in N/m per method]) for a uniform indentation."""
    mesh = punch_mesh(level)
    body = DeformableBody(mesh, LinearElasticMaterial(E, NU, 1e3), mesh.nodes[:, 2] == mesh.nodes[:, 2].min())
    c = HALF_SIDE
    patch = body.contact_patch(nodes_in_polygon(mesh, [[-c, -c, 0], [c, -c, 0], [c, c, 0], [-c, c, 0]]))
    press = np.tile([0.0, 0.0, -DEPTH], (patch.n_nodes, 1))
    return mesh.n_nodes, [patch.reaction_forces(press, m)[:, 2].sum() / DEPTH for m in methods]


def sneddon_stiffness() -> float:
    radius = 2 * HALF_SIDE / np.sqrt(np.pi)  # circle of the same area as the square
    return 2 * radius * E / (1 - NU**2)


def test_flat_punch_stiffness_converges_toward_sneddon_half_space():
    reference = sneddon_stiffness()
    levels = (1, 2, 3, 4)  # 1k to 8k nodes
    sizes, errors, gaps = [], [], []
    for level in levels:
        n_nodes, (k, k_traction) = punch_stiffness(level, ("consistent", "traction"))
        sizes.append(2 * HALF_SIDE / (2 * level))
        errors.append(k / reference - 1.0)
        gaps.append(1.0 - k_traction / k)
    errors = np.array(errors)
    # The traction method (eqs. 41-44) and the consistent forces approach each other.
    # The gap depends on which kind of node lies under the punch's edge (the mesh's cells
    # are mirror images of their neighbours, and the top layer's parity alternates with
    # the level: measured 0.71, 0.40, 0.48, 0.29), so it shrinks from level to level + 2.
    assert gaps[2] < gaps[0] and gaps[3] < gaps[1], f"traction/consistent gap must shrink, got {gaps}"
    assert np.all(errors > 0), "displacement FE must be stiffer than the exact solution"
    assert np.all(np.diff(errors) < 0), f"error must decrease with refinement, got {errors}"
    rate = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert 0.3 < rate < 1.5, f"fitted convergence rate {rate:.2f}"
    assert errors[-1] < 0.6
