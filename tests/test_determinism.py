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


DISTANCE_SCRIPT = """
import sys
import coal, numpy as np, pinocchio as pin
import stances
from environments.geometry import CollisionShape
from stances.collision import CollisionChecker
if {prime!r}:
    # Another user of coal in the process asks a box for its support first, along a
    # direction with no zero component (coal 3.0 keeps state from that first call).
    request = coal.DistanceRequest()
    request.gjk_initial_guess = coal.GJKInitialGuess.CachedGuess
    request.cached_gjk_guess = np.array([1.0, 2.0, 3.0])
    coal.distance(coal.Box(1.0, 1.0, 1.0), coal.Transform3s(), coal.Box(1.0, 1.0, 1.0),
                  coal.Transform3s(np.eye(3), np.array([2.0, 0.3, 0.2])), request, coal.DistanceResult())
robot = stances.Robot.load("talos")
cube_to_world = np.eye(4)
cube_to_world[:3, 3] = [0.4, -0.6, 0.45]
cube = CollisionShape(cube_to_world, box_size=(0.8, 0.8, 0.9))
checker = CollisionChecker(robot, [("cube", cube)], margin=1.0, self_collision=True)
data = robot.model.createData()
q = robot.reference_configuration.copy()
q[2] += 0.3
pin.forwardKinematics(robot.model, data, q)
print(*[float(pair.distance).hex() for pair in checker.pairs(robot.model, data)])
"""


def test_distances_do_not_depend_on_an_earlier_box_query_in_the_process():
    """Robot and scene boxes (palm plates, cubes) are measured with no state left by earlier queries."""
    outputs = [
        subprocess.run(
            [sys.executable, "-c", DISTANCE_SCRIPT.format(prime=prime)],
            capture_output=True, text=True, check=True, timeout=300,
        ).stdout.split()
        for prime in (False, True)
    ]
    assert len(outputs[0]) > 20  # hulls to the cube, and palm plates to the arms
    assert outputs[0] == outputs[1]


INFEASIBLE_SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from conftest import fingerprint
import environments, stances
from environments import Contact, ContactPrint, Stance
robot = stances.Robot.load("talos")
scenario = environments.load("stand")
stance = Stance((Contact("left_sole", ContactPrint("floor", 0.0, 0.085, 0.0)),
                 Contact("right_sole", ContactPrint("floor", 3.0, -0.085, 0.0))))
result = stances.solve(robot, scenario.scene, stance, max_iterations=60)
print(*fingerprint(result))
print(result.reason)
"""


def test_an_infeasible_stance_solved_in_two_fresh_processes_gives_the_same_reason():
    """A sole 3 m from the other: the same iterate, the same reason and the same
    conflicting rows in every process (issue 13 found reasons that changed)."""
    code = INFEASIBLE_SCRIPT.format(tests=os.path.dirname(__file__))
    outputs = [
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300).stdout
        for _ in range(2)
    ]
    assert outputs[0].startswith("False")
    assert "; no step meets together: placement of " in outputs[0]
    assert outputs[0] == outputs[1]
