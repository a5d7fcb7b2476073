"""The robot: a pinocchio model with declared contact surfaces.

A :class:`Robot` bundles what the posture solver and the planner need to know
about a legged robot: its kinematic and inertial model, its collision geometry
with the self-collision pairs its SRDF allows, its joint and torque limits, a
reference posture, the planar surfaces it may put in contact (soles, palm
plates) with their role (foot or hand) and limb, and its support rule.

Contact-frame convention (used everywhere in :mod:`stances`): each robot
surface has a frame whose origin lies on the surface and whose z axis points
*into* the link, i.e. opposite to the surface's outward normal. A contact is
then simply "the robot surface frame coincides with the print frame", whose z
axis is the environment surface's outward normal.

Robots are data: :meth:`Robot.load` reads a robot description
(:mod:`stances.description`; the built-in ones, Talos, Romeo, iCub and ANYmal,
point to the files installed by the ``example-robot-data`` package, so no path of one
machine is hard-coded).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from .ball_cover import trim_into_balls
from .collision import KEPT_DISTANCE, hull_overlaps, ignore_self_pairs
from .description import (
    BUILTIN_DIRECTORY,
    ROLES,
    RobotDescription,
    RobotDescriptionError,
    SupportRule,
    SurfaceDeclaration,
    builtin_robot_names,
    example_robot_data_share,
    read_description,
)
from .errors import FrameNotFound, StanceError
from .mesh_rotations import MeshRotation, turn_meshes
from .plates import PlateDeclaration, mount_plate, plate_geometry
from .results import contact_frame_name

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class RobotSurface:
    """A planar contact surface attached to a link.

    Parameters
    ----------
    name : str
        Name used in stances, e.g. ``"left_sole"``.
    frame : str
        Pinocchio frame name of the contact frame (added to the model). Its z
        axis points into the link; its origin is on the surface.
    polygon : (k, 2) float
        Vertices of the surface, metres, in the contact frame's xy plane,
        counter-clockwise seen from outside the link.
    contact_geometries : tuple of str
        Collision geometries that form the surface: the only ones allowed to
        touch the support the surface rests on (a palm's plate, the foot whose
        bottom is the sole). Every other geometry keeps its distance.
    role : str
        ``"foot"`` or ``"hand"`` (see :data:`stances.description.ROLES`).
    limb : str
        Limb the surface ends, a key of :attr:`Robot.limbs`.
    radius : float, optional
        A point foot: radius of its ball, metres, centred on the contact
        frame's origin (which then lies ``radius`` above the support);
        ``polygon`` is its print (:func:`stances.description.point_print`).
        None for a planar surface.
    """

    name: str
    frame: str
    polygon: np.ndarray
    contact_geometries: tuple = ()
    role: str = "foot"
    limb: str = ""
    radius: float | None = None

    def __post_init__(self) -> None:
        polygon = np.array(self.polygon, dtype=float)
        if polygon.ndim != 2 or polygon.shape[1] != 2 or len(polygon) < 3:
            raise StanceError(
                f"robot surface {self.name!r}: polygon must be (k, 2) with k >= 3, "
                f"got shape {polygon.shape}"
            )
        if self.role not in ROLES:
            raise StanceError(f"robot surface {self.name!r}: unknown role {self.role!r}; roles: {', '.join(ROLES)}")
        if self.radius is not None and not (np.isfinite(self.radius) and self.radius > 0):
            raise StanceError(f"robot surface {self.name!r}: a point foot's radius must be positive, got {self.radius!r}")
        polygon.setflags(write=False)
        object.__setattr__(self, "polygon", polygon)
        object.__setattr__(self, "contact_geometries", tuple(str(name) for name in self.contact_geometries))

    @property
    def is_point(self) -> bool:
        """Whether the surface is a point foot (a ball) rather than a polygon."""
        return self.radius is not None

    @property
    def vertices_in_frame(self) -> np.ndarray:
        """(k, 3) float: the polygon's vertices in the contact frame (z = 0)."""
        return np.column_stack([self.polygon, np.zeros(len(self.polygon))])

    @property
    def area(self) -> float:
        """Area of the polygon, square metres (shoelace formula)."""
        x, y = self.polygon.T
        return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _chain_to_root(model, joint: int) -> list[int]:
    """Joint indices from ``joint`` up to the universe's child (the free flyer), inclusive."""
    chain = [joint]
    while model.parents[chain[-1]] > 0:
        chain.append(model.parents[chain[-1]])
    return chain


def _limb_roots(model, surfaces, limbs) -> dict:
    """Each limb's root joint name, checked against the surfaces that end the limb.

    Without ``limbs``, a limb's root is the joint just below the last branching
    joint above its first surface: the hip of a leg, the shoulder of an arm.

    Raises
    ------
    FrameNotFound
        For a root joint not in the model, or a surface limb not in ``limbs``.
    StanceError
        If a surface is not below its limb's root joint.
    """
    children = np.bincount(np.asarray(model.parents[1:], dtype=int), minlength=model.njoints)
    roots = {} if limbs is None else dict(limbs)
    for surface in surfaces.values():
        chain = _chain_to_root(model, model.frames[model.getFrameId(surface.frame)].parentJoint)
        if limbs is None and surface.limb not in roots:
            below_branch = [joint for joint in chain if children[model.parents[joint]] > 1] or [chain[-1]]
            roots[surface.limb] = model.names[below_branch[0]]
        if surface.limb not in roots:
            raise FrameNotFound("limb", surface.limb, roots, f"robot surface {surface.name!r}")
        root = roots[surface.limb]
        if not model.existJointName(root):
            raise FrameNotFound("joint", root, list(model.names)[1:], f"limb {surface.limb!r}")
        if model.getJointId(root) not in chain:
            raise StanceError(
                f"robot surface {surface.name!r} on limb {surface.limb!r} is not below the limb's root joint "
                f"{root!r}; its chain: {', '.join(model.names[joint] for joint in reversed(chain))}"
            )
    return roots


def _turn_collision_meshes(model, collision_model, rotations) -> None:
    """Apply ``rotations`` to the collision meshes; every link they name must carry one.

    Raises
    ------
    FrameNotFound
        For a link not in the model.
    StanceError
        For a link without any collision mesh (nothing to turn: a typo for
        another link, or a link whose geometry is a primitive).
    """
    turned = turn_meshes(model, collision_model, rotations)
    bare = [link for rotation in rotations for link in rotation.links if link not in turned]
    if bare:
        with_meshes = sorted({model.frames[g.parentFrame].name for g in collision_model.geometryObjects if g.meshPath})
        raise StanceError(
            f"mesh_rotations: link {bare[0]!r} has no collision mesh to turn; links with meshes: {', '.join(with_meshes)}"
        )


def _reference_configurations(model) -> dict:
    # pinocchio's map iterates as (name, configuration) pairs.
    return {entry.key(): np.array(entry.data()) for entry in model.referenceConfigurations}


class Robot:
    """A legged robot's model ready for posture problems.

    Build one with :meth:`Robot.load` (a built-in robot or a description
    file, see :mod:`stances.description`) or :meth:`Robot.from_urdf` (any
    URDF/SRDF with declared contact surfaces).

    Attributes
    ----------
    name : str
        Robot name.
    model : pinocchio.Model
        Kinematic and inertial model with a free-flyer root and one extra
        frame per contact surface.
    collision_model : pinocchio.GeometryModel
        Collision geometry, with the self-collision pairs the SRDF allows.
    surfaces : dict of str to RobotSurface
        Contact surfaces by name, in declaration order.
    reference_configuration : (nq,) float
        Reference posture (read-only), the objective's target.
    limbs : dict of str to str
        Limb name -> name of its root joint.
    support : SupportRule
        Contacts every stance keeps (a biped: one foot).
    source : str
        What :meth:`Robot.load` loads it from again: a built-in name or a
        description file; empty for a robot built by :meth:`from_urdf`.
    locked_joints : dict of str to tuple of float
        Joints of the URDF removed from ``model``, with the configuration
        values they are locked at (radians or metres), in URDF order.
    urdf : Path or None
        The URDF file the model was built from.
    mesh_rotations : tuple of MeshRotation
        Rotations applied to the meshes of some links (see
        :mod:`stances.mesh_rotations`): the collision model has them, and a
        visual model built from ``urdf`` needs them too.
    """

    def __init__(
        self, name, model, collision_model, surfaces, reference_configuration, limbs=None, support=SupportRule(),
        locked_joints=None, urdf=None, mesh_rotations=(),
    ):
        self.name = name
        self.mesh_rotations = tuple(mesh_rotations)
        self.locked_joints = {str(k): tuple(float(v) for v in values) for k, values in dict(locked_joints or {}).items()}
        self.urdf = None if urdf is None else Path(urdf)
        self.model = model
        self.collision_model = collision_model
        self.surfaces = dict(surfaces)
        reference_configuration = np.array(reference_configuration, dtype=float)
        reference_configuration.setflags(write=False)
        self.reference_configuration = reference_configuration
        self.limbs = dict(limbs) if limbs is not None else {}
        self.support = support
        self.source = ""
        # Self-collision pairs the SRDF enables but that are not checked (see from_urdf).
        self.ignored_pairs = ()
        self._reference_positions = (None, {})  # see reference_position

    @classmethod
    def load(cls, name_or_file="talos") -> "Robot":
        """Load a built-in robot by name, or a robot from its description file.

        Parameters
        ----------
        name_or_file : str or os.PathLike
            A name of :func:`stances.description.builtin_robot_names`
            (``"talos"``, ``"romeo"``, ``"icub"``, ``"anymal"``) or a robot description YAML file.

        Returns
        -------
        Robot

        Raises
        ------
        RobotNotFound
            For a name that is neither built in nor a file.
        RobotDescriptionError
            For an invalid description (naming the file and the key at fault).

        Examples
        --------
        >>> robot = Robot.load("talos")
        >>> sorted(robot.surfaces)
        ['left_palm', 'left_sole', 'right_palm', 'right_sole']
        >>> robot.model.nv
        34
        """
        return cls.from_description(read_description(name_or_file))

    @classmethod
    def from_description(cls, description: RobotDescription) -> "Robot":
        """Build the robot a :class:`~stances.description.RobotDescription` describes.

        Raises
        ------
        RobotDescriptionError
            If a name of the description (link, joint, geometry, posture) is
            not in the model, naming the description file.
        """
        try:
            robot = cls.from_urdf(
                name=description.name,
                urdf=description.urdf,
                srdf=description.srdf,
                package_dirs=description.package_dirs,
                surfaces=description.surfaces,
                locked_joints=description.locked_joints,
                reference_posture=description.reference_posture,
                checked_pairs=description.checked_pairs,
                ignored_pairs=description.ignored_pairs,
                limbs=description.limbs,
                support=description.support,
                mesh_rotations=description.mesh_rotations,
            )
        except RobotDescriptionError:
            raise
        except StanceError as error:
            raise RobotDescriptionError(description.path, "", str(error)) from None
        builtin = description.path is not None and description.path == BUILTIN_DIRECTORY / f"{description.name}.yaml"
        robot.source = description.name if builtin else str(description.path or "")
        return robot

    @classmethod
    def from_urdf(
        cls,
        name,
        urdf,
        srdf,
        package_dirs,
        surfaces,
        locked_joints=(),
        removed_geometry_prefixes=(),
        reference_posture="half_sitting",
        checked_pairs=(),
        limbs=None,
        support=SupportRule(),
        ignored_pairs=(),
        mesh_rotations=(),
    ) -> "Robot":
        """Build a robot from URDF and SRDF files with declared contact surfaces.

        Parameters
        ----------
        name : str
            Robot name.
        urdf, srdf : path-like
            Model files. The SRDF provides the reference posture and the
            self-collision exclusions.
        package_dirs : list of path-like
            Where ``package://`` mesh URIs resolve.
        surfaces : iterable of SurfaceDeclaration
            Contact surfaces to add as frames, with their plates, roles and limbs.
        locked_joints : iterable of str
            Joints fixed at their reference value and removed from the model.
        removed_geometry_prefixes : iterable of str
            Collision geometries whose name starts with one of these are
            dropped (their mass stays: a plate declares a replaced part).
        reference_posture : str
            Name of the SRDF group state used as reference configuration.
        checked_pairs : iterable of (str, str)
            Collision geometry pairs to check although the SRDF disables them
            (pairs a robot's postures can bring into contact).
        ignored_pairs : iterable of (str, str)
            Collision geometry pairs not to check although the SRDF enables
            them. Pairs whose convex hulls touch, overlap or lie closer than
            the solver keeps them (:data:`stances.collision.KEPT_DISTANCE`) at
            the reference posture are not checked either (unless in
            ``checked_pairs``); both kinds end up in :attr:`ignored_pairs`.
        limbs : mapping of str to str, optional
            Limb name -> root joint. Default: each surface's limb starts at
            the joint after the last branching of the kinematic tree above the
            surface (a leg at its hip, an arm at its shoulder).
        support : SupportRule
            Contacts every stance keeps.
        mesh_rotations : iterable of MeshRotation
            Meshes turned in their own frame, by link, before anything is
            measured on them (see :mod:`stances.mesh_rotations`).

        Returns
        -------
        Robot

        Raises
        ------
        FrameNotFound
            For a link, joint, geometry or posture name not in the model.
        StanceError
            If a surface is not on the chain of its limb's root joint, or a
            link of ``mesh_rotations`` has no collision mesh.
        """
        dirs = [str(d) for d in package_dirs]
        model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
        collision_model = pin.buildGeomFromUrdf(
            model, str(urdf), pin.GeometryType.COLLISION, package_dirs=dirs
        )
        mesh_rotations = tuple(mesh_rotations)
        _turn_collision_meshes(model, collision_model, mesh_rotations)
        pin.loadReferenceConfigurations(model, str(srdf), False)
        references = _reference_configurations(model)
        if reference_posture not in references:
            raise FrameNotFound("reference posture", reference_posture, references)
        q_reference = references[reference_posture]

        lock_ids, locked_values = [], {}
        for joint in locked_joints:
            if not model.existJointName(joint):
                raise FrameNotFound("joint", joint, list(model.names))
            lock_ids.append(model.getJointId(joint))
            start = model.idx_qs[lock_ids[-1]]
            locked_values[joint] = q_reference[start : start + model.nqs[lock_ids[-1]]]
        if lock_ids:
            model, (collision_model,) = pin.buildReducedModel(
                model, [collision_model], lock_ids, q_reference
            )
            pin.loadReferenceConfigurations(model, str(srdf), False)
            q_reference = _reference_configurations(model)[reference_posture]

        # Names first: removing objects invalidates the python views on them.
        names = [geometry.name for geometry in collision_model.geometryObjects]
        for geometry_name in names:
            if geometry_name.startswith(tuple(removed_geometry_prefixes)):
                collision_model.removeGeometryObject(geometry_name)

        frame_names, plates, feet = {}, {}, []
        for declaration in surfaces:
            if not model.existFrame(declaration.parent_frame):
                raise FrameNotFound(
                    "frame", declaration.parent_frame, [f.name for f in model.frames], f"robot surface {declaration.name!r}"
                )
            parent_id = model.getFrameId(declaration.parent_frame)
            parent = model.frames[parent_id]
            placement = parent.placement * declaration.placement  # in the parent joint's frame
            if declaration.plate is not None:
                placement = mount_plate(
                    model, collision_model, parent.parentJoint, placement, declaration.polygon, declaration.plate
                )
            frame_names[declaration.name] = contact_frame_name(declaration.name)
            if model.existFrame(frame_names[declaration.name]):
                # pinocchio would add a second frame of that name, and every later lookup
                # by name would fail with "Several frames match the filter".
                raise StanceError(
                    f"robot surface {declaration.name!r}: its contact frame would be named "
                    f"{frame_names[declaration.name]!r}, which the robot's model already has; "
                    "give the surface another name"
                )
            if declaration.radius is not None:
                feet.append(declaration.geometries)
            frame_id = model.addFrame(
                pin.Frame(frame_names[declaration.name], parent.parentJoint, parent_id, placement, pin.FrameType.OP_FRAME)
            )
            if declaration.plate is not None:
                plate = plate_geometry(
                    f"{declaration.name}_plate", model, frame_id, declaration.polygon, declaration.plate.thickness
                )
                collision_model.addGeometryObject(plate)
                plates[declaration.name] = (plate.name,)
        trim_into_balls(collision_model, feet)
        # After the plates: the SRDF knows nothing of them (they hang on new
        # frames), so a plate is checked against every link of other joints.
        collision_model.addAllCollisionPairs()
        pin.removeCollisionPairs(model, collision_model, str(srdf), False)
        geometry_names = [geometry.name for geometry in collision_model.geometryObjects]
        for first, second in (*checked_pairs, *ignored_pairs):
            for geometry_name in (first, second):
                if geometry_name not in geometry_names:
                    raise FrameNotFound("collision geometry", geometry_name, geometry_names)
        for first, second in checked_pairs:
            collision_model.addCollisionPair(
                pin.CollisionPair(geometry_names.index(first), geometry_names.index(second))
            )
        for first, second in ignored_pairs:
            collision_model.removeCollisionPair(
                pin.CollisionPair(geometry_names.index(first), geometry_names.index(second))
            )

        robot_surfaces = {}
        for declaration in surfaces:
            frame_name = frame_names[declaration.name]
            joint = model.frames[model.getFrameId(frame_name)].parentJoint
            # Without a plate or declared geometries, the surface is part of its
            # link's own geometry.
            for geometry_name in declaration.geometries:
                if geometry_name not in geometry_names:
                    raise FrameNotFound(
                        "collision geometry", geometry_name, geometry_names, f"robot surface {declaration.name!r}"
                    )
            contact_geometries = plates.get(declaration.name) or declaration.geometries or tuple(
                geometry.name for geometry in collision_model.geometryObjects if geometry.parentJoint == joint
            )
            robot_surfaces[declaration.name] = RobotSurface(
                declaration.name, frame_name, declaration.polygon, contact_geometries, declaration.role, declaration.limb,
                declaration.radius,
            )
        limb_roots = _limb_roots(model, robot_surfaces, limbs)
        robot = cls(
            name, model, collision_model, robot_surfaces, q_reference, limb_roots, support, locked_values, urdf,
            mesh_rotations,
        )
        checked = {frozenset(pair) for pair in checked_pairs}
        # A pair nearer than the solver keeps at the reference posture holds no posture near it
        # (iCub's pelvis and hip-pitch disc are 0.6 mm apart whatever the hip pitch).
        overlapping = [
            pair for pair in hull_overlaps(robot, q_reference, within=KEPT_DISTANCE) if frozenset(pair) not in checked
        ]
        ignore_self_pairs(robot, overlapping)
        if overlapping:
            logger.warning(
                "%s: %d self-collision pairs whose convex hulls already touch at the reference posture (or lie "
                "within the %g mm the posture solver keeps) are not checked: %s (list them in checked_pairs to "
                "check them anyway)",
                name, len(overlapping), 1e3 * KEPT_DISTANCE, ", ".join(f"{a}-{b}" for a, b in overlapping),
            )
        robot.ignored_pairs = tuple(tuple(pair) for pair in ignored_pairs) + tuple(overlapping)
        return robot

    @property
    def nq(self) -> int:
        """Size of a configuration vector (free-flyer quaternion included)."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Size of a velocity / tangent vector."""
        return self.model.nv

    @property
    def configuration_names(self) -> list[str]:
        """Name of each coordinate of a configuration q, ``(nq,)`` list.

        The free flyer's are ``<joint>:x``, ``:y``, ``:z`` (metres, world frame)
        and ``:qx``, ``:qy``, ``:qz``, ``:qw`` (its orientation quaternion); a
        one-coordinate joint's is the joint name, a joint with k coordinates
        gives ``<joint>:0`` to ``<joint>:k-1``.

        Examples
        --------
        >>> names = Robot.load("talos").configuration_names
        >>> names[:8], len(names)
        (['root_joint:x', 'root_joint:y', 'root_joint:z', 'root_joint:qx', 'root_joint:qy', 'root_joint:qz', 'root_joint:qw', 'leg_left_1_joint'], 35)
        """
        names = []
        for joint_id in range(1, self.model.njoints):
            joint, name = self.model.joints[joint_id], self.model.names[joint_id]
            if joint.shortname() == "JointModelFreeFlyer":
                names += [f"{name}:{axis}" for axis in ("x", "y", "z", "qx", "qy", "qz", "qw")]
            elif joint.nq == 1:
                names.append(name)
            else:
                names += [f"{name}:{index}" for index in range(joint.nq)]
        return names

    @property
    def actuated_joint_names(self) -> list[str]:
        """Names of the actuated joints, in tangent-vector order after the free flyer."""
        return [name for name in self.model.names[2:]]

    @property
    def effort_limits(self) -> np.ndarray:
        """(nv - 6,) float: torque limit of each actuated joint, N m."""
        return np.asarray(self.model.effortLimit[6:], dtype=float)

    @property
    def mass(self) -> float:
        """Total mass, kilograms."""
        return float(pin.computeTotalMass(self.model))

    @property
    def weight(self) -> float:
        """Weight, newtons: the mass times the model's gravity."""
        return self.mass * float(np.linalg.norm(self.model.gravity.linear))

    def surface(self, name: str) -> RobotSurface:
        """The robot contact surface called ``name``.

        Raises
        ------
        FrameNotFound
            Listing the declared surfaces.
        """
        try:
            return self.surfaces[name]
        except KeyError:
            raise FrameNotFound("robot surface", name, self.surfaces) from None

    def surfaces_with_role(self, role: str, limb: str | None = None) -> list[str]:
        """Names of the contact surfaces with a role (and on a limb), in declaration order.

        Parameters
        ----------
        role : str
            ``"foot"`` or ``"hand"``.
        limb : str, optional
            Only the surfaces of this limb.

        Examples
        --------
        >>> Robot.load("talos").surfaces_with_role("foot")
        ['left_sole', 'right_sole']
        """
        return [
            name
            for name, surface in self.surfaces.items()
            if surface.role == role and (limb is None or surface.limb == limb)
        ]

    def reference_position(self, frame: str) -> np.ndarray:
        """(3,) float: where frame ``frame`` is at the reference posture, metres, world frame.

        Made once per reference posture (every cold start reads its feet's: a
        pinocchio Data and forward kinematics, 0.2 ms, for the same answer each time).

        Raises
        ------
        FrameNotFound
            If the model has no such frame.
        """
        key, positions = self._reference_positions
        reference = np.asarray(self.reference_configuration, dtype=float)
        current = reference.tobytes()
        if key != current:
            data = pin.Data(self.model)
            pin.framesForwardKinematics(self.model, data, reference)
            positions = {}
            for frame_data, placement in zip(self.model.frames, data.oMf):
                positions.setdefault(frame_data.name, placement.translation.copy())  # the first, as getFrameId
            self._reference_positions = (current, positions)
        try:
            position = positions[frame]
        except KeyError:
            raise FrameNotFound("frame", frame, list(positions)) from None
        return position.copy()

    def frame_id(self, name: str) -> int:
        """Pinocchio frame index of ``name``, with a helpful error."""
        if not self.model.existFrame(name):
            raise FrameNotFound("frame", name, [f.name for f in self.model.frames])
        return self.model.getFrameId(name)

    def __repr__(self) -> str:
        return (
            f"Robot({self.name!r}, nq={self.nq}, nv={self.nv}, "
            f"surfaces={sorted(self.surfaces)})"
        )


__all__ = [
    "MeshRotation",
    "PlateDeclaration",
    "Robot",
    "RobotSurface",
    "SupportRule",
    "SurfaceDeclaration",
    "builtin_robot_names",
    "example_robot_data_share",
]
