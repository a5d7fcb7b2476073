"""Deformable contacts: robot links pressing prints into one linear-elastic body.

All prints on one body form ONE contact system: the body couples them, so the
force under one sole depends on where the other sole (or a palm) presses. At
the nominal placement each print node ``x_n`` (eq. 27) is matched with the
point ``a_n`` of the robot surface lying on it; those points move with their
link, and the node displacements are the motion they impose (eq. 29):

    U_n(q) = R_b^T (y_n(q) - x_n),     y_n(q) = T_link(q) a_n      (body frame)

The print's nodes (``reaction_model="consistent"``) are every surface node whose
shape function the robot's polygon covers, even in part (``fem.print_coverage``); a node
covered by a fraction ``w < 1`` is coupled to its link point through a series
compliance ``(1 - w) / w C_ii`` (``fem.ContactPatch``), so the link points move by
``(C + D) f`` and the print's force does not jump as node rows enter or leave it. Such a
node lies ``D f`` behind its link point, the deformed mesh reaching into the link at the
print's edge: rows keep that within ``max_mesh_overlap``.
A partly covered node's link point is its rest position, at most a cell's diagonal
outside the polygon (its shape function reaching in), where it carries a small share of
the load: the print's forces are then the consistent loads of a pressure inside it, and
rows keep its centre of pressure inside the outline. The ``traction`` model
keeps the nodes inside the polygon.

A point foot (a ball of radius r) may press the nodes under its print octagon,
which circumscribes the ball's circle: its link points are all the ball's
centre, ``x_n`` is replaced by the centre's rest position r above the print,
and ``U_n = R_b^T (c(q) - c_0)``: the print translates with the ball and does
not turn with the foot (the ball rolls freely, and every node's force acts at
its centre, as in the rigid point contact of :mod:`stances.contacts`). A node
at distance rho from the print's origin lies the ball's profile
``g_n = r - sqrt(r^2 - rho^2)`` below it (:func:`ball_gaps`): the contact solve
sees the motion ``U_n + g_n n``, so a node is pressed only once the ball has sunk
that far, and the contact spreads as the ball sinks (Hertz's contact, solved on
the mesh; until 2026-12-03 every node followed the ball from the start, a flat
punch of radius r: 42-154 N where Hertz and a fine mesh give 1-9 N at the same
depth). This needs the ``coulomb`` law (nodes lift off) and a mesh fine against
the contact radius ``sqrt(r d)`` at depth d.

The body pushes back with forces linear in ``U`` over the union of the
prints' nodes, ``f = R U`` (R: fem's reaction matrix over the union, ``-S_P``
for ``consistent``; eq. 44 for ``traction``).

Compliance form. Written as ``f = R U(q)`` the contact is hopelessly
ill-conditioned for stiff bodies (R grows like E: a nanometre of posture moves
the forces by newtons). Each link's print instead gets a 6-vector variable
``W_l``, its generalised force ``G_l^T R_c G_l xi_l`` (G: the nodes' rigid motion
basis about the print origin, body frame; ``R_c = -S_P`` the consistent
reaction), and with ``A = G^T R_c G`` (symmetric negative definite),
``D = R G A^-1``:

    placement (6 rows per link):   xi(q) - A^-1 W = 0
    node forces:                   f(W) = R (G A^-1 W + r(A^-1 W)) = D W + R r(A^-1 W)

``xi(q) = (t, theta)`` is the link's motion from its nominal placement (the
print origin's translation and the rotation vector of the turn, body frame), and
``r(theta)_n = (exp(theta) - I - [theta]x) x_n`` is what a finite turn moves the
points beyond the linear ``theta x x_n`` that G holds: the link points move
exactly by ``U(q) = G xi(q) + r(theta(q))``. Where the placement rows hold,
``f = R U(q)``, the bonded FEM answer, exactly. The forces are functions of W
alone: D does not depend on E and r is second order in the turn ``A^-1 W``,
which vanishes with the compliance, so every row stays well scaled for any
stiffness, and as ``E -> inf`` (``A^-1 -> 0``) the placement rows become the
rigid contact's. This is the compliance-based contact of Duriez, Dubois and
Kheddar, reduced to the six rigid modes of each link. (Until 2026-11-26 the
forces were ``D W + (R - D G^T R_c) U(q)``, equal where the rows hold; but at an
iterate that had not met them, the second term carried r of the link's actual
turn: tens of nanometres of bending for a palm still turned by 1e-3 rad, more
than a steel-stiff body gives, and Coulomb solves on stiff bodies failed or
depended on last bits.) The traction model (eq. 44, turned normals) keeps its
posture-dependent reaction: ``f = R(q) U(q) + D (W - A xi(q))``.

The stiff limit. A body that gives by micrometres under the stance's loads has W weighed
where its nodes, some lifted off, carry something else (not where all stick:
:meth:`DeformableContact.sticks`); there the stance is solved held
rigid and the links' motion whose Coulomb forces carry that answer is found by inverting
the contact law (:meth:`DeformableContact.held_prints`, :meth:`~DeformableContact.carrying_variables`,
``stances.stages._solve_stiff_limit``).

How nodes meet their link (``contact_law``), beyond the paper's bonded prints:

- ``"coulomb"`` (default): R is the mode-fixed Jacobian L of
  :func:`fem.solve_print_contact` (each node sticks, slips with its friction on the
  circular cone's bound exactly against its slip, or lifts off, solved on the
  condensed compliance; the forces are positively homogeneous in U, ``f = L U``,
  with L their exact Jacobian for fixed modes). It is evaluated at
  ``U~ = G A^-1 W + r(A^-1 W)``, the motion the link points have where the rows
  hold, so the forces stay continuous in W when nodes change mode. Each print must press (its
  mean height not above the rest surface), a sole or palm with its whole face (each corner
  sunk at least ``corner_sinking`` of the corners' mean sinking, less ``max_corner_lift``: a
  print pivoting toward its edge presses a strip narrower than the mesh resolves, and an
  independent audit found such palms 6.7-16.4 % below a converged mesh's force), and keep
  its resultant inside ``friction_margin`` of its pyramid. Each node's contact is solved in
  its print's frame turned with the link's face (``contact_frames="turned"``, as eq. 63
  turns the traction model's normals; ``docs/turned-face.md``): the gap along the face's
  normal, the slip and the cone in its plane, the turn the one W stands for. With
  ``contact_frames="rest"`` (the linear model's frames) a tilt allowance ``a``
  (``tilt_allowance``) narrows the cones to ``mu' = tan(atan(mu) - a)`` and rows keep the
  face's tilt within ``a``, so each node's force lies in its cone about both normals.
- ``"sticking"``: bonded nodes, each pushing and inside its own friction pyramid.
- ``"bonded"``: the paper's model; bonded nodes push, each print's resultant is in
  its pyramid.

Validity (the paper leaves it implicit): nodes are indented less than a bound
relative to the body's thickness, and the principal strains around the prints,
each the mean over a ball of the object's ``strain_radius`` (a tet's own strain at a
rigid print's edge grows as the mesh is refined), stay within the object's strain
bound (linear elasticity holds only there). The strain counted is the prints' plus
the one the body holds under its own weight: a scene's soft body is meshed as it
rests, so by superposition its weight moves no print force (eq. 31, exact for a
body at rest under gravity), but its strain is there before any robot comes.
:meth:`DeformableContact.verify` checks all of it on the full FEM model.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import pinocchio as pin
import scipy.linalg
import scipy.spatial

import fem
from fem.dense import block_diagonal_product, single_threaded_blas
from fem.layer_contact import side_contact_limit, widest_contact
from fem.prints import clip_polygon

from environments.geometry import polygon_area, signed_edge_distances

from .blocks import PLACEMENT_ACCURACY, ConstraintBlock, equality
from .contacts import PYRAMID_SIDES, convex_polygon, friction_cone_generators, pyramid_faces
from .errors import StanceError
from .layer_ball import layer_under
from .qp_backend import proxsuite
from .results import NodeSlips
from .statics import PointLoads, point_jacobians, points_in_world

__all__ = ["DeformableContact", "HeldPrint", "PrintSpec", "MINIMUM_PRINT_NODES", "PIVOTING_ROW", "PIVOTING_REFUSAL"]

MINIMUM_PRINT_NODES = 3

# A ball foot that presses fewer mesh nodes than this has a contact smaller than the
# cells: its force depends on where it stands against the nodes (quadruped-foam's 10 mm
# foam at 1-2.5 mm deep, 1-5 nodes: -46 % to +31 % of a converged mesh's force;
# bench/results/ball_foot.md). Verify counts them and reports a coarse contact. More nodes
# do not make a node contact's force converged (bench/results/ball_node_contact.md: 9-74
# pressed nodes +0.2 to +10 % off the continuum, 2.5 mm bands +4.9 to +8.6 %): a ball is
# judged against a continuum estimate, and refused where there is none.
RESOLVED_BALL_NODES = 9
# Newton metres a print's centre-of-pressure moment may fall below zero in verify: ten times
# the solver's tolerance on those rows (its feasibility tolerance 1e-7, the rows' scale 1 N m).
_MOMENT_TOLERANCE = 1e-6
# Newtons a print must press with for its node forces to be fitted by a pressure under it
# (DeformableContact.pressure_fits): the fit is relative, and forces at the solver's rounding
# (1e-12 N of mixed signs) read 0.78 (a review, 2026-12-06); the centre of pressure's check
# leaves a tenth of a newton alone likewise.
_FIT_LEAST_LOAD = 0.1
# The whisker of |c|^2 in spread_forces' least-energy QP (its energy scaled to a unit diagonal),
# and the QP's iteration limit.
_SPREAD_REGULARISATION = 1e-9
_SPREAD_QP_ITERATIONS = 10_000
# Newtons a node presses with for spread_motions to fit its link's motion to it.
_PRESSED_LOAD = 1e-4
# Shape-function shares under this are rounding (a corner on a mesh edge): _pressure_corners
# drops them, so that such a corner is not left out for a node of no print.
_SHARE_ROUNDING = 1e-12
# A ball whose sinking a lower bound puts past this many times verify's placement tolerance
# is refused before the solve (DeformableContact.balls_refused_anyway): the margin covers
# what the bound leaves out (friction, other prints lifting the surface under it).
_REFUSED_SINKING = 10.0
# What a whole-print row's label and verify's refusal of a pivoting print say: the planner
# counts rejected stances by them (cbm.rejections.pivoting_print_hint).
PIVOTING_ROW = "lifted: pivoting on an edge"
PIVOTING_REFUSAL = "the print pivots toward its edge"
# What to do about a ball verification refuses (or would refuse whatever the posture).
_BALL_ADVICE = ("keep the balls where the layer's law holds (a layer held on its base, pressed by balls only, far "
                "enough inside its edges), or accept it with the solver option ball_force_error=inf")

logger = logging.getLogger(__name__)

# Soft bodies (their fem bodies' ids) whose coarse ball contact this process has logged (once each).
_COARSE_BALLS_LOGGED: set = set()

# Tets whose largest principal strain is above this fraction of the bound enter the QP.
_STRAIN_ACTIVATION = 0.5
# Nodes indented beyond this fraction of the bound enter the QP (one row each): the
# others are far from it (a sole pair on a mat: 123 rows, none near, were 46 % of the
# QP's rows). stances.verify checks every node.
_INDENTATION_ACTIVATION = 0.5
# Nodes whose mesh overlap (see _overlap_block) is beyond this fraction of its bound enter the QP.
_OVERLAP_ACTIVATION = 0.5
# Tets the body's own weight alone strains to this fraction of the bound are strain-row
# centres wherever they lie, not only near the prints.
_REST_STRAIN = 0.25
_SLIP_ROWS = 6  # largest node slips bounded in each QP (one row each)
_HELD_WRENCH_STEPS = 3  # fixed-point steps of the W that carries given forces from held slips
# How many times max_slip a held slip may start at. The stance before kept its own bound, which
# is the spacing under all the body's prints (a sole joining a palm on the foam took its bound
# from 5.556 to 5.500 mm); a print held past this one's slides back within it, or is refused
# by its slip rows. Twice the bound is no slip an answer of the same print left.
_HELD_SLIP_SHARE = 2.0
# The small-slip bound (options.max_slip None), a share of the mesh's spacing under the prints:
# contact is solved on the nodes under the declared print, and a link sliding a whole spacing
# over them presses others. At 0.02 m (the bound before, 0.9 of the default mesh's spacing) an
# audit's fuzz of 71 plans found soft palms slid 5-18 mm and turned up to 14 degrees, loaded
# nodes 25 mm outside the palm (bench/results/audit-fuzz-plans-2026-12-06.md). At a quarter the
# 15 built-in soft stances all solve, hand-on-soft-cube's palm sliding 5.4 mm (at its bound)
# instead of 8.6 (objective +0.5 %).
SLIP_SHARE = 0.25
# ... and at most this, metres (the bound before): the paper's coarse cube, a palm on 4 nodes of
# 100 mm cells, would otherwise let it slide 25 mm, a third of its width.
SLIP_CAP = 0.02
# A ball's start depth (DeformableContact.variables_from_forces): up to 2^12 times the flat
# print's, then the scale's bracket halved (in log) to 2^(1/2^5) = 1.022.
_BALL_DOUBLINGS, _BALL_HALVINGS = 12, 5
#: A soft body that gives less than this under a stance's loads, metres, is solved in its
#: stiff limit (``stances.stages``): held rigid, then at most a few restoration steps onto
#: every row (hand-on-cube's palm at 1e10 Pa: 1 on meshes of 22.5, 15 and 10 mm). At
#: verify's placement tolerance, 1 um, the palm on the 10 mm mesh at 1e10 Pa was refused: on
#: its edge it gives 6 um. The posture moves by the give, which no other row resolves.
STIFF_GIVE = 1e-5
# A print's nodes covered less than fem.MINIMUM_COVERAGE carry under a hundredth of a node's
# share and are left out; on a body so stiff under it that the robot's weight would sink it
# less than STIFF_GIVE (stiff_under), nodes down to this coverage stay: there the partly
# covered row past a print's edge carries a centre of pressure near that edge as the print
# pivots by micrometres, and without it a print held in its stiff limit stops where the
# rows covered a hundredth end. A palm on a 1e10 Pa cube beside a 1e6 Pa mat, which the
# rigid support tips onto its edge (35 mm out): 31.3 mm and 2.8 % from the rigid support's
# force with those rows, 34.8 mm and 0.19 % with these (2026-12-06). On soft bodies they
# would move a print's force by 0.2 % at most (the twelve references of
# bench/bench_print_coupling.py), add a fifth more nodes to a palm and a tenth to a sole,
# and moved hand-on-cube's answer to another optimum, 3 % above.
_STIFF_COVERAGE = 1e-3
# A print held rigid in its stiff limit (DeformableContact.held_prints) has its forces this
# fraction of its nodes' spacing inside their hull: on the hull's edge one line of nodes
# carries the load and the link's turn about that line is not fixed by it.
_REACH_MARGIN = 0.05
# ... and this fraction inside the print's own outline: only off the edge itself (the
# tipping limit, which no body of finite stiffness holds), since partly covered nodes past
# the edge carry a centre of pressure near it over several rows. Romeo's palm on its cube
# at 1e10 Pa, which the rigid support tips onto its edge: 2.86 % from the rigid support's
# force with the hull's 0.05 (1.1 mm), 0.69 % with 0.01 (0.2 mm) (session s, median-dual
# cells; 0.69 % again with shape functions, session u).
_OUTLINE_MARGIN = 0.01
LAWS = ("coulomb", "sticking", "bonded")


@dataclass(frozen=True)
class PrintSpec:
    """One robot surface pressing one print on a deformable object.

    Parameters
    ----------
    robot_surface : str
        Robot contact surface name.
    surface : environments.ContactSurface
        The deformable object's surface carrying the print.
    transform_print_to_world : (4, 4) float
        Nominal print frame (z: outward normal of the surface).
    label : str
        Readable name, e.g. ``"right_sole on foam_top"``.
    held_slips : stances.NodeSlips, optional
        Where the print's link points lie over its nodes at the start (the stance
        before, keeping this print, left them there): under the ``coulomb`` law a node
        that sticks keeps this slip. None: at rest.
    """

    robot_surface: str
    surface: Any
    transform_print_to_world: np.ndarray
    label: str
    held_slips: Any = None

    def __post_init__(self) -> None:
        transform = np.array(self.transform_print_to_world, dtype=float)
        transform.setflags(write=False)
        object.__setattr__(self, "transform_print_to_world", transform)


# Weight of a point foot's moment in W, relative to the force term: the rigid point
# contact has no moment variable; this keeps the QP strictly convex in W (proxsuite
# stalls at its iteration cap without it).
_POINT_MOMENT_WEIGHT = 0.1


def rigid_force_metric(surface, friction: float) -> np.ndarray:
    """The rigid contact's force term as a quadratic form in its wrench.

    A rigid contact's force variables are the cone coefficients ``c >= 0`` of
    :func:`~stances.contacts.friction_cone_generators` at its polygon's vertices,
    weighed by ``|c|^2``; the least ``|c|^2`` that gives the wrench ``W`` about the
    print origin is ``W^T (B B^T)^-1 W`` (B: the wrench of each coefficient, 6 x 4k),
    the metric a soft print's ``W`` is weighed with.

    Parameters
    ----------
    surface : stances.robot.ContactSurface
        The robot surface; a point foot's moment, which its rigid contact has not,
        is weighed by ``_POINT_MOMENT_WEIGHT``.
    friction : float
        Friction coefficient of the print.

    Returns
    -------
    (6, 6) float
        Per N^2 (force rows) and (N m)^2 (moment rows), print frame.
    """
    edges = friction_cone_generators(friction)  # (4, 3), print frame
    if surface.is_point:
        metric = np.zeros((6, 6))
        metric[:3, :3] = np.linalg.inv(edges.T @ edges)
        metric[3:, 3:] = _POINT_MOMENT_WEIGHT * np.eye(3)
        return metric
    wrenches = _edge_wrenches(surface.vertices_in_frame, edges)  # (4k, 6)
    return np.linalg.inv(wrenches.T @ wrenches)


def _edge_wrenches(points, edges) -> np.ndarray:
    """The wrench of a unit force along each friction-cone edge at each point: ``(k e, 6)``,
    force then moment about the frame's origin, the points' and edges' frame.

    Parameters
    ----------
    points : (k, 3) float
        Metres.
    edges : (e, 3) float
        Unit edge directions (:func:`~stances.contacts.friction_cone_generators`).
    """
    return np.vstack([np.hstack([edges, np.cross(point, edges)]) for point in points])


def stiff_under(weight, polygon, material) -> bool:
    """Whether a body is so stiff under a print that the robot's whole weight would sink
    it less than ``STIFF_GIVE``: a rigid flat circular punch of the print's area on an
    elastic half-space sinks ``W (1 - nu^2) / (2 a E)`` (Boussinesq; ``a`` its radius).

    Parameters
    ----------
    weight : float
        Newtons.
    polygon : (k, 2) float
        The print's outline, metres, any frame in its plane; a point foot's is no polygon:
        False.
    material : fem.LinearElasticMaterial

    Examples
    --------
    >>> from fem import LinearElasticMaterial
    >>> palm = [[-0.05, -0.035], [0.05, -0.035], [0.05, 0.035], [-0.05, 0.035]]
    >>> steel, foam = LinearElasticMaterial(1e10, 0.4, 0.0), LinearElasticMaterial(1e8, 0.4, 0.0)
    >>> stiff_under(930.0, palm, steel), stiff_under(930.0, palm, foam)   # a 95 kg robot
    (True, False)
    """
    polygon = np.asarray(polygon, dtype=float)
    if len(polygon) < 3:
        return False
    radius = np.sqrt(abs(polygon_area(polygon)) / np.pi)
    sinking = weight * (1.0 - material.poisson_ratio**2) / (2.0 * radius * material.young_modulus)
    return bool(sinking < STIFF_GIVE)


@dataclass(frozen=True)
class HeldPrint:
    """A soft print held rigid in its body's stiff limit (:meth:`DeformableContact.held_prints`).

    Parameters
    ----------
    reach : (m, 2) float
        Counter-clockwise convex polygon, print frame, metres, that its forces' centre of
        pressure must lie in: where its nodes can carry them.
    resultant_friction : float
        Its resultant's friction coefficient (``friction_margin`` included).
    motion : (6,) float, optional
        Where the link's face is held: the print moved by this rigid motion, translation
        (metres) then rotation vector (radians), print frame (the body's give under the
        held loads, :meth:`DeformableContact.spread_motions`); at rest by default.
    """

    reach: np.ndarray
    resultant_friction: float
    motion: np.ndarray = field(default_factory=lambda: np.zeros(6))

    def __post_init__(self) -> None:
        if not self.resultant_friction >= 0.0:
            raise StanceError(f"a held print's resultant friction must be >= 0, got {self.resultant_friction}")
        object.__setattr__(self, "reach", convex_polygon(self.reach, "a held print's reach"))
        motion = np.array(self.motion, dtype=float)
        if motion.shape != (6,) or not np.isfinite(motion).all():
            raise StanceError(f"a held print's motion must be 6 finite numbers, got {self.motion!r}")
        motion.setflags(write=False)
        object.__setattr__(self, "motion", motion)


@dataclass(frozen=True)
class _PrintValues:
    """A deformable contact's state at one iterate, without derivatives.

    Attributes
    ----------
    displacements : (p, 3) float
        U imposed by the link points, metres, body frame (eq. 29).
    forces : (p, 3) float
        Node forces on the robot, newtons, world frame.
    forces_body : (3p,) float
        The same, stacked, body frame.
    nodes : (3p,) float
        The body's own print-node displacements, metres, body frame.
    solved : object
        What the derivatives reuse: the Coulomb contact solve (fem.PrintContact),
        the traction model's (reaction matrix, turned normals), or None.
    """

    displacements: np.ndarray
    forces: np.ndarray
    forces_body: np.ndarray
    nodes: np.ndarray
    solved: Any


def _cone_margins(forces, normals, mu):
    """Each force's normal part, tangential size and Coulomb margin ``mu f_n - |f_t|`` about its
    normal: forces (k, 3), normals (k, 3) or (3,) (unit), mu (k,) or scalar; newtons."""
    normal = np.einsum("...j,...j->...", forces, normals)
    tangential = np.linalg.norm(forces - normal[:, None] * normals, axis=1)
    return normal, tangential, mu * normal - tangential


def ball_gaps(nodes_in_print: np.ndarray, radius: float) -> np.ndarray:
    """How far a ball resting on a print is above each node: its profile's height there.

    The ball of radius ``R`` touches the print plane at the print's origin; over a
    point at distance ``rho`` from it, its lowest point is ``R - sqrt(R^2 - rho^2)``
    above the plane (``~ rho^2 / 2R``, the paraboloid of Hertz's contact near the
    centre); beyond ``rho = R`` the gap is ``R``, its equator's height (a node there is
    never touched from above).

    Parameters
    ----------
    nodes_in_print : (p, 3) float
        Node rest positions, metres, print frame (z along the outward normal).
    radius : float
        Ball radius, metres.

    Returns
    -------
    (p,) float
        Gap from each node up to the ball, metres, >= 0 (a node above the print plane
        by more than its profile height is touching: 0).
    """
    rho_squared = np.minimum(np.einsum("pi,pi->p", nodes_in_print[:, :2], nodes_in_print[:, :2]), radius * radius)
    profile = radius - np.sqrt(radius * radius - rho_squared)
    return np.maximum(profile - nodes_in_print[:, 2], 0.0)


def _tangential(vectors: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(p, 3) ``vectors`` less their parts along the unit ``normals`` (p, 3)."""
    return vectors - np.einsum("pj,pj->p", vectors, normals)[:, None] * normals


def _skew_rows(points: np.ndarray) -> np.ndarray:
    """(p, 3) -> (p, 3, 3) cross-product matrices: ``out[i] @ v == np.cross(points[i], v)``."""
    x, y, z = np.asarray(points, dtype=float).reshape(-1, 3).T
    out = np.zeros((len(x), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -z, y, -x
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = z, -y, x
    return out


def inset_hull(points, margin: float) -> np.ndarray:
    """The convex hull of 2-D points with its edges moved in by ``margin``.

    Parameters
    ----------
    points : (k, 2) float
        At least three, not on one line; metres.
    margin : float
        Metres, >= 0, less than the hull's inradius.

    Returns
    -------
    (m, 2) float
        Counter-clockwise corners: where consecutive moved edges meet.

    Raises
    ------
    StanceError
        If the margin leaves no polygon (the moved edges cross).
    """
    corners = np.asarray(points, dtype=float)[scipy.spatial.ConvexHull(points).vertices]  # counter-clockwise
    edges = np.roll(corners, -1, axis=0) - corners  # edge i from corner i to i + 1
    normals = np.column_stack([edges[:, 1], -edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]  # outward
    offsets = np.einsum("ij,ij->i", normals, corners) - margin  # each edge's line n . x = offset, moved in
    previous = np.roll(np.arange(len(corners)), 1)
    moved = np.array([np.linalg.solve(np.array([normals[j], normals[i]]), [offsets[j], offsets[i]])
                      for i, j in enumerate(previous)])
    what = f"the nodes' hull moved in by {margin:g} m"
    moved = convex_polygon(moved, what)
    # An edge turned over (the margin past the inradius) can leave a convex polygon, turned.
    if np.any(np.einsum("ij,ij->i", np.roll(moved, -1, axis=0) - moved, edges) <= 0.0):
        raise StanceError(f"{what} leaves no polygon: its edges cross")
    return moved


class DeformableContact:
    """Every print on one deformable object, as one coupled contact system.

    Parameters
    ----------
    robot : stances.Robot
    deformable_object : environments.DeformableObject
        Holds the fem body, its placement and its strain bound.
    prints : sequence of PrintSpec
        The robot surfaces pressing this object, in stance order.
    options : stances.PostureOptions
        ``reaction_model``, ``indentation_limit`` / ``max_indentation``,
        ``max_mesh_overlap``, ``deformation_weight``, ``max_strain_rows``.

    Raises
    ------
    StanceError
        A point foot presses the body with the traction model or a law other than
        ``coulomb``, a print holds fewer than three mesh nodes, two prints share nodes,
        or a print's nodes cannot hold a rigid link (collinear).
    """

    kind = "deformable"

    def __init__(self, robot, deformable_object, prints, options):
        self.deformable_object = deformable_object
        self.method = options.reaction_model
        self.max_strain_rows = int(options.max_strain_rows)
        self.law = options.contact_law
        self.friction_margin = float(options.friction_margin)
        self.strain_limit = float(deformable_object.strain_limit)
        self.strain_radius = float(deformable_object.strain_radius)
        self.max_slip = None if options.max_slip is None else float(options.max_slip)  # per the mesh: below
        self.max_mesh_overlap = float(options.max_mesh_overlap)
        self.ball_force_error = float(options.ball_force_error)
        self.turned_frames = options.contact_frames == "turned" and self.law == "coulomb"
        self.corner_sinking = float(options.corner_sinking)
        self.max_corner_lift = float(options.max_corner_lift)
        body = deformable_object.body
        body_placement = pin.SE3(np.asarray(deformable_object.transform_body_to_world, dtype=float))
        self.rotation_body = body_placement.rotation
        self.prints = list(prints)
        self.label = " and ".join(p.label for p in self.prints)

        if options.max_indentation is not None:
            self.max_indentation = float(options.max_indentation)
        else:
            # Thickness of the body along each print's normal, from its mesh.
            heights = [np.ptp(body.mesh.nodes @ (self.rotation_body.T @ spec.transform_print_to_world[:3, 2]))
                       for spec in self.prints]
            self.max_indentation = float(options.indentation_limit * min(heights))
        node_sets, coverages, insides, joints, points_in_joint, frames = [], [], [], [], [], []
        point_rests = []  # (print index, rest position of its ball's centre, world) for point feet
        self.ball_radii = {}  # print index -> its ball's radius, metres, for point feet
        self._layers = {}  # print index -> (thickness, side distances) of the layer under it, or None (_layer_under)
        gaps = []  # per print, (nodes,) distance from each node up to its link's surface at rest
        corners = []  # per print, (k, 2) its polygon's corners in its frame, or None for a point foot
        self.frame_ids, self.print_placements, self.friction = [], [], []
        self._polygons_in_body = []  # per print, its polygon (k, 3) on the body, body frame (None: a ball)
        self._stiff_prints = []  # per print, whether its body is too stiff to give under it (stiff_under)
        for spec in self.prints:
            surface_model = robot.surface(spec.robot_surface)
            if surface_model.is_point and self.method == "traction":
                raise StanceError(
                    f"{spec.label}: a point foot's print needs the consistent reaction model "
                    "(its nodes follow the ball's centre, not the foot's turn)"
                )
            if surface_model.is_point and self.law != "coulomb":
                raise StanceError(
                    f"{spec.label}: a point foot on a soft body needs contact_law 'coulomb': a ball touches the "
                    f"nodes its profile reaches as it sinks, which the {self.law!r} law (every print node held "
                    "to the link) cannot say"
                )
            frame_id = robot.frame_id(surface_model.frame)
            frame = robot.model.frames[frame_id]
            placement = pin.SE3(spec.transform_print_to_world)
            polygon_in_world = surface_model.vertices_in_frame @ placement.rotation.T + placement.translation
            polygon_in_body = (polygon_in_world - body_placement.translation) @ body_placement.rotation
            stiff = (not surface_model.is_point) and stiff_under(robot.weight, surface_model.vertices_in_frame[:, :2],
                                                                 body.material)
            self._polygons_in_body.append(None if surface_model.is_point else polygon_in_body)
            self._stiff_prints.append(stiff)
            inside = np.asarray(fem.nodes_in_polygon(body.mesh, polygon_in_body, tolerance=1e-6), dtype=np.int64)
            if self.method == "consistent":
                # Every node whose shape function the polygon covers, coupled by the
                # covered share (fem.ContactPatch): the print's force then does not
                # jump as node rows enter or leave it.
                ids, covered = fem.print_coverage(body.mesh, polygon_in_body, tolerance=1e-6,
                                                  minimum=_STIFF_COVERAGE if stiff else fem.MINIMUM_COVERAGE)
                ids = np.asarray(ids, dtype=np.int64)
            else:
                ids, covered = inside, np.ones(len(inside))
            if surface_model.is_point:
                # A ball touches a node once it has sunk the node's gap, and it sinks no
                # further than the nearest node's gap plus the indentation bound: the
                # nodes beyond that never touch (20 of the octagon's 58 on ANYmal's feet
                # on foam, every contact solve and compliance the smaller for it).
                gap = ball_gaps(self._in_print(body.mesh.nodes[ids], body_placement, placement), surface_model.radius)
                kept = gap <= self.max_indentation + gap.min()
                ids, covered = ids[kept], covered[kept]
            if len(ids) < MINIMUM_PRINT_NODES:
                raise StanceError(
                    f"the print of {spec.label} holds {len(ids)} mesh node(s); at least "
                    f"{MINIMUM_PRINT_NODES} are needed: refine the mesh of {deformable_object.name!r} "
                    "where prints land (a scenario's soft_box takes resolution and refine)"
                )
            cells = float(covered.sum())
            if self.method == "consistent" and not surface_model.is_point and cells < deformable_object.minimum_print_cells:
                # environments.DEFAULT_MINIMUM_PRINT_CELLS says what fewer cells cost.
                raise StanceError(
                    f"the print of {spec.label} covers {cells:.1f} cells of the mesh under it; at least "
                    f"{deformable_object.minimum_print_cells:g} are needed for its force (a palm on 1-3.5 cells lay 3-33 % "
                    f"below its force on the default resolution's): refine the mesh of {deformable_object.name!r} where "
                    "prints land (a scenario's soft_box takes resolution and refine), or lower its minimum_print_cells"
                )
            for index, (other, other_ids) in enumerate(zip(self.prints, node_sets)):
                shared = np.intersect1d(inside, insides[index])
                if shared.size:
                    raise StanceError(
                        f"the prints of {other.label} and {spec.label} overlap ({shared.size} shared mesh "
                        f"node(s) of {deformable_object.name!r}): two links cannot press the same spot; "
                        "move one print"
                    )
                # Prints closer than a cell share the nodes whose shape functions both cover.
                keep_here, keep_there = fem.split_shared_nodes(ids, covered, other_ids, coverages[index])
                if not keep_there.all():
                    node_sets[index], coverages[index] = other_ids[keep_there], coverages[index][keep_there]
                    joints[index], points_in_joint[index] = joints[index][keep_there], points_in_joint[index][keep_there]
                    gaps[index] = gaps[index][keep_there]
                ids, covered = ids[keep_here], covered[keep_here]
            nodes_in_print = self._in_print(body.mesh.nodes[ids], body_placement, placement)
            node_sets.append(ids)
            coverages.append(covered)
            insides.append(inside)
            joints.append(np.full(len(ids), frame.parentJoint))
            if surface_model.is_point:
                # Every node of a ball's print follows the ball's centre, where its force acts.
                points_in_joint.append(np.tile(frame.placement.translation, (len(ids), 1)))
                point_rests.append((len(node_sets) - 1, placement.translation + surface_model.radius * placement.rotation[:, 2]))
                self.ball_radii[len(node_sets) - 1] = float(surface_model.radius)
                gaps.append(ball_gaps(nodes_in_print, surface_model.radius))
                corners.append(None)
            else:
                points_in_joint.append(nodes_in_print @ frame.placement.rotation.T + frame.placement.translation)
                gaps.append(np.zeros(len(ids)))
                corners.append(surface_model.vertices_in_frame[:, :2])
            frames.append(surface_model.frame)
            self.frame_ids.append(frame_id)
            self.print_placements.append(placement)
            self.friction.append(float(spec.surface.friction))

        for spec, ids in zip(self.prints, node_sets):
            if len(ids) < MINIMUM_PRINT_NODES:
                raise StanceError(
                    f"the print of {spec.label} holds {len(ids)} mesh node(s) once the nodes it shares with "
                    f"a neighbouring print go to that print; at least {MINIMUM_PRINT_NODES} are needed: move "
                    f"the prints apart or refine the mesh of {deformable_object.name!r}"
                )
        # Each print's nodes at rest in its frame, (n, 2): what a polygon print's corner rows
        # and centre-of-pressure rows are made from.
        rests = [self._in_print(body.mesh.nodes[ids], body_placement, placement)[:, :2]
                 for ids, placement in zip(node_sets, self.print_placements)]
        self._corners, self._corner_print = self._corner_weights(corners, rests)
        self._outlines = corners  # per print, its polygon in its frame (k, 2), None for a point foot
        # (k, p): each corner's row gives its print's corners' mean height; the whole-print
        # rows are the corners' heights less corner_sinking times that.
        self._corner_means = np.zeros_like(self._corners)
        for i in np.unique(self._corner_print):
            self._corner_means[self._corner_print == i] = self._corners[self._corner_print == i].mean(axis=0)
        self._corner_rows = self._corners - self.corner_sinking * self._corner_means
        self._pressure_rows, self._pressure_print = self._centre_of_pressure_rows(corners, rests)
        self.node_ids = np.concatenate(node_sets)
        self.coverage = np.concatenate(coverages)
        self.print_of_node = np.concatenate([np.full(len(s), i) for i, s in enumerate(node_sets)])
        self.loads = PointLoads(np.concatenate(joints), np.concatenate(points_in_joint))
        self.print_labels = tuple(spec.label for spec in self.prints)
        self.print_surfaces = tuple(spec.robot_surface for spec in self.prints)
        self.load_prints = self.print_of_node
        self.load_frames = tuple(frames[i] for i in self.print_of_node)
        self._print_frames = tuple(frames)
        self._body_placement = body_placement
        self._corners_memo = {}  # print index -> _pressure_corners' answer
        self.patch = body.contact_patch(self.node_ids, self.coverage if self.method == "consistent" else None)
        if self.max_slip is None:
            self.max_slip = min(SLIP_SHARE * self.patch.spacing, SLIP_CAP)
        # Partly covered nodes' series compliance D (fem.ContactPatch), its (p, 3, 3)
        # diagonal blocks: a link point moves by its node's motion plus D times the
        # force; None when every node is covered.
        self._coupling = None if np.all(self.coverage == 1.0) else self.patch.coupling_blocks
        self.nodes_in_world = body.mesh.nodes[self.node_ids] @ self.rotation_body.T + body_placement.translation
        # Where each node's link point is when the body is at rest: the node itself
        # for a polygon; the ball's centre, a radius above the print, for a point foot.
        self.link_points_at_rest = self.nodes_in_world.copy()
        for index, centre in point_rests:
            self.link_points_at_rest[self.print_of_node == index] = centre
        n_prints, p = len(self.prints), len(self.node_ids)
        self.n_variables = 6 * n_prints
        self.variable_lower = np.full(self.n_variables, -np.inf)

        # Rigid-motion basis G (3p, 6L), body frame, about each print's origin: each
        # node's lever x from its print's origin turns with theta as theta x x = -[x]x theta.
        origins = np.array([(pl.translation - body_placement.translation) @ body_placement.rotation
                            for pl in self.print_placements]).reshape(-1, 3)
        self.levers = body.mesh.nodes[self.node_ids] - origins[self.print_of_node]
        self._lever_skews = _skew_rows(self.levers)
        basis = np.zeros((p, 3, 6 * n_prints))
        print_rotations_in_body = []
        for i, placement in enumerate(self.print_placements):
            rows = self.print_of_node == i
            basis[rows, :, 6 * i : 6 * i + 3] = np.eye(3)
            basis[rows, :, 6 * i + 3 : 6 * i + 6] = -self._lever_skews[rows]
            print_rotations_in_body.append(self.rotation_body.T @ placement.rotation)
        self.basis = basis.reshape(3 * p, -1)
        self.point_prints = np.array([i for i, _ in point_rests], dtype=np.int64)
        # The rigid modes are split off with the consistent stiffness (always
        # symmetric positive definite; G^T R G with R = -(C + D)^-1, through a Cholesky
        # solve on G's columns, not the whole inverse: 8 -> 2 ms on two soles); the
        # traction model reuses that split.
        a = -(self.basis.T @ self.patch.link_solve(self.basis))
        a = 0.5 * (a + a.T)  # symmetric to the last bit
        if np.linalg.cond(a) > 1e12:
            raise StanceError(
                f"the print nodes of {self.label} cannot hold a rigid link (nearly collinear): "
                f"refine the mesh of {deformable_object.name!r} under the prints"
            )
        a_inverse = np.linalg.inv(a)
        self.a = a
        self.a_inverse = a_inverse
        self.rigid_motion = self.basis @ a_inverse  # (3p, 6L): W -> rigid motion of the nodes
        # (L, 3, 6L): W -> each print's turn A^-1 W (none for a point foot, whose print does not turn).
        self._turn_of_w = a_inverse.reshape(n_prints, 6, -1)[:, 3:, :].copy()
        self._turn_of_w[self.point_prints] = 0.0
        # Rows of the placement residual in each print's own axes (x, y, normal).
        to_print = np.zeros((6 * n_prints, 6 * n_prints))
        for i, rotation in enumerate(print_rotations_in_body):
            to_print[6 * i : 6 * i + 3, 6 * i : 6 * i + 3] = rotation.T
            to_print[6 * i + 3 : 6 * i + 6, 6 * i + 3 : 6 * i + 6] = rotation.T
        self.to_print = to_print
        self.compliance_rows = -to_print @ a_inverse  # d residual / d W
        # The force term weighs W as the rigid contact's weighs the least cone
        # coefficients that give it, so that as E -> inf the objective, and with it the
        # posture, tends to the rigid support's.
        self.force_metric = to_print.T @ scipy.linalg.block_diag(*
            [rigid_force_metric(robot.surface(spec.robot_surface), friction)
             for spec, friction in zip(self.prints, self.friction)]
        ) @ to_print
        self._print_rotations_in_body = print_rotations_in_body
        if self.method == "traction":
            # Made now, not at the first soft evaluation: a print the traction model cannot
            # integrate (no whole surface triangle) is refused while the problem is built.
            _ = self.reaction

        # Per-node frames: normal and tangents of each node's print, world.
        self.normals = np.array([self.print_placements[i].rotation[:, 2] for i in self.print_of_node])
        self.tangents = np.array([self.print_placements[i].rotation[:, :2].T for i in self.print_of_node])
        # Each flat print's tilt allowance (radians): its nodes' cones are narrowed by it
        # and rows keep its face's tilt within it, so that a node's force lies in its cone
        # about the turned face too (tilt_allowance; none on a ball, which does not turn,
        # nor at mu 0 or inf, whose cones no narrowing serves).
        # No more than twice what a print could turn on a stiff body: its bonded turn under
        # the robot's whole weight plus max_corner_lift over its least width (the corner
        # rows' give), twice as lifted and slipping nodes turn it further than the bonded
        # estimate (a review: 1.22 times it on a 1e10 Pa cube, the palm's centre of pressure
        # in a corner of its reach). On a stiff body that is a fraction of a milliradian: as
        # E grows the narrowing fades (under 1e-3 of mu at 1e10 Pa, what max_corner_lift
        # leaves) and the rows do not bind where the whole-print rows hold.
        under_weight = self._tilts_under(robot.weight)
        self.tilt_allowances = np.array([
            0.0 if i in self.point_prints or not 0.0 < mu < np.inf
            else min(float(options.tilt_allowance), 0.5 * float(np.arctan(mu)),
                     2.0 * (under_weight[i] + self.max_corner_lift / float(np.ptp(corners[i], axis=0).min())))
            for i, mu in enumerate(self.friction)
        ]) if self.law != "bonded" else np.zeros(n_prints)
        # Each print's friction in its nodes' law, its resultant's rows and its held (stiff)
        # form: narrowed by the allowance in the rest frames, whose cones are about the rest
        # normal; the turned frames' cones are the face's already (the allowance then bounds
        # the tilt only).
        self.print_mu = [float(np.tan(np.arctan(mu) - a)) if a > 0.0 and not self.turned_frames else mu
                         for mu, a in zip(self.friction, self.tilt_allowances)]
        self.node_mu = np.array([self.print_mu[i] for i in self.print_of_node])
        self._tilted_prints = np.flatnonzero(self.tilt_allowances > 0.0)
        self.load_normals = self.normals
        normals_in_body = self.normals @ self.rotation_body
        self.normals_in_body = normals_in_body
        # (p, 3) body frame: from each node at rest up to its link's surface along the
        # print normal, nonzero under a ball (its profile, ball_gaps); the link points
        # then press a node once they have moved that far: U + gap is the node's motion.
        self.gaps = np.concatenate(gaps)[:, None] * normals_in_body
        # (p, 3) body frame: each node's held slip (PrintSpec.held_slips), in its print's
        # frame at rest: fixed in the link, it turns with the print (exp(theta) held). A node
        # that sticks meets the link's face there: its coupling end at U + gap - exp(theta) held
        # (:meth:`_held_motion`); zero from rest and off the coulomb law.
        self.held_slips = {}  # robot surface -> NodeSlips of the prints that start from them (_held_slips)
        self.held = self._held_slips(normals_in_body)
        self._holding = bool(np.any(self.held))
        # Rows t1, t2, n of each node's print frame, body frame (for the contact solve).
        self.node_frames = np.array([print_rotations_in_body[i].T for i in self.print_of_node])
        self._modes = None  # (modes, slip directions) of the last contact solve: its warm start
        self._contact_system = None  # fem.PrintContactSystem, built on the first Coulomb solve
        self._frozen = None  # (modes, slip directions) held fixed by freeze_modes
        # Strain-row centres verify found over the bound outside the rows (take_strain_outlier).
        self._found_centres = None
        self._strain_outlier = None  # the tet of the last verify's strain failure outside the rows
        # The iterate's values (_PrintValues) and derivatives, memoised by _values.
        self._load_joints = [int(joint) for joint in np.unique(self.loads.joints)]
        self._cache_key = None
        self._cache = None
        self._derivatives = None

    def _held_slips(self, normals_in_body) -> np.ndarray:
        """(p, 3) body frame: the held slips of the prints' nodes (``PrintSpec.held_slips``),
        their part along each node's rest normal taken out; zero for nodes without one. Those
        read are kept in :attr:`held_slips` (none off the coulomb law)."""
        held = np.zeros((len(self.node_ids), 3))
        if self.law != "coulomb":
            return held
        # A held node the print no longer has (a neighbouring print now shares it) is
        # dropped, a node it gains starts from rest: node sets change only by such shares.
        for index, spec in enumerate(self.prints):
            given = spec.held_slips
            if given is None:
                continue
            if index in self.ball_radii:
                raise StanceError(f"held_slips given for {spec.label}, a ball's print: its slips are not kept")
            if given.body != self.deformable_object.name:
                raise StanceError(f"held_slips of {spec.label} are on {given.body!r}, its print on "
                                  f"{self.deformable_object.name!r}: give the slips of the same print")
            self.held_slips[spec.robot_surface] = given
            rows = np.flatnonzero(self.print_of_node == index)
            where = {int(node): row for row, node in enumerate(given.nodes)}
            for row in rows:
                known = where.get(int(self.node_ids[row]))
                if known is not None:
                    held[row] = given.slips[known]
        held = _tangential(held, normals_in_body)
        slide = np.linalg.norm(held, axis=1)
        if slide.max(initial=0.0) > _HELD_SLIP_SHARE * self.max_slip:
            label = self.prints[int(self.print_of_node[int(np.argmax(slide))])].label
            raise StanceError(
                f"held_slips of {label} reach {slide.max():.3g} m, over twice the small-slip bound "
                f"{self.max_slip:g} m: no answer of this print left them; give the slips the stance before left "
                "(its result's slips), solved with the same max_slip")
        return held

    def print_slips(self, model, data, w) -> dict:
        """Where each flat print's link points lie over its nodes at the iterate, under the
        ``coulomb`` law: robot surface -> :class:`~stances.results.NodeSlips` (the contact
        solve's relative motion plus the held slip, turned back by the print's turn A^-1 W
        and tangential at rest: fixed in the link). Empty off it."""
        if self.law != "coulomb":
            return {}
        w = np.asarray(w, dtype=float)
        solved = self._values(model, data, w).solved
        _, turns, _ = self._print_turns(w)
        return self._as_slips(solved.relative - self._held_motion(w).reshape(-1, 3), turns)

    def _as_slips(self, whole, turns) -> dict:
        """Robot surface -> NodeSlips of each flat print from the link points' whole slips
        ``whole`` (p, 3) body frame, under the prints' turns (L, 3, 3): turned back into the
        print's frame at rest, tangential there."""
        back = np.einsum("pji,pj->pi", turns[self.print_of_node], whole)
        back = _tangential(back, self.normals_in_body)
        return {spec.robot_surface: NodeSlips(self.deformable_object.name, self.node_ids[rows], back[rows])
                for index, spec in enumerate(self.prints) if index not in self.ball_radii
                for rows in [np.flatnonzero(self.print_of_node == index)]}

    @staticmethod
    def _corner_weights(corners, rests):
        """(k, p) weights that give the polygon prints' k corners' heights from the p print
        nodes' link-point heights, and (k,) the print of each corner (point feet, whose
        ``corners`` are None, have none); ``rests``: each print's nodes at rest in its frame, (n, 2).

        A rigid motion moves points by ``(R - I) x + t``, affine in the rest position, and
        the print's nodes and corners lie in its plane: any affine combination of the nodes
        that reproduces a corner's rest position (``sum c = 1``, ``sum c x = corner``; the
        least-norm one here) gives that corner's height, and its derivative, exactly.
        """
        blocks, owners, start = [], [], 0
        total = sum(len(rest) for rest in rests)
        for index, (rest, polygon) in enumerate(zip(rests, corners)):
            count = len(rest)
            if polygon is not None:
                affine = np.vstack([rest.T, np.ones(count)])  # (3, n)
                targets = np.vstack([polygon.T, np.ones(len(polygon))])  # (3, k)
                block = np.zeros((len(polygon), total))
                block[:, start : start + count] = (np.linalg.pinv(affine) @ targets).T
                blocks.append(block)
                owners.extend([index] * len(polygon))
            start += count
        return (np.vstack(blocks) if blocks else np.zeros((0, total))), np.array(owners, dtype=np.int64)

    def _centre_of_pressure_rows(self, outlines, rests):
        """Rows whose values, times the forces (world frame, stacked), are each polygon print's
        moment of its normal forces about each edge of its outline, positive inside
        (N m): all of them >= 0 puts the print's centre of pressure inside its outline.
        ``outlines`` and ``rests`` as :meth:`_corner_weights`' ``corners`` and ``rests``.

        A partly covered node's link point is its rest position, up to a cell's diagonal
        outside the outline (its force acts there; fem.ContactPatch): on a new user's and the
        built-in stances up to 25 % of a sole's or palm's load acted up to 13 mm past its edge
        (measured with median-dual cells, before 2026-12-06; an audit since found 5-13 % on
        three built-in stances, `/work/notes/audit-shape-coverage-2026-12-06/`).
        A foot whose centre of pressure lies past its edge would need a pressure outside
        it, which no converged contact gives. Returns ``((r, 3p) float, (r,) int print)``.
        """
        p = sum(len(rest) for rest in rests)
        blocks, owners, start = [], [], 0
        for i, (outline, rest) in enumerate(zip(outlines, rests)):
            if outline is not None:
                polygon = np.asarray(outline, dtype=float)
                if polygon_area(polygon) < 0.0:
                    polygon = polygon[::-1]
                inside = signed_edge_distances(polygon, rest).T  # (k, n) metres inside each edge
                block = np.zeros((len(polygon), p, 3))
                block[:, start : start + len(rest)] = inside[:, :, None] * self.print_placements[i].rotation[:, 2]
                blocks.append(block.reshape(len(polygon), 3 * p))
                owners.extend([i] * len(polygon))
            start += len(rest)
        return (np.vstack(blocks) if blocks else np.zeros((0, 3 * p))), np.array(owners, dtype=np.int64)

    @staticmethod
    def _in_print(nodes, body_placement, placement) -> np.ndarray:
        """(k, 3) body-frame points in a print's frame, metres."""
        return (nodes @ body_placement.rotation.T + body_placement.translation - placement.translation) @ placement.rotation

    # -- kinematics of the prints -------------------------------------------
    def _displacements(self, data) -> np.ndarray:
        """(p, 3) U imposed by the link points, metres, body frame (eq. 29)."""
        return (points_in_world(data, self.loads) - self.link_points_at_rest) @ self.rotation_body

    def _motion(self, model, data, displacements, d_displacements=None):
        """Each print's link motion from its nominal placement, xi = (translation, rotation
        vector), body frame, about the print's origin (6L,), and d xi / dq (6L, nv).

        The link's points move exactly by ``G xi + r(theta)`` (:meth:`_rotation_residue`).
        A point foot's print translates with the ball's centre and does not turn
        (theta = 0). ``d_displacements`` (3p, nv), when given, asks for the derivative.
        """
        n = len(self.prints)
        xi = np.zeros(6 * n)
        d_xi = None if d_displacements is None else np.zeros((6 * n, model.nv))
        to_body = self.rotation_body.T
        for i, (frame_id, placement) in enumerate(zip(self.frame_ids, self.print_placements)):
            if i in self.point_prints:
                node = int(np.flatnonzero(self.print_of_node == i)[0])
                xi[6 * i : 6 * i + 3] = displacements[node]
                if d_xi is not None:
                    d_xi[6 * i : 6 * i + 3] = d_displacements[3 * node : 3 * node + 3]
                continue
            link = data.oMf[frame_id]
            turn = link.rotation @ placement.rotation.T  # world
            xi[6 * i : 6 * i + 3] = to_body @ (link.translation - placement.translation)
            xi[6 * i + 3 : 6 * i + 6] = to_body @ pin.log3(turn)
            if d_xi is not None:
                jacobian = pin.getFrameJacobian(model, data, frame_id, pin.LOCAL_WORLD_ALIGNED)
                d_xi[6 * i : 6 * i + 3] = to_body @ jacobian[:3]
                # A world angular velocity w turns ``turn`` into exp(w) turn = turn exp(turn^T w).
                d_xi[6 * i + 3 : 6 * i + 6] = to_body @ pin.Jlog3(turn) @ turn.T @ jacobian[3:]
        return xi, d_xi

    def _print_turns(self, w):
        """Each print's turn that W stands for (``A^-1 W``, body frame; none on a point
        foot's print): rotation vectors (L, 3), rotations exp (L, 3, 3) and exp's right
        Jacobians (L, 3, 3)."""
        theta = self._turn_of_w @ w
        return theta, np.array([pin.exp3(t) for t in theta]), np.array([pin.Jexp3(t) for t in theta])

    def _rotation_residue(self, w) -> np.ndarray:
        """(3p,) ``r = (exp(theta) - I - [theta]x) x``: what a finite turn theta of a link
        moves its points beyond the linear ``theta x x`` that G holds, at the turn W
        stands for (``A^-1 W``); second order in theta, so a vanishing term on a stiff
        body, but micrometres of a palm's tilt on foam."""
        theta, turns, _ = self._print_turns(w)
        owner, x = self.print_of_node, self.levers
        turned = np.einsum("pij,pj->pi", turns[owner], x)
        return (turned - x - np.cross(theta[owner], x)).reshape(-1)

    def _imposed_motion(self, w) -> np.ndarray:
        """(3p,) U the link points move by where the placement rows hold under W:
        ``G A^-1 W + r(A^-1 W)``, metres, body frame (:meth:`_rotation_residue`), less
        each node's held slip turned with its print (:meth:`_held_motion`)."""
        motion = self.rigid_motion @ w + self._rotation_residue(w)
        return motion + self._held_motion(w) if self._holding else motion

    def _held_motion(self, w) -> np.ndarray:
        """(3p,) ``-exp(theta) held``: where a sticking node meets its link, from its link
        point, the held slip being fixed in the link (theta = A^-1 W); zero from rest."""
        if not self._holding:
            return np.zeros(self.held.size)
        return -self._turned_held(self._print_turns(w)[1]).reshape(-1)

    def _turned_held(self, turns) -> np.ndarray:
        """(p, 3) each node's held slip turned by its print's turn ``turns`` (L, 3, 3)."""
        return np.einsum("pij,pj->pi", turns[self.print_of_node], self.held)

    def _held_motion_derivative(self, w) -> np.ndarray:
        """(3p, 6L) d :meth:`_held_motion` / dW: ``exp(theta) [held]x Jr(theta) d theta``."""
        _, turns, right = self._print_turns(w)
        owner = self.print_of_node
        d_theta = turns[owner] @ _skew_rows(self.held) @ right[owner]
        return np.einsum("pij,pjk->pik", d_theta, self._turn_of_w[owner]).reshape(3 * len(owner), -1)

    def _motion_derivative(self, w) -> np.ndarray:
        """(3p, 6L) d :meth:`_imposed_motion` / dW."""
        derivative = self.rigid_motion + self._rotation_residue_derivative(w)
        return derivative + self._held_motion_derivative(w) if self._holding else derivative

    def _rotation_residue_derivative(self, w) -> np.ndarray:
        """(3p, 6L) d :meth:`_rotation_residue` / dW."""
        theta, turns, right = self._print_turns(w)
        owner = self.print_of_node
        # d(exp(t) x) = -exp(t) [x]x Jr(t) dt (Jr: exp's right Jacobian); d(t x x) = -[x]x dt.
        skews = self._lever_skews
        d_theta = skews - turns[owner] @ skews @ right[owner]
        return np.einsum("pij,pjk->pik", d_theta, self._turn_of_w[owner]).reshape(3 * len(owner), -1)

    def _tilts_under(self, load: float) -> np.ndarray:
        """(L,) float: for each print, the largest tilt of its face, radians, that forces of
        ``load`` newtons on every print, each acting at its print's farthest node, could
        give: through ``A^-1`` (a bound, first order in the turn), the turn's part about
        the print's tangents. Infinite where a print has no turn (a point foot's)."""
        n_prints = len(self.prints)
        tilts = np.zeros(n_prints)
        reach = [float(np.linalg.norm(self.levers[self.print_of_node == j], axis=1).max()) for j in range(n_prints)]
        for i, rotation in enumerate(self._print_rotations_in_body):
            tangents = rotation[:, :2].T  # (2, 3) body frame
            for j in range(n_prints):
                block = tangents @ self.a_inverse[6 * i + 3 : 6 * i + 6, 6 * j : 6 * j + 6]  # (2, 6)
                tilts[i] += load * (np.linalg.norm(block[:, :3], 2) + reach[j] * np.linalg.norm(block[:, 3:], 2))
        tilts[self.point_prints] = np.inf
        return tilts

    def _tilt_block(self, model, data, columns, derivatives):
        """The face-tilt rows of the prints with a tilt allowance (see :meth:`blocks`), with
        their ``second_order`` (the rows' weighted Jacobian again at a moved posture, which
        :mod:`stances.curvature` differences into their curvature)."""
        value, d_value = self._tilt_rows(model, data, derivatives)
        jacobian = second_order = None
        if derivatives:
            jacobian = np.zeros((len(value), columns))
            jacobian[:, :model.nv] = d_value

            def second_order(model, moved, weights):
                return weights @ self._tilt_rows(model, moved, True)[1]
        return ConstraintBlock("face tilt", value, jacobian, -np.inf, 0.0, 1e-2, self._labels["tilt"],
                               second_order=second_order)

    def _tilt_rows(self, model, data, derivatives):
        """``t - a`` of each print with a tilt allowance a, t the angle between its rest
        normal and its face's (k,), and its derivative along the joints' motions (k, nv) or
        None: ``dt = axis . omega``, omega the world angular velocity, axis the unit
        ``n0 x n1`` (zero where the face is not turned at all, where t has no derivative;
        the row is then far from its bound, a > 0)."""
        allowances = self.tilt_allowances[self._tilted_prints]
        value = np.zeros(len(allowances))
        jacobian = np.zeros((len(allowances), model.nv)) if derivatives else None
        for row, i in enumerate(self._tilted_prints):
            rest = self.print_placements[i].rotation[:, 2]
            face = data.oMf[self.frame_ids[i]].rotation[:, 2]
            across = np.cross(rest, face)  # sin(t) times the axis
            size = float(np.linalg.norm(across))
            value[row] = np.arctan2(size, float(rest @ face)) - allowances[row]
            if derivatives and size > 0.0:
                frame_jacobian = pin.getFrameJacobian(model, data, self.frame_ids[i], pin.LOCAL_WORLD_ALIGNED)
                jacobian[row] = (across / size) @ frame_jacobian[3:]
        return value, jacobian

    def _tilts(self, data) -> np.ndarray:
        """(k,) float: how far each print with a tilt allowance has its face turned from the
        body's rest surface, the angle between the rest normal and the link face's, radians
        (the link frame is the print's at rest)."""
        return self._tilt_rows(None, data, False)[0] + self.tilt_allowances[self._tilted_prints]

    def _contact_frames(self, data) -> np.ndarray:
        """(p, 3, 3) rows t1, t2, n of each node's contact frame, body frame: under the Coulomb
        law its rest frame turned with its link's face (a ball's print does not turn), else
        its rest frame."""
        if not self.turned_frames:
            return self.node_frames
        return np.matmul(self.node_frames, self._face_turns(data)[self.print_of_node].transpose(0, 2, 1))

    def _face_turns(self, data) -> np.ndarray:
        """(L, 3, 3) each print's face turned with its link, relative to its nominal, body
        frame (:meth:`_link_rotations`); the identity for a ball's print, which does not turn."""
        turns = np.array(self._link_rotations(data))
        turns[self.point_prints] = np.eye(3)
        return turns

    def _link_rotations(self, data) -> list:
        """Each print's link rotation relative to its nominal, body frame."""
        return [
            self.rotation_body.T @ data.oMf[frame_id].rotation @ rotation.T
            for frame_id, rotation in zip(self.frame_ids, self._print_rotations_in_body)
        ]

    def _turned_normals(self, data) -> np.ndarray:
        """(T, 3) print-triangle normals turned with their link, body frame (eq. 63)."""
        relative = self._link_rotations(data)
        owner = self.print_of_node[self.patch.triangles[:, 0]]
        rest = self.patch.triangle_normals
        return np.einsum("tij,tj->ti", np.array(relative)[owner], rest)

    def _traction_reaction(self, data):
        """Traction: fem's reaction matrix with each print's normals turned with its
        link (eq. 63), and those normals (T, 3), body frame."""
        normals = self._turned_normals(data)
        return np.asarray(self.patch.reaction_matrix("traction", normals=normals)), normals

    def _turning_derivative(self, model, data, displacements, normals) -> np.ndarray:
        """Traction: (3p, nv) the q-derivative of ``R(q) U`` through the turning normals
        (eq. 63, first term: each triangle's normal turns with its link, dn = omega x n)."""
        per_triangle = np.asarray(self.patch.traction_normal_derivative(displacements))  # (T, 3, 3)
        skews = _skew_rows(normals)
        per_triangle_omega = -np.einsum("tij,tjk->tik", per_triangle, skews)
        owner = self.print_of_node[self.patch.triangles[:, 0]]
        omegas = np.array([
            self.rotation_body.T @ pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)[3:]
            for f in self.frame_ids
        ])  # (L, 3, nv)
        d = np.einsum("tik,tkv->tiv", per_triangle_omega, omegas[owner])
        out = np.zeros((len(self.node_ids), 3, model.nv))
        for corner in range(3):
            np.add.at(out, self.patch.triangles[:, corner], d)
        return out.reshape(3 * len(self.node_ids), -1)

    def _values(self, model, data, w) -> _PrintValues:
        """U, the forces (world) and the body's print displacement at the iterate.

        Memoised on the link placements and ``w``: a linearisation's pieces (forces,
        rows, cost) read it several times, and the line search's accepted trial is
        linearised at the same point, whose contact solve is then reused (so the
        contact modes the next solve starts from are the same either way).
        """
        w = np.asarray(w, dtype=float)
        key = (id(data), b"".join(data.oMi[j].homogeneous.tobytes() for j in self._load_joints), w.tobytes())
        if self._cache_key == key:
            return self._cache
        p = len(self.node_ids)
        displacements = self._displacements(data)
        u = displacements.reshape(-1)
        # Where the placement rows hold (xi(q) = A^-1 W), the link points' motion is
        # U = G A^-1 W + r(A^-1 W): the nodes are given that motion, a function of W
        # alone, so the forces never see a posture that the rows have not yet met
        # (on a stiff body, r of a link still turned by 1e-3 rad would be tens of
        # nanometres of bending, far more than the nanometres the body gives).
        imposed = self._imposed_motion(w)
        if self.law == "coulomb":
            # Contact solved at that motion, against the faces turned as W turns them: f = L (U~ +
            # gap), continuous in W when nodes change modes.
            solved = self._contact(imposed, self._node_turns(w))
            forces_body = solved.forces.reshape(-1)
        else:
            if self.method == "traction":
                # Eq. (44) at the link points' own motion, turned normals included, with
                # the rows' residual carried by D: R(q) U + D (W - A xi(q)).
                solved = self._traction_reaction(data)
                xi, _ = self._motion(model, data, displacements)
                forces_body = solved[0] @ u + self.distribution @ (w - self.a @ xi)
            else:
                solved, forces_body = None, self.reaction @ imposed  # D W + R r
        forces = (forces_body.reshape(p, 3)) @ self.rotation_body.T
        # The body's own print displacement: the compliance under the forces (the link
        # points' U only where the nodes stick; traction has no compliance form).
        nodes = u if self.method == "traction" else -(self.patch.compliance @ forces_body)  # (not -C: a copy of C)
        self._cache_key = key
        self._cache = _PrintValues(displacements, forces, forces_body, nodes, solved)
        self._derivatives = None
        return self._cache

    def _contact(self, imposed, turns=None) -> fem.PrintContact:
        """Signorini-Coulomb contact of the nodes under link points moved by ``imposed``
        (3p,), metres, body frame, against faces turned by ``turns`` (:meth:`_node_turns`);
        warm started from the last solve's modes, or held to :meth:`freeze_modes`'s. A node
        is pressed once its link point has closed its gap."""
        corrected = imposed.reshape(-1, 3) + self.gaps
        if self._frozen is not None:
            return self._system().with_modes(corrected, *self._frozen, turns=turns)
        warm = (None, None) if self._modes is None else self._modes
        solved = self._system().solve(corrected, initial_modes=warm[0], initial_directions=warm[1], turns=turns)
        self._modes = (solved.modes, solved.directions)
        return solved

    def _node_turns(self, w):
        """(p, 3, 3) float: each node's turned contact frame in its rest frame's coordinates,
        ``F R^T F^T`` (F its rest frame's rows, R its print's turn ``exp(A^-1 W)``, body
        frame): the face that presses is the link's, turned with it, and a node that slips
        meets it there (``docs/turned-face.md``). None where no print is turned (a ball's
        print never is)."""
        if not self.turned_frames:
            return None
        theta, turns, _ = self._print_turns(np.asarray(w, dtype=float))
        if not np.any(theta):
            return None
        owner = self.print_of_node
        return np.matmul(np.matmul(self.node_frames, turns[owner].transpose(0, 2, 1)), self.node_frames.transpose(0, 2, 1))

    def _turning_columns(self, solved, w):
        """(3p, 6L) the forces' derivative in W through their frames' turn (``docs/turned-face.md``):
        for a turn dth of print p's frames, ``df = (dth x f)_p + L[-(dth x r)_p + C (dth x f)_p]``
        (f, r the forces and relative motions, body frame; L the mode-fixed Jacobian), and
        ``dth = R Jr(theta) T dW`` (T: the turn's rows of A^-1)."""
        theta, turns, right = self._print_turns(np.asarray(w, dtype=float))
        p, n_prints = len(self.node_ids), len(self.prints)
        # Column k of a print's block is e_k x f (own) and -(e_k x r) (slide): -[f]x and [r]x.
        # (np.cross of each axis cost a tenth of a palm's linearisation.)
        f_skews, r_skews = _skew_rows(solved.forces), _skew_rows(solved.relative)
        own = np.zeros((3 * p, 3 * n_prints))
        slide = np.zeros((3 * p, 3 * n_prints))
        for i in range(n_prints):
            if i in self.point_prints:
                continue
            rows = np.flatnonzero(self.print_of_node == i)
            own.reshape(p, 3, -1)[rows, :, 3 * i : 3 * i + 3] = -f_skews[rows]
            slide.reshape(p, 3, -1)[rows, :, 3 * i : 3 * i + 3] = r_skews[rows]
        d_theta = own + solved.jacobian_dot(slide + self.patch.link_compliance @ own)  # (3p, 3L)
        turn_rates = np.einsum("lij,ljk,lkv->liv", turns, right, self._turn_of_w).reshape(3 * n_prints, -1)
        return d_theta @ turn_rates

    def force_curvature(self, model, data, w):
        """The forces' curvature in W at ``w`` (6L,), for the SQP's Hessian, or None where
        the forces are (nearly) linear in W: no node slips, or the law is not Coulomb's.

        A slipping node's friction lies along its trial slip, a direction that turns with
        the links' motion, and (in turned frames) its gap and cone turn with the face: the
        forces curve in W. At hand-on-cube's answer the static equilibrium's fy curved by
        -21 N per unit of a step whose linear model it met (0.007 in the rest frames), and
        each QP asked for a step that the merit then refused: the solve stopped 3.2 % above
        the optimum after line searches of 10 trials. The curvature is the contact law's
        own (:meth:`fem.PrintContact.derivatives`, the modes held), with ``U(W)``'s and the
        frames' second derivatives through the print turns ``exp(A^-1 W)``. Without slip
        the forces are linear in U and only the turn's second order (micrometres) curves
        them: left out (a review measured 0.004 on both-on-foam's soles, against 0.02-0.13
        once nodes slip: the QP's model steps by that much when a first node slips).

        Parameters
        ----------
        model, data : pinocchio Model and Data
            The robot, its kinematics at the iterate (the forces are W's alone).
        w : (6L,) float
            The print variables W.

        Returns
        -------
        callable or None
            ``weights (3p,) -> (6L, 6L)``: ``d^2 / dW^2`` of ``weights . forces`` (world
            frame, newtons per (unit of W)^2; forces as :meth:`forces` stacks them),
            symmetric. The second derivatives are computed on the first call, and the
            contact state they come from is then let go (a linearisation keeps the callable).
        """
        if self.law != "coulomb":  # (the traction method's law is the bonded one)
            return None
        w = np.asarray(w, dtype=float).copy()
        solved = self._values(model, data, w).solved
        if not solved.n_slip:
            return None
        state = {"solved": solved}

        def curvature(weights):
            if "second" not in state:
                state["second"] = self._force_second_derivative(state.pop("solved"), w)
            weights_body = (np.asarray(weights, dtype=float).reshape(-1, 3) @ self.rotation_body).ravel()
            out = np.einsum("i,iab->ab", weights_body, state["second"])
            return 0.5 * (out + out.T)

        return curvature

    def _force_second_derivative(self, solved, w) -> np.ndarray:
        """(3p, 6L, 6L) ``d^2 forces / dW^2``, body frame, the modes of ``solved`` held
        (:meth:`force_curvature`)."""
        d_turn, dd_turn = _exp_derivatives(self._turn_of_w @ w)  # (L, 3, 3, 3), (L, 3, 3, 3, 3): d R / d theta_j, ...
        rates = self._turn_of_w  # (L, 3, 6L): d theta / dW
        owner, m = self.print_of_node, rates.shape[2]
        # U = G W + exp(theta) x - x - theta x x - exp(theta) held: its second derivative is
        # exp's, on the levers less the held slips.
        dd_rotation = np.einsum("ljkmn,ljA,lkB->lmnAB", dd_turn, rates, rates, optimize=True)  # (L, 3, 3, 6L, 6L)
        dd_motion = np.zeros((owner.size, 3, m, m))
        levers = self.levers - self.held
        for i in range(len(self.prints)):
            rows = owner == i
            dd_motion[rows] = np.einsum("mnAB,pn->pmAB", dd_rotation[i], levers[rows], optimize=True)
        dd_motion = dd_motion.reshape(3 * owner.size, m, m)
        d_motion = self._motion_derivative(w)
        d_turns = dd_turns = None
        if self.turned_frames:
            # Q = F R^T F^T per node (_node_turns); only a slipping node's frame enters its law.
            slipping = np.flatnonzero(solved.modes == fem.SLIP)
            frames, print_of = self.node_frames[slipping], owner[slipping]
            d_rotation = np.einsum("ljmn,ljA->lAmn", d_turn, rates)  # (L, 6L, 3, 3)
            d_turns, dd_turns = np.zeros((owner.size, m, 3, 3)), np.zeros((owner.size, m, m, 3, 3))
            d_turns[slipping] = np.einsum("kim,kAnm,kjn->kAij", frames, d_rotation[print_of], frames, optimize=True)
            dd_turns[slipping] = np.einsum("kim,knmAB,kjn->kABij", frames, dd_rotation[print_of], frames, optimize=True)
        return solved.derivatives(d_motion, dd_motion, d_turns, dd_turns)[1]

    def _system(self) -> fem.PrintContactSystem:
        """The nodes' contact system, made on first use: it keeps the factorisation of each
        contact set it meets (the SQP holds a set or comes back to it at most linearisations)."""
        if self._contact_system is None:
            self._contact_system = fem.PrintContactSystem(self.patch.link_compliance, self.node_frames, self.node_mu)
        return self._contact_system

    def _state(self, model, data, w):
        """U, dU/dq, forces (world) and their derivatives in q and W, the body's print
        displacement and its derivative, at the iterate (joint Jacobians computed)."""
        values = self._values(model, data, w)
        if self._derivatives is None:
            self._derivatives = self._derive(model, data, values, w)
        d_displacements, d_forces_dq, d_forces_dw, d_nodes = self._derivatives
        return values.displacements, d_displacements, values.forces, d_forces_dq, d_forces_dw, values.nodes, d_nodes

    def _derive(self, model, data, values, w):
        """dU/dq (3p, nv), d forces / dq (3p, nv), d forces / dW (3p, 6L) and the
        body's print displacement's derivative (3p, nv + 6L) at the iterate of ``values``."""
        nv, p = model.nv, len(self.node_ids)
        jacobians = point_jacobians(model, data, self.loads)  # (p, 3, nv) world
        d_displacements = np.einsum("ji,pjv->piv", self.rotation_body, jacobians).reshape(-1, nv)
        if self.method == "traction":
            reaction, normals = values.solved
            _, d_xi = self._motion(model, data, values.displacements, d_displacements)
            d_turn = self._turning_derivative(model, data, values.displacements, normals)
            d_q = reaction @ d_displacements + d_turn - self.distribution @ (self.a @ d_xi)
            d_forces_body = np.hstack([d_q, self.distribution])  # (3p, nv + 6L)
        else:
            # The imposed motion depends on W alone: the forces have no q-derivative.
            d_imposed = self._motion_derivative(np.asarray(w, dtype=float))
            if self.law == "coulomb":
                d_w = values.solved.jacobian_dot(d_imposed)  # only L applied to a few directions
                if self.turned_frames:
                    # (at a zero turn too: the frames' turn moves the forces there as well)
                    d_w = d_w + self._turning_columns(values.solved, w)
            else:
                d_w = self.reaction @ d_imposed
            d_forces_body = np.hstack([np.zeros((3 * p, nv)), d_w])
        d_forces = np.einsum("ij,pjv->piv", self.rotation_body, d_forces_body.reshape(p, 3, -1)).reshape(3 * p, -1)
        if self.method == "traction":
            d_nodes = np.hstack([d_displacements, np.zeros((3 * p, self.n_variables))])
        else:
            # Only W moves the forces: C times their W columns alone (the q columns, zero,
            # made this product 4-5 times larger: 2 ms a linearisation on two soles).
            d_nodes = np.hstack([np.zeros((3 * p, nv)), -(self.patch.compliance @ d_forces_body[:, nv:])])
        return d_displacements, d_forces[:, :nv], d_forces[:, nv:], d_nodes

    # -- contact set ---------------------------------------------------------
    def freeze_modes(self, model, data, w) -> np.ndarray:
        """Hold the current stick / slip / lift modes of every node (Coulomb law).

        The forces are then linear in the corrected displacement, so an SQP converges
        fast; :func:`stances.verify` still checks Signorini and Coulomb at the answer.

        Returns
        -------
        (p,) int
            The modes held, one per print node (a copy).
        """
        self.release_modes()
        self._values(model, data, w)
        self._frozen = self._modes
        self._cache_key = None
        return np.array(self._frozen[0])

    def release_modes(self) -> None:
        """Let every node change mode again."""
        self._frozen = None
        self._cache_key = None

    # -- contact-model interface --------------------------------------------
    def initial_variables(self, model, data) -> np.ndarray:
        """W consistent with the current placement: ``A xi(q)``."""
        return self.a @ self._motion(model, data, self._displacements(data))[0]

    def print_wrenches(self, model, point_forces) -> np.ndarray:
        """Each print's resultant wrench of given forces, (6L,) float: the forces on its
        link (N) and their moment about the print's origin (N m), body frame, as W.

        Parameters
        ----------
        model : pinocchio.Model
        point_forces : sequence of PointForce
            Forces on the robot, world frame; those on each print's link frame count.
        """
        w = np.zeros(self.n_variables)
        for i, (frame_id, placement) in enumerate(zip(self.frame_ids, self.print_placements)):
            frame = model.frames[frame_id].name
            on_link = [(np.asarray(f.point, float), np.asarray(f.force, float)) for f in point_forces if f.frame == frame]
            force = sum((f for _, f in on_link), np.zeros(3))
            moment = sum((np.cross(point - placement.translation, f) for point, f in on_link), np.zeros(3))
            w[6 * i : 6 * i + 3] = self.rotation_body.T @ force
            w[6 * i + 3 : 6 * i + 6] = self.rotation_body.T @ moment
        return w

    def variables_from_forces(self, model, point_forces) -> np.ndarray:
        """W carrying given forces, (6L,) float: each print's resultant wrench
        (:meth:`print_wrenches`), less what held slips carry.

        The consistent reaction gives ``G^T f = G^T R G A^-1 W = W``: a print's W is the
        wrench its nodes put on the link, body frame, moments about the print's origin
        (second order in the turn aside). Held slips (a print kept from the stance before)
        add ``G^T R h``, h their motion (:meth:`_held_motion`, which turns with W): W is the
        wrench less that, a fixed point found in a few steps (where every node sticks, to
        the turn's second order again). From the forces of the same stance held rigid,
        a solve starts with the prints pressed as deep as that load presses them, where
        W read off a posture whose links barely touch (:meth:`initial_variables`) leaves
        every node at the point of lifting off, with no force gradient.

        A ball (point foot) must sink further than a flat print to carry the same load,
        its nodes touching only where its profile reaches them: its W is scaled up (by
        doublings, then halvings of the step) until the contact solve gives its print
        the normal force the wrench asks for (a few percent more).

        Parameters
        ----------
        model, point_forces
            As :meth:`print_wrenches`.
        """
        wrench = self.print_wrenches(model, point_forces)
        w = wrench
        if self._holding:
            # G^T f = G^T R (G A^-1 W + h(W)) = W + G^T R h(W), R = -(C + D)^-1: read as the
            # wrench, W started a kept palm pushed 40 N along its held slips. h turns with
            # W (a kept palm's 43 N of correction turns it 31 mrad): read at the wrench's
            # turn, the forces were 1.1 % off; three steps leave 3e-4.
            for _ in range(_HELD_WRENCH_STEPS):
                w = wrench + self.basis.T @ self.patch.link_solve(self._held_motion(w))
        if self.law == "coulomb":
            w = np.array(w)
            for i in self.point_prints:
                w[6 * i : 6 * i + 3] *= self._ball_load_scale(w, int(i), wrench)
        return w

    def _ball_load_scale(self, w, i: int, wrench) -> float:
        """How many times ball print ``i``'s W must be scaled for the contact solve to give
        it the normal force of its ``wrench`` (6L,) (1 when it already does, or asks for
        none): W's own where no print holds slips, else less what their motion carries."""
        normal = self.print_placements[i].rotation[:, 2] @ self.rotation_body
        target = float(normal @ wrench[6 * i : 6 * i + 3])
        rows = self.print_of_node == i

        def carried(scale):
            trial = np.array(w)
            trial[6 * i : 6 * i + 3] *= scale
            forces = self._contact(self._imposed_motion(trial)).forces
            return float(forces[rows].sum(axis=0) @ normal)

        if target <= 0.0 or carried(1.0) >= target:
            return 1.0
        low, high = 1.0, 2.0
        for _ in range(_BALL_DOUBLINGS):
            if carried(high) >= target:
                break
            low, high = high, 2.0 * high
        for _ in range(_BALL_HALVINGS):
            middle = np.sqrt(low * high)
            low, high = (middle, high) if carried(middle) < target else (low, middle)
        return high

    # -- the stiff limit (stances.stages._solve_stiff_limit) ----------------------
    def solver_state(self) -> tuple:
        """What a solve leaves behind that the next one starts from (the last contact
        solve's modes, the strain rows' centres verify added, the contact system with the
        factorisations it keeps): for :meth:`restore_solver_state`."""
        return self._modes, self._frozen, self._found_centres, self._strain_outlier, self._contact_system

    def restore_solver_state(self, state) -> None:
        """Back to a :meth:`solver_state`: a solve abandoned leaves no trace in the next
        (the contact system made anew where it had not been made: the factorisations a
        solve leaves there move the next solve's last bits)."""
        self._modes, self._frozen, self._found_centres, self._strain_outlier, self._contact_system = state
        self._cache_key, self._cache, self._derivatives = None, None, None

    def stiff_give(self, w) -> float:
        """The body's give under W (6L,), metres: the largest component of the bonded
        print nodes' motion ``G A^-1 W``."""
        return float(np.abs(self.rigid_motion @ np.asarray(w, dtype=float)).max())

    def sticks(self, w) -> bool:
        """Whether under W (6L,) every node would stick: the bonded forces ``R G A^-1 W``
        (W's own, which W's force term weighs) each push and lie in their node's cone.

        Then they are the Coulomb forces too, and the solve through W weighs what the
        nodes carry (soles flat on a steel-stiff block, at the rigid answer's loads);
        where some node would pull or slip (a palm on its edge) the nodes carry another
        wrench than W: the stiff limit's reason. One solve with the print's kept Cholesky
        factor; the contact solve's state is untouched.
        """
        w = np.asarray(w, dtype=float)
        forces = -self.patch.link_solve(self._imposed_motion(w)).reshape(-1, 3)
        local = np.einsum("pij,pj->pi", self.node_frames, forces)  # (tangential x, y, normal)
        inside = np.isinf(self.node_mu) | (self.node_mu * local[:, 2] >= np.linalg.norm(local[:, :2], axis=1))
        return bool(np.all(inside) and np.all(local[:, 2] >= 0.0))

    def held_prints(self, coverage: float = 0.0, friction: float = 1.0) -> dict:
        """Each print held rigid in the body's stiff limit.

        As E grows a print's links move by nanometres and its nodes' Coulomb forces can
        carry what a rigid contact carries where they are: a centre of pressure inside
        the convex hull of its link points (not the link's whole polygon, on a mesh
        coarse under it) and inside that polygon, moved in by ``_REACH_MARGIN`` and
        ``_OUTLINE_MARGIN`` of the nodes' spacing, with its resultant in the friction
        pyramid of its nodes' coefficient scaled by ``friction``. For
        :func:`stances.build_problem`'s ``held_prints``.

        Inside the polygon too: partly covered nodes past its edge are link points, and a
        hull through them let the stance hold with its centre of pressure on a sole's toe
        edge, the tipping limit, carried by those nodes' forces past the toes, which no sole
        exerts (both soles on a 1e10 Pa slab, 71-95 % of their load on that row 6.9 mm
        past the toe edge: an independent audit, ``bench/results/audit-stiff-slab-2026-12-06.md``).

        Parameters
        ----------
        coverage : float, optional
            The hull's nodes are those covered at least this much (``fem.print_coverage``):
            0 takes every node of the print; a centre of pressure carried by the partly
            covered rows past an edge asks the print to pivot on them, by more than the
            stiff limit takes on a softer body (hand-on-cube's palm on its edge at 1e9 Pa:
            52 um), where the nodes covered a hundredth or more reach less far.
        friction : float, optional
            The share of its nodes' friction coefficient the resultant keeps to: 1, the
            rigid contact's; ``friction_margin`` keeps the nodes from all sliding at once,
            where a resultant on the rigid pyramid may be carried only so (climb's palm at
            1e12 Pa: no restoration step met the rows from such an answer).

        Returns
        -------
        dict of str to HeldPrint
            By robot surface; empty where a point foot presses the body.
        """
        if len(self.point_prints):
            return {}
        out = {}
        for i, (spec, placement) in enumerate(zip(self.prints, self.print_placements)):
            rows = self.print_of_node == i
            if np.count_nonzero(rows & (self.coverage >= coverage)) >= 3:
                rows &= self.coverage >= coverage
            points = ((self.link_points_at_rest[rows] - placement.translation) @ placement.rotation)[:, :2]
            spacing = float(np.median(scipy.spatial.cKDTree(points).query(points, k=2)[0][:, 1]))
            reach = clip_polygon(inset_hull(points, _REACH_MARGIN * spacing),
                                 inset_hull(self._outlines[i], _OUTLINE_MARGIN * spacing))
            out[spec.robot_surface] = HeldPrint(np.array(reach), friction * self.print_mu[i])
        return out

    def pressure_fits(self, forces, every: bool = False) -> list:
        """Per print on a body too stiff to give (:func:`stiff_under`; with ``every``, per
        flat print), how far its nodes' normal forces are from those of any non-negative
        pressure inside its polygon (:func:`fem.pressure_fit`); None for the others and for
        a print pressing under ``_FIT_LEAST_LOAD`` (its forces are the solver's rounding).

        On a stiff body a link pivoting by nanometres onto the partly covered nodes past its
        edge, while the nodes inside lift, is no row's concern (the whole-print rows bound
        millimetres), and the forces it gives no pressure under the link gives (an
        independent audit: climb-with-soft-support's palm at 1e12 Pa, 7.5 % off).

        Parameters
        ----------
        forces : (p, 3) float
            The print nodes' forces on the robot, world frame, newtons.
        every : bool, optional
            Fit every flat print, not only the stiff ones (the stiff limit's answers: a body
            can be solved there under a load that gives under ``STIFF_GIVE`` though the
            robot's whole weight would sink it more).
        """
        forces = np.asarray(forces, dtype=float)
        fits = []
        for i, (polygon, stiff) in enumerate(zip(self._polygons_in_body, self._stiff_prints)):
            rows = self.print_of_node == i
            loads = forces[rows] @ self.print_placements[i].rotation[:, 2]
            if polygon is None or not (stiff or every) or loads.sum() < _FIT_LEAST_LOAD:
                fits.append(None)
                continue
            fits.append(fem.pressure_fit(self.deformable_object.body.mesh, polygon, self.node_ids[rows], loads))
        return fits

    def unpressed(self, forces, tolerance: float, every: bool = False, measures: dict | None = None) -> list:
        """Why the prints' node forces are no pressure under their faces: each fit of
        :meth:`pressure_fits` (``forces``, ``every`` as there) over ``tolerance``, its value
        put in ``measures`` (``pressure fit of <print>``) where given."""
        reasons = []
        for spec, fit in zip(self.prints, self.pressure_fits(forces, every)):
            if fit is None:
                continue
            if measures is not None:
                measures[f"pressure fit of {spec.label}"] = fit
            if fit > tolerance:
                reasons.append(f"the node forces of {spec.label} are no pressure under its face ({100 * fit:.3g} % of "
                               "them off: a link pivoting onto the partly covered nodes past its edge gives such forces)")
        return reasons

    def spread_forces(self, data, point_forces):
        """Node forces of a pressure under each print's face carrying its wrench in
        ``point_forces``: of every such pressure whose tractions lie in its nodes' friction
        pyramid, the one of least elastic energy (:meth:`_least_energy_pressure`).

        For a stiff body whose nodes' own contact would carry a held answer only by
        pivoting onto the partly covered nodes past an edge (:mod:`stances.stages`): the
        node forces of a link's face, as a converged mesh would give them, where this mesh
        gives none. Where the body gives nanometres under them its nodes lie against their
        links to that, which :func:`stances.verify` checks.

        Parameters
        ----------
        data : pinocchio.Data
            Frame placements computed at the answer's posture.
        point_forces : sequence of PointForce
            Forces on the robot, world frame; those on each print's contact frame count
            (one print a frame: each robot surface has its own, ``<surface>_contact``, and
            a stance presses each surface once).

        Returns
        -------
        (p, 3) float or None
            The print nodes' forces on the robot, world frame; None where no such pressure
            carries a print's wrench.
        """
        out = np.zeros((len(self.node_ids), 3))
        for i, (frame, frame_id, placement) in enumerate(zip(self._print_frames, self.frame_ids, self.print_placements)):
            on_link = [f for f in point_forces if f.frame == frame]
            if not on_link or self._polygons_in_body[i] is None:
                continue
            link = data.oMf[frame_id]
            # The wrench on the link about its frame, in its axes (its print's at rest).
            local = np.array([link.actInv(np.asarray(f.point, dtype=float)) for f in on_link])
            local_forces = np.array([f.force for f in on_link], dtype=float) @ link.rotation
            wrench = np.concatenate([local_forces.sum(axis=0), np.cross(local, local_forces).sum(axis=0)])
            forces = self._least_energy_pressure(i, wrench)
            if forces is None:
                return None
            # Into the link's axes (the print's at rest; the face turned by micro-radians where
            # its give holds it, HeldPrint.motion), then the world's.
            in_print = self.rotation_body.T @ placement.rotation
            out += forces @ in_print @ link.rotation.T
        return out

    def spread_motions(self, model, data, forces) -> list:
        """Each print's rigid motion (6,) (translation, metres, then rotation vector, radians;
        its frame) that puts its link points where its pressed nodes are under ``forces``
        (least squares over them): the body's field, the partly covered nodes' couplings'
        stretch added (``ends`` as :meth:`verify` reads them). A link whose forces
        :meth:`spread_forces` gave is held there (:attr:`HeldPrint.motion`), not at rest:
        on a steel-stiff cube a palm's nodes slide a micrometre under its friction.

        Parameters
        ----------
        model, data : pinocchio Model and Data
        forces : (p, 3) float
            The print nodes' forces on the robot, world frame.

        Returns
        -------
        list of (6,) float
            Per print; zeros for a ball and for a print pressing fewer than three nodes.
        """
        forces = np.asarray(forces, dtype=float)
        forces_body = forces @ self.rotation_body
        ends = self.displacement_field(model, data, forces)[self.node_ids]
        if self._coupling is not None:
            ends = ends - block_diagonal_product(self._coupling, forces_body.reshape(-1)).reshape(-1, 3)
        motions = []
        for i, placement in enumerate(self.print_placements):
            # Nodes pressing a ten-thousandth of a newton or more: the others' ends are free to
            # lie anywhere below their links.
            pressed = (self.print_of_node == i) & (forces @ placement.rotation[:, 2] > _PRESSED_LOAD)
            if self._polygons_in_body[i] is None or np.count_nonzero(pressed) < 3:
                motions.append(np.zeros(6))
                continue
            # The print's rigid motions G (body frame, about its origin) on those nodes.
            basis = self.basis.reshape(-1, 3, self.n_variables)[pressed][:, :, 6 * i : 6 * i + 6].reshape(-1, 6)
            motion = np.linalg.lstsq(basis, ends[pressed].reshape(-1), rcond=None)[0]
            in_print = self.rotation_body.T @ placement.rotation  # print axes in the body's
            motions.append(np.concatenate([motion[:3] @ in_print, motion[3:] @ in_print]))
        return motions

    def _least_energy_pressure(self, i, wrench):
        """Node forces of print ``i``'s least-energy pressure with ``wrench``
        (:meth:`_least_energy_weights`): (p, 3) float, body frame, on the robot, or None."""
        weights = self._least_energy_weights(i, wrench)
        return None if weights is None else (self._pressure_corners(i)[1] @ weights).reshape(-1, 3)

    def _least_energy_weights(self, i, wrench):
        """The pressure under print ``i``'s face with ``wrench``, its tractions in the pyramid
        of its nodes' friction, of least elastic energy ``1/2 f^T (C + D) f`` (the body's and
        its partly covered nodes' couplings': of the loads a rigid link's face could put
        there, those the model's elasticity selects). (With the body's energy alone, ``C``,
        the loads gathered on the barely covered nodes past an edge, whose couplings then
        stretched micrometres: iCub's and climb's palms at 1e10 Pa were refused, a node
        2.5 um from its link.)

        The pressure is spanned by point loads at the corners of the surface triangles'
        parts under the face (:func:`fem.pressure_corners`), each a combination of its
        pyramid's edges: a QP over those coefficients (proxsuite), its equality then made
        exact on their support.

        Parameters
        ----------
        i : int
            The print.
        wrench : (6,) float
            Force (N) and moment about the print's origin (N m), its frame.

        Returns
        -------
        (4m,) float or None
            Each corner's pyramid-edge coefficients, newtons (:meth:`_pressure_corners`'
            columns), non-negative, carrying ``wrench`` to 1e-9 of it; None where the
            corners cannot (a centre of pressure off the face, a load past the pyramid) or the
            QP fails.
        """
        corners = self._pressure_corners(i)
        if corners is None:
            return None
        levers, spread = corners  # (m, 3) print frame; (3p, 4m) body frame: each edge's node loads
        edges = friction_cone_generators(self.print_mu[i])  # (4, 3), print frame
        columns = _edge_wrenches(levers, edges).T  # (6, 4m)
        # The moment rows in newtons (over the print's reach): equilibrated rows took climb's
        # palm's QP from 1,755 iterations to 263 (its spread 0.48 -> 0.15 s).
        reach = float(np.abs(levers[:, :2]).max())
        columns[3:] /= reach
        wrench = np.concatenate([wrench[:3], wrench[3:] / reach])
        hessian = spread.T @ self.patch.link_compliance @ spread
        n = hessian.shape[0]
        # Scaled to a unit diagonal; a whisker of |c|^2 makes it definite (corners of one triangle
        # load the same nodes).
        hessian = hessian / max(float(np.diag(hessian).max()), 1e-300) + _SPREAD_REGULARISATION * np.eye(n)
        qp = proxsuite.proxqp.dense.QP(n, 6, 0, True)  # c >= 0 as box constraints
        size = max(float(np.linalg.norm(wrench)), 1.0)  # newtons
        qp.settings.eps_abs, qp.settings.eps_rel = 1e-10 * size, 0.0
        qp.settings.max_iter, qp.settings.verbose = _SPREAD_QP_ITERATIONS, False
        qp.init(hessian, np.zeros(n), columns, wrench, None, None, None, np.zeros(n), np.full(n, 1e20))
        qp.solve()
        if qp.results.info.status != proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED:
            return None
        weights = np.maximum(np.asarray(qp.results.x), 0.0)
        for _ in range(3):
            # The equality to rounding on the coefficients in use, kept non-negative.
            residual = wrench - columns @ weights
            if np.linalg.norm(residual) <= 1e-9 * size:
                return weights
            support = weights > 0.0
            weights[support] += np.linalg.lstsq(columns[:, support], residual, rcond=None)[0]
            weights = np.maximum(weights, 0.0)
        return weights if np.linalg.norm(wrench - columns @ weights) <= 1e-9 * size else None

    def _pressure_corners(self, i):
        """Print ``i``'s :func:`fem.pressure_corners` that its nodes keep, memoised: their
        positions in its frame (m, 3), and each of its pyramid's edges' loads on the body's
        print nodes (3p, 4m), body frame; None where it keeps none. A corner whose triangle
        has a node the print does not keep (covered less than it keeps, or gone to a
        neighbouring print) is left out: its load would go to no node."""
        if i not in self._corners_memo:
            mesh, body, placement = self.deformable_object.body.mesh, self._body_placement, self.print_placements[i]
            points, triangles, shares = fem.pressure_corners(mesh, self._polygons_in_body[i])
            # A corner shared by parts (a node inside the polygon, a crossing of a mesh edge)
            # once: the same point loads the same nodes alike from either triangle.
            _, first = np.unique(np.round(points / 1e-9), axis=0, return_index=True)
            first = np.sort(first)
            points, triangles, shares = points[first], triangles[first], shares[first]
            rows = np.flatnonzero(self.print_of_node == i)
            order = np.argsort(self.node_ids[rows])
            ids = self.node_ids[rows][order]
            where = np.clip(np.searchsorted(ids, triangles), 0, len(ids) - 1)
            mine = ids[where] == triangles
            shares = np.where(shares > _SHARE_ROUNDING, shares, 0.0)
            kept = (mine | (shares == 0.0)).all(axis=1)
            memo = None
            if kept.any():
                edges_in_body = self.rotation_body.T @ placement.rotation @ friction_cone_generators(self.print_mu[i]).T
                spread = np.zeros((len(self.node_ids), 3, int(kept.sum()), 4))
                for k, (node_rows, node_shares, own) in enumerate(zip(rows[order][where[kept]], shares[kept], mine[kept])):
                    for row, share in zip(node_rows[own], node_shares[own]):
                        spread[row, :, k, :] += share * edges_in_body
                memo = (self._in_print(points[kept], body, placement), spread.reshape(3 * len(self.node_ids), -1))
            self._corners_memo[i] = memo
        return self._corners_memo[i]

    def carrying_variables(self, wrench):
        """W whose Coulomb forces carry given wrenches, and the links' motion it asks.

        The inverse of the contact law at fixed posture: the links' motion xi whose
        contact solve gives forces with each print's ``wrench``
        (:meth:`fem.PrintContactSystem.solve_loaded`, from rest), and ``W = A xi``, the
        variables whose placement rows ask that motion.

        Parameters
        ----------
        wrench : (6L,) float
            Each print's force (N) and moment about its origin (N m), body frame, as W.

        Returns
        -------
        (w, xi) : ((6L,) float, (6L,) float)
            Or None where no motion of the links makes the nodes carry the wrenches (a
            centre of pressure beyond them, a sideways load at which the print would
            slide off).
        """
        answer = self._system().solve_loaded(self.basis, np.asarray(wrench, dtype=float), self._link_motion,
                                             np.zeros(self.n_variables),
                                             turns=lambda xi: self._node_turns(self.a @ xi))
        return None if answer is None else (self.a @ answer[1], answer[1])

    def link_give(self, xi) -> float:
        """The links' give, metres: the largest component of the link points' motion under
        the links' motion ``xi`` (6L,)."""
        w = self.a @ np.asarray(xi, dtype=float)
        return float(np.abs(self.basis @ xi + self._rotation_residue(w)).max())

    def _link_motion(self, xi):
        """The link points' motion, the nodes' gaps added and held slips taken off, under
        links moved by ``xi`` (6L,), and its derivative: ``G xi + r(xi) + gap - exp(theta)
        held`` (p, 3), ``G + d(r - exp(theta) held)/dxi`` (3p, 6L); body frame, metres (r:
        :meth:`_rotation_residue`, read at ``W = A xi``; :meth:`_held_motion`)."""
        w = self.a @ xi
        moved = self.basis @ xi + self._rotation_residue(w)
        derivative = self.basis + self._rotation_residue_derivative(w) @ self.a
        if self._holding:
            moved, derivative = moved + self._held_motion(w), derivative + self._held_motion_derivative(w) @ self.a
        return moved.reshape(-1, 3) + self.gaps, derivative

    def displacements(self, model, data) -> np.ndarray:
        """(p, 3) float: print-node displacements U, metres, body frame (eq. 29)."""
        return self._displacements(data)

    def forces(self, model, data, w) -> np.ndarray:
        """(p, 3) world forces of the print nodes on the robot, newtons (eq. 44)."""
        return self._values(model, data, w).forces

    def force_jacobians(self, model, data, w):
        """d forces / d q (3p, nv) and d forces / d W (3p, 6L)."""
        state = self._state(model, data, w)
        return state[3], state[4]

    def blocks(self, model, data, w, columns, offset, derivatives=True):
        """Elastic placement, per-node no adhesion and friction, indentation, mesh overlap, strain.

        Parameters
        ----------
        columns : int
            Width of the step vector (nv + m).
        offset : int
            Column of this contact's first variable in the step vector.
        derivatives : bool
            False: the rows' values only (``jacobian`` None), without the
            print points' Jacobians nor the contact solve's derivative.
        """
        values = self._values(model, data, w)
        displacements, forces, nodes = values.displacements, values.forces, values.nodes
        forces_body = values.forces_body
        nv, p = model.nv, len(self.node_ids)
        w_columns = slice(offset, offset + self.n_variables)
        blocks = []
        # Derivatives in the full step (None: values only).
        d_displacements = d_forces = d_nodes_full = jacobian = None
        if derivatives:
            _, d_displacements, _, d_forces_dq, d_forces_dw, _, d_nodes = self._state(model, data, w)

        # Compliance form of the placement (see the module docstring), in each print's axes.
        xi, d_xi = self._motion(model, data, displacements, d_displacements)
        residual = self.to_print @ xi + self.compliance_rows @ w
        if derivatives:
            jacobian = np.zeros((self.n_variables, columns))
            jacobian[:, :nv] = self.to_print @ d_xi
            jacobian[:, w_columns] = self.compliance_rows
        labels = self._labels
        blocks.append(equality("placement", residual, jacobian, 1e-2, labels["placement"], PLACEMENT_ACCURACY))

        if derivatives:
            d_forces = np.zeros((p, 3, columns))
            d_forces[:, :, :nv] = d_forces_dq.reshape(p, 3, nv)
            d_forces[:, :, w_columns] = d_forces_dw.reshape(p, 3, -1)
            d_nodes_full = np.zeros((3 * p, columns))
            d_nodes_full[:, :nv] = d_nodes[:, :nv]
            d_nodes_full[:, w_columns] = d_nodes[:, nv:]
            d_forces_body = self._body_rows(d_forces.reshape(3 * p, columns))
        if len(self._tilted_prints):
            # Each flat print's face within its tilt allowance a of the rest surface, so that
            # its nodes' narrowed cones about the rest normal lie in their cones about the
            # face: t - a <= 0, t the angle between the normals (linear in the turn, where
            # the smooth (sin^2 t - sin^2 a) / (2 sin a) overshot its bound from a tilted
            # start: hand-on-coarse-cube's palm 12 -> 15 SQP iterations).
            blocks.append(self._tilt_block(model, data, columns, derivatives))
        if self.law == "coulomb":
            # The contact solve keeps every node admissible; each link must still
            # press its print (on average not above the rest surface; a ball down to
            # its nearest node at least), or it is not in contact.
            heights = np.einsum("pj,pj->p", displacements + self.gaps, self.normals_in_body)
            value, jacobian, d_heights = np.zeros(len(self.prints)), None, None
            for i in range(len(self.prints)):
                rows = self.print_of_node == i
                value[i] = heights[rows].min() if i in self.point_prints else heights[rows].mean()
            if derivatives:
                d_heights = np.einsum("pj,pjv->pv", self.normals_in_body, d_displacements.reshape(p, 3, nv))
                jacobian = np.zeros((len(self.prints), columns))
                for i in range(len(self.prints)):
                    jacobian[i, :nv] = d_heights[self.print_of_node == i].mean(axis=0)
            # Within 10 nm of the surface a print touches (a steel-stiff body sinks less).
            blocks.append(ConstraintBlock("touch", value, jacobian, -np.inf, 0.0, 1e-2, labels["touch"], slack=1e-8))
            if np.isfinite(self.max_corner_lift):
                # ... and presses with its whole face: each corner sunk its share of the
                # print's mean sinking (corner_sinking, max_corner_lift).
                value, jacobian = self._corner_rows @ heights, None
                if derivatives:
                    jacobian = np.zeros((len(value), columns))
                    jacobian[:, :nv] = self._corner_rows @ d_heights
                blocks.append(ConstraintBlock(
                    "whole print", value, jacobian, -np.inf, self.max_corner_lift, 1e-2, labels["corners"]))
            # A link point slides over its node's coupling end: the node plus its coupling's stretch.
            ends, d_ends = nodes, d_nodes_full
            if self._coupling is not None:
                ends = nodes - block_diagonal_product(self._coupling, forces_body)
                if derivatives:
                    d_ends = d_nodes_full - block_diagonal_product(self._coupling, d_forces_body)
            blocks.append(self._slip_block(displacements, d_displacements, ends, d_ends, columns))
            # Each print's resultant stays in its pyramid (less ``friction_margin``): each
            # node's circular cone alone would let a print carry more than a rigid
            # contact's pyramid allows.
            values, jacobians = self._resultant_rows(forces, d_forces)
            blocks.append(ConstraintBlock("node contact", values, jacobians, 0.0, np.inf, 1.0, labels["resultant"]))
        else:
            # Bonded nodes push; each node's force stays in its own (inner) friction
            # pyramid ("sticking"), or only each print's resultant does ("bonded").
            values = [np.einsum("pj,pj->p", self.normals, forces)]
            jacobians = [np.einsum("pj,pjc->pc", self.normals, d_forces)] if derivatives else None
            if self.law == "sticking":
                faces = pyramid_faces(self.normals, self.tangents, self.node_mu)  # (p, 4, 3)
                values.append(np.einsum("pkj,pj->pk", faces, forces).reshape(-1))
                if derivatives:
                    jacobians.append(np.einsum("pkj,pjc->pkc", faces, d_forces).reshape(4 * p, columns))
            else:
                resultant = self._resultant_rows(forces, d_forces)
                values.append(resultant[0])
                if derivatives:
                    jacobians.append(resultant[1])
            blocks.append(ConstraintBlock(
                "node contact", np.concatenate(values), np.vstack(jacobians) if derivatives else None,
                0.0, np.inf, 1.0, labels["node contact"],
            ))

        if len(self._pressure_print):
            # Each polygon print's centre of pressure inside its outline.
            value = self._pressure_rows @ forces.reshape(-1)
            jacobian = self._pressure_rows @ d_forces.reshape(3 * p, columns) if derivatives else None
            blocks.append(ConstraintBlock("centre of pressure", value, jacobian, 0.0, np.inf, 1.0, labels["pressure"]))
        # Indentation of the body's print nodes along their normal, bounded
        # relative to the body's thickness.
        depth = -np.einsum("pj,pj->p", nodes.reshape(p, 3), self.normals_in_body)
        deep = np.flatnonzero(depth >= _INDENTATION_ACTIVATION * self.max_indentation)
        jacobian = None
        if derivatives:
            jacobian = -np.einsum("pj,pjc->pc", self.normals_in_body[deep], d_nodes_full.reshape(p, 3, columns)[deep])
        blocks.append(ConstraintBlock(
            "indentation", depth[deep], jacobian, -np.inf, self.max_indentation, 1e-2,
            tuple(labels["indentation"][i] for i in deep),
        ))
        blocks.append(self._overlap_block(displacements, d_displacements, nodes, d_nodes_full, columns))
        if self.method == "traction":
            strain = self._strain_block(nodes, d_nodes_full, columns)
        else:
            # The compliance form knows the forces: the strains of the loads on the body
            # (minus the forces on the robot), no condensed stiffness needed.
            strain = self._strain_block(-forces_body, -d_forces_body if derivatives else None, columns, per="load")
        if strain is not None:
            blocks.append(strain)
        return blocks

    def _overlap_block(self, displacements, d_displacements, nodes, d_nodes, columns) -> ConstraintBlock:
        """How far the body's print nodes reach past their link points along the print normal,
        within ``max_mesh_overlap`` (``options.max_mesh_overlap``).

        A node the print's outline covers in part lies its coupling's stretch ``D f`` behind
        its link point (the module docstring), so the deformed mesh passes into the link at
        the print's edge; a fully covered node follows its link. Rows for the nodes past
        half the bound (the others are far from it; :meth:`verify` checks every node).

        Parameters
        ----------
        displacements : (p, 3) float
            The link points' motion U, metres, body frame.
        d_displacements : (3p, nv) float or None
            Its derivative in the configuration step (None: values only).
        nodes : (3p,) float
            The body's print-node displacements, metres, body frame.
        d_nodes : (3p, columns) float or None
            Their derivative in the whole step.
        """
        p = len(self.node_ids)
        overlap = np.einsum("pj,pj->p", nodes.reshape(p, 3) - displacements.reshape(p, 3) - self.gaps, self.normals_in_body)
        near = np.flatnonzero(overlap >= _OVERLAP_ACTIVATION * self.max_mesh_overlap)
        jacobian = None
        if d_nodes is not None:
            jacobian = np.einsum("pj,pjc->pc", self.normals_in_body[near], d_nodes.reshape(p, 3, columns)[near])
            jacobian[:, : d_displacements.shape[1]] -= np.einsum(
                "pj,pjv->pv", self.normals_in_body[near], d_displacements.reshape(p, 3, -1)[near])
        return ConstraintBlock(
            "mesh overlap", overlap[near], jacobian, -np.inf, self.max_mesh_overlap, 1e-3,
            tuple(self._labels["overlap"][i] for i in near),
        )

    def _slip_block(self, displacements, d_displacements, nodes, d_nodes, columns) -> ConstraintBlock:
        """Small slip: the largest tangential motions of link points over their nodes.

        Coulomb contact is solved on the nodes under the declared print; a link
        that slides far over them would touch others (measured: hand-on-soft-cube
        was accepted with its palm turned 76 degrees, loaded nodes up to 70 mm
        from their link points). The length of each of the ``_SLIP_ROWS``
        largest slips is kept within ``max_slip`` (what verify checks), linearised
        along the slip itself; the row count is fixed. (Each component within
        ``max_slip / sqrt(2)``, the disc's inner square, refused a print kept from the
        stance before with 4.8 mm of its 5.5 mm held, one component past 3.9 mm: its
        rows started violated and the solve stalled.) ``d_displacements`` (3p, nv) and
        ``d_nodes`` (3p, columns), in the full step, are None for values only.
        """
        p = len(self.node_ids)
        relative = displacements.reshape(-1) - nodes  # link point minus node, body frame
        tangential = np.einsum("pij,pj->pi", self.node_frames[:, :2], relative.reshape(p, 3))
        lengths = np.linalg.norm(tangential, axis=1)
        chosen = np.argsort(-lengths, kind="stable")[: min(_SLIP_ROWS, p)]
        jacobian = None
        if d_displacements is not None:
            entries = (3 * chosen[:, None] + np.arange(3)).reshape(-1)  # the chosen nodes' rows
            d_relative = -d_nodes[entries]
            d_relative[:, : d_displacements.shape[1]] += d_displacements[entries]
            d_tangential = np.einsum("pij,pjc->pic", self.node_frames[chosen, :2], d_relative.reshape(len(chosen), 3, columns))
            # d|s| = (s / |s|) . ds; a slip of zero is far from its bound (no direction to give).
            along = tangential[chosen] / np.where(lengths[chosen] > 0.0, lengths[chosen], 1.0)[:, None]
            jacobian = np.einsum("pi,pic->pc", along, d_tangential)
        labels = tuple(f"slip at node {int(self.node_ids[i])} of {self.deformable_object.name}" for i in chosen)
        return ConstraintBlock("slip", lengths[chosen], jacobian, -np.inf, self.max_slip, 1e-2, labels)

    @cached_property
    def reaction(self) -> np.ndarray:
        """(3p, 3p) float, N/m, body frame: the print's reaction matrix R at the rest
        normals (``fem.ContactPatch.reaction_matrix`` of the method), what the bonded and
        sticking laws' forces ``R U`` and the traction model read; the Coulomb law has
        its contact solve instead, and never forms it (an inverse of C + D)."""
        return np.asarray(self.patch.reaction_matrix(self.method))

    @cached_property
    def distribution(self) -> np.ndarray:
        """(3p, 6L) float: ``D = R G A^-1``, each print's W spread over its nodes as a
        rigid motion of them loads them (independent of E); the traction model's."""
        return self.reaction @ self.basis @ self.a_inverse

    @cached_property
    def _labels(self) -> dict:
        """Row labels that do not change between linearisations, by block (made once)."""
        name = self.deformable_object.name
        resultant = tuple(f"friction cone of the resultant of {spec.label} ({s})" for spec in self.prints for s in PYRAMID_SIDES)
        if self.law == "coulomb":
            node_contact = resultant
        else:
            node_contact = tuple(f"no adhesion at node {n} of {name}" for n in self.node_ids) + (
                tuple(f"friction cone at node {n} of {name} ({s})" for n in self.node_ids for s in PYRAMID_SIDES)
                if self.law == "sticking" else resultant
            )
        return {
            "placement": tuple(
                f"placement of {spec.label} ({axis}, elastic)"
                for spec in self.prints
                for axis in ("x", "y", "z", "roll", "pitch", "yaw")
            ),
            "touch": tuple(f"contact of {spec.label} (lifted off its print)" for spec in self.prints),
            "corners": tuple(
                f"contact of {self.prints[i].label} (corner {j} {PIVOTING_ROW})"
                for i in np.unique(self._corner_print) for j in range(int(np.sum(self._corner_print == i)))
            ),
            "resultant": resultant,
            "tilt": tuple(
                f"tilt of the face of {self.prints[i].label} ({np.degrees(self.tilt_allowances[i]):.3g} degrees at "
                "most, tilt_allowance)" for i in self._tilted_prints
            ),
            "pressure": tuple(
                f"centre of pressure of {self.prints[i].label} (past edge {k} of its outline)"
                for i in np.unique(self._pressure_print) for k in range(int(np.sum(self._pressure_print == i)))
            ),
            "node contact": node_contact,
            "indentation": tuple(f"indentation bound at node {n} of {name}" for n in self.node_ids),
            # (The option named: a user's stance failed on this row among others, and only
            # a larger max_mesh_overlap was seen to carry it.)
            "overlap": tuple(f"mesh overlap bound ({self.max_mesh_overlap:g} m, max_mesh_overlap) at node {n} of {name}"
                             for n in self.node_ids),
        }

    def _resultant_rows(self, forces, d_forces):
        """Each print's resultant inside its friction pyramid, mu (its nodes', narrowed by the
        print's tilt allowance) scaled by ``friction_margin``
        (4 rows each, labels ``_labels["resultant"]``); jacobians None when ``d_forces``
        (p, 3, columns) is."""
        values, jacobians = [], []
        for i in range(len(self.prints)):
            rows = self.print_of_node == i
            rotation = self.print_placements[i].rotation
            mu = self.friction_margin * self.print_mu[i]
            face = pyramid_faces(rotation[:, 2][None], rotation[:, :2].T[None], [mu])[0]  # (4, 3)
            values.append(face @ forces[rows].sum(axis=0))
            if d_forces is not None:
                jacobians.append(face @ d_forces[rows].sum(axis=0))
        return np.concatenate(values), np.vstack(jacobians) if d_forces is not None else None

    @cached_property
    def _rest_centres(self):
        """Tets whose ball mean the body's own weight alone strains to a quarter of the
        bound or more, within a print's width of the tets touching the prints, (n,)
        sorted ids, or None. The strain rows read them as well as the tets next to the
        prints: a print's strain, smaller there, can take them over the bound
        (step-on-cube's cube with a 0.3 % bound: 0.35 % at 16 cm under the sole's edge,
        by the free side face, where the weight gives 0.16 %). Farther away a print's
        strain has fallen to a fraction of its peak (Boussinesq: about a quarter two
        radii down), and rows there would only cost: the base of hand-on-soft-cube's
        1 m cube, 2.4 % under its weight, is 16,821 such tets (0.32 -> 0.97 s a solve)."""
        tets = self.deformable_object.strained_at_rest(_REST_STRAIN * self.strain_limit)
        if tets.size == 0:
            return None
        body = self.deformable_object.body
        averages = body.strain_averages
        nodes = body.mesh.nodes[self.node_ids]
        width = max(float(np.linalg.norm(np.ptp(nodes[self.print_of_node == i], axis=0))) for i in range(len(self.prints)))
        distance, _ = scipy.spatial.cKDTree(averages.centroids[self.patch.neighbour_tets]).query(
            averages.centroids[tets], distance_upper_bound=width)
        tets = tets[np.isfinite(distance)]
        return tets if tets.size else None

    @property
    def _row_also(self):
        """The strain rows' centres beyond the prints' neighbourhood, (n,) sorted tet ids
        or None: the weight's (:attr:`_rest_centres`) and those verify found strained
        beyond the bound outside the rows (:meth:`take_strain_outlier`)."""
        return self._rest_centres if self._found_centres is None else self._found_centres

    def take_strain_outlier(self) -> bool:
        """Make the tets around the last verify's strain failure strain-row centres, if
        it lay outside the rows; True if it did (the SQP then goes on from its answer).

        The rows cover the tets near the prints and where the body's own weight strains
        it to a quarter of its bound within a print's width of them; the largest strain
        can still sit elsewhere (a base corner the weight already strains to 90 % of
        the bound, a print's strain small there): verify, which looks at every tet,
        finds it, and the rows read it from then on.
        """
        tet, self._strain_outlier = self._strain_outlier, None
        if tet is None:
            return False
        body = self.deformable_object.body
        around = body.strain_averages.near([tet], 2.0 * self.strain_radius)
        current = self._row_also
        self._found_centres = around if current is None else np.union1d(current, around)
        self.__dict__.pop("_weight_strains", None)  # read at the new centres
        return True

    @cached_property
    def _weight_strains(self):
        """(T', 6) ball-mean strains of the body's own weight at the strain rows' centres
        (the scene is meshed as the body rests, so the weight moves no print force but
        its strain adds to theirs); None for a weightless body."""
        weight = self.deformable_object.self_weight_field
        return self.patch.field_strains(weight, self.strain_radius, self._row_also) if weight.any() else None

    def _strain_block(self, u, d_u, columns, per="displacement"):
        """Largest and smallest principal strains of the most strained tets near the prints.

        ``u`` (3p,) are the body's print-node displacements (``per="displacement"``) or
        the loads on its print nodes (``per="load"``: forces ON the body, body frame),
        ``d_u`` (3p, columns) their derivative in the step (None: values only).
        """
        if self.max_strain_rows == 0:
            return None
        # The Frobenius norm of a strain tensor bounds its principal strains: the
        # centres whose ball mean is below the activation by that norm are left out of
        # the (costly) eigendecomposition, which is per tet, so the others' answers are
        # unchanged; the patch averages only where a bound on that norm reaches it.
        floor = (1.0 - 1e-9) * _STRAIN_ACTIVATION * self.strain_limit
        near, voigt = self.patch.strained_centres(
            u, floor, self.strain_radius, self._row_also, per=per, offset=self._weight_strains)  # (k,), (k, 6) ball means
        kept = np.flatnonzero(fem.frobenius_norms(voigt) >= floor)
        if kept.size == 0:
            return None
        screened, voigt = near[kept], voigt[kept]
        values, vectors = np.linalg.eigh(fem.voigt_to_tensor_strain(voigt))
        largest, smallest = values[:, 2], values[:, 0]
        ratio = np.maximum(largest, -smallest) / self.strain_limit
        candidates = np.flatnonzero(ratio >= _STRAIN_ACTIVATION)  # indices into screened
        if candidates.size == 0:
            return None
        chosen = candidates[np.argsort(-ratio[candidates], kind="stable")][: self.max_strain_rows]
        tets = self.patch.strain_centres(self.strain_radius, self._row_also)
        rows_value, rows_jacobian, lower, upper, labels = [], [], [], [], []
        for k, t in zip(chosen.tolist(), screened[chosen].tolist()):
            for which, bound_lower, bound_upper, name in ((2, -np.inf, self.strain_limit, "stretch"),
                                                          (0, -self.strain_limit, np.inf, "compression")):
                if d_u is not None:
                    v = vectors[k, :, which]
                    # d lambda = v^T dE v; Voigt with engineering shears.
                    weights = np.array([v[0] ** 2, v[1] ** 2, v[2] ** 2, v[0] * v[1], v[0] * v[2], v[1] * v[2]])
                    rows_jacobian.append(
                        self.patch.neighbour_strain_row(weights, t, self.strain_radius, self._row_also, per=per) @ d_u)
                rows_value.append(values[k, which])
                lower.append(bound_lower)
                upper.append(bound_upper)
                labels.append(f"strain bound ({name}) of tet {int(tets[t])} of {self.deformable_object.name}")
        return ConstraintBlock(
            "strain", np.array(rows_value), None if d_u is None else np.array(rows_jacobian), np.array(lower), np.array(upper),
            self.strain_limit, tuple(labels),
        )

    def cost(self, model, data, w, options, columns, offset, derivatives=True):
        """The prints' terms of the objective: value, gradient and Gauss-Newton Hessian
        (``(value, None, None)`` without ``derivatives``).

        - Force term: ``force_weight / 2 W^T M W``, M the rigid contact's metric
          (:func:`rigid_force_metric`), so that a stiff print weighs its load as a rigid
          one does. (A ball's W is the flat print's bonded wrench at its depth, more
          than it carries. Weighing its carried force instead, tried 2026-12-03, solved
          none of five quadruped-foam stances of which W's term solves three: that force
          is only piecewise smooth in W as nodes enter the contact.)
        - Deformation term (paper note 2): with ``deformation_cost="energy"``
          (default) the elastic energy the body stores, ``1/2 f^T C f`` (C: the
          condensed compliance of the print nodes), weighed per joule; it vanishes as
          E grows, so the posture tends to the rigid support's. ``"force"``: the
          paper's ``1/2 |f|^2`` of the nodal reactions, per N^2.
        """
        n_w = self.n_variables
        weighted = options.force_weight * (self.force_metric @ w)
        value = 0.5 * float(w @ weighted)
        gradient = hessian = None
        if derivatives:
            gradient, hessian = np.zeros(columns), np.zeros((columns, columns))
            gradient[offset : offset + n_w] = weighted
            hessian[offset : offset + n_w, offset : offset + n_w] = options.force_weight * self.force_metric
        weight = options.deformation_weight
        if weight == 0.0:
            return value, gradient, hessian
        values = self._values(model, data, w)
        forces, nodes = values.forces, values.nodes
        if options.deformation_cost == "force":
            stacked = forces.reshape(-1)
            value = value + 0.5 * weight * float(stacked @ stacked)
        else:
            # C f: the print nodes' displacement under the forces, body frame, negated
            # (``nodes`` is -C f_body except under the traction model, which has no compliance form).
            forces_body = forces @ self.rotation_body
            compliant = self.patch.compliance @ forces_body.reshape(-1) if self.method == "traction" else -nodes
            value = value + 0.5 * weight * float(forces_body.reshape(-1) @ compliant)
        if not derivatives:
            return value, None, None
        # Derivatives in the columns the forces move with (q, then this contact's W),
        # not across the whole step.
        _, _, _, d_forces_dq, d_forces_dw, _, d_nodes = self._state(model, data, w)
        jacobian = np.hstack([d_forces_dq, d_forces_dw])  # (3p, nv + 6L), world
        if options.deformation_cost == "force":
            term_gradient, term_hessian = jacobian.T @ stacked, jacobian.T @ jacobian
        else:
            jacobian_body = self._body_rows(jacobian)
            d_compliant = self.patch.compliance @ jacobian_body if self.method == "traction" else -d_nodes
            term_gradient = jacobian_body.T @ compliant
            term_hessian = 0.5 * (jacobian_body.T @ d_compliant + d_compliant.T @ jacobian_body)
        moved = np.r_[0 : model.nv, offset : offset + n_w]
        gradient[moved] += weight * term_gradient
        hessian[np.ix_(moved, moved)] += weight * term_hessian
        return value, gradient, hessian

    def _body_rows(self, rows: np.ndarray) -> np.ndarray:
        """Stacked per-node world 3-vectors' rows (3p, m) turned into the body frame."""
        return np.einsum("ji,pjm->pim", self.rotation_body, rows.reshape(-1, 3, rows.shape[1])).reshape(rows.shape)

    def displacement_field(self, model, data, forces) -> np.ndarray:
        """Displacement of every node of the body, metres, body frame (eq. 36).

        Parameters
        ----------
        forces : (p, 3) float
            This contact's forces on the robot, world frame, newtons: the body is
            loaded by their opposite (one sparse solve). The traction model has no
            compliance form: its field is the one of the imposed print motion.

        Returns
        -------
        (N, 3) float
        """
        body = self.deformable_object.body
        if self.method == "traction":
            return np.asarray(body.displacement_field(*self.print_motion(data)))
        return body.displacement_under_loads(*self.field_loads(forces))

    def field_loads(self, forces):
        """``(node_ids, loads)``: the point loads on the body whose field is
        :meth:`displacement_field`'s (what a result keeps to draw it later, not this
        contact), or None for the traction model, whose field is its print's motion.

        Parameters
        ----------
        forces : (p, 3) float
            As :meth:`displacement_field`.

        Returns
        -------
        ((p,) int, (p, 3) float) or None
            Nodes and their loads, newtons, body frame.
        """
        if self.method == "traction":
            return None
        return self.node_ids, -(np.asarray(forces) @ self.rotation_body)

    def print_motion(self, data):
        """``(patch, displacements)``: what the traction model's field is made of, the print's
        :class:`fem.ContactPatch` and its link points' displacements (p, 3), metres, body
        frame, at the kinematics of ``data`` (what a result keeps to draw it later)."""
        return self.patch, self._displacements(data)

    # -- independent check ---------------------------------------------------
    def verify(self, model, data, points, forces, tolerances, measures, field=None, shown_slips=None) -> list:
        """Check the reported forces against a full FEM solve, node by node.

        ``consistent``: the whole body is loaded by the reported forces (one sparse
        solve of the full system, not the condensed one); the motion of each link
        point relative to its node must then obey the contact law: Signorini and
        Coulomb at every node (``coulomb``), or no relative motion at all (the
        bonded laws). ``traction``: the forces are recomputed from the link
        placement with eq. (44). Then the friction cones (per node, or of each
        print's resultant for ``bonded``), the indentation and the strain over
        every tet of the body are checked. The body's elastic energy under the
        forces is measured too (``deformation energy of <name>``, joules). ``forces`` are finite
        (:func:`stances.verify.verify_problem` refuses any other first).
        ``field``: :meth:`displacement_field` of these forces, if the caller has it
        already (computed here otherwise). ``shown_slips``: the answer's ``slips`` (robot
        surface -> NodeSlips), checked against the link points' own slips over the nodes.
        """
        name = self.deformable_object.name
        body = self.deformable_object.body
        reasons = []
        expected_points = points_in_world(data, self.loads)
        if len(points) != len(expected_points) or np.abs(points - expected_points).max() > tolerances.placement:
            return [f"forces on {name} are not applied at the print nodes' link points"]
        displacements = self._displacements(data)
        forces_body = forces @ self.rotation_body
        if self.method == "traction":
            expected = np.asarray(
                self.patch.reaction_forces(displacements, method="traction", normals=self._turned_normals(data))
            ) @ self.rotation_body.T
            error = np.abs(forces - expected).max() / max(np.abs(expected).max(), 1.0)
            measures[f"FEM force error on {name}"] = float(error)
            if error > tolerances.deformable_force:
                reasons.append(f"forces on {name} differ from the FEM reaction by {error:.3g} (relative)")
        field = self.displacement_field(model, data, forces) if field is None else field
        # Contact frames: forces and relative motions (link point minus node) as (t1, t2, n),
        # the normal the link face's (turned with it) under the Coulomb law.
        frames = self._contact_frames(data)
        phi = np.einsum("pij,pj->pi", frames, forces_body)
        # Link point minus the node's coupling end (the node itself when fully covered).
        ends = field[self.node_ids]
        if self._coupling is not None:
            ends = ends - block_diagonal_product(self._coupling, forces_body.reshape(-1)).reshape(-1, 3)
        reached = displacements + self.gaps  # where each link point's surface over its node has moved
        # The law reads each node's motion from where its link held it (its held slip, fixed
        # in the link and turned with it; none from rest), the small-slip bound the whole slip.
        whole = reached - ends
        turns = self._face_turns(data)
        relative = np.einsum("pij,pj->pi", frames, whole - self._turned_held(turns))
        slide = np.linalg.norm(np.einsum("pij,pj->pi", frames, whole)[:, :2], axis=1)
        if self.law == "coulomb" and shown_slips is not None:
            reasons.extend(self._check_shown_slips(self._as_slips(whole, turns), shown_slips, tolerances, measures))
        # How far the mesh itself reaches past the links' faces, along the print normal: a
        # partly covered node lies its cell's series compliance times its force (D f)
        # behind its link point, at the print's edge on a coarse mesh (the contact law holds
        # at the coupling's end): bounded by max_mesh_overlap (unbounded, independent audits
        # found 2.8 mm on hand-on-soft-cube's palm on 2026-11-26; 3.6 mm there and 5.2 mm on
        # the paper's coarse cube, 4 nodes under the palm, on 2026-12-03).
        overlap = -np.einsum("pij,pj->pi", self.node_frames, reached - field[self.node_ids])[:, 2]
        measures[f"mesh overlap into the links on {name}"] = float(overlap.max())
        if overlap.max() > self.max_mesh_overlap + tolerances.deformable_placement:
            node = int(self.node_ids[int(np.argmax(overlap))])
            reasons.append(
                f"node {node} of {name} reaches {overlap.max():.3g} m into its link, beyond the mesh overlap "
                f"bound {self.max_mesh_overlap:g} m (max_mesh_overlap)"
            )
        if self.law == "coulomb":
            reasons.extend(self._check_corners(reached, tolerances, measures))
        reasons.extend(self._check_centres_of_pressure(forces, tolerances, measures))
        reasons.extend(self.unpressed(forces, tolerances.pressure_fit, measures=measures))
        measures[f"smallest node normal force on {name}"] = float(phi[:, 2].min())
        if phi[:, 2].min() < -tolerances.cone:
            node = int(self.node_ids[int(np.argmin(phi[:, 2]))])
            reasons.append(f"node {node} of {name} pulls on the robot ({phi[:, 2].min():.3g} N): adhesion")
        if self.method != "traction":
            if self.law == "coulomb":
                reasons.extend(self._check_coulomb(phi, relative, slide, tolerances, measures))
            else:
                mismatch = float(np.abs(relative).max())
                measures[f"print mismatch on {name}"] = mismatch
                if mismatch > tolerances.deformable_placement:
                    reasons.append(
                        f"under the reported forces, the full FEM model of {name} leaves a print node "
                        f"{mismatch:.3g} m off its link (the nodes are bonded)"
                    )
        reasons.extend(self._check_cones(forces, frames[:, 2] @ self.rotation_body.T, tolerances, measures))
        reasons.extend(self._check_face_cones(data, forces, tolerances, measures))
        reasons.extend(self._check_balls(points, phi[:, 2], measures, tolerances))
        depth = float((-np.einsum("pj,pj->p", field[self.node_ids], self.normals_in_body)).max())
        measures[f"indentation of {name}"] = depth
        # Elastic energy stored in the body, joules: by Clapeyron's theorem 1/2 F.U over
        # the loaded nodes equals 1/2 U^T K U, the bilinear form of eq. (6) at w = u
        # (>= 0; exact for the consistent forces). The planner's terrain cost reads it.
        measures[f"deformation energy of {name}"] = float(0.5 * np.sum(-forces_body * field[self.node_ids]))
        if depth > self.max_indentation + tolerances.deformable_placement:
            reasons.append(f"a node of {name} is indented {depth:.3g} m, beyond its bound {self.max_indentation:.3g} m")
        # The body holds its own weight's strain at rest (the scene is meshed as it rests).
        strain, tet = body.largest_principal_strain(field + self.deformable_object.self_weight_field, self.strain_radius)
        measures[f"largest strain of {name}"] = strain
        self._strain_outlier = None
        if strain > self.strain_limit + 1e-6:
            if tet not in self.patch.strain_centres(self.strain_radius, self._row_also):
                self._strain_outlier = tet
            centre = self.deformable_object.points_in_world(body.mesh.nodes[body.mesh.tets[tet]].mean(axis=0)[None])[0]
            reasons.append(
                f"strain {strain:.3g} of {name} (its own weight's included) at ({centre[0]:.3f}, {centre[1]:.3f}, {centre[2]:.3f}) m "
                f"(mean over {1e3 * self.strain_radius:g} mm) exceeds its bound {self.strain_limit:g}: linear "
                "elasticity does not hold there"
            )
        return reasons

    def _check_centres_of_pressure(self, forces, tolerances, measures) -> list:
        """Each polygon print's centre of pressure inside its outline (measured: the least
        margin, metres, over the body's prints; a print pressing less than a tenth of a
        newton has none)."""
        if not len(self._pressure_print):
            return []
        moments = self._pressure_rows @ np.asarray(forces, dtype=float).reshape(-1)
        reasons, margins = [], []
        for i in np.unique(self._pressure_print):
            rows = self._pressure_print == i
            normal = float(self.print_placements[i].rotation[:, 2] @ forces[self.print_of_node == i].sum(axis=0))
            if normal <= 0.0:
                continue
            least = float(moments[rows].min())  # N m, about the nearest edge
            margin = least / normal  # metres inside the nearest edge
            if normal * tolerances.deformable_placement > _MOMENT_TOLERANCE:
                # A print carrying under a tenth of a newton has no centre of pressure worth a
                # number: its moments are the solver's rounding (-3.9 mm was reported for a palm
                # carrying next to nothing on a verified answer).
                margins.append(margin)
            # Past the edge by more than the placement tolerance, and by more than ten times
            # the solver's own tolerance on the rows' moments (1e-7 N m): a print carrying a
            # tenth of a newton on its bound is no refusal.
            if least < -max(tolerances.deformable_placement * normal, _MOMENT_TOLERANCE):
                reasons.append(
                    f"the centre of pressure of {self.prints[i].label} lies {-margin:.3g} m past its outline's "
                    "edge: its partly covered nodes' forces, past the edge, carry a moment no pressure under "
                    f"{self.print_surfaces[i]} could"
                )
        if margins:
            measures[f"centre of pressure margin on {self.deformable_object.name}"] = min(margins)
        return reasons

    def _check_corners(self, reached, tolerances, measures) -> list:
        """Whether each polygon print presses with its whole face: each corner sunk at
        least ``corner_sinking`` of its print's corners' mean sinking, less
        ``max_corner_lift`` (``reached``: (p, 3) body frame, where each link point over a
        node has moved). Measures the highest corner and the largest shortfall."""
        if len(self._corner_print) == 0:
            return []
        heights = np.einsum("pj,pj->p", reached, self.normals_in_body)
        corners, means = self._corners @ heights, self._corner_means @ heights
        rows = corners - self.corner_sinking * means
        name = self.deformable_object.name
        worst = int(np.argmax(rows))
        measures[f"highest print corner on {name}"] = float(corners.max())
        measures[f"print corner shortfall on {name}"] = float(rows[worst])
        if rows[worst] <= self.max_corner_lift + tolerances.deformable_placement:
            return []
        return [
            f"a corner of {self.prints[self._corner_print[worst]].label} sinks {-corners[worst]:.3g} m into {name}, "
            f"less than {self.corner_sinking:g} of its print's mean sinking ({-means[worst]:.3g} m) by {rows[worst]:.3g} m, beyond "
            f"max_corner_lift {self.max_corner_lift:g} m: {PIVOTING_REFUSAL}, pressing a strip narrower "
            "than the mesh resolves (no converged force: palms on their edge came 7-16 % below a converged mesh's; "
            "corner_sinking)"
        ]

    def _check_balls(self, points, normal, measures, tolerances) -> list:
        """Whether each ball foot's force is one a converged mesh would give
        (``ball_force_error``, :class:`~stances.problem.PostureOptions`): within that of the
        continuum's estimate (:meth:`_estimate_ball_forces`). A ball sunk into the body where
        there is no estimate is refused, however many nodes it presses: a node contact's
        force is no converged one (9-74 pressed nodes: up to +10 % off the continuum,
        ``bench/results/ball_node_contact.md``). Measures both; ``inf`` accepts every ball,
        one without an estimate or pressing few nodes logged once a body and process.
        ``points`` (p, 3): the link points, world; ``normal`` (p,): the nodes' normal forces,
        newtons; ``tolerances``: a ball sunk less than their ``deformable_placement`` rests
        on the body (no contact to judge), whatever it carries: on a steel-stiff body a ball
        with no estimate is accepted so (1e10 Pa, 0.14 um on one node)."""
        self._count_pressed_nodes(normal, measures)
        self._estimate_ball_forces(points, normal, measures)
        reasons, name = [], self.deformable_object.name
        for index in self.point_prints.tolist():
            label = self.prints[index].label
            count = measures[f"pressed nodes under {label}"]
            error = measures.get(f"ball force error under {label}")
            if error is not None:
                if abs(error) > self.ball_force_error:
                    reasons.append(
                        f"the force under {label} is {error:+.1%} off a continuous layer's at its sinking "
                        f"({measures[f'ball force estimate under {label}']:.4g} N; ball_force_error "
                        f"{self.ball_force_error:g}): its contact on {name} is smaller than the mesh resolves; refine "
                        f"the mesh where balls land (a finer soft_box resolution: refine_lines bands stay up to +10 % "
                        f"stiff), {_BALL_ADVICE}")
                elif not np.isfinite(self.ball_force_error) and 0 < count < RESOLVED_BALL_NODES:
                    self._log_unjudged_ball(
                        "%s presses %d mesh node(s) of %r: a ball contact smaller than the cells, whose force depends on "
                        "where the ball stands against the nodes (1-5 nodes: -46 %% to +31 %% of a converged mesh's; the "
                        "verification's 'ball force error under <print>' compares it with a continuous layer's), "
                        "accepted (ball_force_error inf)", label, count)
                continue
            sinking = self._ball_sinking(points, index)
            if sinking <= tolerances.deformable_placement:
                continue
            if np.isfinite(self.ball_force_error):
                reasons.append(
                    f"{label} presses {count} mesh node(s) of {name}, sunk {sinking:.3g} m, where no continuum "
                    f"estimate of a ball's force exists ({name} is no layer held on its base under it, or the ball "
                    "is too near its sides or too deep for the layer's law): the mesh's node contact does not resolve "
                    "a ball's contact, whatever the nodes it presses (9-74: up to +10 % off a converged force); "
                    f"{_BALL_ADVICE}")
            else:
                self._log_unjudged_ball(
                    "%s presses %d mesh node(s) of %r with no continuum estimate of its force: a node contact, up to "
                    "+10 %% off a converged force whatever the nodes it presses (fewer than 9: -46 %% to +31 %%), "
                    "accepted (ball_force_error inf)", label, count)
        return reasons

    def balls_refused_anyway(self, least_loads, placement: float) -> list:
        """Why verification would refuse balls of this body whatever the posture (``[]``: none):
        a ball where no continuum estimate of its force exists (:meth:`_layer_under` is None
        under it) and that carries at least its least load sinks past ``placement``, which
        :meth:`_check_balls` refuses (``ball_force_error`` finite).

        A lower bound of its sinking: a loaded ball touches a node, so it sinks at least the
        nearest node's gap ``g``; past it, with ``k`` the stiffness along the print's normal
        of a punch bonding every node it may touch (from their compliance), Cauchy-Schwarz in
        the stiffness's inner product bounds its load by ``sqrt(k f.u)``, and the work its
        frictionless nodes do, ``f.u``, by ``F (d - g)``: ``d >= g + F / k``. A ball is refused
        where that bound exceeds :data:`_REFUSED_SINKING` times ``placement``. Not proven:
        friction (a sticking node's sideways work, with the ball held over its print) and the
        other prints on the body, whose loads can lift the surface under the ball (a review
        measured up to 2e-7 m per newton on a thin 0.49 layer, about 1 % of the loaded ball's
        own sinking). ANYmal's 30 N on a soft step's 3e6 Pa tread: 4.48 mm of bound (4.4 of them the
        nearest node's gap), where it sank 4.6 mm.

        Parameters
        ----------
        least_loads : sequence of float
            Each print's least normal load, newtons (:func:`stances.problem.min_normal_load`).
        placement : float
            Metres a ball may sink and still rest on the body (verify's ``deformable_placement``).
        """
        reasons, name = [], self.deformable_object.name
        gaps = np.einsum("pj,pj->p", self.gaps, self.normals_in_body)
        for index in self.point_prints.tolist():
            if least_loads[index] <= 0.0 or self._layer_under(index) is not None:
                continue
            rows = np.flatnonzero(self.print_of_node == index)
            dofs = (3 * rows[:, None] + np.arange(3)).ravel()
            normals = self.normals_in_body[rows].reshape(-1)
            with single_threaded_blas():
                stiffness = float(normals @ np.linalg.solve(self.patch.link_compliance[np.ix_(dofs, dofs)], normals))
            sinking = float(gaps[rows].min()) + least_loads[index] / stiffness
            if sinking > _REFUSED_SINKING * placement:
                reasons.append(
                    f"{self.prints[index].label} carries at least {least_loads[index]:.3g} N on {name}, where no "
                    f"continuum estimate of a ball's force exists ({name} is no layer held on its base under it, or "
                    f"the ball is too near its sides): it sinks at least {sinking:.3g} m, and the mesh's node "
                    f"contact does not resolve a ball's contact, whatever the nodes it presses; {_BALL_ADVICE}")
        return reasons

    def _log_unjudged_ball(self, message: str, label: str, count: int) -> None:
        """Log ``message`` (a format of the ball's ``label`` and ``count`` of pressed nodes,
        then the body's name) once a body and process: a ball ``ball_force_error=inf``
        accepted that the default tolerance would judge."""
        body = id(self.deformable_object.body)
        if body not in _COARSE_BALLS_LOGGED:
            _COARSE_BALLS_LOGGED.add(body)
            logger.warning(message, label, count, self.deformable_object.name)

    def _count_pressed_nodes(self, normal, measures) -> None:
        """``pressed nodes under <print>`` of each ball foot: its nodes carrying more than a
        thousandth of its largest node force, from (p,) node normal forces, newtons."""
        for index in self.point_prints.tolist():
            pushed = normal[self.print_of_node == index]
            count = int(np.count_nonzero(pushed > 1e-3 * pushed.max())) if pushed.max() > 0.0 else 0
            measures[f"pressed nodes under {self.prints[index].label}"] = count

    def _estimate_ball_forces(self, points, normal, measures) -> None:
        """``ball force estimate under <print>`` (newtons) and ``ball force error under
        <print>`` (the mesh's over it, less 1) of each ball foot pressed into a layer: the
        continuum's frictionless force at the ball's depth (:func:`fem.sphere_on_layer_force`),
        an independent estimate of what a mesh fine enough would give. Only where its
        formula holds (:meth:`_layer_under`: a layer held on its base, the print on the far
        face a sixth of the thickness inside its sides, whose softening the estimate counts)
        and the contact is within :func:`fem.layer_contact.widest_contact` and the sides'
        :func:`fem.layer_contact.side_contact_limit` (within 0.8 % of independent FEMs there
        beside one side, 1.4 % in a corner). Never raises: a ball sunk past what the formula
        takes gets none."""
        material = self.deformable_object.body.material
        for index in self.point_prints.tolist():
            site = self._layer_under(index)
            if site is None:
                continue
            thickness, sides = site
            widest = min(widest_contact(self.ball_radii[index], thickness), side_contact_limit(thickness, sides))
            rows = self.print_of_node == index
            sinking = self._ball_sinking(points, index)
            radius = self.ball_radii[index]
            # Hertz's contact radius sqrt(R d) is under the layer's: past the share, no estimate.
            if not 0.0 < sinking < radius or np.sqrt(radius * sinking) > widest:
                continue
            estimate, contact = fem.sphere_on_layer_force(sinking, radius, thickness, material.young_modulus,
                                                          material.poisson_ratio, sides)
            if contact > widest:
                continue
            label = self.prints[index].label
            measures[f"ball force estimate under {label}"] = estimate
            measures[f"ball force error under {label}"] = float(normal[rows].sum()) / estimate - 1.0

    def _ball_sinking(self, points, index: int) -> float:
        """How far point print ``index``'s ball has sunk below where it rests on the body, metres,
        along its print's normal, from the (p, 3) link points (world; a ball's all its centre)."""
        rows = self.print_of_node == index
        return float((self.link_points_at_rest[rows][0] - points[rows][0]) @ self.print_placements[index].rotation[:, 2])

    def _layer_under(self, index: int):
        """The body's thickness and side distances under point print ``index`` if the body is
        a layer held on its base there, else None (:func:`stances.layer_ball.layer_under`; kept)."""
        if index not in self._layers:
            self._layers[index] = layer_under(self.deformable_object, self.print_placements[index].homogeneous,
                                              self.ball_radii[index])
        return self._layers[index]

    def _check_shown_slips(self, made, shown, tolerances, measures) -> list:
        """The slips an answer shows (``shown``: robot surface -> NodeSlips) against its link
        points' own over its nodes (``made``, :meth:`_as_slips` of the checked field): the
        next stance of a sequence starts from them. Every flat print's are shown."""
        reasons, worst = [], 0.0
        for index, spec in enumerate(self.prints):
            if index in self.ball_radii:
                continue
            given, own = shown.get(spec.robot_surface), made[spec.robot_surface]
            if given is None:
                reasons.append(f"the answer shows no slips for {spec.label}, which the next stance would start from")
                continue
            if given.body != own.body or not np.array_equal(given.nodes, own.nodes):
                reasons.append(f"the slips shown for {spec.label} are not over its print's nodes")
                continue
            error = float(np.abs(given.slips - own.slips).max(initial=0.0))
            worst = max(worst, error)
            if error > tolerances.deformable_placement:
                reasons.append(f"the slips shown for {spec.label} are off its link points' by {error:.3g} m")
        measures[f"slip error on {self.deformable_object.name}"] = worst
        return reasons

    def _check_coulomb(self, phi, relative, slide, tolerances, measures) -> list:
        """Signorini and Coulomb at every node, from forces and relative motions in node frames
        (from the held slips), and the small-slip bound on the whole slips ``slide`` (p,)."""
        name = self.deformable_object.name
        gap_tolerance, force_tolerance = tolerances.deformable_placement, tolerances.cone
        reasons = []
        penetration = -relative[:, 2]
        measures[f"deepest penetration into {name}"] = float(penetration.max())
        if penetration.max() > gap_tolerance:
            node = int(self.node_ids[int(np.argmax(penetration))])
            reasons.append(f"a link point sinks {penetration.max():.3g} m into {name} at node {node}")
        measures[f"largest slip on {name}"] = float(slide.max())
        if slide.max() > self.max_slip + gap_tolerance:
            node = int(self.node_ids[int(np.argmax(slide))])
            reasons.append(
                f"a link point slides {slide.max():.3g} m over node {node} of {name}, beyond the small-slip bound "
                f"{self.max_slip:g} m: the link would then touch other nodes than its print's"
            )
        pressed = phi[:, 2] > force_tolerance
        open_gap = np.where(pressed, relative[:, 2], 0.0)
        if np.abs(open_gap).max() > gap_tolerance:
            node = int(self.node_ids[int(np.argmax(np.abs(open_gap)))])
            reasons.append(f"node {node} of {name} pushes across a gap of {np.abs(open_gap).max():.3g} m")
        # Coulomb, isotropic: a node inside its cone sticks; a node that slips has
        # its friction on the bound, exactly against its slip (maximum dissipation).
        bound = self.node_mu * np.maximum(phi[:, 2], 0.0)
        friction = phi[:, :2]
        tangential = relative[:, :2]
        size = np.linalg.norm(friction, axis=1)
        slip = np.linalg.norm(tangential, axis=1)
        sticking = pressed & (size < bound - force_tolerance)
        stuck_slip = np.where(sticking, slip, 0.0)
        if stuck_slip.max() > gap_tolerance:
            node = int(self.node_ids[int(np.argmax(stuck_slip))])
            reasons.append(f"node {node} of {name} slips {stuck_slip.max():.3g} m while its force is inside the cone")
        moving = slip > gap_tolerance
        against = -tangential / np.where(moving, slip, 1.0)[:, None]
        expected = np.where(np.isfinite(bound), bound, 0.0)[:, None] * against
        wrong = np.where(moving & np.isfinite(bound), np.linalg.norm(friction - expected, axis=1), 0.0)
        measures[f"largest friction error of slipping nodes on {name}"] = float(wrong.max(initial=0.0))
        # The motions are known to gap_tolerance, so a slip s is known in direction
        # to about gap_tolerance / s radians: the friction may turn that much.
        allowed = force_tolerance + bound * gap_tolerance / np.where(moving, slip, 1.0)
        excess = np.where(moving & np.isfinite(bound), wrong - allowed, 0.0)
        if excess.max(initial=0.0) > 0.0:
            node = int(np.argmax(excess))
            reasons.append(
                f"friction at node {int(self.node_ids[node])} of {name} is not mu f_n against its slip "
                f"(off by {wrong[node]:.3g} N: {size[node]:.3g} N, bound {bound[node]:.3g} N, slip {slip[node]:.3g} m)"
            )
        return reasons

    def _check_face_cones(self, data, forces, tolerances, measures) -> list:
        """Each node of a print with a tilt allowance in its cone about the face that presses
        it (the link's, turned), with the surface's own friction; measures the largest tilt
        and the least such margin."""
        if not len(self._tilted_prints):
            return []
        name = self.deformable_object.name
        tilts = self._tilts(data)
        measures[f"largest face tilt on {name}"] = float(tilts.max())
        reasons, margins = [], []
        for row, i in enumerate(self._tilted_prints):
            rows = np.flatnonzero(self.print_of_node == i)
            face = data.oMf[self.frame_ids[i]].rotation[:, 2]
            normal, tangential, margin = _cone_margins(forces[rows], face, self.friction[i])
            margins.append(margin.min())
            worst = int(np.argmin(margin))
            if margin[worst] < -tolerances.cone:
                reasons.append(
                    f"node {int(self.node_ids[rows[worst]])} of {name} leaves its friction cone about the face of "
                    f"{self.prints[i].label}, turned {np.degrees(tilts[row]):.3g} degrees, by {-margin[worst]:.3g} N "
                    f"(tangential {tangential[worst]:.3g} N, normal {normal[worst]:.3g} N, mu {self.friction[i]:g})"
                )
        measures[f"face cone margin on {name}"] = float(min(margins))
        return reasons

    def _check_cones(self, forces, normals, tolerances, measures) -> list:
        """Exact Coulomb cones: per node about its contact normal (``normals``, (p, 3) world),
        or (``bonded``) of each print's resultant."""
        name = self.deformable_object.name
        if self.law == "bonded":
            totals = np.array([forces[self.print_of_node == i].sum(axis=0) for i in range(len(self.prints))])
            normals = np.array([placement.rotation[:, 2] for placement in self.print_placements])
            mu = np.asarray(self.friction, dtype=float)
            what = [f"the resultant of {spec.label}" for spec in self.prints]
        else:
            # All nodes at once (a python loop over them cost 0.6 ms a soft check).
            totals, mu = forces, self.node_mu
            what = [f"node {int(n)} of {name}" for n in self.node_ids]
        normal_part, tangential, margins = _cone_margins(totals, normals, mu)
        # fmin: a node of infinite friction with no normal force (inf * 0) has no margin, as before.
        measures[f"cone margin on {name}"] = float(np.fmin.reduce(margins, initial=np.inf))
        return [
            f"{what[i]} leaves its friction cone by {-margins[i]:.3g} N "
            f"(tangential {tangential[i]:.3g} N, normal {normal_part[i]:.3g} N, mu {mu[i]:g})"
            for i in np.flatnonzero(margins < -tolerances.cone).tolist()
        ]


def _exp_derivatives(theta, step=1e-5):
    """First and second derivatives of ``R = exp(theta)`` in the rotation vector, per row of
    ``theta`` (L, 3): ``(L, 3, 3, 3)`` with ``[l, j] = dR / dtheta_j = R [Jr e_j]x`` (exact),
    and ``(L, 3, 3, 3, 3)`` with ``[l, j, k]`` the second derivative, by central
    differences of the first (step 1e-5 rad: error about 1e-10 of R's scale)."""
    def first(t):
        rotation, right = pin.exp3(t), pin.Jexp3(t)
        return np.array([rotation @ skew for skew in _skew_rows(right.T)])

    d = np.array([first(t) for t in theta])
    dd = np.array([[(first(t + step * e) - first(t - step * e)) / (2.0 * step) for e in np.eye(3)] for t in theta])
    # dd[l, k, j] = d/dtheta_k (dR/dtheta_j): symmetric in (j, k) to the differences' error
    dd = 0.5 * (dd + dd.transpose(0, 2, 1, 3, 4))
    return d, dd
