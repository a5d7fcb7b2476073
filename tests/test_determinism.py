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
