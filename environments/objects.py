"""Rigid scene objects: boxes, the floor and arbitrary triangle meshes."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from .errors import SceneError
from .geometry import (
    pose_from_center_yaw,
    readonly_array,
    transform_from_rotation_translation,
    validate_rigid_transform,
)
from .surfaces import ContactSurface, rectangle

__all__ = ["RigidObject", "box", "floor", "mesh_object", "box_surfaces", "DEFAULT_FRICTION"]

DEFAULT_FRICTION = 0.7
"""Friction coefficient given to surfaces when none is specified (rubber sole on wood)."""

FLOOR_THICKNESS = 0.1
"""Thickness of the floor slab, metres; its top is the plane z = 0."""


@dataclass(frozen=True, eq=False)
class RigidObject:
    """A rigid obstacle or support.

    Parameters
    ----------
    name : str
        Unique object name in the scene.
    mesh : trimesh.Trimesh
        Closed triangle mesh, metres, object frame. Treat it as read-only.
    transform_object_to_world : (4, 4) float
        Rigid placement of the object frame.
    box_size : (3,) float or None
        Side lengths, metres, when the object is a box centred on its frame
        (collision then uses an exact box).
    """

    name: str
    mesh: trimesh.Trimesh
    transform_object_to_world: np.ndarray
    box_size: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise SceneError(f"RigidObject.name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.mesh, trimesh.Trimesh) or len(self.mesh.faces) == 0:
            raise SceneError(f"object {self.name!r}: mesh must be a non-empty trimesh.Trimesh")
        object.__setattr__(
            self,
            "transform_object_to_world",
            validate_rigid_transform(self.transform_object_to_world, f"object {self.name!r} transform"),
        )
        if self.box_size is not None:
            size = readonly_array(self.box_size, (3,), f"object {self.name!r} box_size")
            if np.any(size <= 0.0):
                raise SceneError(f"object {self.name!r}: box sides must be > 0, got {size.tolist()}")
            object.__setattr__(self, "box_size", size)

    @property
    def deformable(self) -> bool:
        """False: a rigid object."""
        return False

    @property
    def bounds_in_object(self) -> np.ndarray:
        """(2, 3) float: lower and upper corners of its box, metres, object frame.

        The exact box for a box object, the mesh's axis-aligned bounds otherwise.
        """
        if self.box_size is not None:
            half = 0.5 * self.box_size
            return np.array([-half, half])
        return np.asarray(self.mesh.bounds, dtype=float).copy()

    def mesh_in_world(self) -> trimesh.Trimesh:
        """A copy of the mesh placed in the world frame."""
        return self.mesh.copy().apply_transform(self.transform_object_to_world)


def _positive_size(size, name: str) -> np.ndarray:
    size = readonly_array(size, (3,), f"object {name!r} size")
    if np.any(size <= 0.0):
        raise SceneError(f"object {name!r}: size must be > 0 on every axis, got {size.tolist()}")
    return size


def box(name: str, size, center=(0.0, 0.0, 0.0), yaw: float = 0.0, pose=None) -> RigidObject:
    """A rigid box whose frame is at its centre.

    Parameters
    ----------
    name : str
        Object name.
    size : (3,) float
        Side lengths along the object axes, metres.
    center : (3,) float
        Centre, metres, world frame (ignored when ``pose`` is given).
    yaw : float
        Rotation about world z, radians (ignored when ``pose`` is given).
    pose : (4, 4) float, optional
        ``transform_object_to_world`` of the centre frame.

    Returns
    -------
    RigidObject

    Examples
    --------
    >>> table = box("table", (0.6, 0.8, 0.8), center=(0.65, -0.25, 0.4))
    >>> table.mesh_in_world().bounds[1].round(2).tolist()
    [0.95, 0.15, 0.8]
    """
    size = _positive_size(size, name)
    transform = pose if pose is not None else pose_from_center_yaw(center, yaw)
    return RigidObject(name, trimesh.creation.box(extents=size), transform, box_size=size)


def floor(name: str = "floor", size=(10.0, 10.0)) -> RigidObject:
    """The floor: a large thin box whose top is the plane z = 0, centred on the origin.

    Parameters
    ----------
    name : str
        Object name.
    size : (2,) float
        Extent along x and y, metres.

    Returns
    -------
    RigidObject
    """
    size = readonly_array(size, (2,), "floor size")
    return box(name, (size[0], size[1], FLOOR_THICKNESS), center=(0.0, 0.0, -0.5 * FLOOR_THICKNESS))


def mesh_object(name: str, mesh, center=(0.0, 0.0, 0.0), yaw: float = 0.0, pose=None) -> RigidObject:
    """A rigid object from a triangle mesh or a file trimesh can load.

    Parameters
    ----------
    name : str
        Object name.
    mesh : trimesh.Trimesh or str or os.PathLike
        The mesh (object frame, metres) or its file.
    center, yaw, pose
        Placement of the object frame, as in :func:`box`.

    Raises
    ------
    SceneError
        If the file cannot be read or holds no triangles.
    """
    if not isinstance(mesh, trimesh.Trimesh):
        try:
            mesh = trimesh.load(mesh, force="mesh")
        except Exception as error:  # trimesh raises many types for bad files
            raise SceneError(f"object {name!r}: cannot load mesh {mesh!s}: {error}") from None
    transform = pose if pose is not None else pose_from_center_yaw(center, yaw)
    return RigidObject(name, mesh, transform)


# Face frames of a box, in the box frame: (suffix, outward normal axis, sign).
# Tangent axes are chosen so that every side face has its y axis along the box's
# +z (up on a wall) and each frame is right-handed.
_FACE_ROTATIONS = {
    "top": np.eye(3),
    "front": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),  # normal +x
    "back": np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),  # normal -x
    "left": np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]),  # normal +y
    "right": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # normal -y
}


def box_face_frames(size) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Frames and rectangles of a centred box's faces, bottom excepted.

    Parameters
    ----------
    size : (3,) float
        Side lengths, metres.

    Returns
    -------
    dict
        ``face -> (transform_surface_to_box (4, 4), polygon (4, 2))`` for the faces
        ``top`` (+z), ``front`` (+x), ``back`` (-x), ``left`` (+y), ``right`` (-y).
    """
    sx, sy, sz = (float(v) for v in size)
    lengths = {"top": (sx, sy), "front": (sy, sz), "back": (sy, sz), "left": (sx, sz), "right": (sx, sz)}
    frames = {}
    for face, rotation in _FACE_ROTATIONS.items():
        origin = rotation[:, 2] * 0.5 * np.array([sx, sy, sz])
        frames[face] = (transform_from_rotation_translation(rotation, origin), rectangle(*lengths[face]))
    return frames


def box_surfaces(
    obj: RigidObject,
    friction: float = DEFAULT_FRICTION,
    sides: bool = False,
    top_name: str | None = None,
) -> list[ContactSurface]:
    """Contact surfaces on a rigid box's top face (and optionally its four sides).

    Surfaces are named ``<object>_top``, ``<object>_front`` (+x), ``_back`` (-x),
    ``_left`` (+y) and ``_right`` (-y); the top frame sits at the top-face centre
    with the box's x and y axes.

    Parameters
    ----------
    obj : RigidObject
        A box (``obj.box_size`` set).
    friction : float
        Friction coefficient of every face.
    sides : bool
        Also declare the four side faces.
    top_name : str, optional
        Name of the top surface instead of ``<object>_top`` (``"floor"`` for the floor).

    Raises
    ------
    SceneError
        If the object is not a box.
    """
    if obj.box_size is None:
        raise SceneError(f"object {obj.name!r} is not a box; declare its surfaces explicitly")
    surfaces = []
    for face, (transform_surface_to_box, polygon) in box_face_frames(obj.box_size).items():
        if face != "top" and not sides:
            continue
        name = top_name if face == "top" and top_name is not None else f"{obj.name}_{face}"
        surfaces.append(
            ContactSurface(
                name,
                obj.name,
                polygon,
                obj.transform_object_to_world @ transform_surface_to_box,
                friction,
                deformable=False,
            )
        )
    return surfaces


def surface_from_pose(name: str, object_name: str, polygon, transform_surface_to_object,
                      transform_object_to_world, friction: float, deformable: bool = False) -> ContactSurface:
    """A contact surface given in an object's frame, placed in the world.

    Parameters
    ----------
    name, object_name : str
        Surface and object names.
    polygon : (k, 2) float
        Convex counter-clockwise vertices, metres, surface frame.
    transform_surface_to_object, transform_object_to_world : (4, 4) float
        Rigid transforms.
    friction : float
        Friction coefficient.
    deformable : bool
        Whether the object is deformable.
    """
    return ContactSurface(
        name,
        object_name,
        polygon,
        np.asarray(transform_object_to_world) @ np.asarray(transform_surface_to_object),
        friction,
        deformable,
    )


def rpy_rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation ``Rz(yaw) Ry(pitch) Rx(roll)``, radians, ``(3, 3)``."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx
