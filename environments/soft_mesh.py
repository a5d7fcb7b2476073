"""Soft solids of any shape: a closed surface mesh tetrahedralised with gmsh, or a
tetrahedral mesh file, placed in the world, part of its boundary fixed, its contact
surfaces found like those of a rigid mesh (:mod:`environments.mesh_surfaces`).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from .deformable import (
    DEFAULT_MINIMUM_PRINT_CELLS, DEFAULT_STRAIN_LIMIT, DEFAULT_STRAIN_RADIUS, DeformableObject, _fem, _fine_spacing,
)
from .errors import SceneError
from .geometry import transform_from_rotation_translation
from .mesh_surfaces import SurfaceSearch, auto_surfaces, find_surfaces
from .objects import rpy_rotation
from .surfaces import ContactSurface

__all__ = ["soft_mesh", "FixedPlane", "ON_FLOOR", "TET_MESH_SUFFIXES"]

TET_MESH_SUFFIXES = (".msh", ".vtu", ".vtk", ".xdmf", ".med")
"""File endings read as tetrahedral meshes (with ``fem.read_mesh``); any other file
is a closed triangle surface for trimesh (STL, OBJ, PLY, ...), meshed with gmsh."""

# A node lies on a fixing plane when it is this close to it, metres: gmsh and
# meshio keep the nodes of a flat face on its plane to about 1e-12 m, a placement
# by roll, pitch and yaw moves them by about 1e-16 m per metre.
_ON_PLANE = 1e-6

# Cells grow away from the refined region by this many metres per metre (soft
# boxes grow by a ratio of 1.45 per cell, i.e. about 0.45 m per metre), up to
# _COARSE_FACTOR times the fine spacing, as in soft boxes.
_GROWTH = 0.45
_COARSE_FACTOR = 4.0


@dataclass(frozen=True)
class FixedPlane:
    """The fixed set F: the boundary nodes lying on a world plane ``axis = value``.

    Parameters
    ----------
    axis : {"x", "y", "z"}
        World axis normal to the plane.
    value : float
        Position of the plane along that axis, metres, world frame.
    """

    axis: str
    value: float

    def __post_init__(self) -> None:
        if self.axis not in ("x", "y", "z"):
            raise SceneError(f"a fixing plane is 'x = a', 'y = b' or 'z = c' (world frame), got axis {self.axis!r}")
        if not math.isfinite(self.value):
            raise SceneError(f"a fixing plane's position must be finite, got {self.value!r}")

    @classmethod
    def parse(cls, text: str) -> FixedPlane:
        """A plane from text such as ``"z = 0"`` or ``"x=-0.25"``.

        Raises
        ------
        SceneError
            If the text is not ``<x|y|z> = <number>``.
        """
        match = re.fullmatch(r"\s*([xyz])\s*=\s*([-+0-9.eE]+)\s*", str(text))
        try:
            return cls(match.group(1), float(match.group(2)))
        except (AttributeError, ValueError):
            raise SceneError(f"plane must read '<x|y|z> = <metres>' in the world frame, e.g. 'z = 0'; got {text!r}") from None

    def __str__(self) -> str:
        return f"{self.axis} = {self.value:g}"


ON_FLOOR = FixedPlane("z", 0.0)
"""The floor's top: a solid standing on the floor is fixed where it touches z = 0."""


def _read_solid(source, fine: float, search: SurfaceSearch, rotation_body_to_world: np.ndarray):
    """The tet mesh (body frame) and the surface on which contact surfaces are found.

    A surface file is meshed by gmsh with edges of ``fine`` metres over the region
    of its foot surfaces (all its surfaces when none faces up), growing by
    :data:`_GROWTH` per metre away from it to ``_COARSE_FACTOR * fine``.
    """
    fem = _fem()
    if isinstance(source, (str, os.PathLike)) and Path(source).suffix.lower() in TET_MESH_SUFFIXES:
        mesh = fem.read_mesh(source)
        nodes = np.asarray(mesh.nodes, dtype=float)
        return mesh, trimesh.Trimesh(nodes, np.asarray(mesh.surface_triangles), process=False)
    if isinstance(source, trimesh.Trimesh):
        surface = source
    else:
        try:
            surface = trimesh.load(source, force="mesh")
        except Exception as error:  # trimesh raises many types for bad files
            raise SceneError(f"cannot load mesh {os.fspath(source)!s}: {error}") from None
    if not surface.is_watertight:
        raise SceneError("the surface mesh is not closed (watertight): a soft solid needs a closed surface")
    found = find_surfaces(surface, rotation_body_to_world, search)
    region = [f for f in found if f.role == "foot"] or found
    refine_box = None
    if region:
        corners = np.vstack([
            np.column_stack([f.polygon, np.zeros(len(f.polygon)), np.ones(len(f.polygon))]) @ f.transform_surface_to_object.T
            for f in region
        ])[:, :3]
        refine_box = [corners.min(axis=0), corners.max(axis=0)]
    mesh = fem.mesh_from_surface(surface, _COARSE_FACTOR * fine, refine_box=refine_box, refine_size=fine,
                                 refine_growth=_GROWTH)
    return mesh, surface


def soft_mesh(
    name: str,
    source,
    material,
    position=(0.0, 0.0, 0.0),
    rpy=(0.0, 0.0, 0.0),
    fixed: FixedPlane = ON_FLOOR,
    resolution="default",
    search: SurfaceSearch | None = None,
    strain_limit: float = DEFAULT_STRAIN_LIMIT,
    strain_radius: float = DEFAULT_STRAIN_RADIUS,
    minimum_print_cells: float = DEFAULT_MINIMUM_PRINT_CELLS,
) -> tuple[DeformableObject, list[ContactSurface]]:
    """A deformable solid of any shape, fixed where it lies on a plane.

    Parameters
    ----------
    name : str
        Object name.
    source : str or os.PathLike or trimesh.Trimesh
        A closed triangle surface (a file trimesh reads, or a Trimesh), meshed
        with gmsh (:func:`fem.mesh_from_surface`), or a tetrahedral mesh file
        (:data:`TET_MESH_SUFFIXES`, read with :func:`fem.read_mesh`); metres, body frame.
    material : fem.LinearElasticMaterial
    position : (3,) float
        Origin of the body frame, metres, world frame.
    rpy : (3,) float
        Roll, pitch, yaw of the body frame, radians (``Rz(yaw) Ry(pitch) Rx(roll)``).
    fixed : FixedPlane
        Boundary nodes on this world plane are fixed (default the floor, z = 0).
    resolution : {"coarse", "default"} or float
        Edge length h where feet land, metres, or a preset as for soft boxes; a
        tetrahedral mesh file is used as it is.
    search : SurfaceSearch, optional
        How contact surfaces are found on the boundary (slope, minimum area,
        sides, friction).
    strain_limit : float
        Largest principal strain allowed in a stance.
    strain_radius : float
        Metres over which the strain is averaged before its bound applies (see
        :class:`DeformableObject`).
    minimum_print_cells : float
        Fewest surface cells a flat print must cover (see :class:`DeformableObject`).

    Returns
    -------
    (DeformableObject, list of ContactSurface)
        The object and its surfaces ``<name>_top_<k>`` and ``<name>_side_<k>``.

    Raises
    ------
    SceneError
        On a surface that is not closed, an unreadable file, or no boundary node
        on the fixing plane (the message gives the solid's extent along that axis).
    """
    fem = _fem()
    search = SurfaceSearch() if search is None else search
    fixed = FixedPlane.parse(fixed) if isinstance(fixed, str) else fixed
    position = np.asarray(position, dtype=float)
    rpy = np.asarray(rpy, dtype=float)
    if position.shape != (3,) or rpy.shape != (3,) or not np.all(np.isfinite(np.concatenate([position, rpy]))):
        raise SceneError(f"object {name!r}: position and rpy must be 3 finite numbers each")
    transform_body_to_world = transform_from_rotation_translation(rpy_rotation(*rpy), position)
    try:
        mesh, surface = _read_solid(source, _fine_spacing(resolution), search, transform_body_to_world[:3, :3])
    except SceneError as error:
        raise SceneError(f"object {name!r}: {error}") from None
    nodes_in_world = np.asarray(mesh.nodes) @ transform_body_to_world[:3, :3].T + transform_body_to_world[:3, 3]
    coordinate = nodes_in_world[:, "xyz".index(fixed.axis)]
    on_plane = np.flatnonzero(np.asarray(mesh.is_surface_node) & (np.abs(coordinate - fixed.value) <= _ON_PLANE))
    if on_plane.size < 3:
        raise SceneError(
            f"object {name!r}: {on_plane.size} boundary node(s) lie on the fixing plane {fixed} (the solid spans "
            f"{fixed.axis} = {coordinate.min():.6g} .. {coordinate.max():.6g} m in the world); place it so that a face "
            "lies on that plane, or give the plane it rests on"
        )
    body = fem.DeformableBody(mesh, material, on_plane)
    description = "faces on the floor (z = 0) fixed" if fixed == ON_FLOOR else f"faces on the plane {fixed} fixed"
    # Collisions see the user's surface when it is coarser than the tet mesh's boundary.
    coarser = len(surface.faces) < len(mesh.surface_triangles)
    obj = DeformableObject(name, body, transform_body_to_world, description, float(strain_limit), strain_radius,
                           (np.asarray(surface.vertices), np.asarray(surface.faces)) if coarser else None,
                           minimum_print_cells=minimum_print_cells)
    return obj, auto_surfaces(name, surface, transform_body_to_world, search, deformable=True)
