"""The robot: a pinocchio model with declared contact surfaces.

A :class:`Robot` bundles what the posture solver needs to know about a
humanoid: its kinematic and inertial model, its collision geometry with the
self-collision pairs its SRDF allows, its joint and torque limits, a reference
posture, and the planar surfaces it may put in contact (soles, palm plates).

Contact-frame convention (used everywhere in :mod:`stances`): each robot
surface has a frame whose origin lies on the surface and whose z axis points
*into* the link, i.e. opposite to the surface's outward normal. A contact is
then simply "the robot surface frame coincides with the print frame", whose z
axis is the environment surface's outward normal.

Talos (the paper's HRP-2 is not public) is loaded from the files installed by
the ``example-robot-data`` package; no path of one machine is hard-coded.
"""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from .errors import FrameNotFound, RobotNotFound, StanceError
from .plates import PlateDeclaration, mount_plate, plate_geometry


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
    """

    name: str
    frame: str
    polygon: np.ndarray
    contact_geometries: tuple = ()

    def __post_init__(self) -> None:
        polygon = np.array(self.polygon, dtype=float)
        if polygon.ndim != 2 or polygon.shape[1] != 2 or len(polygon) < 3:
            raise StanceError(
                f"robot surface {self.name!r}: polygon must be (k, 2) with k >= 3, "
                f"got shape {polygon.shape}"
            )
        polygon.setflags(write=False)
        object.__setattr__(self, "polygon", polygon)
        object.__setattr__(self, "contact_geometries", tuple(str(name) for name in self.contact_geometries))

    @property
    def vertices_in_frame(self) -> np.ndarray:
        """(k, 3) float: the polygon's vertices in the contact frame (z = 0)."""
        return np.column_stack([self.polygon, np.zeros(len(self.polygon))])

    @property
    def area(self) -> float:
        """Area of the polygon, square metres (shoelace formula)."""
        x, y = self.polygon.T
        return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


@dataclass(frozen=True)
class SurfaceDeclaration:
    """Where a robot surface sits on a link, before it is added to a model.

    Parameters
    ----------
    name : str
        Robot surface name.
    parent_frame : str
        Existing pinocchio frame the surface is attached to.
    placement : pin.SE3
        Transform from the contact frame to ``parent_frame``; with a plate,
        from the plate's mounting frame (the link's flange, oriented as the
        contact frame), which the contact frame then lies beyond along its
        normal (see :func:`stances.plates.mount_plate`).
    polygon : (k, 2) float
        Vertices in the contact frame, metres.
    plate : PlateDeclaration, optional
        A plate carrying the surface, in place of part of the link (a hand's
        gripper): its box becomes a collision geometry named
        ``"<name>_plate"``, the surface's only contact geometry.
    """

    name: str
    parent_frame: str
    placement: pin.SE3
    polygon: np.ndarray
    plate: PlateDeclaration | None = None


def _rectangle(x_min: float, x_max: float, y_min: float, y_max: float) -> np.ndarray:
    return np.array([[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max]])


# Talos's feet: the sole frames already have z up (into the foot) at ground
# level; the rectangle is the bottom of the foot's collision mesh, slightly
# shrunk so that contact-point forces stay inside the real sole.
_TALOS_SOLE = _rectangle(-0.10, 0.11, -0.065, 0.065)
# The foot mesh's bottom is the sole plane to within 0.4 mm (a few vertices of
# the mesh lie up to 0.40 mm below it, measured): the foot mesh itself is the
# sole's contact geometry, and no other geometry of the foot link exists.
# The paper's "modified hand link": a flat plate replacing the gripper. It is
# mounted on the wrist flange (the tool frame, whose z axis already points back
# into the forearm, the contact-frame convention), past the wrist's own
# collision geometry: the forearm mesh reaches 17.0 mm beyond the flange
# (measured when the robot is built, see stances.plates). Its outer face, 27 mm
# from the flange with a 10 mm plate, is the palm.
_TALOS_PALM = _rectangle(-0.05, 0.05, -0.035, 0.035)
_TALOS_PALM_THICKNESS = 0.01
# Turned half a turn about the normal so that, with the forearm pointing down
# in front of the robot, the palm's x axis points forward: a print with
# theta = 0 is then the natural hand orientation.
_PALM_PLACEMENT = pin.SE3(pin.utils.rotate("z", np.pi), np.zeros(3))
# The plate takes the gripper's mass (1.184 kg, its links' total in the URDF),
# so that the robot weighs what Talos weighs; the mass moves from the gripper's
# centre (134 mm past the wrist joint) to the plate's (86 mm past it).
_LEFT_PALM_PLATE = PlateDeclaration(_TALOS_PALM_THICKNESS, replaces="gripper_left_")
_RIGHT_PALM_PLATE = PlateDeclaration(_TALOS_PALM_THICKNESS, replaces="gripper_right_")

TALOS_SURFACES = (
    SurfaceDeclaration("left_sole", "left_sole_link", pin.SE3.Identity(), _TALOS_SOLE),
    SurfaceDeclaration("right_sole", "right_sole_link", pin.SE3.Identity(), _TALOS_SOLE),
    SurfaceDeclaration("left_palm", "wrist_left_ft_tool_link", _PALM_PLACEMENT, _TALOS_PALM, _LEFT_PALM_PLATE),
    SurfaceDeclaration("right_palm", "wrist_right_ft_tool_link", _PALM_PLACEMENT, _TALOS_PALM, _RIGHT_PALM_PLATE),
)
# The grippers are replaced by the palm plates (locked first: a plate cannot
# replace a moving part), and the head does not take part in static postures:
# locking them keeps the problem small (nv = 34).
TALOS_LOCKED_JOINTS = ("gripper_left_joint", "gripper_right_joint", "head_1_joint", "head_2_joint")
# Pairs the SRDF marks "Never" that solved postures do bring into contact: the
# forearm against the wrist's force-torque sensor (measured -1.13 mm in
# hand-on-soft-cube before these were checked; 3.6 mm for arm 6). At the
# reference posture they are 15.5 and 12.8 mm apart.
TALOS_CHECKED_PAIRS = tuple(
    (f"arm_{side}_{link}_link_0", f"wrist_{side}_ft_link_0") for side in ("left", "right") for link in (5, 6)
)


def example_robot_data_share() -> Path:
    """Directory holding example-robot-data's ``robots/`` folder.

    Returns
    -------
    Path
        The ``share`` directory usable as a pinocchio package directory, so that
        ``package://example-robot-data/...`` mesh URIs resolve.

    Raises
    ------
    RobotNotFound
        If example-robot-data is not installed.
    """
    try:
        distribution = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as error:
        raise RobotNotFound(
            "example-robot-data is not installed; `pip install example-robot-data`"
        ) from error
    share = Path(distribution.locate_file("cmeel.prefix/share"))
    if not (share / "example-robot-data" / "robots").is_dir():
        raise RobotNotFound(f"example-robot-data's robots folder is missing under {share}")
    return share


def _reference_configurations(model) -> dict:
    # pinocchio's map iterates as (name, configuration) pairs.
    return {entry.key(): np.array(entry.data()) for entry in model.referenceConfigurations}


class Robot:
    """A humanoid model ready for posture problems.

    Build one with :meth:`Robot.load` (built-in robots) or
    :meth:`Robot.from_urdf` (any URDF/SRDF with declared contact surfaces).

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
        Contact surfaces by name.
    reference_configuration : (nq,) float
        Reference posture (read-only), the objective's target.
    locked_joints : dict of str to tuple of float
        Joints of the URDF removed from ``model``, with the configuration
        values they are locked at (radians or metres), in URDF order.
    urdf : Path or None
        The URDF file the model was built from.
    """

    def __init__(self, name, model, collision_model, surfaces, reference_configuration, locked_joints=None, urdf=None):
        self.name = name
        self.locked_joints = {str(k): tuple(float(v) for v in values) for k, values in dict(locked_joints or {}).items()}
        self.urdf = None if urdf is None else Path(urdf)
        self.model = model
        self.collision_model = collision_model
        self.surfaces = dict(surfaces)
        reference_configuration = np.array(reference_configuration, dtype=float)
        reference_configuration.setflags(write=False)
        self.reference_configuration = reference_configuration

    @classmethod
    def load(cls, name: str = "talos") -> "Robot":
        """Load a built-in robot.

        Parameters
        ----------
        name : str
            ``"talos"`` (the only built-in robot so far).

        Returns
        -------
        Robot

        Raises
        ------
        RobotNotFound
            For an unknown name.

        Examples
        --------
        >>> robot = Robot.load("talos")
        >>> sorted(robot.surfaces)
        ['left_palm', 'left_sole', 'right_palm', 'right_sole']
        >>> robot.model.nv
        34
        """
        if name != "talos":
            raise RobotNotFound(f"unknown robot {name!r}; built-in robots: talos")
        share = example_robot_data_share()
        talos = share / "example-robot-data" / "robots" / "talos_data"
        return cls.from_urdf(
            name="talos",
            urdf=talos / "robots" / "talos_reduced.urdf",
            srdf=talos / "srdf" / "talos.srdf",
            package_dirs=[share],
            surfaces=TALOS_SURFACES,
            locked_joints=TALOS_LOCKED_JOINTS,
            reference_posture="half_sitting",
            checked_pairs=TALOS_CHECKED_PAIRS,
        )

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
            Contact surfaces to add as frames, with their plates.
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

        Returns
        -------
        Robot
        """
        dirs = [str(d) for d in package_dirs]
        model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
        collision_model = pin.buildGeomFromUrdf(
            model, str(urdf), pin.GeometryType.COLLISION, package_dirs=dirs
        )
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

        frame_names, plates = {}, {}
        for declaration in surfaces:
            if not model.existFrame(declaration.parent_frame):
                raise FrameNotFound("frame", declaration.parent_frame, [f.name for f in model.frames])
            parent_id = model.getFrameId(declaration.parent_frame)
            parent = model.frames[parent_id]
            placement = parent.placement * declaration.placement  # in the parent joint's frame
            if declaration.plate is not None:
                placement = mount_plate(
                    model, collision_model, parent.parentJoint, placement, declaration.polygon, declaration.plate
                )
            frame_names[declaration.name] = f"{declaration.name}_contact"
            frame_id = model.addFrame(
                pin.Frame(frame_names[declaration.name], parent.parentJoint, parent_id, placement, pin.FrameType.OP_FRAME)
            )
            if declaration.plate is not None:
                plate = plate_geometry(
                    f"{declaration.name}_plate", model, frame_id, declaration.polygon, declaration.plate.thickness
                )
                collision_model.addGeometryObject(plate)
                plates[declaration.name] = (plate.name,)
        # After the plates: the SRDF knows nothing of them (they hang on new
        # frames), so a plate is checked against every link of other joints.
        collision_model.addAllCollisionPairs()
        pin.removeCollisionPairs(model, collision_model, str(srdf), False)
        geometry_names = [geometry.name for geometry in collision_model.geometryObjects]
        for first, second in checked_pairs:
            for geometry_name in (first, second):
                if geometry_name not in geometry_names:
                    raise FrameNotFound("collision geometry", geometry_name, geometry_names)
            collision_model.addCollisionPair(
                pin.CollisionPair(geometry_names.index(first), geometry_names.index(second))
            )

        robot_surfaces = {}
        for declaration in surfaces:
            frame_name = frame_names[declaration.name]
            joint = model.frames[model.getFrameId(frame_name)].parentJoint
            # Without a plate, the surface is part of its link's own geometry.
            contact_geometries = plates.get(declaration.name) or tuple(
                geometry.name for geometry in collision_model.geometryObjects if geometry.parentJoint == joint
            )
            robot_surfaces[declaration.name] = RobotSurface(
                declaration.name, frame_name, declaration.polygon, contact_geometries
            )
        return cls(name, model, collision_model, robot_surfaces, q_reference, locked_values, urdf)

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


__all__ = ["PlateDeclaration", "Robot", "RobotSurface", "SurfaceDeclaration", "example_robot_data_share"]
