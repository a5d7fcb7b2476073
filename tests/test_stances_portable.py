"""Results crossing a process boundary keep every value and get their displacement fields back."""

import pickle

import numpy as np

import environments
import stances
from stances.portable import portable, restore_deformations


def test_a_soft_result_pickles_and_gets_the_same_fields_back(robot):
    scenario = environments.load("cross-soft-block")
    result = stances.solve(robot, scenario.scene, scenario.stance("right-on-foam"), max_iterations=40)
    assert result.feasible and list(result.deformations) == ["foam"]
    sent = pickle.loads(pickle.dumps(portable(result)))
    assert dict(sent.deformations) == {}
    assert np.array_equal(sent.q, result.q)
    restored = restore_deformations(robot, scenario.scene, sent)
    # Built again from q, the forces and the recorded options: the same field, bit for bit.
    assert np.array_equal(restored.deformations["foam"], result.deformations["foam"])
    assert np.abs(result.deformations["foam"]).max() > 1e-4  # the foam does give under the sole


def test_a_rigid_result_has_no_field_to_restore(robot):
    scenario = environments.load("stand")
    result = portable(stances.solve(robot, scenario.scene, scenario.stance("stand")))
    assert dict(restore_deformations(robot, scenario.scene, result).deformations) == {}
