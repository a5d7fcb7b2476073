"""Everything written for a plan: JSON, pictures, meshes, the viewer page."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .display import plan_bounds, scene_edges, stance_display
from .viewer import viewer_data, write_viewer

__all__ = ["OutputFiles", "write_outputs", "stance_labels"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class OutputFiles:
    """Paths written by :func:`write_outputs`.

    Parameters
    ----------
    plan : Path
        ``plan.json``.
    pictures : tuple of Path
        ``stance_XX.png``, one per stance (empty with ``pictures=False``).
    meshes : tuple of Path
        ``stance_XX_<object>.vtu``, one per deformable object per stance.
    viewer : Path
        ``viewer.html``.
    """

    plan: Path
    pictures: tuple
    meshes: tuple
    viewer: Path

    def all(self):
        """Every path, plan first."""
        return (self.plan, *self.pictures, *self.meshes, self.viewer)


def stance_labels(plan):
    """Titles of a plan's stances, e.g. ``"2/6: place left_sole on ..."``."""
    count = len(plan.stances)
    return tuple(
        f"{i}/{count - 1}: {planned.move or 'start'}" for i, planned in enumerate(plan.stances)
    )


def write_outputs(plan, scenario, robot, out_dir, *, pictures=True):
    """Write a plan's files into a directory (created if needed).

    Parameters
    ----------
    plan : cbm.Plan
    scenario : environments Scenario
        The scenario planned (scene for drawing and meshes).
    robot : stances Robot
        For forward kinematics.
    out_dir : path-like
    pictures : bool
        Also draw one PNG per stance (the slowest part).

    Returns
    -------
    OutputFiles
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = scenario.scene
    plan_path = plan.save(out / "plan.json")
    labels = stance_labels(plan)
    displays = [stance_display(p, scene, robot, label) for p, label in zip(plan.stances, labels)]
    bounds = plan_bounds(displays) if displays else np.array([[-1.0, -1.0, 0.0], [1.0, 1.0, 2.0]])
    edges = scene_edges(scene, bounds)
    from .render import force_scale  # matplotlib only once needed

    scale = force_scale(displays)
    legend = _round_newtons(0.25 / scale)
    meshes = []
    for index, planned in enumerate(plan.stances):
        for obj in scene.deformable_objects:
            u = planned.deformations.get(obj.name)
            if u is None:
                u = np.zeros_like(np.asarray(obj.mesh.nodes, dtype=float))
            path = out / f"stance_{index:02d}_{obj.name}.vtu"
            obj.body.write_vtu(path, u)
            meshes.append(path)
    picture_paths = []
    if pictures:
        from .render import render_stance

        top = max(
            (float(d.magnitude.max()) for s in displays for d in s.deformables if len(d.magnitude)), default=0.0
        )
        for index, display in enumerate(displays):
            path = out / f"stance_{index:02d}.png"
            render_stance(display, path, edges=edges, bounds=bounds, scale=scale, max_displacement=top)
            picture_paths.append(path)
    status = "success" if plan.success else f"failed: {plan.reason}"
    data = viewer_data(f"{plan.scenario_name} ({status})", displays, edges, bounds, scale, legend)
    viewer_path = write_viewer(out / "viewer.html", data)
    logger.info("wrote %s: plan, %d pictures, %d meshes, viewer", out, len(picture_paths), len(meshes))
    return OutputFiles(plan_path, tuple(picture_paths), tuple(meshes), viewer_path)


def _round_newtons(value):
    magnitude = 10 ** np.floor(np.log10(max(value, 1e-9)))
    return float(np.round(value / magnitude) * magnitude)
