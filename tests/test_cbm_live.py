"""The live view: pinocchio's MeshcatVisualizer fed a plan, recorded instead of sent to a server."""

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from cbm.live import LiveViewUnavailable, meshcat_module


class RecordingWindow:
    """Stands for meshcat's server connection: keeps every command, serialised as it would be sent."""

    def __init__(self):
        self.commands = []

    def send(self, command):
        command.lower()  # what the server would receive: it must serialise
        self.commands.append(command)

    def objects(self, prefix):
        """The objects set under a path prefix (meshcat.geometry objects, with their geometry and material)."""
        return [c.object for c in self.commands if type(c).__name__ == "SetObject" and c.path.lower().startswith(prefix)]


def test_missing_meshcat_is_a_clear_error_that_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "meshcat", None)  # import meshcat now raises ImportError
    with pytest.raises(LiveViewUnavailable) as raised:
        meshcat_module()
    message = str(raised.value)
    assert message.startswith("the live view needs meshcat, an optional dependency (")
    assert message.endswith(
        "pip install meshcat (or pip install 'softcbm[view]'); without it, open viewer.html from cbm plan's "
        "output folder"
    )


def test_plan_show_puts_the_robot_meshes_soft_body_prints_and_forces_in_meshcat(tmp_path, robot):
    """The live view (an optional feature for users; meshcat is in the test extra, so
    a broken meshcat install fails here instead of skipping)."""
    import meshcat
    import environments

    from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source
    from cbm.robot_mesh import visual_model

    scenario = environments.load("cross-soft-block")
    foam = scenario.scene.deformable_objects[0]
    stance = scenario.stances["right-on-foam"]
    u = np.zeros((len(foam.mesh.nodes), 3))
    u[:, 2] = -0.003
    forces = [{"frame": robot.surfaces[c.robot_surface].frame, "point": scenario.scene.print_origin_in_world(c),
               "force": [0.0, 0.0, 400.0]} for c in stance]
    plan = Plan(True, "goal reached", [PlannedStance(stance, robot.reference_configuration, forces, {"foam": u})],
                PlanStatistics(), scenario.name, robot=robot_description(robot),
                scenario_source=scenario_source(scenario))
    window = RecordingWindow()
    view = plan.show(scenario, robot, viewer=meshcat.Visualizer(window=window), play=False)
    visuals = window.objects(f"/meshcat/{robot.name}/visuals/")
    assert len(visuals) == len(visual_model(robot).geometryObjects) > 40
    (soft,) = window.objects("/meshcat/soft/foam")
    colours = soft.geometry.color
    assert colours.shape == (len(np.unique(foam.mesh.surface_triangles)), 3)
    import matplotlib

    # A uniform 3 mm dent, the plan's largest: the top of the colour scale everywhere.
    np.testing.assert_allclose(colours, np.tile(matplotlib.colormaps["viridis"](1.0)[:3], (len(colours), 1)), atol=1e-6)
    assert soft.material.vertexColors
    assert len(window.objects("/meshcat/prints/")) == 2  # left and right soles
    (arrows,) = window.objects("/meshcat/forces/")
    ends = np.asarray(arrows.geometry.position).T
    np.testing.assert_allclose(ends[1::2] - ends[::2], [[0.0, 0.0, 0.4]] * 2, atol=1e-6)  # the largest is 0.4 m
    assert view.url is None or view.url.startswith("http")


def _meshcat_screenshot(viewer, tmp_path, name):
    """Headless Chromium's picture of what a meshcat server holds (its self-contained export)."""
    import subprocess

    from matplotlib.image import imread
    from test_cbm_output import chromium

    page = tmp_path / f"{name}.html"
    page.write_text(viewer.static_html())
    picture = tmp_path / f"{name}.png"
    command = chromium(tmp_path, "--window-size=960,640", f"--screenshot={picture}", page.as_uri())
    subprocess.run(command, capture_output=True, text=True, timeout=120, check=True)
    return imread(picture)[..., :3]


def test_the_live_view_draws_the_robot_in_a_real_browser(tmp_path, robot):
    """`cbm plan --view` through a real meshcat server, opened in headless Chromium: with
    the robot shown and hidden, what differs is a standing humanoid in the middle."""
    import meshcat

    import environments
    from test_cbm_output import chromium_binary

    if chromium_binary() is None:
        pytest.skip("chromium is not installed (apt-get install chromium)")
    from cbm.plan import Plan, PlannedStance, PlanStatistics, robot_description, scenario_source

    scenario = environments.load("cross-soft-block")
    stance = scenario.stances["start"]
    plan = Plan(True, "goal reached", [PlannedStance(stance, robot.reference_configuration, [], {})],
                PlanStatistics(), scenario.name, robot=robot_description(robot),
                scenario_source=scenario_source(scenario))
    viewer = meshcat.Visualizer()  # starts a local meshcat server, as cbm plan --view does
    try:
        plan.show(scenario, robot, viewer=viewer, play=False)
        shown = _meshcat_screenshot(viewer, tmp_path, "shown")
        viewer[robot.name].set_property("visible", False)
        hidden = _meshcat_screenshot(viewer, tmp_path, "hidden")
    finally:
        viewer.window.server_proc.kill()  # this meshcat's Visualizer.close() calls a method its window lacks
        viewer.window.server_proc.wait()
    robot_pixels = np.abs(shown - hidden).max(axis=2) > 0.1
    assert robot_pixels.sum() > 2000, "the robot is not drawn"
    rows, columns = np.nonzero(robot_pixels)
    height, width = robot_pixels.shape
    # Tall (over a quarter of the window), narrower than tall, near the middle.
    assert rows.max() - rows.min() > 0.25 * height
    assert columns.max() - columns.min() < rows.max() - rows.min()
    assert 0.25 * width < columns.mean() < 0.75 * width


def _children(pid):
    """Process ids whose parent is ``pid`` (Linux: read from /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # ended while read
        if int(fields[1]) == pid:
            found.append(stat.parent.name)
    return found


def _until_meshcat(child):
    """A view's standard output read up to the line giving its meshcat address (the lines)."""
    lines = []
    for line in child.stdout:
        lines.append(line)
        if line.strip().startswith("meshcat: "):
            break
    return lines


def test_cli_view_keeps_meshcat_open_until_the_user_closes_it(tmp_path):
    """``cbm check ... --view`` serves the stance until the user answers ``q``: the page
    answers while the command waits (before, the server was closed with the process a
    second after it started), and standard input's end closes it too."""
    import re
    import signal
    import subprocess
    import time
    import urllib.request

    root = Path(__file__).resolve().parents[1]
    environment = {**os.environ, "PYTHONUNBUFFERED": "1",
                   "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    command = [sys.executable, "-m", "cbm", "check", "hand-on-table", "--stance", "hand-on-table", "--view"]
    child = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             env=environment, text=True)
    try:
        lines = _until_meshcat(child)
        url = re.search(r"meshcat: (\S+)", "".join(lines))
        assert url is not None, "".join(lines) + child.stderr.read()
        time.sleep(1.0)
        assert child.poll() is None, "the view closed without being asked to"
        with urllib.request.urlopen(url.group(1), timeout=30) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
        child.stdin.write("q\n")
        child.stdin.flush()
        assert child.wait(timeout=60) == 0
    finally:
        child.kill()
        child.wait()
    rest = child.stdout.read()
    assert "Enter: play the plan, q then Enter: close the view" in rest
    # A non-interactive run (standard input at its end) does not hang.
    closed = subprocess.run(command, stdin=subprocess.DEVNULL, capture_output=True, text=True, env=environment,
                            timeout=240)
    assert closed.returncode == 0 and "meshcat: http" in closed.stdout, closed.stderr
    # Closed from outside (SIGTERM, as a closing terminal's SIGHUP): it exits as on Ctrl-C and
    # takes its meshcat server along (before, the server outlived it, holding its port).
    child = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             env=environment, text=True)
    try:
        _until_meshcat(child)
        servers = _children(child.pid)
        assert servers, "no meshcat server process under the view"
        child.send_signal(signal.SIGTERM)
        assert child.wait(timeout=60) == 128 + signal.SIGTERM
    finally:
        child.kill()
        child.wait()
    time.sleep(1.0)
    assert not any(Path(f"/proc/{pid}").exists() for pid in servers)
