"""Same input, same output, bit for bit: in one process and in fresh processes."""

from __future__ import annotations

import os
import subprocess
import sys

from conftest import fingerprint

SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from conftest import coarse_scenario, fingerprint
import stances
robot = stances.Robot.load("talos")
scenario = coarse_scenario("hand-on-cube")
print(*fingerprint(stances.solve(robot, scenario.scene, scenario.stance("hand-on-cube"))))
"""


def test_a_soft_stance_solved_twice_in_one_process_is_identical(robot):
    import stances
    from conftest import coarse_scenario

    scenario = coarse_scenario("hand-on-cube")
    first = stances.solve(robot, scenario.scene, scenario.stance("hand-on-cube"))
    second = stances.solve(robot, scenario.scene, scenario.stance("hand-on-cube"))
    assert first.feasible
    assert fingerprint(first) == fingerprint(second)


def test_a_soft_stance_solved_in_two_fresh_processes_is_identical():
    tests = os.path.dirname(__file__)
    code = SCRIPT.format(tests=tests)
    outputs = [
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300).stdout.strip()
        for _ in range(2)
    ]
    assert outputs[0].startswith("True")
    assert outputs[0] == outputs[1]


CURVATURE_SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from conftest import fingerprint
import environments, stances
robot = stances.Robot.load("talos")
scenario = environments.load("hand-on-table")
result = stances.solve(robot, scenario.scene, scenario.stances["hand-on-table"], constraint_curvature=True)
print(*fingerprint(result), result.statistics["curvature_iterations"])
"""


def test_a_solve_with_constraint_curvature_in_two_fresh_processes_is_identical():
    """The curvature's finite differences and bounds run the same arithmetic in every process."""
    code = CURVATURE_SCRIPT.format(tests=os.path.dirname(__file__))
    outputs = [
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300).stdout.strip()
        for _ in range(2)
    ]
    assert outputs[0].startswith("True")
    assert int(outputs[0].split()[-1]) > 0  # the curvature was used
    assert outputs[0] == outputs[1]
