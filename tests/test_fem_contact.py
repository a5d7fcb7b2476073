"""Signorini-Coulomb contact of a rigid indenter on a print, against the full FEM system.

Each answer of :func:`fem.solve_print_contact` is checked with quantities it did
not compute: the whole body is loaded by the returned forces (one sparse solve of
the full stiffness), and the motion of each indenter point relative to its node
must then obey the contact law, node by node. Limits: infinite friction is the
bonded answer, zero friction is frictionless.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fem
from fem.dense import spd_inverse

MU = 0.5
DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="module")
def pad():
    """A 0.4 x 0.4 x 0.1 m pad, base fixed, and a 0.2 x 0.2 m print in the middle."""
    mesh = fem.box_mesh((0.4, 0.4, 0.1), (16, 16, 6))
    body = fem.DeformableBody(mesh, fem.LinearElasticMaterial(1e6, 0.45), np.flatnonzero(mesh.nodes[:, 2] == 0.0))
    ids = np.asarray(fem.nodes_in_polygon(mesh, [[0.1, 0.1, 0.1], [0.3, 0.1, 0.1], [0.3, 0.3, 0.1], [0.1, 0.3, 0.1]]))
    patch = body.contact_patch(ids)
    frames = np.tile(np.eye(3), (ids.size, 1, 1))  # t1 = x, t2 = y, n = z (outward)
    return body, patch, frames


def _rigid_motion(points, translation, rotation_vector, centre):
    """Displacement of points under a small rigid motion (exact rotation)."""
    angle = np.linalg.norm(rotation_vector)
    if angle == 0.0:
        return np.tile(translation, (len(points), 1))
    axis = rotation_vector / angle
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    return (points - centre) @ rotation.T + centre + translation - points


def _full_system_relative_motion(body, patch, forces):
    """Indenter-minus-node motion needs U; here: node displacements from the full system."""
    return body.displacement_under_loads(patch.node_ids, -forces)[patch.node_ids]


def _check_signorini_coulomb(body, patch, displacements, state, mu, tolerance=1e-9):
    forces = state.forces
    relative = displacements - _full_system_relative_motion(body, patch, forces)
    scale = np.abs(forces).max()
    normal, gap = forces[:, 2], relative[:, 2]
    assert normal.min() >= -1e-9 * scale  # every node pushes or is free
    assert gap.min() >= -tolerance  # no indenter point inside the body
    pressed = normal > 1e-9 * scale
    assert np.abs(gap[pressed]).max(initial=0.0) <= tolerance  # pressing nodes touch
    assert np.abs(forces[~pressed]).max(initial=0.0) <= 1e-9 * scale  # lifted nodes carry nothing
    tangential = relative[:, :2]
    friction = forces[:, :2]
    bound = mu * normal
    size = np.linalg.norm(friction, axis=1)
    assert np.all(size <= bound + 1e-9 * scale)  # inside the exact (circular) cone
    inside = pressed & (size < bound - 1e-6 * scale)
    assert np.abs(tangential[inside]).max(initial=0.0) <= tolerance  # sticking nodes stick
    slipping = np.linalg.norm(tangential, axis=1) > tolerance
    # A slipping node's friction is on its bound, exactly against its slip (the
    # force on the indenter opposes the indenter's motion): maximum dissipation.
    against = -tangential[slipping] / np.linalg.norm(tangential[slipping], axis=1)[:, None]
    expected = (mu * normal[slipping])[:, None] * against
    assert np.abs(friction[slipping] - expected).max(initial=0.0) <= 1e-6 * scale
    return relative


def test_pressed_and_sheared_print_obeys_signorini_and_coulomb_in_the_full_system(pad):
    body, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.002, -0.001, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    state = fem.solve_print_contact(patch.compliance, displacements, frames, np.full(patch.n_nodes, MU))
    relative = _check_signorini_coulomb(body, patch, displacements, state, MU)
    # Shearing this much makes the print slide somewhere: both modes occur.
    assert 0 < state.n_stick < patch.n_nodes
    assert np.abs(relative[:, :2]).max() > 1e-6


def test_tilted_indenter_lifts_off_on_one_side(pad):
    body, patch, frames = pad
    centre = patch.points.mean(axis=0)
    displacements = _rigid_motion(patch.points, [0.0, 0.0, -0.002], [0.0, 0.03, 0.0], centre)
    state = fem.solve_print_contact(patch.compliance, displacements, frames, np.full(patch.n_nodes, MU))
    _check_signorini_coulomb(body, patch, displacements, state, MU)
    lifted = state.modes == fem.LIFT
    assert lifted.any() and not lifted.all()
    # A rotation about +y lowers the +x side: the -x side lifts off.
    assert patch.points[lifted, 0].mean() < centre[0] < patch.points[~lifted, 0].mean()


def test_infinite_friction_is_the_bonded_answer(pad):
    _, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.001, 0.001, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    state = fem.solve_print_contact(patch.compliance, displacements, frames, np.full(patch.n_nodes, np.inf))
    bonded = patch.reaction_forces(displacements)
    assert (state.modes == fem.STICK).all()
    assert np.allclose(state.forces, bonded, atol=1e-9 * np.abs(bonded).max())
    assert np.allclose(state.jacobian, patch.reaction_matrix("consistent"), atol=1e-9 * np.abs(bonded).max() / 1e-3)


def test_large_friction_tends_to_bonded_and_zero_friction_is_frictionless(pad):
    body, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.001, 0.0, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    shear = []
    for mu in (0.0, 0.2, 0.5, 2.0, 50.0):
        state = fem.solve_print_contact(patch.compliance, displacements, frames, np.full(patch.n_nodes, mu))
        _check_signorini_coulomb(body, patch, displacements, state, mu)
        shear.append(state.forces[:, 0].sum())
    bonded = patch.reaction_forces(displacements)[:, 0].sum()
    assert shear[0] == pytest.approx(0.0, abs=1e-9 * abs(bonded))
    grip = np.abs(shear)  # the pad holds the indenter back: its shear force opposes +x
    assert np.all(np.diff(grip[:3]) > 0) and np.all(np.diff(grip) >= -1e-9 * grip[-1])  # more friction, more grip
    assert shear[-1] == pytest.approx(bonded, rel=1e-9)


def test_forces_are_linear_in_the_motion_with_the_returned_jacobian(pad):
    """Within one contact set the forces are L U exactly; central differences agree."""
    _, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.002, -0.001, -0.004], [0.0, 0.02, 0.0], patch.points.mean(axis=0))
    mu = np.full(patch.n_nodes, MU)
    state = fem.solve_print_contact(patch.compliance, displacements, frames, mu)
    assert np.allclose(state.jacobian @ displacements.ravel(), state.forces.ravel(), atol=1e-9 * np.abs(state.forces).max())
    rng = np.random.default_rng(0)
    direction = rng.normal(size=displacements.shape) * 1e-9
    plus = fem.solve_print_contact(patch.compliance, displacements + direction, frames, mu, initial_modes=state.modes)
    minus = fem.solve_print_contact(patch.compliance, displacements - direction, frames, mu, initial_modes=state.modes)
    assert np.array_equal(plus.modes, state.modes) and np.array_equal(minus.modes, state.modes)
    numeric = (plus.forces - minus.forces).ravel() / 2.0
    # Entry by entry: within 1e-6 of each force component's change, plus a round-off
    # floor 1e-8 of the largest (measured: 1e-13 N off, changes up to 2e-4 N).
    predicted = state.jacobian @ direction.ravel()
    floor = 1e-8 * np.abs(predicted).max()
    assert np.all(np.abs(numeric - predicted) <= 1e-6 * np.abs(predicted) + floor)


def test_a_print_pulled_up_carries_nothing(pad):
    _, patch, frames = pad
    displacements = np.tile([0.0, 0.0, 0.001], (patch.n_nodes, 1))
    state = fem.solve_print_contact(patch.compliance, displacements, frames, np.full(patch.n_nodes, MU))
    assert state.n_lift == patch.n_nodes and np.abs(state.forces).max() == 0.0


def test_bad_shapes_and_negative_friction_are_refused(pad):
    _, patch, frames = pad
    with pytest.raises(fem.FemError, match="shapes do not match"):
        fem.solve_print_contact(patch.compliance, np.zeros((3, 3)), frames, MU)
    with pytest.raises(fem.FemError, match="friction coefficients must be >= 0"):
        fem.solve_print_contact(patch.compliance, np.zeros((patch.n_nodes, 3)), frames, -1.0)


def test_gauss_seidel_fallback_finds_the_same_contact_state(pad):
    """The projected Gauss-Seidel used when the active set cycles agrees with it."""
    import scipy.linalg

    from fem.contact import _gauss_seidel

    _, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.002, -0.001, -0.004], [0.0, 0.02, 0.0], patch.points.mean(axis=0))
    mu = np.full(patch.n_nodes, MU)
    state = fem.solve_print_contact(patch.compliance, displacements, frames, mu)
    rotation = scipy.linalg.block_diag(*frames)  # body to node frames
    phi = _gauss_seidel(rotation @ patch.compliance @ rotation.T, (rotation @ displacements.ravel()).reshape(-1, 3), mu)[0]
    assert np.allclose(phi, state.forces, atol=1e-6 * np.abs(state.forces).max())


def test_held_modes_give_smooth_forces_and_say_when_they_no_longer_hold(pad):
    _, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    pressed = _rigid_motion(patch.points, [0.0005, 0.0, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    state = fem.solve_print_contact(patch.compliance, pressed, frames, mu)
    same = fem.print_contact_with_modes(patch.compliance, pressed, frames, mu, state.modes, state.directions)
    assert same.admissible and np.allclose(same.forces, state.forces, atol=1e-9 * np.abs(state.forces).max())
    pulled = np.tile([0.0, 0.0, 0.001], (patch.n_nodes, 1))  # the indenter leaves: every node should lift
    held = fem.print_contact_with_modes(patch.compliance, pulled, frames, mu, state.modes, state.directions)
    assert not held.admissible
    assert held.forces[:, 2].min() < 0.0  # held in contact, the nodes would pull


def test_held_modes_that_admit_no_coulomb_state_stop_on_their_cycle_not_the_step_limit(pad, monkeypatch):
    """A slipping node held in contact while the indenter leaves pulls: its bound mu phi_n is
    negative and its slip direction flips at every Newton step. The held solve sees the cycle
    (the direction back where it was two steps before) and stops there, unsettled, where it ran
    all ``_MAX_ITERATIONS`` (60 factorisations; a 520-node pair of soles spent 0.7 s a call so);
    a held solve that settles is not cut short."""
    from fem import contact

    _, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    system = fem.PrintContactSystem(patch.compliance, frames, mu)
    pressed = _rigid_motion(patch.points, [0.002, 0.0, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    state = system.solve(pressed)
    assert state.n_slip == 1
    steps = []
    forces = contact.PrintContactSystem._forces
    monkeypatch.setattr(contact.PrintContactSystem, "_forces", lambda self, *a: steps.append(1) or forces(self, *a))
    pulled = np.tile([0.0, 0.0, 0.001], (patch.n_nodes, 1))
    held = system.with_modes(pulled, state.modes, state.directions)
    assert not held.admissible and held.forces[state.modes == contact.SLIP, 2].min() < 0.0
    assert len(steps) == 2  # the flip back seen at the second step
    steps.clear()
    again = system.with_modes(pressed, state.modes, state.directions)
    assert again.admissible and np.allclose(again.forces, state.forces, atol=1e-9 * np.abs(state.forces).max())


def test_a_contact_system_reused_over_motions_gives_the_one_shot_answers(pad):
    """PrintContactSystem keeps each contact set's factorisation: the answers are the
    same bits as a fresh solve, whichever motions it met before."""
    _, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    system = fem.PrintContactSystem(patch.compliance, frames, mu, kept=2)
    centre = patch.points.mean(axis=0)
    motions = [
        _rigid_motion(patch.points, [0.0005 * k, -0.0003 * k, -0.004], [0.0, 0.01 * k, 0.0], centre) for k in range(4)
    ]
    for displacements in motions + motions[::-1]:
        reused = system.solve(displacements)
        fresh = fem.solve_print_contact(patch.compliance, displacements, frames, mu)
        assert np.array_equal(reused.forces, fresh.forces) and np.array_equal(reused.modes, fresh.modes)
        direction = np.random.default_rng(3).normal(size=(3 * patch.n_nodes, 2))
        assert np.array_equal(reused.jacobian_dot(direction), fresh.jacobian_dot(direction))
        held = system.with_modes(displacements, fresh.modes, fresh.directions)
        # Held modes: slipping nodes' directions are solved again from the given ones
        # (Newton on a different linearisation), the same answer to round-off.
        assert held.admissible and np.allclose(held.forces, reused.forces, rtol=0.0, atol=1e-10 * np.abs(reused.forces).max())
    assert len(system._factors) <= 2
    with pytest.raises(fem.FemError, match=r"displacements must have shape \(%d, 3\)" % patch.n_nodes):
        system.solve(np.zeros((2, 3)))


def test_the_law_is_isotropic_turning_the_tangent_axes_changes_nothing(pad):
    """Coulomb's cone is circular: the node frames' tangent axes turned 30 degrees
    about the normal give the same forces (an inner pyramid would not)."""
    _, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.002, 0.0015, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    mu = np.full(patch.n_nodes, MU)
    state = fem.solve_print_contact(patch.compliance, displacements, frames, mu)
    assert state.n_slip > 0  # the test needs slipping nodes, whose friction direction the axes would bias
    angle = np.radians(30.0)
    turn = np.array([[np.cos(angle), np.sin(angle), 0.0], [-np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    turned = fem.solve_print_contact(patch.compliance, displacements, turn @ frames, mu)
    assert np.array_equal(turned.modes, state.modes)
    assert np.allclose(turned.forces, state.forces, rtol=0.0, atol=1e-9 * np.abs(state.forces).max())


def test_a_print_turned_as_a_whole_gives_the_turned_forces_and_jacobian(pad):
    """The same print seen in axes turned by R (compliance, motions and node frames
    turned, each node's tangent axes turned about its normal by its own angle): the
    modes are the same and the forces and their Jacobian are the turned ones. The
    turned system goes through the node-frame rotation that frames equal to the body's
    axes skip (``PrintContactSystem``), so the two paths are checked against each other."""
    _, patch, frames = pad
    # Turned about z too: without it, on the mesh of mirrored cells (2026-12-03) every
    # node sticks (0 of 81 slip), and the turned system's slip rows go untested.
    displacements = _rigid_motion(patch.points, [0.002, 0.0015, -0.004], [0.01, -0.02, 0.01], patch.points.mean(axis=0))
    mu = np.full(patch.n_nodes, MU)
    system = fem.PrintContactSystem(patch.compliance, frames, mu)
    state = system.solve(displacements)
    assert state.n_slip > 0 and state.n_stick > 0
    rng = np.random.default_rng(7)
    angles = rng.uniform(-np.pi, np.pi, patch.n_nodes)
    spins = np.zeros((patch.n_nodes, 3, 3))
    spins[:, 0, 0] = spins[:, 1, 1] = np.cos(angles)
    spins[:, 0, 1], spins[:, 1, 0], spins[:, 2, 2] = np.sin(angles), -np.sin(angles), 1.0
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    turn = np.eye(3) + np.sin(1.1) * k + (1 - np.cos(1.1)) * k @ k
    big = np.kron(np.eye(patch.n_nodes), turn)
    turned_system = fem.PrintContactSystem(big @ patch.compliance @ big.T, spins @ frames @ turn.T, mu)
    turned = turned_system.solve(displacements @ turn.T)
    assert np.array_equal(turned.modes, state.modes)
    scale = np.abs(state.forces).max()
    assert np.abs(turned.forces - state.forces @ turn.T).max() <= 1e-9 * scale
    jacobian = big @ state.jacobian @ big.T
    assert np.abs(turned.jacobian - jacobian).max() <= 1e-9 * np.abs(jacobian).max()


def test_a_contact_solved_in_turned_frames_is_the_contact_of_those_frames(pad):
    """``turns`` (each node's contact frame in its node frame's coordinates: an indenter face
    turned from them) give the answer of a system built on the turned frames themselves (the
    same modes, forces, relative motions and Jacobian, in the body frame), while the system
    keeps its own frames' factorisations: sticking and lifted nodes are the same in any
    frame, slipping ones turn. Warm and held solves too; a wrong shape is refused."""
    _, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.002, 0.0015, -0.004], [0.01, -0.02, 0.01], patch.points.mean(axis=0))
    mu = np.full(patch.n_nodes, MU)
    face = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.03), np.sin(0.03)], [0.0, -np.sin(0.03), np.cos(0.03)]])  # a tilt
    turns = np.matmul(np.matmul(frames, face.T), frames.transpose(0, 2, 1))
    system = fem.PrintContactSystem(patch.compliance, frames, mu)
    reference = fem.PrintContactSystem(patch.compliance, np.matmul(turns, frames), mu)
    expected = reference.solve(displacements)
    assert expected.n_slip > 0 and expected.n_stick > 0
    for state in (system.solve(displacements, turns=turns),
                  system.solve(displacements, expected.modes, expected.directions, turns=turns),
                  system.with_modes(displacements, expected.modes, expected.directions, turns=turns)):
        assert np.array_equal(state.modes, expected.modes) and state.admissible
        scale = np.abs(expected.forces).max()
        assert np.abs(state.forces - expected.forces).max() <= 1e-9 * scale
        assert np.abs(state.relative - expected.relative).max() <= 1e-12
        assert np.abs(state.jacobian - expected.jacobian).max() <= 1e-9 * np.abs(expected.jacobian).max()
    # The module's functions pass the turns on.
    assert np.array_equal(fem.solve_print_contact(patch.compliance, displacements, frames, mu, turns=turns).forces,
                          system.solve(displacements, turns=turns).forces)
    held = fem.print_contact_with_modes(patch.compliance, displacements, frames, mu, expected.modes, expected.directions,
                                        turns=turns)
    assert np.abs(held.forces - expected.forces).max() <= 1e-9 * scale
    # The rest frames' answer is another: the turned face moves the slipping nodes' gap.
    assert np.abs(system.solve(displacements).forces - expected.forces).max() > 1e-3 * scale
    with pytest.raises(fem.FemError, match=r"turns must have shape \(\d+, 3, 3\), got \(2, 3, 3\)"):
        system.solve(displacements, turns=turns[:2])


def test_held_modes_forces_have_the_returned_jacobian_with_slip_directions_following(pad):
    """With the modes held, a slipping node's friction turns with its slip: the forces
    are smooth, not linear, and central differences agree with the held Jacobian."""
    _, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    displacements = _rigid_motion(patch.points, [0.002, -0.001, -0.004], [0.0, 0.02, 0.0], patch.points.mean(axis=0))
    state = fem.solve_print_contact(patch.compliance, displacements, frames, mu)
    assert state.n_slip > 0
    system = fem.PrintContactSystem(patch.compliance, frames, mu)
    held = system.with_modes(displacements, state.modes, state.directions)
    direction = np.random.default_rng(5).normal(size=displacements.shape) * 1e-8
    plus = system.with_modes(displacements + direction, state.modes, state.directions)
    minus = system.with_modes(displacements - direction, state.modes, state.directions)
    numeric = (plus.forces - minus.forces).ravel() / 2.0
    assert np.allclose(numeric, held.jacobian_dot(direction.reshape(-1, 1))[:, 0], rtol=0.0, atol=1e-6 * np.abs(numeric).max())
    # Not linear: a larger move turns the slip directions, so L U is no longer the force.
    moved = displacements + 1e3 * direction
    far = system.with_modes(moved, state.modes, state.directions)
    assert not np.allclose(held.jacobian @ moved.ravel(), far.forces.ravel(), rtol=0.0, atol=1e-6 * np.abs(far.forces).max())
    assert np.allclose(far.jacobian @ moved.ravel(), far.forces.ravel(), rtol=0.0, atol=1e-9 * np.abs(far.forces).max())


def test_infinite_friction_without_a_contact_state_is_refused_with_the_reason(pad):
    """Pressed, slid and turned, nodes slip at any finite friction with their normal
    force going to zero (mu = 1e6 still solves; two nodes here); at mu = inf no state
    exists, and the error says so instead of reporting a bug."""
    _, patch, frames = pad
    displacements = _rigid_motion(patch.points, [0.001, 0.002, -0.003], [0.04, -0.02, 0.02], patch.points.mean(axis=0))
    state = fem.solve_print_contact(patch.compliance, displacements, frames, np.full(patch.n_nodes, 1e6))
    slipping = state.forces[state.modes == fem.SLIP]
    assert len(slipping) >= 1
    # Their tangential force is what friction allows: 1e6 times a vanishing normal force.
    assert np.abs(slipping[:, 2]).max() < 1e-4 and np.linalg.norm(slipping[:, :2], axis=1).min() > 1.0
    with pytest.raises(fem.ContactStateError, match="with infinite friction this motion has no contact state"):
        fem.solve_print_contact(patch.compliance, displacements, frames, np.full(patch.n_nodes, np.inf))


def test_a_state_lost_to_high_friction_is_reported_as_such_not_as_a_bug():
    """Two strongly coupled nodes (a compliance no mesh makes, SPD), the second pressed and
    slid: as mu grows its normal force falls while its friction stays (mu = inf has no state
    at all); from mu = 10 the active set finds none, and the error says why and what to try."""
    a = np.array([[0.1, 0.3, -0.8, 0.7, 1.8, -0.3], [-0.6, -0.2, -0.5, -0.7, 0.1, -0.3],
                  [1.4, 0.0, 0.3, 1.0, -0.3, 1.4], [-0.6, -0.8, -0.4, -0.1, -1.4, -0.0],
                  [-1.7, 1.4, -0.1, -0.6, -0.9, -0.4], [-0.2, -1.0, -0.9, -0.2, -0.5, 0.9]])
    compliance = a @ a.T + 0.1 * np.eye(6)
    motion = np.array([[1.1, 0.0, -0.5], [-1.3, 0.6, -1.0]])
    frames = np.tile(np.eye(3), (2, 1, 1))
    normals = []
    for mu in (0.3, 1.0, 3.0, 8.0):
        state = fem.solve_print_contact(compliance, motion, frames, [mu, mu])
        assert state.modes[1] == fem.SLIP
        normals.append(state.forces[1, 2])
    assert np.all(np.diff(normals) < 0.0) and normals[-1] < 0.2 * normals[0]
    with pytest.raises(fem.ContactStateError, match=r"did not settle, even from a Gauss-Seidel solution: with friction as high "
                                           r"as mu = 10 a node can need a tangential force with almost no normal force, "
                                           r"where the active set finds no state \(try a smaller coefficient\)"):
        fem.solve_print_contact(compliance, motion, frames, [10.0, 10.0])


def test_gauss_seidel_gives_up_once_its_sweeps_stop_converging():
    """The same two nodes: at low friction projected Gauss-Seidel reaches its tolerance (its
    answer pushes and meets Coulomb's cone); at mu = 3 and 10 its sweeps wander without
    converging (2,000 of them measured), and it stops after a few windows, not its 500."""
    from fem.contact import _GS_WINDOW, _gauss_seidel

    a = np.array([[0.1, 0.3, -0.8, 0.7, 1.8, -0.3], [-0.6, -0.2, -0.5, -0.7, 0.1, -0.3],
                  [1.4, 0.0, 0.3, 1.0, -0.3, 1.4], [-0.6, -0.8, -0.4, -0.1, -1.4, -0.0],
                  [-1.7, 1.4, -0.1, -0.6, -0.9, -0.4], [-0.2, -1.0, -0.9, -0.2, -0.5, 0.9]])
    compliance = a @ a.T + 0.1 * np.eye(6)
    motion = np.array([[1.1, 0.0, -0.5], [-1.3, 0.6, -1.0]])
    for mu in (0.3, 1.0):
        phi, sweeps = _gauss_seidel(compliance, motion, np.array([mu, mu]))
        assert sweeps < 100
        assert np.all(phi[:, 2] >= 0.0) and np.all(np.hypot(phi[:, 0], phi[:, 1]) <= mu * phi[:, 2] * (1 + 1e-9))
        # Its answer is the active set's.
        assert np.allclose(phi, fem.solve_print_contact(compliance, motion, np.tile(np.eye(3), (2, 1, 1)),
                                                        [mu, mu]).forces, rtol=0.0, atol=1e-9)
    for mu in (3.0, 10.0):
        phi, sweeps = _gauss_seidel(compliance, motion, np.array([mu, mu]))
        assert sweeps <= 5 * _GS_WINDOW + 1
    # At mu = 3 the active set finds a state, which the wandering sweeps had not reached.
    state = fem.solve_print_contact(compliance, motion, np.tile(np.eye(3), (2, 1, 1)), [3.0, 3.0])
    assert not np.allclose(_gauss_seidel(compliance, motion, np.array([3.0, 3.0]))[0], state.forces, atol=1e-6)


@pytest.mark.parametrize("n_slip, n_lift", [(0, 0), (3, 0), (4, 6), (10, 2), (15, 25), (25, 30)])
def test_low_rank_factorisation_solves_the_law_as_a_dense_solve(pad, n_slip, n_lift):
    """The linearised law with slipping and lifted nodes (up to 140 of 243 rows replaced,
    58 %: the library takes this path up to 60 %), solved through C^-1 and a
    capacitance matrix (Woodbury), equals numpy's dense solve of the same matrix: a
    vector (refined) with a residual at rounding level and within 1e-11, and a block of columns (the Jacobian's) to 1e-9."""
    from fem.contact import _LowRankFactor, _compliance_rows, _mode_rows, _replace_rows

    _, patch, frames = pad
    system = fem.PrintContactSystem(patch.compliance, frames, np.full(patch.n_nodes, MU))
    rng = np.random.default_rng(n_slip + 10 * n_lift)
    p = patch.n_nodes
    modes = np.full(p, fem.STICK)
    chosen = rng.choice(p, n_slip + n_lift, replace=False)
    modes[chosen[:n_slip]], modes[chosen[n_slip:]] = fem.SLIP, fem.LIFT
    angles = rng.uniform(0.0, 2.0 * np.pi, p)
    directions = np.where((modes == fem.SLIP)[:, None], np.column_stack([np.cos(angles), np.sin(angles)]), 0.0)
    gains = np.where(modes == fem.SLIP, rng.uniform(0.2, 0.9, p), 0.0)
    law, _ = _mode_rows(modes, directions, gains, system.mu, system.scale)
    matrix = _replace_rows(system.c_local, law)
    rows = np.flatnonzero(~_compliance_rows(modes))
    assert np.array_equal(law.layout.rows, rows) and rows.size == 2 * n_slip + 3 * n_lift
    # The replaced rows, written out from the law (fem.contact's docstring): a lifted
    # node's phi = 0; a slipping node's phi_t - mu phi_n d - P (U + C phi)_t = 0 with
    # P = k s (I - d d^T), as matrix rows (O = (1 - k) I + k d d^T on phi_t).
    expected = system.c_local.copy()
    s = 0.5 * (system.scale[:, 0] + system.scale[:, 1])
    for node in range(p):
        dofs = slice(3 * node, 3 * node + 3)
        if modes[node] == fem.LIFT:
            expected[dofs] = np.eye(3 * p)[dofs]
        elif modes[node] == fem.SLIP:
            d, k = directions[node], gains[node]
            projected = k * s[node] * (np.eye(2) - np.outer(d, d))
            tangential = projected @ system.c_local[3 * node : 3 * node + 2]
            tangential[:, 3 * node : 3 * node + 2] += (1.0 - k) * np.eye(2) + k * np.outer(d, d)
            tangential[:, 3 * node + 2] -= MU * d
            expected[3 * node : 3 * node + 2] = tangential
    np.testing.assert_allclose(matrix, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    # The dense path places the rows; the low-rank path applies the law: the same numbers.
    assert np.array_equal(matrix[law.layout.rows], law.values(np.eye(3 * p), system.c_local))
    factor = _LowRankFactor(system.c_local, spd_inverse(system.c_local, "C"), law)
    vector, block = rng.normal(size=3 * p), rng.normal(size=(3 * p, 5))
    exact_vector, exact_block = np.linalg.solve(matrix, vector), np.linalg.solve(matrix, block)
    solved = factor.solve(vector)
    # Refined, the vector is backward stable: its residual is at rounding level (a
    # forward comparison with numpy's own solve would measure numpy's error too,
    # cond(A) eps: 2e-12 on one of these matrices).
    assert np.abs(matrix @ solved - vector).max() <= 1e-13 * np.abs(matrix).max() * np.abs(solved).max()
    assert np.abs(solved - exact_vector).max() <= 1e-11 * np.abs(exact_vector).max()
    assert np.abs(factor.solve(block) - exact_block).max() <= 1e-9 * np.abs(exact_block).max()


def test_a_slipping_print_is_solved_through_the_low_rank_path_with_the_same_answer(pad):
    """A sheared print with a few slipping nodes goes through the low-rank factorisation
    (C^-1 computed), and its forces obey Signorini and Coulomb in the full system."""
    body, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    displacements = _rigid_motion(patch.points, [0.002, 0.0, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    system = fem.PrintContactSystem(patch.compliance, frames, mu)
    state = system.solve(displacements)
    assert 0 < state.n_slip and 2 * state.n_slip + 3 * state.n_lift <= 0.25 * 3 * patch.n_nodes
    assert system._inverse is not None
    from fem.contact import _LowRankFactor

    assert isinstance(state._system[0], _LowRankFactor)  # not the dense fallback
    _check_signorini_coulomb(body, patch, displacements, state, MU)


def test_an_ill_conditioned_capacitance_falls_back_to_the_dense_factorisation(pad, monkeypatch):
    """Where the Woodbury capacitance is too badly conditioned (here: any, the bound raised
    above every reciprocal condition number), the law is factorised densely, with the
    same forces."""
    import fem.contact as contact

    body, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    displacements = _rigid_motion(patch.points, [0.002, 0.0, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    low_rank = fem.PrintContactSystem(patch.compliance, frames, mu).solve(displacements)
    factor = low_rank._system[0]
    assert isinstance(factor, contact._LowRankFactor)
    # gecon's estimate is within a factor 10 of the exact 1-norm condition number of the
    # capacitance A[R] S[:, R] (formed here from the dense law matrix).
    matrix = contact._replace_rows(factor._compliance, factor._law)
    capacitance = matrix[factor._law.layout.rows] @ factor._inverse[:, factor._law.layout.rows]
    exact = 1.0 / np.linalg.cond(capacitance, 1)
    assert exact / 10.0 <= factor.reciprocal_condition <= 10.0 * exact
    assert contact._LOW_RANK_RCOND < factor.reciprocal_condition <= 1.0
    monkeypatch.setattr(contact, "_LOW_RANK_RCOND", 2.0)
    dense = fem.PrintContactSystem(patch.compliance, frames, mu).solve(displacements)
    assert isinstance(dense._system[0], contact._DenseFactor)
    assert np.array_equal(dense.modes, low_rank.modes)
    np.testing.assert_allclose(dense.forces, low_rank.forces, rtol=0, atol=1e-9 * np.abs(low_rank.forces).max())


def test_spd_inverse_matches_the_general_inverse_and_refuses_an_indefinite_matrix():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((40, 40))
    spd = a @ a.T + 40.0 * np.eye(40)
    inverse = spd_inverse(spd, "a test matrix")
    np.testing.assert_allclose(inverse, np.linalg.inv(spd), rtol=1e-12, atol=1e-15)
    assert np.array_equal(inverse, inverse.T)
    indefinite = spd - 80.0 * np.eye(40) * (np.arange(40) == 7)
    with pytest.raises(fem.FemError, match=r"^a test matrix is not positive definite \(LAPACK info 8\)$"):
        spd_inverse(indefinite, "a test matrix")


def test_modes_read_off_a_gauss_seidel_solution_are_the_contact_state(pad):
    """The fallback starts its Newton solve from the modes of a projected Gauss-Seidel
    solution: a node whose normal force is projected to exactly zero is lifted off,
    and the modes read are those of the solved state (stick, slip and lift all occur)."""
    import scipy.linalg

    from fem.contact import _gauss_seidel, _modes_of

    _, patch, frames = pad
    centre = patch.points.mean(axis=0)
    displacements = _rigid_motion(patch.points, [0.002, 0.0, -0.002], [0.0, 0.03, 0.0], centre)
    mu = np.full(patch.n_nodes, MU)
    state = fem.solve_print_contact(patch.compliance, displacements, frames, mu)
    rotation = scipy.linalg.block_diag(*frames)
    phi = _gauss_seidel(rotation @ patch.compliance @ rotation.T, (rotation @ displacements.ravel()).reshape(-1, 3), mu)[0]
    modes, directions = _modes_of(phi, mu)
    assert (phi[modes == fem.LIFT, 2] == 0.0).all() and (modes == fem.LIFT).any()
    assert {fem.STICK, fem.SLIP, fem.LIFT} <= set(state.modes.tolist())
    np.testing.assert_array_equal(modes, state.modes)
    slipping = modes == fem.SLIP
    np.testing.assert_allclose(directions[slipping], state.directions[slipping], atol=1e-6)
    assert (directions[~slipping] == 0.0).all()


def _print_basis(patch):
    """G (3p, 6): the print points' motion under a rigid motion (translation, small turn)
    about the print's centre; its transpose sums forces into a wrench about that centre."""
    levers = patch.points - patch.points.mean(axis=0)
    basis = np.zeros((patch.n_nodes, 3, 6))
    basis[:, :, :3] = np.eye(3)
    basis[:, :, 3:] = -np.array([[[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]] for x in levers])
    return basis.reshape(-1, 6)


def test_a_loaded_solve_finds_the_motion_whose_forces_carry_a_wrench(pad):
    """solve_loaded inverts the law: from the wrench the forces of a pressed, sheared and
    tilted print carry, it finds that print's motion again (some nodes lifted, some
    slipping), its state obeys Signorini and Coulomb in the full system, and started from
    that answer's motion and modes a nearby wrench takes fewer Newton steps."""
    body, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    basis = _print_basis(patch)
    system = fem.PrintContactSystem(patch.compliance, frames, mu)

    def motion(xi):
        return (basis @ xi).reshape(-1, 3), basis

    xi = np.array([0.0006, 0.0, -0.002, 0.0, 0.03, 0.0])
    forward = system.solve(motion(xi)[0])
    assert (forward.modes == fem.LIFT).any() and (forward.modes == fem.SLIP).any()
    wrench = basis.T @ forward.forces.reshape(-1)
    state, found = system.solve_loaded(basis, wrench, motion, np.zeros(6))
    assert np.allclose(found, xi, rtol=0.0, atol=1e-12)
    assert np.allclose(basis.T @ state.forces.reshape(-1), wrench, rtol=0.0, atol=1e-9 * np.abs(wrench).max())
    assert np.array_equal(state.modes, forward.modes)
    _check_signorini_coulomb(body, patch, motion(found)[0], state, MU)
    nearby = wrench * (1.0 + 1e-3)
    cold = system.solve_loaded(basis, nearby, motion, np.zeros(6))
    warm = system.solve_loaded(basis, nearby, motion, found, state.modes, state.directions)
    assert np.allclose(warm[1], cold[1], rtol=0.0, atol=1e-12) and warm[0].iterations < cold[0].iterations


def test_a_body_k_times_stiffer_pressed_k_times_less_gives_the_same_forces(pad, monkeypatch):
    """C / k and U / k are the same contact: the forces must not change. The dense
    factorisation of a law with lifted and slipping nodes (here in turned frames) mixes C's
    rows (m/N) with replaced rows of size one. Unscaled it lost 1.7e-10 of these forces at
    k = 1e5, and 4e-7 of a palm's and a sole's on foot-and-hand-on-foam's foam at 1e11 Pa,
    where a loaded solve then never reached its 1e-9 tolerance (the stiff limit refused,
    the answer 12 % off the rigid support's); its replaced rows scaled by their dofs'
    compliance, 2e-15 here."""
    import fem.contact as contact

    monkeypatch.setattr(contact, "_LOW_RANK_ROWS", 0.0)  # every law with slip factorised densely
    _, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    basis = _print_basis(patch)
    xi = np.array([0.0006, 0.0, -0.002, 0.0, 0.03, 0.0])
    turns = _exp_turns(patch.n_nodes, xi[3:])
    soft = fem.PrintContactSystem(patch.compliance, frames, mu).solve((basis @ xi).reshape(-1, 3), turns=turns)
    assert (soft.modes == fem.LIFT).any() and (soft.modes == fem.SLIP).any()
    assert isinstance(soft._system[0], contact._DenseFactor)
    k = 1e5
    stiff_system = fem.PrintContactSystem(patch.compliance / k, frames, mu)
    stiff = stiff_system.solve((basis @ xi / k).reshape(-1, 3), turns=turns)
    assert np.array_equal(stiff.modes, soft.modes)
    np.testing.assert_allclose(stiff.forces, soft.forces, rtol=0.0, atol=1e-12 * np.abs(soft.forces).max())
    # The inverse, a wrench carried (its forces in untilted frames): the motion found again.
    plain = fem.PrintContactSystem(patch.compliance, frames, mu).solve((basis @ xi).reshape(-1, 3))
    wrench = basis.T @ plain.forces.reshape(-1)
    loaded = stiff_system.solve_loaded(basis, wrench, lambda x: ((basis @ x).reshape(-1, 3), basis), np.zeros(6))
    assert loaded is not None
    np.testing.assert_allclose(loaded[1], xi / k, rtol=0.0, atol=1e-9 * np.abs(xi / k).max())


def test_a_loaded_solve_of_a_wrench_beyond_the_print_is_none(pad):
    """A centre of pressure outside the print's nodes: no motion carries it."""
    _, patch, frames = pad
    basis = _print_basis(patch)
    system = fem.PrintContactSystem(patch.compliance, frames, np.full(patch.n_nodes, MU))
    half_width = np.ptp(patch.points[:, 0]) / 2
    pushed = np.array([0.0, 0.0, 100.0, 0.0, -100.0 * 1.2 * half_width, 0.0])  # centre of pressure at 1.2 half-widths
    assert system.solve_loaded(basis, pushed, lambda xi: ((basis @ xi).reshape(-1, 3), basis), np.zeros(6)) is None
    inside = pushed * [1, 1, 1, 1, 0.5, 1]
    assert system.solve_loaded(basis, inside, lambda xi: ((basis @ xi).reshape(-1, 3), basis), np.zeros(6)) is not None


def test_a_warm_start_that_cycles_restarts_from_sticking_not_gauss_seidel(monkeypatch):
    """Climb's palm on its platform: nodes at the brink of lifting put the semismooth
    Newton, warm started from the last linearisation's modes, on a cycle of two contact
    sets. The cycle is seen on its third entry into a set (not after 60 steps) and the solve
    restarts from every node sticking, which settles; the projected Gauss-Seidel (20 ms a
    call on this 20-node print) is not needed. The print, the motion, the warm modes and the
    turned frames are those of a solve of left-on-platform at 0209338 (``tests/data/README.md``),
    replayed: since the SQP's Hessian carries the Coulomb forces' curvature (2026-12-06) that
    solve no longer meets the cycle."""
    from fem import contact

    def no_gauss_seidel(*args, **kwargs):
        raise AssertionError("the Gauss-Seidel fallback was called")

    failed_steps = []
    newton, forces = contact.PrintContactSystem._newton, contact.PrintContactSystem._forces

    def counted_newton(self, u_local, modes, directions, **options):
        steps = []
        monkeypatch.setattr(self, "_forces", lambda *args: steps.append(1) or forces(self, *args))
        result = newton(self, u_local, modes, directions, **options)
        if result is None:
            failed_steps.append(len(steps))
        return result

    recorded = np.load(DATA / "palm-cycle-on-platform.npz")
    motion, turns = recorded["displacements"], recorded["turns"]
    monkeypatch.setattr(contact, "_gauss_seidel", no_gauss_seidel)
    monkeypatch.setattr(contact.PrintContactSystem, "_newton", counted_newton)
    system = fem.PrintContactSystem(recorded["compliance"], recorded["frames"], recorded["friction"])
    warm = system.solve(motion, recorded["initial_modes"], recorded["initial_directions"], turns=turns)
    assert failed_steps, "the warm start did not cycle: this case no longer exercises the restart"
    assert max(failed_steps) <= 2 * contact._SET_ENTRIES + 4
    cold = system.solve(motion, turns=turns)
    assert np.array_equal(warm.forces, cold.forces) and warm.admissible
    assert warm.n_slip and warm.n_lift


def test_only_a_warm_start_gives_up_on_a_cycle(pad, monkeypatch):
    """A start from modes other than every node sticking gives up on a cycle at once (the
    cold start follows); the cold start, given or by default, keeps the whole budget: a run
    that comes back to a set while its slip directions converge is no cycle."""
    from fem import contact

    _, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    tilted = _rigid_motion(patch.points, [0.002, -0.001, -0.004], [0.0, 0.02, 0.0], patch.points.mean(axis=0))
    earlier = fem.solve_print_contact(patch.compliance, tilted, frames, mu)
    assert np.any(earlier.modes != contact.STICK)  # slipping or lifting nodes: a warm start
    flags, newton = [], contact.PrintContactSystem._newton

    def recorded(self, u_local, modes, directions, give_up_on_cycles=False):
        flags.append(give_up_on_cycles)
        return newton(self, u_local, modes, directions, give_up_on_cycles)

    monkeypatch.setattr(contact.PrintContactSystem, "_newton", recorded)
    pressed = _rigid_motion(patch.points, [0.0005, 0.0, -0.004], [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    cold = fem.solve_print_contact(patch.compliance, pressed, frames, mu)
    sticking = fem.solve_print_contact(patch.compliance, pressed, frames, mu, initial_modes=np.full(patch.n_nodes, contact.STICK))
    warm = fem.solve_print_contact(patch.compliance, pressed, frames, mu, earlier.modes, earlier.directions)
    assert flags == [False, False, True]
    assert np.array_equal(cold.forces, sticking.forces)
    assert np.allclose(warm.forces, cold.forces, rtol=0.0, atol=1e-9 * np.abs(cold.forces).max())


def _exp_turns(n_nodes, theta):
    """(p, 3, 3) turned frames ``R(theta)^T`` (the pad's node frames are the body's axes)."""
    angle = np.linalg.norm(theta)
    k = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]]) / angle
    rotation = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    return np.broadcast_to(rotation.T, (n_nodes, 3, 3)).copy()


@pytest.mark.parametrize("turning", [False, True], ids=["node frames", "turning frames"])
@pytest.mark.parametrize("curved_motion", [False, True], ids=["straight motion", "curved motion"])
def test_forces_second_derivatives_match_finite_differences_of_held_solves(pad, turning, curved_motion):
    """The forces' first and second derivatives along a parameter x that moves the indenter
    points by U(x) and turns the contact frames by Q(x), the modes held: against central
    differences of the held solves (``with_modes``: the slip directions follow). With a
    straight motion and fixed frames the curvature is the slip directions' alone (about 130 N
    per unit of x squared here, the first derivatives up to 94 N per unit), which no
    linear model of the forces sees."""
    _, patch, frames = pad
    p, m = patch.n_nodes, 3
    rng = np.random.default_rng(3)
    start = _rigid_motion(patch.points, [0.002, 0.0015, -0.004], [0.01, -0.02, 0.01], patch.points.mean(axis=0))
    linear = rng.normal(size=(3 * p, m)) * 3e-4
    quadratic = rng.normal(size=(3 * p, m, m)) * (1e-3 if curved_motion else 0.0)
    quadratic = 0.5 * (quadratic + quadratic.transpose(0, 2, 1))
    rates = rng.normal(size=(3, m)) * (0.02 if turning else 0.0)
    tilt = np.array([0.0, 0.03, 0.01])

    def motion(x):
        return (start.ravel() + linear @ x + 0.5 * np.einsum("imn,m,n->i", quadratic, x, x)).reshape(p, 3)

    def turns(x):
        return _exp_turns(p, tilt + rates @ x)

    def turn_derivatives(x, h=1e-4):
        steps = h * np.eye(m)
        first = np.stack([(turns(x + e) - turns(x - e)) / (2 * h) for e in steps], axis=1)
        second = np.array([[(turns(x + a + b) - turns(x + a - b) - turns(x - a + b) + turns(x - a - b)) / (4 * h * h)
                            for b in steps] for a in steps]).transpose(2, 0, 1, 3, 4)
        return first, second

    system = fem.PrintContactSystem(patch.compliance, frames, np.full(p, MU))
    x0 = np.zeros(m)
    state = system.solve(motion(x0), turns=turns(x0))
    assert state.n_slip > 0 and state.n_stick > 0

    def held(x):
        return system.with_modes(motion(x), state.modes, state.directions, turns=turns(x))

    def derivatives(solved, x):
        return solved.derivatives(linear + np.einsum("imn,n->im", quadratic, x), quadratic, *turn_derivatives(x))

    first, second = derivatives(state, x0)
    h = 1e-6
    numeric = np.stack([(held(x0 + e).forces - held(x0 - e).forces).ravel() / (2 * h) for e in h * np.eye(m)], axis=1)
    assert np.abs(first - numeric).max() <= 1e-7 * np.abs(numeric).max()
    if not turning:
        assert np.abs(first - state.jacobian_dot(linear)).max() <= 1e-10 * np.abs(first).max()
    h = 1e-5
    numeric = np.stack([(derivatives(held(x0 + e), x0 + e)[0] - derivatives(held(x0 - e), x0 - e)[0]) / (2 * h)
                        for e in h * np.eye(m)], axis=2)
    assert np.abs(second - numeric).max() <= 1e-5 * np.abs(numeric).max()
    assert np.array_equal(second, second.transpose(0, 2, 1))
    # The slip directions' curvature is most of it: the motion's own, through L, is not.
    along_motion = state.jacobian_dot(quadratic.reshape(3 * p, -1)).reshape(3 * p, m, m)
    assert np.abs(second - along_motion).max() > 0.3 * np.abs(second).max()


def test_a_node_held_slipping_without_trial_friction_has_finite_derivatives():
    """A node held slipping (``with_modes``) under a straight press has no trial friction
    (tau = 0): it keeps its direction, as the factorisation's law does, and its derivatives
    are those of that law, finite (a review found NaN there)."""
    system = fem.PrintContactSystem(np.diag(np.full(6, 1e-4)), np.tile(np.eye(3), (2, 1, 1)), np.full(2, MU))
    held = system.with_modes(np.array([[0.0, 0.0, -1e-3]] * 2), np.full(2, fem.SLIP), np.array([[1.0, 0.0], [0.0, 1.0]]))
    first, second = held.derivatives(np.eye(6)[:, :2], np.zeros((6, 2, 2)))
    assert np.all(np.isfinite(first)) and np.all(np.isfinite(second))
    assert np.allclose(held.forces, [[MU * 10.0, 0.0, 10.0], [0.0, MU * 10.0, 10.0]])
    assert np.allclose(first, held.jacobian_dot(np.eye(6)[:, :2]), rtol=0.0, atol=1e-9)
    assert not second.any()


def test_derivatives_refuse_shapes_that_do_not_match_and_a_state_without_its_law(pad):
    _, patch, frames = pad
    p = patch.n_nodes
    state = fem.PrintContactSystem(patch.compliance, frames, np.full(p, MU)).solve(
        _rigid_motion(patch.points, [0.002, 0.0, -0.004], [0.0, 0.02, 0.0], patch.points.mean(axis=0)))
    with pytest.raises(fem.FemError, match=rf"dd_motion must have shape \({3 * p}, 2, 2\) for a print of {p} nodes"):
        state.derivatives(np.zeros((3 * p, 2)), np.zeros((3 * p, 2)))
    with pytest.raises(fem.FemError, match=rf"d_turns must have shape \({p}, 2, 3, 3\)"):
        state.derivatives(np.zeros((3 * p, 2)), np.zeros((3 * p, 2, 2)), np.zeros((p, 3, 3)))
    bare = fem.PrintContact(state.forces, state.relative, state.modes, state.directions, 0, state._system)
    with pytest.raises(fem.FemError, match="derivatives need a contact state solved by a PrintContactSystem"):
        bare.derivatives(np.zeros((3 * p, 2)), np.zeros((3 * p, 2, 2)))


@pytest.mark.parametrize("shear", [[0.002, -0.001, -0.004], [0.003, 0.0, -0.004]])
def test_a_print_held_where_it_slipped_to_sticks_with_the_same_forces(pad, shear):
    """The next small step of an incremental load: the indenter's motion less each slipping
    node's slip (held where it slipped to) carries the same forces with every node sticking,
    the slipped ones on their cones' edges. Read as slipping there (a trial 1e-16 over the
    bound), such nodes cycled the active set on a motion's chained samples."""
    body, patch, frames = pad
    mu = np.full(patch.n_nodes, MU)
    displacements = _rigid_motion(patch.points, shear, [0.0, 0.0, 0.0], patch.points.mean(axis=0))
    first = fem.PrintContactSystem(patch.compliance, frames, mu).solve(displacements)
    assert first.n_slip > 0
    relative = displacements - (patch.compliance @ (-first.forces.ravel())).reshape(-1, 3)
    slipped = np.where((first.modes == fem.SLIP)[:, None], relative * [1.0, 1.0, 0.0], 0.0)
    held = fem.PrintContactSystem(patch.compliance, frames, mu).solve(displacements - slipped)
    assert held.n_slip == 0 and held.n_lift == first.n_lift
    np.testing.assert_allclose(held.forces, first.forces, rtol=0, atol=1e-12 * np.abs(first.forces).max())
    on_edge = first.modes == fem.SLIP
    size = np.linalg.norm(held.forces[on_edge, :2], axis=1)
    np.testing.assert_allclose(size, MU * held.forces[on_edge, 2], rtol=1e-9)
    _check_signorini_coulomb(body, patch, displacements - slipped, held, MU)


@pytest.mark.parametrize("over", [0.0, 5e-11, 2e-10, 4e-10, 1e-9])
def test_a_node_just_over_its_cone_settles_whichever_mode_it_starts_in(over):
    """Two nodes with coupled tangential compliance, the first pushed sideways so that sticking
    it would need friction ``over`` its bound (relative): the first node sticks on its cone's
    edge within the edge's share of the bound, slips past it, and the solve settles either
    way. (An edge read the same from both modes, a band where sticking says slip and slipping
    says stick, cycled into a FemError at 2e-10 to 4e-10 here.)"""
    from fem.contact import _CONE_EDGE

    compliance = 1e-5 * np.eye(6)
    compliance[0, 3] = compliance[3, 0] = 0.9e-5  # the nodes' t1 strongly coupled
    frames, mu = np.tile(np.eye(3), (2, 1, 1)), np.array([0.5, 0.5])
    stiffness = np.linalg.inv(compliance[np.ix_([0, 3], [0, 3])])
    normal = 100.0  # N on each node: the motion presses 1 mm at 1e-5 m/N, uncoupled
    motion = np.array([[-mu[0] * normal * (1 + over) / stiffness[0, 0], 0.0, -1e-3], [0.0, 0.0, -1e-3]])
    state = fem.solve_print_contact(compliance, motion, frames, mu)
    forces = state.forces
    np.testing.assert_allclose(forces[:, 2], normal, rtol=1e-12)
    assert state.modes[1] == fem.STICK
    assert state.modes[0] == (fem.STICK if over <= _CONE_EDGE else fem.SLIP)
    ratio = np.hypot(*forces[0, :2]) / (mu[0] * forces[0, 2])
    assert 1 - 1e-12 <= ratio <= 1 + _CONE_EDGE
