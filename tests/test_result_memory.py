"""A posture result keeps what draws its soft bodies' fields, not the contacts that solved it.

A search keeps every answer it meets; each soft contact holds its print's dense
compliance, factorisations and strain sets (5-10 MB a solve on a user's rubber mat). Held
through the result's lazy fields, a 300-expansion plan grew to 5.2 GB (a new user's audit,
2026-12-05); the field needs only the body and the point loads on it.
"""

import gc
import weakref

import numpy as np
import pinocchio as pin
import pytest

import stances
from conftest import coarse_scenario
from stances.deformable import DeformableContact
from stances.layer_ball import LayerBalls
from stances.problem import build_problem
from stances.stages import posture_options


@pytest.mark.parametrize("name, stance, kind, options", [
    ("cross-soft-block", "both-on-foam", DeformableContact, {}),
    ("cross-soft-block", "both-on-foam", DeformableContact, {"reaction_model": "traction", "contact_law": "bonded"}),
    ("quadruped-foam", "front-feet-on-foam", LayerBalls, {}),
], ids=["coulomb", "traction", "layer balls"])
def test_a_result_outlives_its_contacts_and_still_draws_its_fields(robot, anymal, monkeypatch, name, stance, kind,
                                                                   options):
    made = []
    original = kind.__init__

    def recorded(self, *args, **kwargs):
        original(self, *args, **kwargs)
        made.append(weakref.ref(self))

    monkeypatch.setattr(kind, "__init__", recorded)
    scenario = coarse_scenario(name)
    solver_robot = anymal if scenario.robot == "anymal" else robot
    result = stances.solve(solver_robot, scenario.scene, scenario.stance(stance), **options)
    assert result.feasible, result.reason
    assert made, f"no {kind.__name__} was built: this stance no longer tests it"
    gc.collect()
    assert [ref() for ref in made] == [None] * len(made)  # none kept alive by the result
    (soft,) = scenario.scene.deformable_objects
    field = result.deformations[soft.name]
    assert field.shape == (soft.body.mesh.n_nodes, 3) and np.abs(field).max() > 1e-5  # pressed in
    # The contact's own field under the result's forces, from a problem built anew: the same bits.
    problem = build_problem(solver_robot, scenario.scene, result.stance, posture_options(options))
    (contact, loads), = [(c, s) for c, s in zip(problem.contacts, problem.load_slices) if c.deformable_object is soft]
    data = pin.Data(solver_robot.model)
    pin.framesForwardKinematics(solver_robot.model, data, result.q)
    forces = np.array([p.force for p in result.point_forces[loads]])
    assert np.array_equal(field, contact.displacement_field(solver_robot.model, data, forces))
