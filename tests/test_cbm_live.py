"""The live view: pinocchio's MeshcatVisualizer fed a plan, recorded instead of sent to a server."""

import sys

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
