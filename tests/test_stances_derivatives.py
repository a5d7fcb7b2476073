"""Finite-difference checks of every analytic derivative of the posture problem.

Steps are taken on the configuration manifold with ``pin.integrate`` (central
differences, eps = 1e-6); the tolerance is relative to the Jacobian's size
because central differences carry an O(eps^2) truncation and O(1e-16/eps)
rounding error on values of size up to 1e5 (FEM forces in newtons).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import coarse_scenario
from stances.problem import PostureOptions, build_problem
from stances import NodeSlips, solve
from stances.statics import PointLoads, point_jacobians, static_torque_derivatives, static_torques

EPS = 1e-6


def _central_difference(function, q, model, n):
    columns = []
    for i in range(n):
        step = np.zeros(model.nv)
        step[i] = EPS
        columns.append((function(pin.integrate(model, q, step)) - function(pin.integrate(model, q, -step))) / (2 * EPS))
    return np.column_stack(columns)


def _random_configuration(robot, seed, spread=0.2):
    rng = np.random.default_rng(seed)
    return pin.integrate(robot.model, robot.reference_configuration, spread * rng.normal(size=robot.nv))


@pytest.mark.parametrize("seed", [0, 1])
def test_static_torque_derivatives_match_finite_differences(robot, seed):
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(seed)
    q = _random_configuration(robot, seed)
    joints = [model.frames[robot.frame_id(s.frame)].parentJoint for s in robot.surfaces.values()]
    loads = PointLoads(joints, 0.1 * rng.normal(size=(len(joints), 3)))
    forces = 100.0 * rng.normal(size=(len(joints), 3))
    _, dtau_dq, dtau_dforces = static_torque_derivatives(model, data, q, loads, forces)
    numeric = _central_difference(lambda x: static_torques(model, data, x, loads, forces), q, model, model.nv)
    # Row by row (one joint's torque each): 1e-6 of the row's size, at least 1e-6 N m/rad.
    error = np.abs(numeric - dtau_dq).max(axis=1)
    assert np.all(error <= 1e-6 * np.maximum(np.abs(dtau_dq).max(axis=1), 1.0)), error.max()
    # Torques are linear in the forces: d tau / d f = -J^T exactly.
    pin.computeJointJacobians(model, data, q)
    jacobians = point_jacobians(model, data, loads)
    assert np.allclose(dtau_dforces, -np.hstack([j.T for j in jacobians]), atol=1e-12)


def test_static_torques_agree_with_rnea_and_external_forces(robot):
    """Two independent routes (computeStaticTorque vs RNEA with fext) give one answer."""
    model, data = robot.model, robot.model.createData()
    q = _random_configuration(robot, 3)
    frame = model.frames[robot.frame_id(robot.surface("right_palm").frame)]
    loads = PointLoads([frame.parentJoint], [[0.01, 0.02, 0.03]])
    force = np.array([[10.0, -20.0, 300.0]])
    tau = static_torques(model, data, q, loads, force)
    pin.forwardKinematics(model, data, q)
    placement = data.oMi[frame.parentJoint]
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    local = placement.rotation.T @ force[0]
    fext[frame.parentJoint] = pin.Force(local, np.cross([0.01, 0.02, 0.03], local))
    expected = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv), pin.StdVec_Force(fext))
    assert np.allclose(tau, expected, atol=1e-9)


def _problems(robot):
    yield "rigid hand-on-table", coarse_scenario("hand-on-table"), "hand-on-table", {}
    for law in ("coulomb", "sticking", "bonded"):
        yield f"deformable hand-on-cube ({law})", coarse_scenario("hand-on-cube"), "hand-on-cube", {"contact_law": law}
    yield (
        "deformable hand-on-cube (traction)",
        coarse_scenario("hand-on-cube"),
        "hand-on-cube",
        {"reaction_model": "traction", "contact_law": "bonded"},
    )
    yield (
        "deformable hand-on-cube (paper's force term)",
        coarse_scenario("hand-on-cube"),
        "hand-on-cube",
        {"deformation_cost": "force", "deformation_weight": 1e-3},
    )
    # The contact solved in the print's rest frames (the turned frames' derivative terms off).
    yield (
        "deformable hand-on-cube (coulomb, rest frames)", coarse_scenario("hand-on-cube"), "hand-on-cube",
        {"contact_frames": "rest"},
    )
    # A palm whose tilt is bounded (tilt_allowance): the face-tilt rows.
    yield (
        "deformable hand-on-cube (tilt allowance)", coarse_scenario("hand-on-cube"), "hand-on-cube",
        {"tilt_allowance": 0.0175},
    )
    # A palm whose nodes start slipped (held_slips, the stance before's): the law from there.
    yield (
        "deformable hand-on-cube (coulomb, held slips)", coarse_scenario("hand-on-cube"), "hand-on-cube",
        {"held_slips": "random"},
    )
    yield "deformable step-on-cube", coarse_scenario("step-on-cube"), "step-on-cube", {}
    # Two soles on one foam block: one coupled contact system.
    yield "coupled both-on-foam (coulomb)", coarse_scenario("cross-soft-block"), "both-on-foam", {}
    yield (
        "coupled both-on-foam (traction)",
        coarse_scenario("cross-soft-block"),
        "both-on-foam",
        {"reaction_model": "traction", "contact_law": "bonded"},
    )


@pytest.fixture(scope="module")
def linearised_problems(robot):
    """Problems at a configuration near their solution (where the FEM forces matter)."""
    cases = []
    for label, scenario, stance_name, options in _problems(robot):
        stance = scenario.stance(stance_name)
        warm = solve(robot, scenario.scene, stance, deformable_as_rigid=True)
        options = dict(options)
        held = _random_held_slips(robot, scenario, stance, options) if options.pop("held_slips", None) else None
        problem = build_problem(robot, scenario.scene, stance, PostureOptions(min_normal_force=5.0, **options),
                                held_slips=held)
        for contact in problem.contacts:
            if contact.kind == "deformable":
                # Tiny bounds activate the strain, indentation and mesh overlap rows, so
                # they are checked too.
                contact.strain_limit = 1e-5
                contact.max_indentation = 1e-6
                contact.max_mesh_overlap = 1e-9
        rng = np.random.default_rng(7)
        q = pin.integrate(robot.model, warm.q, 2e-3 * rng.normal(size=robot.nv))
        lam = problem.initial_variables(q) + rng.uniform(1.0, 50.0, size=problem.n_variables)
        cases.append((label, problem, q, lam))
    return cases


def _random_held_slips(robot, scenario, stance, options):
    """Each soft print's nodes slipped by up to 2 mm, seeded, tangential and normal parts
    both (the normal part is taken out where the slips are read)."""
    plain = build_problem(robot, scenario.scene, stance, PostureOptions(**options))
    rng = np.random.default_rng(11)
    held = {}
    for contact in plain.contacts:
        if contact.kind != "deformable":
            continue
        for index, spec in enumerate(contact.prints):
            nodes = contact.node_ids[contact.print_of_node == index]
            held[spec.robot_surface] = NodeSlips(contact.deformable_object.name, nodes,
                                                 rng.uniform(-2e-3, 2e-3, size=(len(nodes), 3)))
    return held


def _rows(problem, q, lam, derivatives=True):
    """Every row but the collision ones (their witness points jump), by label: (value,
    Jacobian row), the Jacobian None with ``derivatives`` False (the values alone, as a
    line search reads them: bit for bit those of a linearisation, test_problem_evaluate)."""
    blocks = problem.linearize(q, lam).blocks if derivatives else problem.evaluate(q, lam).blocks
    rows = {}
    for block in blocks:
        if block.name == "collision":
            continue
        for i, label in enumerate(block.labels):
            rows[(block.name, label)] = (block.value[i], block.jacobian[i] if derivatives else None)
    return rows


def _value_noise(problem, q, lam, base, detours=4):
    """Each row's change when evaluated again at the same point after other points.

    The Coulomb contact solve starts from the contact modes of its last solve and
    settles within a tolerance, so its forces (and every row they enter) repeat to
    about 2e-12 of the largest force, not to the last bit (measured: 1.2-2.8e-10 N
    on the coupled sole pair, largest node force 117 N). Central differences with
    step EPS see that noise divided by EPS.
    """
    rng = np.random.default_rng(1)
    noise = dict.fromkeys(base, 0.0)
    for _ in range(detours):
        _rows(problem, q, lam + 1e-3 * rng.standard_normal(len(lam)), derivatives=False)
        again = _rows(problem, q, lam, derivatives=False)
        for key in base:
            if key in again:
                noise[key] = max(noise[key], abs(again[key][0] - base[key][0]))
    return noise


def test_every_constraint_jacobian_matches_finite_differences(linearised_problems):
    names = set()
    for label, problem, q, lam in linearised_problems:
        model = problem.robot.model
        base = _rows(problem, q, lam)
        noise = _value_noise(problem, q, lam, base)
        names.update(name for name, _ in base)
        # A row's label names the option that bounds it, where a user can act on it.
        overlap = [row for name, row in base if name == "mesh overlap"]
        assert all(row.startswith("mesh overlap bound (1e-09 m, max_mesh_overlap) at node ") for row in overlap)
        keys = list(base)
        numeric = np.zeros((len(keys), problem.n_step))
        directions = [("q", i) for i in range(model.nv)] + [("lam", j) for j in range(problem.n_variables)]
        for column, (kind, i) in enumerate(directions):
            if kind == "q":
                step = np.zeros(model.nv)
                step[i] = EPS
                plus = _rows(problem, pin.integrate(model, q, step), lam, derivatives=False)
                minus = _rows(problem, pin.integrate(model, q, -step), lam, derivatives=False)
            else:
                step = np.zeros(problem.n_variables)
                step[i] = EPS
                plus, minus = _rows(problem, q, lam + step, derivatives=False), _rows(problem, q, lam - step, derivatives=False)
            for r, key in enumerate(keys):
                # A strain row's tet may drop out of the active set under a step: skip it there.
                numeric[r, column] = (plus[key][0] - minus[key][0]) / (2 * EPS) if key in plus and key in minus else np.nan
        for r, key in enumerate(keys):
            analytic = base[key][1]
            known = np.isfinite(numeric[r])
            # Per row: relative to that row's own size, so a wrong small row cannot hide.
            size = max(np.abs(analytic).max(), 1e-8)
            error = np.abs(numeric[r, known] - analytic[known]).max()
            # Plus the row's own repeat noise over EPS (zero for rows that do not pass
            # through the Coulomb contact solve), times 4 as a few detours may not hit its
            # worst case, and 1e-10 absolute.
            tolerance = 2e-5 * size + 1e-10 + 4.0 * noise[key] / EPS
            assert error <= tolerance, f"{label}: {key} off by {error:.3g} (row size {size:.3g}, noise {noise[key]:.2g})"
    assert {"placement", "touch", "whole print", "node contact", "centre of pressure", "indentation", "mesh overlap", "strain",
            "equilibrium", "torque limit", "normal load", "face tilt"} <= names


def test_objective_gradient_matches_finite_differences(linearised_problems):
    for label, problem, q, lam in linearised_problems:
        model = problem.robot.model
        linearization = problem.linearize(q, lam)

        def objective(x):
            return np.array([problem.evaluate(x, lam).objective])

        numeric = _central_difference(objective, q, model, model.nv)[0]
        analytic = linearization.gradient[: model.nv]
        assert np.abs(numeric - analytic).max() <= 1e-5 * max(1.0, np.abs(analytic).max()), label
        # In the force variables too: the torque-usage term depends on them.
        numeric = np.array([
            (problem.evaluate(q, lam + e).objective - problem.evaluate(q, lam - e).objective) / (2 * EPS)
            for e in EPS * np.eye(problem.n_variables)
        ])
        analytic = linearization.gradient[model.nv:]
        assert np.abs(numeric - analytic).max() <= 1e-5 * max(1.0, np.abs(analytic).max()), label


def test_torque_usage_term_is_half_the_weighted_squared_usage_beyond_half_the_limits(robot):
    scenario = coarse_scenario("hand-on-table")
    stance = scenario.stance("hand-on-table")
    q = robot.reference_configuration
    with_term = build_problem(robot, scenario.scene, stance, PostureOptions(torque_weight=0.5))
    without = build_problem(robot, scenario.scene, stance, PostureOptions(torque_weight=0.0))
    lam = with_term.initial_variables(q)
    linearization = with_term.linearize(q, lam)
    usage = np.abs(linearization.torques[6:]) / robot.effort_limits
    excess = np.maximum(usage - 0.5, 0.0)
    assert excess.max() > 0.0 and (excess == 0.0).any()  # both sides of the threshold are met
    expected = 0.25 * float(excess @ excess)
    assert linearization.objective - without.linearize(q, lam).objective == pytest.approx(expected, rel=1e-12)


def test_deformable_forces_derivative_includes_the_rotating_normals(linearised_problems):
    """With ``traction``, dropping eq. (63)'s first term would break the FD match."""
    label, problem, q, lam = next(c for c in linearised_problems if "traction" in c[0])
    index = next(i for i, c in enumerate(problem.contacts) if c.kind == "deformable")
    contact, own = problem.contacts[index], lam[problem.variable_slices[index]]
    model, data = problem.robot.model, problem.data

    def forces(x):
        problem.linearize(x, lam)
        return contact.forces(model, data, own).reshape(-1).copy()

    numeric = _central_difference(forces, q, model, model.nv)
    problem.linearize(q, lam)
    analytic = contact.force_jacobians(model, data, own)[0]
    # Row by row, as every constraint row above: 2e-5 of the row's own size, plus 1e-10
    # absolute (the traction forces pass through no iterative solve: no repeat noise).
    error = np.abs(numeric - analytic).max(axis=1)
    assert np.all(error <= 2e-5 * np.abs(analytic).max(axis=1) + 1e-10), error.max()


def test_coupled_prints_move_each_other(linearised_problems):
    """Two soles on one block: one sole's node forces depend on the other sole's load."""
    label, problem, q, lam = next(c for c in linearised_problems if c[0].startswith("coupled") and "coulomb" in c[0])
    index = next(i for i, c in enumerate(problem.contacts) if c.kind == "deformable")
    contact, own = problem.contacts[index], lam[problem.variable_slices[index]]
    assert len(contact.prints) == 2 and contact.n_variables == 12
    problem.linearize(q, lam)
    d_forces_dw = contact.force_jacobians(problem.robot.model, problem.data, own)[1].reshape(-1, 3, 12)
    first = contact.print_of_node == 0
    own_block = np.abs(d_forces_dw[first][:, :, :6]).max()
    cross_block = np.abs(d_forces_dw[first][:, :, 6:]).max()
    # The blocks are 0.2 m apart on a 0.1 m thick block: weak but real coupling.
    assert 1e-4 * own_block < cross_block < own_block


def test_every_cost_term_gradient_matches_finite_differences(linearised_problems):
    """Each cost piece of stances.terms on its own, in q and in lambda."""
    seen = set()
    for label, problem, q, lam in linearised_problems:
        model = problem.robot.model
        for term in problem.costs:

            def value(x, y, term=term):
                return term.evaluate(problem, problem.iterate(x, y, derivatives=False))[0]

            _, gradient, _ = term.evaluate(problem, problem.iterate(q, lam))
            if np.abs(gradient).max() > 0.0:
                seen.add(type(term).__name__)  # exercised, not only present
            numeric_q = np.array([
                (value(pin.integrate(model, q, e), lam) - value(pin.integrate(model, q, -e), lam)) / (2 * EPS)
                for e in EPS * np.eye(model.nv)
            ])
            numeric_lam = np.array([
                (value(q, lam + e) - value(q, lam - e)) / (2 * EPS) for e in EPS * np.eye(problem.n_variables)
            ])
            numeric = np.concatenate([numeric_q, numeric_lam])
            size = max(np.abs(gradient).max(), 1e-8)
            error = np.abs(numeric - gradient).max()
            assert error <= 1e-5 * max(size, 1.0), f"{label}: {type(term).__name__} off by {error:.3g}"
    assert {"PostureCost", "TorqueUsageCost", "ForceCost", "ContactCosts"} <= seen


def test_every_variable_curvature_matches_finite_differences(linearised_problems):
    """Each block's curvature in the force variables (``variable_curvature``: the Coulomb
    forces' through static equilibrium and the torques) against central differences, in the
    variables, of the weighted rows' Jacobian; the soft Coulomb palm's is no zero one."""
    curved = []
    for label, problem, q, lam in linearised_problems:
        nv = problem.robot.model.nv
        blocks = {block.name: block for block in problem.linearize(q, lam).blocks}
        rng = np.random.default_rng(11)
        for name, block in blocks.items():
            if block.variable_curvature is None:
                continue
            weights = rng.normal(size=len(block))
            analytic = block.variable_curvature(weights)[nv:, nv:]
            step = 1e-4
            columns = []
            for j in range(problem.n_variables):
                moved = [lam.copy(), lam.copy()]
                moved[0][j] += step
                moved[1][j] -= step
                gradients = [weights @ {b.name: b for b in problem.linearize(q, x).blocks}[name].jacobian[:, nv:] for x in moved]
                columns.append((gradients[0] - gradients[1]) / (2 * step))
            numeric = np.column_stack(columns)
            scale = max(np.abs(numeric).max(), 1e-9)
            assert np.abs(analytic - numeric).max() <= 1e-4 * scale, (label, name, np.abs(analytic - numeric).max(), scale)
            curved.append((label, name, scale))
    assert any("coulomb" in label and scale > 1e-3 for label, _, scale in curved), curved
