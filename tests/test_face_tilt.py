"""The contact of a turned face (issue 8.3, ``docs/turned-face.md``): each soft print node's
Signorini-Coulomb contact solved in its print's frame turned with the link's face (the default,
``contact_frames="turned"``) against the rest frames (``"rest"``, the linear model's), and the
tilt allowance (``tilt_allowance``): cones narrowed by the angle a face may turn, and rows
keeping it there."""

from __future__ import annotations

import math
import re

import numpy as np
import pinocchio as pin
import pytest

import environments
import fem
from cbm.rejections import cause_of
from stances import CentreOfMassBounds, PostureOptions, solve, verify
from stances.curvature import ConstraintCurvature
from stances.errors import StanceError
from stances.problem import build_problem
import stances.stages
from stances.stages import HELD_AT_NODES
from test_curvature import second_differences

PALM = "right_palm"
ONE_DEGREE = math.radians(1.0)


@pytest.fixture(scope="module")
def coarse_cube():
    """The paper's 1 m cube on its coarse mesh: the built-in palm that tilts most (1.25 degrees
    in the rest frames)."""
    return environments.load("hand-on-coarse-cube")


@pytest.fixture(scope="module")
def answers(robot, coarse_cube):
    """hand-on-cube's answers: the turned frames (the default), the rest frames, and the rest
    frames with a 1 degree tilt allowance."""
    stance = coarse_cube.stance("hand-on-cube")
    options = {"turned": {}, "rest": {"contact_frames": "rest"},
               "allowance": {"contact_frames": "rest", "tilt_allowance": ONE_DEGREE}}
    return {name: solve(robot, coarse_cube.scene, stance, **option) for name, option in options.items()}


def _palm_nodes(robot, coarse_cube, result):
    """The palm's node forces (n, 3), world, the palm face's unit normal (toward the robot)
    and its tilt from the cube's top, radians: from the answer's posture alone."""
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(result.q))
    frame = robot.surface(PALM).frame
    forces = np.array([np.asarray(f.force) for f in result.point_forces if f.frame == frame])
    top = np.array([0.0, 0.0, 1.0])  # the cube's top face, at rest
    axis = data.oMf[model.getFrameId(frame)].rotation[:, 2]
    face = axis * np.sign(axis @ top)
    return forces, face, float(np.arccos(min(1.0, face @ top)))


def _face_ratios(forces, face):
    """Each pushing node's tangential over normal force about ``face``."""
    normal = forces @ face
    tangential = np.linalg.norm(forces - normal[:, None] * face, axis=1)
    pushing = normal > 1e-9 * normal.max()
    return tangential[pushing] / normal[pushing]


def test_every_node_of_a_turned_palm_lies_in_its_cone_about_the_face_that_presses_it(robot, coarse_cube, answers):
    """The default answer: the palm tilted over a degree, every pushing node inside the cone of
    the cube's own mu about the palm's face (slipping ones on it), none pulling."""
    result = answers["turned"]
    assert result.feasible and result.verification.ok, result.reason
    mu = coarse_cube.scene.surface("cube_top").friction
    forces, face, tilt = _palm_nodes(robot, coarse_cube, result)
    assert tilt > ONE_DEGREE
    ratios = _face_ratios(forces, face)
    assert ratios.max() <= mu * (1.0 + 1e-6) and ratios.max() >= mu * (1.0 - 1e-6)
    assert (forces @ face).min() >= -1e-9


def test_the_turned_frames_answer_is_the_plane_contact_of_its_face_and_the_rest_frames_one_is_not(
        robot, coarse_cube, answers):
    """At each answer's posture, the exact plane contact of the palm's face (the contact solved
    in the node frames turned with the link, the same compliance and link motion) against the
    forces reported: the default's to 1e-7 (the placement rows' accuracy), the rest frames' 6-9 % off (a slipping node's gap
    misses its slip times the tilt) and past the face's cone by about (1 + mu^2) / mu times the
    tilt; verified with the turned frames, that answer is refused."""
    stance = coarse_cube.stance("hand-on-cube")
    mu = coarse_cube.scene.surface("cube_top").friction
    for name, off in (("turned", (0.0, 1e-7)), ("rest", (0.06, 0.09))):
        result = answers[name]
        problem = build_problem(robot, coarse_cube.scene, stance, PostureOptions(**result.statistics["options"] or {}))
        (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
        model, data = robot.model, problem.data
        pin.framesForwardKinematics(model, data, np.asarray(result.q))
        turn = soft.rotation_body.T @ data.oMf[soft.frame_ids[0]].rotation @ soft.print_placements[0].rotation.T @ soft.rotation_body
        turned = np.matmul(soft.node_frames, turn.T)
        exact = fem.solve_print_contact(soft.patch.link_compliance, soft.displacements(model, data) + soft.gaps, turned,
                                        np.full(len(soft.node_ids), mu)).forces.sum(axis=0)
        reported, _, tilt = _palm_nodes(robot, coarse_cube, result)
        reported = reported.sum(axis=0) @ soft.rotation_body
        assert off[0] <= np.linalg.norm(reported - exact) / np.linalg.norm(exact) <= off[1], name
    forces, face, tilt = _palm_nodes(robot, coarse_cube, answers["rest"])
    worst = _face_ratios(forces, face).max() / mu
    assert 1.0 + 0.8 * (1 + mu**2) / mu * tilt < worst < 1.0 + 1.2 * (1 + mu**2) / mu * tilt
    assert answers["rest"].verification.ok  # as solved
    checked = verify(robot, coarse_cube.scene, stance, answers["rest"], contact_frames="turned")
    assert not checked.ok
    assert any("leaves its friction cone" in reason or "friction at node" in reason for reason in checked.reasons)


def test_a_tilt_allowance_holds_the_face_and_keeps_the_rest_frames_nodes_in_its_cone(robot, coarse_cube, answers):
    """With the rest frames a 1 degree allowance narrows the cones and bounds the tilt: every
    node inside its cone about the face too, the face on its bound; verify measures it."""
    result = answers["allowance"]
    assert result.feasible and result.verification.ok, result.reason
    mu = coarse_cube.scene.surface("cube_top").friction
    forces, face, tilt = _palm_nodes(robot, coarse_cube, result)
    assert tilt <= ONE_DEGREE + 1e-7
    assert _face_ratios(forces, face).max() <= mu * (1.0 + 1e-6)
    measures = result.verification.measures
    assert measures["largest face tilt on cube"] == pytest.approx(tilt, abs=1e-9)
    assert measures["face cone margin on cube"] >= -1e-6
    # The rest frames' answer without it: checked with the allowance, refused for the face's cone.
    checked = verify(robot, coarse_cube.scene, coarse_cube.stance("hand-on-cube"), answers["rest"],
                     tilt_allowance=ONE_DEGREE)
    assert any("leaves its friction cone about the face of right_palm on cube_top, turned 1.2" in reason
               for reason in checked.reasons), checked.reasons


def test_a_prints_friction_is_narrowed_by_its_allowance_and_by_no_more_than_a_stiff_body_can_tilt(robot, coarse_cube):
    stance = coarse_cube.stance("hand-on-cube")
    mu = coarse_cube.scene.surface("cube_top").friction

    def soft(**options):
        problem = build_problem(robot, coarse_cube.scene, stance, PostureOptions(**options))
        (contact,) = [c for c in problem.contacts if c.kind == "deformable"]
        return contact

    allowed = soft(tilt_allowance=ONE_DEGREE, contact_frames="rest")
    assert allowed.tilt_allowances.tolist() == [ONE_DEGREE]
    assert allowed.print_mu == [math.tan(math.atan(mu) - ONE_DEGREE)]
    assert np.all(allowed.node_mu == allowed.print_mu[0])
    # The turned frames' cones are the face's: the allowance bounds the tilt, narrows nothing.
    turned = soft(tilt_allowance=ONE_DEGREE)
    assert turned.tilt_allowances.tolist() == [ONE_DEGREE] and turned.print_mu == [mu]
    # At most half the cone's angle; none by default, nor with the paper's bonded law.
    assert soft(tilt_allowance=1.5, contact_frames="rest").tilt_allowances.tolist() == [0.5 * math.atan(mu)]
    for options in ({}, {"contact_law": "bonded", "tilt_allowance": ONE_DEGREE}):
        contact = soft(**options)
        assert contact.tilt_allowances.tolist() == [0.0] and contact.print_mu == [mu]
        assert not any(block.name == "face tilt" for block in _blocks(robot, contact))
    # The robot's weight tilts the 1 m cube's palm tens of degrees: the option binds. On a
    # steel-stiff slab (below) the bound is a fraction of a milliradian.
    assert allowed._tilts_under(robot.weight)[0] > math.radians(10.0)
    assert [block.name for block in _blocks(robot, allowed)].count("face tilt") == 1


def _blocks(robot, contact):
    """The contact's rows at the robot's reference configuration (values only)."""
    model, data = robot.model, robot.model.createData()
    q = robot.reference_configuration
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    w = np.zeros(contact.n_variables)
    return contact.blocks(model, data, w, model.nv + contact.n_variables, model.nv, derivatives=False)


@pytest.mark.parametrize("value", [-0.01, math.nan, math.inf, 0.5 * math.pi])
def test_a_tilt_allowance_that_is_no_angle_below_a_right_angle_is_refused(value):
    with pytest.raises(StanceError, match=r"tilt_allowance must be an angle in \[0, pi/2\) radians \(0: no tilt "
                                          r"bound\), got "):
        PostureOptions(tilt_allowance=value)
    with pytest.raises(StanceError, match=r"tilt_allowance must be a number, got 'one degree'"):
        PostureOptions(tilt_allowance="one degree")
    with pytest.raises(StanceError, match=r"contact_frames must be one of \('turned', 'rest'\), got 'tilted'"):
        PostureOptions(contact_frames="tilted")


_STIFF_SLAB = """
robot: talos
objects:
  - {name: floor, type: floor}
  - name: slab
    type: soft_box
    size: [0.8, 1.0, 0.2]
    center: [0.0, 0.0, 0.1]
    material: {E: 1.0e+10, nu: 0.3, rho: 0.0}
    strain_limit: 0.3
    refine: [[-0.3, -0.3], [0.3, 0.3]]
stances:
  stand:
    left_sole: {surface: slab_top, x: 0.0, y: 0.09}
    right_sole: {surface: slab_top, x: 0.0, y: -0.09}
"""


def test_on_a_steel_stiff_slab_the_allowance_is_a_fraction_of_a_milliradian_and_binds_nothing_the_rigid_support_allows(robot):
    """A review's case: both soles on a 1e10 Pa slab, the robot leaning forward (its centre of
    mass 0.101 m ahead, the soles' centres of pressure toward their toes). Lifted and slipping
    nodes turn the soles 2e-5 rad, more than their bonded turn under the robot's weight (1.5e-5):
    an allowance of that alone refused the stance the rigid support holds. With the corner rows'
    give in it (max_corner_lift over the sole's width, doubled) it is solved in its stiff limit."""
    scenario = environments.load_string(_STIFF_SLAB, name="stiff-slab")
    stance = scenario.stance("stand")
    ahead = CentreOfMassBounds(lower=(0.101, -math.inf, -math.inf), label="ahead")  # the soles' centres of pressure toward their toes
    assert solve(robot, scenario.scene, stance, constraints=[ahead], deformable_as_rigid=True).feasible
    result = solve(robot, scenario.scene, stance, constraints=[ahead], tilt_allowance=ONE_DEGREE)
    assert result.feasible and result.verification.ok, result.reason
    assert result.statistics["stiff_limit"] is True
    (soft,) = [c for c in build_problem(robot, scenario.scene, stance, PostureOptions(tilt_allowance=ONE_DEGREE)).contacts
               if c.kind == "deformable"]
    width = np.ptp(robot.surface("left_sole").vertices_in_frame[:, :2], axis=0).min()  # metres across
    assert np.allclose(soft.tilt_allowances, 2.0 * (soft._tilts_under(robot.weight) + 1e-5 / width), rtol=1e-3)
    assert np.all(soft.tilt_allowances < 2e-4)
    assert 1e-5 < result.verification.measures["largest face tilt on slab"] < soft.tilt_allowances.min()


def test_on_a_steel_stiff_slab_leaning_on_a_grid_moved_under_the_soles_is_solved_in_its_stiff_limit(robot):
    """The leaning stance above (the centre of mass 0.101 m ahead) with the slab's grid lines
    moved 3/4 of a cell (17 mm along x, 10 mm along y) under the soles, which stay where they
    were. Held rigid, then carried, the user's row stayed 4.4 nm behind its bound and the
    equilibrium 1e-6 N off through every step with the soles' W held: the stiff limit was
    abandoned and the solve through W refused the stance after 8.6 s. A last restoration step
    with W free meets both (``_FREE_STEPS``): solved, the soles' loads the rigid support's."""
    _held_as_on_a_rigid_support(robot, 0.75, 0.101)


def _held_as_on_a_rigid_support(robot, cells, ahead_x):
    """Solve the leaning stance on :func:`_shifted_slab` with the centre of mass ``ahead_x``
    ahead, rigid and soft: the soft answer verified, from the stiff limit, its soles' loads the
    rigid support's."""
    scenario = _shifted_slab(cells)
    stance = scenario.stance("stand")
    ahead = CentreOfMassBounds(lower=(ahead_x, -math.inf, -math.inf), label="ahead")
    rigid = solve(robot, scenario.scene, stance, constraints=[ahead], deformable_as_rigid=True)
    assert rigid.feasible, rigid.reason
    result = solve(robot, scenario.scene, stance, constraints=[ahead])
    assert result.feasible and result.verification.ok, result.reason
    assert result.statistics["stiff_limit"] is True

    def sole_loads(answer):
        return np.array([sum(p.force[2] for p in answer.point_forces if p.frame == frame)
                         for frame in sorted({p.frame for p in answer.point_forces})])

    assert np.allclose(sole_loads(result), sole_loads(rigid), rtol=1e-6)


def _shifted_slab(cells):
    """The steel-stiff slab with its grid lines moved ``cells`` of its 22.5 mm spacing along x
    (and 0.6 of that along y) under the soles, which stay where they were in the world."""
    shift = cells * 0.0225
    return environments.load_string(
        _STIFF_SLAB.replace("center: [0.0, 0.0, 0.1]", f"center: [{shift}, {0.6 * shift}, 0.1]")
        .replace("x: 0.0, y: 0.09", f"x: {-shift}, y: {0.09 - 0.6 * shift}")
        .replace("x: 0.0, y: -0.09", f"x: {-shift}, y: {-0.09 - 0.6 * shift}"),
        name=f"stiff-slab-moved-{cells}")


@pytest.mark.parametrize("cells", [0.0, 0.25])
def test_on_a_steel_stiff_slab_a_centre_of_pressure_5_mm_behind_the_toe_edge_is_held_as_on_a_rigid_support(robot, cells):
    """The grid moved 0 or a quarter cell, the centre of mass 0.105 m ahead: each sole's
    centre of pressure 5 mm behind its toe edge, which the rigid support holds. Until
    2026-12-06 the soles' last node rows stopped short of it at these two placements (a
    node's median-dual cell left the row past the toes out): refused, held rigid
    (``HELD_AT_NODES``) and by a pivot's give. A print now takes every node whose shape
    function it covers, that row too: solved in the stiff limit with the rigid support's
    sole loads, verified on the full model."""
    _held_as_on_a_rigid_support(robot, cells, 0.105)


@pytest.mark.parametrize("cells", [0.0, 0.5])
def test_on_a_steel_stiff_slab_a_centre_of_pressure_on_the_soles_toe_edge_is_refused_at_once(robot, cells):
    """The same slab, the centre of mass 0.11 m ahead: each sole's centre of pressure on its toe
    edge (x = 0.11 m in the sole's frame), the tipping limit, which the rigid support holds with
    all the load on the toes' corners and no sole on a body of finite stiffness does. Held rigid,
    a print's centre of pressure stays inside its outline as well as its nodes' hull: where the
    grid put a row of partly covered nodes past the toes (half a cell moved), the stiff limit had
    accepted it, balanced and Coulomb's, with 71-95 % of each sole's load on that row, 6.9 mm past
    the toe edge, where the model applies those nodes' forces (an independent audit,
    ``bench/results/audit-stiff-slab-2026-12-06.md``); on the default grid the soles' nodes had
    carried it only by pivoting (a 70 um give) and the solve through W had then failed after
    4-6 s. Now refused at once, wherever the grid lies, with the held solve's reason."""
    scenario = _shifted_slab(cells)
    stance = scenario.stance("stand")
    ahead = CentreOfMassBounds(lower=(0.11, -math.inf, -math.inf), label="ahead")
    assert solve(robot, scenario.scene, stance, constraints=[ahead], deformable_as_rigid=True).feasible
    result = solve(robot, scenario.scene, stance, constraints=[ahead])
    assert not result.feasible and result.reason.startswith(HELD_AT_NODES), result.reason
    assert cause_of(result.reason) == "balance (static equilibrium)"


def test_on_a_steel_stiff_slab_a_centre_of_pressure_the_nodes_carry_only_by_pivoting_is_a_pressure_under_the_soles(robot):
    """The same slab, the grid moved a quarter cell, the centre of mass 0.108 m ahead: each
    sole's centre of pressure 2 mm behind its toe edge, inside its nodes' reach, but the
    soles' nodes carry it only if the soles pivot (an 18 um give, over the stiff limit's
    10 um: see the next test). The least-energy pressure under each sole carries the held
    answer's wrench, the soles held where the slab gives under it: verified, a pressure under
    each sole to rounding, the rigid support's sole forces to 1e-4 (refused before
    2026-12-06 w)."""
    scenario = _shifted_slab(0.25)
    stance = scenario.stance("stand")
    ahead = CentreOfMassBounds(lower=(0.108, -math.inf, -math.inf), label="ahead")
    rigid = solve(robot, scenario.scene, stance, constraints=[ahead], deformable_as_rigid=True)
    result = solve(robot, scenario.scene, stance, constraints=[ahead])
    assert rigid.feasible and result.feasible and result.statistics["stiff_limit"] is True, result.reason
    for sole in ("left_sole", "right_sole"):
        assert result.verification.measures[f"pressure fit of {sole} on slab_top"] < 1e-9
        frame = robot.surface(sole).frame
        force, expected = (sum(np.array(p.force) for p in a.point_forces if p.frame == frame) for a in (result, rigid))
        assert np.linalg.norm(force - expected) < 1e-4 * np.linalg.norm(expected)


def test_on_a_steel_stiff_slab_a_centre_of_pressure_the_nodes_carry_only_by_pivoting_is_refused_saying_why(
        robot, monkeypatch):
    """The same stance without the stiff limit's spread answers: the soles' nodes carry it only
    if the soles pivot (an 18 um give), over the stiff limit's 10 um, and through W the solve
    stops short of feasibility: refused, where the rigid support holds it, the reason saying
    why before the rows it could not meet. (Until 2026-12-06 this was the stance 5 mm behind
    the toe edge on the unmoved grid, a 33 um give; see the test above.)"""
    monkeypatch.setattr(stances.stages, "_spread_answer", lambda *args: (None, "spread turned off by the test"))
    scenario = _shifted_slab(0.25)
    stance = scenario.stance("stand")
    ahead = CentreOfMassBounds(lower=(0.108, -math.inf, -math.inf), label="ahead")
    assert solve(robot, scenario.scene, stance, constraints=[ahead], deformable_as_rigid=True).feasible
    result = solve(robot, scenario.scene, stance, constraints=[ahead])
    assert not result.feasible and "stiff_limit" not in result.statistics
    assert result.statistics["status"] != "time budget spent"
    head, _, rows = result.reason.partition("; no step meets together: ")
    assert "held rigid" in head and "held rigid" not in rows
    assert re.search(r"held rigid, the stance holds, but the nodes of left_sole on slab_top and right_sole on slab_top "
                     r"carry its loads only by giving (\d+(\.\d+)?) um, more than the 10 um", head), result.reason


def test_the_tilt_under_the_robots_weight_bounds_the_bonded_turn_of_a_load_on_the_print(robot, coarse_cube):
    """``_tilts_under``: the robot's weight at the palm's farthest node, along its normal or
    along a tangent, turns the bonded palm by less than the bound, and by more than a fifth of it."""
    (soft,) = [c for c in build_problem(robot, coarse_cube.scene, coarse_cube.stance("hand-on-cube")).contacts
               if c.kind == "deformable"]
    bound = soft._tilts_under(robot.weight)[0]
    rotation = soft._print_rotations_in_body[0]
    farthest = soft.levers[np.argmax(np.linalg.norm(soft.levers, axis=1))]
    turns = []
    for direction in rotation.T:  # the print's tangents and normal, body frame
        force = robot.weight * direction
        turn = soft.a_inverse[3:6] @ np.concatenate([force, np.cross(farthest, force)])
        turns.append(np.linalg.norm(rotation[:, :2].T @ turn))  # about the tangents: the tilt
    assert max(turns) < bound < 5.0 * max(turns)


def test_the_tilt_rows_curvature_matches_second_differences_of_the_tilt(robot, coarse_cube, answers):
    """The face-tilt row's ``second_order`` (its Jacobian again at moved postures) gives, through
    :mod:`stances.curvature`, the second derivative of the tilt along the joints, at the
    allowance's answer's posture (the palm on its 1 degree bound)."""
    problem = build_problem(robot, coarse_cube.scene, coarse_cube.stance("hand-on-cube"),
                            PostureOptions(contact_frames="rest", tilt_allowance=ONE_DEGREE))
    q = np.asarray(answers["allowance"].q)
    (block,) = [b for b in problem.linearize(q, problem.initial_variables(q)).blocks if b.name == "face tilt"]
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    model, data = robot.model, robot.model.createData()

    def tilt(configuration):
        pin.framesForwardKinematics(model, data, configuration)
        return soft._tilts(data)[0]

    columns = np.arange(6, model.nv)[-7:]  # the right arm's joints, which turn the palm
    expected = second_differences(model, q, tilt, 1e-4, columns)
    hessian = ConstraintCurvature(model).hessian(q, [block], [np.ones(1)])[np.ix_(columns, columns)]
    np.testing.assert_allclose(hessian, expected, rtol=0, atol=2e-5 + 1e-3 * np.abs(expected).max())
    assert np.abs(expected).max() > 0.1  # the tilt is curved along the arm: the test can fail
