"""Quasi-static motion between consecutive stances of a plan.

Two consecutive stances differ by one contact: the robot adds it (a limb
reaches a new print) or removes it (a limb leaves one). Every other contact,
the *support*, is held throughout. A motion is a sequence of postures, each a
posture problem of the support alone (:func:`stances.solve`: static
equilibrium, torque and joint limits, friction cones, collision avoidance, the
soft bodies' FEM forces) with one more constraint: the moving limb's contact
frame sits on a waypoint of a path from where it is in the first stance to
where it is in the second, lifted along the print's normal by a clearance so
that it leaves and reaches its print squarely instead of sliding over it.
While it moves across, only its height and progress are held: sideways it is
free, so that collision avoidance decides how it passes the support (a fixed
detour of 0.2 m from each support print, and one of both surfaces' reach, each
left 2 of the 57 motions of seven built-in plans unfound, different ones;
sideways free, none). A point foot's path places its centre only. Each
sample's posture cost pulls toward the two stances' postures blended as far as
its waypoint lies along the path. Each sample is solved warm-started from the
previous one (small steps of a continuation) and verified by
:func:`stances.verify` as a stance of the support; the motion starts at the
first stance's posture and ends at the second's. A waypoint the continuation
from the first stance does not reach is approached from the other end: the
waypoints left are solved backward from the second stance's posture.

Between two consecutive samples the robot is checked for collisions at 7
postures interpolated in joint space (:data:`BETWEEN`); where one collides, a
sample is solved halfway along the path (at most :data:`MAX_INSERTED` in one
step of the motion), and a step that still collides makes the motion
infeasible. The moving contact geometry may sink into its own print's object
only as deep as the interpolation of its depths at the step's two ends (a
limb resting on a soft print sinks into it). The same postures must keep every
held contact on its line: a polygon's vertices (a point foot's centre) within
:data:`HELD_DRIFT` of the straight line between where the step's two samples
put them; a step that carries one further gets samples halfway too (at most
:data:`MAX_STRAY_INSERTED`), and one that still does makes the motion infeasible.

Touch-down and lift-off are sampled too. The limb meets its print (or
leaves it) with no load on it: a posture of the stance that holds the
contact, with the contact's normal load held at zero (:class:`ContactSample`),
so that it is balanced on the support alone and on the contact alike (a print
on a soft support is held rigid on its undeformed surface there: unloaded, it
deforms nothing, and as a soft print every node would sit exactly where it
lifts off, where the contact model gives the SQP no direction). The load
then moves onto the contact (or off it) between that posture and the stance's
own; where that step collides or carries a held contact off its line,
postures of the stance holding the contact are solved halfway (the load
transfer), each carrying the mean of its neighbours' loads (any load where no
posture carries exactly that; between two unloaded samples, another unloaded one). Static equilibrium
is checked at the samples, not between them: a robot moving slowly enough
between two balanced postures close together stays balanced, and the checks
between samples bound how far apart they are.

Under Coulomb friction a soft print node that slipped stays where it slipped to: each
posture of a motion starts the soft prints it keeps where the posture before it left them,
from the leaving stance's answer on, and the arriving stance is solved again from where the
last sample leaves them (:attr:`Motion.arrival`), which :func:`plan_motions` puts in the
plan, so that the next motion starts there.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from environments.errors import SceneError
from environments.geometry import axes_across
from fem.errors import FemError
import stances
from stances.blocks import PLACEMENT_ACCURACY, ConstraintBlock, equality
from stances.contacts import placement_residual, point_placement_residual
from stances.errors import StanceError
from stances.problem import stance_collision_checker
from stances.terms import print_normal_loads

from .between_samples import BETWEEN, HELD_DRIFT, BetweenSamples, checked_drift
from .slip_chain import chained, history_of, slips_not_carried
from .errors import MotionError
from .step_path import RAMP, halfway, lifted_path

__all__ = [
    "BETWEEN",
    "HELD_DRIFT",
    "ContactSample",
    "FramePlacementConstraint",
    "Motion",
    "MotionError",
    "held_strays",
    "motions_summary",
    "plan_motion",
    "plan_motions",
    "plan_motions_reposing",
    "retreat",
    "verify_motion",
]

logger = logging.getLogger(__name__)

#: A sample's frame may miss its waypoint by this much (m and rad), as
#: stances.verify's placements: the SQP meets these rows to PLACEMENT_ACCURACY (1e-7).
PATH_TOLERANCE = 1e-6

#: Samples inserted, at most, into one step of the motion that collides (a step that
#: still collides after them makes the motion infeasible). Each halves the step where it
#: collides: climb-with-soft-support 1 -> 2 and 3 -> 4 cleared with 3 and 4 (1.3 mm and
#: 0.5 mm deep after 2), rail-over-gap 6 -> 7 (the swing ankle 2.4 mm into the stance
#: knee after 4) with 6.
MAX_INSERTED = 6

#: Samples inserted, at most, into one step of the motion where a held contact strays
#: beyond :data:`HELD_DRIFT` (apart from those for collisions). A weight shift onto a new
#: contact takes the most: climb-with-soft-support 3 -> 4 moves a sole's 540 N in eighths
#: (6 samples); 4 -> 5, before load-transfer samples were pulled toward their step's
#: midpoint, was left at 5.3 mm with 4.
MAX_STRAY_INSERTED = 8

#: Sine of the angle to the print's normal below which the nearest scene object's
#: normal gives no direction to draw a free limb off across it (:func:`retreat`).
_ACROSS = 0.3

#: Newtons: the largest force a touch-down or lift-off sample may put on its limb
#: (the solver holds the normal load at zero within its 1e-7 tolerance).
UNLOADED_FORCE = 1e-4

# How much harder than the stances' posture cost a load-transfer sample pulls its joints
# toward its step's midpoint (``posture_weight``; the base's orientation weight is left
# as it is, its position has none). With the stances' own weight the samples follow the optimum for their
# load, which need not lead to the stance's posture: climb-with-soft-support 4 -> 5, 8
# samples (the last at 425 N of the sole's 439 N) left a step whose base pitch turns 3.5
# degrees and whose palm strays 1.07 mm; 10 times harder, 3 samples keep it within 1 mm
# (100 times: the same 3).
_TRANSFER_PULL = 10.0

# rad (or m): the SQP's step bound first tried for a touch-down or lift-off sample. It lies
# close to the lifted sample it starts from (the limb 1.5 cm lower), and 0.3 rad steps
# from there overshot: quadruped-walk's 7 -> 8 touch-down took 55 iterations and turned
# a knee by 1.09 rad.
_SWITCH_TRUST = 0.05


@dataclass(frozen=True, eq=False)
class FramePlacementConstraint:
    """A robot frame placed at a target (up to 6 equality rows), as a posture-problem constraint.

    Parameters
    ----------
    frame : str
        Frame of ``robot.model``.
    transform_frame_to_world : (4, 4) float
        Where the frame must be, world frame, metres.
    label : str
        Names the rows in an infeasible answer's reason.
    position_only : bool
        Place the frame's origin only (3 rows): a point foot, whose
        orientation its leg does not set (a 3-joint leg cannot hold 6 rows
        without the whole body turning to serve it).
    free_direction : (3,) float, optional
        A world direction along which the frame's origin is left free (2
        position rows instead of 3): sideways while a limb crosses, so that
        collision avoidance, not a fixed detour, decides how it passes the
        support.
    """

    frame: str
    transform_frame_to_world: np.ndarray
    label: str = "path"
    position_only: bool = False
    free_direction: np.ndarray | None = None

    def __post_init__(self):
        transform = np.array(self.transform_frame_to_world, dtype=float)
        if transform.shape != (4, 4):
            raise MotionError(f"transform_frame_to_world must be (4, 4), got {transform.shape}")
        transform.setflags(write=False)
        object.__setattr__(self, "transform_frame_to_world", transform)
        if self.free_direction is not None:
            direction = np.array(self.free_direction, dtype=float)
            length = np.linalg.norm(direction) if direction.shape == (3,) else 0.0
            if not (np.isfinite(length) and length > 0.0):
                raise MotionError(f"free_direction must be a non-zero (3,) vector, got {self.free_direction!r}")
            direction /= length
            direction.setflags(write=False)
            object.__setattr__(self, "free_direction", direction)

    @property
    def _held(self) -> np.ndarray:
        """(2, 3) orthonormal world directions across ``free_direction``, along which the origin is held."""
        return axes_across(self.free_direction)

    def blocks(self, problem, iterate):
        """Rows ``log6(target^-1 frame) = 0`` and their Jacobian (as a rigid contact's placement);
        with ``position_only`` the origin's offset in the target frame (as a point foot's); with
        ``free_direction`` the origin's offset across it, world frame, and ``log3(R_t^T R)``."""
        model, data = problem.robot.model, problem.data
        frame_id = model.getFrameId(self.frame)
        target = pin.SE3(self.transform_frame_to_world)
        if self.free_direction is not None:
            held = self._held
            residual = held @ (data.oMf[frame_id].translation - target.translation)
            tangent = held @ pin.getFrameJacobian(model, data, frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
            axes = ("held 1", "held 2")
            if not self.position_only:
                # The turn from the target, log3(R_t^T R), in the frame (a LOCAL angular step).
                turn = target.rotation.T @ data.oMf[frame_id].rotation
                local = pin.getFrameJacobian(model, data, frame_id, pin.LOCAL)[3:]
                residual = np.concatenate([residual, pin.log3(turn)])
                tangent = np.vstack([tangent, pin.Jlog3(turn) @ local])
                axes += ("roll", "pitch", "yaw")
        elif self.position_only:
            residual, tangent = point_placement_residual(model, data, frame_id, target, 0.0)
            axes = ("x", "y", "z")
        else:
            residual, tangent = placement_residual(model, data, frame_id, target)
            axes = ("x", "y", "z", "roll", "pitch", "yaw")
        jacobian = np.zeros((len(axes), problem.n_step))
        jacobian[:, : model.nv] = tangent
        labels = [f"{self.label} ({axis})" for axis in axes]
        return [equality("frame path", residual, jacobian, 1e-2, labels, PLACEMENT_ACCURACY)]

    def error(self, robot, q):
        """Largest translation (m) or rotation (rad) error of the frame at ``q`` (translation
        alone with ``position_only``, across ``free_direction`` only when it is given)."""
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
        placement = data.oMf[robot.model.getFrameId(self.frame)]
        error = pin.SE3(self.transform_frame_to_world).actInv(placement)
        if self.free_direction is None and not self.position_only:
            residual = pin.log6(error).vector
            return float(max(np.linalg.norm(residual[:3]), np.linalg.norm(residual[3:])))
        if self.free_direction is None:
            offset = error.translation
        else:
            offset = self._held @ (placement.translation - self.transform_frame_to_world[:3, 3])
        turn = 0.0 if self.position_only else np.linalg.norm(pin.log3(error.rotation))
        return float(max(np.linalg.norm(offset), turn))


@dataclass(frozen=True, eq=False)
class ContactSample:
    """A sample of a motion that holds the moving contact: touch-down, lift-off or load transfer.

    Solved and verified as a posture of the stance that holds the contact (the
    support and the moving contact), not of the support alone.

    Parameters
    ----------
    frame : str
        The moving surface's contact frame.
    robot_surface : str
        The moving robot surface.
    surface : str
        The scene surface its print lies on.
    label : str
        Names the sample (and its rows in an infeasible answer's reason).
    unloaded : bool
        True at touch-down and lift-off: the print's load along its normal is
        held at zero (one row, ``<= 0``; no adhesion makes it ``= 0``), so the
        posture is balanced on the support alone. False for a load-transfer
        sample: the stance, its print's load ``normal_load`` when given.
    normal_load : float, optional
        Newtons: a load-transfer sample's print load along its normal (one row,
        ``=``). Halfway between two postures it is halfway between their loads,
        which moves the robot's weight halfway: pulled toward the midpoint
        alone, the samples landed next to the stance's own posture, the step
        from touch-down left whole (cross-soft-block 5 -> 6: the base 0.25 m
        from the touch-down sample, 3.9 mm of stray on the other sole between them).
    transform_frame_to_world : (4, 4) float, optional
        Where the frame is in the solved sample, world frame (set once solved).
    """

    frame: str
    robot_surface: str
    surface: str
    label: str
    unloaded: bool = True
    normal_load: float | None = None
    transform_frame_to_world: np.ndarray | None = None

    def __post_init__(self):
        if self.normal_load is None:
            return
        if self.unloaded:
            raise MotionError(f"{self.label}: an unloaded sample carries no normal_load (it is held at zero)")
        load = float(self.normal_load)
        if not (np.isfinite(load) and load >= 0.0):
            raise MotionError(f"{self.label}: normal_load must be a finite load >= 0 newtons, got {self.normal_load!r}")
        object.__setattr__(self, "normal_load", load)

    @property
    def print_label(self) -> str:
        """The contact's print as its posture problem names it."""
        return f"{self.robot_surface} on {self.surface}"

    def blocks(self, problem, iterate):
        """Unloaded: the row ``normal load of the print <= 0`` and its Jacobian; with a
        ``normal_load``, the row ``normal load = normal_load``; otherwise none."""
        if not self.unloaded and self.normal_load is None:
            return []
        labels, value, jacobian = print_normal_loads(problem, iterate, only=self.print_label)
        if not labels:
            raise MotionError(f"{self.label}: the posture problem has no print {self.print_label!r}")
        if self.unloaded:
            return [ConstraintBlock("unloaded contact", value, jacobian, -np.inf, 0.0, 1.0,
                                    (f"{self.label} (normal load)",))]
        return [ConstraintBlock("contact load", value, jacobian, self.normal_load, self.normal_load, 1.0,
                                (f"{self.label} (normal load {self.normal_load:.4g} N)",))]

    def options(self, options) -> dict:
        """The posture options its solve and verification take: unloaded, its print is held
        rigid on the undeformed surface (``rigid_prints``: a print that carries nothing deforms
        nothing, and as a soft print every node would sit exactly where it lifts off, where the
        contact model gives the SQP no direction: cross-two-mats' touch-down of a sole on a soft
        mat stalled 2 N from unloaded) and no print need carry ``min_normal_force``. Loaded or
        not, the sample moves load onto or off its print, through less than the support
        share of the weight the stances keep on each foot: no ``support_load`` holds."""
        if not self.unloaded:
            return {**options, "support_load": 0.0}
        return {**options, "rigid_prints": (self.robot_surface,), "min_normal_force": 0.0, "support_load": 0.0}

    def load(self, result) -> float:
        """Newtons: the magnitude of the resultant force on the frame's link in a result."""
        forces = [p.force for p in result.forces_on(self.frame)]
        return float(np.linalg.norm(np.sum(forces, axis=0))) if forces else 0.0


@dataclass(frozen=True, eq=False)
class Motion:
    """A quasi-static motion from stance ``index`` of a plan to the next.

    Parameters
    ----------
    index : int
        The stance the motion leaves.
    moving_surface : str
        Robot surface that reaches or leaves its print.
    support : environments Stance
        The contacts held throughout (those both stances share).
    configurations : (k, nq) float
        Postures, the first stance's ``q`` first and, when feasible, the
        second's last (its ``arrival``'s where it has one); between them, one per
        waypoint, and one per sample inserted where a step collided or strayed
        (fewer if the motion failed).
    paths : tuple of FramePlacementConstraint or ContactSample
        How the moving surface is held at each interior sample: its frame on
        the path's waypoints (and any halfway waypoints the solves or the
        checks between samples needed), free sideways while it crosses; or on its
        print (:class:`ContactSample`): unloaded at touch-down or lift-off,
        loaded in a load-transfer sample.
    results : tuple of stances PostureResult
        The posture solve of each interior sample: of the support, or of the
        stance holding the moving contact for a :class:`ContactSample`.
    feasible : bool
        Whether every waypoint was reached by a verified posture and no step
        between consecutive postures collides or carries a held contact more
        than its bound off its line (:data:`BETWEEN`, :data:`HELD_DRIFT`).
    reason : str
        Why not (empty when feasible).
    seam : int or None
        When the solves from the first stance stopped short and the rest were
        solved backward from the second stance's posture: the index in
        ``configurations`` of the first backward sample in path order (the last
        one solved; a larger joint step may lie just before it). None when every
        sample was solved forward.
    reposed : bool
        Whether the arriving stance's posture was solved again for this motion
        (:func:`plan_motions_reposing`): the plan's own lay out of its reach.
    arrival : stances PostureResult or None
        The arriving stance's answer solved again from where the last sample leaves the
        soft prints it keeps (its posture the last of ``configurations``): the plan's own
        answer starts them where the leaving stance left them, and under Coulomb friction
        the motion between moves them on. None where the plan's answer starts there
        already (no soft print kept, nothing slipped), or the motion is not feasible.
        :func:`plan_motions` and :func:`plan_motions_reposing` put it in the plan they
        return, so that the next motion starts from it.

    Raises
    ------
    MotionError
        If the samples do not add up: one path and one result per interior
        sample, both stances' postures at the ends of a feasible motion (the
        first only, otherwise), a seam among the interior samples.
    """

    index: int
    moving_surface: str
    support: object
    configurations: np.ndarray
    paths: tuple
    results: tuple
    feasible: bool
    reason: str = ""
    seam: int | None = None
    reposed: bool = False
    arrival: object = None

    def __post_init__(self):
        array = np.array(self.configurations, dtype=float)
        array.setflags(write=False)
        object.__setattr__(self, "configurations", array)
        object.__setattr__(self, "paths", tuple(self.paths))
        object.__setattr__(self, "results", tuple(self.results))
        interior = len(array) - 1 - bool(self.feasible)
        if not len(self.paths) == len(self.results) == interior:
            raise MotionError(
                f"a motion with {len(array)} configurations ({'feasible' if self.feasible else 'not feasible'}) "
                f"has {interior} interior samples, got {len(self.paths)} paths and {len(self.results)} results"
            )
        if self.seam is not None and not 1 <= self.seam <= interior:
            raise MotionError(f"seam {self.seam} is not an interior sample (1..{interior})")
        if self.arrival is not None and not (self.feasible and np.array_equal(self.arrival.q, array[-1])):
            raise MotionError("a motion's arrival is the posture it ends on, and only a feasible motion has one")

    @property
    def targets(self) -> np.ndarray:
        """(k - 2, 4, 4) float: each interior sample's waypoint, world frame (where the frame
        is, for a :class:`ContactSample`)."""
        return np.array([path.transform_frame_to_world for path in self.paths]).reshape(-1, 4, 4)

    @property
    def joint_steps(self) -> np.ndarray:
        """(k - 1,) float: the largest joint change from each sample to the next, rad (or m)."""
        return np.abs(np.diff(self.configurations[:, 7:], axis=0)).max(axis=1, initial=0.0)

    def durations(self, joint_speed=0.5, base_speed=0.1):
        """Time between consecutive samples, seconds, at nominal speeds.

        The motion is quasi-static: any slower timing keeps it balanced.

        Parameters
        ----------
        joint_speed : float
            Largest joint speed, rad/s.
        base_speed : float
            Largest speed of the base, m/s.

        Returns
        -------
        (k - 1,) float
        """
        joints = self.joint_steps / joint_speed
        base = np.linalg.norm(np.diff(self.configurations[:, :3], axis=0), axis=1) / base_speed
        return np.maximum(np.maximum(joints, base), 0.05)


def _switch(before, after):
    """``(moving, support, holding, touch_down)`` of a motion between two planned stances: the
    contact they do not share, the contacts they share, the stance holding the moving contact
    (the arriving one at a touch-down, the one left at a lift-off) and which of the two it is."""
    moving, support = _moving_contact(before.stance, after.stance)
    touch_down = support == before.stance
    return moving, support, after.stance if touch_down else before.stance, touch_down


def _moving_contact(before, after):
    """The contact two stances do not share, and the support they share."""
    a, b = set(before.contacts), set(after.contacts)
    if len(a ^ b) != 1:
        raise MotionError(
            f"a motion joins stances that differ by exactly one contact; these differ by {len(a ^ b)}: "
            f"{sorted(c.robot_surface for c in a ^ b)}"
        )
    (moving,) = a ^ b
    support = before if len(before) < len(after) else after
    return moving, support


def _print_surface(stance, robot_surface):
    """The surface a stance's contact of ``robot_surface`` lies on."""
    return next(c.contact_print.surface for c in stance.contacts if c.robot_surface == robot_surface)


def _frame_placement(robot, q, frame):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return data.oMf[robot.model.getFrameId(frame)].homogeneous


def _options_of(planned):
    """The posture options a planned stance was solved with (its result records them)."""
    statistics = getattr(planned.result, "statistics", None) or {}
    return dict(statistics.get("options", {}))


def plan_motion(plan, index, scenario, robot, *, samples=6, clearance=0.05, max_splits=2, solver_options=None,
                held_drift=HELD_DRIFT):
    """The quasi-static motion from stance ``index`` of a plan to stance ``index + 1``.

    Parameters
    ----------
    plan : cbm.Plan
    index : int
        Stance the motion leaves.
    scenario : environments Scenario
    robot : stances Robot
    samples : int
        Waypoints of the moving limb across (:func:`cbm.step_path.lifted_path`; two more,
        straight above each end, make ``samples + 2`` interior postures).
    clearance : float
        Lift of the moving limb off its print, metres, along the print's normal.
        While it moves across, its frame is free sideways (across both the
        normal and the step).
    max_splits : int
        Waypoints no posture reaches from the previous sample are retried from
        a waypoint halfway (a shorter continuation step), at most this many
        times in each direction.
    solver_options : dict, optional
        Posture options; default those the arriving stance was solved with.
    held_drift : float
        Metres: how far a held contact may stray between two samples
        (:data:`HELD_DRIFT`); a step straying further gets samples inserted.

    Returns
    -------
    Motion
        Solved sample after sample from the first stance's posture; if a
        waypoint is out of reach, the waypoints left are solved the same way
        backward, from the second stance's posture, and the two halves meet at
        ``Motion.seam``. If neither reaches it, the motion holds the forward
        samples, ``feasible`` False and both solvers' reasons; if a step
        between samples collides or strays even with samples inserted, every
        sample, ``feasible`` False and the collision or the stray. Where the
        motion fails and the limb's free end (the one off its print) lies within
        the collision checker's activation distance of a scene object, it is
        planned again with that end drawn ``clearance`` away from the nearest one,
        across the normal, as the limb rises (or falls) (:func:`retreat`): a hand
        hanging beside the support it reaches for (Romeo's wrist 5 mm from the soft
        cube's face, which the rise straight up swept 12.8 mm through). The first
        motion found is returned; if neither is, the first with both reasons (a
        failing motion near a support thus costs two tries).

    Raises
    ------
    MotionError
        If ``index`` does not name a pair of stances, they do not differ by
        exactly one contact, or ``held_drift`` is not a positive distance.
    """
    if not 0 <= index < len(plan.stances) - 1:
        raise MotionError(f"stance {index} has no next stance: the plan has {len(plan.stances)} stances")
    held_drift = checked_drift(held_drift)
    settings = dict(samples=samples, clearance=clearance, max_splits=max_splits, solver_options=solver_options,
                    held_drift=held_drift)
    motion = _motion_on_path(plan, index, scenario, robot, None, **settings)
    if motion.feasible:
        return motion
    options = _options_of(plan.stances[index + 1]) if solver_options is None else dict(solver_options)
    offset = retreat(robot, scenario.scene, plan.stances[index], plan.stances[index + 1], clearance, options)
    if offset is None:
        return motion
    detour = _motion_on_path(plan, index, scenario, robot, offset, **settings)
    if detour.feasible:
        logger.info("motion %d -> %d found with its free end drawn %.3g m off the scene", index, index + 1, clearance)
        return detour
    return replace(motion, reason=f"{motion.reason}; with the free end drawn {clearance:g} m off the scene first, "
                                  f"{detour.reason}")


def retreat(robot, scene, before, after, distance, options=None):
    """The detour of a motion's free end: ``(start offset, end offset)``, world, metres,
    the other one None (see :func:`cbm.step_path.lifted_path`); None when no scene object
    is near, or the nearest one lies along the print's normal (nothing to draw off across it).

    The limb off its print (before a touch-down, after a lift-off) is drawn
    ``distance`` away from the scene object nearest to it at that posture (within the
    collision checker's activation margin), across the print's normal: a hand hanging
    beside the face of the support it reaches for is drawn off that face as it rises
    (the path reaches the whole offset at the top of the rise). The limb is every link
    below the root joint of the moving surface's limb (:attr:`stances.Robot.limbs`).

    Parameters
    ----------
    robot : stances Robot
    scene : environments Scene
    before, after : cbm PlannedStance
        The stances the motion joins.
    distance : float
        Metres.
    options : dict, optional
        Posture options the collision checker is built with (its activation margin).

    Returns
    -------
    tuple of ((3,) float or None, (3,) float or None), or None
    """
    moving, support, _, touch_down = _switch(before, after)
    model = robot.model
    free = np.asarray(before.q if touch_down else after.q, dtype=float)
    checker = stance_collision_checker(robot, scene, support, stances.PostureOptions(**(options or {})))
    surface = robot.surface(moving.robot_surface)
    limb = set(model.subtrees[model.getJointId(robot.limbs[surface.limb])])
    data = model.createData()
    pin.forwardKinematics(model, data, free)
    near = [pair for pair in checker.pairs(model, data) if not pair.is_self_collision and pair.joint_a in limb]
    if not near:
        return None
    normal = scene.transform_print_to_world(moving.contact_print)[:3, 2]
    away = np.array(min(near, key=lambda pair: pair.distance).normal)
    away -= (away @ normal) * normal / (normal @ normal)
    length = np.linalg.norm(away)
    if length < _ACROSS:
        return None
    offset = distance * away / length
    return (offset, None) if touch_down else (None, offset)


def _motion_on_path(plan, index, scenario, robot, offset, *, samples, clearance, max_splits, solver_options,
                    held_drift):
    """:func:`plan_motion` along the lifted path with the given ``retreat`` offsets (or none)."""
    before, after = plan.stances[index], plan.stances[index + 1]
    moving, support, holding, touch_down = _switch(before, after)
    surface = robot.surface(moving.robot_surface)
    start = _frame_placement(robot, before.q, surface.frame)
    end = _frame_placement(robot, after.q, surface.frame)
    normal = scenario.scene.transform_print_to_world(moving.contact_print)[:3, 2]
    targets = lifted_path(start, end, normal, clearance, samples, retreat=offset)
    # Sideways: across the normal and the step. Free only while moving across: the
    # waypoints straight above either end hold the limb over its print.
    sideways = np.cross(normal, end[:3, 3] - start[:3, 3])
    s = np.arange(samples + 2) / (samples + 1)
    crossing = (s > RAMP) & (s < 1.0 - RAMP) & (np.linalg.norm(sideways) > 1e-6)
    # Each sample's posture cost pulls toward the two stances' postures blended as far as
    # its waypoint is along the path, not toward the robot's reference posture: the
    # samples then lead into the arriving stance's posture instead of meeting it with a
    # jump at touch-down (seven built-in plans: largest joint step 1.31 -> 0.82 rad, and
    # one motion of the two that needed a backward solve goes through forward).
    paths = [
        (f"waypoint {k + 1}",
         FramePlacementConstraint(surface.frame, target, f"path of {moving.robot_surface} (waypoint {k + 1})",
                                  surface.is_point, sideways if crossing[k] else None),
         pin.interpolate(robot.model, before.q, after.q, float(s[k])))
        for k, target in enumerate(targets)
    ]
    options = _options_of(after) if solver_options is None else dict(solver_options)
    scene = scenario.scene
    # The first sample starts the soft prints it keeps where the leaving stance's answer left
    # them (stances.solve's history), not from rest, and each after it where the one before
    # left them: the forward samples as they are solved, the others in _clear_steps' walk.
    history = history_of(before)
    name = "touch-down" if touch_down else "lift-off"
    switch = ContactSample(surface.frame, moving.robot_surface, moving.contact_print.surface,
                           f"{name} of {moving.robot_surface}")
    lift, lifted = None, None  # a lift-off solved before the samples above it, and the posture it is pulled to
    if not touch_down and history is not None and history.slips:
        # A lift-off comes first: solved before the samples above its print, from the first of
        # them (a probe of the first waypoint), so that they start from where it leaves the
        # kept prints as they are solved (solved after them, it left every one of them to be
        # solved again: climb-with-soft-support's lift-offs, 14 samples each). Only where the
        # leaving stance has soft prints: elsewhere nothing chains, and the probe is a solve more.
        probe = _continuation(robot, scene, support, paths[:1], before.q, start, options, max_splits, history)
        if not probe.pending:
            lifted = probe.results[-1].q
            lift = _switch_sample(robot, scene, support, holding, switch, lifted, options, history)
    first = lift if lift is not None and lift.feasible else history
    forward = _continuation(robot, scene, support, paths, before.q, start, options, max_splits, first, chain=True)
    backward, reason = None, ""
    if forward.pending:
        # From the arriving stance back to where the forward solves stopped: a posture
        # near one end can be out of reach of a continuation from the other (measured
        # with a fixed 0.2 m detour: cross-soft-block 3 -> 4 stopped forward at waypoint
        # 5 of 8, the swing ankle against the stance knee; backward, all 8 were solved).
        backward = _continuation(robot, scene, support, forward.pending[::-1], after.q, end, options, max_splits,
                                 history)
        if backward.pending:
            reason = f"{len(paths)} waypoints; forward, {forward.reason}; backward from the next stance, {backward.reason}"
            logger.info("motion %d -> %d stops: %s", index, index + 1, reason)
            backward = None
        else:
            logger.info("motion %d -> %d joined backward; forward stopped at %s", index, index + 1, forward.reason)
    pieces = [forward] if backward is None else [forward, backward.reversed()]
    samples = [_Sample(r.q, p, r, ref, holds=False) for piece in pieces
               for r, p, ref in zip(piece.results, piece.reached, piece.references)]
    seam = None if backward is None else 1 + len(forward.results)
    ends = (_Sample(before.q, None, None, before.q, holds=not touch_down,
                    load=0.0 if touch_down else _normal_load(before.point_forces, surface.frame, normal)),
            _Sample(after.q, None, None, after.q, holds=touch_down,
                    load=_normal_load(after.point_forces, surface.frame, normal) if touch_down else 0.0))
    if not reason:
        # The limb meets (leaves) its print unloaded, next to the lifted sample above it.
        if lift is not None and lift.feasible:
            result, reference = lift, lifted
        else:
            nearest = samples[-1] if touch_down else samples[0]
            # From where the forward samples leave the kept prints (a touch-down follows them;
            # after a backward half, and a lift-off not solved before them, the walk solves
            # the postures after it again).
            left = nearest.result if touch_down and backward is None else history
            result = _switch_sample(robot, scene, support, holding, switch, nearest.q, options, left)
            reference = nearest.q
        if not result.feasible:
            reason = f"{name}: {result.reason}"
            logger.info("motion %d -> %d stops: %s", index, index + 1, reason)
        else:
            touch = _Sample(result.q, _placed(robot, switch, result.q), result, reference, holds=True)
            samples = samples + [touch] if touch_down else [touch] + samples
            if seam is not None and not touch_down:
                seam += 1
    arrival = None
    if not reason:
        between = BetweenSamples(robot, scene, support, moving, options, held_drift)
        samples, seam, reason, arrival = _clear_steps(robot, scene, support, holding, between, ends, samples, seam,
                                                      options, surface, normal, index, history, after.result)
    configurations = [before.q] + [sample.q for sample in samples] + (
        [] if reason else [after.q if arrival is None else arrival.q])
    return Motion(index, moving.robot_surface, support, np.array(configurations),
                  tuple(sample.path for sample in samples), tuple(sample.result for sample in samples),
                  not reason, reason, seam, arrival=None if reason else arrival)


def _switch_sample(robot, scene, support, holding, switch, q, options, history):
    """The touch-down or lift-off sample ``switch`` (a :class:`ContactSample`) solved from
    posture ``q``, the lifted sample's beside it, and pulled toward it: the limb only comes
    down (goes up) by the approach height; the stance's own posture, which may lean on the
    contact, is reached by the load transfer after it (quadruped-walk 7 -> 8: pulled toward
    the arriving stance's posture, the touch-down sample lay 1.06 rad from the lifted one and
    the foot swept 2.8 mm into the step between them). Short steps first; where they stall,
    the solver's own. ``history``: as :func:`_solve_sample`'s."""
    for trust in (_SWITCH_TRUST, None):
        tried = options if trust is None else {**options, "trust_region": trust}
        result = _solve_sample(robot, scene, support, holding, switch, q, q, None, tried, history)
        if result.feasible:
            break
    return result


@dataclass(frozen=True)
class _Sample:
    """A posture of a motion: interior (with its path, result and reference posture) or a stance's
    (the ends); ``holds``: whether the moving contact is held there."""

    q: np.ndarray
    path: FramePlacementConstraint | ContactSample | None
    result: object
    reference: np.ndarray
    holds: bool
    load: float = 0.0  # newtons: the moving contact's print load along its normal (0 where not held)


def _normal_load(point_forces, frame, normal) -> float:
    """Newtons: the load of the forces on ``frame`` along ``normal`` (world)."""
    return float(sum(np.dot(p.force, normal) for p in point_forces if p.frame == frame))


def _placed(robot, sample, q):
    """A ContactSample with the frame's placement at posture ``q``."""
    return replace(sample, transform_frame_to_world=_frame_placement(robot, q, sample.frame))


def _step_text(k, problem, last):
    """Where a step of a motion fails, in words; ``last``: the step into the next stance."""
    step = f"between sample {k} and the next stance's posture" if last else f"between samples {k} and {k + 1}"
    return f"{step}, {problem}"


def _clear_steps(robot, scene, support, holding, between, ends, samples, seam, options, surface, normal, index,
                 history=None, arriving=None):
    """Walk the steps between consecutive postures, each posture starting where the one before
    it left the soft prints both keep, and check each step for collisions and held contacts'
    strays (``between``, a :class:`cbm.between_samples.BetweenSamples`); where one fails, solve
    a sample halfway along the path and check both halves, at most :data:`MAX_INSERTED`
    samples for collisions and :data:`MAX_STRAY_INSERTED` for strays in each step of the
    motion (which sample: :func:`_halfway_sample`). ``holding``: the stance holding the moving
    contact; ``normal``: its print's normal (world); ``history``: the leaving stance's answer,
    where the first posture starts; ``arriving``: the arriving stance's.

    Under Coulomb friction a print node that slipped stays where it slipped to: as an
    incremental quasi-static solve along the motion would, each posture starts where the
    posture before it left the kept prints, not where the leaving stance did. A posture the
    walk reaches that did not start there (a sample of the backward half, one after a sample
    inserted before it, the arriving stance's answer) is solved again from there
    (:func:`_chained`) before its step is checked. With every sample from the leaving stance,
    foot-and-hand-on-foam's palm, held down while a sole moved, came 3.8 mm off where the
    motion leaves it at the arriving stance (climb-with-soft-support's soles 0.1-0.9 mm; the
    slip bound 5.6 mm), and on the coarse soft cube a palm's load transfer slid it 5.5 mm
    between its last sample and the stance: the walk now inserts samples there.

    Returns
    -------
    samples, seam, reason, arrival
        The samples, the seam moved past any inserted before it, a reason (empty when every
        step is clear), and the arriving stance's answer solved again from where the last
        sample leaves its kept prints (None where ``arriving`` starts there, or a reason).
    """
    nodes = [ends[0], *samples, ends[1]]
    origin = list(range(len(nodes) - 1))  # the step of the motion each step comes from
    budget = {"collision": MAX_INSERTED, "drift": MAX_STRAY_INSERTED}
    inserted = {kind: [0] * len(origin) for kind in budget}  # samples inserted into each step of the motion
    arrival = None
    k = 0
    while k < len(nodes) - 1:
        a = nodes[k]
        left = history if k == 0 else a.result  # where a leaves the kept soft prints
        last = k == len(nodes) - 2
        b, answer, why_not = _chained(robot, scene, support, holding, left, nodes[k + 1],
                                      (arrival or arriving) if last else None, options)
        if why_not:
            what = "the next stance" if last else f"sample {k + 1}"
            before_it = "the last sample" if last else "the posture before it"
            return nodes[1:-1], seam, (f"{what}, solved again from where {before_it} leaves its soft prints: "
                                       f"{why_not}"), None
        if last and answer is not arriving:
            arrival = answer
            if b.holds:  # the load a halfway sample of the last step carries the mean of
                b = replace(b, load=_normal_load(answer.point_forces, surface.frame, normal))
        nodes[k + 1] = b
        problem = between.first_problem(a.q, b.q, held=a.holds and b.holds)
        if problem is None:
            k += 1
            continue
        kind, words = problem
        where = _step_text(k, words, last)
        if inserted[kind][origin[k]] >= budget[kind]:
            logger.info("motion %d -> %d: %s", index, index + 1, where)
            count = sum(counts[origin[k]] for counts in inserted.values())
            return nodes[1:-1], seam, f"{where}, after {count} samples inserted in that step", None
        result, path, reference = _halfway_sample(robot, scene, support, holding, a, b, k, options, surface, left)
        if not result.feasible:
            return nodes[1:-1], seam, f"{where}; no posture halfway: {result.reason}", None
        if isinstance(path, ContactSample):
            path = _placed(robot, path, result.q)
        held = isinstance(path, ContactSample)
        load = 0.0 if not held or path.unloaded else path.normal_load if path.normal_load is not None else (
            _normal_load(result.point_forces, surface.frame, normal))
        nodes.insert(k + 1, _Sample(result.q, path, result, reference, holds=held, load=load))
        origin.insert(k + 1, origin[k])
        inserted[kind][origin[k]] += 1
        if seam is not None and k + 1 <= seam:
            seam += 1
    return nodes[1:-1], seam, "", arrival


def _chained(robot, scene, support, holding, left, node, arriving, options):
    """``node`` (a :class:`_Sample`) solved again where its answer did not start where answer
    ``left`` leaves the soft prints both keep (:func:`cbm.slip_chain.slips_not_carried`), from
    its own posture and forces (most take a step or two): ``(node, answer, "")``, or ``(node,
    answer, the solver's reason)`` where no posture is found so. The motion's last node, the
    arriving stance's posture, has answer ``arriving`` (None: a plan read from a file without
    its answers), and keeps no result of its own (the walk's halfway samples do not start
    from a stance's answer): its answer is that stance solved again. A ``left`` that is no
    posture answer chains nothing."""
    end = node.path is None
    answer = arriving if end else node.result
    if (not isinstance(left, stances.PostureResult) or not isinstance(answer, stances.PostureResult)
            or not slips_not_carried(left, answer)):
        return node, answer, ""
    lam = np.asarray(answer.statistics["lambda"])
    try:
        if end:
            # From the stance's own posture and forces (options other than those it recorded,
            # with other contact variables, are a StanceError below: no start, no posture).
            result = stances.solve(robot, scene, answer.stance, q_init=answer.q, lam_init=lam, history=left,
                                   **options)
        else:
            result = _solve_sample(robot, scene, support, holding, node.path, node.reference, node.q, node.result,
                                   options, left)
    except (StanceError, SceneError, FemError) as error:
        # One posture not found so ends this motion, not the plan's others.
        return node, answer, f"{type(error).__name__}: {error}"
    if not result.feasible:  # (feasible: stances.verify passed, inside the solve and in _solve_sample)
        return node, answer, result.reason
    if end:
        return replace(node, q=result.q), result, ""
    path = _placed(robot, node.path, result.q) if isinstance(node.path, ContactSample) else node.path
    return replace(node, q=result.q, path=path, result=result), result, ""


def _halfway_sample(robot, scene, support, holding, a, b, k, options, surface, history=None):
    """A sample between postures ``a`` and ``b`` (:class:`_Sample`) of a step that
    collides or strays: ``(result, path, reference)``, ``result.feasible`` False with the last
    reason when no candidate is reached.

    Candidates, in turn, each solved from one posture after another until one is
    reached: ``a``, ``b`` and the step's midpoint in joint space (which one first: below;
    the midpoint is among them since climb-with-soft-support 1 -> 2, where the free foot
    slid along the other one between the lifted palm and its touch-down, 5 mm apart at
    both ends, and neither end reached the palm's halfway waypoint):

    - both ends hold the moving contact: a load-transfer sample (a :class:`ContactSample`
      whose print carries the mean of its loads at the two ends, or, where no posture
      does, any load), a posture of the holding
      stance whose joints are pulled toward the step's midpoint (:data:`_TRANSFER_PULL`
      times harder than the stances' toward theirs) and from it first (from a or b with a blend
      of their references, the samples stayed by the end they came from: quadruped-walk
      5 -> 6, two samples 0.01 rad from the touch-down one);
    - neither does: a posture of the support with the frame halfway between where it is
      at the two postures (a free sideways offset included), from ``a`` first, pulled
      toward the blend of the two samples' references;
    - one does (the step between the lifted sample and touch-down or lift-off): first the
      frame halfway, from the step's midpoint in joint space first and pulled toward it,
      which halves the limb's approach and the step (quadruped-walk 7 -> 8: the shin's
      adapter swept 1.6 mm into the step between the lifted foot, 15 mm above it, and its
      touch-down, 1.07 rad away; four more unloaded samples on the print did not clear
      it), its contact geometry allowed to touch the print's object
      (``PostureOptions.touching``): halfway down, it is nearer than the collision
      distance; where that waypoint is not reached, another unloaded sample, the limb on
      its print.
    """
    middle = pin.interpolate(robot.model, a.q, b.q, 0.5)
    blended = pin.interpolate(robot.model, a.reference, b.reference, 0.5)
    free = a.path.free_direction if isinstance(a.path, FramePlacementConstraint) else None
    if free is not None and not (isinstance(b.path, FramePlacementConstraint) and b.path.free_direction is not None
                                 and np.allclose(free, b.path.free_direction)):
        free = None
    waypoint = FramePlacementConstraint(
        surface.frame, halfway(_frame_placement(robot, a.q, surface.frame), _frame_placement(robot, b.q, surface.frame)),
        f"path of {surface.name} (between samples {k} and {k + 1})", surface.is_point, free)
    # Between two unloaded samples on the print (the touch-down and one inserted before it),
    # another unloaded one: a soft print at zero load as a load transfer stalls the solver.
    unloaded_ends = all(isinstance(end.path, ContactSample) and end.path.unloaded for end in (a, b))
    transfer = a.holds and b.holds and not unloaded_ends
    kind = ("load transfer" if transfer else "unloaded contact" if unloaded_ends
            else "touch-down" if b.holds else "lift-off")
    on_print = ContactSample(surface.frame, surface.name, _print_surface(holding, surface.name),
                             f"{kind} of {surface.name} (between samples {k} and {k + 1})",
                             unloaded=not transfer, normal_load=0.5 * (a.load + b.load) if transfer else None)
    starts = (a, b, _Sample(middle, None, None, middle, holds=a.holds and b.holds))
    if unloaded_ends:
        candidates = [(on_print, middle, starts[2:] + starts[:2], options)]
    elif transfer:
        # Its load pinned first; where no posture meets it exactly, free (hand-on-coarse-cube's
        # palm on its 10 mm tets: 0.33 N from half its load, the line search stalling).
        pulled = {**options, "posture_weight": _TRANSFER_PULL * options.get(
            "posture_weight", stances.PostureOptions().posture_weight)}
        candidates = [(path, middle, starts[2:] + starts[:2], pulled)
                      for path in (on_print, replace(on_print, normal_load=None))]
    elif a.holds or b.holds:
        # The waypoint from the joint-space midpoint and pulled toward it: the unloaded sample
        # can lie far from the lifted one in joint space (quadruped-walk 7 -> 8: 1.07 rad), and
        # a waypoint solved from either end stays by that end, leaving the jump whole. The
        # limb may come nearer its print than the collision distance: halfway down it is.
        touching = {**options, "touching": ((surface.name, on_print.surface),)}
        candidates = [(waypoint, middle, starts[2:] + starts[:2], touching), (on_print, middle, starts[::-1], options)]
    else:
        candidates = [(waypoint, blended, starts, options)]
    for path, reference, tried, solved_with in candidates:
        for start in tried:
            result = _solve_sample(robot, scene, support, holding, path, reference, start.q, start.result, solved_with,
                                   history)
            if result.feasible:
                return result, path, reference
    return result, path, reference


@dataclass(frozen=True)
class _Continuation:
    """Waypoints solved one after another, each warm-started from the last."""

    results: list  # the verified posture results, in the order solved
    reached: list  # the FramePlacementConstraint each result holds
    references: list  # the reference posture each result was pulled toward
    pending: list  # (name, FramePlacementConstraint, reference posture) of the waypoints left (empty: all reached)
    reason: str = ""

    def reversed(self):
        """The same samples in the opposite order (a backward continuation in path order)."""
        return _Continuation(self.results[::-1], self.reached[::-1], self.references[::-1], self.pending)


def _continuation(robot, scene, support, paths, q, placement, options, max_splits, history=None, chain=False):
    """Solve the postures holding each of ``paths`` ((name, FramePlacementConstraint,
    reference posture) triples) in turn, from posture ``q`` whose frame is at
    ``placement`` ((4, 4), world); a waypoint not reached is retried from a waypoint
    halfway toward it from the last one reached (a shorter continuation step, its
    reference posture halfway too), at most ``max_splits`` times in all; ``history``: as
    :func:`_solve_sample`'s, for the first, and with ``chain`` each after it from where the
    one before leaves the kept prints (the order of the motion: not so backward)."""
    results, reached, references, splits, last_reference = [], [], [], 0, q
    pending = [(name, path, reference, False) for name, path, reference in paths]
    while pending:
        name, path, reference, halfway_waypoint = pending[0]
        result = _solve_sample(robot, scene, support, None, path, reference, q, results[-1] if results else None,
                               options, results[-1] if chain and results else history)
        if result.feasible:
            q, placement, last_reference = result.q, path.transform_frame_to_world, reference
            pending.pop(0)
            results.append(result)
            reached.append(path)
            references.append(reference)
        elif splits < max_splits:
            closer = replace(path, transform_frame_to_world=halfway(placement, path.transform_frame_to_world),
                             label=path.label.replace(f"({name})", f"(toward {name})"))
            pending.insert(0, (name, closer, pin.interpolate(robot.model, last_reference, reference, 0.5), True))
            splits += 1
        else:
            reason = f"{name} ({splits} shorter steps tried): {result.reason}"
            # The shorter steps' waypoints are the continuation's own: what is left is the path's.
            left = [(n, p, r) for n, p, r, halfway_waypoint in pending if not halfway_waypoint]
            return _Continuation(results, reached, references, left, reason)
    return _Continuation(results, reached, references, [])


def _solve_sample(robot, scene, support, holding, path, reference, q, previous, options, history=None):
    """The posture holding ``path``, from posture ``q``, checked by :func:`stances.verify`:
    a posture of ``support``, or of ``holding`` (the stance holding the moving contact) for a
    :class:`ContactSample`. ``previous``: the result ``q`` comes from when it is a sample of
    the same problem, the same stance with the same prints held rigid (its forces then start
    the solve too, so soft supports stay sunk where they were), else None. ``history``: the
    leaving stance's answer, where the soft prints the sample keeps start (``stances.solve``).
    """
    stance = holding if isinstance(path, ContactSample) else support
    if isinstance(path, ContactSample):
        options = path.options(options)
    same = (previous is not None and previous.stance == stance
            and tuple(previous.statistics["options"].get("rigid_prints", ())) == tuple(options.get("rigid_prints", ())))
    lam = np.asarray(previous.statistics["lambda"]) if same else None
    result = stances.solve(robot, scene, stance, q_init=q, lam_init=lam, constraints=(path,), reference=reference,
                           history=history, **options)
    if result.feasible:
        verification = stances.verify(robot, scene, stance, result, **options)
        if not verification.ok:
            result = replace(result, feasible=False, reason="; ".join(map(str, verification.reasons)))
    return result


def plan_motions(plan, scenario, robot, **options):
    """The motion between every pair of consecutive stances of a plan.

    Parameters
    ----------
    plan, scenario, robot
        As :func:`plan_motion`.
    **options
        Keyword arguments of :func:`plan_motion`.

    Returns
    -------
    plan : cbm.Plan
        The plan with each stance a motion arrives at with its :attr:`Motion.arrival`
        (``PlannedStance.arrived_by_motion``): each motion starts where the one before
        it left the robot and its soft prints.
    motions : tuple of Motion
        ``len(plan.stances) - 1`` motions, in order.
    """
    planned, motions = list(plan.stances), []
    for index in range(len(planned) - 1):
        motion = plan_motion(replace(plan, stances=planned), index, scenario, robot, **options)
        planned = _arrived(planned, index, motion, scenario.scene, robot, options.get("solver_options"))
        motions.append(motion)
    return replace(plan, stances=tuple(planned)), tuple(motions)


def _arrived(planned, index, motion, scene, robot, solver_options=None):
    """``planned`` (PlannedStance, in order) after ``motion`` from stance ``index``: stance
    ``index + 1`` the motion's :attr:`Motion.arrival` where it has one; where the motion is not
    found, the stances from ``index + 1`` on solved again from where the stance before leaves
    their kept soft prints wherever they do not start there (a stance the motion before
    arrived at with its own answer: :func:`cbm.slip_chain.chained`; where one of them has no
    posture so, the stances as they were, which :meth:`cbm.Plan.check` then reports)."""
    planned = list(planned)
    if motion.arrival is not None:
        planned[index + 1] = planned[index + 1].answered(motion.arrival, arrived_by_motion=True)
    elif not motion.feasible:
        if planned[index + 1].arrived_by_motion:
            # Not arrived by this motion (an earlier run's mark on a plan given again is no longer true).
            planned[index + 1] = replace(planned[index + 1], arrived_by_motion=False)
        again = chained(planned, scene, robot, solver_options, start=index + 1)
        if again is None:
            logger.info("stance %d keeps its answer from the stance before's earlier one", index + 1)
        else:
            planned = again
    return planned


def plan_motions_reposing(plan, scenario, robot, **options):
    """The motions of a plan, solving an arriving stance's posture again where its motion fails.

    The planner chooses each stance's posture without the motion into it in view,
    and a motion can find it out of reach: quadruped-walk's last step puts the
    foot down and moves the weight onto it on one side of a support leg's
    adapter, while the stance's posture has that leg bent the other way, 1 rad
    apart (no posture between them clears the step). Where a motion fails, the
    arriving stance is solved again (and verified) from the motion's first
    unloaded sample on the new print (its touch-down; at a lift-off, the last
    lifted sample), pulled toward that sample's posture, and the motion is
    planned again to the new posture; if that fails too, or the motion out of
    the stance fails from the new posture where it is found from the planned one,
    the stance keeps its posture. The motion out of a reposed stance starts from
    its new posture. A reposed stance starts the soft prints it keeps where the
    stance before leaves them, and each stance after it that keeps a soft print of
    the one before is solved again from where that one now leaves it (from its own
    posture); where one of them then has no posture, the stance is not reposed.

    Parameters
    ----------
    plan, scenario, robot
        As :func:`plan_motion`.
    **options
        Keyword arguments of :func:`plan_motion` (its ``solver_options`` serve
        the stances solved again too).

    Returns
    -------
    plan : cbm.Plan
        The plan with the reposed stances' postures, forces and fields, and each stance a
        motion arrives at with its :attr:`Motion.arrival` (as :func:`plan_motions`).
    motions : tuple of Motion
        ``len(plan.stances) - 1`` motions, in order; ``Motion.reposed`` marks
        those that needed their arriving stance reposed.
    """
    planned = list(plan.stances)
    motions, ahead = [], None  # ahead: the next motion, when a repose needed it planned already
    ahead_from = None  # the planned stance ahead leaves from
    for index in range(len(planned) - 1):
        current = replace(plan, stances=planned)
        motion = ahead if ahead is not None else plan_motion(current, index, scenario, robot, **options)
        ahead = None
        if not motion.feasible:
            reposed = _reposed_stance(current, index, motion, scenario, robot, options.get("solver_options"))
            # The stances after it that keep its soft prints start where it now leaves them.
            trial = None if reposed is None else chained(
                planned[:index + 1] + [reposed] + planned[index + 2:], scenario.scene, robot,
                options.get("solver_options"), start=index + 2)
            if trial is not None:
                retried = plan_motion(replace(plan, stances=trial), index, scenario, robot, **options)
                kept = retried.feasible
                if kept and index + 2 < len(planned):
                    # The motion out of the reposed stance starts from its new posture: kept
                    # unless it fails there where it is found from the planned posture.
                    ahead, ahead_from = plan_motion(replace(plan, stances=trial), index + 1, scenario, robot,
                                                    **options), trial[index + 1]
                    if not ahead.feasible:
                        planned_next = plan_motion(current, index + 1, scenario, robot, **options)
                        if planned_next.feasible:
                            kept, ahead, ahead_from = False, planned_next, planned[index + 1]
                if kept:
                    logger.info("motion %d -> %d found with stance %d reposed", index, index + 1, index + 1)
                    planned, motion = trial, replace(retried, reposed=True)
        planned = _arrived(planned, index, motion, scenario.scene, robot, options.get("solver_options"))
        if ahead is not None and planned[index + 1] is not ahead_from:
            # Planned from the stance's answer before its motion arrived with its own, or before
            # it was solved again from the stance before (the repose not kept): planned again.
            ahead = None
        motions.append(motion)
    return replace(plan, stances=tuple(planned)), tuple(motions)


def _reposed_stance(plan, index, motion, scenario, robot, solver_options):
    """Stance ``index + 1`` of a plan solved again from the failed ``motion``'s touch-down
    sample (else its last sample holding that stance's contacts), pulled toward it: a
    PlannedStance, or None (no such sample, or no posture)."""
    after = plan.stances[index + 1]
    held = [(path, result) for path, result in zip(motion.paths, motion.results) if result.stance == after.stance]
    if not held:
        return None
    # From the (first) unloaded sample on the print where there is one: the load transfer starts there, and samples
    # inserted after it may already lie by the stance's posture, across what blocks it.
    touch = [result for path, result in held if isinstance(path, ContactSample) and path.unloaded]
    start = (touch[0] if touch else held[-1][1]).q
    options = _options_of(after) if solver_options is None else dict(solver_options)
    try:
        result = stances.solve(robot, scenario.scene, after.stance, q_init=start, reference=start,
                               history=history_of(plan.stances[index]), **options)
    except (StanceError, SceneError, FemError) as error:
        # A repose is a second chance, not a requirement: the plan keeps its posture.
        logger.info("stance %d not reposed: %s", index + 1, error)
        return None
    if not result.feasible:  # feasible: stances.verify passed inside the solve
        return None
    return after.answered(result)


def motions_summary(motions) -> str:
    """One line on a plan's motions: how many were found, where any was joined backward, and
    which stances were reposed (:func:`plan_motions_reposing`).

    Examples
    --------
    >>> motions_summary([])
    'motions: 0 of 0 found'
    """
    found = sum(motion.feasible for motion in motions)
    joined = [
        f"{m.index} -> {m.index + 1} at sample {m.seam} (largest joint step there {m.joint_steps[m.seam - 1]:.2f} rad)"
        for m in motions if m.feasible and m.seam is not None
    ]
    reposed = [str(m.index + 1) for m in motions if m.reposed]
    return (f"motions: {found} of {len(motions)} found" + (f"; joined backward: {', '.join(joined)}" if joined else "")
            + (f"; stances reposed for the motion into them: {', '.join(reposed)}" if reposed else ""))


def held_strays(motion, plan, scenario, robot):
    """How far each step of a feasible motion carries a held contact off its line.

    Parameters
    ----------
    motion : Motion
        Feasible (its last posture the next stance's).
    plan, scenario, robot
        As :func:`plan_motion`.

    Returns
    -------
    list of (float, str, float)
        Per step between consecutive configurations: where along it (the fraction of
        :data:`BETWEEN`), which robot surface and how far, metres, the held contact's
        point strays most from the straight line between where the step's two postures
        put it (``(0, "", 0)`` when nothing is held). At most :data:`HELD_DRIFT` in a
        motion planned with the default bound.

    Raises
    ------
    MotionError
        If the motion is not feasible.
    """
    if not motion.feasible:
        raise MotionError("held_strays needs a feasible motion (its steps end on the next stance's posture)")
    before, after = plan.stances[motion.index], plan.stances[motion.index + 1]
    moving, _, _, touch_down = _switch(before, after)
    between = BetweenSamples(robot, scenario.scene, motion.support, moving, _options_of(after))
    holds = _holds(motion, touch_down)
    configurations = motion.configurations
    return [between.largest_drift(configurations[k], configurations[k + 1], held=holds[k] and holds[k + 1])
            for k in range(len(configurations) - 1)]


def _holds(motion, touch_down):
    """(k,) bool: whether each configuration of a feasible motion holds its moving contact."""
    return [not touch_down] + [isinstance(path, ContactSample) for path in motion.paths] + [touch_down]


def verify_motion(motion, plan, scenario, robot, solver_options=None, held_drift=HELD_DRIFT):
    """Check a motion again, sample by sample, independently of its solves.

    Parameters
    ----------
    motion : Motion
    plan : cbm.Plan
        The plan it joins two stances of.
    scenario : environments Scenario
    robot : stances Robot
    solver_options : dict, optional
        As given to :func:`plan_motion`.
    held_drift : float
        As given to :func:`plan_motion`.

    Returns
    -------
    list of str
        Problems, one line each; empty if the motion starts and ends on its
        stances' postures, each of its postures (of a feasible motion) starts where the
        one before it left the soft prints both keep, from the leaving stance's answer to
        the arriving one's (:attr:`Motion.arrival`), every interior sample verifies (:func:`stances.verify`)
        as a stance of the support holding its frame on its waypoint, or (a
        :class:`ContactSample`) as the stance holding the moving contact, with no
        load on it at touch-down and lift-off and a load-transfer sample's pinned
        ``normal_load`` on it (to :data:`UNLOADED_FORCE`); a feasible motion has at least one of
        those (its contact switch), and no posture checked between samples collides
        or carries a held contact more than ``held_drift`` off its line.

    Raises
    ------
    MotionError
        If ``held_drift`` is not a positive distance.
    """
    held_drift = checked_drift(held_drift)
    verify = stances.verify
    before, after = plan.stances[motion.index], plan.stances[motion.index + 1]
    moving, _, holding, touch_down = _switch(before, after)
    normal = scenario.scene.transform_print_to_world(moving.contact_print)[:3, 2]
    options = _options_of(after) if solver_options is None else dict(solver_options)
    problems = []
    ends = [(0, before.q)] + ([(-1, after.q)] if motion.feasible else [])
    for position, q in ends:
        if not np.array_equal(motion.configurations[position], q):
            problems.append(f"sample {position} is not the posture of its stance")
    if motion.feasible:
        between = BetweenSamples(robot, scenario.scene, motion.support, moving, options, held_drift)
        holds = _holds(motion, touch_down)
        steps = len(motion.configurations) - 1
        for k in range(steps):
            problem = between.first_problem(motion.configurations[k], motion.configurations[k + 1],
                                            held=holds[k] and holds[k + 1])
            if problem is not None:
                problems.append(_step_text(k, problem[1], last=k == steps - 1))
    switches = [path for path in motion.paths if isinstance(path, ContactSample) and path.unloaded]
    if motion.feasible and not switches:
        problems.append("no touch-down or lift-off sample: a motion has one at least")
    if motion.feasible and isinstance(before.result, stances.PostureResult):
        # Each posture starts where the one before it left the soft prints both keep.
        chain = [("the stance it leaves", before.result)] + [
            (f"sample {k}", result) for k, result in enumerate(motion.results, start=1)]
        chain.append(("the next stance", after.result))
        for (what, left), (name, result) in zip(chain, chain[1:]):
            problems.extend(f"{name}: {problem}" for problem in slips_not_carried(left, result, what=what))
    for k, (result, path) in enumerate(zip(motion.results, motion.paths)):
        if not np.array_equal(result.q, motion.configurations[k + 1]):
            problems.append(f"sample {k + 1}: its result is not its posture")
        held = isinstance(path, ContactSample)
        checked = path.options(options) if held else options
        verification = verify(robot, scenario.scene, holding if held else motion.support, result, **checked)
        if not verification.ok:
            problems.append(f"sample {k + 1}: " + "; ".join(map(str, verification.reasons)))
        if held and path.unloaded and path.load(result) > UNLOADED_FORCE:
            problems.append(f"sample {k + 1} ({path.label}): {path.load(result):.3g} N on {motion.moving_surface}")
        if held and path.normal_load is not None:
            carried = _normal_load(result.point_forces, path.frame, normal)
            if abs(carried - path.normal_load) > UNLOADED_FORCE:
                problems.append(f"sample {k + 1} ({path.label}): its print carries {carried:.6g} N along its normal, "
                                f"not the {path.normal_load:.6g} N pinned")
        # Where the sample holds the frame (a ContactSample records where it came to rest).
        recorded = path if not held else FramePlacementConstraint(path.frame, path.transform_frame_to_world)
        error = recorded.error(robot, result.q)
        if error > PATH_TOLERANCE:
            problems.append(f"sample {k + 1}: {motion.moving_surface} is {error:.3g} m or rad off its path")
    return problems
