"""Terrain-aware path cost: the energy measure, its weight, and the soft-shortcut scenario's choice."""

import re
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest

import environments
from environments.errors import ScenarioError

from cbm.cli import main
from cbm.errors import CbmError
from cbm.planner import StanceCheck, plan
from cbm.terrain import TerrainCost, deepest_indentation, deformation_energy

SCENARIO = "soft-shortcut"


def on_foam(stance):
    return any(contact.contact_print.surface == "foam_top" for contact in stance)


# ------------------------------------------------------------- the energy measure
def test_measured_energy_is_half_the_displacement_times_the_stiffness_times_it(robot):
    # Clapeyron: 1/2 F.U over the print nodes (the verification's measure, from the
    # forces) equals 1/2 U^T K U of the whole body's field (the solver's eq. 36 field
    # and the assembled stiffness), with K the body's own matrix: two computations.
    import stances

    scenario = environments.load(SCENARIO)
    result = stances.solve(robot, scenario.scene, scenario.stance("right-on-foam"))
    assert result.feasible, result.reason
    body = scenario.scene.deformable_of_surface("foam_top").body
    u = np.asarray(result.deformations["foam"]).ravel()
    strain_energy = 0.5 * u @ (body.stiffness @ u)
    measured = result.verification.measures["deformation energy of foam"]
    assert measured == pytest.approx(strain_energy, rel=1e-6)  # same field, two contractions
    assert deformation_energy(result) == measured
    # One sole carries about half of Talos' weight and sinks a millimetre or two:
    # 1/2 F d with F ~ 450 N, d ~ 1 mm (the deepest node; the mean is less).
    depth = deepest_indentation(result)
    assert 0.0 < measured < 0.5 * 1000.0 * depth
    rigid = stances.solve(robot, scenario.scene, scenario.stance("start"))
    assert deformation_energy(rigid) == 0.0 and deepest_indentation(rigid) == 0.0


def test_energy_needs_a_verified_result():
    with pytest.raises(CbmError, match="this result has none"):
        deformation_energy(SimpleNamespace(verification=None, stance="s"))


# ---------------------------------------------------------------- bad weights
@pytest.mark.parametrize("weight", [-1.0, float("nan"), float("inf"), True], ids=["negative", "nan", "inf", "bool"])
def test_plan_refuses_a_weight_that_is_not_a_finite_non_negative_number(weight):
    message = f"terrain_weight must be a finite number >= 0 (metres of goal distance per joule), got {weight!r}"
    with pytest.raises(CbmError, match=re.escape(message)):
        plan(SCENARIO, terrain_weight=weight)
    with pytest.raises(CbmError, match=re.escape(message)):
        TerrainCost(weight)


def test_cli_reports_a_nan_weight_as_bad_input(tmp_path, capsys):
    assert main(["plan", SCENARIO, "--terrain-weight", "nan", "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert "terrain_weight must be a finite number >= 0 (metres of goal distance per joule), got nan" in (
        capsys.readouterr().err
    )


def test_scenario_option_must_be_a_non_negative_number(tmp_path):
    text = environments.builtin_scenario_path(SCENARIO).read_text().replace("options:\n", "options:\n  terrain_weight: -2\n")
    path = tmp_path / "negative.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=re.escape("options.terrain_weight: must be a number >= 0, metres")):
        environments.load(path)


# ------------------------------------------------- the weight reaches the search
@dataclass(frozen=True)
class FakeResult:
    """A verified posture: 1 J in the foam for each sole on it."""

    q: np.ndarray
    verification: object
    point_forces: tuple = ()
    deformations: dict = field(default_factory=dict)


def energy_oracle(stance, parent, parent_check):
    soles = sum(contact.contact_print.surface == "foam_top" for contact in stance)
    measures = {"deformation energy of foam": float(soles)} if soles else {}
    return StanceCheck(True, "", FakeResult(np.zeros(3), SimpleNamespace(measures=measures)))


@pytest.mark.parametrize(
    "option, weight, effective",
    [(None, None, 0.0), (10.0, None, 10.0), (10.0, 0.0, 0.0), (None, 10.0, 10.0)],
    ids=["default", "option", "argument-overrides-option", "argument"],
)
def test_weight_from_option_or_argument_decides_the_crossing(tmp_path, robot, option, weight, effective):
    # 1 J per sole on the foam: at 10 m of goal distance per joule no stance on it
    # is worth it, as the floor beside it leads to the goal too.
    text = environments.builtin_scenario_path(SCENARIO).read_text()
    if option is not None:
        text = text.replace("options:\n", f"options:\n  terrain_weight: {option}\n")
    path = tmp_path / "case.yaml"
    path.write_text(text)
    planned = plan(path, robot=robot, oracle=energy_oracle, terrain_weight=weight)
    assert planned.success
    assert any(on_foam(s.stance) for s in planned.stances) == (effective == 0.0)
    assert (planned.statistics.requeued > 0) == (effective > 0.0)


# ---------------------------------------------------- the real scenario's choice
@pytest.fixture(scope="module")
def plans(robot):
    """soft-shortcut planned with weight 0 and 10 m/J (serial)."""
    return {weight: plan(SCENARIO, robot=robot, terrain_weight=weight) for weight in (0.0, 10.0)}


def test_weight_zero_crosses_the_foam_and_a_large_weight_goes_around(plans):
    free, careful = plans[0.0], plans[10.0]
    assert free.success and careful.success
    assert any(on_foam(s.stance) for s in free.stances)
    assert not any(on_foam(s.stance) for s in careful.stances)
    free_energy = sum(deformation_energy(s.result) for s in free.stances)
    assert free_energy > 0.0 and all(deformation_energy(s.result) == 0.0 for s in careful.stances)
    # The detour is longer: the terrain cost bought rigid ground with moves.
    assert len(careful.stances) > len(free.stances)
    assert free.statistics.requeued == 0 and careful.statistics.requeued > 0


def test_terrain_plan_is_the_same_bit_for_bit_with_two_workers(plans, robot):
    serial = plans[10.0]
    parallel = plan(SCENARIO, robot=robot, terrain_weight=10.0, workers=2)
    assert [s.stance for s in parallel.stances] == [s.stance for s in serial.stances]
    assert all(np.array_equal(a.q, b.q) for a, b in zip(serial.stances, parallel.stances))
    assert parallel.statistics.solver_calls == serial.statistics.solver_calls
    assert parallel.statistics.requeued == serial.statistics.requeued
