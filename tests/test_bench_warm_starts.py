"""The warm-start benchmark's oracle records each attempt, and its counts read them right."""

from __future__ import annotations

import types

import numpy as np
import pytest

import environments
from cbm.planner import StanceCheck
from conftest import bench_module

WARM_STARTS = bench_module("bench_warm_starts")


@pytest.fixture
def oracle(monkeypatch, robot):
    """A recording oracle on ``stand`` whose solver fails from the posture ``q_fails``
    (7 iterations) and succeeds from any other (4 iterations)."""
    scenario = environments.load("stand")
    q_fails = np.full(robot.model.nq, 0.5)

    def solve(robot, scene, stance, q_init=None, **options):
        fails = np.array_equal(q_init, q_fails)
        return types.SimpleNamespace(feasible=not fails, reason="fails" if fails else "", iterations=7 if fails else 4,
                                     verification=types.SimpleNamespace(ok=True, reasons=()))

    monkeypatch.setattr("cbm.planner.posture_api", lambda: (solve, None))
    recording = WARM_STARTS.RecordingOracle(robot, scenario.scene, prefilter=False)
    return recording, scenario.stance("stand"), q_fails


def test_a_failed_warm_attempt_and_its_cold_retry_are_recorded_in_order(oracle):
    recording, stance, q_fails = oracle
    parent = StanceCheck(True, "", types.SimpleNamespace(q=q_fails))
    assert recording(stance, parent_check=parent).feasible
    assert recording(stance).feasible  # no parent: one cold attempt
    assert [(warm, [(feasible, iterations) for feasible, _, iterations in attempts])
            for warm, attempts in recording.calls] == [(True, [(False, 7), (True, 4)]), (False, [(True, 4)])]
    assert all(cpu >= 0.0 for _, attempts in recording.calls for _, cpu, _ in attempts)


def test_counts_of_attempts():
    calls = [(False, [(True, 0.5, 3)]), (True, [(True, 0.25, 5)]), (True, [(False, 1.0, 20), (True, 0.5, 9)]),
             (True, [(False, 2.0, 30), (False, 1.0, 15)]), (True, [(False, 0.5, 10)])]
    assert WARM_STARTS.count_attempts(calls) == {
        "calls": 5, "warm": 4, "warm_ok": 1, "retry_ok": 1, "retry_failed": 1, "failed_warm_cpu": 3.5,
        "failed_warm_iterations": 60}
