"""Mesh generation: structured tensor-product boxes and gmsh meshing of closed surfaces."""

from __future__ import annotations

import itertools
import logging
from collections.abc import Sequence

import numpy as np

from .errors import FemError, MeshError
from .mesh import TetMesh

__all__ = ["tensor_mesh", "box_mesh", "graded_coordinates", "mesh_from_surface"]

logger = logging.getLogger(__name__)

#: Most nodes a structured mesh may have. Beyond it the stiffness factorisation
#: needs tens of gigabytes (3 dofs and about 80 stored entries per dof row), so a
#: request this large is a mistaken spacing, refused before numpy allocates the grid.
MAX_TENSOR_NODES = 2_000_000


def _kuhn_tets() -> np.ndarray:
    """The 6 tets of the unit cube around its diagonal 000-111, positively oriented.

    Corners are numbered ``i + 2 j + 4 k`` (the Kuhn / Freudenthal subdivision).
    """
    tets = []
    for perm in itertools.permutations(range(3)):
        corner = np.zeros(3, dtype=int)
        path = [0]
        for axis in perm:
            corner[axis] = 1
            path.append(int(corner @ [1, 2, 4]))
        sign = np.linalg.det(np.eye(3)[list(perm)])
        if sign < 0:  # odd permutation: swap two nodes to orient positively
            path[2], path[3] = path[3], path[2]
        tets.append(path)
    return np.array(tets)


_CUBE_TETS = _kuhn_tets()

# An odd number of mirrorings reverses a tet's orientation: swap its last two nodes.
_REVERSES = np.array([bin(f).count("1") % 2 == 1 for f in range(8)])


def _mirrored_tets(corners: np.ndarray, flips: np.ndarray) -> np.ndarray:
    """Tets of cells split around alternating diagonals: each cell the mirror image of its neighbours.

    One diagonal everywhere (Kuhn) makes the mesh stiffer along it: a point load
    pressing a top node of a 10 mm foam mesh down moved the node sideways by 0.12 of
    its sinking, toward (-x, -y) at every node, and a ball or a sole pressed straight
    down got a sideways reaction of 10 % (on each axis) or 2 % of its load, always the
    same way. Mirroring the cells of odd index along an axis across that axis keeps
    the mesh conforming (neighbours split their shared face along the same face
    diagonal) and makes it symmetric about every grid plane, so that bias cancels: the
    sideways motion falls to about 0.001 of the sinking (at most 0.0012 on that mesh).
    The price: top nodes where eight surface triangles meet and those where four do
    alternate in point compliance (about 27 % apart).

    Parameters
    ----------
    corners : (c, 8) int
        Node ids of each cell's corners in ``i + 2 j + 4 k`` order.
    flips : (c,) int
        Bit a set: mirror the cell along axis a.

    Returns
    -------
    (6 c, 4) int
        Positively oriented tets.
    """
    mirrored = np.take_along_axis(corners, np.arange(8)[None, :] ^ flips[:, None], axis=1)
    tets = mirrored[:, _CUBE_TETS]  # (c, 6, 4)
    reverse = _REVERSES[flips]
    tets[reverse] = tets[reverse][:, :, [0, 1, 3, 2]]
    return tets.reshape(-1, 4)


def _check_axis(name: str, values: Sequence[float]) -> np.ndarray:
    axis = np.asarray(values, dtype=float)
    if axis.ndim != 1 or axis.size < 2:
        raise MeshError(f"{name} must be a 1-D array of at least 2 coordinates, got {axis.shape}")
    if not np.all(np.isfinite(axis)):
        raise MeshError(f"{name} contains NaN or inf")
    if np.any(np.diff(axis) <= 0):
        k = int(np.flatnonzero(np.diff(axis) <= 0)[0])
        raise MeshError(f"{name} must be strictly increasing; {name}[{k + 1}] <= {name}[{k}]")
    return axis


def tensor_mesh(xs: Sequence[float], ys: Sequence[float], zs: Sequence[float], cells=None) -> TetMesh:
    """Mesh the box ``[xs[0], xs[-1]] x [ys[0], ys[-1]] x [zs[0], zs[-1]]`` (or some of its cells) with tets.

    Each cell of the grid ``xs x ys x zs`` is split into 6 positively oriented tets
    around a diagonal, each cell the mirror image of its neighbours (so the mesh is
    conforming and has no preferred direction, :func:`_mirrored_tets`). Uneven
    spacings let a scene refine only where prints land.

    Parameters
    ----------
    xs, ys, zs : (nx,), (ny,), (nz,) float
        Strictly increasing grid coordinates, metres, body frame.
    cells : (nx - 1, ny - 1, nz - 1) bool, optional
        Which grid cells to mesh (a solid made of grid-aligned boxes, e.g. a
        step); all by default. Nodes of no kept cell are dropped and the others
        renumbered in the same order.

    Returns
    -------
    TetMesh
        With every cell: ``nx * ny * nz`` nodes (node id ``i + nx * (j + ny * k)``)
        and ``6 (nx - 1)(ny - 1)(nz - 1)`` tets; 6 tets per kept cell otherwise.

    Raises
    ------
    MeshError
        If a coordinate array is not strictly increasing or has fewer than 2 values,
        or if the mesh would have more than :data:`MAX_TENSOR_NODES` nodes.

    Examples
    --------
    >>> mesh = tensor_mesh([0, 0.5, 1], [0, 1], [0, 0.2, 1])
    >>> mesh.n_nodes, mesh.n_tets
    (18, 24)
    >>> step = np.zeros((2, 1, 2), bool); step[:, 0, 0] = True; step[1, 0, 1] = True   # an L
    >>> tensor_mesh([0, 0.5, 1], [0, 1], [0, 0.2, 1], cells=step).n_nodes
    16
    """
    xs, ys, zs = _check_axis("xs", xs), _check_axis("ys", ys), _check_axis("zs", zs)
    nx, ny, nz = xs.size, ys.size, zs.size
    _check_node_count(nx, ny, nz)
    gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
    # Node id i + nx (j + ny k): flatten with x fastest.
    nodes = np.stack([gx.ravel("F"), gy.ravel("F"), gz.ravel("F")], axis=1)
    i, j, k = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), np.arange(nz - 1), indexing="ij")
    base = (i + nx * (j + ny * k)).ravel()
    corner_offsets = np.array(
        [dx + nx * (dy + ny * dz) for dz in (0, 1) for dy in (0, 1) for dx in (0, 1)]
    )
    corners = base[:, None] + corner_offsets[None, :]  # (cells, 8) in i + 2j + 4k order
    # Bit a of flips: the cell is mirrored along axis a (odd index along it).
    flips = ((i % 2) + 2 * (j % 2) + 4 * (k % 2)).ravel()
    if cells is not None:
        cells = np.asarray(cells)
        if cells.shape != (nx - 1, ny - 1, nz - 1) or cells.dtype != bool:
            raise MeshError(f"cells must be a boolean array of shape {(nx - 1, ny - 1, nz - 1)}, got {cells.dtype} {cells.shape}")
        if not cells.any():
            raise MeshError("cells keeps no cell of the grid: nothing to mesh")
        corners, flips = corners[cells.ravel()], flips[cells.ravel()]
        used = np.unique(corners)
        renumber = np.full(len(nodes), -1)
        renumber[used] = np.arange(used.size)
        nodes, corners = nodes[used], renumber[corners]
    tets = _mirrored_tets(corners, flips)
    return TetMesh(nodes, tets)


def _check_node_count(nx: int, ny: int, nz: int) -> None:
    """Refuse a grid of more than :data:`MAX_TENSOR_NODES` nodes, saying what fits."""
    count = nx * ny * nz  # Python ints: no overflow for any request
    if count > MAX_TENSOR_NODES:
        # The same shape scaled down uniformly: coarsen each axis by this factor.
        factor = (count / MAX_TENSOR_NODES) ** (1.0 / 3.0)
        raise MeshError(
            f"a {nx} x {ny} x {nz} grid has {count} nodes, more than the limit of {MAX_TENSOR_NODES} "
            f"(fem.meshing.MAX_TENSOR_NODES); use about {factor:.3g} times fewer divisions per axis, "
            f"e.g. {max(1, int((nx - 1) / factor))} x {max(1, int((ny - 1) / factor))} x "
            f"{max(1, int((nz - 1) / factor))} cells"
        )


def graded_coordinates(start: float, stop: float, divisions: int, ratio: float = 1.0) -> np.ndarray:
    """Coordinates whose spacing shrinks geometrically from ``start`` to ``stop``.

    Parameters
    ----------
    start, stop : float
        Interval ends, metres, ``start < stop``.
    divisions : int
        Number of intervals, >= 1.
    ratio : float, optional
        First interval length / last interval length, > 0. 1 is uniform; 10 makes the
        cells at ``stop`` ten times thinner than those at ``start``.

    Returns
    -------
    (divisions + 1,) float
        Increasing coordinates, exactly ``start`` and ``stop`` at the ends.
    """
    if divisions < 1:
        raise MeshError(f"divisions must be >= 1, got {divisions}")
    if not ratio > 0:
        raise MeshError(f"grading ratio must be > 0, got {ratio}")
    if divisions == 1 or ratio == 1.0:
        return np.linspace(start, stop, divisions + 1)
    q = (1.0 / ratio) ** (1.0 / (divisions - 1))
    lengths = q ** np.arange(divisions)
    t = np.concatenate([[0.0], np.cumsum(lengths)]) / lengths.sum()
    t[-1] = 1.0
    return start + (stop - start) * t


def box_mesh(
    size: Sequence[float],
    divisions: Sequence[int],
    origin: Sequence[float] = (0.0, 0.0, 0.0),
    grading: float | None = None,
) -> TetMesh:
    """Mesh the box ``[origin, origin + size]`` with conforming tets.

    Parameters
    ----------
    size : (3,) float
        Edge lengths, metres, all > 0.
    divisions : (3,) int
        Number of cells along x, y, z, all >= 1.
    origin : (3,) float, optional
        Minimum corner, metres, body frame.
    grading : float, optional
        Ratio (bottom layer height) / (top layer height) > 0; values > 1 concentrate
        the layers toward the top face where prints land (geometric progression in z).

    Returns
    -------
    TetMesh

    Examples
    --------
    >>> mesh = box_mesh((1.0, 1.0, 1.0), (2, 2, 2))
    >>> round(float(mesh.volumes.sum()), 12)
    1.0
    """
    size_arr = np.asarray(size, dtype=float)
    div = np.asarray(divisions)
    origin_arr = np.asarray(origin, dtype=float)
    if size_arr.shape != (3,) or not np.all(size_arr > 0):
        raise MeshError(f"size must be 3 positive lengths in metres, got {size}")
    if div.shape != (3,) or not np.all(div >= 1) or not np.all(div == np.round(div)):
        raise MeshError(f"divisions must be 3 integers >= 1, got {divisions}")
    if origin_arr.shape != (3,) or not np.all(np.isfinite(origin_arr)):
        raise MeshError(f"origin must be 3 finite coordinates, got {origin}")
    # Checked before linspace: a huge division count must not allocate its axes.
    _check_node_count(*(int(d) + 1 for d in div))
    end = origin_arr + size_arr
    xs = np.linspace(origin_arr[0], end[0], int(div[0]) + 1)
    ys = np.linspace(origin_arr[1], end[1], int(div[1]) + 1)
    zs = graded_coordinates(origin_arr[2], end[2], int(div[2]), 1.0 if grading is None else grading)
    return tensor_mesh(xs, ys, zs)


def mesh_from_surface(
    surface,
    max_edge: float,
    refine_box: Sequence[Sequence[float]] | None = None,
    refine_size: float | None = None,
    refine_growth: float = 0.5,
    feature_angle_deg: float = 40.0,
) -> TetMesh:
    """Mesh the solid enclosed by a closed triangle surface with gmsh.

    Parameters
    ----------
    surface : trimesh.Trimesh
        Closed, consistently oriented (watertight) surface, metres, body frame.
    max_edge : float
        Target edge length away from the refinement region, metres.
    refine_box : (2, 3) float, optional
        Minimum and maximum corners of a region (e.g. where prints land) meshed with
        edge ``refine_size``; the size grows linearly away from it.
    refine_size : float, optional
        Edge length inside ``refine_box``, metres (default ``max_edge / 4``).
    refine_growth : float, optional
        Increase of the edge length per metre of distance to the box.
    feature_angle_deg : float, optional
        Dihedral angle above which surface edges are kept as sharp features.

    Returns
    -------
    TetMesh
        Positively oriented tets (orientation fixed if gmsh returns inverted ones).

    Raises
    ------
    FemError
        If gmsh is not installed, cannot initialise, or fails to mesh the surface.
    MeshError
        If the surface is not watertight or the result is not a valid mesh.
    """
    try:
        import gmsh
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise FemError("mesh_from_surface needs the 'gmsh' package: pip install gmsh") from exc
    if not getattr(surface, "is_watertight", False):
        raise MeshError("surface must be a closed (watertight) trimesh.Trimesh")
    if not max_edge > 0:
        raise MeshError(f"max_edge must be > 0 m, got {max_edge}")
    fine = max_edge / 4.0 if refine_size is None else float(refine_size)
    box = None if refine_box is None else np.asarray(refine_box, dtype=float).reshape(2, 3)

    vertices = np.asarray(surface.vertices, dtype=float)
    faces = np.asarray(surface.faces, dtype=np.int64)
    try:
        gmsh.initialize(interruptible=False)
    except Exception as exc:
        raise FemError(f"gmsh could not initialise: {exc}") from exc
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("solid")
        discrete = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addNodes(
            2, discrete, np.arange(1, len(vertices) + 1), vertices.ravel()
        )
        gmsh.model.mesh.addElementsByType(discrete, 2, [], (faces + 1).ravel())
        gmsh.model.mesh.classifySurfaces(np.deg2rad(feature_angle_deg), True, True, np.pi)
        gmsh.model.mesh.createGeometry()
        surfaces = [tag for _, tag in gmsh.model.getEntities(2)]
        loop = gmsh.model.geo.addSurfaceLoop(surfaces)
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", float(max_edge))
        gmsh.option.setNumber("Mesh.MeshSizeMin", float(min(fine, max_edge)))
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        if box is not None:

            def size_at(dim, tag, x, y, z, lc):  # noqa: ARG001 - gmsh signature
                p = np.array([x, y, z])
                gap = np.maximum(np.maximum(box[0] - p, p - box[1]), 0.0)
                return float(min(max_edge, fine + refine_growth * np.linalg.norm(gap)))

            gmsh.model.mesh.setSizeCallback(size_at)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, elem_nodes = gmsh.model.mesh.getElementsByType(4)
    except Exception as exc:
        raise FemError(f"gmsh failed to mesh the surface: {exc}") from exc
    finally:
        gmsh.finalize()
    if len(elem_nodes) == 0:
        raise FemError("gmsh produced no tetrahedra; is the surface closed and oriented?")
    coords = np.asarray(coords).reshape(-1, 3)
    tags = np.asarray(tags, dtype=np.int64)
    lookup = np.full(tags.max() + 1, -1, dtype=np.int64)
    lookup[tags] = np.arange(tags.size)
    tets = lookup[np.asarray(elem_nodes, dtype=np.int64).reshape(-1, 4)]
    used, compact = np.unique(tets, return_inverse=True)
    logger.debug("gmsh meshed %d nodes, %d tets", used.size, tets.shape[0])
    return TetMesh(coords[used], compact.reshape(-1, 4), fix_orientation=True)
