"""Pictures, meshes, viewer page and command line, on a synthetic plan over a real scene and robot."""

import json
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

import environments
import stances
from conftest import coarse_scenario

from cbm.errors import PlanFileError
from cbm.cli import DEFAULT_SCENARIO, main
from cbm.display import robot_segments
from cbm.output import write_outputs
from cbm.plan import PLAN_VERSION, SOLVED_AS, Plan, PlannedStance, PlanStatistics, robot_description, scenario_source


def chromium_binary():
    return shutil.which("chromium") or shutil.which("chromium-browser")


def chromium(tmp_path, *arguments):
    """Headless Chromium's command line, with a private profile."""
    return [
        chromium_binary(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'chromium'}",
        "--virtual-time-budget=5000", *arguments,
    ]


def page_status(path, tmp_path):
    """The page's body data-status after loading in headless Chromium."""
    command = chromium(tmp_path, "--dump-dom", path.resolve().as_uri())
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
    return Plan(
        True, "goal reached", planned, PlanStatistics(expanded=3), "cross-soft-block",
        robot=robot_description(robot), scenario_source=scenario_source(scenario),
    )


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
    expected = ["plan.json", "plan.pvd", "viewer.html"] + [f"stance_{i:02d}.png" for i in range(4)]
    expected += [f"stance_{i:02d}_foam.vtu" for i in range(4)] + [f"stance_{i:02d}_robot.vtu" for i in range(4)]
    assert names == sorted(expected)
    assert all(p.stat().st_size > 0 for p in files.all())
    assert Plan.load(files.plan).to_dict() == synthetic_plan.to_dict()
    with open(files.pictures[0], "rb") as stream:
        assert stream.read(8) == b"\x89PNG\r\n\x1a\n"
    import meshio

    mesh = meshio.read(files.meshes[2])
    foam = scenario.scene.deformable_objects[0]
    np.testing.assert_allclose(mesh.points, foam.points_in_world(foam.mesh.nodes), atol=1e-12)
    rotation = foam.transform_body_to_world[:3, :3]
    np.testing.assert_allclose(
        mesh.point_data["displacement"], synthetic_plan.stances[2].deformations["foam"] @ rotation.T, atol=1e-15
    )


def test_pictures_are_cropped_as_matplotlibs_tight_crop_draws_them(synthetic_plan, scenario, robot, tmp_path,
                                                                     monkeypatch):
    # render._save draws once, its layout pass without the robot's and the foam's
    # triangles; matplotlib's own "tight" crop draws everything twice. Same pixels.
    import matplotlib.pyplot as plt

    from cbm import render

    ours = write_outputs(synthetic_plan, scenario, robot, tmp_path / "ours")
    monkeypatch.setattr(render, "_save", lambda figure, path, heavy: figure.savefig(
        path, bbox_inches="tight", pad_inches=0.15))
    tight = write_outputs(synthetic_plan, scenario, robot, tmp_path / "tight")
    assert len(ours.pictures) == len(tight.pictures) == len(synthetic_plan.stances)
    for mine, reference in zip(ours.pictures, tight.pictures):
        np.testing.assert_array_equal(plt.imread(mine), plt.imread(reference))


def test_pvd_plays_the_plan_one_stance_per_time_step(synthetic_plan, scenario, robot, tmp_path):
    import xml.etree.ElementTree as ElementTree

    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    entries = [e.attrib for e in ElementTree.parse(files.series).getroot().iter("DataSet")]
    assert [(e["timestep"], e["part"], e["file"]) for e in entries] == [
        (str(i), "0", f"stance_{i:02d}_foam.vtu") for i in range(4)
    ] + [(str(i), "1", f"stance_{i:02d}_robot.vtu") for i in range(4)]
    assert all((tmp_path / e["file"]).is_file() for e in entries)


def test_robot_vtu_is_the_robot_at_each_stance_in_world(synthetic_plan, scenario, robot, tmp_path):
    """ParaView overlays robot and soft body: each stance's robot file holds the visual
    meshes placed at that stance's posture, in the world frame."""
    import meshio

    from cbm.robot_mesh import robot_meshes

    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    assert [p.name for p in files.robot] == [f"stance_{i:02d}_robot.vtu" for i in range(4)]
    meshes = robot_meshes(robot)
    for planned, path in zip(synthetic_plan.stances, files.robot):
        points, triangles = meshes.posed(robot.model, planned.q)
        read = meshio.read(path)
        np.testing.assert_allclose(read.points, points, atol=1e-12)
        np.testing.assert_array_equal(read.cells_dict["triangle"], triangles)
    # Standing on the floor: the lowest vertex of the robot is at the floor, not below it or far above.
    lowest = meshio.read(files.robot[0]).points[:, 2].min()
    assert -0.01 < lowest < 0.01


SLANTED_SOFT_BOX = """
objects:
  - {name: floor, type: floor}
  - {name: pad, type: soft_box, size: [0.6, 0.4, 0.2], center: [1.0, -0.5, 0.1], yaw_deg: 30,
     material: {E: 1.0e6, nu: 0.4}, resolution: coarse}
stances:
  stand:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
"""


def test_vtu_read_back_gives_world_points_at_rest_and_the_displacement_in_world(tmp_path):
    """On a box turned 30 degrees: ParaView's Warp By Vector lands on the deformed body in the world."""
    import meshio

    pad = environments.load_string(SLANTED_SOFT_BOX, name="slanted").scene.deformable_objects[0]
    nodes = np.asarray(pad.mesh.nodes)
    u = np.zeros_like(nodes)
    u[:, 0] = 0.002 * nodes[:, 2]  # a shear along the box's own x axis
    u[:, 2] = -0.004 * nodes[:, 2] / nodes[:, 2].max()
    pad.write_vtu(tmp_path / "pad.vtu", u)
    mesh = meshio.read(tmp_path / "pad.vtu")
    np.testing.assert_allclose(mesh.points, pad.points_in_world(nodes), atol=1e-12)
    yaw = np.radians(30.0)
    along_x = np.array([np.cos(yaw), np.sin(yaw), 0.0])  # the box's x axis in the world
    expected = 0.002 * nodes[:, 2:3] * along_x + u[:, 2:3] * [0.0, 0.0, 1.0]
    np.testing.assert_allclose(mesh.point_data["displacement"], expected, atol=1e-15)
    warped = (mesh.points + mesh.point_data["displacement"])[np.asarray(pad.mesh.surface_triangles)]
    np.testing.assert_allclose(warped, pad.deformed_surface(u), atol=1e-12)


def test_plan_file_names_units_frames_robot_and_embeds_its_scenario(synthetic_plan, robot, tmp_path):
    data = json.loads(synthetic_plan.save(tmp_path / "plan.json").read_text())
    assert (data["format"], data["version"]) == ("softcbm-plan", 7)
    assert data["units"] == {"length": "m", "angle": "rad", "force": "N", "torque": "N m", "time": "s", "mass": "kg"}
    assert set(data["frames"]) >= {"world", "q", "point_forces", "displacements_in_body", "stance", "move"}
    described = data["robot"]
    assert described["name"] == "talos" and len(described["configuration_names"]) == robot.nq
    assert described["joint_names"] == robot.actuated_joint_names and len(described["joint_names"]) == robot.nv - 6
    assert sorted(described["locked_joints"]) == ["gripper_left_joint", "gripper_right_joint", "head_1_joint", "head_2_joint"]
    source = data["scenario"]
    assert source["name"] == "cross-soft-block" and source["built_in"] and source["robot"] == "talos"
    assert source["text"] == environments.builtin_scenario_path("cross-soft-block").read_text()
    foam = environments.load("cross-soft-block").scene.deformable_objects[0]
    np.testing.assert_array_equal(source["transform_body_to_world"]["foam"], foam.transform_body_to_world)
    force = data["stances"][1]["point_forces"][0]
    assert set(force) == {"link_frame", "point_in_world", "force_in_world"}
    assert force["force_in_world"] == [0.0, 0.0, 450.0]


def test_full_configuration_puts_every_link_of_the_urdf_where_the_plan_has_it(synthetic_plan, robot):
    """The configuration with the locked joints drives the robot's full URDF model to the same posture."""
    from types import SimpleNamespace

    import pinocchio as pin

    full = pin.buildModelFromUrdf(str(robot.urdf), pin.JointModelFreeFlyer())
    names = type(robot).configuration_names.fget(SimpleNamespace(model=full))
    values = synthetic_plan.full_configuration(2)
    assert sorted(values) == sorted(names)  # every coordinate of the URDF, no other
    q_full = np.array([values[name] for name in names])
    data, full_data = robot.model.createData(), full.createData()
    pin.framesForwardKinematics(robot.model, data, synthetic_plan.stances[2].q)
    pin.framesForwardKinematics(full, full_data, q_full)
    links = [f.name for f in full.frames if f.type == pin.FrameType.BODY and robot.model.existFrame(f.name)]
    assert len(links) > 30
    for link in links:
        placed = data.oMf[robot.model.getFrameId(link)]
        np.testing.assert_allclose(full_data.oMf[full.getFrameId(link)].homogeneous, placed.homogeneous, atol=1e-12)


def test_version_1_plan_files_are_still_read(synthetic_plan):
    """Files written before the headers: same stances; no robot description to expand q with."""
    version_1 = {
        "format": "softcbm-plan", "version": 1, "scenario": "cross-soft-block", "success": True,
        "reason": "goal reached", "statistics": synthetic_plan.statistics.to_dict(), "rejections": {},
        "stances": [
            {"stance": s.stance.to_dict(), "move": s.move, "q": s.q.tolist(),
             "point_forces": [f.to_dict() for f in s.point_forces],
             "deformations": {k: v.tolist() for k, v in s.deformations.items()}, "result": None}
            for s in synthetic_plan.stances
        ],
    }
    loaded = Plan.from_dict(version_1)
    assert loaded.scenario_name == "cross-soft-block" and loaded.scenario().name == "cross-soft-block"
    for before, after in zip(synthetic_plan.stances, loaded.stances):
        assert (before.stance, before.move) == (after.stance, after.move)
        np.testing.assert_array_equal(before.q, after.q)
        np.testing.assert_array_equal(before.contact_forces, after.contact_forces)
        np.testing.assert_array_equal(before.deformations["foam"], after.deformations["foam"])
    assert loaded.to_dict()["stances"] == synthetic_plan.to_dict()["stances"]
    with pytest.raises(PlanFileError, match=r"does not name its configuration coordinates \(a version 1 file\)"):
        loaded.full_configuration(0)


def test_earlier_versions_results_read_as_solved_with_the_defaults_of_their_day(robot):
    """Versions 1 and 2 were solved in the rest frames, version 3 in the rest frames with a 1
    degree tilt allowance, all with a 2 cm slip bound (the defaults then, so recorded nowhere):
    their results' options gain those, so that Plan.check verifies them as solved; a current
    result keeps what it recorded (the turned frames by default), and the same forces checked
    so are refused."""
    scenario = environments.load("hand-on-coarse-cube")
    stance = scenario.stance("hand-on-cube")
    assert SOLVED_AS[1] == SOLVED_AS[2]  # (version 1's layout: test_version_1_plan_files_are_still_read)
    for version in (2, 3):
        options = SOLVED_AS[version]
        result = stances.solve(robot, scenario.scene, stance, **options)
        planned = PlannedStance(stance, result.q, result.point_forces, result.deformations, result)
        plan = Plan(True, "goal reached", [planned], PlanStatistics(), "hand-on-coarse-cube",
                    robot=robot_description(robot), scenario_source=scenario_source(scenario))
        data = plan.to_dict()
        assert data["stances"][0]["result"]["statistics"]["options"] == options
        del data["stances"][0]["result"]["statistics"]["options"]  # as the earlier file has it
        read = Plan.from_dict({**data, "version": version})
        assert read.stances[0].result.statistics["options"] == options
        assert read.check().ok, version
        # The same file as the current version: solved against the turned face, which its
        # slipping palm nodes, solved in the rest frames, do not obey.
        current = Plan.from_dict({**data, "version": PLAN_VERSION})
        assert current.stances[0].result.statistics.get("options") is None
        assert not current.check().ok


def test_a_version_4_result_reads_as_solved_with_the_2_cm_slip_bound(robot):
    """Version 4 was solved with a 2 cm small-slip bound (the default then, recorded nowhere):
    hand-on-soft-cube's palm, solved so, slides 11 mm on the coarse cube, past the quarter of
    its 38 mm spacing that bounds it since version 5. Read as version 4 it is checked as solved
    and passes; read as the current version it is refused for that slip."""
    scenario = coarse_scenario("hand-on-soft-cube")
    stance = scenario.stance("hand-on-soft-cube")
    result = stances.solve(robot, scenario.scene, stance, **SOLVED_AS[4])
    assert result.feasible, result.reason
    planned = PlannedStance(stance, result.q, result.point_forces, result.deformations, result)
    plan = Plan(True, "goal reached", [planned], PlanStatistics(), "hand-on-soft-cube",
                robot=robot_description(robot), scenario_source=scenario_source(scenario))
    data = plan.to_dict()
    del data["stances"][0]["result"]["statistics"]["options"]  # as a version 4 file has it
    assert Plan.from_dict({**data, "version": 4}).check().ok
    current = Plan.from_dict({**data, "version": PLAN_VERSION}).check()
    assert not current.ok
    assert any("beyond the small-slip bound" in problem for problem in current.problems), current.problems


def test_a_stance_that_arrived_by_its_motion_says_so_in_the_file(synthetic_plan, tmp_path):
    """Version 7 marks the stances whose answer starts where the motion into them left them;
    a version 6 file has no such stance."""
    marked = replace(synthetic_plan, stances=synthetic_plan.stances[:2] + (
        replace(synthetic_plan.stances[2], arrived_by_motion=True),) + synthetic_plan.stances[3:])
    read = Plan.load(marked.save(tmp_path / "plan.json"))
    assert [s.arrived_by_motion for s in read.stances] == [False, False, True, False]
    data = marked.to_dict()
    for entry in data["stances"]:
        del entry["arrived_by_motion"]
    assert not any(s.arrived_by_motion for s in Plan.from_dict({**data, "version": 6}).stances)


@pytest.mark.parametrize("version", [None, 8, "2"], ids=["no-version", "future", "string"])
def test_plan_file_of_no_or_unknown_version_is_refused_with_the_versions_read(synthetic_plan, version):
    data = synthetic_plan.to_dict()
    if version is None:
        del data["version"]
    else:
        data["version"] = version
    message = (
        f"plan version {version!r} is not supported: this softcbm reads versions 1, 2, 3, 4, 5, 6, 7; "
        "plan the scenario again with this version (cbm plan)"
    )
    with pytest.raises(PlanFileError) as raised:
        Plan.from_dict(data)
    assert str(raised.value) == message


def test_plan_checks_with_its_embedded_scenario_when_the_scenario_file_is_gone(synthetic_plan, tmp_path):
    """A plan of a user's file: the YAML travels in plan.json, the file itself is not needed."""
    text = environments.builtin_scenario_path("cross-soft-block").read_text()
    user_file = tmp_path / "my-foam.yaml"
    user_file.write_text(text.replace("0.35..0.65", "x 0.35 to 0.65"))
    user_scenario = environments.load(user_file)
    plan = Plan(
        True, "goal reached", synthetic_plan.stances[:1], PlanStatistics(), user_scenario.name,
        robot=synthetic_plan.robot, scenario_source=scenario_source(user_scenario),
    )
    saved = plan.save(tmp_path / "plan.json")
    user_file.unlink()
    moved = tmp_path / "elsewhere"
    moved.mkdir()
    shutil.copy(saved, moved / "plan.json")
    loaded = Plan.load(moved / "plan.json")
    scenario = loaded.scenario()
    assert scenario.name == "my-foam" and "x 0.35 to 0.65" in scenario.description
    assert sorted(scenario.stances) == sorted(environments.load("cross-soft-block").stances)
    # Checked against the embedded scene: the start stance's goal is not reached.
    report = loaded.check()
    assert "the plan says it succeeded but its last stance does not reach the scenario's goal" in report.problems


def _viewer_data(files):
    """The plan data a written viewer page embeds."""
    page = files.viewer.read_text()
    start = page.index('type="application/json">') + len('type="application/json">')
    return json.loads(page[start: page.index("</script>", start)])


def test_viewer_page_is_self_contained_and_embeds_every_stance(synthetic_plan, scenario, robot, tmp_path):
    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    page = files.viewer.read_text()
    assert "http://" not in page and "https://" not in page and "<script src" not in page
    data = _viewer_data(files)
    assert len(data["stances"]) == 4
    dent = max(max(d["magnitude"]) for d in data["stances"][3]["deformables"])
    assert dent == pytest.approx(0.012, rel=1e-3)
    assert {p["robot_surface"] for p in data["stances"][1]["polygons"]} == {"left_sole", "right_sole"}
    assert data["stances"][0]["forces"] and data["stances"][0]["segments"]
    # The robot's own meshes, placed per stance: as many placements as meshes.
    meshes = data["robot"]["meshes"]
    assert len(meshes) > 40 and all(len(s["robot"]) == len(meshes) for s in data["stances"])
    assert len(page) < 3_000_000


@pytest.mark.skipif(chromium_binary() is None, reason="chromium is not installed (apt-get install chromium)")
def test_viewer_page_draws_without_errors_in_headless_chromium(synthetic_plan, scenario, robot, tmp_path):
    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    assert page_status(files.viewer, tmp_path) == "ok"


def page_screenshot(path, tmp_path, fragment=""):
    """(h, w, 3) float in [0, 1]: the page drawn by headless Chromium in a 960 x 720 window."""
    import matplotlib.image

    picture = tmp_path / f"screenshot{len(list(tmp_path.glob('screenshot*')))}.png"
    command = chromium(tmp_path, "--window-size=960,720", f"--screenshot={picture}", path.resolve().as_uri() + fragment)
    subprocess.run(command, capture_output=True, text=True, timeout=60)
    return matplotlib.image.imread(picture)[:, :, :3]


@pytest.mark.skipif(chromium_binary() is None, reason="chromium is not installed (apt-get install chromium)")
def test_viewer_draws_the_robot_from_its_meshes_where_it_stands(synthetic_plan, scenario, robot, tmp_path):
    """Screenshots with the robot shown and hidden (#hide=robot): what differs is the robot, in its colour."""
    from cbm.display import ROBOT_RGB

    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    shown, hidden = page_screenshot(files.viewer, tmp_path), page_screenshot(files.viewer, tmp_path, "#hide=robot")
    robot_pixels = np.abs(shown - hidden).max(axis=2) > 0.1
    rows, columns = np.nonzero(robot_pixels)
    height, width = robot_pixels.shape
    # A standing humanoid: tall (over a quarter of the window), narrower than tall, near the middle.
    assert rows.max() - rows.min() > 0.25 * height
    assert columns.max() - columns.min() < rows.max() - rows.min()
    assert 0.25 * width < columns.mean() < 0.75 * width
    # Drawn in the robot's shaded colour: its channels in the robot's proportions.
    colour = shown[robot_pixels]
    expected = np.asarray(ROBOT_RGB, float) / np.max(ROBOT_RGB)
    ratios = colour / np.maximum(colour.max(axis=1, keepdims=True), 1e-9)
    assert np.mean(np.all(np.abs(ratios - expected) < 0.06, axis=1)) > 0.7


@pytest.mark.skipif(chromium_binary() is None, reason="chromium is not installed (apt-get install chromium)")
def test_viewer_reports_a_console_error_in_its_status(synthetic_plan, scenario, robot, tmp_path):
    """An error logged to the console, not thrown, marks the page too, and the drawing
    that follows does not turn it back to ok."""
    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    page = files.viewer.read_text()
    logged = page.replace('  "use strict";', '  "use strict";\n  console.error("a logged failure");', 1)
    assert logged != page
    broken = tmp_path / "logged.html"
    broken.write_text(logged)
    assert page_status(broken, tmp_path) == "error: a logged failure"


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


def test_cli_lists_every_scenario_with_its_stance_names(capsys):
    assert main(["scenarios"]) == 0
    listed, name = {}, None
    for line in capsys.readouterr().out.splitlines():
        if not line.startswith(" "):
            name = line
        elif line.startswith("    stances: "):
            listed[name] = line[len("    stances: "):].split(", ")
    assert sorted(listed) == environments.scenario_names()
    for name in environments.scenario_names():
        scenario = environments.load(name)
        expected = [f"{s} (start)" if s == scenario.start else s for s in scenario.stances]
        assert listed[name] == expected


def test_cli_help_shows_the_defaults_and_the_exit_codes(capsys):
    assert main(["plan", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    for shown in ["(default: 200)", "(default: 300.0)", "(default: 0)", "(default: cbm-out)",
                  f"(default: {DEFAULT_SCENARIO})", "130 interrupted (Ctrl-C)", "141 output pipe closed"]:
        assert shown in text
    assert "(default: None)" not in text and "(default: False)" not in text


def test_cli_and_python_share_their_defaults():
    import inspect

    from cbm.cli import build_parser
    from cbm.planner import plan

    signature = inspect.signature(plan).parameters
    args = build_parser().parse_args(["plan"])
    for name in ("max_expansions", "time_limit", "seed", "print_spacing", "workers", "terrain_weight", "robot"):
        assert getattr(args, name) == signature[name].default, name
    assert (not args.no_prefilter) == signature["prefilter"].default
    assert signature["time_limit"].default == 300.0  # the value README and --help quote


def test_cli_version_names_the_installed_package(capsys):
    from importlib.metadata import version

    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"cbm {version('softcbm')}\n"


def test_cli_output_into_a_closed_pipe_ends_quietly(tmp_path):
    """`cbm scenarios | head -1`: the reader is gone before cbm writes; no traceback, exit 141."""
    import os
    import sys
    from pathlib import Path

    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    process = subprocess.Popen(
        [sys.executable, "-m", "cbm", "scenarios"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env
    )
    process.stdout.close()  # before the child has imported anything, let alone written
    errors = process.stderr.read().decode()
    assert process.wait(timeout=120) == 141, errors
    assert errors == ""


def test_check_report_gives_forces_depths_and_margins():
    from types import SimpleNamespace

    from environments import Contact, ContactPrint, Stance
    from stances.results import NodeSlips, PointForce

    from cbm.report import stance_report

    robot = SimpleNamespace(surfaces={"left_sole": SimpleNamespace(frame="left_sole_contact"),
                                      "right_palm": SimpleNamespace(frame="right_palm_contact")})
    stance = Stance((Contact("left_sole", ContactPrint("floor", 0.0, 0.1)), Contact("right_palm", ContactPrint("cube_top", 0.0, 0.0))))
    forces = [PointForce("left_sole_contact", [0, 0, 0], [3.0, 0.0, 200.0]),
              PointForce("left_sole_contact", [0, 0, 0], [0.0, -4.0, 100.0]),
              PointForce("right_palm_contact", [0, 0, 0], [0.0, 0.0, 30.0])]
    measures = {"indentation of cube": 0.00125, "largest strain of cube": 0.0123, "closest_distance": 0.0119,
                "cone margin on cube": 3.06, "cone margin of left_sole on floor": 120.0, "torque_margin": 5.0}
    limits = {"torque_usage": 0.222, "torque_joint": "arm_left_4_joint", "joint_clearance": 0.06,
              "clearance_joint": "arm_right_2_joint", "at_margin": ["torque of leg_left_4_joint at 90.0 % of its limit"]}
    slips = {"right_palm": NodeSlips("cube", [4, 5], [[0.003, 0.004, 0.0], [0.0, 0.001, 0.0]])}
    held = {"right_palm": NodeSlips("cube", [4, 5], [[0.0015, 0.002, 0.0], [0.0, 0.0, 0.0]])}
    result = SimpleNamespace(point_forces=forces, limits=limits, verification=SimpleNamespace(measures=measures),
                             slips=slips, held_slips=held)
    assert stance_report(result, robot, stance) == [
        "  forces on the robot (N, world frame):",
        "    left_sole on floor: 300.0 N (x 3.0, y -4.0, z 300.0)",
        "    right_palm on cube_top: 30.0 N (x 0.0, y 0.0, z 30.0)",
        "  depths in the soft bodies:",
        "    cube: indented 1.25 mm, largest strain 1.23 %",
        "  slips of the soft prints (link points over their nodes):",
        "    right_palm on cube: up to 5.00 mm, from 2.50 mm where the stance before left it",
        "  margins:",
        "    largest torque: 22.2 % of the limit of arm_left_4_joint",
        "    closest joint limit: 6.0 % of the range of arm_right_2_joint",
        "    closest collision distance: 11.9 mm",
        "    cone margin of left_sole on floor: 120.0 N",
        "    cone margin on cube: 3.1 N",
        "    on its margin: torque of leg_left_4_joint at 90.0 % of its limit",
    ]


def test_cli_check_of_a_plan_file_reports_what_fails(synthetic_plan, tmp_path, capsys):
    path = synthetic_plan.save(tmp_path / "plan.json")
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"{path}: plan of 'cross-soft-block', 4 stances: 7 problems" in out
    assert "  stances 0 -> 1 do not differ by exactly one contact" in out
    assert "  stance 0: no solver result to verify" in out
    assert "where their motions left them" not in out
    marked = replace(synthetic_plan, stances=synthetic_plan.stances[:1] + tuple(
        replace(s, arrived_by_motion=True) for s in synthetic_plan.stances[1:3]) + synthetic_plan.stances[3:])
    main(["check", str(marked.save(tmp_path / "arrived.json"))])
    assert ("  stances 1, 2 start their kept soft prints where their motions left them; the motions' samples are "
            "not in the file (cbm.motion.verify_motion checks them as they are planned)") in capsys.readouterr().out


def test_cli_check_of_a_scenario_needs_a_stance(capsys):
    assert main(["check", "cross-soft-block"]) == 2
    assert "scenario 'cross-soft-block' needs --stance; stances: beyond, both-on-foam" in capsys.readouterr().err


def test_every_visual_geometry_is_drawn_even_from_files_trimesh_cannot_read():
    """Romeo's visuals are COLLADA files (trimesh needs pycollada): they come from pinocchio's copy."""
    from cbm.robot_mesh import robot_meshes, visual_model

    romeo = stances.Robot.load("romeo")
    meshes = robot_meshes(romeo)
    assert [m.name for m in meshes.meshes] == [g.name for g in visual_model(romeo).geometryObjects]
    assert 0 < meshes.triangle_count <= 40_000
    vertices, _ = meshes.posed(romeo.model, romeo.reference_configuration)
    height = vertices[:, 2].max() - vertices[:, 2].min()
    assert 1.2 < height < 1.6  # Romeo is 1.4 m tall


def test_icub_is_drawn_with_its_meshes_turned_where_its_links_are():
    """iCub's visual meshes are turned by its description's mesh_rotations, as its
    collision meshes: drawn at the reference posture it stands 1.04 m tall (as
    loaded, with its head hanging behind the neck, the drawing was 0.86 m tall)."""
    from cbm.robot_mesh import robot_meshes

    icub = stances.Robot.load("icub")
    vertices, _ = robot_meshes(icub).posed(icub.model, icub.reference_configuration)
    assert vertices[:, 2].max() - vertices[:, 2].min() == pytest.approx(1.04, abs=0.01)


@pytest.mark.skipif(chromium_binary() is None, reason="chromium is not installed (apt-get install chromium)")
def test_viewer_shows_the_base_and_contact_frames_on_request(synthetic_plan, scenario, robot, tmp_path):
    """Each stance carries the base's and its contact surfaces' frames where the posture
    puts them; the frames box (or #frames) draws their axes, x red, y green, z blue."""
    import pinocchio as pin

    files = write_outputs(synthetic_plan, scenario, robot, tmp_path, pictures=False)
    data = _viewer_data(files)
    for planned, stance in zip(synthetic_plan.stances, data["stances"]):
        expected = {"base": None} | {robot.surfaces[c.robot_surface].frame: None for c in planned.stance}
        assert [f["name"] for f in stance["frames"]] == list(expected)
        model = robot.model
        pose = pin.Data(model)
        pin.framesForwardKinematics(model, pose, np.asarray(planned.q))
        for frame in stance["frames"][1:]:
            placement = pose.oMf[model.getFrameId(frame["name"])].homogeneous[:3].ravel()
            np.testing.assert_allclose(frame["transform"], placement, atol=1e-5)
    plain, framed = page_screenshot(files.viewer, tmp_path), page_screenshot(files.viewer, tmp_path, "#frames")
    changed = framed[np.abs(framed - plain).max(axis=2) > 0.1]
    for axis in range(3):  # pixels of each axis colour appear
        others = [k for k in range(3) if k != axis]
        assert np.sum((changed[:, axis] > 0.45) & (changed[:, others].max(axis=1) < 0.6 * changed[:, axis])) > 20


@pytest.mark.parametrize("named_by", ["the command line", "the scenario file"])
def test_a_plan_of_a_users_robot_file_checks_where_that_file_is_gone(synthetic_plan, tmp_path, named_by):
    """plan.json carries the robot's description when it came from a user's file: moved
    away, the plan still loads its robot (from that copy) and checks, whether the robot was
    given apart (cbm plan --robot) or named by the user's scenario file, gone too; a
    built-in robot's plan carries no copy."""
    from cbm.plan import robot_description

    user_file = tmp_path / "my-talos.yaml"
    user_file.write_text(stances.description.description_path("talos").read_text())
    mine = stances.Robot.load(user_file)
    source = synthetic_plan.scenario_source
    if named_by == "the scenario file":
        text = environments.builtin_scenario_path("cross-soft-block").read_text()
        scenario_file = tmp_path / "my-foam.yaml"
        scenario_file.write_text(text.replace("robot: talos", "robot: my-talos.yaml"))
        user_scenario = environments.load(scenario_file)
        assert user_scenario.robot == str(user_file.resolve())
        source = scenario_source(user_scenario)
        scenario_file.unlink()
    plan = Plan(True, "goal reached", synthetic_plan.stances[:1], PlanStatistics(), synthetic_plan.scenario_name,
                robot=robot_description(mine), scenario_source=source)
    assert plan.robot["text"] == user_file.read_text() and "text" not in synthetic_plan.robot
    saved = plan.save(tmp_path / "plan.json")
    user_file.unlink()
    loaded = Plan.load(saved)
    robot = loaded.robot_model()
    assert robot.name == mine.name and robot.configuration_names == mine.configuration_names
    report = loaded.check()
    assert not any("robot" in problem for problem in report.problems), report.problems


def test_force_labels_whose_anchors_meet_on_the_picture_are_lifted_apart_and_lone_ones_stay():
    import matplotlib.pyplot as plt

    from cbm.render import spread_labels

    figure = plt.figure(figsize=(8, 7), dpi=90)
    axes = figure.add_subplot(projection="3d")
    axes.view_init(elev=18.0, azim=-60.0)
    # Two soles' resultants 1 cm apart (one label over the other, as drawn before), and one far away.
    labels = [axes.text(0.0, 0.0, 0.5, " 443 N", fontsize=8), axes.text(0.0, 0.01, 0.5, " 443 N", fontsize=8),
              axes.text(0.8, -0.8, 0.0, " 12 N", fontsize=8)]
    lifts = spread_labels(axes, labels)
    plt.close(figure)
    assert lifts[2] == 0.0 and min(lifts[:2]) == 0.0
    # The one lifted clears the other by its own height (1.25 x 8 pt), no more.
    assert max(lifts[:2]) == pytest.approx(10.0, abs=2.0)
    offsets = [label.get_transform().transform((0.0, 0.0)) - axes.transData.transform((0.0, 0.0)) for label in labels]
    assert np.allclose(offsets[2], 0.0) and abs(offsets[0][1] - offsets[1][1]) == pytest.approx(10.0 * 90 / 72, abs=2.5)
