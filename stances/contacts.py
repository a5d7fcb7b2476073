"""Rigid contacts: a robot surface held on a print, pushed by friction-cone forces.

A rigid contact fixes the robot surface frame onto the print frame (6
equalities) and applies, at each vertex of the robot surface polygon, a force
that is a non-negative combination of the edges of a linearised friction cone
(paper ref. [1]): the unknowns ``lambda`` of eq. (45). The force directions
are fixed in the world (they belong to the print); the application points move
with the link.

A point foot (:class:`PointContact`), a ball of radius r centred on its contact
frame, rests on the print with 3 equalities (its centre r above the print
origin along the print normal; the foot turns freely) and one friction pyramid.
Its force is applied at the ball's centre, a point fixed on the link: the
friction's moment about the centre, ``r n x f_t`` (at most ``r mu f_n``), is
left out, as point-foot models usually do.

Every contact model (this one and :mod:`stances.deformable`) offers the same
small interface to the problem builder:

- ``loads``: a :class:`~stances.statics.PointLoads` (where forces act);
- ``deformable_object``: the soft body it presses (its field, strain and checks), or None;
- ``load_frames``: the robot frame each load acts on;
- ``n_variables`` and ``variable_lower``: its force variables and their lower bounds;
- ``forces(model, data, lam)``: (k, 3) world forces at the current iterate;
- ``force_jacobians(model, data, lam)``: their derivatives in q and its variables;
- ``force_curvature(model, data, lam)``: their curvature in its variables at fixed q
  (``weights (3k,) -> (n, n)``), or None where they are linear in them;
- ``blocks(model, data, lam, columns, offset, derivatives=True)``: its own
  constraint rows (its variables start at column ``offset``; without
  derivatives, values only: ``jacobian`` None);
- ``cost(model, data, lam, options, columns, offset, derivatives=True)``: its
  objective term ``(value, gradient, Hessian)`` (without derivatives
  ``(value, None, None)``), or None;
- ``verify(...)``: its independent checks.
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin

from environments.errors import SceneError
from environments.geometry import signed_edge_distances, validate_convex_polygon
from fem.prints import clip_polygon

from .blocks import PLACEMENT_ACCURACY, ConstraintBlock, equality
from .curvature import frame_curvature
from .errors import StanceError
from .statics import PointLoads, points_in_world

_SAME_POINT = 1e-9  # metres: clipped vertices closer than this are one


#: A friction pyramid's faces (:func:`pyramid_faces`): the signs (s1, s2) of their tangential
#: parts, and their labels.
PYRAMID_SIGNS = np.array([[1.0, 1.0], [-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0]])
PYRAMID_SIDES = ("+x+y", "-x-y", "-x+y", "+x-y")
_DIAGONALS = PYRAMID_SIGNS / np.sqrt(2.0)


def pyramid_faces(normals, tangents, friction) -> np.ndarray:
    """(k, 4, 3) faces of friction pyramids: f inside iff every face . f >= 0.

    The rigid contacts' pyramid (:func:`friction_cone_generators`: edges ``n +- mu t1``,
    ``n +- mu t2``, on the Coulomb cone), so that a soft print on a stiff body carries the
    loads a rigid contact does. (The axis-aligned square ``|f . t_i| <= mu / sqrt(2) f . n``
    the soft prints had before, its corners on the cone, carries 71 % of that along an
    axis: with the margin of 0.8 it had, hand-on-cube's palm on the cube at E = 1e10
    pressed with 96 N where the rigid contact needs 71 N.) Faces
    ``(mu n + s1 t1 + s2 t2) / sqrt(2)``, one per sign pair (:data:`PYRAMID_SIGNS`):
    ``|f . t1| + |f . t2| <= mu f . n``.

    Parameters
    ----------
    normals : (k, 3) float
    tangents : (k, 2, 3) float
    friction : (k,) float
    """
    mu = (np.asarray(friction, dtype=float) / np.sqrt(2.0))[:, None, None]
    return mu * np.asarray(normals)[:, None, :] + np.einsum("sa,kai->ksi", _DIAGONALS, tangents)


def convex_polygon(polygon, name: str) -> np.ndarray:
    """``polygon`` (k, 2) as a read-only array, checked convex and counter-clockwise by
    :func:`environments.geometry.validate_convex_polygon`.

    Raises
    ------
    StanceError
        Naming ``name`` and what is wrong, where that check refuses it.
    """
    try:
        return validate_convex_polygon(polygon, name)
    except SceneError as error:
        raise StanceError(f"{name} is not convex and counter-clockwise: {error}") from None


def friction_cone_generators(friction: float, n_edges: int = 4) -> np.ndarray:
    """Edges of a friction pyramid inscribed in the Coulomb cone.

    Parameters
    ----------
    friction : float
        Coefficient mu.
    n_edges : int
        Number of edges (4 gives the usual pyramid).

    Returns
    -------
    (n_edges, 3) float
        Unit edge directions in the contact frame (z = surface normal). Any
        non-negative combination lies inside the cone |f_t| <= mu f_n.
    """
    return _cone_generators(float(friction), int(n_edges)).copy()


@functools.lru_cache(maxsize=64)
def _cone_generators(friction: float, n_edges: int) -> np.ndarray:
    """:func:`friction_cone_generators`, made once per coefficient (a contact per stance asks)."""
    angles = 2.0 * np.pi * np.arange(n_edges) / n_edges
    edges = np.column_stack([friction * np.cos(angles), friction * np.sin(angles), np.ones(n_edges)])
    return edges / np.linalg.norm(edges, axis=1, keepdims=True)


def placement_residual(model, data, frame_id: int, transform_print_to_world: pin.SE3):
    """Placement error of a contact frame relative to its print.

    Parameters
    ----------
    model, data : pinocchio Model and Data
        Frame placements and joint Jacobians computed at the iterate.
    frame_id : int
    transform_print_to_world : pin.SE3
        The target frame.

    Returns
    -------
    residual : (6,) float
        ``log6(print^-1 * frame)``: (translation in metres, rotation in
        radians), print frame. Zero when the frames coincide.
    jacobian : (6, nv) float
        Its derivative for a tangent step: ``Jlog6`` times the frame's local Jacobian.
    """
    error = transform_print_to_world.actInv(data.oMf[frame_id])
    residual = pin.log6(error).vector
    return residual, pin.Jlog6(error) @ pin.getFrameJacobian(model, data, frame_id, pin.LOCAL)


class RigidContact:
    """A robot surface on a rigid print.

    Parameters
    ----------
    robot : stances.Robot
    robot_surface : str
        Name of the robot contact surface.
    transform_print_to_world : (4, 4) float
        Print frame (z = outward normal of the environment surface).
    friction : float
        Friction coefficient of the environment surface.
    label : str
        Readable name used in constraint labels, e.g. ``"right_palm on table_top"``.
    surface : environments.ContactSurface, optional
        The environment surface the print lies on. The forces then act at the
        vertices of the part of the robot's polygon that lies on its polygon: a
        sole or palm hanging over an edge is held by the part over the support
        only. Verify checks, in the surface's own frame, that every force acts on it.
    reach : (m, 2) float, optional
        A convex polygon, counter-clockwise, print frame, that the forces' centre of
        pressure must lie in: where a soft print's nodes can carry them, the print held
        rigid in its body's stiff limit
        (:meth:`stances.deformable.DeformableContact.held_prints`). The forces still act
        at the polygon's vertices, so that the force term weighs them as on a rigid
        support.
    resultant_friction : float, optional
        A friction coefficient the forces' resultant must keep to (the pyramid
        ``|f . t1| + |f . t2| <= mu f . n``): a soft print's, its ``friction_margin``
        included. The vertices' own cones keep ``friction`` (their unit edges, and so the
        force term's weights, as on a rigid support).
    """

    kind = "rigid"
    application = "its surface's vertices"  # where its forces act, for messages
    deformable_object = None  # the soft body it presses: none (stances.deformable, stances.layer_ball have one)

    def __init__(self, robot, robot_surface, transform_print_to_world, friction, label, surface=None, reach=None,
                 resultant_friction=None):
        self.support_surface = surface
        surface = robot.surface(robot_surface)
        self.robot_surface = robot_surface
        self.label = label
        self.frame_id = robot.frame_id(surface.frame)
        frame = robot.model.frames[self.frame_id]
        self.print_placement = pin.SE3(np.asarray(transform_print_to_world, dtype=float))
        self.friction = float(friction)
        vertices = self._points_in_frame(surface)
        if self.support_surface is not None and not surface.is_point:
            vertices = supported_vertices(vertices, _polygon_in_print(self.support_surface, self.print_placement), label)
        self.loads = PointLoads(
            np.full(len(vertices), frame.parentJoint),
            np.array([frame.placement.act(v) for v in vertices]),
        )
        edges_in_print = friction_cone_generators(self.friction)
        edges_in_world = edges_in_print @ self.print_placement.rotation.T
        n_vertices, n_edges = len(vertices), len(edges_in_world)
        # generators: stacked forces (3k,) = generators @ lambda (k * n_edges,)
        self.generators = np.zeros((3 * n_vertices, n_vertices * n_edges))
        for i in range(n_vertices):
            self.generators[3 * i : 3 * i + 3, i * n_edges : (i + 1) * n_edges] = edges_in_world.T
        self.n_variables = n_vertices * n_edges
        self.variable_lower = np.zeros(self.n_variables)
        self.load_frames = (surface.frame,) * n_vertices
        # One print: every vertex load pushes along the print normal.
        self.print_labels = (label,)
        self.print_surfaces = (robot_surface,)  # the robot surface of each print
        self.load_prints = np.zeros(n_vertices, dtype=int)
        self.load_normals = np.tile(self.print_placement.rotation[:, 2], (n_vertices, 1))
        # Rows R lambda >= 0 of a soft print held rigid (reach, resultant_friction), and their labels.
        held = []
        if reach is not None:
            held += self._reach_rows(vertices, np.asarray(reach, dtype=float))
        if resultant_friction is not None:
            held += self._resultant_rows(float(resultant_friction))
        self.held_rows = np.array([row for row, _ in held]) if held else None
        self._held_labels = tuple(label for _, label in held)

    def _print_forces(self) -> np.ndarray:
        """(k, 3, n): each vertex's force in the print frame per variable."""
        return np.einsum("ji,kjn->kin", self.print_placement.rotation, self.generators.reshape(-1, 3, self.n_variables))

    def _reach_rows(self, vertices, reach) -> list:
        """``(row, label)`` pairs, ``row @ lambda >= 0`` iff the centre of pressure lies in ``reach``.

        Each edge ``n . x <= o`` of the reach (``n`` its outward normal) holds the centre
        of pressure ``sum f_z,i v_i / sum f_z,i`` iff ``sum_i f_z,i (o - n . v_i) >= 0``,
        ``v_i`` the vertices and ``f_z,i`` their normal forces, print frame: linear in lambda.
        """
        reach = convex_polygon(reach, f"the reach of {self.label}")
        levers = signed_edge_distances(reach, vertices[:, :2]).T  # (e, k): o - n . v_i
        rows = levers @ self._print_forces()[:, 2, :]
        return [(row, f"centre of pressure of {self.label} in its nodes' reach ({k})") for k, row in enumerate(rows)]

    def _resultant_rows(self, friction) -> list:
        """``(row, label)`` pairs, ``row @ lambda >= 0`` iff the resultant keeps ``|f . t1| + |f . t2| <= friction f . n``."""
        faces = pyramid_faces(np.array([[0.0, 0.0, 1.0]]), np.eye(3)[None, :2], [friction])[0]  # print frame
        rows = np.einsum("sj,jn->sn", faces, self._print_forces().sum(axis=0))
        return [(row, f"friction pyramid of the resultant of {self.label} ({side})") for row, side in zip(rows, PYRAMID_SIDES)]

    @staticmethod
    def _points_in_frame(surface) -> np.ndarray:
        """(k, 3) application points of the forces, contact frame: the polygon's vertices."""
        return surface.vertices_in_frame

    def forces(self, model, data, lam) -> np.ndarray:
        """(k, 3) world forces on the robot at the polygon vertices, newtons."""
        return (self.generators @ lam).reshape(-1, 3)

    def force_jacobians(self, model, data, lam):
        """Derivatives of the stacked forces: zero in q, ``generators`` in lambda."""
        return np.zeros((self.generators.shape[0], model.nv)), self.generators

    def force_curvature(self, model, data, lam):
        """The forces' curvature in this contact's variables (``weights -> (n, n)``), or None
        where they are linear in them, as here (``generators @ lambda``)."""
        return None

    def blocks(self, model, data, lam, columns, offset, derivatives=True):
        """Placement equalities (6 rows; a point foot's 3), print frame; a print held in
        its stiff limit (``reach``, ``resultant_friction``) adds its ``held print`` rows.

        Parameters
        ----------
        columns : int
            Width of the step vector (nv + m).
        offset : int
            Column of this contact's first variable (its rows do not use them).
        derivatives : bool
            False: the rows' values only (frame placements computed), ``jacobian`` None.
        """
        if derivatives:
            residual, jacobian_q = self._placement(model, data)
            jacobian = np.zeros((len(residual), columns))
            jacobian[:, : model.nv] = jacobian_q
        else:
            residual, jacobian = self._placement_residual(data), None
        labels = [f"placement of {self.label} ({axis})" for axis in self._placement_axes]
        # 1 cm / 10 mrad: the size of a placement error that matters.
        blocks = [equality("placement", residual, jacobian, 1e-2, labels, PLACEMENT_ACCURACY, self._weighted_placement,
                           self._placement_curvature)]
        if self.held_rows is not None:
            held_jacobian = None
            if derivatives:
                held_jacobian = np.zeros((len(self.held_rows), columns))
                held_jacobian[:, offset : offset + self.n_variables] = self.held_rows
            # 1e-2 (N m, N): a centre of pressure 1 mm out under 10 N, a resultant 10 mN out of its pyramid.
            blocks.append(ConstraintBlock("held print", self.held_rows @ lam, held_jacobian, 0.0, np.inf, 1e-2,
                                          self._held_labels))
        return blocks

    _placement_axes = ("x", "y", "z", "roll", "pitch", "yaw")

    def _placement(self, model, data):
        """Placement residual (6,) and its Jacobian (6, nv) at the kinematics in ``data``."""
        return placement_residual(model, data, self.frame_id, self.print_placement)

    def _placement_residual(self, data) -> np.ndarray:
        """Placement residual (6,) alone, at the frame placements in ``data``."""
        return pin.log6(self.print_placement.actInv(data.oMf[self.frame_id])).vector

    def _weighted_placement(self, model, data, weights) -> np.ndarray:
        """(nv,) ``weights @ jacobian`` of the placement rows at the kinematics in ``data``
        (their ``second_order``, see :mod:`stances.curvature`)."""
        return weights @ self._placement(model, data)[1]

    def _placement_curvature(self, model, data, weights) -> np.ndarray:
        """(nv, nv) ``sum_i weights_i d^2 r_i`` of the placement rows ``r = log6(P^-1 oMf)``
        along the joints' motions (their ``curvature``, see :mod:`stances.curvature`): the
        local gradient of ``weights . r`` is ``Jlog6(P^-1 oMf)^T weights``."""
        print_inverse = self.print_placement.inverse()
        return frame_curvature(model, data, self.frame_id, lambda placement: pin.Jlog6(print_inverse * placement).T @ weights)

    def cost(self, model, data, lam, options, columns, offset, derivatives=True):
        """No objective term of its own (lambda's is the problem's force term)."""
        return None

    def verify(self, model, data, points, forces, tolerances, measures) -> list:
        """Independent checks of this contact at a posture (see :mod:`stances.verify`).

        Parameters
        ----------
        points, forces : (k, 3) float
            Reported application points and forces, world frame.

        Returns
        -------
        list of str
            Failed checks, empty when all pass.
        """
        reasons = self._verify_placement(data, tolerances, measures)
        # The forces must act at the robot surface's vertices...
        expected = points_in_world(data, self.loads)
        if len(points) != len(expected) or np.abs(points - expected).max() > tolerances.placement:
            reasons.append(f"forces of {self.label} are not applied at {self.application}")
        # ... on the environment's surface, not past its edge ...
        rotation_print = self.print_placement.rotation
        if self.support_surface is not None and len(points):
            # In the surface's own frame, not the print's: independent of how the
            # solver placed the surface's polygon under the print.
            to_world = self.support_surface.transform_surface_to_world
            in_surface = (points - to_world[:3, 3]) @ to_world[:3, :3]
            beyond = -signed_edge_distances(self.support_surface.polygon, in_surface[:, :2]).min(axis=1)
            measures[f"support overhang of {self.label}"] = float(max(beyond.max(), 0.0))
            if beyond.max() > tolerances.placement:
                reasons.append(f"a force of {self.label} acts {beyond.max():.3g} m past the edge of its surface")
        # ... and lie in the exact Coulomb cone of the print.
        local = forces @ rotation_print
        normal = local[:, 2]
        tangential = np.linalg.norm(local[:, :2], axis=1)
        margin = np.minimum(normal, self.friction * normal - tangential)
        measures[f"cone margin of {self.label}"] = float(margin.min())
        if margin.min() < -tolerances.cone:
            reasons.append(f"a force of {self.label} leaves its friction cone by {-margin.min():.3g} N")
        return reasons

    def _verify_placement(self, data, tolerances, measures) -> list:
        """The surface frame on the print frame: translation and rotation errors."""
        residual = self._placement_residual(data)
        translation, rotation = np.abs(residual[:3]).max(), np.abs(residual[3:]).max()
        measures[f"placement error of {self.label}"] = float(max(translation, rotation))
        if max(translation, rotation) > tolerances.placement:
            return [f"{self.label} is off its print by {translation:.3g} m and {rotation:.3g} rad"]
        return []


def _polygon_in_print(surface, print_placement: pin.SE3) -> np.ndarray:
    """(k, 2) an environment surface's polygon in the frame of a print on it, metres."""
    to_world = np.asarray(surface.transform_surface_to_world, dtype=float)
    corners = np.column_stack([surface.polygon, np.zeros(len(surface.polygon))]) @ to_world[:3, :3].T + to_world[:3, 3]
    return ((corners - print_placement.translation) @ print_placement.rotation)[:, :2]


def supported_vertices(vertices, support, label: str) -> np.ndarray:
    """The vertices of the part of a robot contact polygon that lies on its support.

    Parameters
    ----------
    vertices : (k, 3) float
        The robot polygon's vertices, contact frame (z = 0).
    support : (m, 2) float
        The environment surface's polygon in the print frame, convex and
        counter-clockwise; the contact frame is the print frame where the
        placement holds.
    label : str
        For the message.

    Returns
    -------
    (j, 3) float
        The clipped polygon's vertices (z = 0), repeated vertices merged: the
        robot polygon itself when it lies on the support.

    Raises
    ------
    StanceError
        If the polygons overlap in less than a triangle.
    """
    if signed_edge_distances(support, vertices[:, :2]).min() >= 0.0:
        return vertices
    clipped = []
    for point in clip_polygon(vertices[:, :2], support):
        if not clipped or np.hypot(point[0] - clipped[-1][0], point[1] - clipped[-1][1]) > _SAME_POINT:
            clipped.append(point)
    if len(clipped) > 1 and np.hypot(clipped[0][0] - clipped[-1][0], clipped[0][1] - clipped[-1][1]) <= _SAME_POINT:
        clipped.pop()
    if len(clipped) < 3:
        raise StanceError(f"{label}: the robot's polygon and the surface overlap in less than a triangle; "
                          "move the print onto the surface")
    return np.column_stack([np.array(clipped), np.zeros(len(clipped))])


def point_placement_residual(model, data, frame_id: int, transform_print_to_world: pin.SE3, radius: float):
    """Placement error of a point foot's centre relative to its print.

    Parameters
    ----------
    model, data : pinocchio Model and Data
        Frame placements and joint Jacobians computed at the iterate.
    frame_id : int
        The foot's contact frame, whose origin is the ball's centre.
    transform_print_to_world : pin.SE3
        Print frame (z: outward normal of the support).
    radius : float
        Ball radius, metres.

    Returns
    -------
    residual : (3,) float
        ``R_p^T (c - o_p) - (0, 0, r)``: the centre's offset from the point
        ``r`` above the print origin, metres, print frame. Zero when the ball
        touches the support at the print origin.
    jacobian : (3, nv) float
        Its derivative for a tangent step.
    """
    jacobian = pin.getFrameJacobian(model, data, frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
    residual = _point_residual(data, frame_id, transform_print_to_world, radius)
    return residual, transform_print_to_world.rotation.T @ jacobian


def _point_residual(data, frame_id, transform_print_to_world, radius) -> np.ndarray:
    """(3,) the residual of :func:`point_placement_residual`, without its Jacobian."""
    rotation = transform_print_to_world.rotation
    centre = data.oMf[frame_id].translation
    return rotation.T @ (centre - transform_print_to_world.translation) - np.array([0.0, 0.0, radius])


class PointContact(RigidContact):
    """A point foot (a ball) on a rigid print: 3 placement equalities, one friction pyramid.

    Parameters are those of :class:`RigidContact`; ``robot_surface`` must be
    a point foot (a surface with a ``radius``). The foot's orientation is
    free: only its centre is placed. The force acts at the ball's centre (see
    the module docstring).
    """

    application = "its ball's centre"

    def __init__(self, robot, robot_surface, transform_print_to_world, friction, label, surface=None):
        support_surface = surface
        surface = robot.surface(robot_surface)
        if not surface.is_point:
            raise StanceError(f"robot surface {robot_surface!r} is a polygon, not a point foot: use RigidContact")
        self.radius = float(surface.radius)
        super().__init__(robot, robot_surface, transform_print_to_world, friction, label, support_surface)

    @staticmethod
    def _points_in_frame(surface) -> np.ndarray:
        """(1, 3): the force acts at the ball's centre, the contact frame's origin."""
        return np.zeros((1, 3))

    _placement_axes = ("x", "y", "z")

    def _placement(self, model, data):
        """Placement residual of the ball's centre (3,), print frame, and its Jacobian (3, nv)."""
        return point_placement_residual(model, data, self.frame_id, self.print_placement, self.radius)

    def _placement_residual(self, data) -> np.ndarray:
        """Placement residual of the ball's centre (3,) alone, at the frame placements in ``data``."""
        return _point_residual(data, self.frame_id, self.print_placement, self.radius)

    def _placement_curvature(self, model, data, weights) -> np.ndarray:
        """(nv, nv) ``sum_i weights_i d^2 r_i`` of the centre's rows ``r = R_p^T (c - o_p) - r
        e_z``: the local gradient of ``weights . r`` is ``(R^T R_p weights, 0)``, R the
        foot frame's rotation."""
        pushed = self.print_placement.rotation @ weights
        return frame_curvature(model, data, self.frame_id,
                               lambda placement: np.concatenate([placement.rotation.T @ pushed, np.zeros(3)]))

    def _verify_placement(self, data, tolerances, measures) -> list:
        """The ball's centre ``radius`` above the print origin, along its normal."""
        centre = data.oMf[self.frame_id].translation
        expected = self.print_placement.translation + self.radius * self.print_placement.rotation[:, 2]
        error = float(np.abs(centre - expected).max())
        measures[f"placement error of {self.label}"] = error
        if error > tolerances.placement:
            return [f"{self.label} is off its print by {error:.3g} m (its ball must touch the support at the print)"]
        return []
