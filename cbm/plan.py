"""A plan: the sequence of verified stances, saved to and read from JSON.

The file (``plan.json``, format ``softcbm-plan`` version 7) describes itself: its
``units`` and ``frames`` say what every number is, ``robot`` names each
coordinate of ``q`` and each torque and gives the locked joints' values (the
robot's full configuration), and ``scenario`` embeds the scenario's YAML so that
:meth:`Plan.check` works on the file anywhere. Each value is stored once: a
stance's posture, forces and displacements are not repeated in its solver
summary. Version 1 files (before these headers) are read as they are, and the results of
versions 1 to 4 as solved with the options then the defaults (:data:`SOLVED_AS`; versions 3
to 6 have version 2's layout, version 4's soft prints solved against the turned faces, version
5's with a small-slip bound of a quarter of the mesh's spacing, version 6's kept soft prints
from where the stance before left them: each result's ``slips`` and ``held_slips``; version 7
marks the stances whose answer starts where the motion into them left them,
``arrived_by_motion``, false in earlier files); a file with no version or an unknown one is
refused with the versions this library reads.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import environments
import stances
from environments.scenario import SCENARIO_DIRECTORY
from environments.stance import Stance
from stances.results import PointForce, PostureResult, one_line
from stances.stages import posture_options

from .errors import PlanFileError
from .search import SearchStatistics
from .slip_chain import unkept_slips
from .stance_graph import differ_by_one_contact

__all__ = [
    "PlannedStance",
    "PlanStatistics",
    "Plan",
    "PlanCheck",
    "as_point_force",
    "robot_description",
    "scenario_source",
    "PLAN_VERSION",
    "READABLE_VERSIONS",
    "SOLVED_AS",
]

logger = logging.getLogger(__name__)

PLAN_FORMAT = "softcbm-plan"
#: Open stances a plan keeps of where its search would have gone on (:attr:`Plan.frontier`).
FRONTIER_SIZE = 5
PLAN_VERSION = 7
#: Versions :meth:`Plan.load` reads; version 1 has no headers and repeats each
#: stance's arrays inside its ``result``. Versions 1 to 3 were solved before the contact
#: frames turned with the links' faces (``stances.PostureOptions.contact_frames``,
#: 2026-12-06), version 3 with a 1 degree tilt allowance by default, versions 1 to 4 with a
#: 2 cm small-slip bound (``max_slip``; a quarter of the mesh's spacing since version 5):
#: their results read as solved so (:data:`SOLVED_AS`), and are checked so.
READABLE_VERSIONS = (1, 2, 3, 4, 5, 6, 7)
#: The posture options a result of an earlier version was solved with where it recorded
#: none (they were the defaults then).
SOLVED_AS = {1: {"contact_frames": "rest", "max_slip": 0.02}, 2: {"contact_frames": "rest", "max_slip": 0.02},
             3: {"contact_frames": "rest", "tilt_allowance": math.radians(1.0), "max_slip": 0.02},
             4: {"max_slip": 0.02}}

#: Units of every number in a plan file.
UNITS = {"length": "m", "angle": "rad", "force": "N", "torque": "N m", "time": "s", "mass": "kg"}

#: What each stance entry's values are expressed in.
FRAMES = {
    "world": "z up, gravity -9.81 m/s^2 along z; the scenario's frame",
    "q": "configuration of the robot's model without its locked joints: the free flyer's position (m, world) "
    "and orientation quaternion (qx, qy, qz, qw) of the base, then one angle per joint; coordinate names in "
    "robot.configuration_names, values of the locked joints in robot.locked_joints",
    "point_forces": "force_in_world acts ON the robot at point_in_world, both in the world frame; link_frame names "
    "the robot frame of the link it acts on, not a frame it is expressed in",
    "displacements_in_body": "node displacements of each soft body, in its body frame (scenario."
    "transform_body_to_world maps it to the world), nodes in the order of the body's mesh",
    "stance": "each print's x, y (m) and theta (rad) in its surface's frame",
    "move": "how the stance was reached from the previous one, in words",
    "arrived_by_motion": "true where the answer starts its kept soft prints where the motion into it (cbm plan "
    "--motion) left them, not where the stance before did",
    "result.torques": "actuated joint torques, N m, in robot.joint_names order",
}

#: Keys of a solver result that a stance entry holds once, outside its result.
_STANCE_KEYS = ("q", "point_forces", "deformations", "stance")


def _readonly(array, shape_tail=None):
    array = np.array(array, dtype=float)
    if shape_tail is not None:
        array = array.reshape((-1,) + tuple(shape_tail))
    array.setflags(write=False)
    return array


def as_point_force(value):
    """A ``stances.PointForce`` from one, from its dict, or from any object with
    ``frame``, ``point`` (3,) and ``force`` (3,) (world frame, metres, newtons)."""
    if isinstance(value, PointForce):
        return value
    if isinstance(value, dict):
        return PointForce.from_dict(value)
    return PointForce(str(value.frame), value.point, value.force)


@dataclass(frozen=True, eq=False)
class PlannedStance:
    """One stance of a plan with its posture, forces and deformations.

    Parameters
    ----------
    stance : environments Stance
        The contacts.
    q : (nq,) float
        Configuration (pinocchio, free flyer first), read-only.
    point_forces : tuple of stances.PointForce
        Contact forces on the robot, world frame.
    deformations : dict of str to (N, 3) float
        Node displacements of each deformable object, metres, body frame.
    result : stances PostureResult or dict
        The solver's result; after :meth:`Plan.load`, its ``to_dict`` form
        unless stances can rebuild it.
    move : str
        How this stance was reached from the previous one ("" for the start).
    arrived_by_motion : bool
        Whether its answer starts the soft prints it keeps where the motion into it left
        them (:attr:`cbm.motion.Motion.arrival`), which under Coulomb friction moved them
        on from where the stance before left them: :func:`cbm.motion.verify_motion` checks
        that chain, the plan alone does not hold the motion's samples.
    """

    stance: Any
    q: np.ndarray
    point_forces: tuple = ()
    deformations: dict = field(default_factory=dict)
    result: Any = None
    move: str = ""
    arrived_by_motion: bool = False

    def __post_init__(self):
        object.__setattr__(self, "q", _readonly(self.q))
        object.__setattr__(
            self, "point_forces", tuple(as_point_force(f) for f in self.point_forces)
        )
        object.__setattr__(
            self,
            "deformations",
            {str(k): _readonly(v, (3,)) for k, v in dict(self.deformations or {}).items()},
        )

    def answered(self, result, arrived_by_motion=False) -> "PlannedStance":
        """This stance with another answer of its solver (a posture solved again): its
        posture, forces and fields those of ``result``, a ``stances.PostureResult``."""
        return replace(self, q=result.q, point_forces=tuple(result.point_forces),
                       deformations=dict(result.deformations or {}), result=result,
                       arrived_by_motion=arrived_by_motion)

    @property
    def contact_forces(self):
        """(n, 3) float: every point force, newtons, world frame."""
        return np.array([f.force for f in self.point_forces]).reshape(-1, 3)

    def to_dict(self):
        """Plain JSON-ready data (version 2: each value once, frames in the key names)."""
        result = self.result
        if result is not None and not isinstance(result, dict):
            result = result.to_dict() if hasattr(result, "to_dict") else None
        if result is not None:
            result = {key: value for key, value in result.items() if key not in _STANCE_KEYS}
        return {
            "stance": self.stance.to_dict(),
            "move": self.move,
            "q": self.q.tolist(),
            "point_forces": [
                {"link_frame": f.frame, "point_in_world": f.point.tolist(), "force_in_world": f.force.tolist()}
                for f in self.point_forces
            ],
            "displacements_in_body": {k: v.tolist() for k, v in self.deformations.items()},
            "result": _jsonable(result),
            "arrived_by_motion": bool(self.arrived_by_motion),
        }

    @classmethod
    def from_dict(cls, data, version=PLAN_VERSION):
        """Inverse of :meth:`to_dict`; ``version`` the file's (version 1's layout, and the options
        an earlier version's result was solved with: :data:`SOLVED_AS`)."""
        if version == 1:
            forces = [as_point_force(f) for f in data["point_forces"]]
            deformations = data.get("deformations", {})
            result = data.get("result")
        else:
            forces = [PointForce(f["link_frame"], f["point_in_world"], f["force_in_world"]) for f in data["point_forces"]]
            deformations = data.get("displacements_in_body", {})
            result = data.get("result")
            if result is not None:
                # The solver's result, whole again: what it shares with the stance is stored there.
                shared = [f.to_dict() for f in forces]
                result = {**result, "q": data["q"], "point_forces": shared, "deformations": deformations,
                          "stance": data["stance"]}
        if version in SOLVED_AS and isinstance(result, dict):
            statistics = dict(result.get("statistics") or {})
            statistics["options"] = {**SOLVED_AS[version], **(statistics.get("options") or {})}
            result = {**result, "statistics": statistics}
        return cls(
            stance=Stance.from_dict(data["stance"]),
            q=data["q"],
            point_forces=tuple(forces),
            deformations=deformations,
            result=_rebuild_result(result),
            move=data.get("move", ""),
            arrived_by_motion=bool(data.get("arrived_by_motion", False)),
        )


@dataclass(frozen=True)
class PlanStatistics(SearchStatistics):
    """Effort spent on a plan: the search's counters and the prints sampled.

    ``cpu_time`` adds the worker processes' CPU seconds to this process's (a plan with
    ``workers > 1``), and like every counter it covers every search the plan ran.

    Parameters
    ----------
    prints : int
        Prints sampled (all robot surfaces); the other fields are
        :class:`~cbm.search.SearchStatistics`'.
    prefiltered : dict of str to int
        Stances rejected without a posture solve, by the cheap check that
        rejected them (``StanceCheck.rejected_by``); they are among the
        ``solver_calls`` (oracle answers), so the posture solves were
        ``solver_calls - sum(prefiltered.values())``.
    print_spacing : float or None
        Step of the print grid the plan was found on (or last searched), metres;
        None where not recorded (a plan file written before it was).
    """

    prints: int = 0
    prefiltered: dict = field(default_factory=dict)
    print_spacing: float | None = None


@dataclass(frozen=True)
class PlanCheck:
    """Outcome of :meth:`Plan.check`.

    Parameters
    ----------
    ok : bool
        True if every stance verifies and every transition changes one contact.
    problems : tuple of str
        What failed, one line each.
    """

    ok: bool
    problems: tuple = ()


@dataclass(frozen=True, eq=False, repr=False)
class Plan:
    """A sequence of stances from the start towards the goal.

    Its ``repr`` is one line (scenario, verdict, stances, effort); the stances, with their
    postures and forces, are in :attr:`stances`.

    Parameters
    ----------
    success : bool
        True if the last stance satisfies the goal.
    reason : str
        ``"goal reached"`` or why the search stopped.
    stances : tuple of PlannedStance
        The sequence; on failure, the best partial sequence found.
    statistics : PlanStatistics
        Effort counters.
    scenario_name : str
        Scenario planned for.
    rejections : dict
        Stances the search rejected, by cause (:func:`cbm.rejections.summarise`):
        ``{cause: {"count": int, "example": str}}``.
    robot : dict
        The robot planned for (:func:`robot_description`): ``name``, ``urdf``,
        ``configuration_names``, ``joint_names``, ``locked_joints``, ``mass``.
    scenario_source : dict
        Where the scenario came from (:func:`scenario_source`): ``path``,
        ``built_in``, its YAML ``text`` and each soft body's
        ``transform_body_to_world``.
    frontier : tuple of dict
        The search's open stances nearest the goal when it stopped, nearest first
        (at most :data:`FRONTIER_SIZE`): ``goal_distance`` (the heuristic, metres),
        ``stance`` (its contacts, each print in its surface's frame) and ``move``,
        the step that reached it from a stance the search expanded.
        Where a failed search would have gone on.
    """

    success: bool
    reason: str
    stances: tuple
    statistics: PlanStatistics
    scenario_name: str = ""
    rejections: dict = field(default_factory=dict)
    robot: dict = field(default_factory=dict)
    scenario_source: dict = field(default_factory=dict)
    frontier: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "stances", tuple(self.stances))
        object.__setattr__(self, "frontier", tuple(dict(entry) for entry in self.frontier))

    def __len__(self):
        return len(self.stances)

    def __repr__(self) -> str:
        s = self.statistics
        return (f"Plan({self.scenario_name!r}, success={self.success}, reason={one_line(self.reason, 160)!r}, "
                f"{len(self.stances)} stances, {s.expanded} expanded, {s.solver_calls} solver calls, {s.time:.3g} s)")

    def to_dict(self):
        """Plain JSON-ready data, with the headers that describe it (units, frames, robot, scenario)."""
        return {
            "format": PLAN_FORMAT,
            "version": PLAN_VERSION,
            "units": dict(UNITS),
            "frames": dict(FRAMES),
            "robot": _jsonable(self.robot),
            "scenario": {"name": self.scenario_name, **_jsonable(self.scenario_source)},
            "success": self.success,
            "reason": self.reason,
            "statistics": self.statistics.to_dict(),
            "rejections": dict(self.rejections),
            "frontier": [dict(entry) for entry in self.frontier],
            "stances": [s.to_dict() for s in self.stances],
        }

    @classmethod
    def from_dict(cls, data):
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        PlanFileError
            If the data is not a plan of a known version.
        """
        if not isinstance(data, dict) or data.get("format") != PLAN_FORMAT:
            raise PlanFileError(f"not a plan: expected format {PLAN_FORMAT!r}")
        version = data.get("version")
        if version not in READABLE_VERSIONS:
            readable = ", ".join(map(str, READABLE_VERSIONS))
            raise PlanFileError(
                f"plan version {version!r} is not supported: this softcbm reads versions {readable}; "
                "plan the scenario again with this version (cbm plan)"
            )
        try:
            if version == 1:
                scenario_name, source, robot = str(data.get("scenario", "")), {}, {}
            else:
                source = dict(data["scenario"])
                scenario_name, robot = str(source.pop("name")), dict(data["robot"])
            return cls(
                success=bool(data["success"]),
                reason=str(data["reason"]),
                stances=tuple(PlannedStance.from_dict(s, version) for s in data["stances"]),
                statistics=PlanStatistics(**data["statistics"]),
                scenario_name=scenario_name,
                rejections=dict(data.get("rejections", {})),
                robot=robot,
                scenario_source=source,
                frontier=tuple(data.get("frontier", ())),
            )
        except (KeyError, TypeError) as error:
            raise PlanFileError(f"malformed plan (version {version}): missing or wrong entry {error}") from None

    def save(self, path):
        """Write the plan as JSON (arrays as lists).

        Parameters
        ----------
        path : path-like
            Output file.
        """
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=True))
        logger.debug("plan written to %s", path)
        return path

    @classmethod
    def load(cls, path):
        """Read a plan written by :meth:`save`.

        Raises
        ------
        PlanFileError
            If the file is not valid JSON or not a plan.
        """
        try:
            data = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as error:
            raise PlanFileError(f"cannot read plan {path}: {error}") from None
        return cls.from_dict(data)

    def check(self, scenario=None, robot=None, options=None):
        """Re-verify every stance, every transition and the outcome.

        Each stance is checked by ``stances.verify`` (independent of the
        solver) on the posture, forces and displacement fields the plan shows
        (``q``, ``point_forces`` and ``deformations`` of each stance, not a copy
        inside its result), with
        the posture options its result was solved with. Consecutive stances
        must differ by exactly one contact, each must start the soft prints it keeps
        where the stance before left them (one that ``arrived_by_motion`` where its
        motion left them: :func:`cbm.motion.verify_motion` checks that), and a plan
        that says it succeeded must end on a stance that reaches the scenario's goal.

        Parameters
        ----------
        scenario : environments Scenario, optional
            Default: the scenario embedded in the plan (its YAML text, read
            again; mesh files it names are looked for beside its original
            path), else the built-in scenario ``scenario_name``.
        robot : stances Robot, optional
            Default: the robot the plan names, else the scenario's.
        options : dict, optional
            Posture options (:class:`stances.PostureOptions`) over those each stance
            recorded: a plan saved before an option existed recorded none, and is
            checked with its default (``{"ball_force_error": float("inf")}`` checks a
            plan made before 2026-12-05 as it was solved, its ball feet on nodes the
            mesh does not resolve accepted).

        Raises
        ------
        stances.StanceError
            For an option that is no posture option, or a bad value.

        Returns
        -------
        PlanCheck
        """
        options = dict(options or {})
        posture_options(options)  # a typo or a bad value is an error, not an option ignored
        if scenario is None:
            scenario = self.scenario()
        if robot is None:
            robot = self.robot_model(scenario)
        problems = []
        for index, planned in enumerate(self.stances):
            result = planned.result
            if result is None or isinstance(result, dict):
                problems.append(f"stance {index}: no solver result to verify")
                continue
            # What the plan shows is what is checked.
            # With the options the stance was solved with, which its result records.
            shown = replace(result, q=planned.q, point_forces=planned.point_forces, deformations=planned.deformations)
            verification = stances.verify(robot, scenario.scene, planned.stance, shown, **options)
            if not verification.ok:
                problems.append(f"stance {index}: " + "; ".join(map(str, verification.reasons)))
        for index, (before, after) in enumerate(zip(self.stances, self.stances[1:])):
            if not differ_by_one_contact(before.stance, after.stance):
                problems.append(f"stances {index} -> {index + 1} do not differ by exactly one contact")
            if not after.arrived_by_motion:  # (else the motion's chain: cbm.motion.verify_motion)
                problems.extend(f"stances {index} -> {index + 1}: {problem}" for problem in unkept_slips(before, after))
        goal = getattr(scenario, "goal", None)
        if self.success and goal is not None:
            if not self.stances or not goal.is_satisfied(self.stances[-1].stance, scenario.scene):
                problems.append("the plan says it succeeded but its last stance does not reach the scenario's goal")
        return PlanCheck(not problems, tuple(problems))


    def show(self, scenario=None, robot=None, motions=(), viewer=None, play=True, **timing):
        """Open the plan in meshcat (an optional dependency) and step through it once.

        Parameters
        ----------
        scenario, robot : optional
            As for :meth:`check`.
        motions : sequence of cbm.motion.Motion, optional
            Played between the stances.
        viewer : meshcat.Visualizer, optional
            Default: a new one, with its own local server (its address is logged).
        play : bool
            Step through the stances (else stay on the first).
        **timing
            ``stance_seconds``, ``sample_seconds`` of :meth:`cbm.live.LiveView.play`.

        Returns
        -------
        cbm.live.LiveView

        Raises
        ------
        cbm.live.LiveViewUnavailable
            If meshcat is not installed (the message says how to install it).
        """
        from .live import LiveView, meshcat_module

        meshcat_module()  # before loading anything: a missing meshcat is said at once
        if scenario is None:
            scenario = self.scenario()
        if robot is None:
            robot = self.robot_model(scenario)
        view = LiveView(self, scenario, robot, motions, viewer)
        logger.info("plan shown in meshcat at %s", view.url)
        if play:
            view.play(**timing)
        return view

    def robot_model(self, scenario=None):
        """The robot planned for, loaded again: from its description file, or from the
        copy of it the plan carries where that file is gone (its relative model paths
        then read from where the file was), or the built-in robot the scenario names.

        Parameters
        ----------
        scenario : environments Scenario, optional
            Default: :meth:`scenario`.

        Returns
        -------
        stances Robot
        """
        carried = self._carried_robot_file()
        if carried is not None:
            return stances.Robot.from_description(stances.read_description_text(self.robot["text"], carried))
        return stances.Robot.load(self.robot.get("source") or (scenario or self.scenario()).robot)

    def _carried_robot_file(self):
        """The robot's description file where it is gone and the plan carries its text
        (:func:`robot_description`), else None."""
        source = self.robot.get("source")
        if self.robot.get("text") is not None and source and not Path(source).is_file():
            return source
        return None

    def scenario(self):
        """The scenario planned: the embedded YAML read again, else the built-in one by name
        (its robot file, when the plan carries a copy of it, need not exist any more).

        Raises
        ------
        environments.ScenarioError
            If the embedded text no longer reads (e.g. a mesh file it names is
            gone), or there is no embedded text and no built-in scenario of
            that name.
        """
        text = self.scenario_source.get("text")
        if text is None:
            return environments.load(self.scenario_name)
        # A robot file the plan carries a copy of need not be there any more (robot_model reads the copy).
        return environments.load_string(text, path=self.scenario_source.get("path"), name=self.scenario_name,
                                        robot=self._carried_robot_file())

    def full_configuration(self, index):
        """Stance ``index``'s configuration with the locked joints, by coordinate name.

        Parameters
        ----------
        index : int
            Stance number.

        Returns
        -------
        dict of str to float
            ``robot.configuration_names`` with the values of ``q``, then each
            locked joint's coordinates (``<joint>`` or ``<joint>:i``) at its
            locked value: every coordinate of the robot's URDF.

        Raises
        ------
        PlanFileError
            If the plan does not describe its robot (a version 1 file).
        """
        names = self.robot.get("configuration_names")
        if names is None:
            raise PlanFileError("this plan does not name its configuration coordinates (a version 1 file)")
        values = dict(zip(names, self.stances[index].q.tolist()))
        for joint, locked in self.robot.get("locked_joints", {}).items():
            if len(locked) == 1:
                values[joint] = float(locked[0])
            else:
                values.update({f"{joint}:{i}": float(v) for i, v in enumerate(locked)})
        return values


def robot_description(robot):
    """What a plan file says about its robot.

    Parameters
    ----------
    robot : stances Robot

    Returns
    -------
    dict
        ``name``, ``source`` (what ``stances.Robot.load`` loads it from again: a
        built-in name or a description file; empty for a robot built in code),
        ``urdf`` (path or None),
        ``configuration_names`` (nq,), ``joint_names`` (actuated joints, torque
        order), ``locked_joints`` (name -> locked coordinate values),
        ``mass`` (kg) and, for a robot of a user's description file, its
        ``text``: the plan loads its robot from it where the file is gone
        (:meth:`Plan.robot_model`).
    """
    urdf = getattr(robot, "urdf", None)
    source = str(getattr(robot, "source", ""))
    described = {
        "name": robot.name,
        "source": source,
        "urdf": None if urdf is None else str(urdf),
        "configuration_names": list(robot.configuration_names),
        "joint_names": list(robot.actuated_joint_names),
        "locked_joints": {name: list(values) for name, values in getattr(robot, "locked_joints", {}).items()},
        "mass": float(robot.mass),
    }
    if source and source not in stances.builtin_robot_names() and Path(source).is_file():
        described["text"] = Path(source).read_text(encoding="utf-8")
    return described


def scenario_source(scenario):
    """What a plan file says about its scenario's origin.

    Parameters
    ----------
    scenario : environments Scenario

    Returns
    -------
    dict
        ``path`` (absolute str or None: a plan is checked from anywhere, so a
        scenario named relative to the working directory, with its robot file and
        mesh files relative to it, is found again from another one), ``built_in``
        (bool), ``robot`` (the robot name
        the scenario asks for), ``text`` (its YAML, None for a scenario built in
        code) and ``transform_body_to_world`` ((4, 4) float of each soft body,
        by object name).
    """
    path = getattr(scenario, "path", None)
    path = None if path is None else Path(path).resolve()
    built_in = path is not None and path.parent == SCENARIO_DIRECTORY
    return {
        "path": None if path is None else str(path),
        "built_in": bool(built_in),
        "robot": scenario.robot,
        "text": getattr(scenario, "text", None),
        "transform_body_to_world": {
            obj.name: np.asarray(obj.transform_body_to_world).tolist() for obj in scenario.scene.deformable_objects
        },
    }


def _jsonable(value):
    """Numpy arrays and scalars inside nested data to lists and floats."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _rebuild_result(data):
    """A stances PostureResult from its ``to_dict`` form, else the dict itself."""
    if data is None:
        return None
    try:
        return PostureResult.from_dict(data)
    except (KeyError, TypeError, ValueError) as error:
        logger.debug("solver result kept as a dict (%s)", error)
        return data
