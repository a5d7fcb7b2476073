"""The contact-history benchmark records the solves a plan made with held slips, and tallies them right."""

from __future__ import annotations

import types

from conftest import bench_module

HISTORY = bench_module("bench_history")


def _answer(feasible, held=True, iterations=3, warm=2):
    return types.SimpleNamespace(feasible=feasible, held_slips={"right_palm": object()} if held else {},
                                 iterations=iterations, statistics={"rigid_warm_start_iterations": warm})


def test_only_solves_with_a_history_that_held_slips_are_recorded(monkeypatch):
    answers = {"first": _answer(True, held=False), "kept": _answer(True), "kept, nothing held": _answer(True, held=False)}

    def solve(robot, scene, stance, **options):
        return answers[stance]

    def plan(scenario, robot=None, seed=0, time_limit=60.0):
        solve_now, _ = HISTORY.cbm.planner.posture_api()
        solve_now(None, None, "first")
        solve_now(None, None, "kept", history=answers["first"])
        solve_now(None, None, "kept, nothing held", history=answers["first"])

    monkeypatch.setattr("cbm.planner.posture_api", lambda: (solve, None))
    monkeypatch.setattr(HISTORY.cbm, "plan", plan)
    calls = HISTORY.recorded_solves(None, 0, 60.0)
    assert [args[2] for args, _ in calls] == ["kept"]
    assert calls[0][1]["history"] is answers["first"]
    # The planner's own lookup is given back afterwards.
    assert HISTORY.cbm.planner.posture_api()[0] is solve


def test_tally_counts_verdicts_times_and_iterations():
    pairs = [((_answer(True), 0.5, 10), (_answer(True), 0.25, 8)),
             ((_answer(False), 1.5, 40), (_answer(True), 0.5, 9)),
             ((_answer(True), 0.25, 5), (_answer(False), 2.0, 30))]
    counts = HISTORY.tally(pairs)
    assert counts["verdicts"] == {(True, True): 1, (False, True): 1, (True, False): 1}
    assert counts["cpu"] == {"kept": 2.25, "rest": 2.75}
    assert counts["longest"] == {"kept": 1.5, "rest": 2.0}
    assert counts["slow"] == {"kept": 1, "rest": 1}
    assert counts["iterations"] == {"kept": 55, "rest": 47}
    assert HISTORY.row("turn", counts) == "| turn | 3 | 1 | 1 | 1 | 0 | 2.2 / 2.8 | 1.50 / 2.00 | 1 / 1 | 55 / 47 |"


def test_a_timed_solve_counts_its_warm_starts_iterations():
    answer, cpu, iterations = HISTORY.timed(lambda *args, **kwargs: _answer(True, iterations=4, warm=6), (), {})
    assert answer.feasible and cpu >= 0.0 and iterations == 10
