"""The rigid twin of a scenario: every soft object replaced by a rigid one of the same shape.

A benchmark of soft supports needs its baseline: the same scene, the same
stances and goal, with nothing deforming. The twin is built from the loaded
scenario, not from a second file, so the two cannot drift apart: each
deformable object becomes a rigid object whose mesh is the FEM body's boundary
at rest (an exact box when that boundary is a box, so that collision uses
FCL's box as for a scenario ``box``), and each of its contact surfaces keeps
its name, polygon, frame and friction with ``deformable`` False.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import trimesh

from .errors import SceneError
from .objects import RigidObject, box
from .scenario import Scenario
from .scene import Scene

__all__ = ["rigid_twin", "rigid_object_of"]

# Relative volume mismatch below which a body's boundary is taken to be its
# bounding box: a meshed box matches it to round-off, any other shape misses by
# far more (a 1 cm notch in a 10 cm block is 1e-3 of its volume).
_BOX_VOLUME_TOLERANCE = 1e-9


def rigid_object_of(deformable_object) -> RigidObject:
    """A rigid object of the same shape and placement as a deformable one.

    Parameters
    ----------
    deformable_object : environments DeformableObject
        Its FEM mesh gives the shape (body frame, metres).

    Returns
    -------
    RigidObject
        Same name. A box (``box_size`` set, frame at the box centre) when the
        body's boundary encloses exactly its bounding box, else the boundary
        triangle mesh in the body frame, placed by ``transform_body_to_world``.

    Raises
    ------
    SceneError
        If ``deformable_object`` is not a deformable object.
    """
    if not getattr(deformable_object, "deformable", False) or not hasattr(deformable_object, "mesh"):
        raise SceneError(
            f"rigid_object_of needs a deformable object (a soft_box, soft_blocks or soft_mesh of a scene), "
            f"got {type(deformable_object).__name__}"
        )
    mesh = deformable_object.mesh
    nodes = np.asarray(mesh.nodes, dtype=float)
    # The mesh's boundary, watertight (a soft_blocks object's collision_mesh, its blocks'
    # faces, is not: a rigid object's mesh is a closed solid).
    boundary = trimesh.Trimesh(nodes, np.asarray(mesh.surface_triangles), process=True)
    lower, upper = nodes.min(axis=0), nodes.max(axis=0)
    box_volume = float(np.prod(upper - lower))
    volume = float(np.sum(mesh.volumes))
    if abs(volume - box_volume) <= _BOX_VOLUME_TOLERANCE * box_volume:
        centre_in_world = np.array(deformable_object.transform_body_to_world, dtype=float)
        centre_in_world[:3, 3] = deformable_object.points_in_world(0.5 * (lower + upper))
        return box(deformable_object.name, upper - lower, pose=centre_in_world)
    return RigidObject(deformable_object.name, boundary, deformable_object.transform_body_to_world)


def rigid_twin(scenario: Scenario) -> Scenario:
    """The scenario with every deformable object made rigid, all else unchanged.

    Parameters
    ----------
    scenario : Scenario
        A loaded scenario (``environments.load``).

    Returns
    -------
    Scenario
        Named ``<name>-rigid``; the same robot, stances, start, goal and
        options; its scene has the rigid objects of ``scenario`` in their
        order followed by one rigid object per deformable one
        (:func:`rigid_object_of`), and the same contact surfaces, by name, none
        deformable. It has no file and no YAML text (``path`` and ``text``
        None): it was built in code, and a plan of it must not claim the soft
        scenario's file as its source.
        A scenario without soft objects gives a twin equal to it in all but
        its name.

    Raises
    ------
    SceneError
        If ``scenario`` is not a Scenario (e.g. a file name: load it first).

    Examples
    --------
    >>> from environments import load
    >>> twin = rigid_twin(load("cross-soft-block"))
    >>> twin.name, [obj.name for obj in twin.scene.rigid_objects], twin.scene.deformable_objects
    ('cross-soft-block-rigid', ['floor', 'foam'], ())
    >>> twin.scene.surface("foam_top").deformable
    False
    """
    if not isinstance(scenario, Scenario):
        raise SceneError(
            f"rigid_twin needs a loaded Scenario (environments.load(name_or_path)), got {type(scenario).__name__}"
        )
    scene = scenario.scene
    rigid = list(scene.rigid_objects) + [rigid_object_of(obj) for obj in scene.deformable_objects]
    surfaces = [dataclasses.replace(s, deformable=False) if s.deformable else s for s in scene.surfaces.values()]
    twin_scene = Scene(f"{scene.name}-rigid", rigid, (), surfaces)
    return Scenario(
        name=f"{scenario.name}-rigid",
        scene=twin_scene,
        robot=scenario.robot,
        stances=scenario.stances,
        start=scenario.start,
        goal=scenario.goal,
        description=f"Rigid twin of {scenario.name}: every soft object made rigid. {scenario.description}".strip(),
        options=scenario.options,
    )
