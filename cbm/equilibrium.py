"""Cheap rejection before a posture solve: static equilibrium of the contact set.

Most stances a planner checks are infeasible, and a posture solve (an SQP) of
an infeasible stance is its most expensive answer. Whether ANY posture can
hold a stance is bounded by a small linear program, as RB-PRM's centroidal
check does: can contact forces, each inside its friction cone and applied
where the stance's prints are, balance the robot's weight with its centre of
mass somewhere the robot can put it? If not, no posture solve can succeed,
and the stance is rejected at the cost of one LP (about a millisecond).

The LP is a relaxation of what :func:`stances.solve` and :func:`stances.verify`
require, so it never rejects a stance they accept:

- Rigid prints: a force at each vertex of the robot surface's polygon (a point
  foot: one at its ball's centre) inside the OUTER linearised friction
  pyramid ``|f . t_i| <= mu f . n``, which contains the exact Coulomb cone
  that :func:`stances.verify` checks (and the solver's inscribed pyramid).
- Soft prints (:mod:`stances.deformable`): the forces act at the print nodes'
  link points. At rest a node lies in the print polygon, or (a partly covered
  node, :func:`fem.print_coverage`) within its cell's reach of it, which joins
  the margin below (a point foot's nodes: at its ball's centre), and a force at
  a point of a polygon is a convex combination of the same force at its
  vertices, so the node forces add up to vertex forces with the same resultant
  and moment; with the ``coulomb`` and
  ``sticking`` laws each node force is inside its own cone (verified per node),
  so the vertex forces are too. The link points move from rest with the body:
  the moment of that motion is at most ``r |f|`` per force, ``r`` the margin of
  :func:`soft_print_margin`, and enters as a bounded slack. With the
  ``bonded`` law only each print's resultant is in its cone (node forces may
  twist the print freely): its moment is left free.
- The centre of mass: world gravity is vertical, so only its horizontal
  position enters the moments. It lies within :func:`com_distance_bounds` of
  every contact surface's frame (a bound from the kinematic tree that holds in
  every configuration; a soft print's frame may move by the margin too),
  relaxed to the circumscribed octagon.

Newton-Euler in the world, with ``W = m g``:
``sum_i f_i = (0, 0, W)`` and ``sum_i p_i x f_i + c x (0, 0, -W) + s = 0``,
linear in the forces ``f``, the centre of mass ``c`` and the soft slacks ``s``.
Solved with :func:`scipy.optimize.linprog` (HiGHS, deterministic).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.optimize import linprog

import fem
from stances.deformable import SLIP_SHARE, PrintSpec
from stances.layer_ball import largest_ball_load, layer_sites
from stances.problem import PostureOptions, min_normal_load

__all__ = ["EquilibriumFilter", "com_distance_bounds", "soft_print_margin", "EQUILIBRIUM_IMPOSSIBLE"]

#: How every rejection's reason starts (cbm.rejections files it under balance).
EQUILIBRIUM_IMPOSSIBLE = "static equilibrium impossible for the contact set"

# Joints that keep their origin in place (rotations about it): segment lengths
# between joint origins are then the same in every configuration.
_FIXED_ORIGIN_JOINTS = ("JointModelR", "JointModelSpherical")
# Directions of the octagon around each disc of reachable centres of mass.
_OCTAGON = np.array([[math.cos(a), math.sin(a)] for a in np.arange(4) * math.pi / 4])


def com_distance_bounds(robot) -> dict:
    """How far the centre of mass can be from each contact surface's frame.

    For a body ``k`` of mass ``m_k`` whose centre of mass is reached from the
    surface's frame through a chain of joint origins, ``|x_k - p| <= L_k``,
    the chain's summed segment lengths (the same in every configuration when
    every joint turns about its origin). Hence ``|c - p| <= sum_k m_k L_k / m``.

    Parameters
    ----------
    robot : stances Robot

    Returns
    -------
    dict of str to float
        Robot surface -> bound, metres; ``inf`` for every surface if the model
        has a joint that moves its origin (prismatic, planar) below the root.
    """
    model = robot.model
    for joint in model.joints[2:]:
        if not joint.shortname().startswith(_FIXED_ORIGIN_JOINTS):
            return {name: math.inf for name in robot.surfaces}
    segment = np.array([np.linalg.norm(placement.translation) for placement in model.jointPlacements])
    masses = np.array([inertia.mass for inertia in model.inertias])
    levers = np.array([np.linalg.norm(inertia.lever) for inertia in model.inertias])
    chains = [_chain(model, joint) for joint in range(model.njoints)]
    bounds = {}
    for name, surface in robot.surfaces.items():
        frame = model.frames[robot.frame_id(surface.frame)]
        start = chains[frame.parentJoint]
        lengths = np.zeros(model.njoints)
        for body in range(1, model.njoints):
            common = set(start) & set(chains[body])
            path = [j for j in start if j not in common] + [j for j in chains[body] if j not in common]
            lengths[body] = segment[path].sum() + levers[body]
        bounds[name] = float(np.linalg.norm(frame.placement.translation) + masses @ lengths / masses.sum())
    return bounds


def _chain(model, joint):
    """Joints from ``joint`` up to the universe (0), inclusive."""
    chain = [joint]
    while chain[-1] != 0:
        chain.append(model.parents[chain[-1]])
    return chain


def soft_print_margin(deformable_object, normal_in_world, options) -> float:
    """How far a loaded print node's link point can move from its rest position, metres.

    The sum of the indentation bound (``max_indentation``, else
    ``indentation_limit`` times the body's thickness along the print normal),
    the slip bound of the ``coulomb`` law (``max_slip``, by default at most
    :data:`stances.deformable.SLIP_SHARE` of the longest surface edge) and ``2 strain_limit
    H``: the tangential displacement of a surface node of a body of thickness
    ``H`` held at its far side whose shear strains stay within the strain
    bound that :func:`stances.verify` checks. An estimate, not a theorem (a
    body held at its sides, or bulging, can exceed it); it only widens the LP.

    Parameters
    ----------
    deformable_object : environments DeformableObject
    normal_in_world : (3,) float
        The print's outward normal, world frame.
    options : stances PostureOptions
    """
    rotation = np.asarray(deformable_object.transform_body_to_world, dtype=float)[:3, :3]
    thickness = float(np.ptp(deformable_object.body.mesh.nodes @ (rotation.T @ normal_in_world)))
    indentation = options.max_indentation if options.max_indentation is not None else options.indentation_limit * thickness
    slip = 0.0
    if options.contact_law == "coulomb":
        # By default a share of the spacing under the body's prints: at most that of its
        # longest surface edge (this only widens the LP).
        slip = options.max_slip if options.max_slip is not None else (
            SLIP_SHARE * deformable_object.body.mesh.surface_search[1])
    return float(indentation + slip + 2.0 * deformable_object.strain_limit * thickness)


@dataclass(frozen=True)
class _PrintForces:
    """One print as the LP sees it.

    points : (k, 3) float, world frame, where its k forces act;
    rotation : (3, 3) float, print frame axes as columns (z: normal);
    origin : (3,) float, world, the robot surface frame's origin on the print;
    margin : float, metres the points may move (soft), 0 for rigid;
    free_moment : bool, the bonded law: only the resultant is in the cone.
    """

    label: str
    robot_surface: str
    points: np.ndarray
    rotation: np.ndarray
    origin: np.ndarray
    friction: float
    margin: float = 0.0
    free_moment: bool = False
    min_load: float = 0.0  # least normal load, in weights
    max_load: float = math.inf  # largest normal load, in weights (a ball on a layer: its strain bound's)


class EquilibriumFilter:
    """Rejects stances that no posture can hold in static equilibrium.

    Parameters
    ----------
    robot : stances Robot
        Its total mass (pinocchio's model) and contact surfaces.
    scene : environments Scene
    options : stances PostureOptions, optional
        The options ``stances.solve`` runs with (default: its defaults):
        contact law, indentation and slip bounds, ``min_normal_force``, ``support_load`` and
        ``deformable_as_rigid`` shape the LP.

    Examples
    --------
    >>> import environments, stances
    >>> scenario = environments.load("step-on-cube")
    >>> check = EquilibriumFilter(stances.Robot.load(scenario.robot), scenario.scene)
    >>> check(scenario.stance("step-on-cube"))
    ''
    """

    def __init__(self, robot, scene, options=None):
        self.options = options if options is not None else PostureOptions()
        self.robot = robot
        self.scene = scene
        self.mass = robot.mass
        self.weight = robot.weight
        self.com_bounds = com_distance_bounds(robot)

    def __call__(self, stance) -> str:
        """``""`` if the stance may be held, else why not (starting with :data:`EQUILIBRIUM_IMPOSSIBLE`).

        Raises
        ------
        environments.SceneError, stances.StanceError
            For a print on an unknown surface or an unknown robot surface (as
            ``stances.solve`` would).
        """
        largest = self._ball_loads(stance)
        prints = [self._print_forces(contact, largest.get(index, math.inf)) for index, contact in enumerate(stance)]
        if not prints:
            return ""
        for p, contact in zip(prints, stance):
            if p.max_load < p.min_load:
                name = self.scene.surface(contact.contact_print.surface).object_name
                return (f"{EQUILIBRIUM_IMPOSSIBLE}: {p.label} carries at most {p.max_load * self.weight:.3g} N within "
                        f"{name}'s strain bound (its layer's law), less than its least load "
                        f"{p.min_load * self.weight:.3g} N")
        if _feasible(prints, self.com_bounds, moments=True):
            return ""
        labels = ", ".join(p.label for p in prints)
        if not _feasible(prints, self.com_bounds, moments=False):
            return (
                f"{EQUILIBRIUM_IMPOSSIBLE}: the friction cones of {labels} cannot carry the robot's weight "
                f"({self.mass:.1f} kg) whatever the posture"
            )
        return (
            f"{EQUILIBRIUM_IMPOSSIBLE}: no centre of mass within the robot's reach of {labels} "
            "balances the moments of forces inside their friction cones"
        )

    def _ball_loads(self, stance) -> dict:
        """Stance index -> the largest normal load (weights) of each ball the posture solver
        sinks by a layer's law (every print on its body a ball where the body is a layer,
        ``ball_contact="layer"``): :func:`stances.layer_ball.largest_ball_load`."""
        if self.options.deformable_as_rigid:
            return {}
        on_body = {}  # object name -> [(stance index, its print)]
        for index, contact in enumerate(stance):
            surface = self.scene.surface(contact.contact_print.surface)
            if surface.deformable:
                where = surface.transform_print_to_world(contact.contact_print.x, contact.contact_print.y,
                                                         contact.contact_print.theta)
                spec = PrintSpec(contact.robot_surface, surface, where, f"{contact.robot_surface} on {surface.name}")
                on_body.setdefault(surface.object_name, []).append((index, spec))
        out = {}
        for entries in on_body.values():
            body = self.scene.deformable_of_surface(entries[0][1].surface.name)
            sites = layer_sites(self.robot, body, [spec for _, spec in entries], self.options)
            for (index, spec), site in zip(entries, sites or ()):
                radius = self.robot.surface(spec.robot_surface).radius
                out[index] = largest_ball_load(radius, site, body, self.options, spec.surface.friction) / self.weight
        return out

    def _print_forces(self, contact, max_load=math.inf) -> _PrintForces:
        contact_print = contact.contact_print
        surface = self.scene.surface(contact_print.surface)
        robot_surface = self.robot.surface(contact.robot_surface)
        transform = surface.transform_print_to_world(contact_print.x, contact_print.y, contact_print.theta)
        rotation, origin = transform[:3, :3], transform[:3, 3]
        if robot_surface.is_point:
            origin = origin + robot_surface.radius * rotation[:, 2]  # the ball's centre, where its force acts
            points = origin[None]
        else:
            points = robot_surface.vertices_in_frame @ rotation.T + origin
        label = f"{contact.robot_surface} on {surface.name}"
        # The least load the posture solver asks of the print, in weights.
        min_load = min_normal_load(self.robot, contact.robot_surface, self.options) / self.weight
        if not surface.deformable or self.options.deformable_as_rigid:
            return _PrintForces(label, contact.robot_surface, points, rotation, origin, float(surface.friction),
                                min_load=min_load, max_load=max_load)
        body = self.scene.deformable_of_surface(surface.name)
        reach = 0.0
        if not robot_surface.is_point and self.options.reaction_model == "consistent":
            reach = _covered_reach(body, points)
        return _PrintForces(
            label,
            contact.robot_surface,
            points,
            rotation,
            origin,
            float(surface.friction),
            soft_print_margin(body, rotation[:, 2], self.options) + reach,
            self.options.contact_law == "bonded",
            min_load,
            max_load,
        )


def _covered_reach(deformable_object, polygon_in_world) -> float:
    """Metres: how far outside a soft print's polygon its partly covered nodes lie
    (:func:`fem.coverage_reach`), the farthest a node force acts from the polygon at rest."""
    pose = np.asarray(deformable_object.transform_body_to_world, dtype=float)
    in_body = (polygon_in_world - pose[:3, 3]) @ pose[:3, :3]
    try:
        return fem.coverage_reach(deformable_object.body.mesh, in_body, tolerance=1e-6)
    except fem.FemError:
        return 0.0  # stances.solve refuses such a print with its own reason


def _feasible(prints, com_bounds, moments) -> bool:
    """Whether the equilibrium LP of ``prints`` has a solution (forces in units of the weight).

    Unknowns: each print's point forces (3 per point, world), the centre of
    mass's horizontal offset from the prints' mean origin (2), each soft
    print's moment slack (3). A solver failure other than infeasibility
    counts as feasible: the filter only rejects what it proved.
    """
    centre = np.mean([p.origin for p in prints], axis=0)
    counts = [3 * len(p.points) for p in prints]
    force_columns = np.cumsum([0] + counts)
    n_forces = force_columns[-1]
    com = n_forces
    slack = com + 2
    n = slack + 3 * len(prints)
    equalities = np.zeros((6, n))
    inequalities = []
    for index, p in enumerate(prints):
        columns = slice(force_columns[index], force_columns[index + 1])
        k = len(p.points)
        equalities[:3, columns] = np.tile(np.eye(3), k)
        equalities[3:, columns] = np.hstack([pin.skew(point - centre) for point in p.points])
        normal, tangents = p.rotation[:, 2], p.rotation[:, :2].T
        # Rows on one point force (3,): pushing, and inside the outer pyramid.
        pyramid = [-normal] + [sign * t - p.friction * normal for t in tangents for sign in (1.0, -1.0)]
        normal_sum = np.zeros(n)
        normal_sum[columns] = np.tile(normal, k)
        rows = pyramid[:1] if p.free_moment else pyramid
        for point in range(k):
            for row in rows:
                line = np.zeros(n)
                line[force_columns[index] + 3 * point : force_columns[index] + 3 * point + 3] = row
                inequalities.append((line, 0.0))
        if p.free_moment:
            for row in pyramid[1:]:  # the resultant in the pyramid
                line = np.zeros(n)
                line[columns] = np.tile(row, k)
                inequalities.append((line, 0.0))
        if p.min_load > 0:
            inequalities.append((-normal_sum, -p.min_load))
        if math.isfinite(p.max_load):
            inequalities.append((normal_sum, p.max_load))
        moment_slack = slice(slack + 3 * index, slack + 3 * index + 3)
        equalities[3:, moment_slack] = np.eye(3)
        if not p.free_moment:
            # |s_axis| <= margin * |f|, |f| <= sqrt(1 + 2 mu^2) f.n in the outer pyramid.
            reach = p.margin * math.sqrt(1.0 + 2.0 * p.friction**2) * normal_sum
            for axis in range(3):
                for sign in (1.0, -1.0):
                    line = -reach.copy()
                    line[slack + 3 * index + axis] = sign
                    inequalities.append((line, 0.0))
        bound = com_bounds.get(p.robot_surface, math.inf) + p.margin
        if moments and math.isfinite(bound):
            offset = (p.origin - centre)[:2]
            for direction in _OCTAGON:
                for sign in (1.0, -1.0):
                    line = np.zeros(n)
                    line[com : com + 2] = sign * direction
                    inequalities.append((line, bound + sign * direction @ offset))
    # c x (0, 0, -1) = (-c_y, c_x, 0) about the centre.
    equalities[3, com + 1] = -1.0
    equalities[4, com] = 1.0
    target = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    if not moments:
        equalities, target = equalities[:3], target[:3]
    a_ub = np.array([line for line, _ in inequalities])
    b_ub = np.array([value for _, value in inequalities])
    result = linprog(np.zeros(n), A_ub=a_ub, b_ub=b_ub, A_eq=equalities, b_eq=target, bounds=(None, None), method="highs")
    return result.status != 2  # 2: proven infeasible
