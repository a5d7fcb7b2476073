"""Checks that a scene makes physical sense: soft objects rest on something, objects do not overlap.

A soft box floating 0.7 m above the floor, or a rigid slab filling most of a soft
cube, still gives "feasible" stances: the FEM body is fixed wherever its fixed set
is, and collision checks only concern the robot. These checks refuse such scenes
when they are read, unless the file says the odd placement is intended.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Collection

import numpy as np

from .errors import SceneError
from .geometry import points_in_convex_polygon
from .mesh_surfaces import SurfaceSearch, find_surfaces
from .scene import Scene

__all__ = ["SceneSenseError", "check_supported", "find_overlaps", "check_overlaps", "check_self_weight", "CONTACT_TOLERANCE"]

class SceneSenseError(SceneError):
    """A scene that does not make physical sense, naming the objects at fault.

    Parameters
    ----------
    message : str
        What is wrong and how to fix it.
    objects : tuple of str
        The objects at fault, in scene order.
    """

    def __init__(self, message: str, objects: tuple[str, ...]) -> None:
        super().__init__(message)
        self.objects = objects


CONTACT_TOLERANCE = 1e-3
"""Metres: a fixed node within this distance of a rigid object's face rests on it, and
two objects overlap only where one reaches more than this far into the other (a
box placed by hand on the floor, its centre typed to a millimetre, still touches)."""

logger = logging.getLogger(__name__)

# Every flat face of a rigid object may carry a soft object (the top of a table,
# a shelf's side for a soft bumper), however small.
_SUPPORT_SEARCH = SurfaceSearch(min_area=1e-12, sides=True)
# Points sampled inside a box along each axis (cell centres of a 4 x 4 x 4 grid).
_BOX_SAMPLES = 4
# Most interior points of one deformable object tested against another object.
_MAX_SAMPLES = 4000


def check_supported(scene: Scene, floating: Collection[str] = ()) -> None:
    """Check every deformable object's fixed nodes lie on a face of a rigid object, and no
    rigid object rests on a soft one.

    A rigid object is fixed in the world: one placed on a soft mat (a crate on foam) would
    stand there with the mat carrying none of it, and a robot on it none either.

    Parameters
    ----------
    scene : Scene
    floating : collection of str
        Objects exempt from the check (held in place some other way).

    Raises
    ------
    SceneSenseError
        Naming the first object with a fixed node on no rigid face, and where
        its lowest such node is; or the first rigid object resting on a soft
        surface, and the soft object.
    """
    _check_rigid_on_soft(scene, floating)
    supports = [
        (obj.transform_object_to_world, piece)
        for obj in scene.rigid_objects
        for piece in find_surfaces(obj.mesh, obj.transform_object_to_world[:3, :3], _SUPPORT_SEARCH)
    ]
    for obj in scene.deformable_objects:
        if obj.name in floating:
            continue
        points = obj.points_in_world(np.asarray(obj.mesh.nodes)[obj.body.fixed_nodes])
        resting = np.zeros(len(points), dtype=bool)
        for transform_object_to_world, piece in supports:
            frame = transform_object_to_world @ piece.transform_surface_to_object
            local = (points - frame[:3, 3]) @ frame[:3, :3]
            on_plane = np.abs(local[:, 2]) <= CONTACT_TOLERANCE
            resting |= on_plane & points_in_convex_polygon(piece.polygon, local[:, :2], -CONTACT_TOLERANCE)
        if not resting.all():
            loose = points[~resting]
            raise SceneSenseError(
                f"soft object {obj.name!r} is fixed at {len(loose)} node(s) that rest on no rigid object (the lowest at "
                f"z = {loose[:, 2].min():.4g} m): put its fixed part on the floor or on a rigid "
                "object, or write 'floating: true' on it if something else holds it",
                (obj.name,),
            )


def _check_rigid_on_soft(scene: Scene, floating: Collection[str]) -> None:
    """Refuse a rigid object one of whose downward faces lies on a soft object's upward contact
    surface: a point of either (the face's corners, edge midpoints and centroid; the surface's
    corners, pulled in by the tolerance, and a grid over it) inside the other, on its plane."""
    soft = [surface for surface in scene.surfaces.values()
            if surface.deformable and surface.transform_surface_to_world[2, 2] > 0.9]  # faces up
    if not soft:
        return
    for obj in scene.rigid_objects:
        if obj.name in floating:
            continue
        down = _downward_triangles(obj)
        if not len(down):
            continue
        points = np.einsum("sk,tkj->tsj", _TRIANGLE_SAMPLES, down).reshape(-1, 3)
        low, high = down.min(axis=(0, 1)), down.max(axis=(0, 1))
        for surface in soft:
            frame = surface.transform_surface_to_world
            corners = surface.polygon @ frame[:3, :2].T + frame[:3, 3]
            if np.any(corners.min(axis=0) > high + CONTACT_TOLERANCE) or np.any(corners.max(axis=0) < low - CONTACT_TOLERANCE):
                continue  # apart
            local = (points - frame[:3, 3]) @ frame[:3, :3]
            on = (np.abs(local[:, 2]) <= CONTACT_TOLERANCE) & points_in_convex_polygon(surface.polygon, local[:, :2], CONTACT_TOLERANCE)
            mine = _polygon_samples(surface.polygon) @ frame[:3, :2].T + frame[:3, 3]
            if on.any() or _under_triangles(down, mine).any():
                raise SceneSenseError(
                    f"rigid object {obj.name!r} rests on soft object {surface.object_name!r} (on {surface.name!r}): "
                    f"rigid objects are fixed in the world, so {surface.object_name!r} would carry none of its weight "
                    "nor of what stands on it; make it soft, move it onto a rigid object, or write 'floating: true' "
                    "on it if something else holds it",
                    (surface.object_name, obj.name),
                )


# A triangle's corners, edge midpoints and centroid, as barycentric weights.
_TRIANGLE_SAMPLES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5],
                              [1 / 3, 1 / 3, 1 / 3]])


def _downward_triangles(obj) -> np.ndarray:
    """(t, 3, 3) a rigid object's boundary triangles that look down (its base), world frame."""
    triangles = _triangles_in_world(obj)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    return triangles[(lengths > 0.0) & (normals[:, 2] < -0.9 * lengths)]


def _polygon_samples(polygon: np.ndarray, per_side: int = 5) -> np.ndarray:
    """(k, 2) points of a convex polygon: its corners pulled toward its centroid by the
    contact tolerance, and a grid over its bounding box kept where inside."""
    centroid = polygon.mean(axis=0)
    towards = centroid - polygon
    corners = polygon + CONTACT_TOLERANCE * towards / np.maximum(np.linalg.norm(towards, axis=1), 1e-300)[:, None]
    low, high = polygon.min(axis=0), polygon.max(axis=0)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, per_side + 2)[1:-1], np.linspace(0.0, 1.0, per_side + 2)[1:-1])
    grid = low + np.column_stack([u.ravel(), v.ravel()]) * (high - low)
    return np.concatenate([corners, grid[points_in_convex_polygon(polygon, grid, CONTACT_TOLERANCE)], centroid[None]])


def _under_triangles(triangles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(k,) bool: which world points lie on one of the (t, 3, 3) triangles, within the contact
    tolerance of its plane and inside it seen from above."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = (b - a)[:, :2], (c - a)[:, :2]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]  # (t,) never 0: the triangles face down
    d = points[:, None, :2] - a[None, :, :2]  # (k, t, 2)
    s = (d[..., 0] * e2[None, :, 1] - d[..., 1] * e2[None, :, 0]) / det
    t = (e1[None, :, 0] * d[..., 1] - e1[None, :, 1] * d[..., 0]) / det
    inside = (s >= 0.0) & (t >= 0.0) & (s + t <= 1.0)
    height = a[None, :, 2] + s * (b - a)[None, :, 2] + t * (c - a)[None, :, 2]
    return np.any(inside & (np.abs(points[:, None, 2] - height) <= CONTACT_TOLERANCE), axis=1)


def _bounds_in_world(obj) -> np.ndarray:
    """(2, 3) world axis-aligned bounds of an object at rest, metres."""
    if obj.deformable:
        points = obj.points_in_world(obj.mesh.nodes)
    else:
        points = np.asarray(obj.mesh_in_world().vertices)
    return np.array([points.min(axis=0), points.max(axis=0)])


def _box_in_world(obj):
    """``(transform_box_to_world, half sizes)`` when the object is a box (or a soft mesh filling its box), else None."""
    if not obj.deformable:
        return None if obj.box_size is None else (obj.transform_object_to_world, 0.5 * np.asarray(obj.box_size))
    nodes = np.asarray(obj.mesh.nodes, dtype=float)
    low, high = nodes.min(axis=0), nodes.max(axis=0)
    if abs(float(np.sum(obj.mesh.volumes)) - np.prod(high - low)) > 1e-6 * np.prod(high - low):
        return None
    transform = obj.transform_body_to_world.copy()
    transform[:3, 3] = obj.points_in_world([0.5 * (low + high)])[0]
    return transform, 0.5 * (high - low)


def _triangles_in_world(obj) -> np.ndarray:
    """(T, 3, 3) boundary triangles, outward, metres, world frame."""
    if obj.deformable:
        return obj.rest_surface()
    mesh = obj.mesh_in_world()
    return np.asarray(mesh.vertices)[np.asarray(mesh.faces)]


def _inside(obj, points: np.ndarray) -> np.ndarray:
    """Which world points are inside an object: exactly for boxes, by winding number otherwise."""
    box = _box_in_world(obj)
    if box is not None:
        transform, half = box
        local = (points - transform[:3, 3]) @ transform[:3, :3]
        return np.all(np.abs(local) < half, axis=1)
    triangles = _triangles_in_world(obj)
    winding = np.zeros(len(points))
    chunk = max(1, 2_000_000 // max(1, len(triangles)))
    for start in range(0, len(points), chunk):
        # Solid angle of each triangle seen from each point (Van Oosterom and Strackee).
        a, b, c = (triangles[None, :, k, :] - points[start : start + chunk, None, :] for k in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
        numerator = np.einsum("ptk,ptk->pt", a, np.cross(b, c))
        denominator = la * lb * lc + np.einsum("ptk,ptk->pt", a, b) * lc + np.einsum("ptk,ptk->pt", b, c) * la
        denominator += np.einsum("ptk,ptk->pt", c, a) * lb
        winding[start : start + chunk] = np.sum(2.0 * np.arctan2(numerator, denominator), axis=1) / (4.0 * math.pi)
    return winding > 0.5


def _interior_samples(obj) -> np.ndarray:
    """World points inside an object, at least :data:`CONTACT_TOLERANCE` from its faces where it is thick enough."""
    box = _box_in_world(obj)
    if box is not None:
        transform, half = box
        fractions = (np.arange(_BOX_SAMPLES) + 0.5) / _BOX_SAMPLES * 2.0 - 1.0
        grid = np.stack(np.meshgrid(fractions, fractions, fractions, indexing="ij"), axis=-1).reshape(-1, 3) * half
        return grid @ transform[:3, :3].T + transform[:3, 3]
    if obj.deformable:
        nodes, tets = np.asarray(obj.mesh.nodes), np.asarray(obj.mesh.tets)
        step = max(1, len(tets) // _MAX_SAMPLES)
        return obj.points_in_world(nodes[tets[::step]].mean(axis=1))
    # Face centres of a rigid mesh pushed inward: they lie inside near every face.
    mesh = obj.mesh_in_world()
    return np.asarray(mesh.triangles_center) - 2.0 * CONTACT_TOLERANCE * np.asarray(mesh.face_normals)


def find_overlaps(scene: Scene) -> list[tuple[str, str, int]]:
    """Pairs of objects reaching into each other by more than :data:`CONTACT_TOLERANCE`.

    Each object's interior sample points (a grid in a box, tet centroids of a
    soft body, face centres pushed inward on a rigid mesh) are tested against the
    other object (exactly for boxes, by winding number on its boundary otherwise).

    Returns
    -------
    list of (str, str, int)
        ``(first, second, points)`` in scene order: the number of sample points
        of either object found inside the other.
    """
    objects = list(scene.rigid_objects) + list(scene.deformable_objects)
    bounds = [_bounds_in_world(obj) for obj in objects]
    samples: dict[int, np.ndarray] = {}
    overlaps = []
    for i in range(len(objects)):
        for j in range(i + 1, len(objects)):
            depth = np.minimum(bounds[i][1], bounds[j][1]) - np.maximum(bounds[i][0], bounds[j][0])
            if np.any(depth <= CONTACT_TOLERANCE):
                continue
            count = 0
            for this, other in ((i, j), (j, i)):
                if this not in samples:
                    samples[this] = _interior_samples(objects[this])
                points = samples[this]
                near = np.all((points > bounds[other][0]) & (points < bounds[other][1]), axis=1)
                count += int(np.count_nonzero(_inside(objects[other], points[near]))) if near.any() else 0
            if count:
                overlaps.append((objects[i].name, objects[j].name, count))
    return overlaps


def check_overlaps(scene: Scene, allowed: Collection[frozenset] = ()) -> None:
    """Refuse objects that overlap, except pairs the user says may (logged at DEBUG level).

    Parameters
    ----------
    scene : Scene
    allowed : collection of frozenset of two str
        Pairs of object names whose overlap is intended: accepted, and logged
        (not a ``warnings`` warning: a scene declared so is loaded by every
        ``cbm scenarios``, which must stay quiet).

    Raises
    ------
    SceneSenseError
        Naming the first two objects that overlap without being allowed to.
    """
    for first, second, count in find_overlaps(scene):
        if frozenset((first, second)) in allowed:
            logger.debug("objects %r and %r overlap, as declared in allowed_overlaps", first, second)
            continue
        raise SceneSenseError(
            f"objects {first!r} and {second!r} overlap ({count} sample point(s) of one lie inside the other): move "
            f"one, or list the pair in allowed_overlaps if it is intended, e.g. allowed_overlaps: [[{first}, {second}]]",
            (first, second),
        )


def check_self_weight(scene: Scene) -> None:
    """Refuse a scene whose soft object its own weight alone strains beyond its strain bound.

    Not run when a scene is read: it takes a solve per object (a factorisation the
    first time, the disk cache after). A planner or a stance check runs it first, so
    that such a scene is refused at once rather than stance by stance.

    Raises
    ------
    SceneError
        Naming the object, the strain, where it is and the bound
        (:attr:`environments.DeformableObject.self_weight_field`).
    """
    for soft in scene.deformable_objects:
        soft.self_weight_field
