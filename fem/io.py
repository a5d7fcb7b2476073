"""Reading and writing tetrahedral meshes in any meshio format (.msh, .vtu, .xdmf, ...)."""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Mapping

import numpy as np

from .errors import MeshError
from .mesh import TetMesh

__all__ = ["read_mesh", "write_mesh", "write_pvd"]


def read_mesh(path: str | os.PathLike) -> TetMesh:
    """Read the tetrahedra of a mesh file.

    Parameters
    ----------
    path : str or path-like
        Any format meshio reads (``.msh``, ``.vtu``, ``.vtk``, ``.xdmf``, ``.med``, ...).

    Returns
    -------
    TetMesh
        All ``tetra`` cell blocks; nodes used by no tet (geometry points, surface-only
        nodes) are dropped and ids renumbered; inverted tets are reoriented.

    Raises
    ------
    MeshError
        If the file cannot be read (missing, corrupt, unknown format) or holds no
        linear ``tetra`` cells.
    """
    import meshio

    try:
        raw = _call_meshio(meshio.read, os.fspath(path))
    except Exception as exc:
        raise MeshError(f"cannot read mesh file {os.fspath(path)!r}: {exc}") from exc
    blocks = [np.asarray(c.data) for c in raw.cells if c.type == "tetra"]
    if not blocks:
        kinds = sorted({c.type for c in raw.cells})
        raise MeshError(
            f"{os.fspath(path)!r} holds no linear 'tetra' cells (found {kinds}); "
            "mesh the volume with 4-node tetrahedra"
        )
    tets = np.concatenate(blocks).astype(np.int64)
    used, compact = np.unique(tets, return_inverse=True)
    return TetMesh(np.asarray(raw.points, dtype=float)[used, :3], compact.reshape(-1, 4), fix_orientation=True)


def write_mesh(
    path: str | os.PathLike,
    mesh: TetMesh,
    point_data: Mapping[str, np.ndarray] | None = None,
    cell_data: Mapping[str, np.ndarray] | None = None,
    file_format: str | None = None,
    points: np.ndarray | None = None,
) -> None:
    """Write a mesh and optional fields with meshio.

    Parameters
    ----------
    path : str or path-like
        Output file; the format follows the extension unless ``file_format`` is given.
    mesh : TetMesh
        The mesh; node positions are written as they are (metres).
    point_data : mapping of str to (N, ...) array, optional
        Nodal fields, e.g. ``{"displacement": u}`` with u (N, 3) metres.
    cell_data : mapping of str to (M, ...) array, optional
        Per-tet fields, e.g. ``{"stress": s}`` with s (M, 6) pascals.
    file_format : str, optional
        meshio format name, e.g. ``"gmsh22"``.
    points : (N, 3) float, optional
        Node positions to write instead of ``mesh.nodes`` (e.g. deformed), metres.

    Raises
    ------
    MeshError
        If a field has the wrong length or meshio cannot write the format.
    """
    import meshio

    point_fields = {}
    for name, values in (point_data or {}).items():
        values = np.asarray(values)
        if values.shape[0] != mesh.n_nodes:
            raise MeshError(f"point_data[{name!r}] has {values.shape[0]} rows, expected {mesh.n_nodes}")
        point_fields[name] = values
    cells = {}
    for name, values in (cell_data or {}).items():
        values = np.asarray(values)
        if values.shape[0] != mesh.n_tets:
            raise MeshError(f"cell_data[{name!r}] has {values.shape[0]} rows, expected {mesh.n_tets}")
        cells[name] = [values]
    if points is None:
        points_out = np.asarray(mesh.nodes)
    else:
        points_out = np.asarray(points, dtype=float)
        if points_out.shape != mesh.nodes.shape:
            raise MeshError(f"points must have shape {mesh.nodes.shape}, got {points_out.shape}")
    out = meshio.Mesh(
        points_out, [("tetra", np.asarray(mesh.tets))], point_data=point_fields, cell_data=cells
    )
    try:
        _call_meshio(meshio.write, os.fspath(path), out, file_format=file_format)
    except Exception as exc:
        raise MeshError(f"meshio cannot write {os.fspath(path)!r}: {exc}") from exc


def write_pvd(path: str | os.PathLike, datasets) -> None:
    """Write a ParaView collection (``.pvd``): mesh files as a time series.

    ParaView opens the collection as one source whose time steps are the
    datasets' times, so its play button steps through them; datasets of one
    time with different parts are shown together.

    Parameters
    ----------
    path : str or path-like
        Output ``.pvd`` file.
    datasets : iterable of (float, int, path-like)
        ``(time, part, file)`` of each mesh file (e.g. ``.vtu``); files are
        written relative to the collection's folder when they are inside it.

    Raises
    ------
    MeshError
        If a time is not a finite number or a part not a non-negative integer.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> write_pvd(folder / "plan.pvd", [(0, 0, folder / "stance_00.vtu"), (1, 0, folder / "stance_01.vtu")])
    >>> print((folder / "plan.pvd").read_text().splitlines()[4])
        <DataSet timestep="1" part="0" file="stance_01.vtu"/>
    >>> import shutil; shutil.rmtree(folder)
    """
    from xml.sax.saxutils import quoteattr

    folder = os.path.dirname(os.path.abspath(path))
    lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "  <Collection>"]
    for time, part, file in datasets:
        if isinstance(time, bool) or not isinstance(time, (int, float, np.number)) or not np.isfinite(time):
            raise MeshError(f"a .pvd time must be a finite number, got {time!r}")
        if isinstance(part, bool) or not isinstance(part, (int, np.integer)) or part < 0:
            raise MeshError(f"a .pvd part must be a non-negative integer, got {part!r}")
        file = os.path.abspath(file)
        if os.path.commonpath([folder, file]) == folder:
            file = os.path.relpath(file, folder)
        lines.append(f"    <DataSet timestep={quoteattr(f'{time:g}')} part=\"{int(part)}\" file={quoteattr(file)}/>")
    lines += ["  </Collection>", "</VTKFile>", ""]
    with open(path, "w", encoding="utf-8") as stream:
        stream.write("\n".join(lines))


class _MeshioExit(Exception):
    """meshio tried to end the process; carries what it printed."""


def _call_meshio(function, *args, **kwargs):
    """Call a meshio function so that it can neither end the process nor print.

    meshio 5 prints a reader's error and then calls ``sys.exit(1)`` when no reader
    accepts a file (a corrupt ``.vtu`` or ``.msh``): a library must not end its
    caller's program, so the exit and the printed text become an ordinary exception
    whose message is that text. Both streams are captured because meshio prints the
    reader's error on stdout and its summary on stderr (through ``rich``, which looks
    up ``sys.stderr`` at each call, so the redirection reaches it).
    """
    captured = io.StringIO()
    try:
        with contextlib.redirect_stdout(captured), contextlib.redirect_stderr(captured):
            return function(*args, **kwargs)
    except SystemExit:
        said = " ".join(captured.getvalue().split()).removeprefix("Error: ")
        raise _MeshioExit(
            f"{said or 'meshio gave up without a reason'} (is the file complete and in the format its "
            "extension says?)"
        ) from None


def write_surface(path: str | os.PathLike, points, triangles) -> None:
    """Write a triangle surface (e.g. a robot's meshes placed in the world) with meshio.

    Parameters
    ----------
    path : str or path-like
        Output file; the format follows the extension (``.vtu`` for ParaView).
    points : (v, 3) float
        Vertices, metres.
    triangles : (t, 3) int
        Rows of indices into ``points``.

    Raises
    ------
    MeshError
        On arrays of the wrong shape, indices out of range, or a format meshio cannot write.
    """
    import meshio

    points = np.asarray(points, dtype=float)
    triangles = np.asarray(triangles)
    if points.ndim != 2 or points.shape[1] != 3 or triangles.ndim != 2 or triangles.shape[1] != 3:
        raise MeshError(f"points must be (v, 3) and triangles (t, 3), got {points.shape} and {triangles.shape}")
    if triangles.size and (triangles.min() < 0 or triangles.max() >= len(points)):
        raise MeshError(f"triangle indices must lie in 0..{len(points) - 1}")
    out = meshio.Mesh(points, [("triangle", triangles.astype(np.int64))])
    try:
        _call_meshio(meshio.write, os.fspath(path), out)
    except Exception as exc:
        raise MeshError(f"meshio cannot write {os.fspath(path)!r}: {exc}") from exc
