"""A scenario with its soft meshes refined: every cell of every soft object divided.

A stance solved on a soft support is only as right as the mesh under its prints.
Solving it again on the same scene meshed finer (``stances.check_refined``, ``cbm
check --refine``) tells a user whether the answer is the continuum's or the mesh's.
The refined scenario is read from the scenario's own YAML text with each soft
object's spacing divided, so it is the same scene in every other respect: same
objects, surfaces, stances and goal.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from .deformable import RefineLines, _fine_spacing
from .errors import ScenarioError, SceneError
from .scenario import Scenario, load_string
from .soft_mesh import TET_MESH_SUFFIXES

__all__ = ["refined"]

SOFT_TYPES = ("soft_box", "soft_blocks", "soft_mesh")


def refined(scenario: Scenario, factor: int = 2) -> Scenario:
    """The same scenario with every soft object's mesh ``factor`` times finer.

    A soft box or soft blocks get their node spacing ``resolution`` divided by
    ``factor`` (in plane and in depth, refined regions kept; a soft box's
    ``refine_lines`` their resolution too, their bands as wide); a soft box given
    by its grid lines gets each interval cut into ``factor``; a soft mesh made
    from a surface file is tetrahedralised again with edges ``factor`` times
    shorter.

    Parameters
    ----------
    scenario : environments.Scenario
        Read from a file or text (its ``text`` is what is refined).
    factor : int
        How many times finer, at least 2.

    Returns
    -------
    environments.Scenario
        Same name and path (mesh files it names are found as before).

    Raises
    ------
    SceneError
        If ``factor`` is not an integer of at least 2, the scenario was built in
        code (no text), has no soft object, or a soft object is a tetrahedral
        mesh file (used as it is: mesh it finer yourself). A refined mesh over
        the node limit fails as the scenario file would, naming the object.
    """
    if isinstance(factor, bool) or not isinstance(factor, int) or factor < 2:
        raise SceneError(f"refinement factor must be an integer of at least 2, got {factor!r}")
    if scenario.text is None:
        raise SceneError(
            f"scenario {scenario.name!r} was built in code and has no YAML text to refine; "
            "build its soft objects again with a finer resolution"
        )
    data = yaml.safe_load(scenario.text)
    soft = [item for item in data.get("objects") or () if isinstance(item, dict) and item.get("type") in SOFT_TYPES]
    if not soft:
        raise SceneError(f"scenario {scenario.name!r} has no soft object to refine")
    for item in soft:
        _refine_object(item, factor)
    text = yaml.safe_dump(data, sort_keys=False)
    try:
        return load_string(text, path=scenario.path, name=scenario.name)
    except ScenarioError as error:
        # Its line is one of the rewritten text, not of the user's file.
        raise SceneError(f"scenario {scenario.name!r} refined {factor}x: {error.key}: {error.message}; "
                         "use a smaller factor") from None


def _refine_object(item: dict, factor: int) -> None:
    """Divide one soft object's spacing (or grid intervals) by ``factor``, in place."""
    if item["type"] == "soft_mesh" and Path(str(item.get("file", ""))).suffix.lower() in TET_MESH_SUFFIXES:
        raise SceneError(
            f"object {item.get('name')!r} is a tetrahedral mesh file ({item['file']}), used as it is: "
            "mesh it finer yourself, or give its surface (STL, OBJ) to have it meshed"
        )
    if "grid" in item:
        item["grid"] = {axis: _subdivided(lines, factor) for axis, lines in item["grid"].items()}
        return
    item["resolution"] = _fine_spacing(item.get("resolution", "default")) / factor
    if isinstance(item.get("refine_lines"), dict):
        lines = item["refine_lines"]
        lines["resolution"] = float(lines.get("resolution", RefineLines.resolution)) / factor


def _subdivided(lines, factor: int) -> list:
    """Sorted grid lines with each interval cut into ``factor`` equal parts (given lines kept exactly)."""
    lines = sorted(float(v) for v in lines)
    out = [lines[0]]
    for low, high in zip(lines, lines[1:]):
        out.extend(low + (high - low) * k / factor for k in range(1, factor))
        out.append(high)
    return out
