"""The interactive viewer: one self-contained HTML page (inline JS, no network)."""

from __future__ import annotations

import html
import json
from importlib import resources

import numpy as np

__all__ = ["viewer_data", "viewer_page", "write_viewer"]

# Positions to 0.01 mm and displacements to 1 nm keep the page small and exact enough to look at.
_DIGITS = 5


def _rounded(array, digits=_DIGITS):
    return np.round(np.asarray(array, dtype=float), digits).tolist()


def viewer_data(title, displays, edges, bounds, force_scale, force_legend):
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

    Returns
    -------
    dict
        JSON-ready: ``title``, ``bounds``, ``boxes``, ``force_scale``,
        ``force_legend``, ``max_displacement`` (metres) and ``stances`` (each:
        ``label``, ``segments``, ``polygons``, ``forces``, ``deformables``).
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
                "polygons": [
                    {"robot_surface": name, "points": _rounded(points), "colour": display.colours.get(name, "#2ca02c")}
                    for name, points in display.polygons.items()
                ],
                "forces": [
                    {"point": _rounded(point), "force": _rounded(force, 3)}
                    for point, force in zip(display.force_points, display.forces)
                ],
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
        "stances": stances,
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
