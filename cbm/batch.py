"""Stance checks in bulk: the batch file, one check, and its outcome.

A batch file lists (robot, scenario, stance) checks, as YAML::

    solver_options: {max_iterations: 40}    # optional, for every check
    checks:
      - {scenario: stand, stance: stand}                 # a stance of the scenario, by name
      - scenario: my-scene.yaml                          # a file, relative to the batch file
        robot: talos                                     # optional: the scenario's robot
        id: wide                                         # optional: default its index
        stance:                                          # or a stance written out
          left_sole: {surface: floor, x: 0.0, y: 0.15}
          right_sole: {surface: floor, x: 0.0, y: -0.15}

or as CSV with the columns ``scenario``, ``stance`` (a name) and optionally
``robot`` and ``id``. Every check is solved cold (from
:func:`stances.initial_configuration`, the reference posture over the
stance) and verified, so its answer depends on the check alone: the order
and the machine it runs on do not change it. :func:`cbm.distributed.solve_many`
runs many of them on a cluster.
"""

from __future__ import annotations

import csv
import hashlib
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import CbmError

__all__ = ["BatchFileError", "Check", "CheckOutcome", "read_checks", "run_check"]

_CHECK_KEYS = ("scenario", "stance", "robot", "id")
_TOP_KEYS = ("checks", "solver_options")


class BatchFileError(CbmError):
    """A batch file that cannot be read, naming the file and the entry at fault."""

    def __init__(self, path, where, message):
        self.path, self.where = str(path), where
        super().__init__(f"{self.path}: {where}: {message}" if where else f"{self.path}: {message}")


@dataclass(frozen=True)
class Check:
    """One stance check, self-contained so that any machine can run it.

    Parameters
    ----------
    id : str
        Name of the check in the results.
    scenario_text : str
        The scenario's YAML (shipped whole: workers need no shared files).
    scenario_path : str or None
        Its file, for relative mesh paths and messages.
    stance : dict
        ``{robot_surface: {surface, x, y, theta}}`` (:meth:`environments.Stance.to_dict`).
    robot : str
        ``stances.Robot.load`` argument.
    """

    id: str
    scenario_text: str
    scenario_path: str | None
    stance: dict = field(hash=False)
    robot: str = "talos"

    @property
    def world_key(self):
        """What the robot and scene are built from: checks sharing it share them."""
        return hashlib.sha256(self.scenario_text.encode()).hexdigest(), self.scenario_path, self.robot


@dataclass(frozen=True)
class CheckOutcome:
    """The answer to one check, as stored in a row of the dataset.

    Parameters
    ----------
    id : str
    scenario : str
    robot : str
    stance : dict
    feasible : bool
        Solved and verified.
    reason : str
        Why not; empty when feasible.
    q : (nq,) float
        Final configuration (empty if the solver raised).
    force_frames : tuple of str
    force_points : (k, 3) float
        Application points, metres, world frame.
    forces : (k, 3) float
        Contact forces on the robot, newtons, world frame.
    solve_time : float
        Seconds in ``stances.solve`` (and its cold retry), verification included.
    check_time : float
        Seconds of the whole check on its worker, building the world included
        when it was not built yet.
    """

    id: str
    scenario: str
    robot: str
    stance: dict = field(compare=False)
    feasible: bool
    reason: str
    q: np.ndarray = field(compare=False)
    force_frames: tuple
    force_points: np.ndarray = field(compare=False)
    forces: np.ndarray = field(compare=False)
    solve_time: float = field(compare=False)
    check_time: float = field(compare=False)

    def same_answer(self, other) -> bool:
        """True if ``other`` answers the same check identically, bit for bit (times aside)."""
        return (
            self == other
            and self.stance == other.stance
            and all(np.array_equal(getattr(self, n), getattr(other, n)) for n in ("q", "force_points", "forces"))
        )


def read_checks(path) -> tuple:
    """The checks of a batch file (``.yaml``/``.yml`` or ``.csv``).

    Returns
    -------
    (checks, solver_options) : (tuple of Check, dict)

    Raises
    ------
    BatchFileError
        Naming the file, the check (index) and the key at fault: unreadable
        file, unknown key, missing scenario or stance, unknown stance name,
        malformed stance, scenario that fails to load.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise BatchFileError(path, "", f"cannot read: {error.strerror or error}") from None
    if path.suffix.lower() == ".csv":
        entries, options = _csv_entries(path, text), {}
    elif path.suffix.lower() in (".yaml", ".yml"):
        entries, options = _yaml_entries(path, text)
    else:
        raise BatchFileError(path, "", f"unknown batch file type {path.suffix!r}; use .yaml, .yml or .csv")
    if not entries:
        raise BatchFileError(path, "checks", "no check listed")
    scenarios = {}
    checks = [_check(path, index, entry, scenarios) for index, entry in enumerate(entries)]
    ids = [c.id for c in checks]
    repeated = sorted({i for i in ids if ids.count(i) > 1})
    if repeated:
        raise BatchFileError(path, "checks", f"repeated id(s) {repeated}: each check needs its own")
    return tuple(checks), options


def _yaml_entries(path, text):
    import yaml

    from environments.plain_data import load_yaml

    try:
        data = load_yaml(text)
    except yaml.YAMLError as error:
        raise BatchFileError(path, "", f"not valid YAML: {error}") from None
    if isinstance(data, list):
        data = {"checks": data}
    if not isinstance(data, dict):
        raise BatchFileError(path, "", "expected a mapping with a 'checks' list (or a list of checks)")
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise BatchFileError(path, "", f"unknown key(s) {unknown}; valid keys: {list(_TOP_KEYS)}")
    entries = data.get("checks")
    if not isinstance(entries, list):
        raise BatchFileError(path, "checks", f"must be a list of checks, got {type(entries).__name__}")
    options = data.get("solver_options") or {}
    if not isinstance(options, dict):
        raise BatchFileError(path, "solver_options", f"must be a mapping, got {type(options).__name__}")
    return entries, options


def _csv_entries(path, text):
    rows = list(csv.DictReader(text.splitlines()))
    if rows and None in rows[0]:
        raise BatchFileError(path, "row 1", "more values than columns")
    return [{key: value for key, value in row.items() if value not in ("", None)} for row in rows]


def _check(path, index, entry, scenarios):
    where = f"checks[{index}]"
    if not isinstance(entry, dict):
        raise BatchFileError(path, where, f"must be a mapping with keys {list(_CHECK_KEYS)}, got {type(entry).__name__}")
    unknown = sorted(set(entry) - set(_CHECK_KEYS))
    if unknown:
        raise BatchFileError(path, where, f"unknown key(s) {unknown}; valid keys: {list(_CHECK_KEYS)}")
    for key in ("scenario", "stance"):
        if key not in entry:
            raise BatchFileError(path, where, f"missing key {key!r}")
    reference = str(entry["scenario"])
    if reference not in scenarios:
        scenarios[reference] = _scenario(path, where, reference)
    scenario = scenarios[reference]
    stance = _stance(path, where, entry["stance"], scenario)
    robot = str(entry.get("robot") or scenario.robot)
    return Check(
        id=str(entry.get("id", index)),
        scenario_text=scenario.text,
        scenario_path=None if scenario.path is None else os.fspath(scenario.path),
        stance=stance.to_dict(),
        robot=robot,
    )


def _scenario(path, where, reference):
    import environments
    from environments.errors import SceneError

    candidate = Path(reference)
    if not candidate.is_absolute() and reference not in environments.scenario_names():
        candidate = path.parent / candidate
    if reference not in environments.scenario_names() and not candidate.is_file():
        raise BatchFileError(
            path, f"{where}.scenario",
            f"{reference!r} is neither a file nor a built-in scenario ({', '.join(environments.scenario_names())})",
        )
    try:
        return environments.load(reference if reference in environments.scenario_names() else candidate)
    except SceneError as error:
        raise BatchFileError(path, f"{where}.scenario", str(error)) from None


def _stance(path, where, value, scenario):
    from environments import Stance
    from environments.errors import SceneError

    if isinstance(value, str):
        if value not in scenario.stances:
            raise BatchFileError(
                path, f"{where}.stance",
                f"unknown stance {value!r} in scenario {scenario.name!r}; its stances: {', '.join(scenario.stances)}",
            )
        return scenario.stances[value]
    try:
        stance = Stance.from_dict(value)
        for contact in stance:
            scenario.scene.surface(contact.contact_print.surface)
    except SceneError as error:
        raise BatchFileError(path, f"{where}.stance", str(error)) from None
    return stance


# Robots and scenes built by this process, by Check.world_key: each worker
# process builds a world once and reuses it for every check naming it.
_WORLDS = {}


def _world(check):
    if check.world_key not in _WORLDS:
        import environments
        import stances

        scenario = environments.load_string(check.scenario_text, check.scenario_path)
        _WORLDS[check.world_key] = (scenario.name, stances.Robot.load(check.robot), scenario.scene)
    return _WORLDS[check.world_key]


def run_check(check, solver_options=None) -> CheckOutcome:
    """Solve and verify one check, cold-started, in this process.

    Parameters
    ----------
    check : Check
    solver_options : dict, optional
        Keyword arguments of ``stances.solve``.

    Returns
    -------
    CheckOutcome
        Infeasible with the reason for a stance the solver refuses (e.g. a
        print covering too few FEM nodes).
    """
    from environments import Stance

    from .planner import PostureOracle

    started = time.perf_counter()
    name, robot, scene = _world(check)
    stance = Stance.from_dict(check.stance)
    solve_started = time.perf_counter()
    answer = PostureOracle(robot, scene, solver_options)(stance)
    solve_time = time.perf_counter() - solve_started
    result = answer.result
    forces = () if result is None else tuple(result.point_forces)
    return CheckOutcome(
        id=check.id,
        scenario=name,
        robot=check.robot,
        stance=check.stance,
        feasible=bool(answer.feasible),
        reason=str(answer.reason),
        q=np.zeros(0) if result is None else np.asarray(result.q, dtype=float),
        force_frames=tuple(p.frame for p in forces),
        force_points=np.array([p.point for p in forces], dtype=float).reshape(-1, 3),
        forces=np.array([p.force for p in forces], dtype=float).reshape(-1, 3),
        solve_time=solve_time,
        check_time=time.perf_counter() - started,
    )
