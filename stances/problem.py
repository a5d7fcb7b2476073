"""The posture problem (45)-(49): build it, then linearise it around an iterate.

Building (:func:`build_problem`) turns a stance into contact models and fixes
everything that does not change during a solve, including the list of costs and
constraints (:mod:`stances.terms`, one small piece each); linearising
(:meth:`PostureProblem.linearize`) computes the iterate once (kinematics,
forces, static torques and their Jacobians) and stacks every piece's value and
exact Jacobian at ``(q, lambda)``. The SQP in :mod:`stances.sqp` only stacks
what this returns, so the problem can be inspected, tested and handed to
another solver (the benchmark uses SLSQP).

Unknowns: a tangent step ``dq`` (nv,) applied with ``pin.integrate`` and the
force variables ``lambda`` (m,) of the rigid contacts (friction-cone
coefficients, >= 0). Deformable contacts own no variables: their forces are
functions of q (eq. 29, 44).
"""

from __future__ import annotations

import math
import numbers
import os
from collections import defaultdict
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import pinocchio as pin

from environments.errors import SceneError

from .collision import KEPT_DISTANCE, CollisionChecker, contact_exclusions
from .contacts import PointContact, RigidContact
from .deformable import LAWS, DeformableContact, PrintSpec
from .layer_ball import LayerBalls, layer_sites
from .errors import ConfigurationError, StanceError
from .statics import PointLoads, static_torque_derivatives, static_torques
from .terms import (
    CollisionConstraint,
    ContactConstraints,
    ContactCosts,
    EquilibriumConstraint,
    ForceCost,
    Iterate,
    NormalLoadConstraint,
    PostureCost,
    TorqueLimitConstraint,
    TorqueUsageCost,
    print_normal_loads,
)


# Default weights of the deformation term, by ``deformation_cost``: per joule of
# stored elastic energy, per N^2 of nodal reaction (the paper's).
DEFORMATION_WEIGHTS = {"energy": 1.0, "force": 1e-5}
_FORCE_STEP_IN_WEIGHTS = 10.0  # bound on a force variable's step, in robot weights


@dataclass(frozen=True)
class PostureOptions:
    """Weights, limits and tolerances of a posture solve.

    Parameters
    ----------
    posture_weight : float
        Weight of the squared distance of the joints to the reference posture.
    base_orientation_weight : float
        Weight of the free flyer's orientation error to the reference, per rad^2.
    force_weight : float
        Weight of sum lambda^2 (spreads rigid-contact forces), per N^2.
    torque_weight : float
        Weight of the torque-limit usage beyond half of each limit,
        sum_i max(|tau_i| / tau_max_i - 1/2, 0)^2: loads go where the robot is
        strong instead of onto a joint near its limit.
    effort_margin : float
        Fraction of each joint's effort limit kept free: the solver keeps
        ``|tau_i| <= (1 - effort_margin) tau_max_i``. :func:`stances.verify`
        checks the full limits; the result reports the usage.
    joint_margin : float
        Fraction of each joint's range kept free at both ends.
    deformation_cost : {"energy", "force"}
        The deformation term of the objective (paper note 2): ``"energy"``
        (default) the elastic energy stored in the soft bodies, which vanishes as
        they stiffen, so the posture tends to the rigid support's; ``"force"``
        the paper's squared norm of the nodal reaction forces.
    deformation_weight : float, optional
        Its weight: per joule for ``"energy"`` (default 1), per N^2 for
        ``"force"`` (default 1e-5).
    reaction_model : {"consistent", "traction"}
        How deformable supports react (see :mod:`fem`).
    max_iterations : int
        SQP iteration limit (a soft stance's rigid or bonded warm start stops at 60, or
        at this where lower: :data:`stances.stages._WARM_START_ITERATIONS`).
    trust_region : float
        Bound on each component of a step, rad or m.
    feasibility_tolerance : float
        Accepted violation, in units of each row's scale (see
        :mod:`stances.blocks`): 1e-7 means 1e-9 m placement, 1e-6 N
        equilibrium, 1e-7 N m beyond a torque limit.
    optimality_tolerance : float
        A feasible iterate is final once a step changes the merit function by
        less than this, relative. A nearly feasible one (within 1e-4, scaled) whose
        step would gain less than ten times this of the objective, or whose last three
        steps' gains fall at a rate that leaves less than a hundred times this to gain
        in all, is finished by a restoration step (:data:`stances.stopping.FINISHING_GAIN`,
        :data:`stances.stopping.FINISHING_TAIL`).
    collision_distance : float
        Minimum distance kept between the robot and the scene or itself, m.
    collision_activation : float
        Pairs farther than this are not linearised this iteration, m. At 3 cm the 60
        random rigid bench stances reached the same answers in the same iterations for
        3.5 % fewer instructions, but the suite's quadruped-foam and turn plans (10 seeds)
        took 2,341 solver iterations instead of 2,121, one solve 200 (3.1 s).
    max_collision_rows : int
        At most this many closest pairs enter a QP (20: Talos's four checked
        forearm-sensor pairs are always within reach of the activation
        distance; with 16 they crowded out the feet's rows and step-on-cube's
        rigid start wandered 17 iterations instead of 9).
    self_collision : bool
        Whether the SRDF self-collision pairs are checked.
    indentation_limit : float
        Deformable supports: bound on each print node's indentation along the
        print normal, as a fraction of the body's thickness along that normal.
    max_indentation : float, optional
        The same bound in metres; overrides ``indentation_limit`` when given.
    contact_law : {"coulomb", "sticking", "bonded"}
        Deformable supports, how print nodes meet the link: ``"coulomb"``
        (default) each node sticks, slips with its force on the friction bound, or
        lifts off, solved exactly on the condensed compliance; ``"sticking"``
        every node is bonded and must push and keep its force in its own cone;
        ``"bonded"`` the paper's model: bonded nodes push, only each print's
        resultant is kept in the cone. ``"coulomb"`` needs the consistent
        reaction model.
    ball_contact : {"layer", "nodes"}
        Deformable supports, how a ball foot (a point foot) presses one: ``"layer"``
        (default) where the body is a layer under every ball on it and only balls press
        it (a box, or a convex top face over nothing but the held base, each print far
        enough inside its edges: :func:`stances.layer_ball.layer_site`), each ball
        sinks by the continuum's law of a sphere on a layer (:mod:`stances.layer_ball`),
        and elsewhere as ``"nodes"``: the mesh's nodes touch the ball's profile where it
        reaches them (its force moves with where the ball stands against the nodes when
        the contact is smaller than the cells: -46 % to +31 % on 10 mm cells).
    ball_force_error : float
        Deformable supports, a ball foot pressing mesh nodes (``ball_contact="nodes"``,
        or where the layer's law does not hold): how far its force may be from the
        continuum's at its sinking for the stance to be accepted (0.05), where the body is
        a layer under the ball (:func:`stances.layer_ball.layer_under`; the estimate,
        :func:`fem.sphere_on_layer_force`, within 0.8 % of converged FEMs beside a box's
        sides, 1.1 % of a bevelled pad's). Where there is no estimate a ball sunk into the
        body is refused, however many nodes it presses: a node contact's force is no
        converged one (9-74 pressed nodes: up to +10 % off the continuum, refine_lines bands
        +4.9 to +8.6 % at 2.5 mm, ``bench/results/ball_node_contact.md``; until 2026-12-05, session l, 9
        pressed nodes were accepted). ``inf`` accepts every ball (logged once a body).
    corner_sinking : float
        Deformable supports with Coulomb contact: each corner of a polygon print (a sole, a
        palm) sinks at least this share of the mean of its corners' sinking (0.5), less
        ``max_corner_lift``: a print on a soft body presses with its whole face. A print
        that pivots toward its edge presses a strip narrower than the mesh resolves, and its
        force is no converged one: five palms on their edge in the built-in scenes' answers
        were 6.7-16.4 % below a converged mesh's force for the same motion, where flat prints
        came within 5 % (``bench/results/audit-done-when-2026-12-05.md``; accepted until
        2026-12-05, session m). With every corner merely down (0) climb's palm on the cube
        still lifted 12 of its 20 nodes and came 5.6-7.2 % low; at 0.5, the share a
        frictionless rigid punch on a half-space needs for its whole face to touch (a disc:
        its edge sunk half its mean), 6 nodes and 2.4-3.6 % low. In [0, 1).
    max_corner_lift : float
        How far past ``corner_sinking`` a corner may lift, metres (1e-5): a stiff body's
        give (``stiff_limit``), where a pivot's force error is a motion error of a
        micrometre or two. ``inf`` lets prints pivot, as far as ``tilt_allowance`` lets
        their faces turn (0 for no bound).
    contact_frames : {"turned", "rest"}
        Deformable supports with the Coulomb law: the frames each print node's contact is
        solved in. ``"turned"`` (default, since 2026-12-06): its print's rest frame turned
        with the link's face, as eq. 63 turns the traction model's normals: the gap along the
        face's normal, the slip and the cone in its plane, so a node that slips meets the
        face where it is (``docs/turned-face.md``). ``"rest"``: the print's rest frame, the
        linear model's, as before: a slipping node's gap misses its slip times the face's
        tilt (hand-on-soft-cube's palm 6.2 % off the turned-face contact at its posture) and
        its force leaves the cone about the face by about ``(1 + mu^2) / mu`` times the tilt.
    tilt_allowance : float
        Deformable supports with node cones (``contact_law`` ``"coulomb"`` or ``"sticking"``):
        how far the face of a flat print (a sole, a palm) may turn from the body's rest
        surface, radians (0: no bound): rows keep each print's tilt within it. In the rest
        frames (``contact_frames="rest"``, or the sticking law's pyramids) the nodes' cones are
        narrowed by it too, ``mu' = tan(atan(mu) - a)`` (mu 0.7, 1 degree: 0.674), so that
        every node's force lies in its cone about both the rest normal and the face's; the
        turned frames' cones are the face's already, and the allowance bounds the tilt only.
        :func:`stances.verify` checks the turned face's cones with the surface's own mu where
        it is set. A print takes at most ``atan(mu) / 2``, and at most twice what
        it could turn on a stiff body (its bonded turn under the robot's weight plus
        ``max_corner_lift`` over its width: a fraction of a milliradian at 1e10 Pa, so the
        narrowing fades as E grows; each row's label gives its print's bound); a
        frictionless or infinitely rough print none. In the rest frames answers obey
        Coulomb's law with mu': verify a result with the options it was solved with (results
        record them). In ``[0, pi / 2)``.
    min_normal_force : float
        Each print carries at least this force along its normal, N, so that
        a contact is a support, not a touch. With the torque-usage term a
        palm whose load the legs can take carries nothing by default; set a
        bound where a stance means the hand to push.
    support_load : float or None
        Each print of a surface with the robot's support role (its feet)
        carries at least this share of the robot's weight along its normal, so
        the centre of mass keeps inside the support polygon rather than on its
        edge; None (default) takes the robot's support rule
        (``SupportRule.load``: ANYmal 0.1, the bipeds 0), 0 lets a foot just
        touch. A print's bound is the larger of this and ``min_normal_force``.
    friction_margin : float
        Deformable supports: each print's resultant force stays within the
        friction pyramid of a rigid contact (edges on the Coulomb cone) with mu
        scaled by this, so that a print on a stiff body carries about what a rigid
        contact does. Default 0.99: a print's nodes are never all at the point of
        sliding at once (at 1, hand-on-cube's palm on a 1e4 Pa cube, every node
        sliding, took 119 iterations); 1 gives the paper's bonded model exactly.
    max_slip : float or None
        Deformable supports with Coulomb contact: how far a link point may
        slide over its print node, metres. Contact is solved on the nodes under
        the declared print (small slip, as small strain); a link sliding a
        spacing would touch other nodes. None (default): a quarter of the mesh's
        spacing under the body's prints (:data:`stances.deformable.SLIP_SHARE`;
        5.4-5.6 mm on the default 22.5 mm mesh), at most 2 cm (``SLIP_CAP``).
    max_mesh_overlap : float
        Deformable supports: how far the deformed body may reach into a link's
        contact face, metres, along the print normal (2 mm). A node the print's
        outline covers in part lies its coupling's stretch ``D f`` behind its link
        point (see :mod:`stances.deformable`), so the mesh passes into the link at
        the print's edge; unbounded, a tilted palm's edge let it in by 3.6 mm
        (hand-on-soft-cube) and 5.2 mm (the paper's coarse cube, 4 nodes under
        the palm), several times the body's own displacement there. Rows bound
        it; :func:`stances.verify` checks every node.
    max_strain_rows : int
        Deformable supports: at most this many tets (the most strained ones
        near the prints) bound their principal strains in each QP; the bound
        itself is the object's ``strain_limit``. 0 turns the rows off (verify
        still checks every tet).
    elastic_penalty : float
        Initial weight of the elastic variable that lets the QP relax
        constraints it cannot meet (it grows when needed).
    deformable_as_rigid : bool
        Treat deformable prints as rigid contacts (used for warm starts and
        for comparisons with a rigid support).
    rigid_prints : tuple of str
        Robot surfaces whose prints on deformable surfaces are held as rigid
        contacts on the undeformed surface: a limb that touches a soft support
        without load (a motion's touch-down or lift-off), under which the body
        does not deform.
    touching : tuple of (str, str)
        ``(robot surface, scene surface)`` pairs: the robot surface's contact
        geometry may come as near the scene surface's object as touching it
        (0 m instead of ``collision_distance``) without a contact there: a limb
        approaching its print in a motion, halfway between lifted and set down.
        It still may not go into it (:func:`stances.verify` checks every pair).
    rigid_warm_start : bool
        With deformable contacts, first solve with them held rigid, then
        switch the FEM forces on from that posture: the FEM forces are only
        meaningful near the print, so this homotopy makes solves reliable.
    stiff_limit : bool
        With Coulomb contact and the energy term (``deformation_cost="energy"``): where
        soft bodies of the stance have flat prints only, give less than 10 um under the
        stance's loads (those of the rigid warm start, or ``lam_init``'s) and have nodes
        those loads would lift off or slide (a palm on its edge; not soles flat), the stance
        is solved in those bodies' stiff limit: their prints held rigid with their centre
        of pressure where their nodes are (the other soft bodies solved soft with them),
        the links' motion whose Coulomb forces carry that answer then found, and the
        answer verified as any (as E grows the posture and forces tend to the rigid
        support's; :func:`stances.stages._solve_stiff_limit`). Under
        a time budget, tried only with several warm starts' time left, and then for half
        of it; where it does not hold, the solve goes on as on a softer body. False: always
        as on a softer body.
    reaching_start : bool
        A solve given no posture, none of whose prints lies on a soft body's mesh (those
        start their rigid warm start from the posture over the prints), starts from the
        reference posture over its prints brought onto them by a few damped least-squares steps
        (:func:`stances.reaching_configuration`), and, if it fails from there, solves
        again from the reference posture over the prints (the first attempt's
        iterations and reason in ``statistics["first_start"]``). False: from the reference posture over the prints only.
    constraint_curvature : bool
        Add the curvature of the rigid placement and collision rows, weighted
        by the previous QP's multipliers, to the QP's Hessian (kept convex;
        see :mod:`stances.curvature`) once the iterate is near feasible and
        the Gauss-Newton steps are seen to shrink slowly: the SQP's model
        becomes the Lagrangian's, not the objective's alone (60 random rigid
        stances: 7.0 iterations on average instead of 8.5, hand-on-table 9.5
        instead of 14). False: the objective's Gauss-Newton Hessian only.
        Problems with soft prints leave it out (their rows have no second
        derivatives in q); their rigid warm start uses it. Two curvatures in the
        force variables enter the QP whatever this says
        (:attr:`stances.blocks.ConstraintBlock.variable_curvature`): a ball's strain
        row on a layer, from the start, and near feasibility the soft Coulomb forces'
        through static equilibrium and the torques
        (:meth:`stances.deformable.DeformableContact.force_curvature`).
    """

    posture_weight: float = 1.0
    base_orientation_weight: float = 1.0
    force_weight: float = 1e-5
    torque_weight: float = 1.0
    effort_margin: float = 0.1
    joint_margin: float = 0.02
    deformation_cost: str = "energy"
    deformation_weight: float | None = None
    reaction_model: str = "consistent"
    max_iterations: int = 100
    trust_region: float = 0.3
    feasibility_tolerance: float = 1e-7
    optimality_tolerance: float = 1e-7
    collision_distance: float = KEPT_DISTANCE
    collision_activation: float = 0.05
    max_collision_rows: int = 20
    self_collision: bool = True
    indentation_limit: float = 0.25
    max_indentation: float | None = None
    contact_law: str = "coulomb"
    ball_contact: str = "layer"
    ball_force_error: float = 0.05
    corner_sinking: float = 0.5
    max_corner_lift: float = 1e-5
    contact_frames: str = "turned"
    tilt_allowance: float = 0.0
    min_normal_force: float = 0.0
    support_load: float | None = None
    friction_margin: float = 0.99
    max_slip: float | None = None
    max_mesh_overlap: float = 2e-3
    max_strain_rows: int = 12
    elastic_penalty: float = 1e2
    deformable_as_rigid: bool = False
    rigid_prints: tuple = ()
    touching: tuple = ()
    rigid_warm_start: bool = True
    stiff_limit: bool = True
    reaching_start: bool = True
    constraint_curvature: bool = True

    def __post_init__(self) -> None:
        if self.reaction_model not in ("consistent", "traction"):
            raise StanceError(
                f"reaction_model must be 'consistent' or 'traction', got {self.reaction_model!r}"
            )
        if self.deformation_cost not in DEFORMATION_WEIGHTS:
            raise StanceError(
                f"deformation_cost must be one of {tuple(DEFORMATION_WEIGHTS)}, got {self.deformation_cost!r}"
            )
        if self.deformation_weight is None:
            object.__setattr__(self, "deformation_weight", DEFORMATION_WEIGHTS[self.deformation_cost])
        # Every weight, distance and tolerance is a finite number: a NaN weight made
        # every QP fail and the stance "unreachable", a NaN distance was ignored.
        for name in _NON_NEGATIVE + _POSITIVE + ("ball_force_error", "corner_sinking", "max_corner_lift", "tilt_allowance", "max_indentation"):
            value = getattr(self, name)
            if value is None and name in _BY_DEFAULT:
                continue
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise StanceError(f"{name} must be a number, got {value!r}")
        for name in _NON_NEGATIVE:
            if not 0.0 <= getattr(self, name) < np.inf:
                raise StanceError(f"{name} must be >= 0 and finite, got {getattr(self, name)}")
        if self.contact_law not in LAWS:
            raise StanceError(f"contact_law must be one of {LAWS}, got {self.contact_law!r}")
        if self.ball_contact not in BALL_CONTACTS:
            raise StanceError(f"ball_contact must be one of {BALL_CONTACTS}, got {self.ball_contact!r}")
        if not self.ball_force_error > 0.0:
            raise StanceError(f"ball_force_error must be > 0 (a fraction; inf accepts every ball), "
                              f"got {self.ball_force_error}")
        if not 0.0 <= self.corner_sinking < 1.0:
            raise StanceError(f"corner_sinking must be a share in [0, 1) of a print's mean sinking, got {self.corner_sinking}")
        if not self.max_corner_lift > 0.0:
            raise StanceError(f"max_corner_lift must be > 0 metres (inf lets prints pivot on an edge), "
                              f"got {self.max_corner_lift}")
        if self.contact_frames not in CONTACT_FRAMES:
            raise StanceError(f"contact_frames must be one of {CONTACT_FRAMES}, got {self.contact_frames!r}")
        if not 0.0 <= self.tilt_allowance < 0.5 * math.pi:
            raise StanceError(f"tilt_allowance must be an angle in [0, pi/2) radians (0: no tilt bound), "
                              f"got {self.tilt_allowance}")
        if self.contact_law == "coulomb" and self.reaction_model == "traction":
            raise StanceError(
                "contact_law='coulomb' solves contact on the compliance, which the traction model has not: "
                "use reaction_model='consistent', or contact_law='bonded' with traction"
            )
        for name in ("max_iterations", "max_collision_rows", "max_strain_rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
                raise StanceError(f"{name} must be a whole number >= 0, got {value!r}")
        for name in _POSITIVE:
            if getattr(self, name) is None and name in _BY_DEFAULT:
                continue
            if not 0.0 < getattr(self, name) < np.inf:
                raise StanceError(f"{name} must be > 0 and finite, got {getattr(self, name)}")
        for name in ("effort_margin", "joint_margin"):
            if not 0.0 <= getattr(self, name) < 0.5:
                raise StanceError(f"{name} must be a fraction in [0, 0.5), got {getattr(self, name)}")
        if not 0.0 < self.friction_margin <= 1.0:
            raise StanceError(f"friction_margin must be in (0, 1], got {self.friction_margin}")
        if self.collision_activation < self.collision_distance:
            # Pairs are linearised from the activation distance on: nearer than the
            # distance they keep, they must be.
            raise StanceError(
                f"collision_activation ({self.collision_activation:g} m) must be at least collision_distance "
                f"({self.collision_distance:g} m): pairs nearer than the distance they keep would not be checked"
            )
        if self.support_load is not None and (
            isinstance(self.support_load, bool) or not isinstance(self.support_load, numbers.Real)
            or not 0.0 <= self.support_load < 1.0
        ):
            raise StanceError(
                f"support_load must be a share of the robot's weight in [0, 1) (or None: the robot's support "
                f"rule), got {self.support_load!r}"
            )
        if self.max_indentation is not None and not 0.0 < self.max_indentation < np.inf:
            raise StanceError(f"max_indentation must be > 0 metres and finite (or None), got {self.max_indentation}")
        if isinstance(self.rigid_prints, str) or not all(isinstance(name, str) for name in self.rigid_prints):
            raise StanceError(f"rigid_prints must be a sequence of robot surface names, got {self.rigid_prints!r}")
        object.__setattr__(self, "rigid_prints", tuple(self.rigid_prints))
        pairs = self.touching
        if isinstance(pairs, str) or not all(
            not isinstance(pair, str) and len(pair) == 2 and all(isinstance(name, str) for name in pair) for pair in pairs
        ):
            raise StanceError(
                f"touching must be a sequence of (robot surface, scene surface) name pairs, got {self.touching!r}"
            )
        object.__setattr__(self, "touching", tuple(tuple(pair) for pair in pairs))


#: How a ball foot presses a soft body (PostureOptions.ball_contact).
BALL_CONTACTS = ("layer", "nodes")
CONTACT_FRAMES = ("turned", "rest")

#: Options that are finite numbers >= 0 (weights, newtons, metres) and > 0 (steps,
#: tolerances, penalties, metres), checked by :class:`PostureOptions`.
_NON_NEGATIVE = (
    "posture_weight", "base_orientation_weight", "force_weight", "torque_weight", "deformation_weight",
    "min_normal_force", "collision_distance", "collision_activation",
)
_POSITIVE = (
    "trust_region", "feasibility_tolerance", "optimality_tolerance", "indentation_limit", "elastic_penalty", "max_slip",
    "max_mesh_overlap",
)

#: Options whose None means "from the scene" (the body's thickness, the mesh's spacing).
_BY_DEFAULT = ("max_indentation", "max_slip")

_ON_BOUND = 1e-5  # a usage this close to its bound (fraction of the limit) is on it


class _Rows:
    """The feasibility reading shared by :class:`Evaluation` and :class:`Linearization`
    (both hold ``blocks``, a list of :class:`~stances.blocks.ConstraintBlock`)."""

    def met(self, tolerance: float) -> bool:
        """Whether every row is within ``tolerance`` (scaled) or its block's ``accuracy``
        (found once per tolerance, as :meth:`worst_row`)."""
        known = self.__dict__.setdefault("_met", {})
        if tolerance not in known:
            known[tolerance] = all(block.met(tolerance) for block in self.blocks if len(block))
        return known[tolerance]

    def max_violation(self) -> tuple[float, str]:
        """Largest scaled violation and the label of its row."""
        worst, label, _ = self.worst_row()
        return worst, label

    def worst_row(self) -> tuple[float, str, float]:
        """Largest scaled violation, the label of its row and the violation in the
        row's own units (metres, radians, newtons...).

        Found once (the SQP asks two or three times an iterate: 3 % of a rigid solve
        when each asking went through the blocks again); the blocks do not change.
        """
        known = self.__dict__.get("_worst_row")
        if known is not None:
            return known
        worst, label, raw = 0.0, "", 0.0
        for block in self.blocks:
            if len(block):
                violation = block.violation()
                i = int(np.argmax(violation))
                if violation[i] > worst:
                    worst, label, raw = float(violation[i]), block.labels[i], float(violation[i] * block.scale[i])
        self.__dict__["_worst_row"] = (worst, label, raw)
        return worst, label, raw


@dataclass
class Evaluation(_Rows):
    """Objective and constraint values at one iterate, without derivatives.

    What a line search needs of a trial point (:meth:`PostureProblem.evaluate`):
    the same numbers as :class:`Linearization` at that point, computed without
    the Jacobians.

    Attributes
    ----------
    objective : float
        Objective value.
    blocks : list of ConstraintBlock
        Constraint rows, ``jacobian`` None.
    forces : (k, 3) float
        Contact forces on the robot at the iterate, world, newtons.
    torques : (nv,) float
        ``g(q) - sum J^T f`` at the iterate.
    """

    objective: float
    blocks: list
    forces: np.ndarray
    torques: np.ndarray


@dataclass
class Linearization(_Rows):
    """Everything the SQP needs at one iterate.

    Attributes
    ----------
    objective : float
        Objective value.
    gradient : (n,) float
        Objective gradient in the step (dq, dlambda).
    hessian : (n, n) float
        Gauss-Newton Hessian of the objective.
    blocks : list of ConstraintBlock
        Linearised constraints.
    step_lower, step_upper : (n,) float
        Bounds on the step (joint limits, lambda >= 0, trust region).
    forces : (k, 3) float
        Contact forces on the robot at the iterate, world, newtons.
    torques : (nv,) float
        ``g(q) - sum J^T f`` at the iterate.
    iterate : Iterate or None
        What the pieces read at the iterate (:meth:`PostureProblem.iterate`).
    cost_parts : dict
        Each cost piece's ``(value, gradient, hessian)`` by its index in
        ``PostureProblem.costs``: :meth:`PostureProblem.reweighted` sums them again.
    """

    objective: float
    gradient: np.ndarray
    hessian: np.ndarray
    blocks: list
    step_lower: np.ndarray
    step_upper: np.ndarray
    forces: np.ndarray
    torques: np.ndarray
    iterate: object = None
    cost_parts: dict = field(default_factory=dict)


def _summed(parts: dict, n: int):
    """Objective, (n,) gradient and (n, n) Hessian: the cost pieces' parts summed in index order."""
    objective, gradient, hessian = 0.0, np.zeros(n), np.zeros((n, n))
    for index in sorted(parts):
        value, grad, hess = parts[index]
        objective += value
        gradient += grad
        hessian += hess
    return objective, gradient, hessian


class PostureProblem:
    """A stance's posture problem, ready to be linearised.

    Build it with :func:`build_problem`.

    Attributes
    ----------
    robot : stances.Robot
    contacts : list
        Contact models (rigid and deformable), in stance order.
    options : PostureOptions
    n_variables : int
        Size of lambda.
    variable_slices, load_slices : list of slice
        Each contact's force variables in lambda, and its point loads in the
        stacked loads (and in a result's ``point_forces``).
    """

    def __init__(self, robot, scene, stance, contacts, options, collision_checker=None):
        self.robot = robot
        self.scene = scene
        self.stance = stance
        self.contacts = contacts
        self.options = options
        self.collision_checker = collision_checker
        self.data = pin.Data(robot.model)  # (createData returns a copy: 50 us more)
        self.loads = PointLoads.concatenate(c.loads for c in contacts)
        self.variable_slices, self.load_slices = [], []
        start = load_start = 0
        for contact in contacts:
            self.variable_slices.append(slice(start, start + contact.n_variables))
            self.load_slices.append(slice(load_start, load_start + len(contact.loads)))
            start += contact.n_variables
            load_start += len(contact.loads)
        self.n_variables = start
        self.variable_lower = np.concatenate([c.variable_lower for c in contacts]) if contacts else np.zeros(0)
        # The force term spreads the rigid contacts' cone coefficients (and balls' on layers); a soft print
        # weighs its generalised force W itself (DeformableContact.cost).
        self.force_weights = np.concatenate(
            [np.full(c.n_variables, 1.0 if c.kind in ("rigid", "layer") else 0.0) for c in contacts]
        ) if contacts else np.zeros(0)
        model = robot.model
        self.posture_weights = np.full(model.nv, options.posture_weight)
        self.posture_weights[:3] = 0.0  # the base may go anywhere
        self.posture_weights[3:6] = options.base_orientation_weight
        self.reference = robot.reference_configuration
        # The joint and effort margins shrink the limits the solver keeps.
        lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
        keep = options.joint_margin * (upper - lower)
        self.q_lower, self.q_upper = lower + keep, upper - keep
        self.effort_limits = robot.effort_limits  # (nv - 6,) N m, read at every linearisation
        self.effort = (1.0 - options.effort_margin) * self.effort_limits
        self.force_step = _FORCE_STEP_IN_WEIGHTS * robot.weight  # N, bound on a force variable's step
        # The pieces linearize stacks, in this order (rows and costs), see stances.terms.
        self.constraints = [EquilibriumConstraint(), TorqueLimitConstraint.for_robot(robot, options.effort_margin)]
        self.min_normal_loads = self._min_normal_loads(robot, contacts, options)
        if np.any(self.min_normal_loads > 0):
            self.constraints.append(NormalLoadConstraint(self.min_normal_loads))
        self.constraints.append(ContactConstraints())
        if collision_checker is not None:
            self.constraints.append(
                CollisionConstraint(collision_checker, options.collision_distance, options.max_collision_rows,
                                    touching_pairs(robot, scene, options))
            )
        self.costs = [PostureCost(), TorqueUsageCost(options.torque_weight)]
        if self.n_variables:
            self.costs.append(ForceCost(options.force_weight))
        self.costs.append(ContactCosts())

    @property
    def n_step(self) -> int:
        """Size of the step vector (nv + m)."""
        return self.robot.model.nv + self.n_variables

    def initial_variables(self, q) -> np.ndarray:
        """Force variables at ``q``: the robot's weight shared evenly among rigid
        contacts' cone coefficients, and each deformable contact's own start."""
        lam = np.zeros(self.n_variables)
        # Ball feet on layers carry pyramids as rigid contacts do.
        rigid = [(c, s) for c, s in zip(self.contacts, self.variable_slices) if c.kind in ("rigid", "layer")]
        if rigid:
            weight = self.robot.weight
            # Cone edges are tilted: each carries cos(edge, normal) vertically.
            vertical = min(c.generators[2::3].sum(axis=0).max() for c, _ in rigid)
            count = sum(c.n_variables for c, _ in rigid)
            for _, s in rigid:
                lam[s] = weight / (count * vertical)
        deformable = [(c, s) for c, s in zip(self.contacts, self.variable_slices) if c.kind == "deformable"]
        if deformable:
            model, data = self.robot.model, self.data
            pin.framesForwardKinematics(model, data, q)
            for contact, s in deformable:
                lam[s] = contact.initial_variables(model, data)
        return lam

    def variables_from_rigid(self, rigid, lam, point_forces) -> np.ndarray:
        """Force variables carrying the answer of this stance held rigid.

        Parameters
        ----------
        rigid : PostureProblem
            The same stance with ``deformable_as_rigid``, or with some soft bodies'
            prints held (``held_prints``), the others soft.
        lam : (m_rigid,) float
            Its force variables at its answer.
        point_forces : sequence of PointForce
            Its forces on the robot at that answer, world frame.

        Returns
        -------
        (m,) float
            Rigid contacts' cone coefficients as ``rigid``'s; a body soft in both its
            variables in ``rigid``; each other soft print's W the one that carries its
            resultant wrench there (:meth:`DeformableContact.variables_from_forces`: the
            wrench itself, less what held slips carry).
        """
        out = np.zeros(self.n_variables)
        slices, soft = {}, {}
        for c, s in zip(rigid.contacts, rigid.variable_slices):
            if c.deformable_object is None:
                slices[c.robot_surface] = s
            else:
                soft[c.deformable_object.name] = s
        for contact, s in zip(self.contacts, self.variable_slices):
            if contact.deformable_object is not None and contact.deformable_object.name in soft:
                out[s] = np.asarray(lam)[soft[contact.deformable_object.name]]
            elif contact.kind == "deformable":
                out[s] = contact.variables_from_forces(self.robot.model, point_forces)
            elif contact.kind == "layer":
                out[s] = np.concatenate([np.asarray(lam)[slices[ball.robot_surface]] for ball in contact.balls])
            else:
                out[s] = np.asarray(lam)[slices[contact.robot_surface]]
        return out

    @staticmethod
    def _min_normal_loads(robot, contacts, options) -> np.ndarray:
        """(k,) newtons: :func:`min_normal_load` of each print, in the order of
        :func:`stances.terms.print_normal_loads`."""
        surfaces = [surface for contact in contacts for surface in contact.print_surfaces]
        return np.array([min_normal_load(robot, surface, options) for surface in surfaces], dtype=float)

    def limit_usage(self, q, torques, iterate=None) -> dict:
        """How close a posture comes to the robot's joint, effort and load limits.

        Parameters
        ----------
        q : (nq,) float
        torques : (nv - 6,) float
            Actuated joint torques, N m.
        iterate : Iterate, optional
            The iterate whose contact forces give the prints' loads.

        Returns
        -------
        dict
            ``torque_usage`` (largest ``|tau_i| / tau_max_i``, of the full
            limit) and its ``torque_joint``; ``joint_clearance`` (smallest
            distance to a position limit, as a fraction of the joint's range)
            and its ``clearance_joint``; ``at_margin``, the joints whose torque
            or position sits on the bound its margin sets, which the solver
            keeps (a margin of zero means on the limit itself). Torques are
            moved off half their limit by the objective; positions are not, so
            a joint may sit on its position margin where the posture term or a
            constraint pulls it. With ``iterate`` and contacts, ``least_load``
            (the smallest load a print carries along its normal, as a share of
            the robot's weight) and its ``least_load_print``; a print on the
            least load its support share or ``min_normal_force`` asks is in
            ``at_margin`` too.
        """
        model, options = self.robot.model, self.options
        names = self.robot.actuated_joint_names
        usage = np.abs(np.asarray(torques, float)) / self.robot.effort_limits
        lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
        clearance = np.minimum(q[7:] - lower, upper - q[7:]) / (upper - lower)
        at_margin = [
            f"torque of {names[i]} at {100 * usage[i]:.1f} % of its limit"
            for i in np.flatnonzero(usage >= 1.0 - options.effort_margin - _ON_BOUND)
        ] + [
            f"position of {names[i]} at {100 * clearance[i]:.2f} % of its range from a limit"
            for i in np.flatnonzero(clearance <= options.joint_margin + _ON_BOUND)
        ]
        worst_torque, worst_joint = int(np.argmax(usage)), int(np.argmin(clearance))
        usage = {
            "torque_usage": float(usage[worst_torque]),
            "torque_joint": names[worst_torque],
            "joint_clearance": float(clearance[worst_joint]),
            "clearance_joint": names[worst_joint],
        }
        if iterate is not None and len(iterate.forces):
            labels, loads, _ = print_normal_loads(self, iterate)
            weight = self.robot.weight
            bound = self.min_normal_loads > 0
            at_margin += [
                f"{labels[i]} carrying {100 * loads[i] / weight:.1f} % of the weight, its least"
                for i in np.flatnonzero(bound & (loads <= self.min_normal_loads + _ON_BOUND * weight))
            ]
            least = int(np.argmin(loads))
            usage.update(least_load=float(loads[least] / weight), least_load_print=labels[least])
        return {**usage, "at_margin": at_margin}

    def check_configuration(self, q) -> np.ndarray:
        """A validated copy of ``q`` (size, finite, unit quaternion renormalised)."""
        q = np.array(q, dtype=float).reshape(-1)
        if q.shape != (self.robot.nq,):
            raise ConfigurationError(
                f"q must have shape ({self.robot.nq},) for robot {self.robot.name!r}, got {q.shape}"
            )
        if not np.all(np.isfinite(q)):
            raise ConfigurationError(f"q has non-finite entries at indices {np.flatnonzero(~np.isfinite(q)).tolist()}")
        norm = np.linalg.norm(q[3:7])
        if not 0.5 < norm < 2.0:
            raise ConfigurationError(f"q[3:7] must be a unit quaternion (x, y, z, w), its norm is {norm:.3g}")
        q[3:7] /= norm
        # Start inside the joint limits: the QP keeps iterates there.
        q[7:] = np.clip(q[7:], self.q_lower, self.q_upper)
        return q

    def linearize(self, q, lam, torque_weight=None) -> Linearization:
        """Evaluate objective and constraints, with Jacobians, at ``(q, lam)``.

        Parameters
        ----------
        q : (nq,) float
            Configuration.
        lam : (m,) float
            Rigid-contact force variables, newtons.
        torque_weight : float, optional
            Overrides the options' weight of the torque-limit usage (the SQP
            leaves the term out until it is near feasible).

        Returns
        -------
        Linearization
        """
        options = self.options
        nv, n = self.robot.model.nv, self.n_step
        iterate = self.iterate(q, lam)
        blocks = [block for term in self.constraints for block in term.blocks(self, iterate)]
        parts = {index: term.evaluate(self, iterate) for index, term in self._costs(torque_weight)}
        objective, gradient, hessian = _summed(parts, n)

        # Bounds on the step: trust region, joint limits, lambda >= 0.
        step_lower = np.full(n, -options.trust_region)
        step_upper = np.full(n, options.trust_region)
        step_lower[6:nv] = np.maximum(step_lower[6:nv], self.q_lower - q[7:])
        step_upper[6:nv] = np.minimum(step_upper[6:nv], self.q_upper - q[7:])
        # Force variables move by at most ten body weights a step: an
        # infeasible stance's elastic QP can otherwise send them to 1e20 and
        # the next iterate's torques overflow.
        step_lower[nv:] = np.maximum(self.variable_lower - lam, -self.force_step)
        step_upper[nv:] = self.force_step
        return Linearization(
            objective, gradient, hessian, blocks, step_lower, step_upper, iterate.forces, iterate.tau, iterate, parts
        )

    def reweighted(self, linearization: Linearization, torque_weight: float) -> Linearization:
        """A linearisation with the torque-usage term at another weight: the same rows,
        bounds and iterate, the costs summed again in :meth:`linearize`'s order: what
        linearising again at that weight gives, bit for bit, with the same contact modes
        (soft prints' contact solves start from the last modes found, so a linearisation
        made after other evaluations may differ by rounding), without the kinematics,
        contact solves and collision distances (10-15 ms on a soft stance).

        Parameters
        ----------
        linearization : Linearization
            From :meth:`linearize` of this problem.
        torque_weight : float

        Returns
        -------
        Linearization
        """
        parts = {}
        for index, term in self._costs(torque_weight):
            if isinstance(term, TorqueUsageCost):
                # It reads the iterate's torques alone (the other pieces read self.data,
                # which later calls overwrite: they are taken as they were).
                parts[index] = term.evaluate(self, linearization.iterate)
            elif index in linearization.cost_parts:
                parts[index] = linearization.cost_parts[index]
            else:
                raise StanceError(
                    f"reweighted needs a linearisation of this problem (from its linearize): cost piece {index} "
                    f"({type(term).__name__}) is missing from the one given"
                )
        objective, gradient, hessian = _summed(parts, self.n_step)
        return replace(linearization, objective=objective, gradient=gradient, hessian=hessian, cost_parts=parts)

    def evaluate(self, q, lam, torque_weight=None) -> Evaluation:
        """Objective and constraint values at ``(q, lam)``, without Jacobians.

        The same numbers as :meth:`linearize` gives (objective, every row's
        value, forces and torques), bit for bit, for about two thirds of its
        cost (measured in the built-in soft stances' solves: 2.1 against 3.2 ms):
        what a line search's shortened trials need. What the pieces compute
        that a linearisation at the same point can reuse (collision distances,
        soft contact solves) is kept for it. Parameters are those of
        :meth:`linearize`.

        Returns
        -------
        Evaluation
        """
        iterate = self.iterate(q, lam, derivatives=False)
        blocks = [block for term in self.constraints for block in term.blocks(self, iterate)]
        objective = 0.0
        for _, term in self._costs(torque_weight):
            objective += term.evaluate(self, iterate)[0]
        return Evaluation(objective, blocks, iterate.forces, iterate.tau)

    def _costs(self, torque_weight):
        """``(index in costs, piece)`` of the cost pieces, with the torque-usage term at
        ``torque_weight`` (left out at 0)."""
        for index, term in enumerate(self.costs):
            if isinstance(term, TorqueUsageCost) and torque_weight is not None:
                term = TorqueUsageCost(torque_weight)
            if isinstance(term, TorqueUsageCost) and not term.weight:
                continue
            yield index, term

    def iterate(self, q, lam, derivatives=True) -> Iterate:
        """Kinematics (in ``self.data``), contact forces and static torques at
        ``(q, lam)``, with their Jacobians in the step unless ``derivatives`` is
        False: what every term reads."""
        model, data = self.robot.model, self.data
        nv = model.nv
        pin.framesForwardKinematics(model, data, q)
        if not derivatives:
            forces = [contact.forces(model, data, lam[s]) for contact, s in zip(self.contacts, self.variable_slices)]
            forces = np.vstack(forces) if forces else np.zeros((0, 3))
            return Iterate(q, lam, forces, None, static_torques(model, data, q, self.loads, forces), None)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        # Contact forces and their derivatives (deformable ones depend on q).
        forces, force_dq, force_dlam, curvatures, row = [], [], [], [], 0
        for contact, s in zip(self.contacts, self.variable_slices):
            forces.append(contact.forces(model, data, lam[s]))
            dq_part, dlam_part = contact.force_jacobians(model, data, lam[s])
            force_dq.append(dq_part)
            full = np.zeros((dlam_part.shape[0], self.n_variables))
            full[:, s] = dlam_part
            force_dlam.append(full)
            curvature = contact.force_curvature(model, data, lam[s])
            if curvature is not None:
                curvatures.append((slice(row, row + dlam_part.shape[0]), s, curvature))
            row += dlam_part.shape[0]
        forces = np.vstack(forces) if forces else np.zeros((0, 3))
        force_dq = np.vstack(force_dq) if force_dq else np.zeros((0, nv))
        force_dlam = np.vstack(force_dlam) if force_dlam else np.zeros((0, self.n_variables))
        tau, dtau_dq, dtau_dforces = static_torque_derivatives(model, data, q, self.loads, forces)
        # The static-torque routine reruns kinematics; frames need refreshing.
        pin.updateFramePlacements(model, data)
        tau_jacobian = np.hstack([dtau_dq + dtau_dforces @ force_dq, dtau_dforces @ force_dlam])
        return Iterate(q, lam, forces, np.hstack([force_dq, force_dlam]), tau, tau_jacobian,
                       tau_force_jacobian=dtau_dforces, force_curvatures=tuple(curvatures))


def min_normal_load(robot, robot_surface: str, options: PostureOptions) -> float:
    """Newtons: the least load a print of ``robot_surface`` carries along its normal,
    ``min_normal_force`` or, for a surface of the robot's support role (a foot), its
    share of the weight (``options.support_load``, else the robot's support rule), the larger."""
    share = robot.support.load if options.support_load is None else options.support_load
    foot = robot.surface(robot_surface).role == robot.support.role
    return max(options.min_normal_force, share * robot.weight if foot else 0.0)


def check_posture_arguments(robot, scene, stance) -> None:
    """Refuse the arguments a caller most often swaps for the robot, scene and stance.

    A robot's name, a scenario where its scene belongs, a stance's name or its plain
    dictionary would otherwise fail deep inside, on a missing attribute.

    Raises
    ------
    TypeError
        Saying what was given and how to get what is needed.
    """
    if isinstance(robot, (str, os.PathLike)):
        raise TypeError(f"robot must be a stances.Robot, got the name {str(robot)!r}: load it once with "
                        f"stances.Robot.load({str(robot)!r}) and pass that (loading takes about half a second)")
    if hasattr(scene, "stances") and hasattr(scene, "scene"):
        raise TypeError("scene must be an environments.Scene, got a scenario: pass scenario.scene")
    if isinstance(stance, str):
        raise TypeError(f"stance must be an environments.Stance, got the name {stance!r}: "
                        f"scenario.stance({stance!r}) gives the scenario's stance of that name")
    if isinstance(stance, Mapping):
        raise TypeError("stance must be an environments.Stance, got a mapping: environments.Stance.from_dict(...) "
                        "reads one ({robot surface: {surface, x, y, theta}})")


def build_problem(robot, scene, stance, options: PostureOptions | None = None, held_prints=None,
                  held_slips=None) -> PostureProblem:
    """Turn a stance into a posture problem.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance
        Contacts to hold. Each robot surface must exist on ``robot`` and each
        print's surface in ``scene``.
    options : PostureOptions, optional
    held_prints : dict, optional
        Robot surface -> :class:`~stances.deformable.HeldPrint`: a soft print held rigid
        in its body's stiff limit, its centre of pressure in its reach, its resultant in
        its friction pyramid (:meth:`stances.deformable.DeformableContact.held_prints`);
        the other soft prints stay soft unless ``options.deformable_as_rigid``. Every
        print of a body or none: a body is one contact system.
    held_slips : dict, optional
        Robot surface -> :class:`~stances.results.NodeSlips`: where its soft print's link
        points start over the print's nodes (the stance before left them there; see
        ``history`` of :func:`stances.solve`). Read under the ``coulomb`` law only.

    Returns
    -------
    PostureProblem

    Raises
    ------
    StanceError
        For an empty stance, an unknown robot surface or scene surface, or a
        print whose origin lies off its surface.
    environments.SceneError
        For a soft body pressed by the stance whose own weight strains it beyond its
        strain bound (:attr:`environments.DeformableObject.self_weight_field`).
    """
    check_posture_arguments(robot, scene, stance)
    options = options or PostureOptions()
    if len(stance) == 0:
        raise StanceError("the stance has no contact; a robot cannot stand on nothing")
    unknown = sorted(set(options.rigid_prints) - {c.robot_surface for c in stance})
    if unknown:
        raise StanceError(
            f"rigid_prints names {unknown}, not in the stance; its robot surfaces: {sorted(c.robot_surface for c in stance)}"
        )
    for surface, support in options.touching:
        robot.surface(surface)  # raise with the known names
        scene.surface(support)
    unheld = sorted(set(held_prints or {}) - {c.robot_surface for c in stance})
    if unheld:
        raise StanceError(f"held_prints names {unheld}, not in the stance; its robot surfaces: "
                          f"{sorted(c.robot_surface for c in stance)}")
    unknown = sorted(set(held_slips or {}) - {c.robot_surface for c in stance})
    if unknown:
        raise StanceError(f"held_slips names {unknown}, not in the stance; its robot surfaces: "
                          f"{sorted(c.robot_surface for c in stance)}")
    contacts = []
    # All prints on one deformable object form one contact system (they are
    # coupled through the body); it takes the place of the object's first print.
    deformable_prints: dict[str, list] = {}
    held_bodies: dict[str, list] = defaultdict(list)  # the robot surfaces held_prints holds on each body
    for contact in stance:
        robot.surface(contact.robot_surface)  # raises FrameNotFound with the known names
        contact_print = contact.contact_print
        try:
            surface = scene.surface(contact_print.surface)
        except SceneError as error:
            raise StanceError(str(error)) from None
        if not surface.contains(np.array([[contact_print.x, contact_print.y]]))[0]:
            raise StanceError(
                f"the print of {contact.robot_surface} at ({contact_print.x:.3f}, {contact_print.y:.3f}) "
                f"lies off surface {surface.name!r}; pick x, y inside its polygon "
                f"{np.round(surface.polygon, 3).tolist()}"
            )
        transform = surface.transform_print_to_world(contact_print.x, contact_print.y, contact_print.theta)
        label = f"{contact.robot_surface} on {surface.name}"
        held = (held_prints or {}).get(contact.robot_surface)
        if (surface.deformable and not options.deformable_as_rigid and held is None
                and contact.robot_surface not in options.rigid_prints):
            deformable_object = scene.deformable_of_surface(surface.name)
            if deformable_object.name not in deformable_prints:
                deformable_prints[deformable_object.name] = []
                contacts.append(deformable_object)  # placeholder, replaced below
            deformable_prints[deformable_object.name].append(
                PrintSpec(contact.robot_surface, surface, transform, label, (held_slips or {}).get(contact.robot_surface)))
        elif robot.surface(contact.robot_surface).is_point:
            if held is not None:
                raise StanceError(f"held_prints names {contact.robot_surface}, a point foot: only prints with a "
                                  f"polygon are held in a body's stiff limit")
            contacts.append(PointContact(robot, contact.robot_surface, transform, surface.friction, label, surface=surface))
        elif held is not None:
            if surface.deformable:
                held_bodies[scene.deformable_of_surface(surface.name).name].append(contact.robot_surface)
            # The face held where the body's give puts it (HeldPrint.motion; at rest by default).
            moved = transform @ pin.exp6(pin.Motion(held.motion[:3], held.motion[3:])).homogeneous
            contacts.append(RigidContact(robot, contact.robot_surface, moved, surface.friction, label,
                                         surface=surface, reach=held.reach, resultant_friction=held.resultant_friction))
        else:
            contacts.append(RigidContact(robot, contact.robot_surface, transform, surface.friction, label, surface=surface))
    split = sorted(set(held_bodies) & set(deformable_prints))
    if split:
        name = split[0]
        raise StanceError(
            f"held_prints holds {held_bodies[name]} on {name} but not {[p.robot_surface for p in deformable_prints[name]]}: "
            f"a body's prints are one contact system, hold all of them or none")
    for name in deformable_prints:
        # A body its own weight strains past its bound is refused here, before any solve
        # (a SceneError; the strain rows would raise it mid-solve, 0.2-7 s in: an audit's
        # fuzz of the soft stances at 1e4-1.5e5 Pa found seven such). Computed once a body.
        scene.deformable(name).self_weight_field
    if deformable_prints:
        contacts = [
            c if isinstance(c, RigidContact) else
            LayerBalls(robot, c, deformable_prints[c.name], options)
            if layer_sites(robot, c, deformable_prints[c.name], options) is not None
            else DeformableContact(robot, c, deformable_prints[c.name], options)
            for c in contacts
        ]
    if any(c.kind == "deformable" for c in contacts):
        # Soft prints' rows (elastic placement, node forces) carry no second
        # derivatives in q: with only the collision rows' curvature the Coulomb
        # stage of foot-and-hand took 19 iterations instead of 11 (measured).
        # Their rigid warm start keeps it.
        options = replace(options, constraint_curvature=False)
    checker = stance_collision_checker(robot, scene, stance, options)
    return PostureProblem(robot, scene, stance, contacts, options, checker)


def touching_pairs(robot, scene, options: PostureOptions) -> frozenset:
    """``(robot geometry, object)`` pairs that ``options.touching`` lets touch: each
    named surface's contact geometry and the object of the scene surface named with it."""
    return frozenset(
        pair for surface, support in options.touching
        for pair in contact_exclusions(robot, robot.surface(surface).frame, scene.surface(support).object_name)
    )


def stance_collision_checker(robot, scene, stance, options: PostureOptions) -> CollisionChecker:
    """The collision checker of a stance's posture problem: every pair the options
    check, but each contact surface against the object it rests on.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance
        Its surfaces and prints must exist (as :func:`build_problem` checks).
    options : PostureOptions
        ``collision_activation`` (the checker's margin) and ``self_collision``.
    """
    excluded = []
    for contact in stance:
        frame = robot.surface(contact.robot_surface).frame
        excluded.extend(contact_exclusions(robot, frame, scene.surface(contact.contact_print.surface).object_name))
    return CollisionChecker(
        robot,
        scene.collision_objects(),
        margin=options.collision_activation,
        exclude=excluded,
        self_collision=options.self_collision,
    )
