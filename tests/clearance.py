"""Robot-to-scene clearances measured independently of stances.collision.

The solver measures convex hulls of the robot meshes (stances.narrow_phase) and
exempts what ``contact_exclusions`` says; this helper measures pinocchio's own
collision geometry (the full triangle meshes, through pin.computeDistances)
against shapes rebuilt here from the scene's objects, and exempts only the
geometry named here as touching.
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

# The geometry that forms each surface of Talos, Romeo and iCub, written out here rather
# than read from the robot: a palm touches with its plate only (iCub's, a box, with its
# face), a sole with the foot mesh.
CONTACT_GEOMETRY = {
    "talos": {
        "left_palm": ("left_palm_plate",),
        "right_palm": ("right_palm_plate",),
        "left_sole": ("leg_left_6_link_0",),
        "right_sole": ("leg_right_6_link_0",),
    },
    "romeo": {
        "left_palm": ("left_palm_plate",),
        "right_palm": ("right_palm_plate",),
        "left_sole": ("l_ankle_0",),
        "right_sole": ("r_ankle_0",),
    },
    "icub": {
        "left_palm": ("l_hand_0",),
        "right_palm": ("r_hand_0",),
        "left_sole": ("l_foot_0",),
        "right_sole": ("r_foot_0",),
    },
}


def _scene_geometry(scene, deformations=None):
    """(name, placement, coal shape) of every scene object, world frame."""
    placed = []
    for name, obj in scene.objects.items():
        if obj.deformable:
            nodes = obj.points_in_world(obj.mesh.nodes)
            low, high = nodes.min(axis=0), nodes.max(axis=0)
            field = deformations[name] if deformations is not None and name in deformations else None
            if field is None and np.isclose(obj.mesh.volumes.sum(), np.prod(high - low), rtol=1e-9):
                # A soft box at rest: a solid box, so a link wholly inside counts as inside.
                placed.append((name, pin.SE3(np.eye(3), 0.5 * (low + high)), coal.Box(*(high - low))))
                continue
            # Deformed, or any other shape (a soft step): its boundary triangles.
            corners = (obj.rest_surface() if field is None else obj.deformed_surface(field)).reshape(-1, 3)
            placed.append((name, pin.SE3.Identity(), _triangle_mesh(corners, np.arange(len(corners)).reshape(-1, 3))))
        elif obj.box_size is not None:
            transform = obj.transform_object_to_world
            placed.append((name, pin.SE3(transform[:3, :3], transform[:3, 3]), coal.Box(*obj.box_size)))
        else:
            # Any other rigid object: its own triangle mesh, placed in the world.
            world = obj.mesh_in_world()
            placed.append((name, pin.SE3.Identity(), _triangle_mesh(world.vertices, world.faces)))
    return placed


def _triangle_mesh(vertices, triangles):
    """A coal triangle mesh (BVH) of (n, 3) vertices and (t, 3) vertex indices."""
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(len(triangles), len(vertices))
    mesh.addVertices(np.ascontiguousarray(vertices, dtype=float))
    mesh.addTriangles(np.ascontiguousarray(triangles, dtype=int))
    mesh.endModel()
    return mesh


def robot_clearances(robot, scene, stance, q, deformations=None) -> dict:
    """Distance of every robot geometry to every scene object, but a surface's own to its support.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance
    q : (nq,) float
    deformations : dict of str to (N, 3) float, optional
        Displacement fields of the soft objects, metres, body frame: those
        objects are then their deformed boundary meshes instead of their rest
        boxes.

    Returns
    -------
    dict of (str, str) to float
        ``(robot geometry, scene object) -> distance`` in metres (coal's
        distance on the full meshes; <= 0 when they overlap).
    """
    touching = {
        (geometry, scene.surface(contact.contact_print.surface).object_name)
        for contact in stance
        for geometry in CONTACT_GEOMETRY[robot.name][contact.robot_surface]
    }
    geometry_model = robot.collision_model.copy()
    geometry_model.removeAllCollisionPairs()
    count = len(geometry_model.geometryObjects)
    scene_ids = {
        name: geometry_model.addGeometryObject(pin.GeometryObject(name, 0, 0, placement, shape))
        for name, placement, shape in _scene_geometry(scene, deformations)
    }
    for index in range(count):
        for name, scene_id in scene_ids.items():
            if (geometry_model.geometryObjects[index].name, name) not in touching:
                geometry_model.addCollisionPair(pin.CollisionPair(index, scene_id))
    geometry_data = pin.GeometryData(geometry_model)
    pin.computeDistances(robot.model, robot.model.createData(), geometry_model, geometry_data, np.asarray(q))
    objects = geometry_model.geometryObjects
    return {
        (objects[pair.first].name, objects[pair.second].name): float(result.min_distance)
        for pair, result in zip(geometry_model.collisionPairs, geometry_data.distanceResults)
    }
