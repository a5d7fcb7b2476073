"""Signed distance and witness points between two placed shapes, with coal.

The collision checker's narrow phase. coal (hpp-fcl's successor, the collision
library pinocchio ships) runs GJK while two shapes are apart and EPA once they
overlap, so one query gives the signed distance, the witness points and the
separating direction. A robot mesh becomes the ``coal.Convex`` convex hull of
its mesh file (conservative: it contains the mesh; its distance varies
smoothly with the posture, which the linearisation needs); primitives stay
primitives. Scene objects arrive as plain shapes from ``environments``
(:class:`~environments.geometry.CollisionShape`: boxes and triangle meshes) and are
built once as coal shapes (:func:`scene_shape`).

Accuracy, measured on Talos with coal 3.0.3 (20 random postures, 0.3 rad
normal perturbations of half sitting; every pair within 10 m of a floor slab, a
table box and the SRDF self-collision pairs: 9960 pairs). Independent check,
brute force on the vertices for the 2231 separated polytope pairs of 6 of
those postures (hull-hull, hull-box): along the reported normal, the gap
between the two vertex sets' extents is a lower bound of the distance, and the
witness points, inside both hulls (checked on the hulls' face planes), are an
upper bound. They certify:

- the distance to 1.2e-13 m (coal's default GJK tolerance, 1e-6, left gaps of
  up to 2.8e-6 m; hence 1e-9 in :class:`DistanceQuery`, at a cost within this
  machine's timing noise);
- the witness points: within 3.4e-15 m of the hulls.

Against the python-fcl path this replaced (same postures): robot hull vs box,
which went through the hull's surface triangles, agreed to 1.2e-13 m in
distance, while witness points differ by up to 1.75 mm (p99 66 um): with
equal certified distances, the likely cause is closest features that are not
unique (a sole parallel to the floor), where any point of the face is a witness.
Curved primitives (the wrist cylinders) are outside the certificate; the
analytic sphere-cylinder test in ``tests/test_collision.py`` covers them.
python-fcl's GJK on hull pairs (self-collision) overestimated distances by up
to 1.69 mm (p99 1.1 um), which the certificate shows coal does not.

``tests/test_narrow_phase.py`` repeats the certificate on random hull pairs,
checks the exact penetration depth of overlapping boxes, and the distance of
every hull above a floor against its lowest mesh vertex.
"""

from __future__ import annotations

import functools
import os
import weakref

import numpy as np
import trimesh

from environments.geometry import CollisionShape

from .errors import StanceError

import coal  # pinocchio's collision library since pinocchio 3.4 (hpp-fcl before, other names)

__all__ = [
    "CollisionSetupError", "DistanceQuery", "box_shape", "robot_shape", "scene_geometry", "scene_shape", "witnesses",
    "world_bounds", "world_boxes",
]


class CollisionSetupError(StanceError):
    """Invalid collision set-up: unknown names in an exclusion, duplicate or
    unsupported geometry, malformed scene objects."""


def _convex(vertices: np.ndarray, faces: np.ndarray):
    """``coal.Convex`` from hull vertices ``(n, 3)`` and outward faces ``(f, 3)``."""
    points = coal.StdVec_Vec3s()
    points.extend(list(np.asarray(vertices, dtype=float)))
    triangles = coal.StdVec_Triangle()
    triangles.extend([coal.Triangle(int(i), int(j), int(k)) for i, j, k in faces])
    return coal.Convex(points, triangles)


def box_shape(side) -> "coal.Convex":
    """A box of sides ``side`` (3,), metres, centred at its origin, as a ``coal.Convex``.

    Not ``coal.Box``: coal 3.0's box support function inflates the box's lower
    half-sides by 1e-10 or not depending on the first direction it is ever asked
    about in the process (a ``static const`` set from that call's argument), so
    every box distance afterwards, 1e-11 to 4e-11 m apart between processes,
    depended on which box query came first; the solver then took other
    iterations. A polytope's support has no such state, and GJK is exact on it.
    """
    return _box_shape(*(float(length) for length in side))


@functools.lru_cache(maxsize=256)
def _box_shape(x: float, y: float, z: float):
    # One shape per size: a polytope holds no query state, so scenes and checkers
    # share it (a checker is built per stance, with every box of the scene).
    box = trimesh.creation.box(extents=(x, y, z))
    return _convex(box.vertices, box.faces)


def _mesh_points(geometry_object) -> np.ndarray:
    """(n, 3) float: a collision mesh's vertices, scaled, metres, geometry frame.

    Read from the mesh file; when trimesh cannot read it (COLLADA files, such
    as Romeo's, need pycollada), the copy pinocchio loaded (scale applied).

    Raises
    ------
    CollisionSetupError
        If neither the file nor pinocchio's copy gives vertices.
    """
    try:
        mesh = trimesh.load(geometry_object.meshPath, force="mesh")
    except Exception as error:  # trimesh raises many types on unreadable files
        shape = geometry_object.geometry
        if hasattr(shape, "vertices") and shape.num_vertices > 0:
            return np.asarray(shape.vertices(), dtype=float)
        raise CollisionSetupError(
            f"cannot read collision mesh {geometry_object.meshPath!r} of {geometry_object.name!r}: {error}"
        ) from error
    return np.asarray(mesh.vertices, dtype=float) * np.asarray(geometry_object.meshScale)


# Each mesh file's hull, by its path, modification time, size and scale: a robot loaded again
# in a process (a plan that loads its scenario's robot) reads and hulls no mesh (Talos: 0.2 of
# 0.3 s a load); a polytope holds no query state, so robots share it.
_HULLS: dict = {}


def _mesh_hull(geometry_object):
    """:func:`robot_shape` of a mesh geometry: its points' convex hull, read from the file."""
    # Negative scales mirror the mesh (Talos's right limbs); the hull of the scaled
    # points is rebuilt, so its faces are outward-oriented again.
    hull = trimesh.convex.convex_hull(_mesh_points(geometry_object))
    vertices = np.asarray(hull.vertices, dtype=float)
    center = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    radius = float(np.max(np.linalg.norm(vertices - center, axis=1)))
    return _convex(vertices, np.asarray(hull.faces)), center, radius


def robot_shape(geometry_object):
    """coal shape of a robot collision geometry and its bounding sphere.

    Parameters
    ----------
    geometry_object : pinocchio.GeometryObject

    Returns
    -------
    shape : coal.CollisionGeometry
        The convex hull (``coal.Convex``) of a mesh, or the primitive itself.
    center : (3,) float
        Bounding sphere centre, metres, geometry frame.
    radius : float
        Bounding sphere radius, metres.

    Raises
    ------
    CollisionSetupError
        Unreadable mesh file, or a type other than mesh, Sphere, Box,
        Cylinder, Capsule.
    """
    shape = geometry_object.geometry
    kind = type(shape).__name__
    if geometry_object.meshPath and ("BVH" in kind or "Convex" in kind):
        try:
            stat = os.stat(geometry_object.meshPath)
        except OSError:
            return _mesh_hull(geometry_object)  # (pinocchio's copy, or the error naming the file)
        key = (geometry_object.meshPath, stat.st_mtime_ns, stat.st_size,
               tuple(float(v) for v in geometry_object.meshScale))
        if key not in _HULLS:
            _HULLS[key] = _mesh_hull(geometry_object)
        shape, center, radius = _HULLS[key]
        return shape, center.copy(), radius
    if kind == "Sphere":
        return coal.Sphere(shape.radius), np.zeros(3), float(shape.radius)
    if kind == "Box":
        half = np.asarray(shape.halfSide, dtype=float)
        return box_shape(2.0 * half), np.zeros(3), float(np.linalg.norm(half))
    if kind == "Cylinder":
        radius = float(np.hypot(shape.radius, shape.halfLength))
        return coal.Cylinder(shape.radius, 2.0 * shape.halfLength), np.zeros(3), radius
    if kind == "Capsule":
        radius = float(shape.radius + shape.halfLength)
        return coal.Capsule(shape.radius, 2.0 * shape.halfLength), np.zeros(3), radius
    raise CollisionSetupError(
        f"collision geometry {geometry_object.name!r} has unsupported type {kind}; "
        "supported: meshes (with a meshPath), Sphere, Box, Cylinder, Capsule"
    )


# Meshes converted once per scene shape: scenes keep their shapes, and the
# solver builds a checker per stance.
_MESH_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _mesh_shape(shape):
    """coal shape of a :class:`~environments.geometry.CollisionShape` mesh."""
    cached = _MESH_CACHE.get(shape)
    if cached is not None:
        return cached
    vertices = np.asarray(shape.vertices, dtype=float)
    triangles = np.asarray(shape.triangles, dtype=int)
    mesh = trimesh.Trimesh(vertices, triangles)
    if mesh.is_watertight and mesh.is_convex:
        # A closed convex mesh is its hull: as a solid it gets a penetration depth.
        hull = trimesh.convex.convex_hull(vertices)
        converted = _convex(hull.vertices, hull.faces)
    else:
        converted = coal.BVHModelOBBRSS()
        converted.beginModel(len(triangles), len(vertices))
        converted.addVertices(vertices)
        converted.addTriangles(triangles)
        converted.endModel()
    _MESH_CACHE[shape] = converted
    return converted


def scene_shape(name: str, scene_object):
    """coal shape and world placement of a static scene object.

    Parameters
    ----------
    name : str
        Object name, for messages.
    scene_object : environments.geometry.CollisionShape or coal.CollisionObject
        Placed in the world frame (what ``Scene.collision_objects`` gives). A
        box becomes a box polytope (:func:`box_shape`); a mesh a
        ``coal.Convex`` when closed and convex, a ``coal.BVHModelOBBRSS``
        otherwise. A coal object is taken as it is (a ``coal.Box`` as a box
        polytope).

    Returns
    -------
    shape : coal.CollisionGeometry
    rotation : (3, 3) float
        Object to world.
    translation : (3,) float
        Object origin, metres, world frame.

    Raises
    ------
    CollisionSetupError
        Another type of object.
    """
    if isinstance(scene_object, coal.CollisionObject):
        placement = scene_object.getTransform()
        shape = scene_object.collisionGeometry()
        if isinstance(shape, coal.Box):
            shape = box_shape(2.0 * np.asarray(shape.halfSide, dtype=float))
        return shape, np.array(placement.getRotation()), np.array(placement.getTranslation())
    if not isinstance(scene_object, CollisionShape):
        raise CollisionSetupError(
            f"scene object {name!r} must be an environments.geometry.CollisionShape or a "
            f"coal.CollisionObject, got {type(scene_object).__name__}"
        )
    transform = scene_object.transform_shape_to_world
    shape = box_shape(scene_object.box_size) if scene_object.box_size is not None else _mesh_shape(scene_object)
    return shape, np.array(transform[:3, :3]), np.array(transform[:3, 3])


# A scene shape's coal shape, placement and world bounds, made once per shape (a checker is
# built per stance; a stepped mesh's boxes took a millisecond to group).
_SCENE_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def scene_geometry(name: str, scene_object):
    """:func:`scene_shape` of a scene object with its :func:`world_bounds` and
    :func:`world_boxes`, made once per :class:`~environments.geometry.CollisionShape`.

    Returns
    -------
    shape, rotation, translation
        As :func:`scene_shape` (the arrays read-only).
    bounds : (2, 3) float
    boxes : (b, 2, 3) float
    """
    known = _SCENE_CACHE.get(scene_object) if isinstance(scene_object, CollisionShape) else None
    if known is not None:
        return known
    shape, rotation, translation = scene_shape(name, scene_object)
    # A mesh's triangles as given: the BVH holds them as they are (read back from it one call a
    # triangle, world_boxes took 29 ms a call on foot-and-hand-on-foam's deformed surface of
    # 7,048 triangles, which stances.verify converts at every call; 8.5 ms so).
    triangles = scene_object.triangles if isinstance(scene_object, CollisionShape) else None
    known = (shape, rotation, translation, world_bounds(shape, rotation, translation),
             world_boxes(shape, rotation, translation, triangles=triangles))
    for array in known[1:]:
        array.setflags(write=False)
    if isinstance(scene_object, CollisionShape):
        _SCENE_CACHE[scene_object] = known
    return known


def world_bounds(shape, rotation, translation) -> np.ndarray:
    """(2, 3) float: world axis-aligned bounds [lower, upper] of a placed shape, metres.

    The local bounding box's corners, placed: exact for boxes and meshes
    placed axis-aligned, conservative otherwise.
    """
    shape.computeLocalAABB()
    box = shape.aabb_local
    low, high = np.array(box.min_), np.array(box.max_)
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
        raise CollisionSetupError("scene objects must be bounded (no half-spaces or planes)")
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    placed = corners @ np.asarray(rotation).T + translation
    return np.array([placed.min(axis=0), placed.max(axis=0)])


def world_boxes(shape, rotation, translation, depth: int = 5, triangles=None) -> np.ndarray:
    """(b, 2, 3) float: world boxes [lower, upper] whose union holds a placed shape, metres.

    A triangle mesh (a non-convex support such as a stepped foam block) gets the
    boxes of ``2 ** depth`` groups of its triangles, split at the median along the
    widest spread of their centroids: far tighter than its one bounding box, which
    let pairs 0.2 m away through to a costly mesh query. Other shapes get their
    :func:`world_bounds`. ``triangles``: (t, 3) int, the mesh's triangles as the shape was
    built from them (by default read back from it, one call a triangle).
    """
    if not isinstance(shape, coal.BVHModelBase):
        return world_bounds(shape, rotation, translation)[None]
    vertices = np.asarray(shape.vertices(), dtype=float) @ np.asarray(rotation).T + translation
    if triangles is None:
        triangles = np.array([[t[0], t[1], t[2]] for t in map(shape.tri_indices, range(shape.num_tris))], dtype=int)
    triangles = np.asarray(triangles, dtype=int)
    corners = vertices[triangles.reshape(-1, 3)]  # (t, 3 corners, 3)
    groups = [np.arange(len(corners))]
    for _ in range(depth):
        split = []
        for group in groups:
            if len(group) < 2:
                split.append(group)
                continue
            centroids = corners[group].mean(axis=1)
            order = group[np.argsort(centroids[:, int(np.argmax(np.ptp(centroids, axis=0)))], kind="stable")]
            split.extend((order[: len(order) // 2], order[len(order) // 2 :]))
        groups = split
    return np.array([[corners[g].min(axis=(0, 1)), corners[g].max(axis=(0, 1))] for g in groups if len(g)])


class DistanceQuery:
    """Signed distance between two placed shapes, reusing one coal request.

    :meth:`distance` measures; :meth:`witness` then reads the witness points
    and direction of that measurement, so pairs found beyond the margin skip
    the conversions. Every query starts from coal's default guess (no warm
    start): a result depends only on the two placements, and the solver stays
    bitwise deterministic.
    """

    def __init__(self) -> None:
        self._request = coal.DistanceRequest()
        self._request.enable_signed_distance = True
        # coal's default 1e-6 lets GJK stop with a duality gap of up to ~3e-6 m
        # between hulls (measured); at 1e-9 polytope distances are exact to
        # 1e-13 m for the same time, and curved shapes still converge.
        self._request.gjk_tolerance = 1e-9
        self._request.epa_tolerance = 1e-9
        self._result = coal.DistanceResult()

    def distance(self, shape_a, placement_a, shape_b, placement_b) -> float:
        """Signed distance of a and b, metres; ``<= 0`` means penetration (minus the depth).

        Parameters
        ----------
        shape_a, shape_b : coal.CollisionGeometry
        placement_a, placement_b : coal.Transform3s
            Shape to world.
        """
        self._result.clear()
        return float(coal.distance(shape_a, placement_a, shape_b, placement_b, self._request, self._result))

    def kept_distance(self, shape_a, placement_a, shape_b, placement_b, result):
        """:meth:`distance` into ``result``, kept for a later :meth:`witness`.

        Parameters
        ----------
        result : coal.DistanceResult
            Where to measure (cleared first): the caller keeps it, and reuses it once
            the witness is read (a result made per call cost a fifth of it).

        Returns
        -------
        distance : float
            As :meth:`distance` (the same number).
        result : coal.DistanceResult
            Pass it to :meth:`witness` to read this measurement's witness points.
        """
        result.clear()
        return float(coal.distance(shape_a, placement_a, shape_b, placement_b, self._request, result)), result

    def witness(self, result=None):
        """Witness points and separating direction of the last :meth:`distance`, or of
        the measurement ``result`` holds (from :meth:`kept_distance`).

        Returns
        -------
        point_a, point_b : (3,) float
            Witness points, metres, world frame; ``point_b - point_a`` is the
            distance times the direction from a to b (each point lies inside
            the other body when they penetrate).
        normal : (3,) float or None
            Unit vector, world frame, along which translating a increases the
            distance; None when coal gives no direction.
        """
        points_a, points_b, normals, directed = witnesses([self._result if result is None else result])
        return points_a[0], points_b[0], normals[0] if directed[0] else None


def witnesses(results):
    """Witness points and separating directions of several measurements at once.

    What :meth:`DistanceQuery.witness` gives each, read into arrays (the linearisation
    reads some 20 a call: one by one, the conversions cost as much as coal's distances).

    Parameters
    ----------
    results : sequence of coal.DistanceResult
        k measurements (:meth:`DistanceQuery.kept_distance`).

    Returns
    -------
    points_a, points_b : (k, 3) float
        Witness points, metres, world frame, as :meth:`DistanceQuery.witness`.
    normals : (k, 3) float
        Unit vectors, world frame, along which translating a increases the distance;
        where ``directed`` is False, coal's (near zero) vector as it gave it.
    directed : (k,) bool
        Whether coal gave a direction.
    """
    # coal's normal points from a to b, apart or penetrating; ``result.normal`` is a view
    # into the result, hence the copy.
    normals = -np.array([result.normal for result in results], dtype=float).reshape(-1, 3)
    # Summed in the order of ``v @ v`` (a three-term einsum differs in the last bit).
    lengths = np.sqrt((normals * normals).sum(axis=1))
    directed = lengths > 0.5
    normals[directed] /= lengths[directed, None]
    points_a = np.array([result.getNearestPoint1() for result in results], dtype=float).reshape(-1, 3)
    points_b = np.array([result.getNearestPoint2() for result in results], dtype=float).reshape(-1, 3)
    return points_a, points_b, normals, directed
