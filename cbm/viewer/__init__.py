"""The interactive viewer: one self-contained HTML page (inline JS, no network)."""

from __future__ import annotations

import html
import json
from importlib import resources

import numpy as np

from ..display import ROBOT_RGB

__all__ = ["viewer_data", "viewer_page", "write_viewer"]

# Positions to 0.01 mm and displacements to 1 nm keep the page small and exact enough to look at.
_DIGITS = 5


def _rounded(array, digits=_DIGITS):
    return np.round(np.asarray(array, dtype=float), digits).tolist()


def _transforms(transforms):
    """(g, 4, 4) placements as rows of their 12 top numbers (rotation rows, translation)."""
    return _rounded(np.asarray(transforms, dtype=float).reshape(-1, 4, 4)[:, :3, :].reshape(-1, 12))


def viewer_data(title, displays, edges, bounds, force_scale, force_legend, *, meshes=None, motions=(),
                camera_azimuth=-60.0, grid_spacing=0.25):
    """Plain data drawn by the page.

    Parameters
    ----------
    title : str
        Page title (scenario and outcome).
    displays : sequence of cbm.display.StanceDisplay
        One per stance.
    edges : dict of str to (e, 2, 3) float
        Scene wireframes, metres, world frame.
    bounds : (2, 3) float
        World box to frame, metres.
    force_scale : float
        Arrow metres per newton.
    force_legend : float
        Force shown in the legend, newtons.
    meshes : cbm.robot_mesh.RobotMeshes, optional
        The robot's visual meshes; each display's ``robot_transforms`` places
        them. Without them the page draws the stick figure.
    motions : sequence of dict
        Motions between stances: ``from`` (stance index), ``moving`` (robot
        surface), ``times`` (k,) seconds and ``transforms`` (k, g, 4, 4), the
        meshes' placements at each interior sample.
    camera_azimuth : float
        Initial camera azimuth, degrees (one camera for the whole plan).
    grid_spacing : float
        Ground grid step, metres.

    Returns
    -------
    dict
        JSON-ready: ``title``, ``bounds``, ``boxes``, ``force_scale``,
        ``force_legend``, ``max_displacement`` (metres), ``robot`` (``meshes``,
        each ``vertices`` in its mesh frame and ``triangles``),
        ``robot_colour``, ``camera_azimuth`` (rad), ``grid_spacing``,
        ``grid_height``, ``stances`` (each: ``label``, ``segments``,
        ``robot`` (placements as 12 numbers, row-major 3 x 4), ``polygons``,
        ``forces``, ``frames`` (``name``, ``transform`` as 12 numbers),
        ``deformables``) and ``motions`` (``from``, ``moving``, ``times``,
        ``robot``: placements per sample).
    """
    max_displacement = max(
        (float(d.magnitude.max()) for s in displays for d in s.deformables if len(d.magnitude)), default=0.0
    )
    stances = []
    for display in displays:
        stances.append(
            {
                "label": display.label,
                "segments": _rounded(display.segments),
                "robot": _transforms(display.robot_transforms),
                "polygons": [
                    {"robot_surface": name, "points": _rounded(points), "colour": display.colours.get(name, "#2ca02c")}
                    for name, points in display.polygons.items()
                ],
                "forces": [
                    {"point": _rounded(point), "force": _rounded(force, 3)}
                    for point, force in zip(display.force_points, display.forces)
                ],
                "frames": [{"name": name, "transform": _transforms(placement)[0]}
                           for name, placement in display.frames.items()],
                "deformables": [
                    {
                        "name": d.name,
                        "vertices": _rounded(d.vertices),
                        "triangles": np.asarray(d.triangles, dtype=int).tolist(),
                        "magnitude": _rounded(d.magnitude, 9),
                    }
                    for d in display.deformables
                ],
            }
        )
    return {
        "title": title,
        "bounds": _rounded(bounds),
        "boxes": [{"name": name, "edges": _rounded(lines)} for name, lines in edges.items()],
        "force_scale": float(force_scale),
        "force_legend": float(force_legend),
        "max_displacement": max_displacement,
        "robot": {
            "meshes": [] if meshes is None else [
                # 0.1 mm: far below the decimation's centimetre.
                {"name": m.name, "vertices": _rounded(m.vertices, 4), "triangles": np.asarray(m.triangles).tolist()}
                for m in meshes.meshes
            ]
        },
        "robot_colour": list(ROBOT_RGB),
        "camera_azimuth": float(np.radians(camera_azimuth)),
        "grid_spacing": float(grid_spacing),
        "grid_height": 0.0,  # the floor: world z = 0 by convention
        "stances": stances,
        "motions": [
            {"from": int(m["from"]), "moving": str(m["moving"]), "times": _rounded(m["times"], 3),
             "robot": [_transforms(t) for t in m["transforms"]]}
            for m in motions
        ],
    }


def viewer_page(data):
    """The HTML page showing ``data`` (from :func:`viewer_data`), as a string.

    The data is embedded as JSON in a ``<script type="application/json">``
    element; ``</`` is escaped so that no string can close it early.
    """
    folder = resources.files(__package__)
    template = folder.joinpath("viewer.html").read_text(encoding="utf-8")
    script = folder.joinpath("viewer.js").read_text(encoding="utf-8")
    payload = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    page = template.replace("__TITLE__", html.escape(str(data.get("title", ""))))
    page = page.replace("/*__VIEWER_JS__*/", script)
    return page.replace("__PLAN_DATA__", payload)


def write_viewer(path, data):
    """Write the page to ``path`` and return the path."""
    with open(path, "w", encoding="utf-8") as stream:
        stream.write(viewer_page(data))
    return path
