"""Pictures, meshes, viewer page and command line, on a synthetic plan over a real scene and robot."""

import json
import shutil
import subprocess

import numpy as np
import pytest

import environments
import stances

from cbm.cli import DEFAULT_SCENARIO, main
from cbm.display import robot_segments
from cbm.output import write_outputs
from cbm.plan import Plan, PlannedStance, PlanStatistics


def chromium_binary():
    return shutil.which("chromium") or shutil.which("chromium-browser")


def page_status(path, tmp_path):
    """The page's body data-status after loading in headless Chromium."""
    command = [
        chromium_binary(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'chromium'}",
        "--virtual-time-budget=5000", "--dump-dom", path.resolve().as_uri(),
    ]
    dom = subprocess.run(command, capture_output=True, text=True, timeout=60).stdout
    start = dom.find("<body")
    assert start >= 0, f"no <body> in Chromium's dump: {dom[:300]!r}"
    body = dom[start: dom.find(">", start)]
    marker = 'data-status="'
    return body[body.find(marker) + len(marker):].split('"')[0] if marker in body else None


@pytest.fixture(scope="module")
def robot():
    return stances.Robot.load("talos")


@pytest.fixture(scope="module")
def scenario():
    return environments.load("cross-soft-block")


@pytest.fixture(scope="module")
def synthetic_plan(robot, scenario):
    """Four stances of the scenario with made-up postures, forces and a dent in the foam."""
    foam = scenario.scene.deformable_objects[0]
    nodes = np.asarray(foam.mesh.nodes)
    planned = []
    for index, name in enumerate(["start", "right-on-foam", "both-on-foam", "beyond"]):
        stance = scenario.stances[name]
        q = np.array(robot.reference_configuration)
        q[0] += 0.3 * index
        forces = [
            {"frame": robot.surfaces[c.robot_surface].frame, "point": scenario.scene.print_origin_in_world(c),
             "force": [0.0, 0.0, 450.0]}
            for c in stance
        ]
        u = np.zeros_like(nodes)
        u[:, 2] = -0.004 * index * np.exp(-(nodes[:, 0] ** 2 + nodes[:, 1] ** 2) / 0.02)
        planned.append(PlannedStance(stance, q, forces, {"foam": u}, None, move="" if index == 0 else f"move {index}"))
    return Plan(True, "goal reached", planned, PlanStatistics(expanded=3), "cross-soft-block")


def test_stick_figure_segments_join_each_joint_to_its_parent(robot):
    q = np.array(robot.reference_configuration)
    segments = robot_segments(robot.model, q)
    # Every joint but the free flyer has one segment to its parent.
    assert segments.shape == (robot.model.njoints - 2, 2, 3)
    moved = q.copy()
    moved[:3] += [1.0, -2.0, 0.5]
    np.testing.assert_allclose(robot_segments(robot.model, moved), segments + [1.0, -2.0, 0.5], atol=1e-12)


def test_outputs_write_every_file(synthetic_plan, scenario, robot, tmp_path):
    files = write_outputs(synthetic_plan, scenario, robot, tmp_path / "out")
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    expected = ["plan.json", "viewer.html"] + [f"stance_{i:02d}.png" for i in range(4)]
    expected += [f"stance_{i:02d}_foam.vtu" for i in range(4)]
    assert names == sorted(expected)
    assert all(p.stat().st_size > 0 for p in files.all())
    assert Plan.load(files.plan).to_dict() == synthetic_plan.to_dict()
    with open(files.pictures[0], "rb") as stream:
        assert stream.read(8) == b"\x89PNG\r\n\x1a\n"
    import meshio

    mesh = meshio.read(files.meshes[2])
    np.testing.assert_allclose(mesh.point_data["displacement"], synthetic_plan.stances[2].deformations["foam"])


def test_viewer_page_is_self_contained_and_embeds_every_stance(synthetic_plan, scenario, robot, tmp_path):
    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    page = files.viewer.read_text()
    assert "http://" not in page and "https://" not in page and "<script src" not in page
    start = page.index('type="application/json">') + len('type="application/json">')
    data = json.loads(page[start: page.index("</script>", start)])
    assert len(data["stances"]) == 4
    dent = max(max(d["magnitude"]) for d in data["stances"][3]["deformables"])
    assert dent == pytest.approx(0.012, rel=1e-3)
    assert {p["robot_surface"] for p in data["stances"][1]["polygons"]} == {"left_sole", "right_sole"}
    assert data["stances"][0]["forces"] and data["stances"][0]["segments"]


@pytest.mark.skipif(chromium_binary() is None, reason="chromium is not installed (apt-get install chromium)")
def test_viewer_page_draws_without_errors_in_headless_chromium(synthetic_plan, scenario, robot, tmp_path):
    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    assert page_status(files.viewer, tmp_path) == "ok"


@pytest.mark.skipif(chromium_binary() is None, reason="chromium is not installed (apt-get install chromium)")
def test_viewer_reports_a_script_error_in_its_status(synthetic_plan, scenario, robot, tmp_path):
    # The check must be able to fail: break the page's data and expect an error status.
    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    page = files.viewer.read_text().replace('"stances":[', '"stances":[{"label":"broken"},', 1)
    broken = tmp_path / "broken.html"
    broken.write_text(page)
    status = page_status(broken, tmp_path)
    assert status is not None and status.startswith("error:")


def test_cli_lists_scenarios_with_descriptions(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    assert DEFAULT_SCENARIO in out and "climb-with-soft-support" in out
    assert "foam" in out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["plan", "no-such-scenario", "--out", "x"], "built-in scenarios: climb-with-soft-support"),
        (["plan", "--max-expansions", "-1"], "non-negative integer"),
        (["plan", "--print-spacing", "0"], "positive number"),
        (["check", "cross-soft-block", "--stance", "flying"], "stances: beyond, both-on-foam"),
        (["check", "no-such-scenario", "--stance", "start"], "unknown scenario"),
        (["frobnicate"], "invalid choice"),
    ],
    ids=["unknown-scenario", "negative-expansions", "zero-spacing", "unknown-stance", "check-unknown", "bad-command"],
)
def test_cli_bad_input_exits_2_and_names_the_problem(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_cli_bad_scenario_file_exits_2(tmp_path, capsys):
    path = tmp_path / "broken.yaml"
    path.write_text("robot: talos\nobjects: 3\n")
    assert main(["plan", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "broken.yaml" in capsys.readouterr().err
