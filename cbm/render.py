"""Pictures of stances: matplotlib 3D, Agg backend, one PNG per stance."""

from __future__ import annotations

import logging
import textwrap

import matplotlib

matplotlib.use("Agg")  # files only: never open a window, work without a display

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import cm, colors, transforms  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d import proj3d  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # noqa: E402

from .display import ROBOT_RGB  # noqa: E402

__all__ = ["render_stance", "force_scale", "camera_azimuth", "MIN_ARROW"]

#: Shortest arrow drawn, metres: a palm's few newtons stay visible (its label gives the value).
MIN_ARROW = 0.06

logger = logging.getLogger(__name__)

# Title characters per line: a move's label ("place right_sole on foam_top at x ...
# in foam_top's frame") ran past the figure's left edge on one line.
_TITLE_WIDTH = 64


def force_scale(displays, length=0.4):
    """Metres of arrow per newton so that the largest resultant is ``length`` long.

    Parameters
    ----------
    displays : sequence of StanceDisplay
    length : float
        Arrow length of the largest force, metres.

    Returns
    -------
    float
        Metres per newton (1e-3 if there is no force at all).
    """
    largest = max((np.linalg.norm(d.forces, axis=1).max() for d in displays if len(d.forces)), default=0.0)
    return length / largest if largest > 0 else 1e-3


def render_stance(display, path, *, edges=None, bounds=None, scale=1e-3, max_displacement=None, meshes=None,
                  azimuth=None):
    """Draw one stance and save it as a PNG.

    Parameters
    ----------
    display : StanceDisplay
        What to draw.
    path : path-like
        Output file.
    edges : dict of str to (e, 2, 3) float, optional
        Scene wireframes, world frame.
    bounds : (2, 3) float, optional
        World box to show, metres.
    scale : float
        Arrow metres per newton.
    max_displacement : float, optional
        Top of the colour scale, metres (shared by a plan's pictures).
    meshes : cbm.robot_mesh.RobotMeshes, optional
        The robot's visual meshes, placed by ``display.robot_transforms``;
        without them the stick figure is drawn.
    azimuth : float, optional
        Camera azimuth, degrees (one for a plan's pictures); default
        :func:`camera_azimuth` of this display.
    """
    figure = plt.figure(figsize=(8, 7), dpi=90)
    axes = figure.add_subplot(projection="3d")
    # Drawn in this order (zorder), not sorted by depth: the camera is on the
    # robot's side of the soft bodies (camera_azimuth), and the forces and
    # prints, small and important, stay on top of the robot's legs.
    axes.computed_zorder = False
    heavy = []  # the many-triangle collections, left out of the layout pass (see _save)
    for name, lines in (edges or {}).items():
        axes.add_collection3d(Line3DCollection(lines, colors="0.55", linewidths=0.8, zorder=0))
    mappable = None
    top = max_displacement
    if top is None:
        top = max((d.magnitude.max() for d in display.deformables if len(d.magnitude)), default=0.0)
    norm = colors.Normalize(0.0, max(top, 1e-9) * 1e3)
    colormap = plt.get_cmap("viridis")
    for deformable in display.deformables:
        face_values = deformable.magnitude[deformable.triangles].mean(axis=1) * 1e3
        faces = Poly3DCollection(
            deformable.vertices[deformable.triangles],
            facecolors=colormap(norm(face_values)),
            edgecolors="none",
            alpha=0.9,
            zorder=1,
        )
        axes.add_collection3d(faces)
        heavy.append(faces)
        mappable = cm.ScalarMappable(norm=norm, cmap=colormap)
    if azimuth is None:
        azimuth = camera_azimuth([display])
    elevation = 18.0
    if meshes is not None and len(display.robot_transforms):
        heavy.append(_draw_robot(axes, meshes, display.robot_transforms, azimuth, elevation))
    else:
        axes.add_collection3d(Line3DCollection(display.segments, colors="k", linewidths=2.0, zorder=2))
        joints = display.segments.reshape(-1, 3)
        axes.scatter(joints[:, 0], joints[:, 1], joints[:, 2], s=4, c="k", depthshade=False)
    for robot_surface, polygon in display.polygons.items():
        colour = display.colours.get(robot_surface, "tab:green")
        patch = Poly3DCollection([polygon], facecolors=colour, edgecolors=colour, alpha=0.6, zorder=3)
        axes.add_collection3d(patch)
        axes.plot([], [], color=colour, linewidth=6, label=robot_surface)
    if len(display.forces):
        magnitudes = np.linalg.norm(display.forces, axis=1)
        lengths = np.maximum(magnitudes * scale, MIN_ARROW)
        arrows = display.forces / np.maximum(magnitudes, 1e-12)[:, None] * lengths[:, None]
        axes.quiver(
            display.force_points[:, 0],
            display.force_points[:, 1],
            display.force_points[:, 2],
            arrows[:, 0],
            arrows[:, 1],
            arrows[:, 2],
            color="tab:purple",
            linewidth=2.0,
            arrow_length_ratio=0.2,
            zorder=4,
        )
        labels = [axes.text(*tip, f" {magnitude:.0f} N", color="tab:purple", fontsize=8, fontweight="bold", zorder=5)
                  for tip, magnitude in zip(display.force_points + arrows, magnitudes)]
        reference = _round_force(0.25 / scale)
        axes.plot([], [], color="tab:purple",
                  label=f"contact force (arrow {reference * scale:.2f} m = {reference:g} N, at least {MIN_ARROW} m)")
    if bounds is not None:
        _equal_axes(axes, bounds)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_zlabel("z (m)")
    for axis in (axes.xaxis, axes.yaxis, axes.zaxis):
        # An axis seen nearly end-on squeezed a dozen overlapping tick labels.
        axis.set_major_locator(MaxNLocator(5))
    axes.set_title(textwrap.fill(display.label, _TITLE_WIDTH), fontsize=10)
    axes.legend(loc="upper left", fontsize=8)
    axes.view_init(elev=elevation, azim=azimuth)
    if mappable is not None:
        colorbar = figure.colorbar(mappable, ax=axes, shrink=0.6, pad=0.1)
        colorbar.set_label("displacement (mm)")
    if len(display.forces):
        spread_labels(axes, labels)  # once the camera and the axes' place are final
    _save(figure, path, heavy)
    plt.close(figure)
    logger.debug("picture written to %s", path)
    return path


def spread_labels(axes, labels) -> np.ndarray:
    """Lift labels of a 3D picture until none overlaps another (two soles' force labels,
    their arrows' tips side by side as the camera sees them, were drawn over each other).

    Each label's box on the picture is estimated from its font size and its characters;
    from the lowest up, a label that meets one already placed goes just above it.

    Parameters
    ----------
    axes : mpl_toolkits.mplot3d.Axes3D
        With its camera and limits set.
    labels : sequence of mpl_toolkits.mplot3d.art3d.Text3D
        Left-aligned texts; each is moved by an offset added to its transform.

    Returns
    -------
    (len(labels),) float
        Each label's lift, points.
    """
    lifts = np.zeros(len(labels))
    if len(labels) < 2:
        return lifts
    anchors = np.array([label.get_position_3d() for label in labels], dtype=float)
    x, y, _ = proj3d.proj_transform(anchors[:, 0], anchors[:, 1], anchors[:, 2], axes.get_proj())
    pixels = axes.transData.transform(np.column_stack([x, y]))
    per_point = axes.figure.dpi / 72.0
    placed = []  # (left, bottom, width, top), pixels
    for index in np.lexsort((pixels[:, 0], pixels[:, 1])).tolist():
        size = labels[index].get_fontsize() * per_point
        width, height = 0.62 * size * len(labels[index].get_text()), 1.25 * size
        left, bottom = pixels[index]
        lifted = bottom
        while True:
            over = [top for other_left, other_bottom, other_width, top in placed
                    if left < other_left + other_width and other_left < left + width
                    and lifted < top and other_bottom < lifted + height]
            if not over:
                break
            lifted = max(over)
        placed.append((left, lifted, width, lifted + height))
        lifts[index] = (lifted - bottom) / per_point
        if lifts[index] > 0.0:
            labels[index].set_transform(labels[index].get_transform() + transforms.ScaledTranslation(
                0.0, lifts[index] / 72.0, axes.figure.dpi_scale_trans))
    return lifts


def camera_azimuth(displays) -> float:
    """Camera azimuth, degrees, on the robot's side of the soft bodies, for a whole plan.

    matplotlib sorts whole collections by depth, so a soft body between the
    camera and the robot would be drawn over it: look from the robot's side
    (its mean position over the plan), a quarter turn off the line joining
    them. Without soft bodies, the usual front-left three-quarter view.

    Parameters
    ----------
    displays : sequence of StanceDisplay
    """
    displays = [d for d in displays if len(d.segments)]
    if not displays or not displays[0].deformables:
        return -60.0
    robot_centre = np.concatenate([d.segments.reshape(-1, 3) for d in displays]).mean(axis=0)
    bodies_centre = np.mean([d.vertices.mean(axis=0) for d in displays[0].deformables], axis=0)
    away = robot_centre[:2] - bodies_centre[:2]
    if np.linalg.norm(away) < 1e-9:
        return -60.0
    return float(np.degrees(np.arctan2(away[1], away[0]))) - 45.0


def _draw_robot(axes, meshes, transforms, azimuth, elevation):
    """The robot's meshes, flat-shaded by a light at the camera (one collection: sorted by depth),
    added to ``axes`` and returned."""
    vertices, offset, triangles = [], 0, []
    for mesh, transform in zip(meshes.meshes, transforms):
        vertices.append(mesh.vertices @ transform[:3, :3].T + transform[:3, 3])
        triangles.append(mesh.triangles + offset)
        offset += len(mesh.vertices)
    faces = np.concatenate(vertices)[np.concatenate(triangles)]
    normals = np.cross(faces[:, 1] - faces[:, 0], faces[:, 2] - faces[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-15)
    a, e = np.radians(azimuth), np.radians(elevation)
    towards_camera = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    light = 0.45 + 0.55 * np.abs(normals @ towards_camera)
    colours = np.clip(np.outer(light, np.asarray(ROBOT_RGB) / 255.0), 0.0, 1.0)
    robot = Poly3DCollection(faces, facecolors=colours, edgecolors="none", zorder=2)
    axes.add_collection3d(robot)
    return robot


def _save(figure, path, heavy, pad=0.15):
    """Save the figure cropped to its drawn parts, as ``bbox_inches="tight"`` would, drawing
    it once.

    matplotlib's "tight" crop draws the figure twice (a layout pass, then the picture),
    and each pass projects every triangle anew (Talos: 33,000 robot triangles). The crop
    is set by the axes' labels, title, legend and colour bar; the ``heavy`` collections
    lie inside the axes' limits, so the layout pass runs without them. Measured on the
    default plan's 9 pictures (``bench/bench_outputs.py``, rounds alternating): the same
    pixels, 0.46-0.53 CPU s a picture against 0.53-0.60 with matplotlib's crop.
    """
    for artist in heavy:
        artist.set_visible(False)
    figure.draw_without_rendering()  # the layout pass savefig's "tight" runs
    box = figure.get_tightbbox().padded(pad)
    for artist in heavy:
        artist.set_visible(True)
    figure.savefig(path, bbox_inches=box)


def _round_force(value):
    """A round number of newtons near ``value`` for the legend."""
    magnitude = 10 ** np.floor(np.log10(max(value, 1e-9)))
    return float(np.round(value / magnitude) * magnitude)


def _equal_axes(axes, bounds):
    bounds = np.asarray(bounds, dtype=float)
    centre = bounds.mean(axis=0)
    half = 0.5 * np.max(bounds[1] - bounds[0])
    axes.set_xlim(centre[0] - half, centre[0] + half)
    axes.set_ylim(centre[1] - half, centre[1] + half)
    axes.set_zlim(max(centre[2] - half, bounds[0][2]), max(centre[2] - half, bounds[0][2]) + 2 * half)
    axes.set_box_aspect((1, 1, 1))
