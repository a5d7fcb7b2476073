"""A plan: the sequence of verified stances, saved to and read from JSON."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from environments.stance import Stance
from stances.results import PointForce

from .errors import PlanFileError
from .search import SearchStatistics
from .stance_graph import differ_by_one_contact

__all__ = ["PlannedStance", "PlanStatistics", "Plan", "PlanCheck", "as_point_force"]

logger = logging.getLogger(__name__)

PLAN_FORMAT = "softcbm-plan"
PLAN_VERSION = 1


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
    """

    stance: Any
    q: np.ndarray
    point_forces: tuple = ()
    deformations: dict = field(default_factory=dict)
    result: Any = None
    move: str = ""

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

    @property
    def contact_forces(self):
        """(n, 3) float: every point force, newtons, world frame."""
        return np.array([f.force for f in self.point_forces]).reshape(-1, 3)

    def to_dict(self):
        """Plain JSON-ready data."""
        result = self.result
        if result is not None and not isinstance(result, dict):
            result = result.to_dict() if hasattr(result, "to_dict") else None
        return {
            "stance": self.stance.to_dict(),
            "move": self.move,
            "q": self.q.tolist(),
            "point_forces": [f.to_dict() for f in self.point_forces],
            "deformations": {k: v.tolist() for k, v in self.deformations.items()},
            "result": _jsonable(result),
        }

    @classmethod
    def from_dict(cls, data):
        """Inverse of :meth:`to_dict`."""
        return cls(
            stance=Stance.from_dict(data["stance"]),
            q=data["q"],
            point_forces=tuple(as_point_force(f) for f in data["point_forces"]),
            deformations=data.get("deformations", {}),
            result=_rebuild_result(data.get("result")),
            move=data.get("move", ""),
        )


@dataclass(frozen=True)
class PlanStatistics(SearchStatistics):
    """Effort spent on a plan: the search's counters and the prints sampled.

    Parameters
    ----------
    prints : int
        Prints sampled (all robot surfaces); the other fields are
        :class:`~cbm.search.SearchStatistics`'.
    """

    prints: int = 0


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


@dataclass(frozen=True, eq=False)
class Plan:
    """A sequence of stances from the start towards the goal.

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
    robot : str
        Robot planned for: a built-in robot name or a robot description file;
        empty for the scenario's robot.
    """

    success: bool
    reason: str
    stances: tuple
    statistics: PlanStatistics
    scenario_name: str = ""
    rejections: dict = field(default_factory=dict)
    robot: str = ""

    def __post_init__(self):
        object.__setattr__(self, "stances", tuple(self.stances))

    def __len__(self):
        return len(self.stances)

    def to_dict(self):
        """Plain JSON-ready data."""
        return {
            "format": PLAN_FORMAT,
            "version": PLAN_VERSION,
            "scenario": self.scenario_name,
            "robot": self.robot,
            "success": self.success,
            "reason": self.reason,
            "statistics": self.statistics.to_dict(),
            "rejections": dict(self.rejections),
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
        if data.get("version") != PLAN_VERSION:
            raise PlanFileError(f"plan version {data.get('version')!r} is not supported (expected {PLAN_VERSION})")
        try:
            return cls(
                success=bool(data["success"]),
                reason=str(data["reason"]),
                stances=tuple(PlannedStance.from_dict(s) for s in data["stances"]),
                statistics=PlanStatistics(**data["statistics"]),
                scenario_name=str(data.get("scenario", "")),
                rejections=dict(data.get("rejections", {})),
                robot=str(data.get("robot", "")),
            )
        except (KeyError, TypeError) as error:
            raise PlanFileError(f"malformed plan: {error}") from None

    def save(self, path):
        """Write the plan as JSON (arrays as lists).

        Parameters
        ----------
        path : path-like
            Output file.
        """
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=True))
        logger.info("plan written to %s", path)
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

    def check(self, scenario=None, robot=None):
        """Re-verify every stance, every transition and the outcome.

        Each stance is checked by ``stances.verify`` (independent of the
        solver) on the posture and forces the plan shows (``q`` and
        ``point_forces`` of each stance, not a copy inside its result), with
        the posture options its result was solved with. Consecutive stances
        must differ by exactly one contact, and a plan that says it succeeded
        must end on a stance that reaches the scenario's goal.

        Parameters
        ----------
        scenario : environments Scenario, optional
            Loaded from ``scenario_name`` if not given.
        robot : stances Robot, optional
            Loaded from the plan's robot (else the scenario's) if not given.

        Returns
        -------
        PlanCheck
        """
        import environments
        import stances

        from .planner import posture_api

        if scenario is None:
            scenario = environments.load(self.scenario_name)
        if robot is None:
            robot = stances.Robot.load(self.robot or scenario.robot)
        verify = None
        problems = []
        for index, planned in enumerate(self.stances):
            result = planned.result
            if result is None or isinstance(result, dict):
                problems.append(f"stance {index}: no solver result to verify")
                continue
            if verify is None:
                verify = posture_api()[1]
            # What the plan shows is what is checked.
            shown = replace(result, q=planned.q, point_forces=planned.point_forces)
            options = dict(getattr(result, "statistics", {}).get("options", {}))
            verification = verify(robot, scenario.scene, planned.stance, shown, **options)
            if not verification.ok:
                problems.append(f"stance {index}: " + "; ".join(map(str, verification.reasons)))
        for index, (before, after) in enumerate(zip(self.stances, self.stances[1:])):
            if not differ_by_one_contact(before.stance, after.stance):
                problems.append(f"stances {index} -> {index + 1} do not differ by exactly one contact")
        goal = getattr(scenario, "goal", None)
        if self.success and goal is not None:
            if not self.stances or not goal.is_satisfied(self.stances[-1].stance, scenario.scene):
                problems.append("the plan says it succeeded but its last stance does not reach the scenario's goal")
        return PlanCheck(not problems, tuple(problems))


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
    from stances.results import PostureResult

    try:
        return PostureResult.from_dict(data)
    except (KeyError, TypeError, ValueError) as error:
        logger.debug("solver result kept as a dict (%s)", error)
        return data
