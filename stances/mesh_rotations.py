"""Mesh rotations: a link's mesh files turned in their own frame, where the URDF misplaces them.

A URDF places each mesh by its ``<origin>``; pinocchio's loader (assimp, through
coal) reads the mesh's vertices as the file stores them, whatever axis a Collada
file declares as up. Most of example-robot-data's iCub meshes (Collada files with
``<up_axis>Y_UP</up_axis>``) then lie a quarter turn about their own x axis from
where the kinematics puts their links (the thigh mesh sticks out forward from the
hip instead of running down to the knee; Gepetto/example-robot-data issue 105);
the hands and a few small discs do not. A robot description lists the links to
turn with the rotation that puts their meshes back (``mesh_rotations`` in
:mod:`stances.description`, measured in ``stances/robots/icub.yaml``): each mesh
geometry of those links, collision and visual, gets its placement

    M_mesh_to_joint <- M_mesh_to_joint * R(rpy),

the rotation acting in the mesh's own frame, before the URDF's origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .errors import FrameNotFound, StanceError

__all__ = ["MeshRotation", "link_names", "turn_meshes"]


@dataclass(frozen=True)
class MeshRotation:
    """A rotation applied to the meshes of some links, in each mesh's own frame.

    Parameters
    ----------
    links : tuple of str
        URDF link names whose mesh geometries are turned.
    rpy_deg : tuple of 3 float
        Roll, pitch, yaw, degrees (the URDF's ``rpy`` convention:
        ``R = Rz(yaw) Ry(pitch) Rx(roll)``).
    """

    links: tuple
    rpy_deg: tuple

    def __post_init__(self) -> None:
        links = tuple(self.links) if isinstance(self.links, (list, tuple)) else ()
        if not links or not all(isinstance(link, str) and link for link in links):
            raise StanceError(f"a mesh rotation needs a non-empty list of link names, got {self.links!r}")
        angles = tuple(self.rpy_deg) if isinstance(self.rpy_deg, (list, tuple)) else ()
        if len(angles) != 3 or not all(
            isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a) for a in angles
        ):
            raise StanceError(f"a mesh rotation's rpy_deg must be 3 finite numbers of degrees, got {self.rpy_deg!r}")
        object.__setattr__(self, "links", links)
        object.__setattr__(self, "rpy_deg", tuple(float(a) for a in angles))

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) float: takes the file's coordinates to the mesh frame the URDF's origin places (p -> R p)."""
        return pin.rpy.rpyToMatrix(*np.radians(self.rpy_deg))


def _is_mesh(geometry_object) -> bool:
    return bool(geometry_object.meshPath) and type(geometry_object.geometry).__name__.startswith(("BVH", "Convex"))


def link_names(model) -> list:
    """Names of the model's body frames (its URDF links).

    Parameters
    ----------
    model : pinocchio.Model

    Returns
    -------
    list of str
    """
    return [frame.name for frame in model.frames if frame.type == pin.FrameType.BODY]


def turn_meshes(model, geometry_model, rotations) -> set:
    """Turn the mesh geometries of the listed links in their own frame.

    Parameters
    ----------
    model : pinocchio.Model
        The model the geometry was built for (its frames name the links).
    geometry_model : pinocchio.GeometryModel
        Collision or visual geometry, modified in place: each mesh attached to
        a listed link gets its placement multiplied on the right by the rotation.
    rotations : iterable of MeshRotation

    Returns
    -------
    set of str
        The links at least one of whose meshes was turned.

    Raises
    ------
    FrameNotFound
        For a link that is not in the model, listing its links.
    StanceError
        For a link listed in two rotations.
    """
    turn_by_link = {}
    known = link_names(model)
    for rotation in rotations:
        for link in rotation.links:
            if link not in known:
                raise FrameNotFound("link", link, known, "mesh_rotations")
            if link in turn_by_link:
                raise StanceError(f"mesh_rotations: link {link!r} is listed twice; give each link one rotation")
            turn_by_link[link] = pin.SE3(rotation.rotation, np.zeros(3))
    turned = set()
    for index, geometry_object in enumerate(geometry_model.geometryObjects):
        link = model.frames[geometry_object.parentFrame].name
        if link in turn_by_link and _is_mesh(geometry_object):
            geometry_object.placement = geometry_object.placement * turn_by_link[link]
            geometry_model.geometryObjects[index] = geometry_object
            turned.add(link)
    return turned
