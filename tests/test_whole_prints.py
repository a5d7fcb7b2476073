"""A sole or palm on a soft body presses with its whole face (``corner_sinking``,
``max_corner_lift``).

A print pivoting on its edge presses a strip narrower than the mesh resolves: an
independent audit found five palms on their edge 6.7-16.4 % below a converged mesh's
force for the same motion (``bench/results/audit-done-when-2026-12-05.md``). The solver
sinks every corner of a polygon print at least half its corners' mean sinking (less
``max_corner_lift``), and verify refuses an answer whose print pivots.
"""

import re

import numpy as np
import pinocchio as pin
import pytest

import stances
from cbm.rejections import cause_of, pivoting_print_hint
from conftest import coarse_scenario, solved_stance
from stances.problem import build_problem

CORNER = "highest print corner on cube"
SHORTFALL = "print corner shortfall on cube"


@pytest.fixture(scope="module")
def scenario():
    return coarse_scenario("hand-on-cube")


@pytest.fixture(scope="module")
def pivoting(robot, scenario):
    """hand-on-cube's answer with the palm let pivot (no corner rows, no tilt bound): it
    leans on its edge."""
    return solved_stance(robot, scenario, "hand-on-cube", max_corner_lift=np.inf, tilt_allowance=0.0)


def test_a_palm_let_pivot_leans_on_its_edge_and_verify_refuses_it(robot, scenario, pivoting):
    lifted = pivoting.verification.measures[CORNER]
    assert lifted > 1e-4  # metres: the palm leans on its edge
    # Checked as solved (max_corner_lift inf, recorded in the result) it holds; at the
    # default bound it is refused.
    assert stances.verify(robot, scenario.scene, pivoting.stance, pivoting).ok
    verification = stances.verify(robot, scenario.scene, pivoting.stance, pivoting, max_corner_lift=1e-5)
    assert not verification.ok
    (reason,) = [r for r in verification.reasons if "corner" in r]
    assert re.fullmatch(
        r"a corner of right_palm on cube_top sinks -?[0-9.e-]+ m into cube, less than 0.5 of its print's mean sinking "
        r"\([0-9.e-]+ m\) by [0-9.e-]+ m, beyond max_corner_lift 1e-05 m: the print pivots toward its edge, pressing a "
        r"strip narrower than the mesh resolves \(no converged force: palms on their edge came 7-16 % below a "
        r"converged mesh's; corner_sinking\)", reason), reason
    assert f"{-lifted:.3g} m into cube" in reason
    # A planner whose rejections are mostly this refusal says so.
    assert pivoting_print_hint([f"verification failed: {reason}"]).startswith("; 1 of the 1 stances rejected could not press")
    # A solve that cannot keep the rows names them so; the planner counts them as the soft support's.
    (soft,) = [c for c in build_problem(robot, scenario.scene, pivoting.stance).contacts if c.kind == "deformable"]
    assert soft._labels["corners"] == tuple(f"contact of right_palm on cube_top (corner {j} lifted: pivoting on an edge)"
                                            for j in range(4))
    label = soft._labels["corners"][1]
    assert cause_of(f"{label} violated by 0.001") == "soft support (indentation, strain, contact)"
    assert pivoting_print_hint([f"{label} violated by 0.001", "torque limit of j"]) != ""


def test_by_default_the_palm_presses_with_its_whole_face(robot, scenario, pivoting):
    result = stances.solve(robot, scenario.scene, scenario.stance("hand-on-cube"))
    assert result.feasible and result.verification.ok, result.reason
    assert result.verification.measures[SHORTFALL] <= 1e-5 + 1e-6
    assert result.verification.measures[CORNER] < -1e-4  # every corner down, by a tenth of a millimetre at least
    assert pivoting.verification.measures[SHORTFALL] > 1e-4


def test_every_corner_merely_down_is_not_enough(robot, scenario):
    """With ``corner_sinking=0`` the palm keeps each corner down but leans on one side,
    which the default share refuses: its shallowest corner sinks less than half the mean."""
    down = stances.solve(robot, scenario.scene, scenario.stance("hand-on-cube"), corner_sinking=0.0)
    assert down.feasible, down.reason
    assert down.verification.measures[CORNER] <= 1e-5 + 1e-6
    assert down.verification.measures[SHORTFALL] == down.verification.measures[CORNER]
    verification = stances.verify(robot, scenario.scene, down.stance, down, corner_sinking=0.5)
    assert not verification.ok
    assert any("less than 0.5 of its print's mean sinking" in reason for reason in verification.reasons)


def test_the_corner_heights_are_those_of_the_link_itself(robot, scenario, pivoting):
    """The rows read each corner's height off the nodes' link points (an affine
    combination, exact for a rigid motion): the same as the link's frame placed at q."""
    problem = build_problem(robot, scenario.scene, pivoting.stance)
    (soft,) = [c for c in problem.contacts if c.kind == "deformable"]
    data = problem.data
    pin.forwardKinematics(robot.model, data, np.asarray(pivoting.q))
    pin.updateFramePlacements(robot.model, data)
    heights = np.einsum("pj,pj->p", soft._displacements(data) + soft.gaps, soft.normals_in_body)
    corners = soft._corners @ heights
    surface = robot.surface("right_palm")
    frame = data.oMf[robot.model.getFrameId(surface.frame)]
    placement = soft.print_placements[0]
    expected = (surface.vertices_in_frame @ frame.rotation.T + frame.translation - placement.translation) @ placement.rotation[:, 2]
    assert np.allclose(corners, expected, rtol=0, atol=1e-12)
    assert corners.max() == pytest.approx(pivoting.verification.measures[CORNER], abs=1e-12)
