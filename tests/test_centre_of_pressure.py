"""A sole or palm on a soft body keeps its centre of pressure inside its outline.

A partly covered node's force acts at its link point, the node's rest position, up to a
cell past the outline (``fem.ContactPatch``'s coverage): on the built-in and a new user's
stances up to 25 % of a print's load acted up to 13 mm past its edge. The solver keeps each
polygon print's moment of its normal forces about each edge of its outline non-negative,
and verify refuses a centre of pressure past an edge: no pressure under the foot gives it.
"""

import dataclasses
import re

import numpy as np
import pinocchio as pin
import pytest

import stances
from conftest import coarse_scenario, solved_stance
from stances.results import PointForce

MARGIN = "centre of pressure margin on cube"


@pytest.fixture(scope="module")
def scenario():
    return coarse_scenario("hand-on-cube")


@pytest.fixture(scope="module")
def solved(robot, scenario):
    return solved_stance(robot, scenario, "hand-on-cube")


def _palm(robot, result):
    """The palm's reported forces: points in its surface frame (2D), normal components, and
    the outline (counter-clockwise), from the posture itself."""
    surface = robot.surface("right_palm")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, result.q)
    placement = data.oMf[robot.model.getFrameId(surface.frame)]
    pairs = [(placement.rotation.T @ (f.point - placement.translation), placement.rotation.T @ f.force)
             for f in result.point_forces if f.frame == surface.frame]
    points = np.array([p[:2] for p, _ in pairs])
    normal = np.array([f[2] for _, f in pairs])
    outline = np.asarray(surface.vertices_in_frame)[:, :2]
    x, y = outline[:, 0], outline[:, 1]
    if np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) < 0.0:
        outline = outline[::-1]
    return points, normal, outline


def _margin(point, outline) -> float:
    """Metres inside the nearest edge of a counter-clockwise outline (negative outside)."""
    edges = np.roll(outline, -1, axis=0) - outline
    inward = np.stack([-edges[:, 1], edges[:, 0]], axis=1) / np.linalg.norm(edges, axis=1)[:, None]
    return float(np.min(np.einsum("kj,kj->k", point - outline, inward)))


def test_the_margin_verify_reports_is_the_centre_of_pressure_of_the_reported_forces(robot, solved):
    points, normal, outline = _palm(robot, solved)
    assert np.any([_margin(p, outline) < -1e-3 for p in points])  # some forces act past the outline
    centre = normal @ points / normal.sum()
    # The same to the palm's tilt from its print (the rows read the print's normal).
    assert solved.verification.measures[MARGIN] == pytest.approx(_margin(centre, outline), abs=2e-4)
    assert solved.verification.measures[MARGIN] > 0.01  # well inside: the rows do not bind here


def test_a_centre_of_pressure_past_the_outline_is_refused(robot, scenario, solved):
    points, normal, outline = _palm(robot, solved)
    past = np.array([_margin(p, outline) < -1e-3 for p in points])
    # The palm's load moved onto its nodes past the outline (the equilibrium breaks too; the
    # centre of pressure is what is looked for).
    moved, k = [], 0
    for force in solved.point_forces:
        if force.frame == robot.surface("right_palm").frame:
            scale = normal.sum() / normal[past].sum() if past[k] else 0.0
            moved.append(PointForce(force.frame, force.point, scale * np.asarray(force.force)))
            k += 1
        else:
            moved.append(force)
    result = dataclasses.replace(solved, point_forces=tuple(moved))
    verification = stances.verify(robot, scenario.scene, result.stance, result)
    (reason,) = [r for r in verification.reasons if "centre of pressure" in r]
    assert re.fullmatch(r"the centre of pressure of right_palm on cube_top lies [0-9.e-]+ m past its outline's edge: "
                        r"its partly covered nodes' forces, past the edge, carry a moment no pressure under right_palm "
                        r"could", reason), reason
    assert verification.measures[MARGIN] < -1e-3


def test_a_print_carrying_next_to_nothing_reports_no_margin(robot, scenario, solved):
    """A palm pressing a micronewton with its centre of pressure past its edge: within the
    solver's tolerance on the rows' moments (1e-7 N m), so no refusal, and no margin either,
    whose number would be rounding (an audit saw -3.9 mm reported on a verified answer)."""
    points, normal, outline = _palm(robot, solved)
    past = np.array([_margin(p, outline) < -1e-3 for p in points])
    moved, k = [], 0
    for force in solved.point_forces:
        if force.frame == robot.surface("right_palm").frame:
            scale = 1e-6 / normal[past].sum() if past[k] else 0.0
            moved.append(PointForce(force.frame, force.point, scale * np.asarray(force.force)))
            k += 1
        else:
            moved.append(force)
    verification = stances.verify(robot, scenario.scene, solved.stance, dataclasses.replace(solved, point_forces=tuple(moved)))
    assert not [r for r in verification.reasons if "centre of pressure" in r]
    assert MARGIN not in verification.measures
