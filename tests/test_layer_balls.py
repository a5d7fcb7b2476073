"""Ball feet on a soft layer sinking by the continuum's law (``ball_contact="layer"``,
:mod:`stances.layer_ball`): its rows' derivatives, the force each ball carries against the
law solved afresh, the rigid limit, the field's balance, where the law applies, and verify
fed what the law forbids."""

from __future__ import annotations

import functools
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.spatial

import environments
import fem
from environments import Contact, ContactPrint, Stance
from stances import StanceError
from stances.deformable import PrintSpec
from fem.layer_strain import largest_ball_mean
from fem.layer_contact import SIDE_DROP, SIDE_REACH, widest_contact
from stances.layer_ball import (LayerBalls, _strain_on_layer, _without_sides, largest_ball_load, layer_site,
                                layer_under)
from stances.problem import PostureOptions, build_problem
from stances import solve
from stances.results import PointForce
from stances.verify import verify

LAYER = {"ball_contact": "layer"}
FRONT = ("left_front_foot_contact", "right_front_foot_contact")


@functools.lru_cache(maxsize=None)
def foam(resolution: float = 0.025, young_modulus: float = 3.0e6, strain_limit: float | None = None):
    """quadruped-foam with its foam meshed at ``resolution`` (the law does not read the
    mesh; its field does), Young's modulus and strain bound replaced."""
    text = environments.builtin_scenario_path("quadruped-foam").read_text()
    text = text.replace("resolution: 0.01", f"resolution: {resolution}").replace("E: 3.0e+6", f"E: {young_modulus:.6e}")
    if strain_limit is not None:
        text = text.replace("    resolution:", f"    strain_limit: {strain_limit}\n    resolution:", 1)
    return environments.load_string(text, name="quadruped-foam")


@pytest.fixture(scope="module")
def front_feet(anymal):
    """The front-feet-on-foam stance solved with the layer's law: (scenario, stance, result)."""
    scenario = foam()
    stance = scenario.stance("front-feet-on-foam")
    result = solve(anymal, scenario.scene, stance, **LAYER)
    assert result.feasible, result.reason
    return scenario, stance, result


def _normal_forces(result, frames=FRONT):
    return [sum(p.force[2] for p in result.point_forces if p.frame == frame) for frame in frames]


def test_each_ball_carries_the_laws_force_at_its_sinking(anymal, front_feet):
    scenario, stance, result = front_feet
    problem = build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER))
    layer = [c for c in problem.contacts if c.kind == "layer"]
    assert len(layer) == 1 and len(layer[0].balls) == 2
    data = anymal.model.createData()
    pin.framesForwardKinematics(anymal.model, data, result.q)
    material = scenario.scene.deformable_objects[0].body.material
    for ball, law, force in zip(layer[0].balls, layer[0].laws, _normal_forces(result)):
        centre = data.oMf[ball.frame_id].translation
        sinking = ball.radius - (centre[2] - 0.05)  # the foam's top at rest is z = 0.05 m
        assert 1e-3 < sinking < 3e-3
        # The front feet 0.1 m from the foam's front side, 0.3 m from its others.
        np.testing.assert_allclose(sorted(law.side_distances), [0.1, 0.3, 0.3, 0.7], atol=1e-9)
        expected, _ = fem.sphere_on_layer_force(sinking, ball.radius, 0.05, material.young_modulus,
                                                material.poisson_ratio, law.side_distances)
        # The solver's table against the law solved afresh: 1e-7 m of sinking is 5e-3 N here.
        assert force == pytest.approx(expected, abs=5e-3)
    # The robot's weight is carried: the four feet's vertical forces add up to it.
    assert sum(p.force[2] for p in result.point_forces) == pytest.approx(anymal.weight, rel=1e-6)
    check = verify(anymal, scenario.scene, stance, result, **LAYER)
    assert check.ok, check.reasons
    assert abs(check.measures["layer law error of left_front_foot on foam_top"]) < 5e-3


def test_the_layer_rows_match_finite_differences(anymal, front_feet):
    scenario, stance, result = front_feet
    problem = build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER))
    rng = np.random.default_rng(3)
    q = pin.integrate(anymal.model, result.q, 1e-3 * rng.normal(size=anymal.nv))
    lam = np.asarray(result.statistics["lambda"]) + rng.uniform(0.5, 5.0, size=problem.n_variables)
    contact, mine = next((c, s) for c, s in zip(problem.contacts, problem.variable_slices) if c.kind == "layer")
    offset = anymal.nv + mine.start

    def rows(q, lam, derivatives):
        model, data = anymal.model, problem.data
        pin.computeJointJacobians(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        blocks = contact.blocks(model, data, lam[mine], problem.n_step, offset, derivatives=derivatives)
        return np.concatenate([b.value for b in blocks]), (np.vstack([b.jacobian for b in blocks]) if derivatives else None)

    value, jacobian = rows(q, lam, True)
    eps = 1e-7
    numeric = np.zeros_like(jacobian)
    for i in range(anymal.nv):
        step = np.zeros(anymal.nv)
        step[i] = eps
        numeric[:, i] = (rows(pin.integrate(anymal.model, q, step), lam, False)[0]
                         - rows(pin.integrate(anymal.model, q, -step), lam, False)[0]) / (2 * eps)
    for j in range(problem.n_variables):
        step = np.zeros(problem.n_variables)
        step[j] = eps
        numeric[:, anymal.nv + j] = (rows(q, lam + step, False)[0] - rows(q, lam - step, False)[0]) / (2 * eps)
    for r in range(len(value)):
        size = max(np.abs(jacobian[r]).max(), 1e-8)
        assert np.abs(numeric[r] - jacobian[r]).max() <= 1e-6 * size + 1e-9, r
    # The sinking's columns are the law's slope times each pyramid edge's normal part.
    assert np.abs(jacobian[2, offset: offset + 4]).min() > 0.0


def test_a_stiff_layer_gives_the_rigid_point_contacts_answer(anymal):
    scenario = foam(young_modulus=1e11)
    stance = scenario.stance("front-feet-on-foam")
    stiff = solve(anymal, scenario.scene, stance, **LAYER)
    rigid = solve(anymal, scenario.scene, stance, deformable_as_rigid=True)
    assert stiff.feasible and rigid.feasible
    forces = np.array(_normal_forces(stiff, FRONT + ("left_hind_foot_contact", "right_hind_foot_contact")))
    held = np.array(_normal_forces(rigid, FRONT + ("left_hind_foot_contact", "right_hind_foot_contact")))
    np.testing.assert_allclose(forces, held, rtol=1e-3)
    # Micrometres of sinking: the posture is the rigid one's.
    assert np.abs(pin.difference(anymal.model, stiff.q, rigid.q)).max() < 1e-4


def test_the_fields_base_reactions_balance_the_balls(anymal, front_feet):
    scenario, stance, result = front_feet
    body = scenario.scene.deformable_objects[0].body
    field = result.deformations["foam"]
    on_robot = sum(np.array(p.force) for p in result.point_forces if p.frame in FRONT)
    # The body frame is the world's turned by none here: the base holds what the balls push.
    np.testing.assert_allclose(body.fixed_reactions(field).sum(axis=0), on_robot, rtol=1e-9, atol=1e-9)
    # Under each ball the top sinks, less than the ball (the mesh is stiffer than the
    # continuum at the contact's scale), more than a tenth of it.
    assert field[:, 2].min() < -1e-4


def test_verify_refuses_a_force_off_the_law_a_sinking_past_its_bound_and_a_force_out_of_its_cone(anymal, front_feet):
    scenario, stance, result = front_feet

    def changed(frame, force):
        forces = tuple(PointForce(p.frame, p.point, force(np.array(p.force)) if p.frame == frame else p.force)
                       for p in result.point_forces)
        return replace(result, point_forces=forces)

    heavier = verify(anymal, scenario.scene, stance, changed(FRONT[0], lambda f: 1.01 * f), **LAYER)
    assert any(r.startswith("left_front_foot on foam_top carries ") and "where its layer's law gives" in r
               for r in heavier.reasons), heavier.reasons
    sideways = verify(anymal, scenario.scene, stance, changed(FRONT[1], lambda f: f + np.array([f[2], 0.0, 0.0])), **LAYER)
    assert any(r.startswith("the force of right_front_foot on foam_top leaves its friction cone by ") for r in sideways.reasons)
    assert any(r.startswith("a node under right_front_foot on foam_top leaves its friction cone by ") for r in sideways.reasons)
    shallow = verify(anymal, scenario.scene, stance, result, max_indentation=1e-3, **LAYER)
    assert any("sinks" in r and "beyond its indentation bound 0.001 m" in r for r in shallow.reasons), shallow.reasons


def test_verify_checks_a_result_with_the_contact_model_it_was_solved_with(anymal):
    # Solved with node contact, checked without options: its own model (the result
    # records it), not the default layer law, which its node forces do not follow.
    # Node contact needs the scene's own 10 mm mesh under the balls.
    scenario = foam(resolution=0.01)
    stance = scenario.stance("front-feet-on-foam")
    # (accepted as coarse as the balls' contacts are: 1-5 nodes, test_ball_resolution refuses them)
    nodes = solve(anymal, scenario.scene, stance, ball_contact="nodes", ball_force_error=np.inf)
    assert nodes.feasible, nodes.reason
    assert nodes.statistics["options"]["ball_contact"] == "nodes"
    assert verify(anymal, scenario.scene, stance, nodes).ok
    against_the_law = verify(anymal, scenario.scene, stance, nodes, ball_contact="layer")
    # The law's model has one point force a ball; the nodes' result has one a node.
    assert against_the_law.reasons == (
        "44 contact forces reported for the 4 application points of the stance's contacts",)


def test_the_solver_keeps_the_strain_bound_on_the_layers_converged_field_and_names_the_conflict(anymal):
    # Unbounded (5 %), each front ball strains its layer 1.45 % (the converged field under it;
    # the 25 mm mesh's means: 0.82 %). At 1 % their loads move to the hind feet until both
    # balls sit on the bound; verify, solving nothing of the solver's, agrees.
    stance = foam().stance("front-feet-on-foam")
    bounded = foam(strain_limit=0.01)
    result = solve(anymal, bounded.scene, stance, **LAYER)
    assert result.feasible, result.reason
    # The row's curvature along the print in the SQP's Hessian: 16 iterations (91 without it,
    # each QP swinging the sideways force across).
    assert result.iterations <= 25
    check = verify(anymal, bounded.scene, stance, result, **LAYER)
    strains = [check.measures[f"strain under {label}"] for label in ("left_front_foot on foam_top",
                                                                     "right_front_foot on foam_top")]
    assert check.ok and all(0.0099 < s <= 0.01 + 1e-6 for s in strains), strains
    assert check.measures["largest strain of foam"] < 0.009  # the mesh's, lower
    assert max(_normal_forces(result)) < 0.7 * 71.0
    # The sideways force counts (an independent audit, 2026-12-05: without it the solver put
    # 0.37 of each ball's load sideways, 1.16 % on fresh fields): each ball's strain on fresh
    # axisymmetric fields under its normal and sideways forces, within 0.2 % of the bound.
    body = bounded.scene.deformable_objects[0]
    material = body.body.material
    for frame in FRONT:
        force = sum(np.asarray(p.force) for p in result.point_forces if p.frame == frame)
        law = fem.BallOnLayer(anymal.surface(frame.replace("_contact", "")).radius, 0.05, material.young_modulus,
                              material.poisson_ratio)
        a = law.contact_radius(force[2])
        fields = [fem.axisymmetric_layer_field(a, 0.05, material.poisson_ratio, body.strain_radius, sideways=s)
                  for s in (False, True)]
        fresh = force[2] * largest_ball_mean(fields[0], body.strain_radius, a, fields[1],
                                             np.hypot(force[0], force[1]) / force[2]) / material.young_modulus
        assert fresh <= 0.01 * 1.002, (frame, fresh)
    # At 0.5 % a ball cannot carry its least load (a tenth of the weight, 29.7 N, strains it
    # 0.61 %): refused, the conflict named.
    tight = foam(strain_limit=0.005)
    refused = solve(anymal, tight.scene, stance, **LAYER)
    assert not refused.feasible
    # Led by the strongest row of the conflict among those violated alike (the elastic QP
    # spreads its violation: placements and balance were as violated as the strain).
    assert refused.reason.startswith("strain under "), refused.reason
    conflict = refused.reason.split("; no step meets together: ")[1].split(", ")
    assert set(conflict) == {"strain under left_front_foot on foam_top (foam's converged field)",
                             "strain under right_front_foot on foam_top (foam's converged field)",
                             "normal load of left_front_foot on foam_top", "normal load of right_front_foot on foam_top"}


def test_verify_refuses_a_ball_that_strains_its_layer_past_the_bound(anymal, front_feet):
    scenario, stance, result = front_feet
    # The 5 % default holds the free stance's 1.45 %; a bound under it does not.
    check = verify(anymal, foam(strain_limit=0.012).scene, stance, result, **LAYER)
    strain = check.measures["strain under left_front_foot on foam_top"]
    assert 0.012 < strain < 0.016
    assert any(r.startswith(f"strain {strain:.3g} under left_front_foot on foam_top (its layer's converged field")
               and r.endswith("exceeds its bound 0.012: linear elasticity does not hold there") for r in check.reasons)


def test_the_equilibrium_filter_refuses_a_ball_its_layer_cannot_carry_within_the_strain_bound(anymal):
    from cbm.equilibrium import EquilibriumFilter
    from cbm.rejections import strain_bound_hint

    # On a 3e5 Pa foam a ball's least load (a tenth of the weight) strains it past 5 %: the
    # planner's filter says so before any solve (a plan on it took 133 s of solves to give up).
    soft = foam(young_modulus=3e5)
    stance = soft.stance("front-feet-on-foam")
    reason = EquilibriumFilter(anymal, soft.scene)(stance)
    assert re.fullmatch(r"static equilibrium impossible for the contact set: left_front_foot on foam_top carries at "
                        r"most 25\.\d N within foam's strain bound \(its layer's law\), less than its least load "
                        r"29\.\d N", reason), reason
    assert "strain bound of foam" in strain_bound_hint([reason, reason, "torque limit of j"])
    # The largest load strains the ball to its rows' bound, on the converged field.
    body = soft.scene.deformable_objects[0]
    problem = build_problem(anymal, soft.scene, stance, PostureOptions(**LAYER))
    layer = next(c for c in problem.contacts if c.kind == "layer")
    site = (layer.thicknesses[0], layer.laws[0].side_distances)
    largest = largest_ball_load(layer.balls[0].radius, site, body, PostureOptions(), layer.balls[0].friction)
    assert layer.ball_strain(0, largest)[0] == pytest.approx((1.0 - 2e-3) * body.strain_limit, rel=1e-8)
    # At 3e6 Pa the stance passes, each ball then bounded by its law's table or indentation bound.
    firm = foam()
    assert EquilibriumFilter(anymal, firm.scene)(firm.stance("front-feet-on-foam")) == ""


def test_the_law_applies_where_the_body_is_a_layer_under_balls_only(anymal, robot):
    scenario = foam()
    body = scenario.scene.deformable_objects[0]
    top = scenario.scene.surface("foam_top")
    radius, friction = anymal.surface("left_front_foot").radius, top.friction

    def site(x, y=0.2, ball=radius):
        return layer_site(body, top.transform_print_to_world(x, y, 0.0), ball, friction)

    # The foam (0.4 x 1.0 x 0.05 m, its top centred; its front side at x = -0.2) is a layer for
    # ANYmal's 31 mm ball where no side cuts the law's table short of the load the foam's 5 %
    # strain bound allows (about 250 N, a contact of 11.6 mm): SIDE_REACH such contacts inside
    # its sides (32 mm), each side's distance given for the law's softening.
    free = _without_sides(LayerBalls(anymal, body, [PrintSpec("left_front_foot", top, top.transform_print_to_world(
        0.0, 0.2, 0.0), "mid-mat")], PostureOptions(**LAYER)).laws[0])
    allowed = largest_ball_load(radius, (0.05, ()), body, PostureOptions(), friction)
    assert 240.0 < allowed < 260.0
    nearest = SIDE_REACH * free.contact_radius(allowed)
    thickness, sides = site(-0.2 + 1.002 * nearest)
    assert thickness == pytest.approx(0.05)
    np.testing.assert_allclose(sides, [1.002 * nearest, 0.4 - 1.002 * nearest, 0.7, 0.3], atol=1e-12)
    assert site(-0.2 + 0.998 * nearest) is None
    assert site(0.0, 0.5 - 0.998 * nearest) is None and site(0.0, 0.5 - 1.002 * nearest) is not None
    # A ball of 5 mm is a layer's nearer its sides: 1.5 strain radii then bind (30 mm; nearer,
    # a mat's side strains more than the layer's field: an independent FEM, 2026-12-05).
    assert site(-0.1699, ball=0.005)[1][0] == pytest.approx(0.0301)
    assert site(-0.1701, ball=0.005) is None
    # Means of a smaller radius (each tet's own strain at 0) keep the 30 mm the audit measured
    # with 20 mm means: nearer, the side's edge strains more than the layer's field says.
    pointwise = replace(body, strain_radius=0.0)
    assert layer_site(pointwise, top.transform_print_to_world(-0.1701, 0.2, 0.0), 0.005, friction) is None
    assert layer_site(pointwise, top.transform_print_to_world(-0.1699, 0.2, 0.0), 0.005, friction) is not None
    assert layer_site(body, scenario.scene.surface("floor").transform_print_to_world(0.75, 0.2, 0.0), radius,
                      friction) is None
    # 1.5 cm from the side the law, cut short by it, would bound the ball to 22 N, under the 63 N
    # ANYmal's front feet carry there on the nodes (a review, 2026-12-05): the nodes press it.
    cut = fem.BallOnLayer(radius, 0.05, body.body.material.young_modulus, body.body.material.poisson_ratio,
                          (0.015, 0.385, 0.7, 0.3))
    assert cut.force_limit < 25.0
    assert site(-0.185) is None
    # Under a loose strain bound nothing stops the load short of the table's end: the law needs
    # the sides SIDE_REACH times its widest contact away (61 mm).
    unbounded = replace(body, strain_limit=0.5)
    widest = fem.layer_contact.widest_contact(radius, 0.05)
    assert layer_site(unbounded, top.transform_print_to_world(-0.2 + 1.002 * SIDE_REACH * widest, 0.2, 0.0), radius,
                      friction) is not None
    assert layer_site(unbounded, top.transform_print_to_world(-0.2 + 0.998 * SIDE_REACH * widest, 0.2, 0.0), radius,
                      friction) is None
    inside = build_problem(anymal, scenario.scene, scenario.stance("front-feet-on-foam"), PostureOptions(**LAYER))
    assert [c.kind for c in inside.contacts].count("layer") == 1
    # A sole is no ball: refused by the model itself (the builder keeps the nodes for it).
    sole = PrintSpec("left_sole", top, top.transform_print_to_world(0.0, 0.2, 0.0), "left_sole on foam_top")
    with pytest.raises(StanceError, match="left_sole on foam_top: only ball feet sink by a layer's law"):
        LayerBalls(robot, body, [sole], PostureOptions(**LAYER))
    beside = PrintSpec("left_front_foot", top, top.transform_print_to_world(-0.195, 0.2, 0.0), "near the side")
    with pytest.raises(StanceError, match="near the side: foam is not a layer under this print"):
        LayerBalls(anymal, body, [beside], PostureOptions(**LAYER))


def _front_feet_on_foam_at(x):
    """ANYmal's front feet on quadruped-foam's foam at ``x`` (the foam's frame; its front side
    at -0.2 m), its hind feet on the floor."""
    return Stance((Contact("left_front_foot", ContactPrint("foam_top", x, 0.2, 0.0)),
                   Contact("right_front_foot", ContactPrint("foam_top", x, -0.2, 0.0)),
                   Contact("left_hind_foot", ContactPrint("floor", -0.3, 0.2, 0.0)),
                   Contact("right_hind_foot", ContactPrint("floor", -0.3, -0.2, 0.0))))


def test_near_a_side_a_ball_sinks_by_the_law_softened_by_it(anymal):
    """Front feet 6.5 cm (1.3 thicknesses) inside the foam's front side: the law with the
    sides' softening (0.6 % at 1.4 mm there), which verify solves afresh; the side-free law
    would have each ball carry more at the same sinking."""
    scenario = foam()
    stance = _front_feet_on_foam_at(-0.135)
    problem = build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER))
    (layer,) = [c for c in problem.contacts if c.kind == "layer"]
    assert [min(law.side_distances) for law in layer.laws] == [pytest.approx(0.065)] * 2
    # No side cuts its table short (it ends at 0.7 of the ball's radius, as on a wide mat); an
    # indentation bound shallower ends the force where the softened law sinks the ball to it.
    assert [law.largest_contact_radius for law in layer.laws] == [pytest.approx(0.7 * layer.balls[0].radius)] * 2
    shallow = build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER, max_indentation=5e-4))
    (bounded,) = [c for c in shallow.contacts if c.kind == "layer"]
    assert [law.sinking(limit)[0] for law, limit in zip(bounded.laws, bounded.force_limits)] == [pytest.approx(5e-4)] * 2
    result = solve(anymal, scenario.scene, stance, **LAYER)
    assert result.feasible, result.reason
    check = verify(anymal, scenario.scene, stance, result, **LAYER)
    assert check.ok, check.reasons
    material = scenario.scene.deformable_objects[0].body.material
    for ball, law, force in zip(layer.balls, layer.laws, _normal_forces(result)):
        sinking = check.measures[f"sinking of {ball.label}"]
        softened, _ = fem.sphere_on_layer_force(sinking, ball.radius, 0.05, material.young_modulus,
                                                material.poisson_ratio, law.side_distances)
        free, _ = fem.sphere_on_layer_force(sinking, ball.radius, 0.05, material.young_modulus, material.poisson_ratio)
        assert force == pytest.approx(softened, abs=5e-3)
        assert softened / free == pytest.approx(fem.layer_contact.side_factor(sinking, ball.radius, 0.05,
                                                                              law.side_distances), rel=1e-12)
        assert softened < 0.995 * free


def test_near_a_side_the_ball_strain_is_the_layers_over_the_sides_softening_with_its_derivatives(anymal):
    """6.5 cm from the foam's side, a ball's strain is the layer's field over the sides'
    softening at its contact radius (a free side strains the body more under the same force;
    an audit's FEM of a 12 cm block: 1.1-5.1 % more 3-5 cm from its sides, where the force's
    softening is 2.7-7.4 %), and its derivatives in the normal force and the sideways force's
    square are their finite differences."""
    scenario = foam()
    stance = Stance((Contact("left_front_foot", ContactPrint("foam_top", -0.135, 0.2, 0.0)),
                     Contact("right_front_foot", ContactPrint("foam_top", -0.1, -0.2, 0.0)),
                     Contact("left_hind_foot", ContactPrint("floor", -0.3, 0.2, 0.0)),
                     Contact("right_hind_foot", ContactPrint("floor", -0.3, -0.2, 0.0))))
    (layer,) = [c for c in build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER)).contacts
                if c.kind == "layer"]
    body = scenario.scene.deformable_objects[0]
    law = layer.laws[0]
    force, sideways = 30.0, 6.0
    near = layer.ball_strain(0, force, sideways)[0] - body.largest_strain_at_rest
    # The same ball's field, read at the same contact radius on the laterally infinite layer.
    contact = law.contact_radius(force)
    unsoftened = _strain_on_layer(_without_sides(law), body, force, contact, layer.balls[0].friction,
                                  sideways=sideways, floor=layer.slope_floor)[0] - body.largest_strain_at_rest
    softening = fem.layer_contact.side_softening(contact, 0.05, law.side_distances)[0]
    assert near == pytest.approx(unsoftened / softening, rel=1e-12) and softening < 0.995
    for f in (0.2, 30.0, 90.0):
        value, d_normal, d_square = layer.ball_strain(0, f, 0.2 * f)
        step = 1e-6 * f
        numeric = (layer.ball_strain(0, f + step, 0.2 * f)[0] - layer.ball_strain(0, f - step, 0.2 * f)[0]) / (2 * step)
        assert d_normal == pytest.approx(numeric, rel=1e-5)
        q2 = (0.2 * f) ** 2
        numeric = (layer.ball_strain(0, f, np.sqrt(q2 * (1 + 1e-6)))[0]
                   - layer.ball_strain(0, f, np.sqrt(q2 * (1 - 1e-6)))[0]) / (2e-6 * q2)
        assert d_square == pytest.approx(numeric, rel=1e-5)


def test_34_mm_from_the_mats_side_a_ball_takes_the_law_cut_short_of_its_strain_bound_only(anymal):
    """Front feet 34 mm inside the foam's front side (nodes under the 61 mm rule of before): the
    side ends the law's table at 34 / 2.8 mm of contact (290 N), past the 250 N the 5 % strain
    bound allows; the stance solves and verifies, each ball's strain under the bound."""
    scenario = foam()
    stance = _front_feet_on_foam_at(-0.166)
    problem = build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER))
    (layer,) = [c for c in problem.contacts if c.kind == "layer"]
    body = scenario.scene.deformable_objects[0]
    for ball, law in zip(layer.balls, layer.laws):
        assert law.largest_contact_radius == pytest.approx(0.034 / SIDE_REACH, rel=1e-9)
        assert 280.0 < law.force_limit < 300.0
        allowed = largest_ball_load(ball.radius, (0.05, law.side_distances), body, PostureOptions(), ball.friction)
        assert 240.0 < allowed < 260.0
    result = solve(anymal, scenario.scene, stance, **LAYER)
    assert result.feasible, result.reason
    check = verify(anymal, scenario.scene, stance, result, **LAYER)
    assert check.ok, check.reasons
    for ball in layer.balls:
        assert 0.0 < check.measures[f"strain under {ball.label}"] < body.strain_limit


def test_a_thick_block_and_a_cube_are_layers_under_balls_where_their_sides_leave_the_law(anymal):
    """The law reaches any box held on its base (before 2026-12-05: 1.2 thicknesses inside its
    sides, none of a 0.3 m cube): for ANYmal's ball, where no side cuts its table short of the
    5 % strain bound's load: 34 mm inside the sides of a 12 cm block (32 mm is the mesh's) and
    67 mm inside a 0.3 m cube's (nearer than a quarter of its thickness a side needs 5.6 contact
    radii; 66 mm is the mesh's)."""
    for size, x, thickness in (([0.4, 1.0, 0.12], -0.166, 0.12), ([0.4, 1.0, 0.12], -0.168, None),
                               ([0.3, 0.3, 0.3], 0.0, 0.3), ([0.3, 0.3, 0.3], -0.0815, 0.3),
                               ([0.3, 0.3, 0.3], -0.084, None)):
        text = environments.builtin_scenario_path("quadruped-foam").read_text()
        text = re.sub(r"  front-feet-on-foam:.*?(?=^start:)", "", text, flags=re.S | re.M)  # prints off a cube's top
        text = text.replace("size: [0.4, 1.0, 0.05]", f"size: {size}").replace(
            "center: [0.75, 0.0, 0.025]", f"center: [0.75, 0.0, {size[2] / 2}]").replace("resolution: 0.01", "resolution: 0.05")
        scenario = environments.load_string(text, name="block")
        body = scenario.scene.deformable_objects[0]
        top = scenario.scene.surface("foam_top")
        site = layer_site(body, top.transform_print_to_world(x, 0.0, 0.0), anymal.surface("left_front_foot").radius,
                          top.friction)
        if thickness is None:
            assert site is None
            continue
        assert site[0] == pytest.approx(thickness) and min(site[1]) == pytest.approx(0.5 * size[0] + x)
        stance = Stance((Contact("left_front_foot", ContactPrint("foam_top", x, 0.0, 0.0)),
                         Contact("left_hind_foot", ContactPrint("floor", -0.3, 0.2, 0.0)),
                         Contact("right_hind_foot", ContactPrint("floor", -0.3, -0.2, 0.0))))
        kinds = [c.kind for c in build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER)).contacts]
        assert kinds.count("layer") == 1 and "deformable" not in kinds


PAD_SCENE = Path(__file__).resolve().parents[1] / "bench" / "scenes" / "mesh-files" / "hyq-mesh-scene.yaml"
HYQ_BALL = 0.02175  # m, its description's (bench/scenes/mesh-files/robots/hyq.yaml)


def test_a_bevelled_pad_is_a_layer_where_free_sides_would_move_a_balls_force_little():
    """A soft_mesh pad (a closed STL, 4 cm thick, its edges bevelled 2 cm in, held on the
    floor) is no box, but its top face is a convex rectangle over nothing but its held base:
    a layer, its sides read as free faces at the top's edges. A bevel is stiffer than a free
    face, so a print takes the law only where free faces there would lower a ball's force by
    under 2 % in all at its widest contact: HyQ's front foot at (-0.1, 0.32) on it (0.08 m
    and 0.11 m from the two nearest edges); not 3 cm from an edge, nor within a sixth of the
    thickness of one."""
    scenario = environments.load(PAD_SCENE)
    pad = scenario.scene.deformable_of_surface("pad_top_0")
    top = scenario.scene.surface("pad_top_0")
    thickness, sides = layer_under(pad, top.transform_print_to_world(-0.1, 0.32, 0.0), HYQ_BALL)
    assert thickness == pytest.approx(0.04, rel=1e-6)
    assert sorted(sides) == pytest.approx([0.08, 0.11, 0.28, 0.75], abs=1e-6)
    drop = SIDE_DROP * widest_contact(HYQ_BALL, thickness) * thickness * sum(1.0 / d**2 for d in sides)
    assert 0.01 < drop < 0.02
    near = top.transform_print_to_world(-0.15, 0.0, 0.0)  # 3 cm from the x = -0.18 edge
    assert SIDE_DROP * widest_contact(HYQ_BALL, thickness) * thickness / 0.03**2 > 0.02
    assert layer_under(pad, near, HYQ_BALL) is None
    assert layer_under(pad, top.transform_print_to_world(-0.175, 0.0, 0.0), HYQ_BALL) is None


def test_a_top_face_over_a_gap_or_not_convex_is_no_layer():
    """A bridge's deck (its underside a boundary inside the top face's outline) and an
    L-shaped slab (its top no convex polygon) are no layers; the ledge of a soft step, 0.3 m
    of material down to the held floor, is one."""
    head = ("robot: anymal\nobjects:\n  - {name: floor, type: floor}\n  - name: body\n    type: soft_blocks\n"
            "    material: {E: 3.0e+6, nu: 0.4, rho: 0.0}\n    resolution: 0.05\n    blocks:\n")
    stance = ("stances:\n  s:\n    left_hind_foot: {surface: floor, x: -0.8, y: 0.2}\n"
              "    right_hind_foot: {surface: floor, x: -0.8, y: -0.2}\n    left_front_foot: {surface: floor, x: -0.5, y: 0.2}\n"
              "    right_front_foot: {surface: floor, x: -0.5, y: -0.2}\nstart: s\n")
    # The bridge: a 1.0 x 0.8 x 0.4 m grid with the cells under the deck's middle left out.
    xs, ys, zs = np.linspace(-0.5, 0.5, 11), np.linspace(-0.4, 0.4, 5), np.linspace(0.0, 0.4, 5)
    cells = np.ones((10, 4, 4), dtype=bool)
    cells[2:8, :, :3] = False
    mesh = fem.tensor_mesh(xs, ys, zs, cells)
    bridge = environments.DeformableObject(
        "bridge", fem.DeformableBody(mesh, fem.LinearElasticMaterial(3.0e6, 0.4), mesh.nodes[:, 2] == 0.0), np.eye(4))
    on_deck = np.eye(4)
    on_deck[2, 3] = 0.4
    assert layer_under(bridge, on_deck, 0.031) is None
    cases = (
        ("      - {name: long, size: [1.0, 0.4, 0.1], center: [0.0, 0.0, 0.05]}\n"
         "      - {name: arm, size: [0.4, 0.6, 0.1], center: [-0.3, 0.5, 0.05]}\n", "body_long", None),
        ("      - {name: tread, size: [0.8, 1.0, 0.05], center: [0.8, 0.0, 0.025]}\n"
         "      - {name: ledge, size: [0.8, 1.0, 0.3], center: [1.6, 0.0, 0.15]}\n", "body_ledge", 0.3),
    )
    for blocks, surface, thickness in cases:
        scenario = environments.load_string(head + blocks + stance)
        body = scenario.scene.deformable_of_surface(surface)
        site = layer_under(body, scenario.scene.surface(surface).transform_print_to_world(0.0, 0.0, 0.0), 0.031)
        if thickness is None:
            assert site is None, surface
        else:
            assert site[0] == pytest.approx(thickness) and sorted(site[1]) == pytest.approx([0.4, 0.4, 0.5, 0.5])


def test_an_unknown_ball_contact_is_refused_with_the_choices():
    with pytest.raises(StanceError, match=r"ball_contact must be one of \('layer', 'nodes'\), got 'hertz'"):
        PostureOptions(ball_contact="hertz")


def test_the_report_gives_each_balls_sinking_and_force_and_the_bodys_depth(anymal, front_feet):
    from cbm.report import stance_report

    scenario, stance, result = front_feet
    check = verify(anymal, scenario.scene, stance, result, **LAYER)
    lines = stance_report(replace(result, verification=check), anymal, stance)
    sinking = check.measures["sinking of left_front_foot on foam_top"]
    force = check.measures["layer force of left_front_foot on foam_top"]
    strain = check.measures["strain under left_front_foot on foam_top"]
    assert (f"    left_front_foot on foam_top: sinks {1e3 * sinking:.2f} mm, {force:.1f} N by its layer's law, "
            f"strains it {100 * strain:.2f} % (its converged field)") in lines
    deepest = max(check.measures[f"sinking of {foot} on foam_top"] for foot in ("left_front_foot", "right_front_foot"))
    assert check.measures["indentation of foam"] == deepest
    assert any(line.startswith(f"    foam: indented {1e3 * deepest:.2f} mm, largest strain ") for line in lines)


def test_strain_rows_are_the_most_strained_tets_near_each_ball_or_none(anymal, front_feet):
    scenario, stance, result = front_feet
    lam = np.asarray(result.statistics["lambda"])
    for rows in (12, 3, 0):
        problem = build_problem(anymal, scenario.scene, stance, PostureOptions(max_strain_rows=rows, **LAYER))
        strain = [b for b in problem.evaluate(result.q, lam).blocks if b.name == "strain"]
        assert len(strain) == (1 if rows else 0)
        if rows:
            assert len(strain[0].value) == 2 * rows
            assert all(label.startswith(("strain under left_front_foot on foam_top (tet ",
                                         "strain under right_front_foot on foam_top (tet ")) for label in strain[0].labels)
    # The largest row is verify's largest strain (its tet near a ball; the table's radius interpolation aside).
    problem = build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER))
    (strain,) = [b for b in problem.evaluate(result.q, lam).blocks if b.name == "strain"]
    check = verify(anymal, scenario.scene, stance, result, **LAYER)
    assert strain.value.max() == pytest.approx(check.measures["largest strain of foam"], rel=2e-3)


def test_strain_tables_kept_with_the_body_are_the_most_recently_used(anymal, front_feet, monkeypatch):
    from stances import layer_ball

    scenario, stance, result = front_feet
    monkeypatch.setattr(layer_ball, "_KEPT_STRAIN_TABLES", 2)
    body = scenario.scene.deformable_objects[0].body
    layer_ball._UNIT_STRAINS.pop(body, None)
    lam = np.asarray(result.statistics["lambda"])
    tables = []
    for y in (0.2, 0.1, 0.0, 0.1):
        moved = Stance(tuple(Contact(c.robot_surface, ContactPrint(c.contact_print.surface, c.contact_print.x,
                                                                   y if c.robot_surface == "left_front_foot" else c.contact_print.y))
                             for c in stance))
        problem = build_problem(anymal, scenario.scene, moved, PostureOptions(**LAYER))
        problem.evaluate(result.q, lam)
        tables.append(next(c for c in problem.contacts if c.kind == "layer")._unit_strains)
    kept = layer_ball._UNIT_STRAINS[body]
    assert len(kept) == 2
    # y = 0.1 was met again before the bound dropped it: the same table, not a new one.
    assert tables[3] is tables[1]
    assert [id(t) for t in kept.values()] == [id(tables[2]), id(tables[1])]


def test_the_ball_strain_rows_curvature_along_the_print_matches_finite_differences(anymal, front_feet):
    """The curvature the ball strain block gives the SQP (``variable_curvature``) is the row's
    second derivative in its pyramid's variables along the print: differences of the row's
    gradient, with no sideways force (where the gradient along the print vanishes) and with one."""
    scenario, stance, result = front_feet
    problem = build_problem(anymal, scenario.scene, stance, PostureOptions(**LAYER))
    contact, mine = next((c, s) for c, s in zip(problem.contacts, problem.variable_slices) if c.kind == "layer")
    offset = anymal.nv + mine.start
    model, data = anymal.model, problem.data
    pin.computeJointJacobians(model, data, result.q)
    pin.framesForwardKinematics(model, data, result.q)
    edges = contact._pyramid[0]
    base = np.asarray(result.statistics["lambda"])[mine].copy()
    base[edges] = 10.0  # equal edges: no sideways force
    for pull in (0.0, 4.0):
        lam = base.copy()
        lam[edges.start] += pull  # one edge more: a sideways force along it
        block = next(b for b in contact.blocks(model, data, lam, problem.n_step, offset) if b.name == "ball strain")
        curvature = block.variable_curvature(np.array([1.0, 0.0]))[offset + edges.start: offset + edges.stop,
                                                                    offset + edges.start: offset + edges.stop]
        # Directions along the print: pyramid steps that leave the normal force as it is.
        normal_row = contact._normal_rows[0]
        along = np.array([[1.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, -1.0]]) / normal_row[0]
        assert np.allclose(along @ normal_row, 0.0)
        eps = 1e-4
        for d in along:
            def gradient(x):
                b = next(b for b in contact.blocks(model, data, x, problem.n_step, offset) if b.name == "ball strain")
                return b.jacobian[0, offset + edges.start: offset + edges.stop]
            numeric = (gradient(lam + eps * _padded(d, edges, len(lam))) - gradient(lam - eps * _padded(d, edges, len(lam)))) / (2 * eps)
            # With a sideways force the block leaves out the terms of the table's second
            # derivative in the squared ratio (a few percent here); with none they vanish.
            assert d @ curvature @ d == pytest.approx(d @ numeric, rel=5e-2 if pull else 1e-4), pull
        assert np.all(np.linalg.eigvalsh(curvature) >= -1e-12 * np.abs(curvature).max())


def _padded(direction, where, size):
    out = np.zeros(size)
    out[where] = direction
    return out


def test_a_top_faces_edges_split_at_points_a_mesher_left_off_them_are_one_side_each():
    """qhull splits a hull's edge at its collinear points, and at points a few nanometres off
    it (gmsh, an STL's float32 vertices) into facets whose lines differ by about that: each
    edge must count once as a free side, or a pad's every print would read several."""
    from stances.layer_ball import _merged_lines

    rng = np.random.default_rng(5)
    along = np.linspace(-0.2, 0.2, 11)[:-1]  # each edge from its first corner, every node once
    corners = np.vstack([np.column_stack([along, np.full(10, -0.2)]), np.column_stack([np.full(10, 0.2), along]),
                         np.column_stack([-along, np.full(10, 0.2)]), np.column_stack([np.full(10, -0.2), -along])])
    corners[1:] += rng.uniform(-3e-8, 3e-8, corners[1:].shape)  # a mesher's nanometres
    hull = scipy.spatial.ConvexHull(corners)
    lines = np.column_stack([hull.equations[:, :2], -hull.equations[:, 2]])
    assert len(lines) > 4  # split
    merged = _merged_lines(lines, 0.04)
    assert len(merged) == 4
    np.testing.assert_allclose(np.sort(np.abs(merged[:, 2])), 0.2, atol=1e-7)
    # Two edges at a rounded corner's 1 mrad are two sides.
    turned = np.array([[1.0, 0.0, 0.2], [np.cos(1e-3), np.sin(1e-3), 0.2]])
    assert len(_merged_lines(turned, 0.04)) == 2


def test_the_strain_bound_test_keeps_no_soft_body_alive():
    """A planner asks whether a ball's law reaches its strain bound at every solve, so the
    answer is kept; but by the object weakly: a process planning many scenes must not keep
    every soft body it met, its mesh and factorisation with it."""
    import gc
    import weakref

    from stances import layer_ball

    scenario = environments.load_string(environments.builtin_scenario_path("quadruped-foam").read_text())
    body = scenario.scene.deformable_objects[0]
    top = scenario.scene.surface("foam_top")
    assert layer_site(body, top.transform_print_to_world(0.0, 0.0, 0.0), 0.031, top.friction) is not None
    assert body in layer_ball._COVERED
    gone = weakref.ref(body)
    del scenario, body, top
    gc.collect()
    assert gone() is None
