"""A live view of a plan in meshcat, through pinocchio's ``MeshcatVisualizer``.

meshcat is an optional dependency (``pip install meshcat``, or
``pip install 'softcbm[view]'``): the planner, its files and its offline viewer
page work without it. The robot is drawn by pinocchio's visualizer from its
URDF visual geometry; this module adds what pinocchio does not know: the soft
bodies' deformed surfaces coloured by displacement, the rigid objects, the
prints and the contact forces, and steps through the stances and the motions
between them.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .display import plan_bounds, scene_edges, stance_display
from .errors import CbmError
from .output import stance_labels
from .robot_mesh import visual_model

__all__ = ["LiveView", "LiveViewUnavailable", "meshcat_module"]

logger = logging.getLogger(__name__)

_FORCE_COLOUR = 0x9467BD
_INSTALL = "pip install meshcat (or pip install 'softcbm[view]')"


class LiveViewUnavailable(CbmError):
    """The live view's optional dependency, meshcat, is not installed."""


def meshcat_module():
    """The ``meshcat`` package, or a :class:`LiveViewUnavailable` that says how to install it."""
    try:
        import meshcat
        import meshcat.geometry  # noqa: F401
        import meshcat.transformations  # noqa: F401
    except ImportError as error:
        raise LiveViewUnavailable(
            f"the live view needs meshcat, an optional dependency ({error}): {_INSTALL}; "
            "without it, open viewer.html from cbm plan's output folder"
        ) from None
    return meshcat


class LiveView:
    """A plan shown in meshcat: robot, soft bodies, rigid objects, prints and forces.

    Parameters
    ----------
    plan : cbm.Plan
    scenario : environments Scenario
    robot : stances Robot
    motions : sequence of cbm.motion.Motion, optional
        Played between the stances.
    viewer : meshcat.Visualizer, optional
        Default: a new one (it starts a local meshcat server; its address is
        :attr:`url` and is logged).

    Raises
    ------
    LiveViewUnavailable
        If meshcat is not installed.
    """

    def __init__(self, plan, scenario, robot, motions=(), viewer=None):
        meshcat = meshcat_module()
        from pinocchio.visualize import MeshcatVisualizer

        self.plan, self.scenario, self.robot, self.motions = plan, scenario, robot, tuple(motions or ())
        self.geometry = meshcat.geometry
        self.visualizer = MeshcatVisualizer(robot.model, robot.collision_model, visual_model(robot))
        self.visualizer.initViewer(viewer=viewer if viewer is not None else meshcat.Visualizer())
        self.visualizer.loadViewerModel(rootNodeName=robot.name)
        self.viewer = self.visualizer.viewer
        self.displays = [
            stance_display(p, scenario.scene, robot, label) for p, label in zip(plan.stances, stance_labels(plan))
        ]
        forces = [np.linalg.norm(d.forces, axis=1).max() for d in self.displays if len(d.forces)]
        self.force_scale = 0.4 / max(forces) if forces and max(forces) > 0 else 1e-3
        self.max_displacement = max(
            (float(b.magnitude.max()) for d in self.displays for b in d.deformables if len(b.magnitude)), default=0.0
        )
        self._rigid_objects()
        if self.displays:
            self.show_stance(0)

    @property
    def url(self):
        """Address of the meshcat page (None for a viewer without a server)."""
        try:
            return self.viewer.url()
        except AttributeError:
            return None

    def _rigid_objects(self):
        bounds = plan_bounds(self.displays) if self.displays else None
        for name, edges in scene_edges(self.scenario.scene, bounds).items():
            self._lines(f"scene/{name}", edges, 0x999999)

    def _lines(self, path, segments, colour):
        points = np.asarray(segments, dtype=float).reshape(-1, 3).T
        self.viewer[path].set_object(
            self.geometry.LineSegments(self.geometry.PointsGeometry(points), self.geometry.LineBasicMaterial(color=colour))
        )

    def show_stance(self, index):
        """Put the robot, the soft bodies, the prints and the forces of stance ``index``."""
        import matplotlib

        display = self.displays[index]
        self.visualizer.display(self.plan.stances[index].q)
        colormap = matplotlib.colormaps["viridis"]
        top = max(self.max_displacement, 1e-9)
        for body in display.deformables:
            colours = colormap(body.magnitude / top)[:, :3]
            self.viewer[f"soft/{body.name}"].set_object(
                self.geometry.TriangularMeshGeometry(body.vertices, body.triangles, color=colours),
                self.geometry.MeshLambertMaterial(vertexColors=True),
            )
        self.viewer["prints"].delete()
        for name, polygon in display.polygons.items():
            closed = np.concatenate([polygon, polygon[:1]])
            colour = int(display.colours.get(name, "#2ca02c")[1:], 16)
            self._lines(f"prints/{name}", np.stack([closed[:-1], closed[1:]], axis=1), colour)
        tips = display.force_points + self.force_scale * display.forces
        self.viewer["forces"].delete()
        if len(tips):
            self._lines("forces/arrows", np.stack([display.force_points, tips], axis=1), _FORCE_COLOUR)

    def play(self, stance_seconds=1.0, sample_seconds=0.2):
        """Step through every stance, and the motion after it, once.

        Parameters
        ----------
        stance_seconds : float
            Time each stance stays, seconds.
        sample_seconds : float
            Time each motion sample stays, seconds.
        """
        by_start = {m.index: m for m in self.motions if m.feasible}
        for index in range(len(self.displays)):
            self.show_stance(index)
            time.sleep(stance_seconds)
            motion = by_start.get(index)
            if motion is not None:
                self.viewer["forces"].delete()
                for q in motion.configurations[1:-1]:
                    self.visualizer.display(q)
                    time.sleep(sample_seconds)
