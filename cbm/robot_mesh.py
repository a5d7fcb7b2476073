"""The robot's own look: its URDF visual geometry as triangle meshes, decimated for drawing.

The pictures and the viewer page draw these meshes placed by forward
kinematics, instead of a stick figure. The meshes are read once per robot
(file and cell size) and kept; a posture only moves them. The decimated meshes are
also kept in the disk cache (:mod:`fem.cache`, its environment variables), keyed by
the URDF's bytes, the robot's locked joints and mesh rotations, the cell and this
code, and checked against the size and modification time of every mesh file they
were read from: reading ANYmal's COLLADA files and taking their triangles out of
pinocchio cost 3.4 s at each ``cbm plan``, Talos's 1.2 s.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import trimesh

from fem.cache import cache_digest, default_cache
from stances import mesh_rotations
from stances.mesh_rotations import turn_meshes

__all__ = ["LinkMesh", "RobotMeshes", "robot_meshes", "visual_model", "cluster_vertices"]

logger = logging.getLogger(__name__)

#: Vertex-cluster size of the meshes drawn, metres: on Talos, 2 cm keeps hands,
#: feet and head recognisable with 33 000 of its 159 000 triangles (1 cm: 76 000).
DEFAULT_CELL = 0.02


@dataclass(frozen=True, eq=False)
class LinkMesh:
    """One visual geometry of the robot.

    Parameters
    ----------
    name : str
        Geometry name in the URDF's visual model.
    joint : int
        Parent joint of ``robot.model``.
    transform_mesh_to_joint : (4, 4) float
        Placement of the mesh in its joint's frame.
    vertices : (v, 3) float
        Metres, mesh frame (the URDF's scale applied).
    triangles : (t, 3) int
        Rows of indices into ``vertices``, outward (counter-clockwise) order.
    """

    name: str
    joint: int
    transform_mesh_to_joint: np.ndarray
    vertices: np.ndarray
    triangles: np.ndarray


@dataclass(frozen=True, eq=False)
class RobotMeshes:
    """Every visual geometry of a robot, ready to be placed.

    Parameters
    ----------
    meshes : tuple of LinkMesh
    """

    meshes: tuple

    @property
    def triangle_count(self):
        """Triangles of all meshes."""
        return sum(len(m.triangles) for m in self.meshes)

    def transforms(self, model, q):
        """Placement of each mesh at a configuration.

        Parameters
        ----------
        model : pinocchio.Model
            The robot's model (the one the meshes were made for).
        q : (nq,) float

        Returns
        -------
        (g, 4, 4) float
            ``transform_mesh_to_world`` of each mesh, in ``meshes`` order.
        """
        data = model.createData()
        pin.forwardKinematics(model, data, np.asarray(q, dtype=float))
        return np.array([data.oMi[m.joint].homogeneous @ m.transform_mesh_to_joint for m in self.meshes])

    def posed(self, model, q):
        """All meshes at a configuration, as one triangle soup.

        Returns
        -------
        vertices : (v, 3) float
            Metres, world frame.
        triangles : (t, 3) int
        """
        vertices, triangles, offset = [], [], 0
        for mesh, transform in zip(self.meshes, self.transforms(model, q)):
            vertices.append(mesh.vertices @ transform[:3, :3].T + transform[:3, 3])
            triangles.append(mesh.triangles + offset)
            offset += len(mesh.vertices)
        if not vertices:
            return np.zeros((0, 3)), np.zeros((0, 3), dtype=int)
        return np.concatenate(vertices), np.concatenate(triangles)


def cluster_vertices(vertices, triangles, cell):
    """Decimate a mesh by merging the vertices in each cube of a grid.

    Each occupied cell keeps one vertex (the mean of its vertices); triangles
    whose corners fall into fewer than three cells vanish, duplicates too.
    Coarse but robust: it never fails on the soup-like meshes URDFs ship.

    Parameters
    ----------
    vertices : (v, 3) float
        Metres.
    triangles : (t, 3) int
    cell : float
        Grid size, metres.

    Returns
    -------
    vertices : (v', 3) float
    triangles : (t', 3) int

    Examples
    --------
    >>> import numpy as np
    >>> square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.001, 0, 0]], float)
    >>> v, t = cluster_vertices(square, np.array([[0, 1, 2], [0, 2, 3], [0, 4, 2]]), 0.1)
    >>> len(v), len(t)  # the sliver (0, 4, 2) collapsed with vertices 0 and 4 merged
    (4, 2)
    """
    vertices = np.asarray(vertices, dtype=float)
    triangles = np.asarray(triangles, dtype=int).reshape(-1, 3)
    keys = np.floor(vertices / cell).astype(np.int64)
    _, cluster, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    cluster = cluster.reshape(-1)
    merged = np.zeros((len(counts), 3))
    np.add.at(merged, cluster, vertices)
    merged /= counts[:, None]
    mapped = cluster[triangles]
    distinct = (mapped[:, 0] != mapped[:, 1]) & (mapped[:, 1] != mapped[:, 2]) & (mapped[:, 0] != mapped[:, 2])
    mapped = mapped[distinct]
    # The same triangle from two sides of a thin part: keep one of each orientation.
    _, first = np.unique(mapped, axis=0, return_index=True)
    mapped = mapped[np.sort(first)]
    used, compact = np.unique(mapped, return_inverse=True)
    return merged[used], compact.reshape(-1, 3)


def _primitive(shape):
    """A coal primitive (Box, Cylinder, Sphere, Capsule) as a trimesh, or None."""
    kind = type(shape).__name__
    if kind == "Box":
        return trimesh.creation.box(extents=2 * np.asarray(shape.halfSide, dtype=float))
    if kind == "Cylinder":
        return trimesh.creation.cylinder(radius=shape.radius, height=2 * shape.halfLength, sections=12)
    if kind == "Sphere":
        return trimesh.creation.icosphere(subdivisions=1, radius=shape.radius)
    if kind == "Capsule":
        return trimesh.creation.capsule(radius=shape.radius, height=2 * shape.halfLength, count=[8, 8])
    return None


def _is_mesh_file(geometry_object):
    """Whether a visual geometry was read from a mesh file (its ``meshPath``; a
    primitive's names its kind)."""
    return bool(geometry_object.meshPath) and type(geometry_object.geometry).__name__.startswith(("BVH", "Convex"))


def _geometry_mesh(geometry_object):
    """(vertices, triangles) of one visual geometry, mesh frame, scale applied; None if unreadable.

    Mesh files are read with trimesh; those it cannot read (COLLADA files, as
    ANYmal's and Romeo's, need pycollada) come from the copy pinocchio loaded
    (with assimp, its scale applied).
    """
    shape = geometry_object.geometry
    if _is_mesh_file(geometry_object):
        scale = np.asarray(geometry_object.meshScale, dtype=float)
        try:
            mesh = trimesh.load(geometry_object.meshPath, force="mesh")
            vertices, triangles = np.asarray(mesh.vertices, dtype=float) * scale, np.asarray(mesh.faces, dtype=int)
        except Exception as error:  # trimesh raises many types on files it cannot read
            if not shape.num_tris:
                logger.warning("visual mesh %s not drawn: %s", geometry_object.meshPath, error)
                return None
            vertices = np.asarray(shape.vertices(), dtype=float)
            triangles = np.array([[t[0], t[1], t[2]] for t in map(shape.tri_indices, range(shape.num_tris))])
        if np.prod(np.sign(scale)) < 0:
            triangles = triangles[:, ::-1]  # a mirror turns the faces inside out
        return vertices, triangles
    mesh = _primitive(shape)
    if mesh is None:
        return None
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=int)


@functools.lru_cache(maxsize=4)
def _visual_geometry(urdf, package_dirs, locked, mesh_rotations):
    full = pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())
    visual = pin.buildGeomFromUrdf(full, urdf, pin.GeometryType.VISUAL, package_dirs=list(package_dirs))
    # As the collision meshes (a link may have no visual mesh: nothing to turn then).
    turn_meshes(full, visual, mesh_rotations)
    if locked:
        q = pin.neutral(full)
        ids = []
        for joint, values in locked:
            ids.append(full.getJointId(joint))
            start = full.idx_qs[ids[-1]]
            q[start : start + len(values)] = values
        _, (visual,) = pin.buildReducedModel(full, [visual], ids, q)
    return visual


def _key(robot):
    """What identifies a robot's visual geometry: URDF, package folders, locked joints, mesh rotations
    (None without a URDF)."""
    urdf = getattr(robot, "urdf", None)
    if urdf is None:
        return None
    from stances.description import read_description

    package_dirs = ()
    source = getattr(robot, "source", "")
    if source:
        package_dirs = tuple(str(p) for p in read_description(source).package_dirs)
    locked = tuple((name, tuple(float(v) for v in values)) for name, values in robot.locked_joints.items())
    return str(urdf), package_dirs, locked, tuple(getattr(robot, "mesh_rotations", ()))


def visual_model(robot):
    """The robot's URDF visual geometry for ``robot.model`` (its locked joints locked).

    Parameters
    ----------
    robot : stances Robot

    Returns
    -------
    pinocchio.GeometryModel or None
        None for a robot without a URDF file. Shared between calls: copy it
        before changing it.
    """
    key = _key(robot)
    return None if key is None else _visual_geometry(*key)


# Name of the disk cache's entry of a robot's meshes (the digest holds the rest).
_ENTRY = "robot_meshes"


@functools.lru_cache(maxsize=4)
def _load(key, cell):
    cache = default_cache()
    digest = None if cache is None else _digest(key, cell)
    if digest is not None:
        known = _from_arrays(cache.load(digest, _ENTRY))
        if known is not None:
            return known
    geometry_objects = _visual_geometry(*key).geometryObjects
    # Stamped before trimesh reads them and again after: an entry is stored only if no file
    # changed in between. (pinocchio's copies, for files trimesh cannot read, are those
    # this process loaded first: a file edited since is not seen until a new process.)
    files = sorted({g.meshPath for g in geometry_objects if _is_mesh_file(g)})
    stamps = [_stamp(path) for path in files]
    meshes = []
    for geometry_object in geometry_objects:
        read = _geometry_mesh(geometry_object)
        if read is None:
            continue
        vertices, triangles = cluster_vertices(*read, cell) if cell > 0 else read
        meshes.append(
            LinkMesh(geometry_object.name, int(geometry_object.parentJoint), geometry_object.placement.homogeneous,
                     vertices, triangles)
        )
    meshes = RobotMeshes(tuple(meshes))
    if digest is not None:
        if all(stamp is not None for stamp in stamps) and stamps == [_stamp(path) for path in files]:
            cache.store(digest, _ENTRY, _to_arrays(meshes, list(zip(files, stamps))))
    return meshes


def _digest(key, cell):
    """The disk cache's digest of a robot's meshes at a cell size (None if its URDF cannot be read)."""
    try:
        urdf = Path(key[0]).read_bytes()
    except OSError:
        return None
    return cache_digest({"urdf": np.frombuffer(urdf, dtype=np.uint8)},
                        {"entry": _ENTRY, "key": repr(key), "cell": repr(float(cell)), "code": _code_digest(),
                         "pinocchio": pin.__version__, "trimesh": trimesh.__version__})


@functools.lru_cache(maxsize=1)
def _code_digest():
    """SHA-256 of the code that makes the meshes (this module and the mesh rotations)."""
    digest = hashlib.sha256()
    for module in (__file__, mesh_rotations.__file__):
        digest.update(Path(module).read_bytes())
    return digest.hexdigest()


def _stamp(path):
    """[size in bytes, modification time in ns] of a file, or None if it cannot be read."""
    try:
        status = os.stat(path)
    except OSError:
        return None
    return [status.st_size, status.st_mtime_ns]


def _to_arrays(meshes, files):
    """A disk cache entry's arrays of ``meshes`` read from ``files``, ``[(path, stamp)]``."""
    items = meshes.meshes
    meta = json.dumps({"names": [m.name for m in items], "files": files}).encode()
    return {
        "meta": np.frombuffer(meta, dtype=np.uint8),
        "joints": np.array([m.joint for m in items], dtype=np.int64),
        "placements": np.array([m.transform_mesh_to_joint for m in items], dtype=float).reshape(-1, 4, 4),
        "vertex_counts": np.array([len(m.vertices) for m in items], dtype=np.int64),
        "vertices": np.concatenate([m.vertices for m in items] or [np.zeros((0, 3))]).astype(float),
        "triangle_counts": np.array([len(m.triangles) for m in items], dtype=np.int64),
        "triangles": np.concatenate([m.triangles for m in items] or [np.zeros((0, 3), int)]).astype(np.int64),
    }


def _from_arrays(arrays):
    """The meshes of a disk cache entry (:func:`_to_arrays`), or None if there is none or a
    mesh file it was read from has changed since."""
    if arrays is None:
        return None
    meta = json.loads(arrays["meta"].tobytes())
    if any(_stamp(path) != stamp for path, stamp in meta["files"]):
        return None
    # Copies: the cache's arrays are read-only views of one buffer, and meshes read from
    # their files are not.
    vertices = np.split(arrays["vertices"].copy(), np.cumsum(arrays["vertex_counts"])[:-1])
    triangles = np.split(arrays["triangles"].copy(), np.cumsum(arrays["triangle_counts"])[:-1])
    return RobotMeshes(tuple(
        LinkMesh(name, int(joint), placement.copy(), v, t)
        for name, joint, placement, v, t in zip(meta["names"], arrays["joints"], arrays["placements"], vertices, triangles)
    ))


#: Most triangles drawn for a robot: the page redraws them all at each frame.
MAX_TRIANGLES = 40_000


def robot_meshes(robot, cell=DEFAULT_CELL, max_triangles=MAX_TRIANGLES):
    """The visual meshes of a robot loaded from a URDF, decimated.

    Parameters
    ----------
    robot : stances Robot
        Its ``urdf`` names the file; its ``locked_joints`` are locked as in
        ``robot.model``.
    cell : float
        Vertex-cluster size, metres (0: the meshes as they are).
    max_triangles : int
        The cell grows by half until the meshes have at most this many
        triangles (ANYmal: 62 000 at 2 cm, 39 000 at 3 cm).

    Returns
    -------
    RobotMeshes or None
        None for a robot without a URDF file (built in code): draw its
        stick figure instead.
    """
    key = _key(robot)
    if key is None:
        return None
    meshes = _load(key, float(cell))
    while cell > 0 and meshes.triangle_count > max_triangles:
        cell *= 1.5
        meshes = _load(key, float(cell))
    return meshes
