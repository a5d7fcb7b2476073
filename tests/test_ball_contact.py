"""A ball pressed into a soft block: Hertz's contact on the mesh, not a flat punch.

A point foot's print nodes lie the ball's profile below it (``stances.deformable.ball_gaps``)
and touch only once the ball has sunk that far, so its contact spreads as it sinks and its
force grows as depth^1.5 (Hertz), where a print whose every node followed the ball (a flat
punch of the ball's radius, the model until 2026-12-03) grows linearly and carried 5-35
times the load at the depths ANYmal's planned stances reach on foam.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fem
from environments.deformable import soft_box_coordinates
from stances.deformable import ball_gaps

RADIUS = 0.031  # m, ANYmal's foot
FOAM = fem.LinearElasticMaterial(1e6, 0.4)  # quadruped-foam's foam until 2026-12-03 (3e6 Pa since)
FRICTION = 0.7


def hertz_force(depth: float, radius: float = RADIUS, material=FOAM) -> float:
    """Hertz: a rigid sphere pressed ``depth`` into an elastic half-space, newtons."""
    modulus = material.young_modulus / (1.0 - material.poisson_ratio**2)
    return 4.0 / 3.0 * modulus * math.sqrt(radius) * depth**1.5


def ball_body(size, spacing, centre, margin):
    """A soft box of ``size`` (m), base fixed, meshed at ``spacing`` within ``margin`` of
    ``centre`` (top-face frame, m): its body and the top nodes a ball there may touch."""
    region = [[centre[0] - margin, centre[1] - margin], [centre[0] + margin, centre[1] + margin]]
    mesh = fem.tensor_mesh(*soft_box_coordinates(size, spacing, refine=region))
    body = fem.DeformableBody(mesh, FOAM, np.flatnonzero(mesh.nodes[:, 2] < 1e-12), cache=False)
    return body


def top_nodes_near(body, centre, reach: float) -> np.ndarray:
    """(k,) sorted ids of the body's top nodes within ``reach`` (m) of ``centre`` (xy, m)."""
    nodes = body.mesh.nodes
    top = np.isclose(nodes[:, 2], nodes[:, 2].max())
    return np.flatnonzero(top & (np.linalg.norm(nodes[:, :2] - np.asarray(centre), axis=1) < reach))


def ball_force(body, centre, depth: float, flat: bool = False, reach: float | None = None, known=None):
    """The ball's normal force (N), its pressed nodes and contact state at ``depth`` (m)
    below touching.

    Every top node within ``reach`` (default the ball's radius) of the centre may touch; with
    ``flat`` they all follow the ball from the start (no profile): a flat punch. ``known``:
    (sorted node ids, their compliance) covering those nodes, read instead of solving.
    """
    nodes = body.mesh.nodes
    offsets = nodes[:, :2] - np.asarray(centre)
    ids = top_nodes_near(body, centre, reach or RADIUS)
    in_print = np.column_stack([offsets[ids], np.zeros(ids.size)])
    motion = np.zeros((ids.size, 3))
    motion[:, 2] = -depth + (0.0 if flat else ball_gaps(in_print, RADIUS))
    frames = np.tile(np.eye(3), (ids.size, 1, 1))
    if known is None:
        compliance = body.compliance(ids)
    else:
        dofs = (3 * np.searchsorted(known[0], ids)[:, None] + np.arange(3)).ravel()
        compliance = known[1][np.ix_(dofs, dofs)]
    state = fem.solve_print_contact(compliance, motion, frames, np.full(ids.size, FRICTION))
    pressed = state.modes != fem.LIFT
    return float(state.forces[:, 2].sum()), ids[pressed], state


def test_a_ball_profile_is_its_height_over_the_print_plane():
    nodes = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, -0.02, 0.0], [0.03, 0.03, 0.0], [0.01, 0.0, 0.002]])
    gaps = ball_gaps(nodes, RADIUS)
    expected = [0.0, RADIUS - math.sqrt(RADIUS**2 - 1e-4), RADIUS - math.sqrt(RADIUS**2 - 4e-4), RADIUS, 0.0]
    np.testing.assert_allclose(gaps, expected, rtol=1e-12, atol=1e-15)
    # Near the centre the sphere is Hertz's paraboloid rho^2 / 2R (2.7 % below it at rho = R / 3).
    assert gaps[1] == pytest.approx(1e-4 / (2 * RADIUS), rel=0.03)
    # A node 2 mm above the plane at rho = 10 mm: the ball (1.65 mm up there) already touches it.
    assert gaps[4] == 0.0


@pytest.fixture(scope="module")
def block():
    """A 5 cm foam block (0.12 m square), meshed at 5 mm under the ball."""
    return ball_body((0.12, 0.12, 0.05), 0.005, (0.0, 0.0), 0.035)


@pytest.fixture(scope="module")
def under_ball(block):
    """The block's top nodes under the ball's circle and their compliance (one solve each)."""
    ids = top_nodes_near(block, (0.0, 0.0), RADIUS)
    return ids, block.compliance(ids)


def test_a_ball_contact_spreads_as_it_sinks_and_its_force_grows_as_hertz_says(block, under_ball):
    depths = (0.001, 0.002)
    # Nodes beyond 17 mm cannot touch at 2 mm (their gap is 4.9 mm): left out.
    (f1, pressed1, state1), (f2, pressed2, _) = [
        ball_force(block, (0.0, 0.0), d, reach=0.017, known=under_ball) for d in depths
    ]
    # Hertz: F ~ d^1.5 (2.83 for twice the depth; the 5 cm layer, stiffer as the contact
    # spreads, about 2.97 converged); a flat punch: F ~ d (2.0). Measured 3.30: on this
    # 5 mm mesh the force at 1 mm is 8 % under its limit with the ball on this node
    # (bench/results/ball_foot.md).
    assert 2.5 < f2 / f1 < 3.4
    assert pressed1.size < pressed2.size
    # Pressed nodes lie where the ball reaches below the plane: rho <= sqrt(2 r d - d^2).
    for depth, pressed in zip(depths, (pressed1, pressed2)):
        reach = np.linalg.norm(block.mesh.nodes[pressed, :2], axis=1)
        assert reach.max() <= math.sqrt(2 * RADIUS * depth - depth**2) + 1e-12
    # No adhesion, and the lifted nodes carry nothing.
    assert state1.forces[:, 2].min() >= 0.0
    assert np.all(state1.forces[state1.modes == fem.LIFT] == 0.0)
    # Against Hertz's half-space: a 5 cm layer bonded to its base is stiffer (the contact
    # radius, 5.6-7.9 mm, is 11-16 % of the thickness), never softer.
    for depth, force in zip(depths, (f1, f2)):
        assert 1.0 < force / hertz_force(depth) < 1.4


def test_a_flat_punch_of_the_ball_radius_carries_many_times_the_balls_load(block, under_ball):
    # The model of point feet until 2026-12-03 (every print node following the ball).
    ball, _, _ = ball_force(block, (0.0, 0.0), 0.001, known=under_ball)
    punch, _, _ = ball_force(block, (0.0, 0.0), 0.001, flat=True, known=under_ball)
    assert punch > 5.0 * ball
