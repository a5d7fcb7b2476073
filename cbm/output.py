"""Everything written for a plan: JSON, pictures, meshes, the viewer page."""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fem.io import write_pvd, write_surface

from .display import plan_bounds, scene_edges, stance_display
from .errors import CbmError
from .robot_mesh import robot_meshes
from .trajectory import plan_trajectory, write_trajectory
from .viewer import viewer_data, write_viewer

__all__ = ["OutputFiles", "write_outputs", "stance_labels", "OutputDirectoryError", "StagedOutput"]

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
        ``stance_XX_<object>.vtu``, one per deformable object per stance:
        world frame, rest positions, ``displacement`` point field.
    viewer : Path
        ``viewer.html``.
    series : Path or None
        ``plan.pvd``, the meshes as a ParaView time series (time = stance
        number, one part per deformable object and one for the robot); None
        without soft bodies or robot meshes.
    trajectory : tuple of Path
        ``trajectory.csv`` and ``trajectory.npz`` (:mod:`cbm.trajectory`),
        when motions were given.
    robot : tuple of Path
        ``stance_XX_robot.vtu``, one per stance: the robot's visual meshes
        (decimated as in the viewer) at the stance's posture, world frame, so
        ParaView shows robot and soft bodies together; empty when the robot
        has no visual meshes.
    """

    plan: Path
    pictures: tuple
    meshes: tuple
    viewer: Path
    series: Path | None = None
    trajectory: tuple = ()
    robot: tuple = ()

    def all(self):
        """Every path, plan first."""
        series = () if self.series is None else (self.series,)
        return (self.plan, *self.pictures, *self.meshes, *self.robot, *series, *self.trajectory, self.viewer)


def stance_labels(plan):
    """Titles of a plan's stances, e.g. ``"2/6: place left_sole on ..."``."""
    count = len(plan.stances)
    return tuple(
        f"{i}/{count - 1}: {planned.move or 'start'}" for i, planned in enumerate(plan.stances)
    )


def write_outputs(plan, scenario, robot, out_dir, *, pictures=True, motions=None):
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
    motions : sequence of cbm.motion.Motion, optional
        The motions between the stances (:func:`cbm.motion.plan_motions`):
        written as a joint trajectory and played by the viewer.

    Returns
    -------
    OutputFiles
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = scenario.scene
    plan_path = plan.save(out / "plan.json")
    labels = stance_labels(plan)
    meshes = robot_meshes(robot)
    displays = [stance_display(p, scene, robot, label, meshes) for p, label in zip(plan.stances, labels)]
    bounds = plan_bounds(displays) if displays else np.array([[-1.0, -1.0, 0.0], [1.0, 1.0, 2.0]])
    edges = scene_edges(scene, bounds)
    from .render import camera_azimuth, force_scale  # matplotlib only once needed

    scale = force_scale(displays)
    azimuth = camera_azimuth(displays)
    legend = _round_newtons(0.25 / scale)
    vtu_paths, datasets = [], []
    for index, planned in enumerate(plan.stances):
        for part, obj in enumerate(scene.deformable_objects):
            u = planned.deformations.get(obj.name)
            if u is None:
                u = np.zeros_like(np.asarray(obj.mesh.nodes, dtype=float))
            path = out / f"stance_{index:02d}_{obj.name}.vtu"
            obj.write_vtu(path, u)
            vtu_paths.append(path)
            datasets.append((index, part, path))
    robot_paths = []
    if meshes is not None:
        for index, planned in enumerate(plan.stances):
            path = out / f"stance_{index:02d}_robot.vtu"
            write_surface(path, *meshes.posed(robot.model, planned.q))
            robot_paths.append(path)
            datasets.append((index, len(scene.deformable_objects), path))
    series = None
    if datasets:
        series = out / "plan.pvd"
        write_pvd(series, datasets)
    picture_paths = []
    if pictures:
        from .render import render_stance

        top = max(
            (float(d.magnitude.max()) for s in displays for d in s.deformables if len(d.magnitude)), default=0.0
        )
        for index, display in enumerate(displays):
            path = out / f"stance_{index:02d}.png"
            render_stance(display, path, edges=edges, bounds=bounds, scale=scale, max_displacement=top,
                          meshes=meshes, azimuth=azimuth)
            picture_paths.append(path)
    status = "success" if plan.success else f"failed: {plan.reason}"
    played, trajectory_paths = [], ()
    if motions is not None:
        trajectory = plan_trajectory(plan, motions)
        trajectory_paths = write_trajectory(trajectory, out / "trajectory")
        for motion in motions:
            if motion.feasible and meshes is not None:
                interior = motion.configurations[1:-1]
                times = np.cumsum(motion.durations())[: len(interior)]
                played.append({"from": motion.index, "moving": motion.moving_surface, "times": times,
                               "transforms": [meshes.transforms(robot.model, q) for q in interior]})
    data = viewer_data(f"{plan.scenario_name} ({status})", displays, edges, bounds, scale, legend, meshes=meshes,
                       motions=played, camera_azimuth=azimuth)
    viewer_path = write_viewer(out / "viewer.html", data)
    # Debug: the command line writes into a temporary folder it then renames, and says where.
    logger.debug("wrote %s: plan, %d pictures, %d meshes, viewer", out, len(picture_paths), len(vtu_paths))
    return OutputFiles(plan_path, tuple(picture_paths), tuple(vtu_paths), viewer_path, series, trajectory_paths,
                       tuple(robot_paths))


def _round_newtons(value):
    magnitude = 10 ** np.floor(np.log10(max(value, 1e-9)))
    return float(np.round(value / magnitude) * magnitude)


class OutputDirectoryError(CbmError):
    """An output folder that cannot or must not be written (a file, read-only, not empty)."""


class StagedOutput:
    """An output folder filled in a hidden temporary folder beside it, then moved into place.

    A plan's files are written together or not at all: an interrupted or failed
    write leaves the output folder as it was, and a new plan never sits next to
    an older plan's stance files. The checks run when the object is made, before
    any planning, so that a bad ``--out`` costs nothing.

    Parameters
    ----------
    out_dir : path-like
        Final folder. It must not exist, or be an empty folder, or (with
        ``force``) any folder, whose content is then replaced.
    force : bool
        Replace a non-empty folder.

    Raises
    ------
    OutputDirectoryError
        If ``out_dir`` is a file, is not empty (without ``force``), or its
        parent cannot be made (missing folders are made) or written (checked by
        making the temporary folder there).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> staged = StagedOutput(root / "results")
    >>> _ = (staged.folder / "plan.json").write_text("{}")
    >>> staged.publish().name, sorted(p.name for p in (root / "results").iterdir())
    ('results', ['plan.json'])
    >>> import shutil; shutil.rmtree(root)
    """

    def __init__(self, out_dir, force=False):
        # abspath, not resolve: "." and ".." are folded so the folder has a name and
        # a parent, while a symbolic link stays the link the user named.
        self.out = Path(os.path.abspath(out_dir))
        if self.out.exists() and not self.out.is_dir():
            raise OutputDirectoryError(f"output {str(self.out)!r} is a file, not a folder; give a folder path to --out")
        if self.out.is_dir() and not force and any(self.out.iterdir()):
            raise OutputDirectoryError(
                f"output folder {str(self.out)!r} is not empty; give a new or empty folder, or --force to "
                "replace its content"
            )
        parent = self.out.parent
        # Missing parents are made, as ``mkdir -p`` would (``--out runs/today/plan``); a
        # file in the way is the user's to move.
        blocking = next((path for path in (parent, *parent.parents) if path.exists() and not path.is_dir()), None)
        if blocking is not None:
            raise OutputDirectoryError(
                f"cannot create output folder {str(self.out)!r}: {str(blocking)!r} is a file, not a folder"
            )
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise OutputDirectoryError(
                f"cannot create output folder {str(self.out)!r}: {error.strerror or error} making {str(parent)!r}"
            ) from None
        try:
            # In the same parent, so the final move is a rename on one file system.
            self.folder = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.partial-", dir=parent))
        except OSError as error:
            raise OutputDirectoryError(
                f"cannot write output folder {str(self.out)!r}: {error.strerror or error} in {str(parent)!r}"
            ) from None
        # An existing folder is replaced by renaming, which needs write access to it too.
        if self.out.is_dir() and not os.access(self.out, os.W_OK | os.X_OK):
            self.discard()
            raise OutputDirectoryError(f"output folder {str(self.out)!r} is not writable")

    def publish(self):
        """Move the filled temporary folder to the output folder, replacing it.

        Returns
        -------
        Path
            The output folder.
        """
        # mkdtemp makes the folder 0o700; give it the permissions a new folder gets.
        umask = os.umask(0)
        os.umask(umask)
        self.folder.chmod(0o777 & ~umask)
        old = None
        if self.out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.old-", dir=self.out.parent))
            self.out.rename(old / self.out.name)
        self.folder.rename(self.out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return self.out

    def discard(self):
        """Remove the temporary folder and everything in it (after a failure)."""
        shutil.rmtree(self.folder, ignore_errors=True)

    def final_path(self, path):
        """Where a file written in the temporary folder ends up once published."""
        return self.out / Path(path).relative_to(self.folder)
