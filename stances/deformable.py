"""Deformable contacts: a robot link pressing a print into a linear-elastic body.

At the print's nominal placement, each print node ``x_n`` (eq. 27) is matched
with the point ``a_n`` of the robot surface lying on it. Those points move
with the link; the node displacement is the motion they impose (eq. 29):

    U_n(q) = R_b^T (y_n(q) - x_n),     y_n(q) = T_link(q) a_n      (body frame)

and the body pushes back on the robot with forces linear in ``U_P`` (eq. 44
for ``traction``, the condensed stiffness for ``consistent``):

    f_n(q) = R_b F_n(U_P(q)),   F = R U_P    (R: fem's reaction matrix).

Their derivative follows eqs. (61)-(64): the point Jacobians of ``a_n`` give
``dU_P/dq``, and for ``traction`` the print normals rotate with the link,
adding eq. (63)'s first term. The forces act at the moving points ``y_n``.

A deformable contact owns no force variable. It adds the physical validity
constraints the paper leaves implicit: every node pushes (no adhesion), the
resultant stays in the friction cone, and no node is indented more than
``max_indentation`` along the print normal (small deformations).
"""

from __future__ import annotations

import weakref

import numpy as np
import pinocchio as pin

from .blocks import ConstraintBlock
from .errors import StanceError
from .statics import PointLoads, point_jacobians, points_in_world

# Print patches are expensive to build (compliance solves) and the planner asks
# for the same prints again and again: keep them per body, per node set.
_PATCH_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()

MINIMUM_PRINT_NODES = 3


def contact_patch(body, node_ids):
    """The fem contact patch of ``node_ids`` on ``body``, cached."""
    per_body = _PATCH_CACHE.setdefault(body, {})
    key = tuple(int(i) for i in node_ids)
    if key not in per_body:
        per_body[key] = body.contact_patch(np.asarray(key))
    return per_body[key]


class DeformableContact:
    """A robot surface pressing a print on a deformable object.

    Parameters
    ----------
    robot : stances.Robot
    robot_surface : str
        Robot contact surface name.
    deformable_object : environments.DeformableObject
        Holds the fem body and its placement.
    surface : environments.ContactSurface
        The deformable object's contact surface carrying the print.
    transform_print_to_world : (4, 4) float
        Nominal print frame.
    label : str
        Readable name for constraint labels.
    options : stances.PostureOptions
        ``reaction_model``, ``max_indentation``, ``deformation_weight``.

    Raises
    ------
    StanceError
        When fewer than three mesh nodes lie in the print (the mesh is too
        coarse there).
    """

    kind = "deformable"
    n_variables = 0

    def __init__(self, robot, robot_surface, deformable_object, surface, transform_print_to_world, label, options):
        import fem

        robot_surface_model = robot.surface(robot_surface)
        self.robot_surface = robot_surface
        self.label = label
        self.deformable_object = deformable_object
        self.method = options.reaction_model
        self.max_indentation = options.max_indentation
        self.friction = float(surface.friction)
        self.frame_id = robot.frame_id(robot_surface_model.frame)
        frame = robot.model.frames[self.frame_id]
        print_placement = pin.SE3(np.asarray(transform_print_to_world, dtype=float))
        body_placement = pin.SE3(np.asarray(deformable_object.transform_body_to_world, dtype=float))
        self.print_placement = print_placement
        self.rotation_body = body_placement.rotation

        polygon_in_world = np.array([print_placement.act(v) for v in robot_surface_model.vertices_in_frame])
        polygon_in_body = np.array([body_placement.actInv(p) for p in polygon_in_world])
        body = deformable_object.body
        node_ids = fem.nodes_in_polygon(body.mesh, polygon_in_body, tolerance=1e-6)
        if len(node_ids) < MINIMUM_PRINT_NODES:
            raise StanceError(
                f"the print of {label} holds {len(node_ids)} mesh node(s); at least "
                f"{MINIMUM_PRINT_NODES} are needed: refine the mesh of {deformable_object.name!r} "
                "where prints land"
            )
        self.patch = contact_patch(body, node_ids)
        self.nodes_in_world = np.array([body_placement.act(p) for p in self.patch.points])
        nodes_in_print = np.array([print_placement.actInv(p) for p in self.nodes_in_world])
        # The link points a_n lying on the nodes at the nominal placement.
        self.loads = PointLoads(
            np.full(len(nodes_in_print), frame.parentJoint),
            np.array([frame.placement.act(a) for a in nodes_in_print]),
        )
        self.reaction = np.asarray(self.patch.reaction_matrix(self.method))
        self.normal_in_world = print_placement.rotation[:, 2]
        # Rotation from the nominal contact frame to the print, body frame, for
        # rotating the traction normals with the link (eq. 63).
        self._print_rotation_in_body = self.rotation_body.T @ print_placement.rotation
        self._cache_key = None
        self._cache = None

    # -- kinematics of the print -------------------------------------------
    def _state(self, model, data):
        """Displacements, forces and their q-derivatives at the current kinematics."""
        key = (id(data), data.oMi[int(self.loads.joints[0])].homogeneous.tobytes())
        if self._cache_key == key:
            return self._cache
        rotation_body = self.rotation_body
        displacements = self._displacements(data)
        jacobians = point_jacobians(model, data, self.loads)  # (p, 3, nv) world
        d_displacements = np.einsum("ji,pjv->piv", rotation_body, jacobians).reshape(-1, model.nv)
        if self.method == "traction":
            normals = self._turned_normals(data)
            forces_body = self.patch.reaction_forces(displacements, method="traction", normals=normals)
            reaction = self.patch.reaction_matrix("traction", normals=normals)
            d_forces_body = reaction @ d_displacements
            # eq. (63), first term: normals turn with the link, dn = omega x n.
            angular = pin.getFrameJacobian(model, data, self.frame_id, pin.LOCAL_WORLD_ALIGNED)[3:]
            omega_body = rotation_body.T @ angular  # (3, nv)
            per_triangle = np.asarray(self.patch.traction_normal_derivative(displacements))
            d_forces_body += self._normal_rotation_term(per_triangle, normals, omega_body)
        else:
            forces_body = (self.reaction @ displacements.reshape(-1)).reshape(-1, 3)
            d_forces_body = self.reaction @ d_displacements
        forces = forces_body @ rotation_body.T
        d_forces = np.einsum("ij,pjv->piv", rotation_body, d_forces_body.reshape(-1, 3, model.nv)).reshape(-1, model.nv)
        self._cache_key = key
        self._cache = (displacements, d_displacements, forces, d_forces)
        return self._cache

    def _displacements(self, data) -> np.ndarray:
        """(p, 3) U_P imposed by the link points, metres, body frame (eq. 29)."""
        return (points_in_world(data, self.loads) - self.nodes_in_world) @ self.rotation_body

    def _turned_normals(self, data) -> np.ndarray:
        """(T, 3) print-triangle normals turned with the link, body frame (eq. 63)."""
        link_rotation = data.oMf[self.frame_id].rotation
        relative = self.rotation_body.T @ link_rotation @ self._print_rotation_in_body.T
        return self.patch.triangle_normals @ relative.T

    def _normal_rotation_term(self, per_triangle, normals, omega_body):
        """d f / d q from rotating each triangle normal with the link, body frame."""
        p = len(self.loads)
        out = np.zeros((p, 3, omega_body.shape[1]))
        # df_vertex = D_e (omega x n_e) = -D_e [n_e]x omega
        skews = np.array([pin.skew(n) for n in normals])
        per_triangle_omega = -np.einsum("tij,tjk->tik", per_triangle, skews)  # (T, 3, 3)
        d = np.einsum("tik,kv->tiv", per_triangle_omega, omega_body)
        for corner in range(3):
            np.add.at(out, self.patch.triangles[:, corner], d)
        return out.reshape(3 * p, -1)

    # -- contact-model interface --------------------------------------------
    def displacements(self, model, data) -> np.ndarray:
        """(p, 3) float: print-node displacements U_P, metres, body frame (eq. 29)."""
        return self._displacements(data)

    def forces(self, model, data, lam) -> np.ndarray:
        """(p, 3) world forces of the print nodes on the robot, newtons (eq. 44)."""
        return self._state(model, data)[2]

    def force_jacobians(self, model, data, lam):
        """d forces / d q (3p, nv), eqs. (61)-(64); no force variables."""
        return self._state(model, data)[3], np.zeros((3 * len(self.loads), 0))

    def blocks(self, model, data, lam, columns):
        """No adhesion, friction of the resultant, bounded indentation."""
        displacements, d_displacements, forces, d_forces = self._state(model, data)
        nv, p = model.nv, len(self.loads)
        normal = self.normal_in_world
        blocks = []

        push = forces @ normal
        jacobian = np.zeros((p, columns))
        jacobian[:, :nv] = np.einsum("j,pjv->pv", normal, d_forces.reshape(p, 3, nv))
        blocks.append(
            ConstraintBlock(
                "no adhesion", push, jacobian, 0.0, np.inf, 10.0,
                tuple(f"no adhesion at node {n} of {self.label}" for n in self.patch.node_ids),
            )
        )

        total = forces.sum(axis=0)
        d_total = d_forces.reshape(p, 3, nv).sum(axis=0)
        tangents = self.print_placement.rotation[:, :2].T
        # Inner pyramid: |F . t_i| <= mu / sqrt(2) F . n keeps the cone exact-safe.
        mu = self.friction / np.sqrt(2.0)
        faces = np.array([mu * normal + s * t for t in tangents for s in (1.0, -1.0)])
        jacobian = np.zeros((4, columns))
        jacobian[:, :nv] = faces @ d_total
        blocks.append(
            ConstraintBlock(
                "friction", faces @ total, jacobian, 0.0, np.inf, 10.0,
                tuple(f"friction cone of the resultant of {self.label} ({side})" for side in ("+x", "-x", "+y", "-y")),
            )
        )

        # Small deformations: bound each node's displacement along the print
        # normal (the indentation); tangential motions stay far smaller.
        bound = self.max_indentation
        normal_in_body = self.rotation_body.T @ normal
        jacobian = np.zeros((p, columns))
        jacobian[:, :nv] = np.einsum("j,pjv->pv", normal_in_body, d_displacements.reshape(p, 3, nv))
        blocks.append(
            ConstraintBlock(
                "indentation", displacements @ normal_in_body, jacobian, -bound, bound, 1e-2,
                tuple(f"indentation bound at node {n} of {self.label}" for n in self.patch.node_ids),
            )
        )
        return blocks

    def cost(self, model, data, options, columns):
        """Deformation term of the objective: ``w/2 |f|^2`` (paper note 2)."""
        _, _, forces, d_forces = self._state(model, data)
        weight = options.deformation_weight
        if weight == 0.0:
            return None
        stacked = forces.reshape(-1)
        gradient = np.zeros(columns)
        hessian = np.zeros((columns, columns))
        nv = model.nv
        gradient[:nv] = weight * d_forces.T @ stacked
        hessian[:nv, :nv] = weight * d_forces.T @ d_forces
        return 0.5 * weight * float(stacked @ stacked), gradient, hessian

    def displacement_field(self, model, data) -> np.ndarray:
        """(N, 3) float: displacement of every node of the body, metres, body frame (eq. 36)."""
        return np.asarray(self.deformable_object.body.displacement_field(self.patch, self.displacements(model, data)))

    def verify(self, model, data, points, forces, tolerances, measures) -> list:
        """Recompute the FEM forces from the link placement and check them."""
        reasons = []
        expected_points = points_in_world(data, self.loads)
        if len(points) != len(expected_points) or np.abs(points - expected_points).max() > tolerances.placement:
            reasons.append(f"forces of {self.label} are not applied at the print nodes' link points")
            return reasons
        displacements = self._displacements(data)
        if self.method == "traction":
            forces_body = self.patch.reaction_forces(
                displacements, method="traction", normals=self._turned_normals(data)
            )
        else:
            forces_body = self.patch.reaction_forces(displacements, method="consistent")
        expected = np.asarray(forces_body) @ self.rotation_body.T
        error = np.abs(forces - expected).max() / max(np.abs(expected).max(), 1.0)
        measures[f"FEM force error of {self.label}"] = float(error)
        if error > tolerances.deformable_force:
            reasons.append(f"forces of {self.label} differ from the FEM reaction by {error:.3g} (relative)")
        push = expected @ self.normal_in_world
        measures[f"smallest normal force of {self.label}"] = float(push.min())
        if push.min() < -tolerances.cone:
            reasons.append(f"a print node of {self.label} pulls on the robot ({push.min():.3g} N): adhesion")
        total = expected.sum(axis=0)
        normal_part = total @ self.normal_in_world
        tangential = np.linalg.norm(total - normal_part * self.normal_in_world)
        if tangential > self.friction * normal_part + tolerances.cone:
            reasons.append(f"the resultant of {self.label} leaves its friction cone")
        depth = float(np.abs(displacements @ (self.rotation_body.T @ self.normal_in_world)).max())
        measures[f"indentation of {self.label}"] = depth
        if depth > self.max_indentation + 1e-9:
            reasons.append(f"a node of {self.label} is indented {depth:.3g} m, beyond max_indentation")
        return reasons


__all__ = ["DeformableContact", "contact_patch"]
