"""Contact plates: flat plates mounted on a link in place of an end effector.

The paper's palm is a "modified hand link", a flat plate. Talos's gripper
cannot lean on a table, so each hand gets such a plate instead: the gripper's
collision geometry and inertia leave the model, and a thin box (collision
object and uniform inertia) takes their place on the wrist.

The plate is mounted beyond everything the link's remaining collision geometry
reaches along the surface normal, measured on that geometry (mesh vertices,
exact extents of primitives) when the robot is built. Its outer face is the
contact surface: with it flat on a support, every other geometry of the link
is at least the plate's thickness away from the support, so only the plate
needs to be exempt from collision avoidance with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

try:  # pinocchio's collision library: coal since pinocchio 3.4, hpp-fcl before
    import coal
except ImportError:  # pragma: no cover - older pinocchio
    import hppfcl as coal

from .errors import StanceError


@dataclass(frozen=True)
class PlateDeclaration:
    """A flat plate carrying a contact surface, replacing part of a link.

    Parameters
    ----------
    thickness : float
        Plate thickness along the surface normal, metres (> 0).
    replaces : str or sequence of str
        Name prefix, or prefixes, of the frames the plate replaces (e.g.
        ``"gripper_left_"``; Romeo's ``["RFinger", "RThumb"]``): the collision
        geometries attached to them are removed, and so is their inertia from
        the link's. Empty: nothing is replaced. Stored as a tuple of prefixes.
    mass : float, optional
        Plate mass, kilograms. ``None`` gives it the replaced frames' total
        mass, so that the robot's total mass is unchanged.
    """

    thickness: float
    replaces: tuple = ()
    mass: float | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.thickness, (int, float)) and math.isfinite(self.thickness) and self.thickness > 0.0):
            raise StanceError(f"plate thickness must be a finite number of metres > 0, got {self.thickness!r}")
        if isinstance(self.replaces, str):  # one prefix; "" replaces nothing
            prefixes = (self.replaces,) if self.replaces else ()
        else:
            prefixes = self.replaces
        if not isinstance(prefixes, (list, tuple)) or not all(isinstance(prefix, str) and prefix for prefix in prefixes):
            raise StanceError(
                f"plate 'replaces' must be a frame-name prefix or a list of non-empty prefixes, got {self.replaces!r}"
            )
        # A tuple: str.startswith takes one.
        object.__setattr__(self, "replaces", tuple(prefixes))
        if self.mass is not None and not (
            isinstance(self.mass, (int, float)) and math.isfinite(self.mass) and self.mass >= 0.0
        ):
            raise StanceError(f"plate mass must be None or a finite number of kilograms >= 0, got {self.mass!r}")


def geometry_reach(geometry_object, direction) -> float:
    """How far a collision geometry extends along a direction (its support function).

    Parameters
    ----------
    geometry_object : pinocchio.GeometryObject
        A mesh (its vertices, scale applied by pinocchio's loader), box,
        sphere, cylinder or capsule.
    direction : (3,) float
        Unit vector, frame of the geometry's parent joint.

    Returns
    -------
    float
        ``max p . direction`` over the points ``p`` of the geometry, metres,
        joint frame.

    Raises
    ------
    StanceError
        For a geometry type whose extent is not known here.
    """
    direction = np.asarray(direction, dtype=float)
    placement = geometry_object.placement
    shape = geometry_object.geometry
    local = placement.rotation.T @ direction  # the direction in the geometry frame
    offset = float(placement.translation @ direction)
    kind = type(shape).__name__
    if hasattr(shape, "vertices") and shape.num_vertices > 0:  # meshes (BVH models)
        return offset + float(np.max(np.asarray(shape.vertices()) @ local))
    if kind == "Box":
        return offset + float(np.abs(local) @ np.asarray(shape.halfSide))
    if kind == "Sphere":
        return offset + float(shape.radius)
    if kind in ("Cylinder", "Capsule"):
        # Both are along the geometry's z axis; a capsule is a swept sphere.
        axial = abs(local[2]) * shape.halfLength
        if kind == "Capsule":
            return offset + axial + float(shape.radius)
        return offset + axial + float(shape.radius) * math.hypot(local[0], local[1])
    raise StanceError(
        f"cannot measure the extent of collision geometry {geometry_object.name!r} of type {kind}; "
        "supported: meshes, Box, Sphere, Cylinder, Capsule"
    )


def plate_standoff(collision_model, joint: int, mount_in_joint: pin.SE3) -> float:
    """Distance past a mounting plane that a joint's collision geometry reaches.

    Parameters
    ----------
    collision_model : pinocchio.GeometryModel
    joint : int
        Joint whose geometries are measured (every geometry it carries).
    mount_in_joint : pinocchio.SE3
        Mounting frame in the joint frame: origin on the mounting plane, z
        axis into the link (the outward normal is its -z).

    Returns
    -------
    float
        Largest distance, metres, by which a geometry crosses the plane along
        the outward normal; 0 when none does.
    """
    outward = -mount_in_joint.rotation[:, 2]
    plane = float(mount_in_joint.translation @ outward)
    reach = [
        geometry_reach(geometry_object, outward) - plane
        for geometry_object in collision_model.geometryObjects
        if geometry_object.parentJoint == joint
    ]
    return max([0.0, *reach])


def replaced_inertia(model, joint: int, prefix: str) -> pin.Inertia:
    """Total inertia of the frames a plate replaces, in the joint frame.

    Parameters
    ----------
    model : pinocchio.Model
        A model whose fixed links (and locked joints) are frames carrying
        their link's inertia, as pinocchio's URDF parser and
        ``buildReducedModel`` leave them.
    joint : int
        Joint carrying the plate.
    prefix : str or tuple of str
        Name prefix (or prefixes) of the replaced frames; empty replaces nothing.

    Returns
    -------
    pinocchio.Inertia

    Raises
    ------
    StanceError
        If a frame with that prefix moves with another joint (lock it first:
        a plate cannot replace a moving part).
    """
    total = pin.Inertia.Zero()
    if not prefix:
        return total
    for frame in model.frames:
        if not frame.name.startswith(prefix):
            continue
        if frame.parentJoint != joint:
            raise StanceError(
                f"the plate on {model.names[joint]} replaces frame {frame.name!r}, which moves with joint "
                f"{model.names[frame.parentJoint]!r}; lock that joint so the replaced part is rigid"
            )
        total += frame.placement.act(frame.inertia)
    return total


def _plate_box(contact_in_joint: pin.SE3, polygon, thickness: float):
    """The plate's box: its centre's placement in the joint frame and its (3,) sides, metres."""
    polygon = np.asarray(polygon, dtype=float)
    low, high = polygon.min(axis=0), polygon.max(axis=0)
    size = np.array([*(high - low), thickness])
    # The contact frame's z points into the link: the plate spans z in [0, thickness].
    center_in_contact = np.array([*(0.5 * (low + high)), 0.5 * thickness])
    return contact_in_joint * pin.SE3(np.eye(3), center_in_contact), size


def mount_plate(model, collision_model, joint: int, mount_in_joint: pin.SE3, polygon, plate) -> pin.SE3:
    """Take the replaced part off a joint and put the plate's inertia on it.

    Modifies ``model`` (the joint's inertia; the replaced frames' inertias
    are set to zero) and ``collision_model`` (the replaced geometries are
    removed). The plate's own collision geometry is added by
    :func:`plate_geometry` once its contact frame exists.

    Parameters
    ----------
    model : pinocchio.Model
    collision_model : pinocchio.GeometryModel
    joint : int
        Joint carrying the plate.
    mount_in_joint : pinocchio.SE3
        Mounting frame in the joint frame (see :func:`plate_standoff`).
    polygon : (k, 2) float
        Contact polygon, metres, in the contact frame's xy plane; the plate is
        its bounding rectangle.
    plate : PlateDeclaration

    Returns
    -------
    pinocchio.SE3
        The contact frame in the joint frame: the mounting frame moved along
        the outward normal past the link's remaining geometry and then the
        plate's thickness, so that its origin lies on the plate's outer face.

    Raises
    ------
    StanceError
        If the replaced part moves, or removing its inertia leaves the link
        with a non-physical one.
    """
    removed = replaced_inertia(model, joint, plate.replaces)
    if plate.replaces:
        # Names first: removing objects invalidates the python views on them.
        doomed = [
            geometry_object.name
            for geometry_object in collision_model.geometryObjects
            if model.frames[geometry_object.parentFrame].name.startswith(plate.replaces)
        ]
        for geometry_name in doomed:
            collision_model.removeGeometryObject(geometry_name)
        for index, frame in enumerate(model.frames):
            if frame.name.startswith(plate.replaces):
                frame.inertia = pin.Inertia.Zero()
                model.frames[index] = frame

    # Measured after the replaced geometry is gone: the plate goes past what is left.
    standoff = plate_standoff(collision_model, joint, mount_in_joint)
    contact_in_joint = mount_in_joint * pin.SE3(np.eye(3), np.array([0.0, 0.0, -(standoff + plate.thickness)]))

    link = model.inertias[joint] - removed
    eigenvalues = np.linalg.eigvalsh(link.inertia)
    if link.mass <= 0.0 or eigenvalues.min() < -1e-12:
        raise StanceError(
            f"removing the inertia of the frames {' '.join(p + '*' for p in plate.replaces)} from {model.names[joint]} leaves "
            f"mass {link.mass:.6g} kg and rotational inertia eigenvalues {np.round(eigenvalues, 9).tolist()}; "
            "check the prefix"
        )
    mass = removed.mass if plate.mass is None else float(plate.mass)
    box_in_joint, size = _plate_box(contact_in_joint, polygon, plate.thickness)
    model.inertias[joint] = link + box_in_joint.act(pin.Inertia.FromBox(mass, *size))
    return contact_in_joint


def plate_geometry(name: str, model, contact_frame: int, polygon, thickness: float):
    """The plate's collision geometry: a box whose outer face holds the contact surface.

    Parameters
    ----------
    name : str
        Geometry name.
    model : pinocchio.Model
    contact_frame : int
        Index of the contact frame (origin on the outer face, z into the link).
    polygon : (k, 2) float
        Contact polygon, metres; the box is its bounding rectangle.
    thickness : float
        Metres.

    Returns
    -------
    pinocchio.GeometryObject
        A ``coal.Box`` on the contact frame's joint, parented to the contact frame.
    """
    frame = model.frames[contact_frame]
    box_in_joint, size = _plate_box(frame.placement, polygon, thickness)
    return pin.GeometryObject(name, frame.parentJoint, contact_frame, box_in_joint, coal.Box(*size))


__all__ = ["PlateDeclaration", "geometry_reach", "mount_plate", "plate_geometry", "plate_standoff", "replaced_inertia"]
