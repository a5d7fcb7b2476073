"""Contact surfaces: the flat, convex faces of the scene a robot may touch."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import SceneError
from .geometry import (
    points_in_convex_polygon,
    polygon_area,
    polygon_centroid,
    readonly_array,
    rotation_about_z,
    transform_from_rotation_translation,
    validate_convex_polygon,
    validate_rigid_transform,
)

__all__ = ["ContactSurface", "rectangle"]


def rectangle(length_x: float, length_y: float) -> np.ndarray:
    """Counter-clockwise rectangle centred at the origin.

    Parameters
    ----------
    length_x, length_y : float
        Side lengths, metres.

    Returns
    -------
    (4, 2) float
        Vertices, metres.
    """
    hx, hy = 0.5 * float(length_x), 0.5 * float(length_y)
    return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])


@dataclass(frozen=True, eq=False)
class ContactSurface:
    """A planar convex face of an environment object on which prints are placed.

    Parameters
    ----------
    name : str
        Unique name in the scene, e.g. ``"table_top"``.
    object_name : str
        Name of the rigid or deformable object it belongs to.
    polygon : (k, 2) float
        Convex counter-clockwise vertices, metres, surface frame (z = 0 plane).
    transform_surface_to_world : (4, 4) float
        Rigid transform; its z axis is the object's outward normal at that face
        (pointing into free space).
    friction : float
        Coulomb friction coefficient, > 0.
    deformable : bool
        Whether the face belongs to a deformable (FEM) object.

    Examples
    --------
    >>> surface = ContactSurface("floor", "floor", rectangle(2.0, 2.0), np.eye(4), 0.7)
    >>> surface.transform_print_to_world(0.5, 0.0, 0.0)[:3, 3]
    array([0.5, 0. , 0. ])
    >>> surface.contains([[0.0, 0.0], [1.5, 0.0]]).tolist()
    [True, False]
    """

    name: str
    object_name: str
    polygon: np.ndarray
    transform_surface_to_world: np.ndarray
    friction: float = 0.7
    deformable: bool = False

    def __post_init__(self) -> None:
        for field_name in ("name", "object_name"):
            value = getattr(self, field_name)
            if not isinstance(value, str) or not value:
                raise SceneError(f"ContactSurface.{field_name} must be a non-empty string, got {value!r}")
        label = f"surface {self.name!r}"
        object.__setattr__(self, "polygon", validate_convex_polygon(self.polygon, f"{label} polygon"))
        object.__setattr__(
            self,
            "transform_surface_to_world",
            validate_rigid_transform(self.transform_surface_to_world, f"{label} transform_surface_to_world"),
        )
        friction = self.friction
        if isinstance(friction, bool) or not isinstance(friction, (int, float, np.floating)):
            raise SceneError(f"{label} friction must be a number, got {friction!r}")
        if not (math.isfinite(friction) and friction > 0.0):
            raise SceneError(f"{label} friction must be finite and > 0, got {friction}")
        object.__setattr__(self, "friction", float(friction))
        object.__setattr__(self, "deformable", bool(self.deformable))

    @property
    def normal_in_world(self) -> np.ndarray:
        """Outward unit normal, ``(3,)``, world frame."""
        return self.transform_surface_to_world[:3, 2].copy()

    @property
    def area(self) -> float:
        """Polygon area, m^2."""
        return polygon_area(self.polygon)

    @property
    def centroid(self) -> np.ndarray:
        """Polygon area centroid, ``(2,)`` metres, surface frame."""
        return polygon_centroid(self.polygon)

    def transform_print_to_world(self, x: float, y: float, theta: float) -> np.ndarray:
        """Frame of a print: the surface frame moved by (x, y, 0) and turned theta about z.

        Parameters
        ----------
        x, y : float
            Print origin, metres, surface frame.
        theta : float
            Rotation about the surface normal, radians.

        Returns
        -------
        (4, 4) float
            ``transform_print_to_world``.
        """
        transform_print_to_surface = transform_from_rotation_translation(rotation_about_z(theta), [x, y, 0.0])
        return self.transform_surface_to_world @ transform_print_to_surface

    def point_in_world(self, x: float, y: float) -> np.ndarray:
        """A point of the surface plane, ``(3,)`` metres, world frame."""
        return self.transform_surface_to_world[:3, :3] @ np.array([x, y, 0.0]) + self.transform_surface_to_world[:3, 3]

    def contains(self, points_xy, margin: float = 0.0):
        """Which points lie in the polygon shrunk by a margin.

        Parameters
        ----------
        points_xy : (n, 2) or (2,) float
            Points, metres, surface frame.
        margin : float
            Distance to keep from every edge, metres.

        Returns
        -------
        (n,) bool, or bool for a single point
        """
        return points_in_convex_polygon(self.polygon, points_xy, margin)

    def print_polygon_in_world(self, robot_polygon, x: float, y: float, theta: float) -> np.ndarray:
        """Vertices of a robot surface's print in the world.

        Parameters
        ----------
        robot_polygon : (k, 2) float
            Robot contact surface vertices, metres, in its own contact frame.
        x, y, theta : float
            Print pose in the surface frame (metres, metres, radians).

        Returns
        -------
        (k, 3) float
            Vertices, metres, world frame.
        """
        robot_polygon = readonly_array(robot_polygon, (None, 2), "robot_polygon")
        transform = self.transform_print_to_world(x, y, theta)
        points = np.column_stack([robot_polygon, np.zeros(len(robot_polygon))])
        return points @ transform[:3, :3].T + transform[:3, 3]

    def print_polygon_in_surface(self, robot_polygon, x: float, y: float, theta: float) -> np.ndarray:
        """Vertices of a robot surface's print in the surface frame, ``(k, 2)`` metres."""
        robot_polygon = readonly_array(robot_polygon, (None, 2), "robot_polygon")
        return robot_polygon @ rotation_about_z(theta)[:2, :2].T + np.array([x, y])
