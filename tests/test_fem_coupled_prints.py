"""Several prints on one body: the condensed forces against the full finite-element system.

The reference here is independent of the condensation: the whole stiffness K is
partitioned by hand (prescribed print dofs, fixed base, free rest) and solved
with scipy's sparse direct solver, then the reactions at the prints are K u.
"""

from __future__ import annotations

import numpy as np
import pytest

import fem
from fem_reference import direct_reactions as _direct_reactions

E, NU = 1e6, 0.4


@pytest.fixture(scope="module")
def block():
    """A 0.6 x 0.4 x 0.1 m foam block, base fixed, and two sole-sized prints 5 cm apart."""
    mesh = fem.box_mesh((0.6, 0.4, 0.1), (24, 16, 4))
    body = fem.DeformableBody(mesh, fem.LinearElasticMaterial(E, NU), np.flatnonzero(mesh.nodes[:, 2] == 0.0))
    left = fem.nodes_in_polygon(mesh, [[0.05, 0.05, 0.1], [0.25, 0.05, 0.1], [0.25, 0.35, 0.1], [0.05, 0.35, 0.1]])
    right = fem.nodes_in_polygon(mesh, [[0.30, 0.05, 0.1], [0.55, 0.05, 0.1], [0.55, 0.35, 0.1], [0.30, 0.35, 0.1]])
    return body, np.asarray(left), np.asarray(right)


def _press(rng, count):
    """A different imposed motion per print: down 3-5 mm, a little sideways."""
    return np.column_stack([rng.uniform(-1e-3, 1e-3, count), rng.uniform(-1e-3, 1e-3, count), rng.uniform(-5e-3, -3e-3, count)])


def test_coupled_print_forces_equal_the_full_system_with_both_prints_prescribed(block):
    body, left, right = block
    rng = np.random.default_rng(3)
    both = np.concatenate([left, right])
    displacements = _press(rng, both.size)
    patch = body.contact_patch(both)
    coupled = patch.reaction_forces(displacements)  # on the robot
    direct, _ = _direct_reactions(body, both, displacements)  # on the body
    assert np.abs(coupled + direct).max() <= 1e-8 * np.abs(direct).max()


def test_prints_condensed_separately_get_the_forces_wrong(block):
    """The old model (one Schur complement per print) misses the body's coupling."""
    body, left, right = block
    displacements = np.tile([0.0, 0.0, -0.004], (left.size + right.size, 1))
    coupled = body.contact_patch(np.concatenate([left, right])).reaction_forces(displacements)
    alone = body.contact_patch(left).reaction_forces(displacements[: left.size])
    difference = np.abs(alone - coupled[: left.size]).max() / np.abs(coupled[: left.size]).max()
    assert difference > 0.01


def _pressed_together(block, seed):
    """Both prints pressed with a random motion: body, nodes, U, patch, forces on the body."""
    body, left, right = block
    both = np.concatenate([left, right])
    displacements = _press(np.random.default_rng(seed), both.size)
    patch = body.contact_patch(both)
    return body, both, displacements, patch, -patch.reaction_forces(displacements)


def test_coupled_print_forces_balance_the_base_reactions(block):
    body, _, displacements, patch, on_body = _pressed_together(block, 4)
    field = body.displacement_field(patch, displacements)
    base = body.fixed_reactions(field)
    assert np.abs(on_body.sum(axis=0) + base.sum(axis=0)).max() <= 1e-8 * np.abs(on_body).sum()


def test_field_under_the_print_forces_puts_the_nodes_where_they_were_pressed(block):
    """One solve of the full system with the forces as loads gives back the print motion."""
    body, both, displacements, _, on_body = _pressed_together(block, 5)
    field = body.displacement_under_loads(both, on_body)
    assert np.abs(field[both] - displacements).max() <= 1e-9
    _, direct_field = _direct_reactions(body, both, displacements)
    assert np.abs(field - direct_field).max() <= 1e-9


def test_the_field_of_the_same_loads_asked_again_is_the_same_and_not_shared(block):
    """The last field is kept for a second caller (a solver's check, then its result):
    the same bits, in an array of its own; other loads get their own field."""
    body, both, _, _, on_body = _pressed_together(block, 9)
    first = body.displacement_under_loads(both, on_body)
    again = body.displacement_under_loads(both, on_body.copy())
    np.testing.assert_array_equal(first, again)
    again[:] = 0.0  # a caller writing into its field changes nobody else's
    np.testing.assert_array_equal(body.displacement_under_loads(both, on_body), first)
    doubled = body.displacement_under_loads(both, 2.0 * on_body)
    assert np.allclose(doubled, 2.0 * first, rtol=1e-12, atol=1e-15)
    assert np.allclose(body.displacement_under_loads(both[::-1], on_body[::-1]), first, rtol=1e-12, atol=1e-15)


def test_strain_map_matches_the_strain_of_the_full_field(block):
    body, left, _ = block
    displacements = _press(np.random.default_rng(6), left.size)
    patch = body.contact_patch(left)
    field = body.displacement_field(patch, displacements)
    expected = body.strain(field)[patch.neighbour_tets]
    assert np.allclose(patch.strain_map @ displacements.ravel(), expected, atol=1e-10)
    # The per-evaluation path, through the tets' nodes, gives the full field's strains too.
    assert np.allclose(patch.neighbour_strains(displacements.ravel()), expected, atol=1e-10)


def test_a_strain_row_of_one_tet_is_that_row_of_the_strain_map():
    """What the posture solver's strain rows differentiate with, tet by tet and
    without the full map: the tets around the print (nodes in it, free nodes, and,
    on a block one tet thick, fixed ones) give the map's rows."""
    mesh = fem.box_mesh((0.6, 0.4, 0.05), (12, 8, 1))
    body = fem.DeformableBody(mesh, fem.LinearElasticMaterial(E, NU), np.flatnonzero(mesh.nodes[:, 2] == 0.0))
    left = fem.nodes_in_polygon(mesh, [[0.05, 0.05, 0.05], [0.25, 0.05, 0.05], [0.25, 0.35, 0.05], [0.05, 0.35, 0.05]])
    patch = body.contact_patch(left)
    rng = np.random.default_rng(8)
    tets = body.mesh.tets[patch.neighbour_tets]
    on_base = np.flatnonzero(body.fixed_mask[tets].any(axis=1))
    in_print = np.flatnonzero(np.isin(tets, left).any(axis=1))
    chosen = np.unique(np.concatenate([on_base[:3], in_print[:3], rng.choice(len(tets), 4, replace=False)]))
    assert on_base.size and in_print.size
    for tet in chosen.tolist():
        weights = rng.normal(size=6)
        expected = weights @ patch.strain_map[tet]
        assert np.allclose(patch.neighbour_strain_row(weights, tet), expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())


def test_strain_map_does_not_depend_on_the_young_modulus(block):
    body, left, _ = block
    stiff = fem.DeformableBody(body.mesh, fem.LinearElasticMaterial(1e10, NU), body.fixed_nodes)
    soft_map = body.contact_patch(left).strain_map
    stiff_map = stiff.contact_patch(left).strain_map
    assert np.allclose(soft_map, stiff_map, rtol=1e-6, atol=1e-9 * np.abs(soft_map).max())


def test_loads_on_a_fixed_node_are_refused(block):
    body, _, _ = block
    with pytest.raises(fem.BoundaryError, match="is fixed"):
        body.displacement_under_loads(body.fixed_nodes[:1], np.zeros((1, 3)))


def test_largest_principal_strain_is_the_maximum_over_every_tet(block):
    body, left, right = block
    both = np.concatenate([left, right])
    displacements = _press(np.random.default_rng(7), both.size)
    field = body.displacement_field(body.contact_patch(both), displacements)
    every = np.abs(body.principal_strains(field)).max(axis=1)
    value, tet = body.largest_principal_strain(field)
    assert value == pytest.approx(every.max(), rel=1e-12) and every[tet] == pytest.approx(value, rel=1e-12)
