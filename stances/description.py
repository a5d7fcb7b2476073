"""Robot description files: a robot as data (model files, surfaces with roles and limbs).

A description is a small YAML file; the built-in ones ship in ``stances/robots/``
(``talos.yaml`` is the reference example)::

    name: talos
    model:
      example_robot_data: talos_data      # a folder of example-robot-data's robots/;
      urdf: robots/talos_reduced.urdf     # without it, paths are relative to this file
      srdf: srdf/talos.srdf               # and package_dirs (list) resolve package:// URIs
    locked_joints: [head_1_joint, head_2_joint]
    reference_posture: half_sitting       # an SRDF group state
    support: {role: foot, keep: 1}        # a stance keeps at least one foot down
    limbs: {left_leg: leg_left_1_joint, left_arm: arm_left_1_joint}   # limb -> root joint
    surfaces:
      left_sole:
        role: foot                        # foot or hand
        limb: left_leg
        link: left_sole_link              # URDF link or frame carrying the surface
        xyz: [0, 0, 0]                    # contact frame in that frame, metres
        rpy_deg: [0, 0, 0]                #   (its z axis points into the link)
        polygon: [[-0.1, -0.065], [0.11, -0.065], [0.11, 0.065], [-0.1, 0.065]]
        plate: {thickness: 0.01, replaces: gripper_left_}   # optional, see stances.plates
      left_front_foot:                    # a point foot (see anymal.yaml): a ball
        role: foot
        limb: left_front_leg
        link: LF_FOOT
        xyz: [0, 0, 0.02325]              # the ball's centre in the link frame
        point: {radius: 0.031}            # in place of polygon, metres
        geometries: [LF_FOOT_0]           # optional: the collision geometries that touch
    checked_pairs: [[arm_left_5_link_0, wrist_left_ft_link_0]]   # optional
    ignored_pairs: [[base_link_0, FL_UPPER_LEG_0]]                 # optional
    mesh_rotations:                       # optional: meshes the URDF misplaces (icub.yaml)
      - {links: [l_foot, r_foot], rpy_deg: [90, 0, 0]}   # in each mesh's own frame

Self-collision is checked between the robot's convex hulls on the pairs the SRDF
leaves enabled, plus ``checked_pairs``, minus ``ignored_pairs``. Pairs whose hulls
already touch or overlap at the reference posture, or lie closer than the 5 mm the
posture solver keeps between bodies, are not checked either (a hull holds its mesh,
so two links that never meet can have hulls that do: Solo-12's base and upper legs
overlap by 4 mm standing, iCub's pelvis and hip-pitch discs are 0.6 mm apart at any
hip pitch; MoveIt's setup assistant disables pairs colliding in the default posture
the same way; loading logs a warning that names them); ``Robot.ignored_pairs`` lists
both kinds, and a pair named in ``checked_pairs`` is always checked.

A surface is a polygon (a sole, a palm: a rigid contact holds it with 6
placement equalities and a friction pyramid at each vertex) or a point foot (a
ball of ``radius`` centred on the contact frame's origin: 3 placement
equalities and one friction pyramid, see :mod:`stances.point_contact`).

``mesh_rotations`` turns the meshes of the links it lists in their own frame,
collision and visual, before anything is measured on them: for mesh files the
URDF places for a loader that turns them (see :mod:`stances.mesh_rotations`).

Reading a description checks its structure and values (roles, polygons, limbs)
without loading the model; names of links, joints and geometries are checked
against the model when :meth:`stances.Robot.from_description` builds it. Every
fault is a :class:`RobotDescriptionError` naming the file and the key path.
"""

from __future__ import annotations

import importlib.metadata
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from environments.plain_data import checked_mapping, join_key, kind_of, load_yaml

from .errors import RobotNotFound, StanceError
from .mesh_rotations import MeshRotation
from .plates import PlateDeclaration

__all__ = [
    "ROLES",
    "BUILTIN_DIRECTORY",
    "RobotDescriptionError",
    "SupportRule",
    "SurfaceDeclaration",
    "RobotDescription",
    "builtin_robot_names",
    "description_path",
    "example_robot_data_share",
    "point_print",
    "read_description",
    "read_description_text",
]

#: Roles a robot contact surface can have: a foot supports the robot and the
#: planner samples its prints only on surfaces facing up (a stance given by hand may
#: put it on any surface: the solver judges it); a hand may touch any surface.
ROLES = ("foot", "hand")

BUILTIN_DIRECTORY = Path(__file__).resolve().parent / "robots"
"""Folder of the built-in robot descriptions."""

_DESCRIPTION_SUFFIXES = (".yaml", ".yml")


class RobotDescriptionError(StanceError):
    """Invalid robot description, with the file and the key path at fault.

    Parameters
    ----------
    path : str or os.PathLike or None
        The description file (None for data that did not come from a file).
    key : str
        Dotted key path, e.g. ``"surfaces.left_sole.role"``; empty for the whole file.
    message : str
        What is wrong and what would be valid.
    """

    def __init__(self, path, key: str, message: str) -> None:
        self.path = None if path is None else os.fspath(path)
        self.key = key
        self.message = message
        where = self.path if self.path is not None else "<robot description>"
        super().__init__(f"{where}: {key}: {message}" if key else f"{where}: {message}")


@dataclass(frozen=True)
class SupportRule:
    """Which contacts a stance must keep: at least ``keep`` surfaces of ``role``.

    Parameters
    ----------
    role : str
        One of :data:`ROLES`.
    keep : int
        Smallest number of surfaces of that role in contact (>= 1): a biped
        keeps one foot down.
    load : float
        Smallest share of the robot's weight each of those surfaces carries
        while in contact, in ``[0, 1)``. On three point feet a foot carries the
        weight times the centre of mass's distance from the edge opposite the
        foot over the foot's own, so a quadruped's ``0.1`` keeps its centre of
        mass a tenth of the way in from each edge of the support triangle
        instead of on an edge with a foot just touching. 0: a foot may just
        touch.
    """

    role: str = "foot"
    keep: int = 1
    load: float = 0.0

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise StanceError(f"support role must be one of {', '.join(ROLES)}, got {self.role!r}")
        if isinstance(self.keep, bool) or not isinstance(self.keep, int) or self.keep < 1:
            raise StanceError(f"support 'keep' must be an integer >= 1, got {self.keep!r}")
        if isinstance(self.load, bool) or not isinstance(self.load, (int, float)) or not 0.0 <= self.load < 1.0:
            raise StanceError(
                f"support 'load' must be a share of the robot's weight in [0, 1), got {self.load!r}"
            )
        object.__setattr__(self, "load", float(self.load))


def _check_polygon(polygon, owner: str) -> np.ndarray:
    """A convex, counter-clockwise (k, 2) polygon with k >= 3, as floats, or a StanceError."""
    polygon = np.array(polygon, dtype=float)
    if polygon.ndim != 2 or polygon.shape[1] != 2 or len(polygon) < 3:
        raise StanceError(f"{owner}: polygon must be (k, 2) with k >= 3, got shape {polygon.shape}")
    if not np.all(np.isfinite(polygon)):
        raise StanceError(f"{owner}: polygon has non-finite vertices")
    edges = np.roll(polygon, -1, axis=0) - polygon
    turns = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
    if not np.all(turns > 0.0):
        raise StanceError(
            f"{owner}: polygon must be convex with its vertices counter-clockwise (seen from outside the "
            f"link), no repeated or aligned vertices; got {polygon.tolist()}"
        )
    return polygon


#: Vertices of a point foot's print polygon: a regular polygon circumscribing
#: the foot's circle, so that sampling keeps the whole foot inside a surface.
POINT_PRINT_VERTICES = 8


def _check_radius(radius, owner: str) -> float:
    if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not (math.isfinite(radius) and radius > 0):
        raise StanceError(f"{owner}: a point foot's radius must be a positive number of metres, got {radius!r}")
    return float(radius)


def point_print(radius: float) -> np.ndarray:
    """The print polygon of a point foot: a regular octagon around its circle.

    Parameters
    ----------
    radius : float
        Foot radius, metres.

    Returns
    -------
    (8, 2) float
        Vertices, metres, counter-clockwise, circumscribing the circle of
        ``radius`` (the planner keeps it inside surfaces; displays draw it).

    Examples
    --------
    >>> point_print(0.02).round(4)[:2].tolist()
    [[0.0216, 0.0], [0.0153, 0.0153]]
    """
    radius = _check_radius(radius, "point_print")
    angles = 2.0 * np.pi * np.arange(POINT_PRINT_VERTICES) / POINT_PRINT_VERTICES
    outer = radius / math.cos(math.pi / POINT_PRINT_VERTICES)
    return outer * np.column_stack([np.cos(angles), np.sin(angles)])


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
        Vertices in the contact frame, metres, convex, counter-clockwise seen
        from outside the link.
    plate : PlateDeclaration, optional
        A plate carrying the surface, in place of part of the link (a hand's
        gripper): its box becomes a collision geometry named
        ``"<name>_plate"``, the surface's only contact geometry.
    role : str
        One of :data:`ROLES`.
    limb : str
        Name of the limb the surface ends (a key of the description's limbs).
    radius : float, optional
        A point foot: the radius of its ball, metres, centred on the contact
        frame's origin; ``polygon`` is then its print (see :func:`point_print`).
    geometries : tuple of str
        Collision geometries forming the surface, the only ones allowed to
        touch its support; empty: every geometry of the link (or the plate).
    """

    name: str
    parent_frame: str
    placement: pin.SE3
    polygon: np.ndarray
    plate: PlateDeclaration | None = None
    role: str = ""  # required: the defaults only let plate keep its place
    limb: str = ""
    radius: float | None = None
    geometries: tuple = ()

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise StanceError(f"robot surface {self.name!r}: unknown role {self.role!r}; roles: {', '.join(ROLES)}")
        if not isinstance(self.limb, str) or not self.limb:
            raise StanceError(f"robot surface {self.name!r}: limb must be a non-empty limb name, got {self.limb!r}")
        if self.radius is not None:
            _check_radius(self.radius, f"robot surface {self.name!r}")
            if self.plate is not None:
                raise StanceError(f"robot surface {self.name!r}: a point foot carries no plate")
        object.__setattr__(self, "geometries", tuple(str(name) for name in self.geometries))
        polygon = _check_polygon(self.polygon, f"robot surface {self.name!r}")
        polygon.setflags(write=False)
        object.__setattr__(self, "polygon", polygon)


@dataclass(frozen=True)
class RobotDescription:
    """A robot as data: model files, posture, contact surfaces with roles and limbs.

    Parameters
    ----------
    name : str
        Robot name.
    urdf, srdf : Path
        Model files; the SRDF gives the reference posture and the collision
        pairs to ignore.
    package_dirs : tuple of Path
        Where ``package://`` mesh URIs resolve.
    surfaces : tuple of SurfaceDeclaration
        Contact surfaces, in the file's order.
    limbs : dict of str to str
        Limb name -> name of its root joint (the first joint of the chain
        from the body to the limb's surfaces).
    locked_joints : tuple of str
        Joints fixed at the reference posture and removed from the model.
    reference_posture : str
        SRDF group state used as reference configuration.
    support : SupportRule
        Contacts every stance keeps.
    checked_pairs : tuple of (str, str)
        Collision geometry pairs checked although the SRDF disables them.
    ignored_pairs : tuple of (str, str)
        Collision geometry pairs not checked although the SRDF enables them.
    mesh_rotations : tuple of MeshRotation
        Rotations of the meshes of some links, in each mesh's own frame (see
        :mod:`stances.mesh_rotations`).
    description : str
        Free text.
    path : Path or None
        File it was read from.
    """

    name: str
    urdf: Path
    srdf: Path
    package_dirs: tuple
    surfaces: tuple
    limbs: dict
    locked_joints: tuple = ()
    reference_posture: str = "half_sitting"
    support: SupportRule = SupportRule()
    checked_pairs: tuple = ()
    ignored_pairs: tuple = ()
    mesh_rotations: tuple = ()
    description: str = ""
    path: Path | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        names = [surface.name for surface in self.surfaces]
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            raise StanceError(f"robot {self.name!r}: repeated surface names {repeated}")
        for surface in self.surfaces:
            if surface.limb not in self.limbs:
                raise StanceError(
                    f"robot {self.name!r}: surface {surface.name!r} is on limb {surface.limb!r}, which is not "
                    f"declared; limbs: {', '.join(self.limbs) or '(none)'}"
                )
        if not any(surface.role == self.support.role for surface in self.surfaces):
            raise StanceError(
                f"robot {self.name!r}: the support rule keeps {self.support.role} surfaces but the robot has none"
            )
        count = sum(surface.role == self.support.role for surface in self.surfaces)
        if count * self.support.load >= 1.0:
            raise StanceError(
                f"robot {self.name!r}: the support rule asks each of its {count} {self.support.role} surfaces to "
                f"carry {self.support.load:g} of the weight, {count * self.support.load:g} in all when all touch; "
                f"give a 'load' below {1.0 / count:.4g}"
            )
        object.__setattr__(self, "limbs", dict(self.limbs))


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
        raise RobotNotFound("example-robot-data is not installed; `pip install example-robot-data`") from error
    share = Path(distribution.locate_file("cmeel.prefix/share"))
    if not (share / "example-robot-data" / "robots").is_dir():
        raise RobotNotFound(f"example-robot-data's robots folder is missing under {share}")
    return share


def builtin_robot_names() -> list[str]:
    """Sorted names of the built-in robots.

    Examples
    --------
    >>> builtin_robot_names()
    ['anymal', 'icub', 'romeo', 'talos']
    """
    return sorted(path.stem for path in BUILTIN_DIRECTORY.glob("*.yaml"))


def description_path(name_or_file) -> Path:
    """File of a built-in robot name, or the given description file.

    Raises
    ------
    RobotNotFound
        If it is neither a built-in name nor an existing file; lists the built-ins.
    """
    text = os.fspath(name_or_file)
    if text in builtin_robot_names():
        return BUILTIN_DIRECTORY / f"{text}.yaml"
    path = Path(text)
    if path.is_file():
        return path.resolve()
    hint = "no such file" if path.suffix in _DESCRIPTION_SUFFIXES or os.sep in text else "not a built-in robot"
    raise RobotNotFound(
        f"unknown robot {text!r} ({hint}); built-in robots: {', '.join(builtin_robot_names())}, "
        "or give a robot description file (.yaml)"
    )


def read_description(name_or_file) -> RobotDescription:
    """Read and check a robot description: a built-in name or a YAML file.

    Parameters
    ----------
    name_or_file : str or os.PathLike
        A name from :func:`builtin_robot_names`, or a description file.

    Returns
    -------
    RobotDescription

    Raises
    ------
    RobotNotFound
        For a name that is neither built in nor a file.
    RobotDescriptionError
        For any invalid entry, naming the file and the key.

    Examples
    --------
    >>> description = read_description("talos")
    >>> [(s.name, s.role, s.limb) for s in description.surfaces][:2]
    [('left_sole', 'foot', 'left_leg'), ('right_sole', 'foot', 'right_leg')]
    """
    path = description_path(name_or_file)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise RobotDescriptionError(path, "", f"cannot read: {error}") from None
    return read_description_text(text, path)


def read_description_text(text: str, path) -> RobotDescription:
    """Read and check a robot description given as text, as if it were the file ``path``:
    its relative model paths are read from that file's folder, and errors name it (a
    plan file carries its robot's description, so that it loads where the file is gone).

    Raises
    ------
    RobotDescriptionError
        For any invalid entry, naming ``path`` and the key.
    """
    path = Path(path)
    try:
        data = load_yaml(text)
    except yaml.YAMLError as error:
        raise RobotDescriptionError(path, "", f"YAML syntax error: {error}") from None
    return _Reader(path).description(data)


_TOP_KEYS = (
    "name", "description", "model", "locked_joints", "reference_posture", "support", "limbs", "surfaces",
    "checked_pairs", "ignored_pairs", "mesh_rotations",
)
_SURFACE_KEYS = ("role", "limb", "link", "xyz", "rpy_deg", "polygon", "point", "plate", "geometries")


class _Reader:
    """Validating reader of the plain data of one description file."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def error(self, key: str, message: str) -> RobotDescriptionError:
        return RobotDescriptionError(self.path, key, message)

    def mapping(self, value, key: str, allowed, required=()) -> dict:
        return checked_mapping(value, key, allowed, required, self.error)

    def string(self, value, key: str) -> str:
        if not isinstance(value, str) or not value:
            raise self.error(key, f"must be a non-empty string, got {kind_of(value)}")
        return value

    def strings(self, value, key: str) -> tuple:
        if not isinstance(value, list):
            raise self.error(key, f"must be a list of names, got {kind_of(value)}")
        return tuple(self.string(item, f"{key}[{index}]") for index, item in enumerate(value))

    def geometry_pairs(self, value, key: str) -> tuple:
        """A list of [name, name] collision geometry pairs, as a tuple of 2-tuples."""
        if not isinstance(value, list):
            raise self.error(key, f"must be a list of [geometry, geometry] pairs, got {kind_of(value)}")
        pairs = []
        for index, pair in enumerate(value):
            names = self.strings(pair, f"{key}[{index}]")
            if len(names) != 2:
                raise self.error(f"{key}[{index}]", f"must be a pair of collision geometry names, got {pair!r}")
            pairs.append(names)
        return tuple(pairs)

    def mesh_rotations(self, value, key: str) -> tuple:
        """A list of {links: [link, ...], rpy_deg: [r, p, y]} entries, as MeshRotation's."""
        if not isinstance(value, list):
            raise self.error(key, f"must be a list of {{links, rpy_deg}} entries, got {kind_of(value)}")
        rotations = []
        for index, item in enumerate(value):
            entry = f"{key}[{index}]"
            item = self.mapping(item, entry, ("links", "rpy_deg"), ("links", "rpy_deg"))
            links = self.strings(item["links"], join_key(entry, "links"))
            if not links:
                raise self.error(join_key(entry, "links"), "must name at least one link")
            rotations.append(MeshRotation(links, tuple(self.numbers(item["rpy_deg"], join_key(entry, "rpy_deg"), 3))))
        return tuple(rotations)

    def numbers(self, value, key: str, length: int) -> list:
        if not isinstance(value, list) or len(value) != length:
            raise self.error(key, f"must be a list of {length} numbers, got {kind_of(value)}")
        for index, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, (int, float)) or not math.isfinite(item):
                raise self.error(f"{key}[{index}]", f"must be a finite number, got {kind_of(item)}")
        return [float(item) for item in value]

    def file(self, value, key: str, base: Path) -> Path:
        path = (base / self.string(value, key)).resolve()
        if not path.is_file():
            raise self.error(key, f"file not found: {path}")
        return path

    def description(self, data) -> RobotDescription:
        top = self.mapping(data, "", _TOP_KEYS, ("model", "limbs", "surfaces"))
        name = self.string(top.get("name", self.path.stem), "name")
        urdf, srdf, package_dirs = self.model(top["model"])
        if not isinstance(top["limbs"], Mapping) or not top["limbs"]:
            raise self.error("limbs", f"must be a non-empty mapping of limb names to root joints, got {kind_of(top['limbs'])}")
        limbs = {str(limb): self.string(joint, f"limbs.{limb}") for limb, joint in top["limbs"].items()}
        surfaces_data = top["surfaces"]
        if not isinstance(surfaces_data, Mapping) or not surfaces_data:
            raise self.error("surfaces", f"must be a non-empty mapping of surface names to surfaces, got {kind_of(surfaces_data)}")
        surfaces = tuple(self.surface(str(surface), item, limbs) for surface, item in surfaces_data.items())
        support_data = self.mapping(top.get("support", {}), "support", ("role", "keep", "load"))
        pairs = {key: self.geometry_pairs(top.get(key, []), key) for key in ("checked_pairs", "ignored_pairs")}
        both = set(pairs["checked_pairs"]) & {p for pair in pairs["ignored_pairs"] for p in (pair, pair[::-1])}
        if both:
            raise self.error("ignored_pairs", f"pairs both checked and ignored: {sorted(both)}")
        description = top.get("description", "")
        if not isinstance(description, str):
            raise self.error("description", f"must be text, got {kind_of(description)}")
        try:
            support = SupportRule(**support_data)
            return RobotDescription(
                name=name,
                urdf=urdf,
                srdf=srdf,
                package_dirs=package_dirs,
                surfaces=surfaces,
                limbs=limbs,
                locked_joints=self.strings(top.get("locked_joints", []), "locked_joints"),
                reference_posture=self.string(top.get("reference_posture", "half_sitting"), "reference_posture"),
                support=support,
                checked_pairs=pairs["checked_pairs"],
                ignored_pairs=pairs["ignored_pairs"],
                mesh_rotations=self.mesh_rotations(top.get("mesh_rotations", []), "mesh_rotations"),
                description=" ".join(description.split()),
                path=self.path,
            )
        except RobotDescriptionError:
            raise
        except StanceError as error:
            raise self.error("", str(error)) from None

    def model(self, data):
        data = self.mapping(data, "model", ("example_robot_data", "urdf", "srdf", "package_dirs"), ("urdf", "srdf"))
        if "example_robot_data" in data:
            if "package_dirs" in data:
                raise self.error("model.package_dirs", "only without example_robot_data (its meshes resolve by themselves)")
            share = example_robot_data_share()
            folder = self.string(data["example_robot_data"], "model.example_robot_data")
            base = share / "example-robot-data" / "robots" / folder
            if not base.is_dir():
                known = sorted(p.name for p in base.parent.iterdir() if p.is_dir())
                raise self.error("model.example_robot_data", f"no folder {folder!r} in example-robot-data; folders: {', '.join(known)}")
            package_dirs = (share,)
        else:
            base = self.path.parent
            package_dirs = tuple(
                (base / directory).resolve() for directory in self.strings(data.get("package_dirs", []), "model.package_dirs")
            )
        return self.file(data["urdf"], "model.urdf", base), self.file(data["srdf"], "model.srdf", base), package_dirs

    def surface(self, name: str, data, limbs) -> SurfaceDeclaration:
        key = f"surfaces.{name}"
        data = self.mapping(data, key, _SURFACE_KEYS, ("role", "limb", "link"))
        role = data["role"]
        if role not in ROLES:
            raise self.error(join_key(key, "role"), f"unknown role {role!r}; roles: {', '.join(ROLES)}")
        limb = self.string(data["limb"], join_key(key, "limb"))
        if limb not in limbs:
            raise self.error(join_key(key, "limb"), f"unknown limb {limb!r}; limbs: {', '.join(limbs) or '(none)'}")
        if ("polygon" in data) == ("point" in data):
            raise self.error(key, "give its shape: either polygon (a sole, a palm) or point (a point foot), not both")
        radius = None
        if "point" in data:
            point = self.mapping(data["point"], join_key(key, "point"), ("radius",), ("radius",))
            try:
                radius = _check_radius(point["radius"], "point foot")
            except StanceError:
                raise self.error(join_key(key, "point.radius"), f"must be a positive number of metres, got {kind_of(point['radius'])}") from None
            vertices = point_print(radius)
        else:
            polygon = data["polygon"]
            if not isinstance(polygon, list) or len(polygon) < 3:
                raise self.error(join_key(key, "polygon"), f"must be a list of at least 3 [x, y] vertices, got {kind_of(polygon)}")
            vertices = [self.numbers(vertex, f"{key}.polygon[{index}]", 2) for index, vertex in enumerate(polygon)]
        geometries = self.strings(data.get("geometries", []), join_key(key, "geometries"))
        xyz = self.numbers(data.get("xyz", [0.0, 0.0, 0.0]), join_key(key, "xyz"), 3)
        rpy = [math.radians(angle) for angle in self.numbers(data.get("rpy_deg", [0.0, 0.0, 0.0]), join_key(key, "rpy_deg"), 3)]
        placement = pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))
        try:
            plate = None
            if "plate" in data:
                plate_data = self.mapping(data["plate"], join_key(key, "plate"), ("thickness", "replaces", "mass"), ("thickness",))
                plate = PlateDeclaration(**plate_data)
            return SurfaceDeclaration(
                name, self.string(data["link"], join_key(key, "link")), placement, vertices, plate, role, limb,
                radius, geometries,
            )
        except RobotDescriptionError:
            raise
        except StanceError as error:
            raise self.error(key, str(error)) from None
