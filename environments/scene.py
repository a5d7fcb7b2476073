"""A scene: rigid and deformable objects and the contact surfaces on them."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cached_property
from types import MappingProxyType

import numpy as np

from .deformable import DeformableObject
from .errors import SceneError, known_names
from .geometry import CollisionShape
from .objects import RigidObject
from .stance import Contact, ContactPrint
from .surfaces import ContactSurface

__all__ = ["Scene"]


class Scene:
    """Objects a robot stands in, and the surfaces it may touch.

    Parameters
    ----------
    name : str
        Scene name.
    rigid_objects : sequence of RigidObject
        Rigid obstacles and supports (the floor among them).
    deformable_objects : sequence of DeformableObject
        FEM bodies.
    surfaces : sequence of ContactSurface
        Contact surfaces; each names an object of the scene, and is deformable
        exactly when that object is.

    Raises
    ------
    SceneError
        On repeated names, a surface on an unknown object, or a mismatch of the
        deformable flag.

    Examples
    --------
    >>> from environments import box, floor, box_surfaces
    >>> ground = floor()
    >>> scene = Scene("demo", [ground], [], box_surfaces(ground, top_name="floor"))
    >>> scene.surface("floor").normal_in_world.tolist()
    [0.0, 0.0, 1.0]
    """

    def __init__(
        self,
        name: str,
        rigid_objects: Sequence[RigidObject] = (),
        deformable_objects: Sequence[DeformableObject] = (),
        surfaces: Sequence[ContactSurface] = (),
    ) -> None:
        if not isinstance(name, str) or not name:
            raise SceneError(f"Scene.name must be a non-empty string, got {name!r}")
        self._name = name
        rigid_objects, deformable_objects = tuple(rigid_objects), tuple(deformable_objects)
        for obj in rigid_objects:
            if not isinstance(obj, RigidObject):
                raise SceneError(f"scene {name!r}: rigid_objects must be RigidObject, got {type(obj).__name__}")
        for obj in deformable_objects:
            if not isinstance(obj, DeformableObject):
                raise SceneError(
                    f"scene {name!r}: deformable_objects must be DeformableObject, got {type(obj).__name__}"
                )
        objects: dict[str, RigidObject | DeformableObject] = {}
        for obj in rigid_objects + deformable_objects:
            if obj.name in objects:
                raise SceneError(f"scene {name!r}: repeated object name {obj.name!r}")
            objects[obj.name] = obj
        by_name: dict[str, ContactSurface] = {}
        for surface in surfaces:
            if not isinstance(surface, ContactSurface):
                raise SceneError(f"scene {name!r}: surfaces must be ContactSurface, got {type(surface).__name__}")
            if surface.name in by_name:
                raise SceneError(f"scene {name!r}: repeated surface name {surface.name!r}")
            if surface.object_name not in objects:
                raise SceneError(
                    f"scene {name!r}: surface {surface.name!r} is on unknown object {surface.object_name!r}; "
                    f"known objects: {known_names(objects)}"
                )
            if surface.deformable != objects[surface.object_name].deformable:
                raise SceneError(
                    f"scene {name!r}: surface {surface.name!r} has deformable={surface.deformable} but object "
                    f"{surface.object_name!r} is {'deformable' if objects[surface.object_name].deformable else 'rigid'}"
                )
            by_name[surface.name] = surface
        self._rigid = rigid_objects
        self._deformable = deformable_objects
        self._objects = MappingProxyType(objects)
        self._surfaces = MappingProxyType(by_name)

    @property
    def name(self) -> str:
        """Scene name."""
        return self._name

    @property
    def rigid_objects(self) -> tuple[RigidObject, ...]:
        """Rigid objects, in the order given."""
        return self._rigid

    @property
    def deformable_objects(self) -> tuple[DeformableObject, ...]:
        """Deformable objects, in the order given."""
        return self._deformable

    @property
    def objects(self) -> Mapping[str, RigidObject | DeformableObject]:
        """Every object by name (read-only mapping)."""
        return self._objects

    @property
    def surfaces(self) -> Mapping[str, ContactSurface]:
        """Every contact surface by name (read-only mapping)."""
        return self._surfaces

    def surface(self, name: str) -> ContactSurface:
        """A contact surface by name.

        Raises
        ------
        SceneError
            If there is none; lists the known surfaces.
        """
        try:
            return self._surfaces[name]
        except (KeyError, TypeError):
            raise SceneError(
                f"scene {self._name!r}: unknown surface {name!r}; known surfaces: {known_names(self._surfaces)}"
            ) from None

    def deformable(self, name: str) -> DeformableObject:
        """A deformable object by name.

        Raises
        ------
        SceneError
            If there is none; lists the deformable objects.
        """
        for obj in self._deformable:
            if obj.name == name:
                return obj
        raise SceneError(
            f"scene {self._name!r}: unknown deformable object {name!r}; "
            f"deformable objects: {known_names(o.name for o in self._deformable)}"
        )

    def deformable_of_surface(self, surface_name: str) -> DeformableObject | None:
        """The deformable object a surface belongs to, or None for a rigid surface.

        Raises
        ------
        SceneError
            If the surface is unknown.
        """
        surface = self.surface(surface_name)
        return self.deformable(surface.object_name) if surface.deformable else None

    def transform_print_to_world(self, contact_print: ContactPrint) -> np.ndarray:
        """Frame of a contact print in the world, ``(4, 4)``."""
        surface = self.surface(contact_print.surface)
        return surface.transform_print_to_world(contact_print.x, contact_print.y, contact_print.theta)

    def print_origin_in_world(self, contact_print: ContactPrint | Contact) -> np.ndarray:
        """Origin of a contact print (or of a contact's print), ``(3,)`` metres, world frame."""
        if isinstance(contact_print, Contact):
            contact_print = contact_print.contact_print
        return self.surface(contact_print.surface).point_in_world(contact_print.x, contact_print.y)

    def check_print(self, contact_print: ContactPrint, margin: float = 0.0) -> None:
        """Check a print names a known surface and its origin lies on it.

        Raises
        ------
        SceneError
            If the surface is unknown or the origin is outside its polygon shrunk by ``margin``.
        """
        surface = self.surface(contact_print.surface)
        if not surface.contains((contact_print.x, contact_print.y), margin):
            raise SceneError(
                f"print origin ({contact_print.x:g}, {contact_print.y:g}) is off surface {surface.name!r} "
                f"(polygon x in [{surface.polygon[:, 0].min():g}, {surface.polygon[:, 0].max():g}], "
                f"y in [{surface.polygon[:, 1].min():g}, {surface.polygon[:, 1].max():g}])"
            )

    @cached_property
    def _collision_objects(self) -> tuple[tuple[str, CollisionShape], ...]:
        placed = []
        for obj in self._rigid:
            if obj.box_size is not None:
                shape = CollisionShape(obj.transform_object_to_world, box_size=obj.box_size)
            else:
                shape = CollisionShape(obj.transform_object_to_world, vertices=obj.mesh.vertices, triangles=obj.mesh.faces)
            placed.append((obj.name, shape))
        for obj in self._deformable:
            placed.append((obj.name, _rest_collision_shape(obj)))
        return tuple(placed)

    def collision_objects(self) -> list[tuple[str, CollisionShape]]:
        """The collision geometry of every object at rest, placed in the world (built once, cached).

        Rigid boxes are boxes, other rigid objects their triangle meshes; a
        deformable object is its rest shape: a box when its mesh fills its
        bounding box, otherwise its boundary triangles.

        Returns
        -------
        list of (str, environments.geometry.CollisionShape)
            Object name and its shape, in the order of the scene's objects
            (rigid ones first).
        """
        return list(self._collision_objects)

    def __repr__(self) -> str:
        return (
            f"Scene({self._name!r}, objects={list(self._objects)}, surfaces={list(self._surfaces)})"
        )


def _rest_collision_shape(obj: DeformableObject) -> CollisionShape:
    nodes = np.asarray(obj.mesh.nodes, dtype=float)
    low, high = nodes.min(axis=0), nodes.max(axis=0)
    volume = float(np.sum(obj.mesh.volumes))
    if abs(volume - np.prod(high - low)) <= 1e-6 * np.prod(high - low):
        transform_box_to_body = np.eye(4)
        transform_box_to_body[:3, 3] = 0.5 * (low + high)
        return CollisionShape(obj.transform_body_to_world @ transform_box_to_body, box_size=high - low)
    if obj.collision_mesh is not None:
        return CollisionShape(obj.transform_body_to_world, vertices=obj.collision_mesh[0], triangles=obj.collision_mesh[1])
    # Its own boundary, not the convex hull: a hull would fill a soft step's
    # re-entrant corner where a foot on its tread stands.
    return CollisionShape(obj.transform_body_to_world, vertices=nodes, triangles=np.asarray(obj.mesh.surface_triangles))
