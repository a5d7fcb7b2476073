"""A rigid contact polygon hanging over its surface's edge is held by the part on the
surface only (``stances.contacts.supported_vertices``), and verify refuses forces that
act past the edge."""

from __future__ import annotations

import re

import numpy as np
import pytest

import environments
import stances
import stances.contacts
from environments import Contact, ContactPrint, Stance
from stances import StanceError
from stances.contacts import supported_vertices

SQUARE = np.array([[-0.05, -0.03, 0.0], [0.05, -0.03, 0.0], [0.05, 0.03, 0.0], [-0.05, 0.03, 0.0]])
TABLE_EDGE = 0.35  # world x of hand-on-table's near table edge, metres


def test_a_polygon_on_its_support_is_kept_as_it_is():
    support = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    assert supported_vertices(SQUARE, support, "palm") is SQUARE


def test_a_polygon_over_an_edge_keeps_the_part_on_the_support():
    support = np.array([[0.02, -1.0], [1.0, -1.0], [1.0, 1.0], [0.02, 1.0]])  # edge at x = 0.02
    clipped = supported_vertices(SQUARE, support, "palm")
    expected = {(0.02, -0.03), (0.05, -0.03), (0.05, 0.03), (0.02, 0.03)}
    assert {tuple(np.round(v[:2], 12)) for v in clipped} == expected and np.all(clipped[:, 2] == 0.0)
    # An edge through two vertices gives no repeated vertex.
    on_edge = np.array([[0.05, -1.0], [1.0, -1.0], [1.0, 1.0], [0.05, 1.0]])
    with pytest.raises(StanceError, match=re.escape(
            "palm: the robot's polygon and the surface overlap in less than a triangle; move the print onto the surface")):
        supported_vertices(SQUARE, on_edge, "palm")


def _hanging_stance(scenario, x):
    """hand-on-table with the right palm's print at x on the table top (its near edge at x = -0.3)."""
    return Stance(tuple(
        c if c.robot_surface != "right_palm" else Contact("right_palm", ContactPrint("table_top", x, 0.0, 0.0))
        for c in scenario.stance("hand-on-table").contacts
    ))


def _palm_points(result):
    return np.array([p.point for p in result.point_forces if p.point[2] > 0.5])


def test_a_palm_hanging_over_the_table_edge_is_held_on_the_table_only(robot):
    """The palm's back 4 cm hang past the edge: its forces act at the edge and forward."""
    scenario = environments.load("hand-on-table")
    result = stances.solve(robot, scenario.scene, _hanging_stance(scenario, -0.29))
    assert result.feasible, result.reason
    points = _palm_points(result)
    assert len(points) == 4 and points[:, 0].min() == pytest.approx(TABLE_EDGE, abs=1e-6)
    assert result.verification.measures["support overhang of right_palm on table_top"] <= 1e-6


def test_verify_refuses_forces_that_act_past_the_edge(robot, monkeypatch):
    """The posture solved with the whole palm bearing (as before the clipping) puts
    its back forces 4 cm past the edge; verify says so."""
    scenario = environments.load("hand-on-table")
    stance = _hanging_stance(scenario, -0.29)
    with monkeypatch.context() as patch:
        patch.setattr(stances.contacts, "supported_vertices", lambda vertices, support, label: vertices)
        whole = stances.solve(robot, scenario.scene, stance, )
    assert _palm_points(whole)[:, 0].min() == pytest.approx(TABLE_EDGE - 0.04, abs=1e-6)
    verification = stances.verify(robot, scenario.scene, stance, whole)
    assert not verification.ok
    assert any(re.fullmatch(r"a force of right_palm on table_top acts 0\.04\d* m past the edge of its surface", r)
               for r in verification.reasons), verification.reasons


@pytest.mark.parametrize("yaw_deg, x, y, theta_deg, corners", [
    (0.0, -0.28, 0.0, 30.0, 4),     # turned palm over the near edge: two corners cut off
    (0.0, -0.28, 0.37, 30.0, 5),    # turned palm over a corner: five vertices
    (0.0, -0.27, 0.38, 45.0, 6),    # and six
    (30.0, -0.28, 0.0, 90.0, 4),    # turned table, palm across its edge
])
def test_forces_of_a_turned_palm_over_an_edge_act_on_the_table(robot, yaw_deg, x, y, theta_deg, corners):
    """Every force point of the answer lies on the table top, measured in the table's own
    frame from its centre and yaw (not through the library's surface frames)."""
    text = environments.builtin_scenario_path("hand-on-table").read_text()
    text = text.replace("center: [0.65, -0.25, 0.4]}", f"center: [0.65, -0.25, 0.4], yaw_deg: {yaw_deg}}}")
    scenario = environments.load_string(text, name="hand-on-table")
    stance = Stance(tuple(
        c if c.robot_surface != "right_palm"
        else Contact("right_palm", ContactPrint("table_top", x, y, np.radians(theta_deg)))
        for c in scenario.stance("hand-on-table").contacts
    ))
    result = stances.solve(robot, scenario.scene, stance)
    assert result.feasible, result.reason
    points = _palm_points(result)
    assert len(points) == corners
    yaw = np.radians(yaw_deg)
    in_table = (points[:, :2] - [0.65, -0.25]) @ np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    assert np.all(np.abs(in_table) <= np.array([0.3, 0.4]) + 1e-7) and np.allclose(points[:, 2], 0.8, atol=1e-7)
    # The palm does hang over: some of its points lie on an edge of the top.
    assert np.isclose(np.abs(in_table), [0.3, 0.4], atol=1e-6).any()
