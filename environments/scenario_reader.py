"""Validating reader of scenario YAML documents (the format is described in ``scenario.py``).

Every fault becomes a :class:`ScenarioError` naming the file, the dotted key path
(``objects[1].size``, ``stances.stand.left_sole.surface``) and the line, found by
composing the YAML node tree once and recording each key's position.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import yaml

from .deformable import (
    DEFAULT_MINIMUM_PRINT_CELLS, DEFAULT_STRAIN_LIMIT, DEFAULT_STRAIN_RADIUS, RESOLUTIONS, DeformableObject, RefineLines,
    _fem, _fine_spacing, soft_blocks, soft_box,
)
from .errors import ScenarioError, SceneError, known_names
from .goal import Goal, GoalRegion
from .objects import DEFAULT_FRICTION, RigidObject, box, box_surfaces, floor, mesh_object, rpy_rotation, surface_from_pose
from .mesh_surfaces import SurfaceSearch, auto_surfaces
from .options import validate_options
from .plain_data import checked_mapping, join_key, kind_of, load_yaml, repeated_key
from .scene import Scene
from .scene_checks import SceneSenseError, check_overlaps, check_supported
from .soft_mesh import ON_FLOOR, FixedPlane, soft_mesh
from .stance import Contact, Stance, contact_print_from_dict
from .surfaces import ContactSurface

__all__ = ["read_scenario_fields", "line_of", "ROBOT_FILE_SUFFIXES", "SCENARIO_KEYS", "OBJECT_KEYS", "NESTED_KEYS"]

#: Keys of a scenario document.
SCENARIO_KEYS = (
    "name", "robot", "description", "objects", "allowed_overlaps", "surfaces", "stances", "start", "goal", "options"
)

#: Keys each object ``type`` takes (docs/scenarios.md describes every one).
OBJECT_KEYS = {
    "floor": ("name", "type", "size", "friction"),
    "box": ("name", "type", "size", "center", "yaw_deg", "friction", "side_surfaces", "floating"),
    "soft_box": (
        "name", "type", "size", "center", "yaw_deg", "material", "resolution", "refine", "refine_lines", "grid", "friction",
        "strain_limit", "strain_radius", "minimum_print_cells", "floating",
    ),
    "soft_blocks": (
        "name", "type", "blocks", "material", "resolution", "friction", "strain_limit", "strain_radius",
        "minimum_print_cells", "floating",
    ),
    "mesh": ("name", "type", "file", "center", "yaw_deg", "surfaces", "auto_surfaces", "floating"),
    "soft_mesh": (
        "name", "type", "file", "position", "rpy_deg", "material", "resolution", "fixed", "surfaces", "auto_surfaces",
        "strain_limit", "strain_radius", "minimum_print_cells", "floating",
    ),
}

#: Keys of the mappings inside a scenario: a soft box's material, a mesh's
#: surfaces, a print (in stances and goal contacts), the goal and its regions,
#: a surface override.
NESTED_KEYS = {
    "material": ("E", "nu", "rho"),
    "block": ("name", "size", "center"),
    "mesh surface": ("name", "polygon", "origin", "rpy_deg", "friction"),
    "auto surfaces": ("max_slope_deg", "min_area", "sides", "friction"),
    "fixed": ("plane",),
    "print": ("surface", "x", "y", "theta", "theta_deg"),
    "goal": ("contacts", "stance", "regions"),
    "goal region": ("robot_surface", "lower", "upper"),
    "surface override": ("friction",),
}

#: A ``robot:`` value ending so is a robot description file, relative to the
#: scenario file; any other value is a built-in robot name.
ROBOT_FILE_SUFFIXES = (".yaml", ".yml")


def line_of(lines: dict, key: str) -> int | None:
    """Line of a dotted key path, or of its nearest enclosing key, in a recorded line map."""
    probe = key
    while probe not in lines and probe:
        probe = probe.rpartition(".")[0] if "." in probe else ""
    return lines.get(probe)


def read_scenario_fields(text: str, path: str | os.PathLike | None = None, name: str | None = None,
                         robot: str | None = None) -> dict:
    """Parse and validate a scenario YAML document into the fields of a ``Scenario``.

    Parameters
    ----------
    text : str
        The YAML document.
    path : str or os.PathLike, optional
        File it came from (for messages and relative mesh files).
    name : str, optional
        Scenario name; default the ``name`` key, else the file stem.
    robot : str, optional
        The robot the scenario asks for, given by the caller instead of read and
        checked from the ``robot`` key (a plan that carries its robot's description
        reads its scenario again where that robot file is gone).

    Returns
    -------
    dict
        Keyword arguments of ``Scenario``.

    Raises
    ------
    ScenarioError
        On a syntax error (with its line) or any invalid entry.
    """
    try:
        lines: dict[str, int] = {}
        # Before building any Python data: the walk bounds what aliases expand to, and
        # refuses a repeated key with its key path.
        data = load_yaml(text, inspect=lambda root: _record_lines(root, lines, path))
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = None if mark is None else mark.line + 1
        problem = getattr(error, "problem", None) or str(error)
        raise ScenarioError(path, "", f"YAML syntax error: {problem}", line=line) from None
    except RecursionError:
        raise ScenarioError(path, "", f"YAML nested too deeply; a scenario needs fewer than {MAX_YAML_DEPTH} levels") from None
    return _Reader(path, lines, robot).scenario_fields(data, name)


#: Most YAML nodes a scenario may expand to, aliases (``*name``) counted at every
#: use. The largest built-in scenario has a few hundred; the bound stops an alias
#: bomb (a kilobyte of nested aliases expanding to billions of nodes) before it
#: exhausts memory in this reader or in the planner that walks its data.
MAX_YAML_NODES = 100_000

#: Deepest nesting of mappings and lists; scenarios need fewer than 10 levels.
MAX_YAML_DEPTH = 64


def _record_lines(root: yaml.Node, lines: dict[str, int], path) -> None:
    """Map each key path of a composed YAML tree to its 1-based line, within bounds.

    Raises
    ------
    ScenarioError
        If the tree, its aliases expanded, has more than :data:`MAX_YAML_NODES`
        nodes, is deeper than :data:`MAX_YAML_DEPTH`, or holds an alias inside
        its own anchor (a cycle).
    """
    # An explicit stack, not recursion: a cyclic or very deep document must give
    # a ScenarioError, not a RecursionError. Each entry carries the ids of the
    # nodes above it, so an alias pointing back up is a cycle.
    stack = [(root, "", ())]
    visited = 0
    checked = set()  # ids of the mappings whose keys were checked
    while stack:
        node, key, ancestors = stack.pop()
        visited += 1
        line = node.start_mark.line + 1
        if visited > MAX_YAML_NODES:
            raise ScenarioError(
                path,
                key,
                f"the document expands to more than {MAX_YAML_NODES} YAML values (each use of an "
                "alias '*name' repeats its anchor's content); write the values out or use fewer "
                "nested aliases",
                line=line,
            )
        if id(node) in ancestors:
            raise ScenarioError(path, key, "an alias refers to a value that contains it (a cycle)", line=line)
        if len(ancestors) > MAX_YAML_DEPTH:
            raise ScenarioError(
                path, key, f"nested deeper than {MAX_YAML_DEPTH} levels; flatten the document", line=line
            )
        lines.setdefault(key, line)
        below = (*ancestors, id(node))
        if isinstance(node, yaml.MappingNode):
            # Once per mapping, not per use of an alias to it (building its keys again
            # at each of up to MAX_YAML_NODES visits would undo that bound).
            repeated = None if id(node) in checked else repeated_key(node)
            checked.add(id(node))
            if repeated is not None:
                raise ScenarioError(path, key, repeated[0], line=repeated[1])
            for key_node, value_node in reversed(node.value):
                child = f"{key}.{key_node.value}" if key else str(key_node.value)
                lines[child] = key_node.start_mark.line + 1
                stack.append((value_node, child, below))
        elif isinstance(node, yaml.SequenceNode):
            for index in reversed(range(len(node.value))):
                stack.append((node.value[index], f"{key}[{index}]", below))


_MISSING = object()

#: fem.LinearElasticMaterial's fields: the key a scenario file gives each under, its
#: default (required without one) and whether it must be > 0.
_MATERIAL_KEYS = {"young_modulus": ("E", _MISSING, True), "poisson_ratio": ("nu", _MISSING, False),
                  "density": ("rho", 0.0, False)}


class _Reader:
    """Validating reader of the plain data of one scenario file."""

    def __init__(self, path, lines: dict[str, int], robot: str | None = None) -> None:
        self.path = None if path is None else Path(path)
        self.lines = lines
        self.given_robot = robot

    # ------------------------------------------------------------------ basics
    def error(self, key: str, message: str) -> ScenarioError:
        return ScenarioError(self.path, key, message, line=line_of(self.lines, key))

    def mapping(self, value, key: str, allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> dict:
        return checked_mapping(value, key, allowed, required, self.error)

    def number(self, data: Mapping, name: str, key: str, default=_MISSING, positive=False) -> float:
        where = join_key(key, name)
        if name not in data:
            if default is _MISSING:
                raise self.error(key, f"missing key {name!r}")
            return default
        return self.to_number(data[name], where, positive)

    def to_number(self, value, where: str, positive: bool = False) -> float:
        # YAML 1.1 reads "1e6" (no dot) as a string: accept any string float() reads.
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.error(where, f"must be a number, got {kind_of(value)}")
        try:
            number = float(value)
        except ValueError:
            raise self.error(where, f"must be a number, got {value!r}") from None
        if not math.isfinite(number):
            raise self.error(where, f"must be finite, got {value!r}")
        if positive and number <= 0.0:
            raise self.error(where, f"must be > 0, got {value!r}")
        return number

    def vector(self, data: Mapping, name: str, key: str, length: int, default=_MISSING, positive=False) -> np.ndarray:
        where = join_key(key, name)
        if name not in data:
            if default is _MISSING:
                raise self.error(key, f"missing key {name!r}")
            return np.array(default, dtype=float)
        value = data[name]
        if not isinstance(value, list) or len(value) != length:
            raise self.error(where, f"must be a list of {length} numbers, got {kind_of(value)}")
        return np.array([self.to_number(v, f"{where}[{i}]", positive) for i, v in enumerate(value)])

    def string(self, data: Mapping, name: str, key: str, default=_MISSING) -> str:
        if name not in data:
            if default is _MISSING:
                raise self.error(key, f"missing key {name!r}")
            return default
        value = data[name]
        if not isinstance(value, str) or not value:
            raise self.error(join_key(key, name), f"must be a non-empty string, got {kind_of(value)}")
        return value

    def boolean(self, data: Mapping, name: str, key: str, default: bool) -> bool:
        value = data.get(name, default)
        if not isinstance(value, bool):
            raise self.error(join_key(key, name), f"must be true or false, got {kind_of(value)}")
        return value

    # ---------------------------------------------------------------- scenario
    def scenario_fields(self, data, name: str | None) -> dict:
        top = self.mapping(
            data if data is not None else {},
            "",
            SCENARIO_KEYS,
            required=("objects", "stances"),
        )
        default_name = self.path.stem if self.path is not None else "scenario"
        name = name if name is not None else self.string(top, "name", "", default_name)
        robot = self.string(top, "robot", "", "talos")
        robot = self.robot(robot) if self.given_robot is None else self.given_robot
        description = top.get("description", "")
        if not isinstance(description, str):
            raise self.error("description", f"must be text, got {kind_of(description)}")
        scene = self.scene(name, top["objects"], top.get("surfaces", {}), top.get("allowed_overlaps", []))
        stances_data = top["stances"]
        if not isinstance(stances_data, Mapping) or not stances_data:
            raise self.error("stances", f"must be a non-empty mapping of stance names to contacts, got {kind_of(stances_data)}")
        stances = {
            str(stance_name): self.stance(contacts, f"stances.{stance_name}", scene)
            for stance_name, contacts in stances_data.items()
        }
        start = top.get("start")
        if start is not None and start not in stances:
            raise self.error("start", f"unknown stance {start!r}; stances: {known_names(stances)}")
        goal = None if top.get("goal") is None else self.goal(top["goal"], scene, stances)
        try:
            options = validate_options(top.get("options", {}), self.path)
        except ScenarioError as error:
            raise self.error(error.key, error.message) from None
        return dict(
            name=name,
            scene=scene,
            robot=robot,
            stances=stances,
            start=start,
            goal=goal,
            description=description.strip(),
            options=options,
            path=self.path,
            lines=dict(self.lines),
        )

    def robot(self, value: str) -> str:
        """A built-in robot name as is, or a description file made absolute (relative to this file)."""
        if not value.endswith(ROBOT_FILE_SUFFIXES):
            return value
        base = self.path.parent if self.path is not None else Path.cwd()
        file_path = (base / value).resolve()
        if not file_path.is_file():
            raise self.error("robot", f"robot description file not found: {file_path}")
        return str(file_path)

    def scene(self, name: str, objects_data, surfaces_data, overlaps_data) -> Scene:
        if not isinstance(objects_data, list) or not objects_data:
            raise self.error("objects", f"must be a non-empty list of objects, got {kind_of(objects_data)}")
        rigid: list[RigidObject] = []
        deformable: list[DeformableObject] = []
        surfaces: list[ContactSurface] = []
        names: set[str] = set()
        floating: set[str] = set()
        keys: dict[str, str] = {}  # object name -> its key path, for messages
        for index, item in enumerate(objects_data):
            key = f"objects[{index}]"
            if not isinstance(item, Mapping):
                raise self.error(key, f"must be a mapping with a 'type', got {kind_of(item)}")
            kind = item.get("type")
            builders = {kind: getattr(self, kind) for kind in OBJECT_KEYS}
            if kind not in builders:
                raise self.error(join_key(key, "type"), f"unknown or missing type {kind!r}; valid types: {', '.join(builders)}")
            try:
                obj, obj_surfaces = builders[kind](item, key)
            except ScenarioError:
                raise
            except SceneError as error:
                raise self.error(key, str(error)) from None
            except ValueError as error:
                # fem's bad-input errors (material, mesh) become this file's errors;
                # any other ValueError is a bug and must surface as one.
                if not _is_fem_error(error):
                    raise
                raise self.error(key, f"{type(error).__name__}: {error}") from None
            if obj.name in names:
                raise self.error(join_key(key, "name"), f"repeated object name {obj.name!r}")
            names.add(obj.name)
            (deformable if obj.deformable else rigid).append(obj)
            surfaces.extend(obj_surfaces)
            if "floating" in OBJECT_KEYS[kind] and self.boolean(item, "floating", key, False):
                floating.add(obj.name)
            keys[obj.name] = key
        surfaces = self.surface_overrides(surfaces_data, surfaces)
        allowed = self.allowed_overlaps(overlaps_data, keys)
        try:
            scene = Scene(name, rigid, deformable, surfaces)
        except SceneError as error:
            raise self.error("objects", str(error)) from None
        try:
            # Overlaps first: a box sunk into the floor is named as that, not as resting on nothing.
            check_overlaps(scene, allowed)
            check_supported(scene, floating)
        except SceneSenseError as error:
            raise self.error(keys[error.objects[-1]], str(error)) from None
        return scene

    def allowed_overlaps(self, data, keys: dict[str, str]) -> set[frozenset]:
        """``allowed_overlaps: [[a, b], ...]``: pairs of known objects whose overlap is intended."""
        if not isinstance(data, list):
            raise self.error("allowed_overlaps", f"must be a list of [object, object] pairs, got {kind_of(data)}")
        allowed = set()
        for index, pair in enumerate(data):
            pair_key = f"allowed_overlaps[{index}]"
            if not (isinstance(pair, list) and len(pair) == 2 and pair[0] != pair[1]):
                raise self.error(pair_key, f"must be a pair of two object names [a, b], got {kind_of(pair)}")
            for name in pair:
                if name not in keys:
                    raise self.error(pair_key, f"unknown object {name!r}; objects: {known_names(keys)}")
            allowed.add(frozenset(pair))
        return allowed

    def surface_overrides(self, data, surfaces: list[ContactSurface]) -> list[ContactSurface]:
        if not isinstance(data, Mapping):
            raise self.error("surfaces", f"must be a mapping of surface names to settings, got {kind_of(data)}")
        by_name = {surface.name: surface for surface in surfaces}
        for surface_name, settings in data.items():
            key = f"surfaces.{surface_name}"
            if surface_name not in by_name:
                raise self.error(key, f"unknown surface {surface_name!r}; known surfaces: {known_names(by_name)}")
            settings = self.mapping(settings, key, NESTED_KEYS["surface override"])
            friction = self.number(settings, "friction", key, by_name[surface_name].friction, positive=True)
            by_name[surface_name] = dataclasses.replace(by_name[surface_name], friction=friction)
        return [by_name[surface.name] for surface in surfaces]

    def floor(self, item: Mapping, key: str):
        item = self.mapping(item, key, OBJECT_KEYS["floor"])
        name = self.string(item, "name", key, "floor")
        obj = floor(name, self.vector(item, "size", key, 2, (10.0, 10.0), positive=True))
        friction = self.number(item, "friction", key, DEFAULT_FRICTION, positive=True)
        return obj, box_surfaces(obj, friction, top_name=name)

    def box(self, item: Mapping, key: str):
        item = self.mapping(item, key, OBJECT_KEYS["box"], ("name", "size", "center"))
        name = self.string(item, "name", key)
        obj = box(
            name,
            self.vector(item, "size", key, 3, positive=True),
            self.vector(item, "center", key, 3),
            math.radians(self.number(item, "yaw_deg", key, 0.0)),
        )
        friction = self.number(item, "friction", key, DEFAULT_FRICTION, positive=True)
        return obj, box_surfaces(obj, friction, sides=self.boolean(item, "side_surfaces", key, False))

    def soft_box(self, item: Mapping, key: str):
        item = self.mapping(item, key, OBJECT_KEYS["soft_box"], ("name", "size", "center", "material"))
        name = self.string(item, "name", key)
        resolution = self.resolution(item, key)
        refine = item.get("refine")
        if refine is not None:
            if not (isinstance(refine, list) and len(refine) == 2 and all(isinstance(r, list) and len(r) == 2 for r in refine)):
                raise self.error(join_key(key, "refine"), f"must be [[x_min, y_min], [x_max, y_max]], got {refine!r}")
            refine = [[self.to_number(v, f"{key}.refine[{i}][{j}]") for j, v in enumerate(row)] for i, row in enumerate(refine)]
        grid = self.grid(item, key)
        size = self.vector(item, "size", key, 3, positive=True)
        refine_lines = self.refine_lines(item, key, size, resolution)
        material = self.material(item, key)
        obj, top = soft_box(
            name,
            size,
            self.vector(item, "center", key, 3),
            material,
            resolution=resolution,
            refine=refine,
            grid=grid,
            refine_lines=refine_lines,
            yaw=math.radians(self.number(item, "yaw_deg", key, 0.0)),
            friction=self.number(item, "friction", key, DEFAULT_FRICTION, positive=True),
            strain_limit=self.number(item, "strain_limit", key, DEFAULT_STRAIN_LIMIT, positive=True),
            strain_radius=self.strain_radius(item, key),
            minimum_print_cells=self.minimum_print_cells(item, key),
        )
        return obj, [top]

    def grid(self, item: Mapping, key: str):
        """A soft box's hand-given grid lines ``{x: [...], y: [...], z: [...]}``, or None."""
        if "grid" not in item:
            return None
        where = join_key(key, "grid")
        for other in ("resolution", "refine"):
            if other in item:
                raise self.error(where, f"a grid fixes every grid line: remove {other!r} or the grid")
        grid = self.mapping(item["grid"], where, ("x", "y", "z"), ("x", "y", "z"))
        lines = []
        for axis in "xyz":
            values = grid[axis]
            if not isinstance(values, list):
                raise self.error(join_key(where, axis), f"must be a list of numbers, got {kind_of(values)}")
            lines.append([self.to_number(v, f"{join_key(where, axis)}[{i}]") for i, v in enumerate(values)])
        return lines

    def refine_lines(self, item: Mapping, key: str, size, box_resolution):
        """A soft box's ``refine_lines: {x: [...], y: [...], half_width, resolution}``, or None,
        checked against the box's ``size`` and resolution (as read)."""
        if "refine_lines" not in item:
            return None
        where = join_key(key, "refine_lines")
        if "grid" in item:
            raise self.error(where, "a grid fixes every grid line: remove 'refine_lines' or the grid")
        lines = self.mapping(item["refine_lines"], where, ("x", "y", "half_width", "resolution"), ())
        axes = {}
        for axis in "xy":
            values = lines.get(axis, [])
            if not isinstance(values, list):
                raise self.error(join_key(where, axis), f"must be a list of numbers, got {kind_of(values)}")
            axes[axis] = [self.to_number(v, f"{join_key(where, axis)}[{i}]") for i, v in enumerate(values)]
        half_width = self.number(lines, "half_width", where, RefineLines.half_width, positive=True)
        resolution = self.number(lines, "resolution", where, RefineLines.resolution, positive=True)
        try:
            refine_lines = RefineLines(axes["x"], axes["y"], half_width, resolution)
            refine_lines.check(size, _fine_spacing(box_resolution))
            return refine_lines
        except SceneError as error:
            raise self.error(where, str(error).removeprefix("refine_lines ")) from None

    def strain_radius(self, item: Mapping, key: str) -> float:
        """A soft object's ``strain_radius``: metres, >= 0 (default :data:`DEFAULT_STRAIN_RADIUS`)."""
        return self.non_negative(item, "strain_radius", key, DEFAULT_STRAIN_RADIUS,
                                 ">= 0 metres (0: each tet's own strain)")

    def minimum_print_cells(self, item: Mapping, key: str) -> float:
        """A soft object's ``minimum_print_cells``: cells, >= 0 (default :data:`DEFAULT_MINIMUM_PRINT_CELLS`)."""
        return self.non_negative(item, "minimum_print_cells", key, DEFAULT_MINIMUM_PRINT_CELLS,
                                 "a number of mesh cells >= 0 (0: any print)")

    def non_negative(self, item: Mapping, name: str, key: str, default: float, meaning: str) -> float:
        """The number ``item[name]`` (``default`` where absent), refused below 0 with ``meaning``."""
        value = self.number(item, name, key, default)
        if value < 0.0:
            raise self.error(join_key(key, name), f"must be {meaning}, got {value:g}")
        return value

    def resolution(self, item: Mapping, key: str):
        resolution = item.get("resolution", "default")
        if isinstance(resolution, str) and resolution not in RESOLUTIONS:
            try:
                resolution = float(resolution)  # YAML 1.1 reads "1e-2" (no dot) as a string
            except ValueError:
                raise self.error(
                    join_key(key, "resolution"),
                    f"unknown resolution {resolution!r}; valid: {', '.join(RESOLUTIONS)} or a spacing in metres",
                ) from None
        if isinstance(resolution, str):
            return resolution
        return self.to_number(resolution, join_key(key, "resolution"), positive=True)

    def material(self, item: Mapping, key: str):
        material_key = join_key(key, "material")
        material_data = self.mapping(item["material"], material_key, NESTED_KEYS["material"], ("E", "nu"))
        fem = _fem()
        values = {field: self.number(material_data, key, material_key, default, positive)
                  for field, (key, default, positive) in _MATERIAL_KEYS.items()}
        try:
            with warnings.catch_warnings(record=True) as raised:
                warnings.simplefilter("always")
                material = fem.LinearElasticMaterial(**values)
            # Said where the file says it, as its errors are (path:line: key: message; the
            # line itself printed below), not at this reader's line.
            for warning in raised:
                text, where = str(warning.message), material_key
                field = next((field for field in _MATERIAL_KEYS if text.startswith(field + " ")), None)
                if field is not None:  # fem's name of the field, as the file names it
                    where, text = join_key(material_key, _MATERIAL_KEYS[field][0]), text[len(field) + 1:]
                warnings.warn_explicit(f"{where}: {text}", warning.category,
                                       str(self.path) if self.path is not None else "<scenario>",
                                       line_of(self.lines, where) or 0)
            return material
        except ValueError as error:
            if not _is_fem_error(error):
                raise
            field = getattr(error, "field", None)
            if field in _MATERIAL_KEYS:
                # Named by the file's key: its message starts with fem's name of the field.
                raise self.error(join_key(material_key, _MATERIAL_KEYS[field][0]), str(error)[len(field) + 1:]) from None
            raise self.error(material_key, str(error)) from None

    def soft_blocks(self, item: Mapping, key: str):
        item = self.mapping(item, key, OBJECT_KEYS["soft_blocks"], ("name", "blocks", "material"))
        name = self.string(item, "name", key)
        blocks_data = item["blocks"]
        if not isinstance(blocks_data, list) or not blocks_data:
            raise self.error(join_key(key, "blocks"), f"must be a non-empty list of {{name, size, center}}, got {kind_of(blocks_data)}")
        blocks = []
        for index, block in enumerate(blocks_data):
            block_key = f"{key}.blocks[{index}]"
            block = self.mapping(block, block_key, NESTED_KEYS["block"], ("name", "size", "center"))
            blocks.append((
                self.string(block, "name", block_key),
                self.vector(block, "size", block_key, 3, positive=True),
                self.vector(block, "center", block_key, 3),
            ))
        return soft_blocks(
            name,
            blocks,
            self.material(item, key),
            resolution=self.resolution(item, key),
            friction=self.number(item, "friction", key, DEFAULT_FRICTION, positive=True),
            strain_limit=self.number(item, "strain_limit", key, DEFAULT_STRAIN_LIMIT, positive=True),
            strain_radius=self.strain_radius(item, key),
            minimum_print_cells=self.minimum_print_cells(item, key),
        )

    def surface_search(self, item: Mapping, key: str) -> SurfaceSearch:
        """The settings of ``surfaces: auto`` (``auto_surfaces``), defaults where absent."""
        settings_key = join_key(key, "auto_surfaces")
        settings = self.mapping(item.get("auto_surfaces", {}), settings_key, NESTED_KEYS["auto surfaces"])
        defaults = SurfaceSearch()
        max_slope = self.number(settings, "max_slope_deg", settings_key, defaults.max_slope_deg)
        if not 0.0 <= max_slope < 90.0:
            raise self.error(join_key(settings_key, "max_slope_deg"), f"must be in [0, 90) degrees, got {max_slope:g}")
        return SurfaceSearch(
            max_slope,
            self.number(settings, "min_area", settings_key, defaults.min_area, positive=True),
            self.boolean(settings, "sides", settings_key, defaults.sides),
            self.number(settings, "friction", settings_key, defaults.friction, positive=True),
        )

    def mesh_file(self, item: Mapping, key: str) -> Path:
        """The ``file`` of a mesh object, relative to the scenario file, which must exist."""
        file_name = self.string(item, "file", key)
        base = self.path.parent if self.path is not None else Path.cwd()
        file_path = (base / file_name).resolve()
        if not file_path.is_file():
            raise self.error(join_key(key, "file"), f"mesh file not found: {file_path}")
        return file_path

    def soft_mesh(self, item: Mapping, key: str):
        item = self.mapping(item, key, OBJECT_KEYS["soft_mesh"], ("name", "file", "material"))
        name = self.string(item, "name", key)
        if item.get("surfaces", "auto") != "auto":
            raise self.error(join_key(key, "surfaces"), f"must be 'auto' (a soft mesh's surfaces are found on it), got {kind_of(item['surfaces'])}")
        return soft_mesh(
            name,
            self.mesh_file(item, key),
            self.material(item, key),
            position=self.vector(item, "position", key, 3, (0.0, 0.0, 0.0)),
            rpy=np.radians(self.vector(item, "rpy_deg", key, 3, (0.0, 0.0, 0.0))),
            fixed=self.fixed_plane(item, key),
            resolution=self.resolution(item, key),
            search=self.surface_search(item, key),
            strain_limit=self.number(item, "strain_limit", key, DEFAULT_STRAIN_LIMIT, positive=True),
            strain_radius=self.strain_radius(item, key),
            minimum_print_cells=self.minimum_print_cells(item, key),
        )

    def fixed_plane(self, item: Mapping, key: str) -> FixedPlane:
        """``fixed: on_floor`` (the default) or ``fixed: {plane: "z = 0.3"}``."""
        fixed_key = join_key(key, "fixed")
        value = item.get("fixed", "on_floor")
        if value == "on_floor":
            return ON_FLOOR
        if not isinstance(value, Mapping):
            raise self.error(fixed_key, f"must be on_floor or {{plane: '<x|y|z> = <metres>'}}, got {kind_of(value)}")
        value = self.mapping(value, fixed_key, NESTED_KEYS["fixed"], ("plane",))
        try:
            return FixedPlane.parse(value["plane"])
        except SceneError as error:
            raise self.error(join_key(fixed_key, "plane"), str(error)) from None

    def mesh(self, item: Mapping, key: str):
        item = self.mapping(item, key, OBJECT_KEYS["mesh"], ("name", "file"))
        name = self.string(item, "name", key)
        file_path = self.mesh_file(item, key)
        obj = mesh_object(
            name,
            str(file_path),
            self.vector(item, "center", key, 3, (0.0, 0.0, 0.0)),
            math.radians(self.number(item, "yaw_deg", key, 0.0)),
        )
        surfaces_data = item.get("surfaces", [])
        if surfaces_data == "auto":
            return obj, auto_surfaces(name, obj.mesh, obj.transform_object_to_world, self.surface_search(item, key))
        if "auto_surfaces" in item:
            raise self.error(join_key(key, "auto_surfaces"), "applies only with 'surfaces: auto'")
        if not isinstance(surfaces_data, list):
            raise self.error(join_key(key, "surfaces"), f"must be 'auto' or a list of surfaces, got {kind_of(surfaces_data)}")
        surfaces = []
        for index, surface_item in enumerate(surfaces_data):
            surface_key = f"{key}.surfaces[{index}]"
            surface_item = self.mapping(surface_item, surface_key, NESTED_KEYS["mesh surface"], ("name", "polygon"))
            polygon = surface_item["polygon"]
            if not isinstance(polygon, list) or not all(isinstance(p, list) and len(p) == 2 for p in polygon):
                raise self.error(join_key(surface_key, "polygon"), "must be a list of [x, y] vertices, counter-clockwise")
            polygon = [[self.to_number(v, f"{surface_key}.polygon[{i}]") for v in p] for i, p in enumerate(polygon)]
            rpy = np.radians(self.vector(surface_item, "rpy_deg", surface_key, 3, (0.0, 0.0, 0.0)))
            transform_surface_to_object = np.eye(4)
            transform_surface_to_object[:3, :3] = rpy_rotation(*rpy)
            transform_surface_to_object[:3, 3] = self.vector(surface_item, "origin", surface_key, 3, (0.0, 0.0, 0.0))
            try:
                surfaces.append(
                    surface_from_pose(
                        self.string(surface_item, "name", surface_key),
                        name,
                        polygon,
                        transform_surface_to_object,
                        obj.transform_object_to_world,
                        self.number(surface_item, "friction", surface_key, DEFAULT_FRICTION, positive=True),
                    )
                )
            except ScenarioError:
                raise
            except SceneError as error:
                raise self.error(surface_key, str(error)) from None
        return obj, surfaces

    # ------------------------------------------------------------------ stances
    def contacts(self, data, key: str, scene: Scene) -> tuple[Contact, ...]:
        if not isinstance(data, Mapping) or not data:
            raise self.error(key, f"must be a non-empty mapping robot_surface -> {{surface, x, y, theta_deg}}, got {kind_of(data)}")
        contacts = []
        for robot_surface, print_data in data.items():
            print_key = f"{key}.{robot_surface}"
            print_data = self.mapping(print_data, print_key, NESTED_KEYS["print"], ("surface",))
            surface_name = print_data["surface"]
            if surface_name not in scene.surfaces:
                raise self.error(
                    join_key(print_key, "surface"),
                    f"unknown surface {surface_name!r}; known surfaces: {known_names(scene.surfaces)}",
                )
            for name in ("x", "y", "theta", "theta_deg"):
                if name in print_data:
                    self.to_number(print_data[name], join_key(print_key, name))
            try:
                contact_print = contact_print_from_dict(str(robot_surface), print_data)
                scene.check_print(contact_print)
            except SceneError as error:
                raise self.error(print_key, str(error)) from None
            contacts.append(Contact(str(robot_surface), contact_print))
        return tuple(contacts)

    def stance(self, data, key: str, scene: Scene) -> Stance:
        return Stance(self.contacts(data, key, scene))

    def goal(self, data, scene: Scene, stances: dict[str, Stance]) -> Goal:
        data = self.mapping(data, "goal", NESTED_KEYS["goal"])
        if "contacts" in data and "stance" in data:
            raise self.error("goal", "give 'contacts' or 'stance', not both")
        contacts: tuple[Contact, ...] = ()
        if "contacts" in data:
            contacts = self.contacts(data["contacts"], "goal.contacts", scene)
        if "stance" in data:
            stance_name = data["stance"]
            if stance_name not in stances:
                raise self.error("goal.stance", f"unknown stance {stance_name!r}; stances: {known_names(stances)}")
            contacts = stances[stance_name].contacts
        regions_data = data.get("regions", [])
        if not isinstance(regions_data, list):
            raise self.error("goal.regions", f"must be a list, got {kind_of(regions_data)}")
        regions = []
        for index, item in enumerate(regions_data):
            key = f"goal.regions[{index}]"
            item = self.mapping(item, key, NESTED_KEYS["goal region"], NESTED_KEYS["goal region"])
            lower, upper = self.vector(item, "lower", key, 2), self.vector(item, "upper", key, 2)
            if np.any(lower > upper):
                raise self.error(key, f"lower {lower.tolist()} must be <= upper {upper.tolist()}")
            regions.append(GoalRegion(self.string(item, "robot_surface", key), lower, upper))
        if not contacts and not regions:
            raise self.error("goal", "needs 'contacts', 'stance' or 'regions'")
        return Goal(contacts, tuple(regions))


def _is_fem_error(error: Exception) -> bool:
    """Whether an exception is one of fem's own bad-input errors (fem imported lazily)."""
    try:
        from fem.errors import FemError
    except ImportError:  # pragma: no cover - fem is part of the project
        return False
    return isinstance(error, FemError)
