"""Scenarios: a scene, named stances, a start and a goal, read from YAML files.

A scenario file (see ``environments/scenarios/*.yaml`` for examples)::

    robot: talos                      # default talos; or a robot description file (.yaml)
    description: Both feet on the floor.
    objects:                          # a list; each has a name and a type
      - {name: floor, type: floor}    # top at z = 0; its surface is named like it
      - {name: table, type: box, size: [0.6, 0.8, 0.8], center: [0.65, -0.25, 0.4],
         yaw_deg: 0, friction: 0.7, side_surfaces: false}   # surfaces table_top (+ sides)
      - {name: cube, type: soft_box, size: [1, 1, 1], center: [0.9, -0.3, 0.5],
         material: {E: 1.0e6, nu: 0.4, rho: 1000}, resolution: default,
         refine: [[-0.5, -0.5], [0.5, 0.5]]}                # surface cube_top
      - {name: rock, type: mesh, file: rock.stl, center: [1, 0, 0], yaw_deg: 0,
         surfaces: [{name: rock_top, polygon: [[0, 0], [0.1, 0], [0, 0.1]],
                     origin: [0, 0, 0.2], rpy_deg: [0, 0, 0], friction: 0.5}]}
      - {name: stairs, type: mesh, file: stairs.stl, surfaces: auto}   # stairs_top_0, ..., stairs_side_0, ...
      - {name: pad, type: soft_mesh, file: pad.stl, position: [0.5, 0, 0], rpy_deg: [0, 0, 90],
         material: {E: 2.0e6, nu: 0.45}, fixed: on_floor}     # pad_top_0, ... (found on it)
    allowed_overlaps: [[stairs, rock]]                      # else overlapping objects are refused
    surfaces: {table_top: {friction: 0.5}}                  # per-surface overrides
    stances:                          # robot surface -> print on a surface
      stand:
        left_sole: {surface: floor, x: 0.0, y: 0.085, theta_deg: 0}
        right_sole: {surface: floor, x: 0.0, y: -0.085}
    start: stand
    goal:
      contacts: {right_palm: {surface: table_top, x: -0.2, y: 0}}   # or stance: <name>
      regions: [{robot_surface: left_sole, lower: [0.8, -0.4], upper: [1.6, 0.4]}]
    options: {print_spacing: 0.1, theta_values_deg: [0]}   # for the planner, see options.py

Print angles are ``theta_deg`` (degrees) or ``theta`` (radians), at most one, default
0; x and y are metres in the surface frame. Mesh files are relative to the YAML
file. Every error is a :class:`ScenarioError` naming the file, the key path and,
when known, the line.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import ScenarioError, SceneError, known_names
from .goal import Goal
from .options import validate_options
from .plain_data import load_yaml
from .scenario_reader import line_of, read_scenario_fields
from .scene import Scene
from .stance import Stance

__all__ = ["Scenario", "load", "load_string", "scenario_names", "builtin_scenario_path", "SCENARIO_DIRECTORY"]

SCENARIO_DIRECTORY = Path(__file__).resolve().parent / "scenarios"
"""Folder of the built-in scenario files."""


@dataclass(frozen=True, eq=False)
class Scenario:
    """A scene with named stances, an optional start and goal, and planner options.

    Parameters
    ----------
    name : str
        Scenario name (the file stem for files).
    scene : Scene
        Objects and contact surfaces.
    robot : str
        Built-in robot name, e.g. ``"talos"``, or the path of a robot
        description file.
    stances : dict of str to Stance
        Named stances.
    start : str or None
        Name of the start stance.
    goal : Goal or None
        Goal for the planner.
    description : str
        Free text.
    options : dict
        Plain data for the planner, validated by
        :func:`environments.options.validate_options` (keys ``print_spacing``,
        ``theta_values_deg``, ``print_margin``, ``sampling_region``,
        ``robot_surfaces``).
    path : pathlib.Path or None
        File it was read from.
    text : str or None
        The YAML document it was read from (None for a scenario built in code),
        kept so that a plan can carry its scenario and be checked anywhere.
    lines : dict of str to int
        Line of each key path in that file, for messages.

    Examples
    --------
    >>> scenario = load("stand")
    >>> scenario.stance("stand").robot_surfaces
    ('left_sole', 'right_sole')
    """

    name: str
    scene: Scene
    robot: str = "talos"
    stances: Mapping[str, Stance] = field(default_factory=dict)
    start: str | None = None
    goal: Goal | None = None
    description: str = ""
    options: Mapping[str, Any] = field(default_factory=dict)
    path: Path | None = None
    text: str | None = None
    lines: Mapping[str, int] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.scene, Scene):
            raise SceneError(f"Scenario.scene must be a Scene, got {type(self.scene).__name__}")
        stances = dict(self.stances)
        for name, stance in stances.items():
            if not isinstance(stance, Stance):
                raise SceneError(f"stance {name!r} must be a Stance, got {type(stance).__name__}")
        object.__setattr__(self, "stances", stances)
        object.__setattr__(self, "options", validate_options(self.options, self.path))
        if self.start is not None and self.start not in stances:
            raise SceneError(f"start stance {self.start!r} is not defined; stances: {known_names(stances)}")

    def stance(self, name: str) -> Stance:
        """A named stance.

        Raises
        ------
        SceneError
            If there is none; lists the names.
        """
        try:
            return self.stances[name]
        except KeyError:
            raise SceneError(
                f"scenario {self.name!r}: unknown stance {name!r}; stances: {known_names(self.stances)}"
            ) from None

    def check_self_weight(self) -> None:
        """Refuse a soft object its own weight alone strains beyond its strain bound
        (:func:`environments.scene_checks.check_self_weight`), naming, for a scenario
        read from a file, the file and the object's line.

        Raises
        ------
        SceneError
            A :class:`ScenarioError` for a scenario read from a file.
        """
        for soft in self.scene.deformable_objects:
            try:
                soft.self_weight_field
            except SceneError as error:
                key = self._object_key(soft.name)
                if self.path is None or key is None:
                    raise
                raise ScenarioError(self.path, key, str(error), line=line_of(self.lines, key)) from None

    def _object_key(self, name: str) -> str | None:
        """``"objects[i]"``, the key path of the file's object of that name, or None."""
        if self.text is None:
            return None
        objects = (load_yaml(self.text) or {}).get("objects") or ()
        return next((f"objects[{i}]" for i, item in enumerate(objects)
                     if isinstance(item, Mapping) and item.get("name") == name), None)

    def check_robot_surfaces(self, robot_surfaces, robot_name: str = "the robot") -> None:
        """Check that every stance and goal names only surfaces the robot has.

        Parameters
        ----------
        robot_surfaces : iterable of str
            The robot's contact surface names.
        robot_name : str
            For the message.

        Raises
        ------
        ScenarioError
            At the first contact or goal region naming another surface: the
            file, key path and line, the surface, and the robot's surfaces.

        Examples
        --------
        >>> load("stand").check_robot_surfaces(["left_foot", "right_foot"], "a robot")
        Traceback (most recent call last):
        ...
        environments.errors.ScenarioError: ...: stances.stand.left_sole: robot surface 'left_sole' is not a surface of a robot; its surfaces: left_foot, right_foot
        """
        known = list(robot_surfaces)
        uses = [(f"stances.{name}.{c.robot_surface}", c.robot_surface) for name, st in self.stances.items() for c in st]
        if self.goal is not None:
            uses += [(f"goal.contacts.{c.robot_surface}", c.robot_surface) for c in self.goal.contacts]
            uses += [(f"goal.regions[{i}].robot_surface", r.robot_surface) for i, r in enumerate(self.goal.regions)]
        for key, robot_surface in uses:
            if robot_surface not in known:
                raise ScenarioError(
                    self.path,
                    key,
                    f"robot surface {robot_surface!r} is not a surface of {robot_name}; its surfaces: "
                    f"{', '.join(known) or '(none)'}",
                    line=line_of(self.lines, key),
                )

    @property
    def start_stance(self) -> Stance | None:
        """The start stance, or None."""
        return None if self.start is None else self.stances[self.start]


def scenario_names() -> list[str]:
    """Sorted names of the built-in scenarios.

    Examples
    --------
    >>> "hand-on-cube" in scenario_names()
    True
    """
    return sorted(path.stem for path in SCENARIO_DIRECTORY.glob("*.yaml"))


def builtin_scenario_path(name: str) -> Path:
    """File of a built-in scenario.

    Raises
    ------
    ScenarioError
        If there is no such built-in scenario; lists the names.
    """
    path = SCENARIO_DIRECTORY / f"{name}.yaml"
    if not isinstance(name, str) or "/" in name or not path.is_file():
        raise ScenarioError(None, "", f"unknown scenario {name!r}; built-in scenarios: {known_names(scenario_names())}")
    return path


def load(name_or_path: str | os.PathLike) -> Scenario:
    """Load a built-in scenario by name, or a scenario YAML file by path.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A name from :func:`scenario_names`, or a path to a ``.yaml`` file.

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError
        If the name is unknown, the file is unreadable or any entry is invalid.

    Examples
    --------
    >>> scenario = load("hand-on-table")
    >>> sorted(scenario.scene.surfaces)
    ['floor', 'table_top']
    """
    if isinstance(name_or_path, str) and name_or_path in scenario_names():
        path = builtin_scenario_path(name_or_path)
    else:
        path = Path(name_or_path)
        if not path.is_file():
            raise ScenarioError(
                path, "", f"no such file, and not a built-in scenario; built-in scenarios: {known_names(scenario_names())}"
            )
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ScenarioError(path, "", f"cannot read: {error}") from None
    return load_string(text, path=path)


def load_string(text: str, path: str | os.PathLike | None = None, name: str | None = None,
                robot: str | None = None) -> Scenario:
    """Read a scenario from YAML text.

    Parameters
    ----------
    text : str
        The YAML document.
    path : str or os.PathLike, optional
        File it came from (for messages and relative mesh files).
    name : str, optional
        Scenario name; default the ``name`` key, else the file stem.
    robot : str, optional
        The scenario's robot (a built-in name or a description file), given instead
        of its ``robot`` key, whose file is then neither looked for nor checked.

    Raises
    ------
    ScenarioError
        On a syntax error (with its line) or any invalid entry.
    """
    return Scenario(**read_scenario_fields(text, path, name, robot), text=text)
