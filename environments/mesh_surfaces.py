"""Contact surfaces found on a triangle mesh: its flat regions, split into convex pieces.

A user drops in an STL of stairs or rubble and plans on it without typing any
surface. Adjacent facets lying in one plane are merged into a region; a region
facing up within a slope bound takes feet (and hands), any other region hands
only; each region is cut into convex pieces (a tread, a landing, the flat top of a
rock) and pieces smaller than a minimum area are dropped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from .errors import SceneError
from .geometry import polygon_area, polygon_centroid, transform_from_rotation_translation
from .objects import DEFAULT_FRICTION
from .surfaces import ContactSurface

__all__ = ["FoundSurface", "SurfaceSearch", "find_surfaces", "auto_surfaces", "ROLES"]

ROLES = ("foot", "hand")
"""Roles of a found surface: ``foot`` faces up within the slope bound (it takes feet
and hands), ``hand`` has any other orientation (hands only)."""

# Two facets are one plane when their normals differ by less than this angle and
# each vertex lies within _PLANE_DISTANCE of the region's first facet's plane:
# meshes written in float32 (STL) keep coplanar facets within about 1e-6 rad, while
# a finely tessellated curved surface, whose facets turn by a few degrees, is not
# taken for a plane.
_PLANE_ANGLE = math.radians(0.5)
_PLANE_DISTANCE = 1e-4
# A vertex is collinear with its neighbours (dropped from a piece's outline) when it
# is this far from their chord, metres.
_COLLINEAR = 1e-9


@dataclass(frozen=True)
class SurfaceSearch:
    """Settings of the search for flat regions on a mesh.

    Parameters
    ----------
    max_slope_deg : float
        Largest angle between a region's outward normal and world +z for it to take
        feet, degrees (default 20, the planner's bound for soles).
    min_area : float
        Smallest area of a convex piece kept, m^2 (default 0.01: a 10 cm square,
        about half a Talos sole).
    sides : bool
        Also keep regions of other orientations, for hands (walls, slopes, undersides).
    friction : float
        Friction coefficient given to every surface found.
    """

    max_slope_deg: float = 20.0
    min_area: float = 0.01
    sides: bool = True
    friction: float = DEFAULT_FRICTION

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_slope_deg) and 0.0 <= self.max_slope_deg < 90.0):
            raise SceneError(f"max_slope_deg must be in [0, 90) degrees, got {self.max_slope_deg!r}")
        if not (math.isfinite(self.min_area) and self.min_area > 0.0):
            raise SceneError(f"min_area must be > 0 m^2, got {self.min_area!r}")
        if not (math.isfinite(self.friction) and self.friction > 0.0):
            raise SceneError(f"friction must be finite and > 0, got {self.friction!r}")


@dataclass(frozen=True, eq=False)
class FoundSurface:
    """One convex piece of a flat region of a mesh.

    Parameters
    ----------
    role : {"foot", "hand"}
        ``foot`` when it faces up within the slope bound, else ``hand``.
    polygon : (k, 2) float
        Convex counter-clockwise vertices, metres, surface frame.
    transform_surface_to_object : (4, 4) float
        Frame at the piece's area centroid, z along the outward normal, object frame.
    tilt_deg : float
        Angle between the outward normal and world +z, degrees.
    """

    role: str
    polygon: np.ndarray
    transform_surface_to_object: np.ndarray
    tilt_deg: float

    @property
    def area(self) -> float:
        """Area, m^2."""
        return polygon_area(self.polygon)


def find_surfaces(mesh: trimesh.Trimesh, rotation_object_to_world=None, search: SurfaceSearch | None = None) -> list[FoundSurface]:
    """Flat convex pieces of a closed triangle mesh on which prints may be placed.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Triangle mesh, metres, object frame; a closed one wound inward or
        inconsistently is reoriented (on a copy) so that normals point out.
    rotation_object_to_world : (3, 3) float, optional
        Orientation of the object frame in the world (identity by default): the
        slope of a region is measured against world +z.
    search : SurfaceSearch, optional
        Slope bound, minimum area, sides.

    Returns
    -------
    list of FoundSurface
        Foot pieces first, then hand pieces; within a role by height of the
        centroid in the world, then world x, then world y (a stable order, so
        names built from it do not change between runs).

    Notes
    -----
    A region's frame has z along its outward normal; on a foot piece x is the
    object's x axis projected on the plane, on a hand piece y points up the plane
    (as on a box's side faces) unless the piece is level. Facets must share
    edges to be merged: a T-junction splits a plane into two regions.

    Examples
    --------
    >>> found = find_surfaces(trimesh.creation.box((0.4, 0.3, 0.2)))
    >>> [(f.role, round(f.area, 3), round(float(f.transform_surface_to_object[2, 3]), 3)) for f in found][:2]
    [('foot', 0.12, 0.1), ('hand', 0.12, -0.1)]
    """
    search = SurfaceSearch() if search is None else search
    rotation = np.eye(3) if rotation_object_to_world is None else np.asarray(rotation_object_to_world, dtype=float)
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise SceneError("find_surfaces needs a non-empty trimesh.Trimesh")
    if mesh.is_watertight and (not mesh.is_winding_consistent or mesh.volume < 0.0):
        # Files from other tools may be wound inward or inconsistently: the outward
        # normal decides which side a foot stands on.
        mesh = mesh.copy()
        trimesh.repair.fix_normals(mesh)
    vertices = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    normals = np.asarray(mesh.face_normals, dtype=float)
    areas = np.asarray(mesh.area_faces)
    cos_slope = math.cos(math.radians(search.max_slope_deg))
    found = []
    for region in _planar_regions(vertices, faces, normals, np.asarray(mesh.face_adjacency)):
        if areas[region].sum() < search.min_area:
            continue  # no piece of it can be large enough (a facet of a curved surface)
        normal = _unit(np.sum(normals[region] * areas[region][:, None], axis=0))
        up = float((rotation @ normal)[2])
        role = "foot" if up >= cos_slope else "hand"
        if role == "hand" and not search.sides:
            continue
        frame = _region_frame(normal, rotation, role)
        used, local_faces = np.unique(faces[region], return_inverse=True)
        offset = float(np.mean(vertices[used] @ normal))
        points_2d = vertices[used] @ frame[:, :2]
        for loop in _convex_pieces(local_faces.reshape(-1, 3), points_2d):
            polygon = points_2d[loop][_corners(points_2d[loop])]
            if polygon_area(polygon) < search.min_area:
                continue
            centroid = polygon_centroid(polygon)
            origin = frame[:, :2] @ centroid + offset * normal
            found.append(
                FoundSurface(
                    role,
                    polygon - centroid,
                    transform_from_rotation_translation(frame, origin),
                    math.degrees(math.acos(max(-1.0, min(1.0, up)))),
                )
            )

    def order(piece: FoundSurface):
        origin_in_world = rotation @ piece.transform_surface_to_object[:3, 3]
        return (ROLES.index(piece.role), *np.round([origin_in_world[2], origin_in_world[0], origin_in_world[1]], 9))

    return sorted(found, key=order)


def auto_surfaces(object_name: str, mesh: trimesh.Trimesh, transform_object_to_world,
                  search: SurfaceSearch | None = None, deformable: bool = False) -> list[ContactSurface]:
    """Scene contact surfaces found on an object's mesh.

    Parameters
    ----------
    object_name : str
        The object; surfaces are named ``<object>_top_<k>`` (role foot) and
        ``<object>_side_<k>`` (role hand), numbered in the order of
        :func:`find_surfaces`.
    mesh : trimesh.Trimesh
        Its closed surface, metres, object frame.
    transform_object_to_world : (4, 4) float
        Its placement.
    search : SurfaceSearch, optional
        Slope bound, minimum area, sides and friction.
    deformable : bool
        Whether the object is deformable.

    Returns
    -------
    list of ContactSurface
    """
    search = SurfaceSearch() if search is None else search
    transform_object_to_world = np.asarray(transform_object_to_world, dtype=float)
    surfaces, counts = [], {"foot": 0, "hand": 0}
    for piece in find_surfaces(mesh, transform_object_to_world[:3, :3], search):
        prefix = "top" if piece.role == "foot" else "side"
        surfaces.append(
            ContactSurface(
                f"{object_name}_{prefix}_{counts[piece.role]}",
                object_name,
                piece.polygon,
                transform_object_to_world @ piece.transform_surface_to_object,
                search.friction,
                deformable,
            )
        )
        counts[piece.role] += 1
    return surfaces


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _planar_regions(vertices, faces, normals, adjacency) -> list[np.ndarray]:
    """Face ids of each flat region: facets joined across shared edges, grown from a seed's plane."""
    neighbours = [[] for _ in range(len(faces))]
    for a, b in adjacency:
        neighbours[a].append(b)
        neighbours[b].append(a)
    cos_angle = math.cos(_PLANE_ANGLE)
    region_of = np.full(len(faces), -1)
    regions = []
    for seed in range(len(faces)):
        if region_of[seed] >= 0:
            continue
        normal = normals[seed]
        offset = float(vertices[faces[seed, 0]] @ normal)
        region_of[seed] = len(regions)
        members, stack = [seed], [seed]
        while stack:
            face = stack.pop()
            for other in neighbours[face]:
                if region_of[other] >= 0 or normals[other] @ normal < cos_angle:
                    continue
                if np.max(np.abs(vertices[faces[other]] @ normal - offset)) > _PLANE_DISTANCE:
                    continue
                region_of[other] = len(regions)
                members.append(other)
                stack.append(other)
        regions.append(np.array(sorted(members)))
    return regions


def _region_frame(normal: np.ndarray, rotation_object_to_world: np.ndarray, role: str) -> np.ndarray:
    """Rotation (3, 3) of a region's frame in the object frame: z the normal, x or y as documented."""
    up_in_object = rotation_object_to_world.T @ np.array([0.0, 0.0, 1.0])
    up_on_plane = up_in_object - (up_in_object @ normal) * normal
    if role == "hand" and np.linalg.norm(up_on_plane) > 1e-6:
        y_axis = _unit(up_on_plane)
        x_axis = np.cross(y_axis, normal)
    else:
        # The object's x axis on the plane; its y axis when x is (nearly) the normal.
        x_axis = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x_axis = _unit(x_axis - (x_axis @ normal) * normal)
    return np.column_stack([x_axis, np.cross(normal, x_axis), normal])


def _convex_pieces(faces: np.ndarray, points_2d: np.ndarray) -> list[list[int]]:
    """Vertex loops (counter-clockwise) of convex pieces covering a flat region's triangles.

    A region whose outline is convex is one piece. Otherwise Hertel-Mehlhorn's
    idea: triangulate, then merge two pieces across their shared boundary whenever
    the union is still convex, longest shared edges first. Two triangulations are
    tried and the one giving fewer pieces kept: the mesh's own, and, when the
    region has one outline (no hole), that outline's corners cut into ears (a
    finely meshed L-shaped landing then gives two pieces, not dozens).
    """
    triangles = [[int(v) for v in face] for face in faces]
    outline = _boundary_loop(triangles)
    if outline is None:
        return _merged_pieces(triangles, points_2d)
    corners = [outline[k] for k in _corners(points_2d[outline])]
    if _is_convex(points_2d[corners]):
        return [outline]
    ears = _ears(corners, points_2d)
    candidates = [_merged_pieces(triangles, points_2d)]
    if ears is not None:
        candidates.append(_merged_pieces(ears, points_2d))
    return min(candidates, key=len)


def _ears(loop: list[int], points_2d: np.ndarray) -> list[list[int]] | None:
    """Triangles of a simple counter-clockwise polygon by ear clipping, or None if it has no ear (not simple)."""
    remaining = list(loop)
    triangles = []
    while len(remaining) > 3:
        for index in range(len(remaining)):
            a, b, c = remaining[index - 1], remaining[index], remaining[(index + 1) % len(remaining)]
            corner = points_2d[[a, b, c]]
            if _cross(corner[1] - corner[0], corner[2] - corner[1]) <= 0.0:
                continue  # reflex or straight: not an ear
            others = points_2d[[v for v in remaining if v not in (a, b, c)]]
            inside = np.ones(len(others), dtype=bool)
            for k in range(3):
                inside &= _cross(corner[(k + 1) % 3] - corner[k], others - corner[k]) >= 0.0
            if inside.any():
                continue
            triangles.append([a, b, c])
            remaining.pop(index)
            break
        else:
            return None
    return triangles + [remaining]


def _cross(first: np.ndarray, second: np.ndarray):
    """z of the cross product of 2-D vectors (rows broadcast)."""
    return first[..., 0] * second[..., 1] - first[..., 1] * second[..., 0]


def _merged_pieces(triangles: list[list[int]], points_2d: np.ndarray) -> list[list[int]]:
    """Hertel-Mehlhorn merging of triangles into convex pieces (see :func:`_convex_pieces`)."""
    pieces = dict(enumerate(triangles))
    owner = {}
    for index, loop in pieces.items():
        for u, v in zip(loop, loop[1:] + loop[:1]):
            owner[(u, v)] = index
    shared = [(u, v) for (u, v) in owner if (v, u) in owner and u < v]
    shared.sort(key=lambda edge: (-np.linalg.norm(points_2d[edge[0]] - points_2d[edge[1]]), edge))
    for u, v in shared:
        a, b = owner.get((u, v)), owner.get((v, u))
        if a is None or b is None or a == b:
            continue
        merged = _boundary_loop([pieces[a], pieces[b]])
        if merged is None or not _is_convex(points_2d[merged]):
            continue
        for edge in zip(pieces[b], pieces[b][1:] + pieces[b][:1]):
            if owner.get(edge) == b:
                del owner[edge]
        del pieces[b]
        pieces[a] = merged
        for edge in zip(merged, merged[1:] + merged[:1]):
            owner[edge] = a
    return [pieces[index] for index in sorted(pieces)]


def _boundary_loop(loops: list[list[int]]) -> list[int] | None:
    """The boundary loop of pieces glued along their shared edges, or None if it is not one simple loop."""
    edges = set()
    for loop in loops:
        edges.update(zip(loop, loop[1:] + loop[:1]))
    boundary = {(u, v) for (u, v) in edges if (v, u) not in edges}
    following = {}
    for u, v in boundary:
        if u in following:
            return None  # a vertex touched twice: the union pinches there
        following[u] = v
    start = next(iter(following))
    loop = [start]
    while following[loop[-1]] != start:
        loop.append(following[loop[-1]])
        if len(loop) > len(following):
            return None
    return loop if len(loop) == len(following) else None


def _is_convex(points: np.ndarray) -> bool:
    """Whether a counter-clockwise loop turns left or goes straight at every vertex (no fold back)."""
    incoming = points - np.roll(points, 1, axis=0)
    outgoing = np.roll(points, -1, axis=0) - points
    cross = incoming[:, 0] * outgoing[:, 1] - incoming[:, 1] * outgoing[:, 0]
    dot = np.sum(incoming * outgoing, axis=1)
    scale = np.linalg.norm(incoming, axis=1) * np.linalg.norm(outgoing, axis=1)
    return bool(np.all(cross >= -1e-9 * scale) and np.all((cross > 1e-9 * scale) | (dot > 0.0)))


def _corners(points: np.ndarray) -> list[int]:
    """Indices of a loop's vertices that do not lie on the chord of their neighbours."""
    keep = []
    for index in range(len(points)):
        before, here, after = points[index - 1], points[index], points[(index + 1) % len(points)]
        chord = after - before
        length = np.linalg.norm(chord)
        if length == 0.0 or abs(_cross(chord, before - here)) / length > _COLLINEAR:
            keep.append(index)
    return keep
