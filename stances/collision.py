"""Collision distances between the robot and the scene, linearised for the posture solver.

At each SQP iteration the posture solver keeps every relevant pair of bodies
apart with a linearised constraint ``d + row @ dq >= d_min``. This module
measures the pairs and their rows:

- robot geometry vs scene object (``joint_b = 0``, the universe),
- robot geometry vs robot geometry, for the self-collision pairs the SRDF
  allows (``robot.collision_model.collisionPairs``).

The narrow phase is coal's GJK/EPA (:mod:`stances.narrow_phase`, which states
its measured accuracy). Robot meshes become the ``coal.Convex`` convex hull of
their mesh file once, at construction: GJK on a hull is faster than on a
triangle soup and its distance varies smoothly with the posture, which the
linearisation needs; the hull is conservative (it contains the mesh).
Primitives stay primitives. Scene objects, plain boxes and meshes from
``environments`` (:class:`~environments.geometry.CollisionShape`), become coal
shapes (built once per shape and shared).

Because a python-level coal call still costs microseconds, a numpy broad phase
runs first over all pairs at once: each robot geometry is bounded by a sphere
and by a box, both fixed in its geometry frame (the box is turned into its
world axis-aligned bounds), each (static) scene object by its world
axis-aligned box, and only the pairs whose bounds are closer than ``margin``
reach coal. A non-convex mesh object is bounded by the boxes of groups of
its triangles (:func:`stances.narrow_phase.world_boxes`): at foot-and-hand's
posture on the stepped foam block, six leg and base pairs 0.13-0.24 m from the
mesh (0.7 ms of coal's mesh queries) no longer reach coal.

A posture solver's line search needs the distances only
(:meth:`CollisionChecker.closest_distances`), the linearisation the witness
points of the closest pairs, read as arrays (:meth:`CollisionChecker.closest`); the last
measurement is kept, keyed on the geometry placements, so that the accepted
trial's linearisation measures only the witnesses it uses. Each pair's last
separation bounds its distance at the next posture (a shape's points move by at
most what its bounding sphere's centre and rotation say), and pairs that cannot
be among the closest within the margin are not measured again (on the 15
built-in soft stances, 9,509 coal calls instead of 12,551, the same answers). A
check of clearance (:meth:`CollisionChecker.clearance`) measures the pairs in the
order of their broad-phase bounds and stops where none beyond can be nearer or
penetrate.

Sign conventions. ``distance <= 0`` means penetration (its magnitude is then
the penetration depth). ``normal`` is the unit vector, world frame, along which
translating body a increases the signed distance: from ``point_b`` toward
``point_a`` when apart, the reverse when penetrating. The linearisation is
``d(q (+) dq) ~= d + row @ dq`` with ``row = n^T (J_a(p_a) - J_b(p_b))``, ``J``
the ``(3, nv)`` world-aligned translational Jacobian of the witness point
attached to its link.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from .narrow_phase import (
    CollisionSetupError, DistanceQuery, coal, robot_shape, scene_geometry, witnesses,
)

# Broad-phase bounds within this of the margin reach coal, metres (coal's distances
# are exact to 1e-13 m on polytopes, see stances.narrow_phase).
_BOUND_SLACK = 1e-9
# A distance measured before bounds the same pair's distance now: it moves by at most
# how far a point of either shape moved (CollisionChecker._carry_bounds). The bounds are
# widened by this, metres, for coal's accuracy on curved shapes and the bound's rounding.
_COHERENCE_SLACK = 1e-7
# Deepest penetration reported, metres (deeper than any two robot links can
# overlap): the stand-in when coal cannot measure a depth.
_DEEPEST = 1.0

__all__ = [
    "CollisionChecker",
    "CollisionPair",
    "CollisionSetupError",
    "MeasuredPairs",
    "contact_exclusions",
]

@dataclass(frozen=True)
class CollisionPair:
    """One distance measurement between two bodies.

    Parameters
    ----------
    name_a : str
        Robot geometry name (pinocchio collision model).
    name_b : str
        Robot geometry name, or scene object name.
    joint_a : int
        Pinocchio joint index carrying geometry a.
    joint_b : int
        Joint carrying b, or 0 (the universe) for a scene object.
    point_a : (3,) float
        Witness point on a, metres, world frame.
    point_b : (3,) float
        Witness point on b, metres, world frame.
    distance : float
        Signed distance, metres; ``<= 0`` means penetration.
    normal : (3,) float
        Unit vector, world frame: the direction in which translating a
        increases ``distance``.
    """

    name_a: str
    name_b: str
    joint_a: int
    joint_b: int
    point_a: np.ndarray
    point_b: np.ndarray
    distance: float
    normal: np.ndarray

    def __post_init__(self) -> None:
        for field in ("point_a", "point_b", "normal"):
            value = np.array(getattr(self, field), dtype=float)
            if value.shape != (3,):
                raise CollisionSetupError(
                    f"CollisionPair.{field} must have shape (3,), got {value.shape}"
                )
            value.setflags(write=False)
            object.__setattr__(self, field, value)
        object.__setattr__(self, "distance", float(self.distance))

    @property
    def is_self_collision(self) -> bool:
        """True when b is a robot geometry (``joint_b != 0``)."""
        return self.joint_b != 0


def _measured_pair(name_a, name_b, joint_a, joint_b, point_a, point_b, distance, normal) -> CollisionPair:
    """A :class:`CollisionPair` from the checker's own measurement, without the
    constructor's checks and copies (20 pairs a linearisation): the three vectors
    must be (3,) float arrays that nothing writes to (own arrays, or views of
    :class:`MeasuredPairs`' read-only ones); they are made read-only."""
    for vector in (point_a, point_b, normal):
        vector.setflags(write=False)
    pair = object.__new__(CollisionPair)
    pair.__dict__.update(name_a=name_a, name_b=name_b, joint_a=joint_a, joint_b=joint_b, point_a=point_a,
                         point_b=point_b, distance=distance, normal=normal)
    return pair


@dataclass(frozen=True)
class MeasuredPairs:
    """Pairs of one measurement as arrays: what a linearisation reads of them.

    :meth:`CollisionChecker.closest` gives them without making a :class:`CollisionPair`
    for each; :meth:`pair` and :meth:`pairs` make those.

    Attributes
    ----------
    names : tuple of (str, str)
        ``(name_a, name_b)`` of each pair, as in :class:`CollisionPair`.
    joint_a, joint_b : (k,) int
        Joints carrying a and b (0, the universe, for a scene object).
    points_a, points_b : (k, 3) float
        Witness points, metres, world frame.
    distances : (k,) float
        Signed distances, metres.
    normals : (k, 3) float
        Unit vectors, world frame, along which translating a increases the distance.
    """

    names: tuple
    joint_a: np.ndarray
    joint_b: np.ndarray
    points_a: np.ndarray
    points_b: np.ndarray
    distances: np.ndarray
    normals: np.ndarray

    def __post_init__(self) -> None:
        for field in ("joint_a", "joint_b", "points_a", "points_b", "distances", "normals"):
            getattr(self, field).setflags(write=False)

    @classmethod
    def of(cls, pairs) -> "MeasuredPairs":
        """The arrays of a list of :class:`CollisionPair`."""
        return cls(
            names=tuple((pair.name_a, pair.name_b) for pair in pairs),
            joint_a=np.array([pair.joint_a for pair in pairs], dtype=int),
            joint_b=np.array([pair.joint_b for pair in pairs], dtype=int),
            points_a=np.array([pair.point_a for pair in pairs], dtype=float).reshape(-1, 3),
            points_b=np.array([pair.point_b for pair in pairs], dtype=float).reshape(-1, 3),
            distances=np.array([pair.distance for pair in pairs], dtype=float),
            normals=np.array([pair.normal for pair in pairs], dtype=float).reshape(-1, 3),
        )

    def __len__(self) -> int:
        return len(self.distances)

    def pair(self, i: int) -> CollisionPair:
        """Pair ``i`` as a :class:`CollisionPair` (its vectors are read-only views of the arrays)."""
        name_a, name_b = self.names[i]
        return _measured_pair(name_a, name_b, int(self.joint_a[i]), int(self.joint_b[i]), self.points_a[i],
                              self.points_b[i], float(self.distances[i]), self.normals[i])

    def pairs(self) -> list:
        """Every pair as a :class:`CollisionPair`, in order."""
        return [self.pair(i) for i in range(len(self))]


@dataclass(frozen=True)
class _RobotGeometry:
    """Robot collision geometry converted to coal once per robot (shapes are never moved)."""

    names: tuple
    joints: np.ndarray  # (g,) int, parent joint of each geometry
    joint_names: tuple  # (g,) str, the name of each geometry's parent joint
    rotation_geometry_to_joint: np.ndarray  # (g, 3, 3)
    translation_geometry_to_joint: np.ndarray  # (g, 3) metres
    sphere_center: np.ndarray  # (g, 3) metres, geometry frame
    sphere_radius: np.ndarray  # (g,) metres
    box_center: np.ndarray  # (g, 3) metres, geometry frame: the shape's local bounding box
    box_half: np.ndarray  # (g, 3) metres, its half sides
    shapes: tuple  # coal.Convex hulls and primitives, geometry frame
    self_pairs: np.ndarray  # (p, 2) int geometry indices, SRDF-allowed
    support: np.ndarray  # (njoints, nv) bool, see _support_columns


# One conversion per Robot instance: hulls take tens of milliseconds, and the
# solver builds a checker per stance.
_GEOMETRY_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _robot_geometry(robot) -> _RobotGeometry:
    cached = _GEOMETRY_CACHE.get(robot)
    if cached is not None:
        return cached
    collision_model = robot.collision_model
    names, joints, rotations, translations, centers, radii, boxes = [], [], [], [], [], [], []
    shapes = []
    for geometry_object in collision_model.geometryObjects:
        shape, center, radius = robot_shape(geometry_object)
        shape.computeLocalAABB()
        boxes.append((np.array(shape.aabb_local.min_), np.array(shape.aabb_local.max_)))
        placement = geometry_object.placement
        names.append(geometry_object.name)
        joints.append(int(geometry_object.parentJoint))
        rotations.append(np.array(placement.rotation))
        translations.append(np.array(placement.translation))
        centers.append(center)
        radii.append(radius)
        shapes.append(shape)
    geometry = _RobotGeometry(
        names=tuple(names),
        joints=np.array(joints, dtype=int),
        joint_names=tuple(robot.model.names[joint] for joint in joints),
        rotation_geometry_to_joint=np.array(rotations).reshape(-1, 3, 3),
        translation_geometry_to_joint=np.array(translations).reshape(-1, 3),
        sphere_center=np.array(centers).reshape(-1, 3),
        sphere_radius=np.array(radii, dtype=float),
        box_center=np.array([0.5 * (low + high) for low, high in boxes]).reshape(-1, 3),
        box_half=np.array([0.5 * (high - low) for low, high in boxes]).reshape(-1, 3),
        shapes=tuple(shapes),
        self_pairs=_self_pairs(collision_model),
        support=_support_columns(robot.model),
    )
    _GEOMETRY_CACHE[robot] = geometry
    return geometry


#: Metres: the default distance the posture solver keeps between bodies
#: (``PostureOptions.collision_distance``); a self-collision pair closer than
#: this at the reference posture is not checked (see :func:`hull_overlaps`).
KEPT_DISTANCE = 0.005


def hull_overlaps(robot, q, within: float = 0.0) -> list:
    """Self-collision pairs whose convex hulls touch, overlap or lie within ``within`` at ``q``.

    Parameters
    ----------
    robot : stances.Robot
    q : (nq,) float
    within : float
        Metres: pairs at most this far apart count too (the robot's loader
        gives :data:`KEPT_DISTANCE`: a pair nearer than the solver keeps at
        the reference posture holds no posture near it).

    Returns
    -------
    list of (str, str)
        Geometry names, in the collision model's pair order.
    """
    checker = CollisionChecker(robot, [], margin=float(within))
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return [(pair.name_a, pair.name_b) for pair in checker.pairs(robot.model, data) if pair.is_self_collision]


def ignore_self_pairs(robot, pairs) -> None:
    """Stop checking self-collision pairs, given by geometry names, on ``robot``
    (its collision model and the checker's cached geometry)."""
    if not pairs:
        return
    names = [geometry.name for geometry in robot.collision_model.geometryObjects]
    for first, second in pairs:
        robot.collision_model.removeCollisionPair(pin.CollisionPair(names.index(first), names.index(second)))
    cached = _GEOMETRY_CACHE.get(robot)
    if cached is not None:  # keep its hulls (tens of milliseconds), read its pairs again
        _GEOMETRY_CACHE[robot] = replace(cached, self_pairs=_self_pairs(robot.collision_model))


def _self_pairs(collision_model) -> np.ndarray:
    """(p, 2) int: the geometry indices of the collision model's enabled pairs."""
    return np.array([(pair.first, pair.second) for pair in collision_model.collisionPairs], dtype=int).reshape(-1, 2)


def _support_columns(model) -> np.ndarray:
    """(njoints, nv) bool: columns of ``data.J`` that move each joint (its ancestors')."""
    mask = np.zeros((model.njoints, model.nv), dtype=bool)
    for joint in range(1, model.njoints):
        for ancestor in model.supports[joint]:
            if ancestor == 0:
                continue
            start = model.joints[ancestor].idx_v
            mask[joint, start : start + model.joints[ancestor].nv] = True
    return mask


def _matching_geometries(key, geometry: _RobotGeometry) -> np.ndarray:
    """Indices of the robot geometries an exclusion key designates (may be empty)."""
    if isinstance(key, (int, np.integer)):
        return np.flatnonzero(geometry.joints == int(key))
    return np.array(
        [
            index
            for index, (name, joint_name) in enumerate(zip(geometry.names, geometry.joint_names))
            if name == key or joint_name == key or name.startswith(key)
        ],
        dtype=int,
    )


class CollisionChecker:
    """Distances, witness points and linearisation rows for one robot in one scene.

    A checker keeps what it measured (the last closest pairs, every pair's distance
    bounds): use one per thread.

    Parameters
    ----------
    robot : stances.Robot
        Robot whose ``collision_model`` gives the geometry and the allowed
        self-collision pairs.
    scene_objects : iterable of (str, environments.geometry.CollisionShape or coal.CollisionObject)
        Named static scene objects placed in the world frame (what
        ``scene.collision_objects()`` returns), rebuilt once as coal shapes
        (see :func:`stances.narrow_phase.scene_shape`). Names must be unique
        and differ from the robot's geometry names.
    margin : float
        Pairs farther apart than this, metres, are not reported.
    exclude : iterable of (key, str)
        Pairs to ignore. ``key`` designates robot geometries: a geometry name,
        a joint name or index (every geometry on that joint), or a name prefix
        such as ``"leg_left_6_link"``. The second entry is a scene object name,
        ``"*"`` for every scene object, or a robot geometry key (to drop
        self-collision pairs). :func:`contact_exclusions` builds the entries
        for a link resting on a support.
    self_collision : bool
        Whether to check the SRDF-allowed self-collision pairs.

    Raises
    ------
    CollisionSetupError
        On unknown exclusion names, duplicate scene names, unsupported scene
        geometry or a negative margin.

    Examples
    --------
    >>> import numpy as np, pinocchio as pin
    >>> from environments.geometry import CollisionShape
    >>> from stances import Robot
    >>> robot = Robot.load("talos")
    >>> floor_to_world = np.eye(4)
    >>> floor_to_world[2, 3] = -0.05
    >>> floor = CollisionShape(floor_to_world, box_size=(4.0, 4.0, 0.1))
    >>> checker = CollisionChecker(
    ...     robot, [("floor", floor)],
    ...     exclude=contact_exclusions(robot, "left_sole", "floor")
    ...     + contact_exclusions(robot, "right_sole", "floor"))
    >>> data = robot.model.createData()
    >>> pin.forwardKinematics(robot.model, data, robot.reference_configuration)
    >>> pairs = checker.pairs(robot.model, data)
    >>> min(pair.distance for pair in pairs) > 0.0
    True
    >>> checker.jacobian_rows(robot.model, data, pairs).shape == (len(pairs), robot.nv)
    True
    """

    def __init__(self, robot, scene_objects, *, margin=0.05, exclude=(), self_collision=True):
        margin = float(margin)
        if not margin >= 0.0:
            raise CollisionSetupError(f"margin must be >= 0 metres, got {margin}")
        self.margin = margin
        self.self_collision = bool(self_collision)
        self._robot = robot
        self._geometry = _robot_geometry(robot)
        self._support = self._geometry.support  # once per robot: a Python loop over the joints
        self._geometry_index = None  # geometry name -> index, made on first use
        self._last_closest = None  # (key, closest) of the last _closest
        self._query = DistanceQuery()  # coal's request, made once (0.6 % of a soft solve made it per call)
        self._results = []  # coal results _closest measures into, reused from call to call
        self._placements = _geometry_placements(self._geometry)

        self.scene_names, self._scene_shapes, self._scene_placements, bounds, boxes = [], [], [], [], []
        for entry in scene_objects:
            if len(entry) != 2:
                raise CollisionSetupError(
                    "scene_objects must be (name, CollisionShape or coal.CollisionObject) pairs, got "
                    f"{entry!r}"
                )
            name, collision_object = entry
            if name in self.scene_names or name in self._geometry.names or name == "*":
                raise CollisionSetupError(
                    f"scene object name {name!r} is used twice, or is '*' or a robot "
                    "geometry name; give each scene object a unique name"
                )
            shape, rotation, translation, object_bounds, object_boxes = scene_geometry(name, collision_object)
            self.scene_names.append(name)
            self._scene_shapes.append(shape)
            self._scene_placements.append(coal.Transform3s(rotation, translation))
            bounds.append(object_bounds)
            boxes.append(object_boxes)
        self.scene_names = tuple(self.scene_names)
        self._scene_bounds = np.array(bounds).reshape(-1, 2, 3)
        # Every scene object's boxes (one for a primitive, many for a mesh), stacked,
        # with where each object's start: the broad phase takes the least bound over them.
        self._scene_boxes = (np.concatenate(boxes) if boxes else np.zeros((0, 2, 3))).reshape(-1, 2, 3)
        self._scene_box_starts = np.cumsum([0] + [len(b) for b in boxes[:-1]]).astype(int)
        self.exclude = tuple((key, other) for key, other in exclude)
        self._build_pair_lists()

    def _build_pair_lists(self) -> None:
        geometry = self._geometry
        count = len(geometry.names)
        allowed_scene = np.ones((count, len(self.scene_names)), dtype=bool)
        allowed_self = np.ones((count, count), dtype=bool)
        for key, other in self.exclude:
            rows = _matching_geometries(key, geometry)
            if len(rows) == 0:
                raise CollisionSetupError(
                    f"exclusion key {key!r} matches no robot geometry; use a geometry "
                    f"name, joint name or index, or name prefix. Geometries: "
                    f"{', '.join(geometry.names)}"
                )
            if other == "*":
                allowed_scene[rows, :] = False
            elif other in self.scene_names:
                allowed_scene[rows, self.scene_names.index(other)] = False
            else:
                columns = _matching_geometries(other, geometry)
                if len(columns) == 0:
                    raise CollisionSetupError(
                        f"exclusion target {other!r} is neither a scene object "
                        f"({', '.join(self.scene_names) or 'none'}), '*', nor a robot "
                        "geometry key"
                    )
                allowed_self[np.ix_(rows, columns)] = False
                allowed_self[np.ix_(columns, rows)] = False
        self._scene_pairs = np.argwhere(allowed_scene).reshape(-1, 2)
        self_pairs = geometry.self_pairs if self.self_collision else np.zeros((0, 2), int)
        keep = allowed_self[self_pairs[:, 0], self_pairs[:, 1]]
        self._self_pairs = self_pairs[keep]
        self._self_radii = geometry.sphere_radius[self._self_pairs[:, 0]] + geometry.sphere_radius[self._self_pairs[:, 1]]
        # Bounds on each pair's distance (scene pairs, then self pairs; -inf and inf:
        # none), from the separations coal measured, carried from one measurement to
        # the next by how far the shapes moved in between (CollisionChecker._carry_bounds),
        # and the placements they were carried to: each geometry's rotation and
        # bounding sphere centre.
        self._pair_a = np.concatenate([self._scene_pairs[:, 0], self._self_pairs[:, 0]])
        self._pair_b = np.concatenate([np.full(len(self._scene_pairs), -1), self._self_pairs[:, 1]])
        self._lower = np.full(len(self._pair_a), -np.inf)
        self._upper = np.full(len(self._pair_a), np.inf)
        self._bounds_at = None

    @property
    def pair_count(self) -> int:
        """Number of pairs checked before the broad phase."""
        return len(self._scene_pairs) + len(self._self_pairs)

    def with_exclusions(self, exclude, *, margin=None) -> "CollisionChecker":
        """A checker on the same robot and scene with other exclusions (cheap).

        Parameters
        ----------
        exclude : iterable of (key, str)
            As in the constructor; replaces the current exclusions.
        margin : float, optional
            New margin, metres; defaults to the current one.

        Returns
        -------
        CollisionChecker
        """
        clone = object.__new__(CollisionChecker)
        clone.__dict__.update(self.__dict__)
        if margin is not None:
            margin = float(margin)
            if not margin >= 0.0:
                raise CollisionSetupError(f"margin must be >= 0 metres, got {margin}")
            clone.margin = margin
        clone.exclude = tuple((key, other) for key, other in exclude)
        clone._last_closest = None  # measured with the original's pairs
        clone._query, clone._results = DistanceQuery(), []
        clone._placements = _geometry_placements(clone._geometry)
        clone._build_pair_lists()
        return clone

    def _geometry_to_world(self, data, geometry_placements):
        """(g, 3, 3) rotations and (g, 3) translations of every robot geometry, world frame."""
        geometry = self._geometry
        if geometry_placements is not None:
            if isinstance(geometry_placements, np.ndarray):
                homogeneous = geometry_placements
            else:
                homogeneous = np.array([placement.homogeneous for placement in geometry_placements])
            if homogeneous.shape != (len(geometry.names), 4, 4):
                raise CollisionSetupError(
                    f"geometry_placements must hold {len(geometry.names)} placements "
                    f"(one per collision geometry), got shape {homogeneous.shape}"
                )
            return homogeneous[:, :3, :3], homogeneous[:, :3, 3]
        # One python loop over joints, then numpy over geometries (over a list of the
        # placements: indexing pinocchio's vector element by element took half the loop).
        joint_to_world = np.array([placement.homogeneous for placement in data.oMi.tolist()])
        rotation_joint = joint_to_world[geometry.joints, :3, :3]
        translation_joint = joint_to_world[geometry.joints, :3, 3]
        rotation = rotation_joint @ geometry.rotation_geometry_to_joint
        translation = (
            np.einsum("gij,gj->gi", rotation_joint, geometry.translation_geometry_to_joint)
            + translation_joint
        )
        return rotation, translation

    def _broad_phase(self, rotation, translation, bounds=False):
        """Pairs whose bounds come within ``margin`` at these geometry placements.

        Returns
        -------
        candidates : (k,) int
            Pair ids, ascending: ``i < len(_scene_pairs)`` is ``_scene_pairs[i]`` (robot
            geometry, scene object), the others ``_self_pairs[i - len(_scene_pairs)]``
            (robot geometry, robot geometry).
        centers : (g, 3) float
            Bounding sphere centres, metres, world frame.
        lower : (k,) float
            With ``bounds``: each candidate's lower bound on its signed distance, metres
            (coal's is at least this less ``_BOUND_SLACK``): the gap between its bounds
            where they are apart, -inf where they meet (the shapes may overlap by any depth).
        """
        geometry = self._geometry
        centers = np.einsum("gij,gj->gi", rotation, geometry.sphere_center) + translation
        radius = geometry.sphere_radius
        box_centers = np.einsum("gij,gj->gi", rotation, geometry.box_center) + translation
        box_halves = np.einsum("gij,gj->gi", np.abs(rotation), geometry.box_half)
        lows, highs = box_centers - box_halves, box_centers + box_halves
        # Both bounds never exceed the distance (a shape lies inside its sphere and
        # its box); the larger one is kept. The slack covers coal's own accuracy.
        limit = self.margin + _BOUND_SLACK
        scene_pairs = self._scene_pairs
        scene_candidates, scene_lower = np.zeros(0, dtype=int), np.zeros(0)
        if len(scene_pairs):
            # (g, b) bounds of every robot geometry against every scene box, then the
            # least over each object's boxes (the object lies in their union).
            lower, upper = self._scene_boxes[None, :, 0], self._scene_boxes[None, :, 1]
            c = centers[:, None]
            per_box = np.maximum(
                _norms(c - np.clip(c, lower, upper)) - radius[:, None],
                _norms(np.maximum(np.maximum(lower - highs[:, None], lows[:, None] - upper), 0.0)),
            )
            gap = np.minimum.reduceat(per_box, self._scene_box_starts, axis=1)[scene_pairs[:, 0], scene_pairs[:, 1]]
            scene_candidates = np.flatnonzero(gap <= limit)
            scene_lower = gap[scene_candidates]
        self_pairs = self._self_pairs
        self_candidates, self_lower = np.zeros(0, dtype=int), np.zeros(0)
        if len(self_pairs):
            # Spheres first, over every pair; boxes over the pairs whose spheres are near
            # (a tenth of them): the larger bound within the limit is both within it.
            a, b = self_pairs[:, 0], self_pairs[:, 1]
            sphere_gap = _norms(centers[a] - centers[b]) - self._self_radii
            near = np.flatnonzero(sphere_gap <= limit)
            a, b = a[near], b[near]
            box_gap = _box_gap(lows[a], highs[a], lows[b], highs[b])
            within = box_gap <= limit
            self_candidates = near[within]
            if bounds:
                self_lower = np.maximum(sphere_gap[self_candidates], box_gap[within])
        candidates = np.concatenate([scene_candidates, len(scene_pairs) + self_candidates])
        if bounds:
            lower = np.concatenate([scene_lower, self_lower])
            return candidates, centers, np.where(lower > 0.0, lower, -np.inf)
        return candidates, centers

    def _candidates(self, rotation, translation, ids=None, centers=None):
        """The broad phase's pairs (or the pairs ``ids``, with the sphere ``centers`` it
        gave) as ``(a, placement_a, b, shape_b, placement_b, centre_a, reference_b,
        is_self)`` tuples, scene pairs first (coal placements made once)."""
        geometry = self._geometry
        if ids is None:
            ids, centers = self._broad_phase(rotation, translation)
        split = np.searchsorted(ids, len(self._scene_pairs))
        scene_candidates = self._scene_pairs[ids[:split]]
        self_candidates = self._self_pairs[ids[split:] - len(self._scene_pairs)]
        used = np.zeros(len(geometry.names), dtype=bool)
        used[scene_candidates[:, 0]] = used[self_candidates.ravel()] = True
        # The coal placements of the geometries used, set in place (making them anew cost
        # twice as much); what was measured at the last ones has been read by now.
        placements = self._placements
        for index in np.flatnonzero(used).tolist():
            placement = placements[index]
            placement.setRotation(rotation[index])
            placement.setTranslation(translation[index])
        # A scene pair's reference point for a degenerate normal (the nearest point of b's
        # bounds to a's centre) is left None: :meth:`_pair` finds it in the rare case it is needed.
        shapes, scene_shapes, scene_placements = geometry.shapes, self._scene_shapes, self._scene_placements
        out = [(a, placements[a], b, scene_shapes[b], scene_placements[b], centers[a], None, False)
               for a, b in scene_candidates.tolist()]
        out.extend((a, placements[a], b, shapes[b], placements[b], centers[a], centers[b], True)
                   for a, b in self_candidates.tolist())
        return out

    def pairs(self, model, data, geometry_placements=None) -> list:
        """Measure every pair closer than ``margin``.

        Parameters
        ----------
        model : pinocchio.Model
            The robot's model.
        data : pinocchio.Data
            After ``pin.forwardKinematics`` (``data.oMi``) at the configuration.
        geometry_placements : (g, 4, 4) float or sequence of pinocchio.SE3, optional
            World placements of the collision geometries, in collision-model
            order (e.g. ``GeometryData.oMg``); computed from ``data.oMi`` if
            omitted.

        Returns
        -------
        list of CollisionPair
            Scene pairs first, then self-collision pairs; only those with
            ``distance <= margin``.
        """
        rotation, translation = self._geometry_to_world(data, geometry_placements)
        query = self._query
        measured = [self._measure(query, *candidate) for candidate in self._candidates(rotation, translation)]
        return [pair for pair in measured if pair is not None]

    def distances(self, model, data, geometry_placements=None) -> list:
        """Every pair closer than ``margin``, measured afresh, without witness points.

        The same pairs, order and distances as :meth:`pairs`, without reading and building
        what linearisation rows need (48 witness points and pairs on a climb stance, 0.3 ms);
        :meth:`clearance` gives the least distance and the deep pairs of these for fewer
        measurements.

        Parameters
        ----------
        model, data, geometry_placements
            As :meth:`pairs`.

        Returns
        -------
        list of ((str, str), float)
            ``(name_a, name_b)`` and the signed distance, metres, as
            :class:`CollisionPair` gives them.
        """
        rotation, translation = self._geometry_to_world(data, geometry_placements)
        query, shapes, margin, out = self._query, self._geometry.shapes, self.margin, []
        for candidate in self._candidates(rotation, translation):
            a, placement_a, _, shape_b, placement_b = candidate[:5]
            distance = query.distance(shapes[a], placement_a, shape_b, placement_b)
            if not distance > margin:
                out.append((self._names(candidate), float(_deepest_clamped(distance))))
        return out

    def clearance(self, model, data, depth):
        """The least distance within ``margin`` and the pairs deeper than ``depth``, measured
        afresh: what :meth:`distances` gives of them, measuring only the pairs that can
        change them.

        Pairs are measured in the order of their broad-phase lower bounds, until the
        next bound exceeds both the least distance measured and ``-depth``: no pair
        beyond can be nearer or that deep. What a check of clearance needs
        (:func:`stances.verify`): on the 60 random rigid bench stances, 43 coal calls a
        check with :meth:`distances`.

        Parameters
        ----------
        model, data
            As :meth:`pairs` (``data.oMi`` at the configuration).
        depth : float
            Metres: pairs whose signed distance is below ``-depth`` are returned.

        Returns
        -------
        least : float
            The least signed distance of the pairs within ``margin``, metres (inf if none).
        deep : list of ((str, str), float)
            The pairs deeper than ``depth``, as :meth:`distances` gives them, in its order.
        """
        rotation, translation = self._geometry_to_world(data, None)
        ids, centers, lower = self._broad_phase(rotation, translation, bounds=True)
        candidates = self._candidates(rotation, translation, ids, centers)
        query, shapes, margin = self._query, self._geometry.shapes, self.margin
        least, deep = np.inf, []
        for i in np.argsort(lower, kind="stable").tolist():
            if lower[i] - _BOUND_SLACK > max(least, -depth):
                break
            a, placement_a, _, shape_b, placement_b = candidates[i][:5]
            distance = _deepest_clamped(query.distance(shapes[a], placement_a, shape_b, placement_b))
            if not distance > margin:
                least = min(least, float(distance))
                if distance < -depth:
                    deep.append((i, self._names(candidates[i]), float(distance)))
        return least, [(names, distance) for _, names, distance in sorted(deep)]

    def closest_distances(self, model, data, count):
        """The distances of the ``count`` closest pairs within ``margin``, without witness points.

        What a line search needs: the same numbers, in the same order, as the
        pairs of :meth:`closest`, for fewer coal calls.

        Parameters
        ----------
        model : pinocchio.Model
        data : pinocchio.Data
            After ``pin.forwardKinematics`` (``data.oMi``) at the configuration.
        count : int

        Returns
        -------
        distances : (k,) float
            Signed distances, metres, ascending (k <= count).
        names : list of (str, str)
            ``(name_a, name_b)`` of each pair, as in :class:`CollisionPair`.
        """
        closest = self._closest(data, count)
        return np.array([entry[0] for entry in closest]), [self._names(entry[1]) for entry in closest]

    def closest(self, model, data, count) -> MeasuredPairs:
        """The ``count`` closest pairs within ``margin``, ascending, with witness points, as arrays.

        The first ``count`` of :meth:`pairs` sorted by distance (ties in
        :meth:`pairs` order); only those pairs' witness points are read.

        Parameters
        ----------
        model, data, count
            As :meth:`closest_distances`.

        Returns
        -------
        MeasuredPairs
        """
        closest = self._closest(data, count)
        geometry = self._geometry
        points_a, points_b, normals, directed = witnesses([entry[3] for entry in closest])
        distances = np.array([entry[2] for entry in closest], dtype=float)
        # A pair without a direction, or deeper than coal could measure: the stand-ins of
        # _pair (rare: none in the 60 random rigid stances).
        for i in np.flatnonzero(~(directed & (distances >= -_DEEPEST))).tolist():
            pair = self._pair(distances[i], (points_a[i], points_b[i], normals[i] if directed[i] else None),
                              *closest[i][1])
            points_a[i], points_b[i], normals[i], distances[i] = pair.point_a, pair.point_b, pair.normal, pair.distance
        a = np.array([entry[1][0] for entry in closest], dtype=int)
        b = np.array([entry[1][2] for entry in closest], dtype=int)
        is_self = np.array([entry[1][7] for entry in closest], dtype=bool)
        joint_b = np.zeros(len(closest), dtype=int)
        joint_b[is_self] = geometry.joints[b[is_self]]
        return MeasuredPairs(
            names=tuple(self._names(entry[1]) for entry in closest), joint_a=geometry.joints[a], joint_b=joint_b,
            points_a=points_a, points_b=points_b, distances=distances, normals=normals,
        )

    def closest_pairs(self, model, data, count) -> list:
        """:meth:`closest` as a list of :class:`CollisionPair`."""
        return self.closest(model, data, count).pairs()

    def _closest(self, data, count):
        """The ``count`` closest pairs within ``margin`` at the joint placements in ``data``.

        What :meth:`pairs` then a stable sort by distance would give first, without
        measuring the pairs that cannot be among them (:meth:`_unreachable`).

        Returns
        -------
        list of (float, tuple, float, coal.DistanceResult)
            Signed distance (clamped as :meth:`_pair` does), the pair's
            :meth:`_candidates` entry, coal's distance and its result, ascending. The
            last answer is kept, keyed on the geometry placements, the margin and ``count``.
        """
        rotation, translation = self._geometry_to_world(data, None)
        key = (self.margin, count, rotation.tobytes(), translation.tobytes())
        if self._last_closest is not None and self._last_closest[0] == key:
            return self._last_closest[1]
        ids, centers = self._broad_phase(rotation, translation)
        self._carry_bounds(rotation, centers)
        ids = ids[~self._unreachable(ids, count)]
        geometry, query, margin = self._geometry, self._query, self.margin
        measured, distances = [], np.empty(len(ids))
        # Each result is kept till the next measurement: the rows the linearisation keeps
        # read their witness points there (the answer kept above holds them till then too).
        results = self._results
        results.extend(coal.DistanceResult() for _ in range(len(ids) - len(results)))
        for i, candidate in enumerate(self._candidates(rotation, translation, ids, centers)):
            a, placement_a, _, shape_b, placement_b = candidate[:5]
            distance, result = query.kept_distance(geometry.shapes[a], placement_a, shape_b, placement_b, results[i])
            distances[i] = distance
            if not distance > margin:
                measured.append((_deepest_clamped(distance), candidate, distance, result))
        self._remember(ids, distances)
        closest = sorted(measured, key=lambda entry: entry[0])[:count]
        self._last_closest = (key, closest)
        return closest

    def _carry_bounds(self, rotation, centers) -> None:
        """Widen every pair's distance bounds by how far its shapes moved since they were
        last carried, to these placements (the first call only records them).

        A point of a shape has moved by at most ``|c - c0| + |R - R0| r`` (its bounding
        sphere's centre c and radius r, its rotation R; ``|.|`` the Frobenius norm, which
        bounds the spectral one; a scene object does not move), so a pair's distance has
        changed by at most the sum of its two shapes' motions.
        """
        if self._bounds_at is not None:
            old_rotation, old_centers = self._bounds_at
            radius = self._geometry.sphere_radius
            moved = _norms(centers - old_centers) + _norms((rotation - old_rotation).reshape(-1, 9)) * radius
            moved = np.append(moved, 0.0)  # index -1: a scene object
            spread = moved[self._pair_a] + moved[self._pair_b] + _COHERENCE_SLACK
            self._lower -= spread
            self._upper += spread
        self._bounds_at = (rotation, centers)

    def _unreachable(self, ids, count) -> np.ndarray:
        """(k,) bool: the pairs ``ids`` that cannot be among the ``count`` closest within
        ``margin``, by their bounds (:meth:`_carry_bounds`, :meth:`_remember`).

        A pair whose lower bound exceeds the margin, or the upper bounds of ``count``
        other pairs, is not among the closest; the others are measured, so the answer is
        the one measuring every pair gives, bit for bit. Measured on hand-on-cube's climb
        stance: a third of the broad phase's pairs lie beyond the margin, and a third of
        those within it beyond the closest 20.
        """
        lower, upper = self._lower[ids], self._upper[ids]
        # The count-th smallest upper bound: that many pairs lie no farther, and a pair
        # beyond it ranks after them (upper bounds come from separations only, so it is
        # positive: the deepest stand-in, -_DEEPEST, never ties with it).
        floor = np.partition(upper, count - 1)[count - 1] if 0 < count <= len(ids) else np.inf
        return (lower > self.margin + _BOUND_SLACK) | (lower > floor)

    def _remember(self, ids, distances) -> None:
        """Bound the pairs ``ids`` by the distances just measured at the placements the
        bounds were carried to (a separation, d > 0, GJK's exact answer: both bounds; no
        bound from a penetration)."""
        separated = distances > 0.0
        self._lower[ids] = np.where(separated, distances, -np.inf)
        self._upper[ids] = np.where(separated, distances, np.inf)

    def _names(self, candidate):
        """``(name_a, name_b)`` of a :meth:`_candidates` entry."""
        a, b, is_self = candidate[0], candidate[2], candidate[7]
        names = self._geometry.names
        return names[a], names[b] if is_self else self.scene_names[b]

    def _measure(self, query, *candidate, margin=None) -> CollisionPair | None:
        """The pair of a :meth:`_candidates` entry, measured; None beyond ``margin``."""
        a, placement_a, _, shape_b, placement_b = candidate[:5]
        distance = query.distance(self._geometry.shapes[a], placement_a, shape_b, placement_b)
        if distance > (self.margin if margin is None else margin):
            return None
        return self._pair(distance, query.witness(), *candidate)

    def _pair(
        self, distance, witness, a, placement_a, b, shape_b, placement_b, center_a, reference_b, is_self
    ) -> CollisionPair:
        """The pair of a :meth:`_candidates` entry from coal's distance and witness."""
        geometry = self._geometry
        name_b, joint_b = (geometry.names[b], int(geometry.joints[b])) if is_self else (self.scene_names[b], 0)
        point_a, point_b, normal = witness
        if normal is not None and distance >= -_DEEPEST:
            # coal's witness as it is: the common case (20 pairs a linearisation); the
            # fallbacks below take a pair without a direction or with a lost depth.
            return _measured_pair(geometry.names[a], name_b, int(geometry.joints[a]), joint_b, point_a, point_b,
                                  float(distance), normal)
        if reference_b is None and (normal is None or not distance >= -_DEEPEST):
            reference_b = np.clip(center_a, *self._scene_bounds[b])
        if not distance >= -_DEEPEST:
            # coal's EPA gave up on a deep interpenetration (it answers -1.8e308,
            # seen with a leg through a wrist on a stance 3 m out of reach): a
            # finite stand-in between the centres keeps the solver's arithmetic
            # finite and pushes the bodies apart along the line joining them.
            distance, point_a, point_b, normal = -_DEEPEST, np.array(center_a), np.array(reference_b), None
        if normal is None:
            # coal gave no direction: fall back on the direction from b's
            # centre to a's, a fair separating guess, or world z when those
            # coincide.
            offset = center_a - reference_b
            length = np.linalg.norm(offset)
            normal = offset / length if length > 1e-12 else np.array([0.0, 0.0, 1.0])
        return _measured_pair(geometry.names[a], name_b, int(geometry.joints[a]), joint_b, point_a, point_b,
                              float(distance), normal)

    def jacobian_rows(self, model, data, pairs) -> np.ndarray:
        """Rows of the distance linearisation ``d(q (+) dq) ~= d + row @ dq``.

        Parameters
        ----------
        model : pinocchio.Model
        data : pinocchio.Data
            After ``pin.forwardKinematics`` at the configuration the pairs were
            measured at; ``data.J`` is overwritten (``pin.computeJointJacobians``).
        pairs : list of CollisionPair, or MeasuredPairs
            From :meth:`pairs` or :meth:`closest`.

        Returns
        -------
        (len(pairs), nv) float
            ``n^T (J_a(p_a) - J_b(p_b))``, metres per unit tangent step.
        """
        if len(pairs) == 0:
            return np.zeros((0, model.nv))
        return self._rows(pin.computeJointJacobians(model, data), pairs)

    def _rows(self, jacobian_world, pairs) -> np.ndarray:
        """(k, nv) ``n^T (J_a(p_a) - J_b(p_b))`` from ``data.J``, for a list of
        :class:`CollisionPair` or :class:`MeasuredPairs`."""
        if not isinstance(pairs, MeasuredPairs):
            pairs = MeasuredPairs.of(pairs)
        normal, point_a, point_b = pairs.normals, pairs.points_a, pairs.points_b
        # data.J stacks the motion subspaces in the world frame: a column moves
        # a world point p at v + omega x p. A point of joint i only sees the
        # columns of i's ancestors, hence the support mask.
        linear, angular = jacobian_world[:3], jacobian_world[3:]
        # n . (v + omega x p) = n . v + (p x n) . omega
        along_normal = normal @ linear
        rows_a = along_normal + _cross(point_a, normal) @ angular
        rows_b = along_normal + _cross(point_b, normal) @ angular
        return self._support[pairs.joint_a] * rows_a - self._support[pairs.joint_b] * rows_b

    def remeasured_rows(self, model, data, pairs) -> np.ndarray:
        """The same geometry pairs' distance rows at another configuration, measured again.

        :mod:`stances.curvature` differences these rows into the distances'
        second derivatives: new witness points and normal at each
        configuration, so the turning of the normal (a face of one link
        against a corner of the other) is in them. Pairs are measured whatever
        their distance (no margin), so a row exists at every nearby configuration.

        Parameters
        ----------
        model : pinocchio.Model
        data : pinocchio.Data
            Joint placements (``data.oMi``) and ``data.J``
            (``pin.computeJointJacobians``) at the configuration.
        pairs : list of CollisionPair
            From :meth:`pairs` at some configuration.

        Returns
        -------
        (len(pairs), nv) float
        """
        geometry = self._geometry
        if self._geometry_index is None:
            self._geometry_index = {name: i for i, name in enumerate(geometry.names)}
        index = self._geometry_index
        query = self._query
        measured = []
        for pair in pairs:
            a = index[pair.name_a]
            placement_a = self._placement(data, a)
            if pair.is_self_collision:
                b = index[pair.name_b]
                shape_b, placement_b = geometry.shapes[b], self._placement(data, b)
                reference_b = placement_b.getTranslation()
            else:
                b = self.scene_names.index(pair.name_b)
                shape_b, placement_b = self._scene_shapes[b], self._scene_placements[b]
                reference_b = np.clip(placement_a.getTranslation(), *self._scene_bounds[b])
            measured.append(
                self._measure(
                    query, a, placement_a, b, shape_b, placement_b, placement_a.getTranslation(), reference_b,
                    pair.is_self_collision, margin=np.inf,
                )
            )
        return self._rows(data.J, measured)

    def _placement(self, data, index):
        """coal placement of robot geometry ``index`` at the joint placements in ``data``."""
        geometry = self._geometry
        joint = data.oMi[int(geometry.joints[index])]
        rotation = joint.rotation @ geometry.rotation_geometry_to_joint[index]
        translation = joint.rotation @ geometry.translation_geometry_to_joint[index] + joint.translation
        return coal.Transform3s(rotation, translation)


def _geometry_placements(geometry: _RobotGeometry) -> list:
    """One coal placement per robot geometry, for a checker to set in place."""
    return [coal.Transform3s() for _ in geometry.names]


def _deepest_clamped(distance):
    """A measured distance, or the deepest stand-in (-_DEEPEST) where coal's EPA gave up
    (a depth below it, or NaN), as :meth:`CollisionChecker._pair` reports it."""
    return distance if distance >= -_DEEPEST else -_DEEPEST


def _box_gap(low_a, high_a, low_b, high_b) -> np.ndarray:
    """(k,) Euclidean distances between axis-aligned boxes given by (k, 3) corners (0 where they meet)."""
    return _norms(np.maximum(np.maximum(low_b - high_a, low_a - high_b), 0.0))


def _norms(vectors) -> np.ndarray:
    """Euclidean norms along the last axis (without ``np.linalg.norm``'s overhead)."""
    return np.sqrt(np.einsum("...i,...i->...", vectors, vectors))


def _cross(a, b) -> np.ndarray:
    """Row-wise cross products of (k, 3) arrays (np.cross costs some 50 us of overhead a call)."""
    return np.column_stack([
        a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
        a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
        a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
    ])


def contact_exclusions(robot, surface_or_frame: str, object_name: str, *, include_parent_joint=False):
    """Exclusion entries for a robot surface resting on a support by design.

    Only the surface's own contact geometry may touch the support (a palm's
    plate, the foot whose bottom is the sole): every other geometry of the link,
    such as the wrist above a palm plate, keeps its distance like any link.

    Parameters
    ----------
    robot : stances.Robot
    surface_or_frame : str
        Robot surface name (``"left_sole"``), its contact frame's name
        (``"left_sole_contact"``), or another pinocchio frame name (then every
        geometry on that frame's joint is excluded).
    object_name : str
        Scene object the surface touches, or ``"*"``.
    include_parent_joint : bool
        Also exclude the geometry of the parent joint (e.g. the ankle above
        the sole), which may come within a few millimetres of the support.

    Returns
    -------
    list of (str, str)
        ``(geometry_name, object_name)`` for the surface's contact geometries
        (and the parent joint's), ready for ``exclude``.

    Raises
    ------
    FrameNotFound
        If neither a surface nor a frame has that name.

    Examples
    --------
    >>> from stances import Robot
    >>> robot = Robot.load("talos")
    >>> contact_exclusions(robot, "left_sole", "floor")
    [('leg_left_6_link_0', 'floor')]
    >>> contact_exclusions(robot, "right_palm_contact", "cube")
    [('right_palm_plate', 'cube')]
    """
    surface = robot.surfaces.get(surface_or_frame) or next(
        (s for s in robot.surfaces.values() if s.frame == surface_or_frame), None
    )
    frame_name = surface.frame if surface is not None else surface_or_frame
    joint = robot.model.frames[robot.frame_id(frame_name)].parentJoint
    # The checker's converted geometry (names and joints in collision-model order): reading
    # pinocchio's geometry objects took most of a stance's exclusions.
    geometry = _robot_geometry(robot)
    parents = geometry.joints.tolist()
    if surface is not None and surface.contact_geometries:
        names = set(surface.contact_geometries)
    else:
        names = {name for name, parent in zip(geometry.names, parents) if parent == joint}
    if include_parent_joint and joint != 0:
        above = robot.model.parents[joint]
        names |= {name for name, parent in zip(geometry.names, parents) if parent == above}
    # In collision-model order, so that the entries do not depend on set order.
    return [(name, object_name) for name in geometry.names if name in names]
