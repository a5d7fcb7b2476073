"""Parallel expansions: the same search, and the same plan, whatever the number of workers."""

import dataclasses
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace


import numpy as np
import pytest

import environments

from cbm.cli import main
from cbm.errors import CbmError
from cbm.planner import StanceCheck, plan
from cbm.search import best_first_search

# A 5 x 5 grid from (0, 0) to (4, 4); some cells cannot be held.
BLOCKED = {(1, 1), (2, 1), (1, 3), (3, 2), (2, 3), (3, 3)}


def grid_neighbours(node):
    x, y = node
    steps = [(x + 1, y), (x, y + 1), (x - 1, y), (x, y - 1)]
    return [(n, f"{node}->{n}") for n in steps if 0 <= n[0] <= 4 and 0 <= n[1] <= 4]


class WarmStartedOracle:
    """Answer depends on the node and on the parent's answer (as a warm start does)."""

    def __call__(self, node, parent, parent_result):
        warm = 0.0 if parent_result is None else parent_result.value
        return SimpleNamespace(feasible=node not in BLOCKED, value=0.5 * warm + node[0] + 10 * node[1], parent=parent)


def search(**options):
    return best_first_search(
        (0, 0),
        neighbours=grid_neighbours,
        oracle=WarmStartedOracle(),
        heuristic=lambda n: float(8 - n[0] - n[1]),
        is_goal=lambda n: n == (4, 4),
        path_cost_weight=1.0,
        shuffle_neighbours=True,
        seed=3,
        **options,
    )


def answer_cost(node, answer):
    """A node cost read from the answer, as the planner's terrain cost is (0 on a third of the nodes)."""
    return 0.7 * (answer.value % 3.0)


@pytest.mark.parametrize("node_cost", [None, answer_cost], ids=["no-node-cost", "node-cost"])
@pytest.mark.parametrize("eager", [False, True], ids=["lazy", "eager"])
@pytest.mark.parametrize("lookahead", [1, 2, 5])
def test_search_solving_ahead_consumes_the_answers_a_serial_search_computes(lookahead, eager, node_cost):
    serial = search(eager=eager, node_cost=node_cost)
    oracle = WarmStartedOracle()
    with ThreadPoolExecutor(2) as pool:
        ahead = search(
            eager=eager, node_cost=node_cost, submit=lambda *args: pool.submit(oracle, *args), lookahead=lookahead
        )
    assert serial.success and ahead.success
    assert ahead.path == serial.path
    assert ahead.statistics.requeued == serial.statistics.requeued
    assert [(r.value, r.parent) for r in ahead.results] == [(r.value, r.parent) for r in serial.results]
    assert ahead.statistics.solver_calls == serial.statistics.solver_calls
    assert ahead.statistics.expanded == serial.statistics.expanded


def test_search_refuses_a_lookahead_that_is_not_a_positive_integer():
    with pytest.raises(CbmError, match="lookahead must be a positive integer with submit, got 0"):
        search(submit=lambda *args: None, lookahead=0)


# One step forward on a floor: lift a foot, place it 0.2 m ahead, lift the
# other, place it: small, rigid, but it has infeasible candidates.
STEP = """
robot: talos
objects:
  - {name: floor, type: floor}
stances:
  start:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
start: start
goal:
  regions:
    - {robot_surface: left_sole, lower: [0.15, -0.5], upper: [0.5, 0.5]}
    - {robot_surface: right_sole, lower: [0.15, -0.5], upper: [0.5, 0.5]}
options:
  print_spacing: 0.1
  theta_values_deg: [0]
  sampling_region: {lower: [-0.1, -0.3], upper: [0.3, 0.3]}
  robot_surfaces: [left_sole, right_sole]
"""


@pytest.fixture(scope="module")
def step_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("parallel") / "step.yaml"
    path.write_text(STEP)
    return path


def test_plan_is_the_same_bit_for_bit_with_one_and_two_workers(step_file):
    options = dict(max_expansions=20, time_limit=200.0, solver_options={"max_iterations": 40}, seed=1)
    serial = plan(step_file, **options)
    parallel = plan(step_file, workers=2, **options)
    assert serial.success and parallel.success
    # The plan's CPU counts the workers' solves, not only this process's waiting.
    assert parallel.statistics.cpu_time > 0.5 * serial.statistics.cpu_time
    assert [s.stance for s in parallel.stances] == [s.stance for s in serial.stances]
    for a, b in zip(serial.stances, parallel.stances):
        assert np.array_equal(a.q, b.q)
        assert [p.frame for p in a.point_forces] == [p.frame for p in b.point_forces]
        assert all(np.array_equal(p.force, r.force) for p, r in zip(a.point_forces, b.point_forces))
    assert parallel.statistics.solver_calls == serial.statistics.solver_calls


def test_workers_need_a_positive_integer(step_file):
    with pytest.raises(CbmError, match=r"workers must be a positive integer \(1: no worker process\), got 0"):
        plan(step_file, workers=0)


def test_workers_refuse_a_custom_oracle(step_file):
    with pytest.raises(CbmError, match="a custom oracle= needs workers=1"):
        plan(step_file, workers=2, oracle=lambda stance, parent, check: StanceCheck(True, ""))


def test_workers_refuse_a_scenario_built_in_code(step_file):
    scenario = environments.load(step_file)
    built = dataclasses.replace(scenario, text=None)
    with pytest.raises(CbmError, match="workers > 1 needs a scenario read from YAML"):
        plan(built, workers=2)


def test_cli_rejects_zero_workers(capsys):
    assert main(["plan", "stand", "--workers", "0"]) == 2
    assert "expected a positive integer, got '0'" in capsys.readouterr().err


def test_closing_a_pool_whose_terminate_hangs_kills_its_workers_and_returns(monkeypatch):
    """multiprocessing's terminate can wait for good on a lock a killed worker held (seen
    once in CI); close waits for it only so long, then kills the workers itself."""
    import cbm.parallel as parallel

    class Worker:
        killed = False

        def kill(self):
            self.killed = True

    class HangingPool:
        def __init__(self):
            self._pool = [Worker(), Worker()]
            self.release = threading.Event()

        def terminate(self):
            self.release.wait()

        def join(self):
            pass

    monkeypatch.setattr(parallel, "_TERMINATE_WAIT", 0.2)
    pool = object.__new__(parallel.PosturePool)
    pool._pool = HangingPool()
    started = time.perf_counter()
    pool.close()
    assert time.perf_counter() - started < 2.0
    assert all(worker.killed for worker in pool._pool._pool)
    pool._pool.release.set()  # let the stand-in's thread end
    # A terminate that returns kills nothing.
    quick = object.__new__(parallel.PosturePool)
    quick._pool = HangingPool()
    quick._pool.release.set()
    quick.close()
    assert not any(worker.killed for worker in quick._pool._pool)
