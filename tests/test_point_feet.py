"""Point feet: the ball-foot shape of robot descriptions, its rigid contact, and ANYmal standing on it."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pinocchio as pin
import pytest

import environments
import fem
import stances
from environments import Contact, ContactPrint, Stance
from conftest import assert_point_feet_are_their_spheres
from stances import StanceError
from stances.contacts import PointContact, point_placement_residual
from stances.description import point_print
from stances.problem import PostureOptions, build_problem
from stances.verify import VerificationTolerances, verify_problem

EPS = 1e-6
FOOT_RADIUS = 0.031  # ANYmal's foot spheres, from its URDF


@pytest.fixture(scope="module")
def solved(anymal, walk):
    """Each named stance of quadruped-walk with its problem and result."""
    out = {}
    for name in ("start", "three-feet", "front-feet-up"):
        stance = walk.stance(name)
        problem = build_problem(anymal, walk.scene, stance)
        out[name] = (problem, stances.solve(anymal, walk.scene, stance))
    return out


def test_a_point_print_is_a_regular_octagon_circumscribing_the_foot():
    polygon = point_print(0.02)
    edges = np.roll(polygon, -1, axis=0) - polygon
    # Distance from the centre to each edge's line: the circle touches every edge.
    def cross(a, b):
        return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

    distances = np.abs(cross(polygon, edges)) / np.linalg.norm(edges, axis=1)
    np.testing.assert_allclose(distances, 0.02, rtol=1e-12)
    assert len(polygon) == 8 and np.all(cross(edges, np.roll(edges, -1, axis=0)) > 0)  # convex, counter-clockwise


def test_anymal_has_four_point_feet_touching_only_with_their_spheres(anymal):
    assert anymal.support.keep == 3
    assert anymal.surfaces_with_role("foot") == ["left_front_foot", "right_front_foot", "left_hind_foot", "right_hind_foot"]
    assert all(surface.radius == FOOT_RADIUS for surface in anymal.surfaces.values())
    assert_point_feet_are_their_spheres(anymal)  # the contact frame is the sphere's centre


def test_point_placement_jacobian_matches_finite_differences(anymal):
    model, data = anymal.model, anymal.model.createData()
    rng = np.random.default_rng(0)
    q = pin.integrate(model, anymal.reference_configuration, 0.2 * rng.normal(size=model.nv))
    frame_id = anymal.frame_id(anymal.surface("left_front_foot").frame)
    print_frame = pin.SE3(pin.rpy.rpyToMatrix(0.2, -0.1, 0.7), np.array([0.3, 0.2, 0.05]))

    def residual(x):
        pin.framesForwardKinematics(model, data, x)
        pin.computeJointJacobians(model, data, x)
        return point_placement_residual(model, data, frame_id, print_frame, FOOT_RADIUS)

    _, analytic = residual(q)
    numeric = np.column_stack([
        (residual(pin.integrate(model, q, e))[0] - residual(pin.integrate(model, q, -e))[0]) / (2 * EPS)
        for e in EPS * np.eye(model.nv)
    ])
    # Row by row (metres): 1e-7 of the row's own size, plus 1e-12 m of round-off.
    error = np.abs(numeric - analytic).max(axis=1)
    assert np.all(error <= 1e-7 * np.abs(analytic).max(axis=1) + 1e-12), error
    # The residual is the centre's offset from the point r above the print, print frame.
    value, _ = residual(q)
    centre = data.oMf[frame_id].translation
    np.testing.assert_allclose(print_frame.rotation @ value, centre - print_frame.translation - FOOT_RADIUS * print_frame.rotation[:, 2])


def _rows_match_finite_differences(problem, q, lam):
    """Every non-collision row's Jacobian against central differences in q (on the manifold) and lambda."""
    model = problem.robot.model

    def rows(x, y):
        blocks = [b for b in problem.linearize(x, y).blocks if b.name != "collision"]
        return np.concatenate([b.value for b in blocks]), np.vstack([b.jacobian for b in blocks]), blocks

    _, analytic, blocks = rows(q, lam)
    numeric = np.column_stack(
        [(rows(pin.integrate(model, q, e), lam)[0] - rows(pin.integrate(model, q, -e), lam)[0]) / (2 * EPS)
         for e in EPS * np.eye(model.nv)]
        + [(rows(q, lam + e)[0] - rows(q, lam - e)[0]) / (2 * EPS) for e in EPS * np.eye(problem.n_variables)]
    )
    # Per row, relative to its own size (FEM rows are in newtons, placement rows in metres).
    size = np.maximum(np.abs(analytic).max(axis=1), 1e-8)
    error = np.abs(numeric - analytic).max(axis=1)
    labels = [label for b in blocks for label in b.labels]
    assert np.all(error <= 2e-5 * size), [(labels[i], error[i], size[i]) for i in np.flatnonzero(error > 2e-5 * size)]
    return blocks


def test_point_contact_rows_and_forces_match_finite_differences(anymal, walk):
    """Every constraint row of a three-foot problem (3 placement rows a foot), in q and lambda."""
    problem = build_problem(anymal, walk.scene, walk.stance("three-feet"), PostureOptions(min_normal_force=5.0))
    assert all(isinstance(contact, PointContact) for contact in problem.contacts)
    assert problem.n_variables == 3 * 4  # one four-edge pyramid a foot
    rng = np.random.default_rng(3)
    q = pin.integrate(anymal.model, anymal.reference_configuration, 0.05 * rng.normal(size=anymal.nv))
    lam = rng.uniform(1.0, 50.0, size=problem.n_variables)
    blocks = _rows_match_finite_differences(problem, q, lam)
    assert [len(b.value) for b in blocks if b.name == "placement"] == [3, 3, 3]


@pytest.mark.parametrize("name, feet", [("start", 4), ("three-feet", 3), ("front-feet-up", 4)])
def test_anymal_stances_solve_and_verify_with_balls_on_their_prints(anymal, walk, solved, name, feet):
    problem, result = solved[name]
    assert result.feasible, result.reason
    verification = verify_problem(problem, result)
    assert verification.ok, verification.reasons
    assert len(result.point_forces) == feet  # one force a foot, at its ball's centre
    data = anymal.model.createData()
    pin.framesForwardKinematics(anymal.model, data, result.q)
    total = np.zeros(3)
    for contact, point_force in zip(walk.stance(name), result.point_forces):
        surface = walk.scene.surface(contact.contact_print.surface)
        placement = surface.transform_print_to_world(contact.contact_print.x, contact.contact_print.y, 0.0)
        centre = data.oMf[anymal.frame_id(anymal.surface(contact.robot_surface).frame)].translation
        # The ball touches the support at the print: its centre a radius above it.
        np.testing.assert_allclose(centre, placement[:3, 3] + FOOT_RADIUS * placement[:3, 2], atol=1e-6)
        np.testing.assert_allclose(point_force.point, centre, atol=1e-9)
        normal = point_force.force @ placement[:3, 2]
        tangential = np.linalg.norm(point_force.force - normal * placement[:3, 2])
        assert tangential <= 0.7 * normal + 1e-6  # inside the floor's cone (mu = 0.7)
        total += point_force.force
    # The feet carry the robot's weight.
    np.testing.assert_allclose(total, [0.0, 0.0, anymal.mass * 9.81], atol=1e-5)


def test_verify_catches_a_point_foot_off_its_print_and_a_force_outside_its_cone(anymal, solved):
    problem, result = solved["start"]
    q = np.array(result.q)
    q[0] += 1e-3  # the whole robot slides 1 mm forward
    moved = verify_problem(problem, dataclasses.replace(result, q=q))
    assert not moved.ok
    assert any(
        re.fullmatch(r"left_front_foot on floor is off its print by 0\.001 m \(its ball must touch the support at the print\)", r)
        for r in moved.reasons
    ), moved.reasons
    forces = list(result.point_forces)
    first = forces[0]
    push = first.force[2]
    forces[0] = dataclasses.replace(first, force=first.force + np.array([push, 0.0, 0.0]))  # tangential = normal > mu normal
    pushed = verify_problem(problem, dataclasses.replace(result, point_forces=tuple(forces)))
    label = problem.contacts[0].label
    assert f"a force of {label} leaves its friction cone by {push * (1 - 0.7):.3g} N" in pushed.reasons


@pytest.fixture(scope="module")
def foam():
    return environments.load("quadruped-foam")


# The balls press the foam's nodes here (the default on a layer is its law: test_layer_balls),
# accepted as coarse as they are (1-5 nodes on the 10 mm foam, which the default ball_force_error
# refuses: test_a_ball_the_mesh_does_not_resolve_is_refused_against_the_continuums_force).
NODES = {"ball_contact": "nodes", "ball_force_error": np.inf}


@pytest.fixture(scope="module")
def on_foam(anymal, foam):
    stance = foam.stance("front-feet-on-foam")
    return build_problem(anymal, foam.scene, stance, PostureOptions(**NODES)), stances.solve(anymal, foam.scene, stance, **NODES)


# A posture quadruped-foam's planner (seed 1) started a stance from, on the mesh of
# 2026-12-03 (cells mirrored in alternate rows): the Coulomb stage's free run crept far
# from feasible from it, and the held-mode attempt from the start then had to carry it.
PLANNER_WARM_START = [
    0.1799884357680567, -0.04815431834796758, 0.44679483944793297, 0.009597459892560247, 0.04485995171278758,
    0.065207417725731, 0.9968166662779466, 0.05105976346833939, 0.02097745989557324, -1.0294631318355416,
    -0.1688071245500321, -1.0416725547756533, 1.0274400971152344, 0.40070111317707446, 0.6476370981303338,
    -1.5907359739910016, -0.17103764869274443, -0.7964060881880405, 0.8783991730209793,
]


def test_held_contact_modes_start_from_the_rigid_answers_forces_where_the_free_stage_failed(anymal, foam):
    """Both front balls on the foam, the left one 0.1 m beside its hip. The modes held from
    the rigid answer's posture are those of its loads pressing the balls in: W read off that
    posture instead leaves every node lifting off, where no load row has a gradient (an
    attempt that began each foot's share short; without it this stance is declared
    unreachable, "far from feasible and creeping", measured 2026-12-03)."""
    # The planner's print grid, to its last bit (0.1 m steps summed from the start's feet).
    stance = Stance(tuple(Contact(foot, ContactPrint(surface, x, y)) for foot, surface, x, y in (
        ("left_front_foot", "foam_top", 0.0, 0.30000000000000004),
        ("left_hind_foot", "floor", -0.09999999999999964, 0.10000000000000053),
        ("right_front_foot", "foam_top", -0.1, -0.09999999999999998),
        ("right_hind_foot", "floor", -0.09999999999999964, -0.39999999999999947),
    )))
    result = stances.solve(anymal, foam.scene, stance, q_init=np.array(PLANNER_WARM_START), **NODES)
    assert result.feasible, result.reason
    weight = anymal.mass * 9.81
    assert result.limits["least_load"] >= 0.1 * (1 - 1e-6)
    assert stances.verify(anymal, foam.scene, stance, result, **NODES).ok
    assert sum(p.force[2] for p in result.point_forces) == pytest.approx(weight, rel=1e-6)


def test_a_ball_foot_presses_the_foam_nodes_under_its_print_from_its_centre(anymal, foam, on_foam):
    problem, result = on_foam
    assert result.feasible, result.reason
    verification = verify_problem(problem, result, deformed_surfaces=True)
    assert verification.ok, verification.reasons
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    body = foam.scene.deformable_of_surface("foam_top")
    data = anymal.model.createData()
    pin.framesForwardKinematics(anymal.model, data, result.q)
    forces = np.array([p.force for p in result.point_forces[problem.load_slices[problem.contacts.index(soft)]]])
    points = np.array([p.point for p in result.point_forces[problem.load_slices[problem.contacts.index(soft)]]])
    for i, spec in enumerate(soft.prints):
        rows = soft.print_of_node == i
        # The print holds every top node the ball may reach: those whose gap below it is
        # at most the indentation bound plus the nearest node's gap (the ball sinks no
        # further than that), about 20 of the 30 under its octagon on the 10 mm mesh.
        origin = spec.transform_print_to_world[:3, 3]
        top = np.flatnonzero(np.isclose(body.body.mesh.nodes[:, 2], body.body.mesh.nodes[:, 2].max()))
        under = body.points_in_world(body.body.mesh.nodes[top]) - origin
        gaps = FOOT_RADIUS - np.sqrt(FOOT_RADIUS**2 - np.minimum(np.sum(under[:, :2] ** 2, axis=1), FOOT_RADIUS**2))
        reachable = top[gaps <= soft.max_indentation + gaps.min() + 1e-12]
        np.testing.assert_array_equal(np.sort(soft.node_ids[rows]), np.sort(reachable))
        assert 12 <= rows.sum() <= 30
        nodes = body.points_in_world(body.body.mesh.nodes[soft.node_ids[rows]])
        reach = np.linalg.norm(nodes[:, :2] - origin[:2], axis=1)
        np.testing.assert_allclose(nodes[:, 2], origin[2], atol=1e-9)
        # Every node's force acts at the ball's centre, which sinks into the foam.
        centre = data.oMf[anymal.frame_id(anymal.surface(spec.robot_surface).frame)].translation
        np.testing.assert_allclose(points[rows], np.tile(centre, (rows.sum(), 1)), atol=1e-9)
        depth = origin[2] + FOOT_RADIUS - centre[2]
        assert 0.0 < depth <= verification.measures["indentation of foam"] + 1e-9
        assert forces[rows].sum(axis=0)[2] > 0.0
        # The ball touches only the nodes its profile reaches as it sinks (rho <= sqrt(2 r d - d^2)),
        # not the whole octagon (a flat punch); the others lift off and carry nothing.
        pressed = forces[rows][:, 2] > 1e-9
        assert 1 <= pressed.sum() < rows.sum() / 4
        assert reach[pressed].max() <= math.sqrt(2 * FOOT_RADIUS * depth - depth**2) + 1e-9
        np.testing.assert_array_equal(forces[rows][~pressed], 0.0)
    total = np.sum([p.force for p in result.point_forces], axis=0)
    np.testing.assert_allclose(total, [0.0, 0.0, anymal.mass * 9.81], atol=1e-5)


def test_soft_point_print_rows_match_finite_differences(anymal, on_foam):
    problem, result = on_foam
    # Differences are taken where the contact modes hold: from seed 5, a node of the
    # mesh of 2026-12-03 switches between sticking and slipping within 1e-7 of the
    # point (its slip rows' difference then grows as 1 / step, 121 -> 997 from 1e-6 to
    # 1e-7, and agrees at 1e-8): a kink of the law, not a wrong derivative.
    rng = np.random.default_rng(6)
    q = pin.integrate(anymal.model, result.q, 1e-4 * rng.normal(size=anymal.nv))
    lam = problem.initial_variables(q) + rng.uniform(1.0, 5.0, size=problem.n_variables)
    names = {b.name for b in _rows_match_finite_differences(problem, q, lam)}
    assert {"placement", "touch", "node contact", "indentation"} <= names


def test_a_point_foot_refuses_the_traction_reaction_model(anymal, foam):
    with pytest.raises(StanceError, match=re.escape(
        "left_front_foot on foam_top: a point foot's print needs the consistent reaction model "
        "(its nodes follow the ball's centre, not the foot's turn)"
    )):
        build_problem(
            anymal, foam.scene, foam.stance("front-feet-on-foam"),
            PostureOptions(reaction_model="traction", contact_law="bonded", **NODES),
        )


@pytest.mark.parametrize("law", ["sticking", "bonded"])
def test_a_point_foot_on_a_soft_body_refuses_the_bonded_laws(anymal, foam, law):
    with pytest.raises(StanceError, match=re.escape(
        "left_front_foot on foam_top: a point foot on a soft body needs contact_law 'coulomb': a ball touches "
        f"the nodes its profile reaches as it sinks, which the {law!r} law (every print node held to the link) "
        "cannot say"
    )):
        build_problem(anymal, foam.scene, foam.stance("front-feet-on-foam"), PostureOptions(contact_law=law, **NODES))


def test_a_ball_starts_pressed_as_deep_as_its_rigid_load_needs(anymal, foam, on_foam):
    # From the stance's forces, a ball's W is scaled until its contact carries that load:
    # the flat print's depth for it leaves the ball's nodes at most touching.
    problem, result = on_foam
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    w = soft.variables_from_forces(anymal.model, result.point_forces)
    forces = soft.forces(anymal.model, problem.data, w)
    for i, placement in enumerate(soft.print_placements):
        wanted = np.sum([p.force for p in result.point_forces if p.frame == anymal.surface(soft.prints[i].robot_surface).frame], axis=0)
        carried = forces[soft.print_of_node == i].sum(axis=0)
        normal = placement.rotation[:, 2]
        # (each ball scaled with the others as they were: the foam couples them, a few percent)
        assert wanted @ normal <= carried @ normal <= 1.1 * (wanted @ normal)


@pytest.mark.parametrize("name, support", [("quadruped-walk", "step_top"), ("quadruped-foam", "foam_top")])
def test_anymal_plans_its_front_feet_onto_a_step_or_foam_and_every_stance_verifies(anymal, name, support):
    """Each foot lifts and lands, three feet always down; on foam, the front feet press it."""
    from cbm.planner import plan

    scenario = environments.load(name)
    # A 2 s budget per posture solve: the plans' stances solve in under 0.7 s,
    # while an unreachable candidate grinds for tens of seconds to its iteration limit.
    result = plan(scenario, robot=anymal, time_limit=120, solver_options={"time_budget": 2.0})
    assert result.success, result.reason
    check = result.check(scenario, anymal)
    assert check.ok, check.problems
    feet = set(anymal.surfaces_with_role("foot"))
    for planned in result.stances:
        assert len(feet & set(planned.stance.robot_surfaces)) >= 3
    last = {c.robot_surface: c.contact_print for c in result.stances[-1].stance}
    assert last["left_front_foot"].surface == support and last["right_front_foot"].surface == support
    moved = [
        name for name in feet
        if {c.robot_surface: c.contact_print for c in result.stances[0].stance}[name] != last[name]
    ]
    assert sorted(moved) == sorted(feet)
    assert len(result.stances) >= 9  # each of the four feet lifted and placed again


def test_anymal_steps_are_measured_from_where_its_reference_posture_puts_each_foot(anymal):
    """A foot may land within half a leg of its reference place relative to the three others."""
    from cbm.reach import ReachModel
    from cbm.sampling import PrintSet
    from environments import ContactPrint

    reach = ReachModel.of(anymal)
    legs = {limb.length for limb in reach.limbs.values()}
    assert len(legs) == 1  # four equal legs, measured on the model
    (leg,) = legs
    nominal = {"left_front_foot": (0.363, 0.201), "right_front_foot": (0.363, -0.201),
               "left_hind_foot": (-0.363, 0.201), "right_hind_foot": (-0.363, -0.201)}
    np.testing.assert_allclose(reach.limbs["left_front_leg"].foot_in_support[:2], nominal["left_front_foot"], atol=1e-3)
    others = {name: (np.array([*xy, 0.0]), np.array([1.0, 0.0, 0.0])) for name, xy in nominal.items() if name != "left_front_foot"}
    step = 0.5 * leg  # ReachLimits.step_length, in legs
    ahead = np.array([0.0, 0.9 * step, 1.1 * step])
    origins = np.column_stack([0.363 + ahead, np.full(3, 0.201), np.zeros(3)])
    candidates = PrintSet(
        "left_front_foot", tuple(ContactPrint("floor", x, y, 0.0) for x, y, _ in origins), origins, np.tile([1.0, 0.0, 0.0], (3, 1))
    )
    assert reach.reachable_mask(candidates, others).tolist() == [True, True, False]
    # The support rule: three of the four feet stay down.
    assert reach.may_lift("left_front_foot", list(nominal))
    assert not reach.may_lift("left_front_foot", list(others))


def test_verify_catches_a_point_foot_force_reported_away_from_its_ball(anymal, solved):
    problem, result = solved["start"]
    forces = list(result.point_forces)
    forces[0] = dataclasses.replace(forces[0], point=forces[0].point - np.array([0.0, 0.0, FOOT_RADIUS]))  # at the ground
    moved = verify_problem(problem, dataclasses.replace(result, point_forces=tuple(forces)))
    assert f"forces of {problem.contacts[0].label} are not applied at its ball's centre" in moved.reasons


def test_a_cold_start_puts_the_stance_feet_over_their_prints(anymal, walk):
    """On three feet, the reference posture is moved so that those three feet's
    mid-point lies over their prints' mid-point (it once matched all four feet's)."""
    from stances import initial_configuration

    stance = walk.stance("three-feet")
    assert len(stance.contacts) == 3
    q = initial_configuration(anymal, walk.scene, stance)
    data = anymal.model.createData()
    pin.framesForwardKinematics(anymal.model, data, q)
    feet = np.mean([data.oMf[anymal.frame_id(anymal.surface(c.robot_surface).frame)].translation for c in stance], axis=0)
    prints = np.mean([walk.scene.transform_print_to_world(c.contact_print)[:3, 3] for c in stance], axis=0)
    np.testing.assert_allclose(feet[:2], prints[:2], atol=1e-9)


def test_verify_counts_the_nodes_a_ball_presses_and_says_once_when_they_are_too_few(anymal, on_foam, caplog, monkeypatch):
    """On quadruped-foam's 10 mm foam a ball 1.7 mm deep presses one node: a contact smaller
    than the cells, whose force a converged mesh would not give (bench/results/ball_foot.md).
    Verify counts each ball's pressed nodes, logs it once for the body, and the stance's
    report shows it; the stance stays accepted by the model's own checks."""
    from cbm.report import stance_report
    from stances import deformable

    problem, result = on_foam
    monkeypatch.setattr(deformable, "_COARSE_BALLS_LOGGED", set())
    with caplog.at_level("WARNING", logger="stances.deformable"):
        first = verify_problem(problem, result)
        second = verify_problem(problem, result)
    assert first.ok and second.ok
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    forces = np.array([p.force for p in result.point_forces[problem.load_slices[problem.contacts.index(soft)]]])
    expected = {}
    for i, spec in enumerate(soft.prints):
        normal = forces[soft.print_of_node == i, 2]
        expected[spec.label] = int(np.count_nonzero(normal > 1e-3 * normal.max()))
        assert first.measures[f"pressed nodes under {spec.label}"] == expected[spec.label] < deformable.RESOLVED_BALL_NODES
    warnings = [r.getMessage() for r in caplog.records if "mesh node(s) of 'foam'" in r.getMessage()]
    assert len(warnings) == 1, warnings
    first_label = soft.prints[0].label
    assert warnings[0].startswith(f"{first_label} presses {expected[first_label]} mesh node(s) of 'foam': a ball contact smaller")
    lines = stance_report(dataclasses.replace(result, verification=first), anymal, problem.stance)
    for spec in soft.prints:
        estimate = first.measures[f"ball force estimate under {spec.label}"]
        error = first.measures[f"ball force error under {spec.label}"]
        assert (f"    {spec.label}: {expected[spec.label]} mesh node(s) pressed (a contact smaller than the cells: its force "
                f"depends on the mesh); a continuous layer carries {estimate:.1f} N at its depth, the mesh "
                f"{100 * error:+.0f} %") in lines


def test_verify_sets_each_balls_force_beside_a_continuous_layers_at_its_depth(anymal, foam, on_foam):
    """The foam is a 5 cm layer on a held base: at each ball's depth (its centre's sinking
    below where it rests on the foam) fem.sphere_on_layer_force gives what a mesh fine
    enough would carry; on the 10 mm mesh the ball on its node carries less (the
    2026-12-03 audit's converged FEM found the same stance's balls under-loaded too)."""
    problem, result = on_foam
    verification = verify_problem(problem, result)
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    material = foam.scene.deformable_of_surface("foam_top").body.material
    data = anymal.model.createData()
    pin.framesForwardKinematics(anymal.model, data, result.q)
    forces = np.array([p.force for p in result.point_forces[problem.load_slices[problem.contacts.index(soft)]]])
    for i, spec in enumerate(soft.prints):
        centre = data.oMf[anymal.frame_id(anymal.surface(spec.robot_surface).frame)].translation
        sinking = spec.transform_print_to_world[2, 3] + FOOT_RADIUS - centre[2]
        thickness, sides = soft._layer_under(i)  # the foam's thickness, the print's distances to its sides
        estimate, contact = fem.sphere_on_layer_force(sinking, FOOT_RADIUS, thickness, material.young_modulus,
                                                      material.poisson_ratio, sides)
        assert verification.measures[f"ball force estimate under {spec.label}"] == pytest.approx(estimate, rel=1e-9)
        carried = forces[soft.print_of_node == i, 2].sum()
        assert verification.measures[f"ball force error under {spec.label}"] == pytest.approx(carried / estimate - 1, abs=1e-9)
        assert -0.3 < carried / estimate - 1 < -0.05 and contact < 0.6 * 0.05
    # A print nearer the foam's side than a sixth of its thickness is outside the layer's formula.
    placement = soft.print_placements[0]
    try:
        soft._layers.clear()
        soft.print_placements[0] = pin.SE3(placement.rotation, placement.translation + np.array([0.0, 0.295, 0.0]))  # 5 mm from y = 0.5
        assert soft._layer_under(0) is None and soft._layer_under(1)[0] == pytest.approx(0.05)
    finally:
        soft.print_placements[0] = placement
        soft._layers.clear()
    # A ball sunk past what the formula takes (deeper than its radius) gets no estimate, and verify goes on.
    points = np.array([p.point for p in result.point_forces[problem.load_slices[problem.contacts.index(soft)]]])
    points[soft.print_of_node == 0] -= 0.04 * placement.rotation[:, 2]
    measures = {}
    soft._estimate_ball_forces(points, forces[:, 2], measures)
    assert f"ball force estimate under {soft.prints[0].label}" not in measures
    assert f"ball force estimate under {soft.prints[1].label}" in measures


SOFT_STEP = """
robot: anymal
objects:
  - {name: floor, type: floor}
  - name: step
    type: soft_blocks
    material: {E: 3.0e+6, nu: 0.4, rho: 0.0}
    resolution: 0.03
    blocks:
      - {name: tread, size: [0.8, 1.0, 0.05], center: [0.8, 0.0, 0.025]}
      - {name: ledge, size: [0.8, 1.0, 0.3], center: [1.6, 0.0, 0.15]}
stances:
  on-tread:
    left_front_foot: {surface: step_tread, x: 0.0, y: 0.2}
    right_front_foot: {surface: step_tread, x: 0.0, y: -0.2}
    left_hind_foot: {surface: floor, x: 0.0, y: 0.2}
    right_hind_foot: {surface: floor, x: 0.0, y: -0.2}
start: on-tread
"""


def test_a_soft_step_is_no_layer_under_a_ball_on_its_tread(anymal):
    """A tread 5 cm thick beside a 30 cm ledge, one soft body held on the floor: its far
    face is its fixed set, but it is no box, and its extent is not the tread's thickness."""
    scenario = environments.load_string(SOFT_STEP)
    problem = build_problem(anymal, scenario.scene, scenario.stance("on-tread"))
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    assert [soft._layer_under(i) for i in range(len(soft.prints))] == [None, None]


def test_a_ball_counts_the_nodes_carrying_a_thousandth_of_its_largest_node_force(anymal, on_foam):
    """``pressed nodes under <print>``: the nodes carrying more than a thousandth of the
    ball's largest node force (9 here, a tenth of a thousandth not counted); 0 for a ball
    resting on the foam, carrying nothing."""
    from stances import deformable

    problem, _ = on_foam
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    normal = np.zeros(soft.print_of_node.size)
    for i in range(len(soft.prints)):
        rows = np.flatnonzero(soft.print_of_node == i)
        normal[rows[:deformable.RESOLVED_BALL_NODES]] = 10.0
        normal[rows[deformable.RESOLVED_BALL_NODES]] = 0.009  # under a thousandth of 10 N
    measures = {}
    soft._count_pressed_nodes(normal, measures)
    assert [measures[f"pressed nodes under {spec.label}"] for spec in soft.prints] == [deformable.RESOLVED_BALL_NODES] * 2
    normal[np.flatnonzero(soft.print_of_node == 1)] = 0.0  # a ball resting on the foam, carrying nothing
    soft._count_pressed_nodes(normal, measures)
    assert measures[f"pressed nodes under {soft.prints[1].label}"] == 0


def test_a_ball_the_mesh_does_not_resolve_is_refused_against_the_continuums_force(anymal, foam, on_foam):
    """``ball_force_error`` (0.05 by default): on quadruped-foam's 10 mm foam each front ball
    presses 1-5 nodes and carries about 15 % less than the continuum at its sinking
    (fem.sphere_on_layer_force, within 0.8 % of converged FEMs there). Accepted as coarse
    (``inf``), the same answer is refused by default, each ball named with its error, the
    estimate and what to do; a tolerance above both errors accepts it, one between refuses
    one ball. Solved by default, the stance is an infeasible answer with that reason (the
    bonded model's fallback, which cannot press a ball's nodes, no longer runs)."""
    problem, result = on_foam
    stance = foam.stance("front-feet-on-foam")
    accepted = verify_problem(problem, result)
    assert accepted.ok
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    errors = [accepted.measures[f"ball force error under {spec.label}"] for spec in soft.prints]
    assert all(-0.3 < error < -0.05 for error in errors)

    def reasons(tolerance):
        options = PostureOptions(ball_contact="nodes") if tolerance is None else PostureOptions(
            ball_contact="nodes", ball_force_error=tolerance)
        return verify_problem(build_problem(anymal, foam.scene, stance, options), result).reasons

    expected = [
        f"the force under {spec.label} is {error:+.1%} off a continuous layer's at its sinking "
        f"({accepted.measures[f'ball force estimate under {spec.label}']:.4g} N; ball_force_error 0.05): its contact "
        "on foam is smaller than the mesh resolves; refine the mesh where balls land (a finer soft_box resolution: "
        "refine_lines bands stay up to +10 % stiff), keep the balls where the layer's law holds (a layer held on "
        "its base, pressed by balls only, far enough inside its edges), or accept it with the solver option "
        "ball_force_error=inf"
        for spec, error in zip(soft.prints, errors)
    ]
    assert list(reasons(None)) == expected
    assert list(reasons(1.01 * max(abs(e) for e in errors))) == []
    smaller, larger = sorted(abs(e) for e in errors)
    if larger > smaller:
        assert len(reasons(0.5 * (smaller + larger))) == 1
    solved = stances.solve(anymal, foam.scene, stance, ball_contact="nodes")
    assert not solved.feasible
    assert solved.reason.startswith(f"verification failed: the force under {soft.prints[0].label} is ")


def test_a_ball_on_a_body_that_is_no_layer_is_refused_however_many_nodes_it_presses(anymal, caplog, monkeypatch):
    """Where no continuum estimate exists (the soft step's tread is no layer), a ball sunk into
    the body is refused, whether it presses 1 node or many: a node contact's force is no
    converged one (9-74 pressed nodes up to +10 % off, bench/results/ball_node_contact.md).
    One resting on it (sunk under the placement tolerance) is no contact to judge; with
    ``ball_force_error=inf`` both are accepted and logged once for the body."""
    from stances import deformable

    scenario = environments.load_string(SOFT_STEP)
    stance = scenario.stance("on-tread")
    for tolerance, expect_reasons in ((0.05, True), (np.inf, False)):
        problem = build_problem(anymal, scenario.scene, stance, PostureOptions(ball_force_error=tolerance))
        (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
        normal = np.zeros(soft.print_of_node.size)
        first, second = (np.flatnonzero(soft.print_of_node == i) for i in range(2))
        normal[first[:1]] = 10.0  # one node pressed
        normal[second] = 10.0  # every node it may touch
        monkeypatch.setattr(deformable, "_COARSE_BALLS_LOGGED", set())
        measures = {}
        sunk = soft.link_points_at_rest - np.array([0.0, 0.0, 1e-3])  # each ball 1 mm into the tread
        with caplog.at_level("WARNING", logger="stances.deformable"):
            caplog.clear()
            reasons = soft._check_balls(sunk, normal, measures, VerificationTolerances())
        assert f"ball force estimate under {soft.prints[0].label}" not in measures
        assert measures[f"pressed nodes under {soft.prints[0].label}"] == 1
        assert measures[f"pressed nodes under {soft.prints[1].label}"] == second.size
        logged = [r.getMessage() for r in caplog.records if "mesh node(s) of 'step'" in r.getMessage()]
        if expect_reasons:
            assert reasons == [
                f"{spec.label} presses {count} mesh node(s) of step, sunk 0.001 m, where no continuum estimate of a "
                "ball's force exists (step is no layer held on its base under it, or the ball is too near its sides or "
                "too deep for the layer's law): the mesh's node contact does not resolve a ball's contact, whatever "
                "the nodes it presses (9-74: up to +10 % off a converged force); keep the balls where the layer's law "
                "holds (a layer held on its base, pressed by balls only, far enough inside its edges), or accept it "
                "with the solver option ball_force_error=inf"
                for spec, count in zip(soft.prints, (1, second.size))]
            assert not logged
            # A ball sunk into the tread pressing no node carries nothing it should: refused too;
            # one resting on it (sunk under the placement tolerance) is no contact to judge.
            normal[first] = 0.0
            assert len(soft._check_balls(sunk, normal, {}, VerificationTolerances())) == 2
            assert soft._check_balls(soft.link_points_at_rest, normal, {}, VerificationTolerances()) == []
        else:
            assert reasons == [] and len(logged) == 1
            assert logged[0] == (f"{soft.prints[0].label} presses 1 mesh node(s) of 'step' with no continuum estimate "
                                 "of its force: a node contact, up to +10 % off a converged force whatever the nodes "
                                 "it presses (fewer than 9: -46 % to +31 %), accepted (ball_force_error inf)")


def test_a_loaded_ball_with_no_estimate_is_refused_before_solving_and_its_bound_holds(anymal):
    """ANYmal's feet carry a tenth of its weight each (its support rule): on the soft step's
    tread, where no continuum estimate exists, such a ball sinks past what verification lets
    rest (at least the nearest node's gap, plus its load over the stiffness of a punch
    bonding every node it may touch), so the solve answers at once (no SQP iteration) with
    each ball's least load and sinking bound. The bound holds: accepted with
    ``ball_force_error=inf``, each ball sinks more than it."""
    from stances import stages

    scenario = environments.load_string(SOFT_STEP)
    stance = scenario.stance("on-tread")
    refused = stances.solve(anymal, scenario.scene, stance)
    assert not refused.feasible and refused.iterations == 0
    assert refused.statistics["status"] == stages.BALLS_REFUSED
    problem = build_problem(anymal, scenario.scene, stance)
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    least = [0.1 * anymal.weight] * 2
    assert "; ".join(soft.balls_refused_anyway(least, VerificationTolerances().deformable_placement)) == refused.reason
    bounds = [float(m) for m in re.findall(r"it sinks at least ([0-9.e+-]+) m", refused.reason)]
    assert len(bounds) == 2 and refused.reason.startswith(
        f"{soft.prints[0].label} carries at least {least[0]:.3g} N on step, where no continuum estimate of a ball's "
        "force exists (step is no layer held on its base under it, or the ball is too near its sides): it sinks at "
        "least ")
    accepted = stances.solve(anymal, scenario.scene, stance, ball_force_error=math.inf)
    assert accepted.feasible
    points = np.array([p.point for p in accepted.point_forces[problem.load_slices[problem.contacts.index(soft)]]])
    for index, bound in enumerate(bounds):
        assert soft._ball_sinking(points, index) > bound


def test_a_ball_on_a_node_of_a_steel_stiff_step_is_not_refused_before_solving(anymal):
    """The bound refuses nothing it cannot: the soft step at 1e10 Pa with each front ball
    right over a node (no gap) sinks by far less than verify's placement tolerance under its
    least load, so the solve runs; the balls rest (sunk under 1 um), which verify accepts."""
    from stances import stages

    stiff = SOFT_STEP.replace("E: 3.0e+6", "E: 1.0e+10")
    scenario = environments.load_string(stiff)
    tread = scenario.scene.surface("step_tread")
    body = scenario.scene.deformable_of_surface("step_tread")
    nodes = body.points_in_world(body.mesh.nodes)
    top = nodes[np.isclose(nodes[:, 2], 0.05)]  # the tread's top face
    contacts = []
    for foot, y in (("left_front_foot", 0.2), ("right_front_foot", -0.2)):
        rest = tread.transform_print_to_world(0.0, y, 0.0)[:3, 3]
        node = top[np.argmin(np.linalg.norm(top[:, :2] - rest[:2], axis=1))]
        local = np.linalg.inv(tread.transform_print_to_world(0.0, 0.0, 0.0)) @ np.append(node, 1.0)
        contacts.append(Contact(foot, ContactPrint("step_tread", float(local[0]), float(local[1]), 0.0)))
    stance = Stance(tuple(contacts) + tuple(c for c in scenario.stance("on-tread") if c.robot_surface.endswith("hind_foot")))
    problem = build_problem(anymal, scenario.scene, stance)
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    assert soft.balls_refused_anyway([0.1 * anymal.weight] * 2, VerificationTolerances().deformable_placement) == []
    result = stances.solve(anymal, scenario.scene, stance)
    assert result.feasible and result.iterations > 0, result.reason
    assert result.statistics["status"] != stages.BALLS_REFUSED


def test_cbm_check_takes_solver_options_and_names_a_bad_one(capsys, tmp_path):
    """``--solver-option KEY=VALUE`` reaches the posture solver from the command line: the
    front feet pressing the 10 mm foam's nodes are refused by default and accepted with
    ``ball_force_error=inf``; a misspelt option is bad input naming the valid ones, a pair
    without ``=`` a usage error. A plan is verified with its own options, and
    ``--solver-option`` puts its own over them: a plan saved before ``ball_force_error``
    existed (its stances recorded none) with such feet fails its check, and passes with
    ``ball_force_error=inf``, as it was solved."""
    from cbm.cli import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, main

    check = ["check", "quadruped-foam", "--stance", "front-feet-on-foam", "--solver-option", "ball_contact=nodes"]
    assert main(check) == EXIT_FAILED
    out = capsys.readouterr().out
    assert "infeasible: verification failed: the force under left_front_foot on foam_top is " in out
    assert main(check + ["--solver-option", "ball_force_error=inf"]) == EXIT_OK
    assert "quadruped-foam / front-feet-on-foam: feasible" in capsys.readouterr().out
    assert main(check + ["--solver-option", "ball_force_eror=inf"]) == EXIT_BAD_INPUT
    assert "unknown posture option(s) ['ball_force_eror']" in capsys.readouterr().err
    assert main(check + ["--solver-option", "ball_force_error"]) == EXIT_BAD_INPUT
    assert "expected KEY=VALUE" in capsys.readouterr().err
    from dataclasses import replace

    from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source

    scenario, robot = environments.load("quadruped-foam"), stances.Robot.load("anymal")
    stance = scenario.stance("front-feet-on-foam")
    result = stances.solve(robot, scenario.scene, stance, ball_contact="nodes", ball_force_error=float("inf"))
    assert result.feasible, result.reason
    # As saved before the option existed: the stance recorded its ball contact only.
    old = replace(result, statistics=dict(result.statistics, options={"ball_contact": "nodes"}))
    plan = Plan(False, "search stopped", [PlannedStance(stance, old.q, old.point_forces, {}, old, move="")],
                PlanStatistics(), scenario.name, robot=robot_description(robot), scenario_source=scenario_source(scenario))
    saved = tmp_path / "plan.json"
    plan.save(saved)
    assert main(["check", str(saved)]) == EXIT_FAILED
    assert "the force under left_front_foot on foam_top is " in capsys.readouterr().out
    assert main(["check", str(saved), "--solver-option", "ball_force_error=inf"]) == EXIT_OK
    assert "every stance verifies (with ball_force_error=inf over the recorded options)" in capsys.readouterr().out
    assert main(["check", str(saved), "--solver-option", "ball_force_eror=inf"]) == EXIT_BAD_INPUT
    assert "unknown posture option(s) ['ball_force_eror']" in capsys.readouterr().err
