"""What a user looks at, as plain arrays: one display per stance of a plan.

Both the pictures (:mod:`cbm.render`) and the interactive page
(:mod:`cbm.viewer`) draw from these, so they always show the same thing.
Everything is in the world frame, metres and newtons.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

__all__ = [
    "StanceDisplay",
    "DeformableDisplay",
    "robot_segments",
    "box_edges",
    "scene_edges",
    "stance_display",
    "plan_bounds",
    "contact_colours",
    "ROBOT_RGB",
]

# Colours of the robot surfaces by role, in declaration order within a role
# (Talos: left sole blue, right sole red, left palm cyan, right palm orange).
# Purple is the forces' colour; green marks a surface without a colour.
_ROLE_COLOURS = {
    "foot": ("#1f77b4", "#d62728", "#8c564b", "#e377c2"),
    "hand": ("#17becf", "#ff7f0e", "#bcbd22", "#7f7f7f"),
}
_UNKNOWN_COLOUR = "#2ca02c"
#: The robot's colour in the page and the pictures (red, green, blue in 0..255): a
#: light steel blue, apart from the prints', the forces' and viridis' colours.
ROBOT_RGB = (150, 165, 200)

# Edges of a unit cube's 8 corners, indexed as bits (x, y, z).
_CUBE_EDGES = np.array(
    [[a, b] for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
)
# Boxes wider than this are clipped to the view (the floor is 10 m wide).
_CLIP_SIZE = 3.0


@dataclass(frozen=True, eq=False)
class DeformableDisplay:
    """Surface of one deformed body.

    Parameters
    ----------
    name : str
        Deformable object name.
    vertices : (v, 3) float
        Deformed surface nodes, metres, world frame.
    triangles : (t, 3) int
        Rows of indices into ``vertices``.
    magnitude : (v,) float
        Displacement magnitude of each vertex, metres.
    """

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    magnitude: np.ndarray


@dataclass(frozen=True, eq=False)
class StanceDisplay:
    """Everything drawn for one stance.

    Parameters
    ----------
    label : str
        Short title, e.g. ``"stance 2/6: place left_sole on foam_top"``.
    segments : (m, 2, 3) float
        Robot stick figure: each row a segment (joint to parent joint, and
        link to contact frame), metres, world frame.
    polygons : dict of str to (k, 3) float
        Contact print of each robot surface in contact, world frame.
    force_points : (c, 3) float
        Application point of each contact's resultant (its centre of
        pressure estimate), world frame.
    forces : (c, 3) float
        Resultant contact force on the robot per contact, newtons, world frame.
    deformables : tuple of DeformableDisplay
        Every deformable object, deformed by this stance.
    colours : dict of str to str
        Colour of each robot surface in ``polygons``, ``"#rrggbb"``.
    robot_transforms : (g, 4, 4) float
        Placement of each of the robot's visual meshes
        (:class:`cbm.robot_mesh.RobotMeshes`), world frame; empty when the
        robot is drawn as its stick figure only.
    frames : dict of str to (4, 4) float
        Frames a user may show (off by default): the robot's base and the frame
        of each robot surface in contact, world frame, at the stance's posture.
    """

    label: str
    segments: np.ndarray
    polygons: dict
    force_points: np.ndarray
    forces: np.ndarray
    deformables: tuple = field(default=())
    colours: dict = field(default_factory=dict)
    robot_transforms: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    frames: dict = field(default_factory=dict)


def contact_colours(robot):
    """A colour for each robot surface, from its role and rank among that role's surfaces.

    Parameters
    ----------
    robot : stances Robot

    Returns
    -------
    dict of str to str
        Robot surface -> ``"#rrggbb"``.
    """
    colours, rank = {}, {}
    for name, surface in robot.surfaces.items():
        palette = _ROLE_COLOURS.get(surface.role, (_UNKNOWN_COLOUR,))
        index = rank.get(surface.role, 0)
        rank[surface.role] = index + 1
        colours[name] = palette[index % len(palette)]
    return colours


def robot_segments(model, q, extra_frames=()):
    """Stick figure of a robot from forward kinematics.

    Parameters
    ----------
    model : pinocchio.Model
    q : (nq,) float
        Configuration.
    extra_frames : iterable of str
        Frames (e.g. contact frames) joined to their parent joint.

    Returns
    -------
    (m, 2, 3) float
        Segments from each joint to its parent joint (the free flyer's root
        excluded), then from each extra frame's joint to the frame, metres,
        world frame.
    """
    data = model.createData()
    pin.forwardKinematics(model, data, np.asarray(q, dtype=float))
    pin.updateFramePlacements(model, data)
    segments = []
    for joint in range(1, model.njoints):
        parent = model.parents[joint]
        if parent == 0:
            continue
        segments.append((data.oMi[parent].translation, data.oMi[joint].translation))
    for name in extra_frames:
        frame_id = model.getFrameId(name)
        joint = model.frames[frame_id].parentJoint
        segments.append((data.oMi[joint].translation, data.oMf[frame_id].translation))
    return np.array(segments, dtype=float).reshape(-1, 2, 3)


def box_edges(transform_object_to_world, lower, upper):
    """The 12 edges of a box, ``(12, 2, 3)`` metres, world frame.

    Parameters
    ----------
    transform_object_to_world : (4, 4) float
    lower, upper : (3,) float
        Box corners, metres, object frame.
    """
    bits = (np.arange(8)[:, None] >> np.arange(3)) & 1
    corners = np.where(bits, np.asarray(upper, float), np.asarray(lower, float))
    transform = np.asarray(transform_object_to_world, dtype=float)
    corners = corners @ transform[:3, :3].T + transform[:3, 3]
    return corners[_CUBE_EDGES]


def scene_edges(scene, view_bounds=None):
    """Wireframes of the rigid objects.

    Parameters
    ----------
    scene : environments Scene
    view_bounds : (2, 3) float, optional
        World box, metres; boxes wider than 3 m (the floor) are clipped to
        it in x and y when they are axis aligned.

    Returns
    -------
    dict of str to (e, 2, 3) float
        Edges per object name, metres, world frame.
    """
    edges = {}
    for obj in scene.rigid_objects:
        transform = np.asarray(obj.transform_object_to_world, dtype=float)
        lower, upper = obj.bounds_in_object
        aligned = np.allclose(transform[:3, :3], np.eye(3))
        if view_bounds is not None and aligned and np.max(upper[:2] - lower[:2]) > _CLIP_SIZE:
            world_lower, world_upper = lower + transform[:3, 3], upper + transform[:3, 3]
            world_lower[:2] = np.maximum(world_lower[:2], view_bounds[0][:2])
            world_upper[:2] = np.minimum(world_upper[:2], view_bounds[1][:2])
            edges[obj.name] = box_edges(np.eye(4), world_lower, world_upper)
        else:
            edges[obj.name] = box_edges(transform, lower, upper)
    return edges


def _deformable_display(obj, displacements):
    nodes = np.asarray(obj.mesh.nodes, dtype=float)
    triangles = np.asarray(obj.mesh.surface_triangles)
    used, remapped = np.unique(triangles, return_inverse=True)
    u = np.zeros_like(nodes) if displacements is None else np.asarray(displacements, dtype=float)
    vertices = obj.points_in_world(nodes[used] + u[used])
    magnitude = np.linalg.norm(u[used], axis=1)
    return DeformableDisplay(obj.name, vertices, remapped.reshape(triangles.shape), magnitude)


def stance_display(planned, scene, robot, label="", meshes=None):
    """Display data of one planned stance.

    Parameters
    ----------
    planned : cbm.plan.PlannedStance
        Stance, posture, forces and deformations.
    scene : environments Scene
    robot : stances Robot
    label : str
        Title.
    meshes : cbm.robot_mesh.RobotMeshes, optional
        The robot's visual meshes, placed at the stance's posture.

    Returns
    -------
    StanceDisplay
    """
    frames = [robot.surfaces[rs].frame for rs in robot.surfaces]
    segments = robot_segments(robot.model, planned.q, frames)
    polygons = {}
    for contact in planned.stance:
        p = contact.contact_print
        polygon = robot.surfaces[contact.robot_surface].polygon
        polygons[contact.robot_surface] = np.asarray(
            scene.surface(p.surface).print_polygon_in_world(polygon, p.x, p.y, p.theta)
        )
    points, forces = [], []
    for frame in sorted({f.frame for f in planned.point_forces}):
        group = [f for f in planned.point_forces if f.frame == frame]
        force = np.sum([f.force for f in group], axis=0)
        weights = np.array([max(f.force[2], 0.0) for f in group]) + 1e-12
        point = np.average([f.point for f in group], axis=0, weights=weights)
        points.append(point)
        forces.append(force)
    deformables = tuple(
        _deformable_display(obj, planned.deformations.get(obj.name)) for obj in scene.deformable_objects
    )
    colours = contact_colours(robot)
    return StanceDisplay(
        colours={name: colours.get(name, _UNKNOWN_COLOUR) for name in polygons},
        label=label,
        segments=segments,
        polygons=polygons,
        force_points=np.array(points, dtype=float).reshape(-1, 3),
        forces=np.array(forces, dtype=float).reshape(-1, 3),
        deformables=deformables,
        robot_transforms=np.zeros((0, 4, 4)) if meshes is None else meshes.transforms(robot.model, planned.q),
        frames=stance_frames(robot, planned.q, [contact.robot_surface for contact in planned.stance]),
    )


def stance_frames(robot, q, robot_surfaces):
    """World placements of the robot's base (its first joint, the free flyer) and of the
    frames of some robot surfaces, at posture ``q``.

    Returns
    -------
    dict of str to (4, 4) float
        ``"base"``, then each surface's frame by its frame name.
    """
    model = robot.model
    data = pin.Data(model)
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    frames = {"base": np.array(data.oMi[1].homogeneous)}
    for name in robot_surfaces:
        frame = robot.surfaces[name].frame
        frames[frame] = np.array(data.oMf[model.getFrameId(frame)].homogeneous)
    return frames


def plan_bounds(displays, margin=0.3):
    """World box around the robot and the prints of every stance, ``(2, 3)`` metres."""
    points = [d.segments.reshape(-1, 3) for d in displays]
    points += [p for d in displays for p in d.polygons.values()]
    points += [deformable.vertices for d in displays for deformable in d.deformables]
    points = np.concatenate(points) if points else np.zeros((1, 3))
    return np.array([points.min(axis=0) - margin, points.max(axis=0) + margin])
