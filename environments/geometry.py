"""Small rigid-body and planar-polygon helpers shared by the scene types.

Transforms are ``(4, 4)`` homogeneous matrices named ``transform_a_to_b``: they
map coordinates of a point in frame a to frame b. Polygons are ``(k, 2)`` rows
of vertices, convex and counter-clockwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import SceneError

__all__ = [
    "CollisionShape",
    "readonly_array",
    "rotation_about_z",
    "transform_from_rotation_translation",
    "pose_from_center_yaw",
    "validate_rigid_transform",
    "validate_convex_polygon",
    "polygon_area",
    "polygon_centroid",
    "points_in_convex_polygon",
    "signed_edge_distances",
    "wrap_angle",
    "axes_across",
]

# Orthonormality tolerance: transforms typed by hand in a YAML file (cos/sin to a
# few digits) are still accepted, while a shear or a scale of 1e-6 is refused.
_ROTATION_TOLERANCE = 1e-6


def readonly_array(value, shape: tuple, name: str, dtype=float) -> np.ndarray:
    """Convert to a finite read-only array of a given shape.

    Parameters
    ----------
    value : array_like
        The data.
    shape : tuple
        Expected shape; ``None`` entries match any length.
    name : str
        Name used in the error message.
    dtype : numpy dtype
        Target dtype.

    Returns
    -------
    numpy.ndarray
        A new read-only array.

    Raises
    ------
    SceneError
        If the data cannot be converted, has the wrong shape or is not finite.
    """
    try:
        array = np.array(value, dtype=dtype)
    except (TypeError, ValueError) as error:
        raise SceneError(f"{name} must be numeric with shape {shape}: {error}") from None
    if array.ndim != len(shape) or any(
        want is not None and have != want for have, want in zip(array.shape, shape)
    ):
        raise SceneError(f"{name} must have shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise SceneError(f"{name} must be finite")
    array.setflags(write=False)
    return array


def rotation_about_z(theta: float) -> np.ndarray:
    """Rotation matrix about z.

    Parameters
    ----------
    theta : float
        Angle, radians, counter-clockwise seen from +z.

    Returns
    -------
    (3, 3) float
        The rotation matrix.
    """
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def transform_from_rotation_translation(rotation, translation) -> np.ndarray:
    """Homogeneous transform from a rotation and a translation.

    Parameters
    ----------
    rotation : (3, 3) float
        Rotation matrix.
    translation : (3,) float
        Translation, metres.

    Returns
    -------
    (4, 4) float
        The transform.
    """
    transform = np.eye(4)
    transform[:3, :3] = rotation
    transform[:3, 3] = translation
    return transform


def pose_from_center_yaw(center, yaw: float = 0.0) -> np.ndarray:
    """Transform placing an object frame at ``center`` rotated ``yaw`` about world z.

    Parameters
    ----------
    center : (3,) float
        Origin of the object frame, metres, world frame.
    yaw : float
        Rotation about world z, radians.

    Returns
    -------
    (4, 4) float
        ``transform_object_to_world``.
    """
    center = readonly_array(center, (3,), "center")
    return transform_from_rotation_translation(rotation_about_z(yaw), center)


def validate_rigid_transform(transform, name: str) -> np.ndarray:
    """Check a homogeneous transform is rigid and right-handed.

    Parameters
    ----------
    transform : (4, 4) array_like
        Candidate transform.
    name : str
        Name used in the error message.

    Returns
    -------
    (4, 4) float
        A read-only copy.

    Raises
    ------
    SceneError
        If the rotation block is not orthonormal with determinant +1 or the last
        row is not ``[0, 0, 0, 1]``.
    """
    transform = readonly_array(transform, (4, 4), name)
    rotation = transform[:3, :3]
    if not np.allclose(transform[3], [0.0, 0.0, 0.0, 1.0]):
        raise SceneError(f"{name} must have last row [0, 0, 0, 1], got {transform[3]}")
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=_ROTATION_TOLERANCE):
        raise SceneError(f"{name} rotation block is not orthonormal")
    if np.linalg.det(rotation) < 0.0:
        raise SceneError(f"{name} rotation block is a reflection (determinant -1)")
    return transform


def _cross_2d(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def validate_convex_polygon(polygon, name: str) -> np.ndarray:
    """Check a planar polygon is convex, counter-clockwise and not degenerate.

    Parameters
    ----------
    polygon : (k, 2) array_like
        Vertices, metres; k >= 3.
    name : str
        Name used in the error message.

    Returns
    -------
    (k, 2) float
        A read-only copy.

    Raises
    ------
    SceneError
        If it has fewer than 3 vertices, repeated vertices, is clockwise, or has a
        reflex (or flat) corner.
    """
    polygon = readonly_array(polygon, (None, 2), name)
    if polygon.shape[0] < 3:
        raise SceneError(f"{name} needs at least 3 vertices, got {polygon.shape[0]}")
    edges = np.roll(polygon, -1, axis=0) - polygon
    lengths = np.linalg.norm(edges, axis=1)
    if np.any(lengths <= 1e-12):
        raise SceneError(f"{name} has repeated consecutive vertices")
    turns = _cross_2d(edges, np.roll(edges, -1, axis=0))
    if polygon_area(polygon) <= 0.0:
        raise SceneError(f"{name} must be counter-clockwise (its signed area is <= 0)")
    if np.any(turns <= 1e-12 * lengths * np.roll(lengths, -1)):
        raise SceneError(f"{name} must be strictly convex and counter-clockwise")
    return polygon


def polygon_area(polygon: np.ndarray) -> float:
    """Signed area of a planar polygon (positive when counter-clockwise), m^2."""
    return 0.5 * float(np.sum(_cross_2d(polygon, np.roll(polygon, -1, axis=0))))


def polygon_centroid(polygon: np.ndarray) -> np.ndarray:
    """Area centroid of a planar polygon, ``(2,)`` metres, polygon frame."""
    following = np.roll(polygon, -1, axis=0)
    cross = _cross_2d(polygon, following)
    centroid = ((polygon + following) * cross[:, None]).sum(axis=0) / (3.0 * cross.sum())
    centroid.setflags(write=False)
    return centroid


def points_in_convex_polygon(polygon: np.ndarray, points, margin: float = 0.0) -> np.ndarray:
    """Which points lie in a convex counter-clockwise polygon shrunk by a margin.

    Parameters
    ----------
    polygon : (k, 2) float
        Convex counter-clockwise vertices, metres.
    points : (n, 2) or (2,) float
        Query points, metres, polygon frame.
    margin : float
        Required distance to every edge line, metres (negative grows the polygon).

    Returns
    -------
    (n,) bool, or bool for a single point
        True where inside (boundary included).
    """
    single = np.ndim(points) == 1
    inside = np.all(signed_edge_distances(polygon, points) >= margin - 1e-12, axis=1)
    return bool(inside[0]) if single else inside


def signed_edge_distances(polygon: np.ndarray, points) -> np.ndarray:
    """Signed distances of points to the edge lines of a convex counter-clockwise polygon.

    Parameters
    ----------
    polygon : (k, 2) float
        Convex counter-clockwise vertices, metres.
    points : (n, 2) or (2,) float
        Query points, metres, polygon frame.

    Returns
    -------
    (n, k) float
        Metres, positive inside: a point lies in the polygon where its row is >= 0.
    """
    polygon = np.asarray(polygon, dtype=float)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    # What np.roll and np.linalg.norm give, without their overhead (a stance's build
    # checks its prints' corners against their supports a dozen times).
    edges = np.concatenate((polygon[1:], polygon[:1])) - polygon
    lengths = np.sqrt((edges * edges).sum(axis=1))
    return _cross_2d(edges[None, :, :], points[:, None, :] - polygon[None, :, :]) / lengths


def wrap_angle(theta: float) -> float:
    """Angle wrapped to [-pi, pi], radians."""
    return math.remainder(float(theta), 2.0 * math.pi)


@dataclass(frozen=True, eq=False)
class CollisionShape:
    """A scene object's collision geometry, placed in the world: a box or a triangle mesh.

    Plain data: the posture solver's collision checker (``stances``) builds its
    own shapes from it. Compared by identity (a scene builds each once).

    Parameters
    ----------
    transform_shape_to_world : (4, 4) float
        Placement of the shape's frame, metres.
    box_size : (3,) float, optional
        Side lengths of a box centred at the shape frame's origin, metres.
    vertices : (n, 3) float, optional
        Mesh vertices, metres, shape frame (with ``triangles``; no ``box_size``).
    triangles : (t, 3) int, optional
        Vertex indices of the mesh's triangles.

    Raises
    ------
    SceneError
        Neither or both of a box and a mesh, or malformed arrays.
    """

    transform_shape_to_world: np.ndarray
    box_size: np.ndarray | None = None
    vertices: np.ndarray | None = None
    triangles: np.ndarray | None = None

    def __post_init__(self) -> None:
        transform = validate_rigid_transform(self.transform_shape_to_world, "transform_shape_to_world")
        object.__setattr__(self, "transform_shape_to_world", transform)
        is_mesh = self.vertices is not None or self.triangles is not None
        if (self.box_size is None) == (not is_mesh):
            raise SceneError("a collision shape is either a box (box_size) or a mesh (vertices and triangles)")
        if self.box_size is not None:
            size = readonly_array(self.box_size, (3,), "box_size")
            if np.any(size <= 0.0):
                raise SceneError(f"box_size must be 3 positive lengths, metres, got {size.tolist()}")
            object.__setattr__(self, "box_size", size)
            return
        vertices = readonly_array(self.vertices, (None, 3), "vertices")
        triangles = readonly_array(self.triangles, (None, 3), "triangles", dtype=np.int64)
        if len(triangles) == 0 or triangles.min() < 0 or triangles.max() >= len(vertices):
            raise SceneError(
                f"triangles must index the {len(vertices)} vertices (0 to {len(vertices) - 1}), "
                f"got {len(triangles)} triangles"
                + (f" with indices {triangles.min()} to {triangles.max()}" if len(triangles) else "")
            )
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "triangles", triangles)

    def __repr__(self) -> str:
        origin = ", ".join(f"{v:.4g}" for v in self.transform_shape_to_world[:3, 3])
        if self.box_size is not None:
            return f"CollisionShape(box {' x '.join(f'{v:.4g}' for v in self.box_size)} m at ({origin}))"
        return f"CollisionShape(mesh of {len(self.triangles)} triangles at ({origin}))"


def axes_across(direction) -> np.ndarray:
    """Two orthonormal directions across a unit vector.

    Parameters
    ----------
    direction : (3,) float
        Unit vector.

    Returns
    -------
    (2, 3) float
        Rows ``a, direction x a``: with ``direction`` a right-handed orthonormal frame.
    """
    direction = np.asarray(direction, dtype=float)
    first = np.cross(direction, np.eye(3)[np.argmin(np.abs(direction))])
    first /= np.linalg.norm(first)
    return np.array([first, np.cross(direction, first)])
