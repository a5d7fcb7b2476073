"""Very high friction on a soft support: a posture with no contact state is stepped around or
refused, never raised.

With mu = 50 a node's normal force can fall toward zero while its friction stays: at some
motions the discrete Signorini-Coulomb problem has no state the active set finds
(``fem.ContactStateError``). A probe of every built-in soft stance at mu = 20-50 met it in
three scenarios, where ``stances.solve`` raised it from a line search's trial.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import environments
import fem
import fem.contact
import stances
import stances.deformable
from cbm.rejections import cause_of
from stances.stages import NO_CONTACT_STATE


def _with_soft_friction(name: str, friction: float, resolution: str = "0.04"):
    """A built-in scenario on coarse meshes, its soft surfaces' friction set to ``friction``."""
    text = environments.builtin_scenario_path(name).read_text().replace("resolution: default",
                                                                         f"resolution: {resolution}")
    soft = [n for n, s in environments.load_string(text, name=name).scene.surfaces.items() if s.deformable]
    data = yaml.safe_load(text)
    data["surfaces"] = {n: {"friction": float(friction)} for n in soft}
    return environments.load_string(yaml.safe_dump(data, sort_keys=False), name=name)


@pytest.fixture
def lost_states(monkeypatch):
    """Counts the contact solves that found no state (and raised) during a test."""
    lost = []
    solve = fem.contact.PrintContactSystem.solve

    def counted(self, *args, **kwargs):
        try:
            return solve(self, *args, **kwargs)
        except fem.ContactStateError:
            lost.append(self.mu.max())
            raise

    monkeypatch.setattr(fem.contact.PrintContactSystem, "solve", counted)
    return lost


def test_a_line_search_steps_around_motions_without_a_contact_state(robot, lost_states):
    """foot-and-hand-on-foam at mu = 50 on the soft step: two of the line search's trials have
    no contact state; the solve cuts those steps and answers, balanced and verified, every
    node pushing within its cone (the stance raised FemError before)."""
    scenario = _with_soft_friction("foot-and-hand-on-foam", 50.0)
    result = stances.solve(robot, scenario.scene, scenario.stance("foot-and-hand"))
    assert lost_states and set(lost_states) == {50.0}
    assert result.feasible, result.reason
    assert result.verification.ok


def test_a_start_without_a_contact_state_is_an_answer_with_its_reason(robot, monkeypatch):
    """Where a stage must start from a posture whose contact has no state, the stance is
    refused with that reason (a soft support's cause), not raised."""
    def stateless(self, imposed, turns=None):
        raise fem.ContactStateError("the print's contact did not settle (a test's)")

    monkeypatch.setattr(stances.deformable.DeformableContact, "_contact", stateless)
    scenario = _with_soft_friction("foot-and-hand-on-foam", 0.7)
    result = stances.solve(robot, scenario.scene, scenario.stance("foot-and-hand"))
    assert not result.feasible
    assert result.statistics["status"] == NO_CONTACT_STATE
    assert result.reason == f"{NO_CONTACT_STATE}: the print's contact did not settle (a test's)"
    assert cause_of(result.reason) == "soft support (indentation, strain, contact)"
    assert np.all(np.isfinite(result.q)) and result.iterations == 0


def test_hand_on_coarse_cubes_palm_holds_from_mu_2_to_10(robot):
    """hand-on-coarse-cube's palm from mu = 2 to 10: Coulomb's first stage, modes read at every
    step from the rigid answer's loads, stalled after 4-5 iterations at mu = 3, 5 and 7 (a
    violation of 1) and the stance was refused, though held at 2.5, 4 and 10; a first stage
    stopped that early goes on with the modes held from its start, as one cut short near a
    solution does."""
    for friction in (2.0, 3.0, 5.0, 7.0, 10.0):
        scenario = _with_soft_friction("hand-on-coarse-cube", friction)
        result = stances.solve(robot, scenario.scene, scenario.stance("hand-on-cube"))
        assert result.feasible and result.verification.ok, (friction, result.reason)
