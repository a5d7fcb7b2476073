"""What a posture solve returns: values that can check themselves."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from environments import Stance

from .errors import StanceError


def _readonly(array) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array


class LazyDeformations(Mapping):
    """Displacement fields computed on first access, then kept.

    A full field costs sparse solves on the whole body; a search loop that
    only needs feasibility should not pay for it, a picture or a file should.

    Parameters
    ----------
    producers : dict of str to callable
        Object name -> function returning its (N, 3) field, metres, body frame.
    """

    def __init__(self, producers):
        self._producers = dict(producers)
        self._fields = {}

    def provide(self, fields) -> None:
        """Keep fields computed elsewhere from the same inputs (:func:`stances.verify`
        solves each soft body under the result's forces anyway), so that a first
        access pays nothing.

        Parameters
        ----------
        fields : dict of str to (N, 3) float
            Object name -> displacement field, metres, body frame; names this
            mapping does not hold, or holds already, are left alone.
        """
        for name, value in fields.items():
            if name in self._producers and name not in self._fields:
                value = np.array(value, dtype=float)
                value.setflags(write=False)
                self._fields[name] = value

    def __getitem__(self, name):
        if name not in self._fields:
            field_ = np.array(self._producers[name](), dtype=float)
            field_.setflags(write=False)
            self._fields[name] = field_
        return self._fields[name]

    def __iter__(self):
        return iter(self._producers)

    def __len__(self):
        return len(self._producers)

    def __repr__(self):
        return f"LazyDeformations({sorted(self._producers)})"


@dataclass(frozen=True)
class SolveStatistics(Mapping):
    """What a posture solve records of itself, typed; read as a mapping too.

    Every field is optional (None: not recorded, and then not among the keys),
    so ``result.statistics.get("rigid_warm_start_iterations")`` and
    ``"options" in result.statistics`` read as they would on a dict; ``lambda``
    is the key of :attr:`lam`.

    Parameters
    ----------
    status : str
        How the SQP stopped ("converged", "stagnated", ...), or why none ran ("time budget
        spent" during a print's setup, "ball refused before solving").
    violation : float
        Largest constraint violation at the answer, in row scales.
    objective : float
        The objective at the answer (posture, torque usage, force and soft-print terms, as
        :class:`~stances.PostureOptions` weighs them): two answers of one stance with the
        same options compare by it. The SQP's last model's: the torque-usage term counts
        once the iterate came within 0.1 (scaled) of feasibility, so an answer that never
        did (an infeasible one) has it without that term. An answer in the stiff limit
        (``stiff_limit``) has its stiff prints' force term on W, the wrench their nodes would
        carry bonded under the motion found, which exceeds the wrench carried where the
        print pivots: a palm on a 1e10 Pa cube held on its edge read 6.30 where its held
        solve's objective was 2.04; compare such answers by their postures and forces. An
        answer with ``pressure_spread`` has its held solve's objective (the stiff prints' force
        term the rigid contact's).
    penalty : float
        The elastic penalty at the end.
    qp_time : float
        Seconds in the QP subproblems.
    curvature_iterations : int
        Iterations whose QP carried the configuration's curvature
        (``PostureOptions.constraint_curvature``; the force variables' curvature of soft
        Coulomb contacts and balls on layers is not counted).
    corrections : int
        Full steps the line search took with a second-order correction, in the SQP run
        that gave the answer (a soft stance's warm starts not counted).
    lam : tuple of float
        The contact variables at the answer (``lam_init`` of a restart).
    sqp_time : float
        Seconds of the whole solve, warm starts and verification included.
    options : dict
        The posture options that differ from their defaults.
    rigid_warm_start_iterations : int
        Iterations of the warm starts of a soft stance.
    bonded_warm_start : bool
        A soft stance's Coulomb solve from its rigid answer's forces failed near
        feasible, and it was solved again from the bonded model's answer (the
        earlier pipeline).
    stiff_limit : bool
        A soft stance solved in its bodies' stiff limit (``PostureOptions.stiff_limit``):
        its soft prints held rigid where their nodes are, then the links' motion found
        whose Coulomb forces carry that answer.
    pressure_spread : bool
        An answer in the stiff limit whose stiff prints' node forces are, each print, the
        least-energy pressure under its face carrying the held answer's wrench, the face held
        where the body gives under it (:meth:`stances.deformable.DeformableContact.spread_forces`),
        not the forces of its link's own Coulomb contact, which carried that answer only
        pivoting onto the partly covered nodes past an edge.
    first_start : dict
        A solve given no posture that failed from the reaching start
        (:func:`stances.reaching_configuration`) and was solved again from the reference
        posture over the prints: the first attempt's ``iterations`` and ``reason``.
    """

    status: str | None = None
    violation: float | None = None
    objective: float | None = None
    penalty: float | None = None
    qp_time: float | None = None
    curvature_iterations: int | None = None
    corrections: int | None = None
    lam: tuple | None = None
    sqp_time: float | None = None
    options: dict | None = None
    rigid_warm_start_iterations: int | None = None
    bonded_warm_start: bool | None = None
    stiff_limit: bool | None = None
    pressure_spread: bool | None = None
    first_start: dict | None = None

    _KEYS = {"lambda": "lam"}  # mapping key -> field, where they differ

    @classmethod
    def of(cls, values) -> "SolveStatistics":
        """From a mapping (a dict read back from JSON, or a SolveStatistics).

        Raises
        ------
        ValueError
            If a key is not a statistic.
        """
        if isinstance(values, cls):
            return values
        names = {f: f for f in cls.__dataclass_fields__} | cls._KEYS
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise ValueError(f"unknown solve statistics {unknown}; known: {sorted(set(names) - {'lam'})}")
        fields = {names.get(key, key): value for key, value in values.items()}
        casts = {"status": str, "violation": float, "objective": float, "penalty": float, "qp_time": float, "sqp_time": float,
                 "curvature_iterations": int, "corrections": int, "rigid_warm_start_iterations": int, "bonded_warm_start": bool, "stiff_limit": bool,
                 "pressure_spread": bool,
                 "options": dict,
                 "first_start": dict,
                 "lam": lambda v: tuple(float(x) for x in v)}
        return cls(**{name: None if value is None else casts[name](value) for name, value in fields.items()})

    def _field(self, key):
        return self._KEYS.get(key, key)

    def __getitem__(self, key):
        name = self._field(key)
        value = getattr(self, name, None) if name in self.__dataclass_fields__ else None
        if value is None:
            raise KeyError(key)
        return list(value) if name == "lam" else value

    def __iter__(self):
        keys = {v: k for k, v in self._KEYS.items()}
        return iter([keys.get(name, name) for name in self.__dataclass_fields__ if getattr(self, name) is not None])

    def __len__(self):
        return sum(getattr(self, name) is not None for name in self.__dataclass_fields__)

    def to_dict(self) -> dict:
        """JSON-ready (the recorded statistics only)."""
        return {key: self[key] for key in self}


@dataclass(frozen=True)
class PointForce:
    """A force applied ON the robot at a point of one of its links.

    Parameters
    ----------
    frame : str
        Pinocchio frame (of ``robot.model``) attached to the link the force acts on.
    point : (3,) float
        Application point, metres, world frame.
    force : (3,) float
        Force, newtons, world frame.
    """

    frame: str
    point: np.ndarray
    force: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _readonly(self.point))
        object.__setattr__(self, "force", _readonly(self.force))

    def to_dict(self) -> dict:
        """JSON-ready representation."""
        return {"frame": self.frame, "point": self.point.tolist(), "force": self.force.tolist()}

    @classmethod
    def from_dict(cls, data) -> "PointForce":
        """Inverse of :meth:`to_dict`."""
        return cls(data["frame"], data["point"], data["force"])


@dataclass(frozen=True)
class Verification:
    """Outcome of :func:`stances.verify`: independent checks of a posture.

    Attributes
    ----------
    ok : bool
        True when every check passed.
    reasons : tuple of str
        One line per failed check, empty when ``ok``.
    measures : dict
        The measured quantities (residuals, margins), for reports.
    """

    ok: bool
    reasons: tuple = ()
    measures: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class NodeSlips:
    """Where the link points of one soft print lie over its nodes: their slips.

    Under Coulomb friction a print node that slipped stays where it slipped to; the
    next stance of a sequence that keeps the print starts from there (a node that
    sticks keeps its slip). A posture answer gives these for each soft print it
    solved under the ``coulomb`` law (:attr:`PostureResult.slips`), and records
    those it started from (:attr:`PostureResult.held_slips`).

    Parameters
    ----------
    body : str
        The deformable object the print presses.
    nodes : (k,) int
        Mesh node ids of the print, in the body's mesh.
    slips : (k, 3) float
        Each node's link point minus the node's coupling end, turned back by the print's
        turn (so fixed in the link: the next stance turns it with its own), tangential to
        the print's surface at rest, metres, body frame.
    """

    body: str
    nodes: np.ndarray
    slips: np.ndarray

    def __post_init__(self) -> None:
        nodes = np.array(self.nodes, dtype=np.int64).reshape(-1)
        slips = np.array(self.slips, dtype=float)
        if slips.shape != (len(nodes), 3):
            raise StanceError(f"NodeSlips: slips must be ({len(nodes)}, 3) metres, one row a node; "
                              f"got shape {slips.shape}")
        if not np.isfinite(slips).all():
            raise StanceError(f"NodeSlips: slips of nodes {nodes[~np.isfinite(slips).all(axis=1)].tolist()} "
                              "are not finite")
        if len(np.unique(nodes)) != len(nodes):
            raise StanceError("NodeSlips: a node appears more than once; give each node's slip once")
        nodes.setflags(write=False)
        slips.setflags(write=False)
        object.__setattr__(self, "body", str(self.body))
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "slips", slips)

    def __reduce__(self):
        # Through __init__, so that a copy from another process is read-only too.
        return (NodeSlips, (self.body, self.nodes, self.slips))

    def largest(self) -> float:
        """The largest slip, metres."""
        return float(np.linalg.norm(self.slips, axis=1).max(initial=0.0))

    def to_dict(self) -> dict:
        """JSON-ready representation."""
        return {"body": self.body, "nodes": self.nodes.tolist(), "slips": self.slips.tolist()}

    @classmethod
    def from_dict(cls, data) -> "NodeSlips":
        """Inverse of :meth:`to_dict`."""
        return cls(data["body"], data["nodes"], data["slips"])


CONTACT_FRAME_SUFFIX = "_contact"
"""Each robot surface's contact frame is named ``<surface>_contact`` (:class:`stances.Robot`)."""


def contact_frame_name(robot_surface: str) -> str:
    """The name of ``robot_surface``'s contact frame, the frame its point forces name."""
    return f"{robot_surface}{CONTACT_FRAME_SUFFIX}"


def one_line(text, limit: int = 240) -> str:
    """``text`` on one line (runs of white space made one space), cut to at most ``limit``
    characters with ``...`` where longer."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


@dataclass(frozen=True, repr=False)
class PostureResult:
    """A posture solve's answer.

    Its ``repr`` is one line (the verdict, each contact's load, the effort); the arrays
    are in its attributes.

    Attributes
    ----------
    feasible : bool
        True only when the solver converged and :func:`stances.verify` passed.
    q : (nq,) float
        Final configuration of ``robot.model`` (read-only).
    point_forces : tuple of PointForce
        Contact forces on the robot (rigid vertices and deformable print nodes).
    torques : (nv - 6,) float
        Actuated joint torques, N m.
    iterations : int
        SQP iterations.
    solve_time : float
        Seconds.
    reason : str
        Why the stance is infeasible; empty when feasible.
    stance : environments.Stance
    deformations : dict of str to (N, 3) float
        Node displacements of each deformable object touched, metres, body frame.
    verification : Verification or None
    statistics : SolveStatistics
        What the solve records of itself (a mapping given here is read into one).
    limits : dict
        How close the posture comes to the robot's limits: largest torque
        usage and its joint, smallest joint clearance and its joint, and the
        joints on the bound their margin sets (see
        :meth:`stances.problem.PostureProblem.limit_usage`).
    slips : dict of str to NodeSlips, or None
        Robot surface -> where the link points of its soft print lie over the print's
        nodes at this answer: every flat print solved under the ``coulomb`` law (none for
        a ball, nor under the other laws). None: not recorded (the stiff limit's spread
        answers, answers read from files before plan version 6); the next stance then
        starts from rest.
    held_slips : dict of str to NodeSlips
        Robot surface -> the slips this answer started from (``history`` of
        :func:`stances.solve`: the answer before it in a sequence, for each soft print
        both keep); a node that sticks keeps its held slip, one that slips moves on from
        it. Empty: every print from rest.
    """

    feasible: bool
    q: np.ndarray
    point_forces: tuple
    torques: np.ndarray
    iterations: int
    solve_time: float
    reason: str
    stance: object
    deformations: dict = field(default_factory=dict)
    verification: Verification | None = None
    statistics: SolveStatistics = field(default_factory=SolveStatistics)
    limits: dict = field(default_factory=dict)
    slips: dict | None = None
    held_slips: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", _readonly(self.q))
        object.__setattr__(self, "torques", _readonly(self.torques))
        object.__setattr__(self, "statistics", SolveStatistics.of(self.statistics))

    def __repr__(self) -> str:
        verdict = f"feasible={self.feasible}" + ("" if self.feasible else f", reason={one_line(self.reason, 160)!r}")
        loads = ", ".join(f"{label} {np.linalg.norm(total):.1f} N" for label, total in self.contact_loads())
        return (f"PostureResult({verdict}{', ' + loads if loads else ''}, {self.iterations} iterations, "
                f"{self.solve_time:.3g} s)")

    def contact_loads(self) -> list:
        """Each contact's total force on the robot, newtons, world frame, in stance order.

        Returns
        -------
        list of (str, (3,) float)
            ``("<robot surface> on <surface>", total)``; without a stance, by contact frame.
        """
        contacts = getattr(self.stance, "contacts", None)
        if contacts is None:
            frames = dict.fromkeys(p.frame for p in self.point_forces)
            return [(frame, self._sum_on(frame)) for frame in frames]
        return [(f"{c.robot_surface} on {c.contact_print.surface}", self._sum_on(contact_frame_name(c.robot_surface)))
                for c in contacts]

    def _sum_on(self, frame: str) -> np.ndarray:
        return np.sum([p.force for p in self.forces_on(frame)], axis=0) + np.zeros(3)

    def total_force(self) -> np.ndarray:
        """(3,) float: sum of the contact forces, newtons, world frame."""
        if not self.point_forces:
            return np.zeros(3)
        return np.sum([p.force for p in self.point_forces], axis=0)

    def forces_on(self, frame: str) -> tuple:
        """The point forces acting through ``frame``."""
        return tuple(p for p in self.point_forces if p.frame == frame)

    @classmethod
    def from_dict(cls, data) -> "PostureResult":
        """Inverse of :meth:`to_dict` (the verification is not stored; rerun verify).

        Raises
        ------
        KeyError, TypeError, ValueError
            If ``data`` is not a ``to_dict`` form.
        """
        return cls(
            feasible=bool(data["feasible"]),
            q=data["q"],
            point_forces=tuple(PointForce.from_dict(f) for f in data["point_forces"]),
            torques=data["torques"],
            iterations=int(data["iterations"]),
            solve_time=float(data["solve_time"]),
            reason=str(data["reason"]),
            stance=Stance.from_dict(data["stance"]) if data.get("stance") is not None else None,
            deformations={k: np.asarray(v, dtype=float) for k, v in data.get("deformations", {}).items()},
            statistics=dict(data.get("statistics", {})),
            limits=dict(data.get("limits", {})),
            slips=None if data.get("slips") is None else {k: NodeSlips.from_dict(v) for k, v in data["slips"].items()},
            held_slips={k: NodeSlips.from_dict(v) for k, v in data.get("held_slips", {}).items()},
        )

    def to_dict(self) -> dict:
        """JSON-ready representation (arrays as lists)."""
        return {
            "feasible": self.feasible,
            "q": self.q.tolist(),
            "point_forces": [p.to_dict() for p in self.point_forces],
            "torques": self.torques.tolist(),
            "iterations": self.iterations,
            "solve_time": self.solve_time,
            "reason": self.reason,
            "stance": self.stance.to_dict() if hasattr(self.stance, "to_dict") else None,
            "deformations": {k: np.asarray(v).tolist() for k, v in self.deformations.items()},
            "statistics": self.statistics.to_dict(),
            "limits": dict(self.limits),
            "slips": None if self.slips is None else {k: v.to_dict() for k, v in self.slips.items()},
            "held_slips": {k: v.to_dict() for k, v in self.held_slips.items()},
        }
