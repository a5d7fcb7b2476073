"""Deformable scene objects: a linear-elastic FEM body placed in the world.

The fem body is meshed in its own frame (``body``); displacements computed by
``fem`` are in that frame. ``soft_box`` builds the common case: a box resting on
the floor, its base fixed, its top face a deformable contact surface.
``soft_blocks`` builds one solid from several boxes side by side (a soft step, a
seat and its back), every block's top face a contact surface of the same body, so
prints on different blocks deform each other.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from .errors import SceneError
from .geometry import (
    CollisionShape,
    pose_from_center_yaw,
    readonly_array,
    transform_from_rotation_translation,
    validate_rigid_transform,
)
from .objects import DEFAULT_FRICTION
from .surfaces import ContactSurface, rectangle

__all__ = [
    "DeformableObject",
    "soft_box",
    "soft_blocks",
    "RESOLUTIONS",
    "soft_box_coordinates",
    "grid_coordinates",
    "RefineLines",
    "DEFAULT_STRAIN_LIMIT",
    "GRAVITY",
    "DEFAULT_STRAIN_RADIUS",
    "MAX_SOFT_BOX_NODES",
]

DEFAULT_STRAIN_LIMIT = 0.05
"""Largest principal strain (dimensionless) a soft object may take: linear elasticity
(small strain) is trusted up to a few percent."""

GRAVITY = readonly_array([0.0, 0.0, -9.81], (3,), "GRAVITY")
"""Acceleration of gravity in the world frame, m/s^2 (pinocchio's default, the robot's)."""

DEFAULT_STRAIN_RADIUS = 0.02
"""Radius (metres) of the ball over which a soft object's strain is averaged before
its bound is applied (:class:`fem.strain_average.BallAverages`). A tet's own strain
under a rigid print's edge grows without bound as the mesh is refined (a palm on the
foam mat: 0.117 on the default mesh, 0.163 refined twice, 0.215 four times), so a bound
on it would make the answer depend on the mesh; the mean over a 2 cm ball (about a
default cell) gives 0.072, 0.069 and 0.072."""

DEFAULT_MINIMUM_PRINT_CELLS = 4.0
"""Fewest surface cells of a soft object's mesh a flat print must cover (the sum of its
nodes' covered shares: its area over their cells' area) for its force to be trusted. On
hand-on-cube's cube a palm moved from the refined region toward the far corner, its cells
growing to 9 cm, lay within 2.6 % of the same palm's force on the default resolution
everywhere while it covered 4.0 cells or more (15 in the region), -2.8 to -3.8 % at 2.7-3.5
cells and -8 to -33 % at 2.2 or fewer (measured in session u with prints covering shape
functions; with median-dual cells before: within 4.8 % from 3.9 cells, -3.8 to -6.6 % at
3.0-3.4, -5.5 to -36 % at 2.2 or fewer). Every built-in robot's
print covers more at the default resolution (iCub's palm 6.6 cells, Talos' 13.8, soles
9.6-54); a mesh meant to be coarse (the paper's) sets its own, 0 to accept any print."""

RESOLUTIONS = {"coarse": 0.05, "default": 0.0225}
"""Fine node spacing h of a soft box's mesh where prints land, metres.

The whole mesh scales with h (see :func:`soft_box_coordinates`): halving it halves
every cell, in plane and in depth. ``default`` is chosen so that a Talos palm print
(0.10 m x 0.07 m) placed anywhere, at any angle, on the refined region covers at
least 9 surface nodes (a grid of spacing h, sampled over offsets and angles, leaves
at least 10 under such a rectangle for h <= 0.0227 m); a sole (0.21 m x 0.13 m)
covers 45-60 (54 at the median placement). At this spacing the force of a print made of the nodes inside it is
still 6-15 % above that of the mesh refined twice, and 11-49 % above the extrapolated
converged value (``bench/results/mesh_convergence.md``): linear tets resolve the edge
of a rigid print slowly. Those figures are for a print whose edges lie on node rows,
the worst placement; the covered print the posture solver uses changes by at most
2.6 % from the default mesh to the refined one, wherever it lies (2.4 % with median-dual
cells, before 2026-12-06).
``coarse`` is for fast tests: a sole print still covers several nodes, a palm
print may cover fewer than 9.
"""

# Cells are at most h on the refined region and in the top layer, and grow away from
# them geometrically by _growth_ratio(h) per cell up to _COARSE_FACTOR h. The ratio is
# exp(h / _GRADING_LENGTH): a length in metres rather than a fixed ratio per cell, so
# that halving h takes the square root of the ratio and every cell, in the graded zone
# as elsewhere, is about halved (what a convergence study needs). 6 cm, a bit more
# than half a palm, because the stress under a print decays over about a print width;
# it gives 1.45 per cell at the default h. _MAX_GROWTH keeps coarse spacings (for
# fast tests) from jumping in size. The cap bounds the aspect ratio of every cell by
# about _COARSE_FACTOR: h x h x 4h at the bottom of the refined column, 4h x 4h x h on
# the top face outside it.
_GRADING_LENGTH = 0.06
_MAX_GROWTH = 1.5
_COARSE_FACTOR = 4.0

MAX_SOFT_BOX_NODES = 1_000_000
"""Most nodes a soft box's mesh may have. The default spacing gives 31 740 nodes on a
1 m cube and h / 4 about 1.8 million; past a million the stiffness factorisation and
the compliance columns need tens of gigabytes, so a smaller ``resolution`` is taken
for a mistake and refused, with the smallest spacing that fits, before any array is
allocated."""
# Metres: a soft body taller than this that its own weight strains past its bound is
# asked whether its sizes were typed in metres (millimetres make it hundreds of metres tall).
_TALL = 10.0


def _fem():
    """Import fem lazily: scenes with only rigid objects must not need it."""
    try:
        import fem
    except ImportError as error:  # pragma: no cover - fem is part of the project
        raise SceneError(f"deformable objects need the fem package: {error}") from None
    missing = [name for name in ("tensor_mesh", "LinearElasticMaterial", "DeformableBody") if not hasattr(fem, name)]
    if missing:
        raise SceneError(f"deformable objects need fem.{', fem.'.join(missing)}, which fem does not provide")
    return fem


@dataclass(frozen=True, eq=False)
class DeformableObject:
    """A linear-elastic body in the scene.

    Parameters
    ----------
    name : str
        Unique object name in the scene.
    body : fem.DeformableBody
        The FEM body, meshed in the body frame (metres), with its fixed nodes.
    transform_body_to_world : (4, 4) float
        Rigid placement of the body frame.
    fixed_description : str
        Human-readable description of the fixed set F, e.g. ``"base on the floor"``.
    strain_limit : float
        Largest principal strain a stance may give this body (dimensionless,
        default 5 %): beyond it linear elasticity is not a valid model.
    strain_radius : float
        Metres: the strain bound applies to the strain averaged over a ball of
        this radius around each tet (default :data:`DEFAULT_STRAIN_RADIUS`); 0
        bounds each tet's own strain, which depends on the mesh at a print's edge.
    collision_mesh : ((n, 3) float, (t, 3) int), optional
        Vertices (metres, body frame) and triangles of the body's shape at rest
        as other bodies keep clear of it, when coarser than its mesh's boundary
        (a ``soft_blocks`` object: its blocks' faces; every outside point is as
        far from them as from the boundary). Default: the boundary triangles of
        the mesh (thousands on a fine mesh: a robot hull's distance to the 7,048
        of the foam step of ``foot-and-hand-on-foam`` took 425 us, to its 24
        block triangles a few).
    minimum_print_cells : float
        Fewest surface cells a flat print on it must cover (default
        :data:`DEFAULT_MINIMUM_PRINT_CELLS`); with the consistent reaction model (the
        default) a stance with a print on fewer is refused as a mesh too coarse for it.
        0 accepts any print (a scenario's soft object's ``minimum_print_cells``).
    """

    name: str
    body: Any
    transform_body_to_world: np.ndarray
    fixed_description: str = ""
    strain_limit: float = DEFAULT_STRAIN_LIMIT
    strain_radius: float = DEFAULT_STRAIN_RADIUS
    collision_mesh: tuple | None = None
    minimum_print_cells: float = DEFAULT_MINIMUM_PRINT_CELLS

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise SceneError(f"DeformableObject.name must be a non-empty string, got {self.name!r}")
        if not hasattr(self.body, "mesh"):
            raise SceneError(f"object {self.name!r}: body must be a fem.DeformableBody (with a .mesh)")
        object.__setattr__(
            self,
            "transform_body_to_world",
            validate_rigid_transform(self.transform_body_to_world, f"object {self.name!r} transform"),
        )
        if not (isinstance(self.strain_limit, (int, float)) and 0.0 < self.strain_limit < 1.0):
            raise SceneError(
                f"object {self.name!r}: strain_limit must be a fraction in (0, 1) (e.g. 0.05 for 5 %), "
                f"got {self.strain_limit!r}"
            )
        for field, meaning in (("strain_radius", ">= 0 metres (0: each tet's own strain)"),
                               ("minimum_print_cells", "a number of mesh cells >= 0 (0: any print)")):
            value = getattr(self, field)
            if isinstance(value, bool) or not (isinstance(value, (int, float, np.floating)) and 0.0 <= value < np.inf):
                raise SceneError(f"object {self.name!r}: {field} must be {meaning}, got {value!r}")
            object.__setattr__(self, field, float(value))
        if self.collision_mesh is not None:
            try:
                vertices, triangles = self.collision_mesh
                vertices = np.array(vertices, dtype=float)
                triangles = np.array(triangles, dtype=np.int64)
            except (TypeError, ValueError):
                raise SceneError(f"object {self.name!r}: collision_mesh must be (vertices, triangles)") from None
            if (vertices.ndim != 2 or vertices.shape[1] != 3 or not np.all(np.isfinite(vertices))
                    or triangles.ndim != 2 or triangles.shape[1] != 3 or len(triangles) == 0
                    or triangles.min() < 0 or triangles.max() >= len(vertices)):
                raise SceneError(
                    f"object {self.name!r}: collision_mesh must be finite (n, 3) vertices and (t, 3) triangles "
                    f"indexing them, got shapes {vertices.shape} and {triangles.shape}"
                )
            vertices.setflags(write=False)
            triangles.setflags(write=False)
            object.__setattr__(self, "collision_mesh", (vertices, triangles))

    @property
    def deformable(self) -> bool:
        """True: a deformable object."""
        return True

    @property
    def mesh(self):
        """The fem ``TetMesh``, body frame."""
        return self.body.mesh

    def points_in_world(self, points_in_body) -> np.ndarray:
        """Map points from the body frame to the world, ``(n, 3)`` metres."""
        points = np.asarray(points_in_body, dtype=float)
        transform = self.transform_body_to_world
        return points @ transform[:3, :3].T + transform[:3, 3]

    @cached_property
    def self_weight_field(self) -> np.ndarray:
        """The displacement its own weight gives the body, ``(N, 3)`` metres, body frame
        (:meth:`fem.DeformableBody.self_weight_displacement`; 0 for a density of 0).

        The scene's geometry is the body as it rests under its weight, as a robot
        sees it: by superposition the weight changes no print force (the paper's
        eq. 31), but the body already holds its strain, which a stance's strain
        bound counts.

        Raises
        ------
        SceneError
            If its weight alone strains the body beyond its strain bound: linear
            elasticity cannot describe it even at rest.
        """
        field = self.body.self_weight_displacement(self.transform_body_to_world[:3, :3].T @ GRAVITY)
        field.setflags(write=False)
        if field.any():
            strain, tet = self.body.largest_principal_strain(field, self.strain_radius)
            if strain > self.strain_limit:
                centre = self.points_in_world(self.mesh.nodes[self.mesh.tets[tet]].mean(axis=0)[None])[0]
                # A fixed base is clamped: at its edges the strain is singular and grows as
                # the mesh is refined, which the user should know when it decides.
                at_base = bool(self.body.fixed_mask[self.mesh.tets[tet]].any())
                # A size typed in millimetres makes a body hundreds of metres tall, which its
                # weight then strains (rho g h / E): its height is named where it is that tall.
                height = float(np.ptp(self.points_in_world(self.mesh.nodes)[:, 2]))
                units = f" (it stands {height:.3g} m tall: are its sizes in metres?)" if height > _TALL else ""
                raise SceneError(
                    f"object {self.name!r}: its own weight strains it {strain:.3g} at ({centre[0]:.3f}, "
                    f"{centre[1]:.3f}, {centre[2]:.3f}) m{' (a tet on its fixed base, clamped there)' if at_base else ''}, "
                    f"beyond its strain bound {self.strain_limit:g}: linear elasticity cannot describe it even at "
                    f"rest; raise its Young's modulus E, lower its density rho or raise its strain_limit{units}"
                )
        return field

    @cached_property
    def largest_strain_at_rest(self) -> float:
        """The largest principal strain its own weight gives it (the ball means of
        :attr:`strain_radius`; 0 for a density of 0)."""
        field = self.self_weight_field
        return float(self.body.largest_principal_strain(field, self.strain_radius)[0]) if field.any() else 0.0

    def strained_at_rest(self, threshold: float) -> np.ndarray:
        """(n,) sorted ids of the tets whose strain under the body's own weight, the ball
        mean of :attr:`strain_radius`, has a principal magnitude of ``threshold`` or more
        (:meth:`fem.strain_average.BallAverages.centres_above`); kept per threshold."""
        known = self.__dict__.setdefault("_strained_at_rest", {})
        key = float(threshold)
        if key not in known:
            field = self.self_weight_field
            tets = np.zeros(0, dtype=np.int64)
            if field.any():
                tets = self.body.strain_averages.centres_above(self.body.strain(field), self.strain_radius, key)
            tets.setflags(write=False)
            known[key] = tets
        return known[key]

    def rest_surface(self) -> np.ndarray:
        """Boundary triangles at rest, ``(T, 3, 3)`` metres, world frame."""
        return self.deformed_surface(np.zeros_like(self.mesh.nodes))

    def deformed_collision_object(self, displacements) -> CollisionShape:
        """The deformed boundary as a triangle mesh, world frame, for clearance checks.

        Parameters
        ----------
        displacements : (N, 3) float
            Nodal displacements, metres, body frame.

        Returns
        -------
        environments.geometry.CollisionShape
            A mesh whose vertices are in the world frame (identity placement).
        """
        triangles = self.deformed_surface(displacements)  # validates the shape
        vertices = triangles.reshape(-1, 3)
        return CollisionShape(np.eye(4), vertices=vertices, triangles=np.arange(len(vertices)).reshape(-1, 3))

    def deformed_surface(self, displacements) -> np.ndarray:
        """Boundary triangles of the deformed body, for pictures.

        Parameters
        ----------
        displacements : (N, 3) float
            Nodal displacements, metres, body frame (as ``fem`` computes them).

        Returns
        -------
        (T, 3, 3) float
            Vertices of each surface triangle, metres, world frame.

        Raises
        ------
        SceneError
            If the displacement array does not match the mesh.
        """
        nodes = np.asarray(self.mesh.nodes, dtype=float)
        displacements = np.asarray(displacements, dtype=float)
        if displacements.shape != nodes.shape:
            raise SceneError(
                f"object {self.name!r}: displacements must have shape {nodes.shape}, got {displacements.shape}"
            )
        moved = self.points_in_world(nodes + displacements)
        return moved[np.asarray(self.mesh.surface_triangles)]

    def write_vtu(self, path, displacements) -> None:
        """Write the body for ParaView in the world frame, at rest, with its displacement field.

        Parameters
        ----------
        path : str or os.PathLike
            Output ``.vtu`` file.
        displacements : (N, 3) float
            Nodal displacements, metres, body frame (as ``fem`` computes them).

        Notes
        -----
        Points are the rest positions in the world frame and the point field
        ``displacement`` is rotated into the world frame, so that ParaView's
        Warp By Vector shows the deformed body where the robot stands; stress and
        strain (cell fields, Voigt order) are in the world frame too.
        """
        self.body.write_vtu(path, displacements, transform_body_to_output=self.transform_body_to_world)


def _growth_ratio(fine: float) -> float:
    """Size ratio of successive cells away from the refined region, for the fine spacing h."""
    return min(_MAX_GROWTH, math.exp(fine / _GRADING_LENGTH))


def _graded_side(length: float, fine: float) -> np.ndarray:
    """Node offsets over ``length`` away from a refined edge, cells growing geometrically.

    Parameters
    ----------
    length : float
        Metres from the refined edge to the end of the axis, >= 0.
    fine : float
        Fine spacing h, metres.

    Returns
    -------
    (k,) float
        Increasing offsets from the edge, metres, the last exactly ``length``; empty
        when ``length`` is 0. The cells follow the series h, h g, h g^2, ... capped at
        ``_COARSE_FACTOR`` h (g from :func:`_growth_ratio`), resampled to a whole
        number of cells: cell k spans the series from fractional index (k - 1) c
        to k c, with c <= 1, so no cell is longer than h at the edge, than the cap
        anywhere, or than g times the cell before it.
    """
    if length <= 1e-12:
        return np.zeros(0)
    growth = _growth_ratio(fine)
    graded = fine * growth ** np.arange(math.ceil(math.log(_COARSE_FACTOR) / math.log(growth)))
    graded = np.minimum(graded, _COARSE_FACTOR * fine)
    capped = max(0, math.ceil((length - graded.sum()) / (_COARSE_FACTOR * fine))) + 1
    series = np.concatenate([[0.0], np.cumsum(np.concatenate([graded, np.full(capped, _COARSE_FACTOR * fine)]))])
    # Fractional number of series cells spanning length, rounded up to whole cells.
    cells = float(np.interp(length, series, np.arange(series.size)))
    count = max(1, math.ceil(cells - 1e-9))
    offsets = np.interp(np.arange(1, count + 1) * (cells / count), np.arange(series.size), series)
    offsets[-1] = length
    return offsets


def _axis_coordinates(low: float, high: float, refine_low: float, refine_high: float, fine: float) -> np.ndarray:
    """Coordinates on [low, high], spacing <= fine on [refine_low, refine_high], graded outside."""
    refine_low, refine_high = max(low, refine_low), min(high, refine_high)
    cells = max(1, math.ceil((refine_high - refine_low) / fine - 1e-9))
    middle = np.linspace(refine_low, refine_high, cells + 1)
    below = refine_low - _graded_side(refine_low - low, fine)
    above = refine_high + _graded_side(high - refine_high, fine)
    coordinates = np.concatenate([below[::-1], middle, above])
    coordinates[0], coordinates[-1] = low, high
    return coordinates


def _height_coordinates(height: float, fine: float) -> np.ndarray:
    """Coordinates on [0, height], the top cell about ``fine`` thick, cells growing downward."""
    depths = _graded_side(height, fine)  # from the top face down
    return np.concatenate([height - depths[::-1], [height]])


def _graded_cell_estimate(length: float, fine: float) -> float:
    """About how many cells :func:`_graded_side` puts on ``length`` metres (no arrays).

    The series h g^k (capped at ``_COARSE_FACTOR`` h) is summed in closed form, so
    the estimate costs nothing even for a spacing that would need billions of cells.
    """
    if length <= 1e-12:
        return 0.0
    # log of _growth_ratio(fine), without exp: exp(h / 0.06) rounds to 1 for tiny h.
    log_growth = min(fine / _GRADING_LENGTH, math.log(_MAX_GROWTH))
    graded_terms = math.log(_COARSE_FACTOR) / log_growth  # cells until the cap
    graded_length = fine * (_COARSE_FACTOR - 1.0) / math.expm1(log_growth)
    if length <= graded_length:
        return math.log1p(length * math.expm1(log_growth) / fine) / log_growth
    return graded_terms + (length - graded_length) / (_COARSE_FACTOR * fine)


def _node_count_estimate(size: np.ndarray, region: np.ndarray, fine: float) -> float:
    """About how many nodes :func:`soft_box_coordinates` gives (within a few per axis)."""
    # Python floats: their overflow to inf is silent, numpy's warns.
    half = [0.5 * float(size[0]), 0.5 * float(size[1])]
    count = 1.0
    for axis in range(2):
        low, high = max(-half[axis], float(region[0, axis])), min(half[axis], float(region[1, axis]))
        cells = _ceil((high - low) / fine - 1e-9)
        cells += _graded_cell_estimate(low + half[axis], fine) + _graded_cell_estimate(half[axis] - high, fine)
        count *= _ceil(cells) + 1
    return count * (_ceil(_graded_cell_estimate(float(size[2]), fine)) + 1)


def _ceil(value: float) -> float:
    # A spacing of 1e-300 m gives infinitely many cells: keep inf, not an exception.
    return float(math.ceil(value)) if math.isfinite(value) else value


def _check_soft_box_size(size: np.ndarray, region: np.ndarray, fine: float, resolution) -> None:
    """Refuse a spacing whose mesh would exceed :data:`MAX_SOFT_BOX_NODES`, naming one that fits."""
    estimate = _node_count_estimate(size, region, fine)
    if estimate <= MAX_SOFT_BOX_NODES:
        return
    # The node count falls as the spacing grows: bisect (in log scale) for the
    # smallest spacing that fits, on the closed-form estimate only.
    low, high = fine, max(float(size.max()), fine)
    for _ in range(60):
        middle = math.sqrt(low * high)
        if _node_count_estimate(size, region, middle) > MAX_SOFT_BOX_NODES:
            low = middle
        else:
            high = middle
    shown = f"{resolution!r} ({fine:g} m)" if isinstance(resolution, str) else f"{fine:g} m"
    raise SceneError(
        f"resolution {shown} would mesh this {'x'.join(f'{v:g}' for v in size)} m soft box with "
        f"{f'about {estimate:.3g}' if math.isfinite(estimate) else 'countless'} nodes, more than the limit of {MAX_SOFT_BOX_NODES} "
        f"(environments.deformable.MAX_SOFT_BOX_NODES); use a resolution of at least {_round_up(high)} m, "
        "or refine a smaller region"
    )


def _round_up(value: float) -> str:
    """``value`` rounded up to 3 significant digits, as text (the bound must still fit)."""
    scale = 10.0 ** (math.floor(math.log10(value)) - 2)
    return f"{math.ceil(value / scale - 1e-9) * scale:.3g}"


def _fine_spacing(resolution) -> float:
    """The fine spacing h, metres, of a preset name or a number (see :data:`RESOLUTIONS`)."""
    if isinstance(resolution, str):
        if resolution not in RESOLUTIONS:
            raise SceneError(f"unknown resolution {resolution!r}; valid: {', '.join(RESOLUTIONS)} or a spacing in metres")
        return RESOLUTIONS[resolution]
    try:
        fine = float(resolution)
    except (TypeError, ValueError):
        fine = math.nan
    if not (math.isfinite(fine) and fine > 0.0):
        raise SceneError(f"resolution must be one of {', '.join(RESOLUTIONS)} or a spacing > 0 in metres, got {resolution!r}")
    return fine


@dataclass(frozen=True)
class RefineLines:
    """Bands of finer cells along lines of a soft box's top face, where point feet land.

    A ball foot presses a contact of radius ``sqrt(r d)`` (5-9 mm for ANYmal's 31 mm
    foot 0.7-2.5 mm deep), smaller than the cells a whole region can afford. Its
    force converges only on cells of a few millimetres, which a planner needs only
    at its print origins: a grid of lines. Each line gets cells of ``resolution``
    within ``half_width`` of it (rounded up to whole cells), cells growing by 1.5 away
    from the band to the box's own, and the top layer is ``resolution`` thick with
    layers growing by 1.5 below it (over the whole box: a tensor mesh's layer spans it).
    On quadruped-foam's foam, 5 mm bands 15 mm either side of the print lines (34,584
    nodes against 14,790) put a ball's force 0.7-2.5 mm deep within 0 to +12 % of an
    independent converged FEM, where the 10 mm mesh is -11 % to +37 % off (README, Robots).
    Bands converge to themselves, not to the continuum (the layers under them grow by 1.5):
    on a 5 cm block 2.5 mm bands stay +4.9 to +8.6 % over its force with 16-74 nodes pressed
    (``bench/results/ball_node_contact.md``), so a ball they hold is judged against a
    continuum estimate, and refused where there is none (``stances.deformable``).

    Parameters
    ----------
    x, y : sequence of float
        Lines ``x = c`` and ``y = c`` of the top face, metres, top-surface frame
        (origin at the top-face centre); at least one line in all.
    half_width : float
        Metres either side of a line meshed at ``resolution``.
    resolution : float
        Cell size along the bands and the top layer's thickness, metres, finer
        than the box's resolution.

    Raises
    ------
    SceneError
        On a value that is not a list of finite numbers or a positive length, no
        line at all, or bands narrower than a cell.
    """

    x: tuple = ()
    y: tuple = ()
    half_width: float = 0.015
    resolution: float = 0.005

    def __post_init__(self) -> None:
        for axis in ("x", "y"):
            values = getattr(self, axis)
            if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
                raise SceneError(f"refine_lines {axis} must be a list of coordinates in metres, got {values!r}")
            if not all(isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v) for v in values):
                raise SceneError(f"refine_lines {axis} must be finite coordinates in metres, got {list(values)!r}")
            object.__setattr__(self, axis, tuple(float(v) for v in values))
        if not (self.x or self.y):
            raise SceneError("refine_lines needs at least one line: give x, y or both (metres, top-surface frame)")
        for name in ("half_width", "resolution"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (math.isfinite(value) and value > 0.0):
                raise SceneError(f"refine_lines {name} must be a length > 0 in metres, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.half_width < self.resolution:
            raise SceneError(
                f"refine_lines half_width ({self.half_width:g} m) must be at least its resolution "
                f"({self.resolution:g} m): a band narrower than a cell refines nothing"
            )

    def check(self, size, fine: float) -> None:
        """Refuse lines a box of ``size`` (m) meshed at ``fine`` (m) cannot take.

        Raises
        ------
        SceneError
            A resolution not finer than ``fine``; a line off the top face, or closer to
            one of its edges than 0.6 of a cell without lying on it; or bands that alone
            make more nodes than :data:`MAX_SOFT_BOX_NODES` (before any line is made;
            :func:`soft_box_coordinates` counts the whole grid's).
        """
        if self.resolution >= fine:
            raise SceneError(
                f"refine_lines resolution ({self.resolution:g} m) must be finer than the box's resolution ({fine:g} m)"
            )
        counts = []
        for index, (axis, values) in enumerate((("x", self.x), ("y", self.y))):
            half = 0.5 * float(size[index])
            for value in values:
                edge = half - abs(value)
                if edge < -1e-12 or 1e-12 < edge < 0.6 * self.resolution:
                    raise SceneError(
                        f"refine_lines {axis} = {value:g} m must lie on the top face (|{axis}| <= {half:g} m, "
                        f"top-surface frame), on an edge or at least {0.6 * self.resolution:g} m inside it"
                    )
            # One band alone, clipped to the face, already has this many lines: a grid of
            # more than the limit is refused before any line is made.
            across = 2.0 * half / self.resolution + 1.0
            ratio = self.half_width / self.resolution
            band = across if not ratio < across else 2.0 * math.ceil(ratio - 1e-9) + 1.0
            counts.append(min(band, across) if values else 2.0)
        nodes = counts[0] * counts[1] * 2.0
        if nodes > MAX_SOFT_BOX_NODES:
            amount = f"at least {nodes:.3g}" if math.isfinite(nodes) else "far more"
            raise SceneError(
                f"refine_lines give {amount} nodes, more than the limit of {MAX_SOFT_BOX_NODES}; "
                "use fewer lines, narrower bands or a coarser resolution"
            )

    def coordinates(self, xs: np.ndarray, ys: np.ndarray, zs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A box's grid lines with the bands and the thin top layers added.

        Parameters
        ----------
        xs, ys, zs : 1-D float arrays
            The box's own grid lines, metres, body frame (base centre, z up), for
            lines that passed :meth:`check`.

        Returns
        -------
        xs, ys, zs : 1-D float arrays
            Strictly increasing, the same first and last values.
        """
        return (_banded(xs, self.x, self.half_width, self.resolution),
                _banded(ys, self.y, self.half_width, self.resolution),
                _graded_top(zs, self.resolution))


#: Thickness ratio of successive cells out of a refine line's band and of successive
#: layers under its top layer.
_LAYER_GROWTH = 1.5
#: At most this many cells grade a band out to the box's own (1.5^6 = 11: 5 mm to 57 mm).
_GRADING_CELLS = 6


def _banded(lines: np.ndarray, centres, half_width: float, fine: float) -> np.ndarray:
    """Grid ``lines`` with lines every ``fine`` within ``half_width`` (whole cells) of each
    centre, then cells growing by :data:`_LAYER_GROWTH` to the local spacing of ``lines``.

    Where bands meet, a line closer than ``0.6 fine`` to the one before it goes; a line
    of ``lines`` goes when it is closer to an added line than 0.6 of the added cells
    there (no sliver cells). The ends stay exactly as they were.
    """
    if not centres:
        return lines
    low, high = float(lines[0]), float(lines[-1])
    cells = np.diff(lines)

    def spacing(v: float) -> float:  # the box's own cell at v
        return float(cells[min(max(int(np.searchsorted(lines, v)) - 1, 0), cells.size - 1)])

    steps = math.ceil(half_width / fine - 1e-9)
    candidates = []
    for centre in centres:
        # The band's cells within the box only: a band wider than the box makes no more lines.
        first = max(-steps, math.ceil((low - centre) / fine))
        last = min(steps, math.floor((high - centre) / fine))
        candidates.extend(centre + fine * np.arange(first, last + 1))
        for side in (-1.0, 1.0):
            edge, step = centre + side * steps * fine, fine * _LAYER_GROWTH
            for _ in range(_GRADING_CELLS):
                edge += side * step
                if not low < edge < high or step >= 0.8 * spacing(edge):
                    break
                candidates.append(edge)
                step *= _LAYER_GROWTH
    added = []
    for v in np.unique(np.round(candidates, 12)):
        if low + 0.6 * fine < v < high - 0.6 * fine and (not added or v - added[-1] > 0.6 * fine):
            added.append(float(v))
    added = np.array(added)
    gaps = np.diff(added)
    own = []
    for v in lines[1:-1]:
        i = int(np.argmin(np.abs(added - v)))
        # The added cell on the far side of the nearest added line: the last step of
        # its band's grading when v lies beyond it.
        if v > added[i]:
            step = gaps[i - 1] if i > 0 else fine
        else:
            step = gaps[i] if i < gaps.size else fine
        if abs(added[i] - v) > 0.6 * min(step, spacing(v)):
            own.append(v)
    merged = np.unique(np.concatenate([[low, high], added, own]))
    merged[0], merged[-1] = low, high
    return merged


def _graded_top(zs: np.ndarray, fine: float) -> np.ndarray:
    """Heights ``zs`` with layers from ``fine`` at the top, each :data:`_LAYER_GROWTH`
    times thicker, until they are as thick as the box's own layers there; the box's
    heights within them, or closer below them than 0.6 of the last, go."""
    top = float(zs[-1])
    depths = top - zs[::-1]  # 0 at the top, increasing
    graded, layer = [0.0], fine
    while True:
        j = int(np.searchsorted(depths, graded[-1], side="right"))  # in the box's layer j - 1 .. j
        if j >= depths.size or layer >= depths[j] - depths[j - 1] or graded[-1] + layer >= depths[-1]:
            break
        graded.append(graded[-1] + layer)
        layer *= _LAYER_GROWTH
    end = graded[-1]
    last = end - graded[-2] if len(graded) > 1 else fine
    merged = np.union1d(graded, depths[depths > end + 0.6 * last])
    out = np.sort(top - merged)
    out[0], out[-1] = zs[0], top
    return out


def soft_box_coordinates(size, resolution="default", refine=None, refine_lines=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid coordinates of a soft box's tensor mesh, body frame (base centre, z up).

    Cells are at most h on the refined region of the top face and the top layer is
    at most h thick; away from both, cells grow geometrically (by ``exp(h / 0.06 m)``
    per cell, 1.45 at the default h, at most 1.5) up to 4 h. So no cell is more than
    about 4 times longer in one direction than in another, and halving h about
    halves every cell, in plane and in depth (a convergence study's refinement).

    Parameters
    ----------
    size : (3,) float
        Side lengths, metres.
    resolution : {"coarse", "default"} or float
        Fine node spacing h, metres, or a named preset (see :data:`RESOLUTIONS`).
    refine : (2, 2) float, optional
        ``[[x_min, y_min], [x_max, y_max]]`` of the top-face region where prints
        land, metres, top-surface frame (origin at the top-face centre). Default:
        the whole top face. Its edges are grid lines.
    refine_lines : RefineLines, optional
        Bands of finer cells along lines of the top face (where point feet land)
        and a top layer as thin.

    Returns
    -------
    xs, ys, zs : 1-D float arrays
        Strictly increasing coordinates, metres; ``zs`` from 0 (the base) to the
        height.

    Raises
    ------
    SceneError
        On a non-positive size or spacing, an unknown preset, a refine region
        that is empty or off the top face, or a spacing so small that the mesh
        would have more than :data:`MAX_SOFT_BOX_NODES` nodes (the message gives
        the smallest spacing that fits).

    Examples
    --------
    >>> xs, ys, zs = soft_box_coordinates((1.0, 1.0, 1.0), "default")
    >>> xs.size, ys.size, zs.size                     # 45 cells of 22 mm in plane
    (46, 46, 15)
    >>> round(float(zs[-1] - zs[-2]), 4), round(float(zs[1] - zs[0]), 4)   # top, bottom
    (0.0212, 0.0848)
    >>> [c.size for c in soft_box_coordinates((1.0, 1.0, 1.0), 0.01125)]  # h / 2
    [90, 90, 28]
    """
    size = readonly_array(size, (3,), "soft box size")
    if np.any(size <= 0.0):
        raise SceneError(f"soft box size must be > 0 on every axis, got {size.tolist()}")
    fine = _fine_spacing(resolution)
    half = 0.5 * size[:2]
    if refine is None:
        region = np.array([-half, half])
    else:
        region = readonly_array(refine, (2, 2), "refine")
        if np.any(region[1] <= region[0]):
            raise SceneError(f"refine must be [[x_min, y_min], [x_max, y_max]] with min < max, got {region.tolist()}")
        if np.any(region[1] <= -half) or np.any(region[0] >= half):
            raise SceneError(f"refine region {region.tolist()} does not overlap the top face {(-half).tolist()}..{half.tolist()}")
    _check_soft_box_size(size, region, fine, resolution)
    xs = _axis_coordinates(-half[0], half[0], region[0, 0], region[1, 0], fine)
    ys = _axis_coordinates(-half[1], half[1], region[0, 1], region[1, 1], fine)
    zs = _height_coordinates(float(size[2]), fine)
    if refine_lines is not None:
        refine_lines.check(size, fine)
        xs, ys, zs = refine_lines.coordinates(xs, ys, zs)
        nodes = xs.size * ys.size * zs.size
        if nodes > MAX_SOFT_BOX_NODES:
            raise SceneError(
                f"refine_lines give {nodes} nodes, more than the limit of {MAX_SOFT_BOX_NODES}; "
                "use fewer lines, narrower bands or a coarser resolution"
            )
    return xs, ys, zs


def grid_coordinates(size, grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A soft box's tensor-mesh coordinates given by hand, checked against its size.

    For a mesh a user (or a paper) chose: e.g. the paper's coarse 1 m cube, with
    grid lines where the palm's edges land so that its print holds mesh nodes.

    Parameters
    ----------
    size : (3,) float
        Side lengths, metres.
    grid : (3,) sequence of 1-D float sequences
        ``[xs, ys, zs]``, metres, body frame (base centre, z up): strictly
        increasing, ``xs`` from ``-size[0] / 2`` to ``size[0] / 2``, ``ys`` likewise,
        ``zs`` from 0 to ``size[2]``.

    Returns
    -------
    xs, ys, zs : 1-D float arrays

    Raises
    ------
    SceneError
        Not three sequences, fewer than two values on an axis, values not strictly
        increasing or not finite, ends that do not match the box, or more than
        :data:`MAX_SOFT_BOX_NODES` nodes.

    Examples
    --------
    >>> xs, ys, zs = grid_coordinates((1, 1, 1), [[-0.5, 0, 0.5], [-0.5, 0.5], [0, 0.4, 1]])
    >>> xs.size * ys.size * zs.size
    18
    """
    size = readonly_array(size, (3,), "soft box size")
    if not isinstance(grid, (list, tuple)) or len(grid) != 3:
        raise SceneError(f"grid must be three lists of coordinates [xs, ys, zs], got {grid!r}")
    ends = [(-0.5 * size[0], 0.5 * size[0]), (-0.5 * size[1], 0.5 * size[1]), (0.0, size[2])]
    out = []
    for axis, (values, (low, high)) in enumerate(zip(grid, ends)):
        name = "xyz"[axis]
        try:
            coordinates = np.array(values, dtype=float)
        except (TypeError, ValueError):
            raise SceneError(f"grid {name}s must be a list of numbers, got {values!r}") from None
        if coordinates.ndim != 1 or coordinates.size < 2 or not np.all(np.isfinite(coordinates)):
            raise SceneError(f"grid {name}s must be a list of at least two finite numbers, got {values!r}")
        if np.any(np.diff(coordinates) <= 0.0):
            raise SceneError(f"grid {name}s must be strictly increasing, got {coordinates.tolist()}")
        tolerance = 1e-9 * max(float(size.max()), 1.0)
        if abs(coordinates[0] - low) > tolerance or abs(coordinates[-1] - high) > tolerance:
            raise SceneError(
                f"grid {name}s must run from {low:g} to {high:g} m (the box's faces, body frame: base centre, "
                f"z up), got {coordinates[0]:g} to {coordinates[-1]:g}"
            )
        coordinates[[0, -1]] = low, high
        out.append(coordinates)
    nodes = out[0].size * out[1].size * out[2].size
    if nodes > MAX_SOFT_BOX_NODES:
        raise SceneError(f"grid gives {nodes} nodes, more than the limit of {MAX_SOFT_BOX_NODES}; use fewer grid lines")
    return tuple(out)


def soft_box(
    name: str,
    size,
    center,
    material,
    resolution="default",
    refine=None,
    yaw: float = 0.0,
    friction: float = DEFAULT_FRICTION,
    strain_limit: float = DEFAULT_STRAIN_LIMIT,
    strain_radius: float = DEFAULT_STRAIN_RADIUS,
    grid=None,
    refine_lines=None,
    minimum_print_cells: float = DEFAULT_MINIMUM_PRINT_CELLS,
) -> tuple[DeformableObject, ContactSurface]:
    """A deformable box standing on the floor, base fixed, top face a contact surface.

    The body frame is at the centre of the base, with the box's axes. The tensor
    mesh is refined on the top face where prints land, in plane and in depth, and
    coarsens away from it with bounded cell aspect ratios (see
    :func:`soft_box_coordinates`). Nodes of the base (z = 0 in the body
    frame) are fixed. The top surface is named ``<name>_top``; its frame is at the
    top-face centre, z up.

    Parameters
    ----------
    name : str
        Object name.
    size : (3,) float
        Side lengths, metres.
    center : (3,) float
        Centre of the box, metres, world frame.
    material : fem.LinearElasticMaterial
        The material.
    resolution : {"coarse", "default"} or float
        Mesh spacing preset or fine spacing h in metres; the whole mesh scales
        with it.
    refine : (2, 2) float, optional
        Region of the top face to refine, metres, top-surface frame.
    yaw : float
        Rotation about world z, radians.
    friction : float
        Friction coefficient of the top surface.
    strain_limit : float
        Largest principal strain allowed in a stance (see :class:`DeformableObject`).
    strain_radius : float
        Metres over which the strain is averaged before its bound applies (see
        :class:`DeformableObject`).
    grid : (3,) sequence of 1-D float sequences, optional
        The mesh's grid lines given by hand (see :func:`grid_coordinates`), in
        place of ``resolution`` and ``refine``.
    refine_lines : RefineLines, optional
        Bands of finer cells along lines of the top face, where point feet land.
    minimum_print_cells : float
        Fewest surface cells a flat print must cover (:data:`DEFAULT_MINIMUM_PRINT_CELLS`;
        0 for a mesh meant to be coarse).

    Returns
    -------
    (DeformableObject, ContactSurface)
        The object and its top surface.

    Raises
    ------
    SceneError
        On bad sizes or options, or when fem is not available.
    """
    fem = _fem()
    size = readonly_array(size, (3,), f"object {name!r} size")
    if grid is None:
        xs, ys, zs = soft_box_coordinates(size, resolution, refine, refine_lines)
    elif refine is not None or refine_lines is not None:
        which = "refine" if refine is not None else "refine_lines"
        raise SceneError(f"object {name!r}: give either grid or {which}, not both (grid fixes every grid line)")
    else:
        xs, ys, zs = grid_coordinates(size, grid)
    mesh = fem.tensor_mesh(xs, ys, zs)
    fixed_nodes = np.flatnonzero(np.asarray(mesh.nodes)[:, 2] <= 1e-9 * float(size[2]))
    body = fem.DeformableBody(mesh, material, fixed_nodes)
    center = readonly_array(center, (3,), f"object {name!r} center")
    transform_body_to_world = pose_from_center_yaw(center - [0.0, 0.0, 0.5 * size[2]], yaw)
    obj = DeformableObject(
        name, body, transform_body_to_world, "base (z = 0 in the body frame) fixed", float(strain_limit),
        strain_radius, minimum_print_cells=minimum_print_cells,
    )
    transform_top_to_body = transform_from_rotation_translation(np.eye(3), [0.0, 0.0, size[2]])
    top = ContactSurface(
        f"{name}_top",
        name,
        rectangle(size[0], size[1]),
        transform_body_to_world @ transform_top_to_body,
        friction,
        deformable=True,
    )
    return obj, top


def _breakpoint_coordinates(breakpoints, fine: float) -> np.ndarray:
    """Sorted coordinates through every breakpoint, evenly spaced at most ``fine`` between them."""
    points = np.unique(np.round(np.asarray(breakpoints, dtype=float), 12))
    pieces = [points[:1]]
    for low, high in zip(points[:-1], points[1:]):
        cells = max(1, math.ceil((high - low) / fine - 1e-9))
        pieces.append(np.linspace(low, high, cells + 1)[1:])
    return np.concatenate(pieces)


def _merged_heights(bottoms, tops, fine: float) -> np.ndarray:
    """Heights of the layers of blocks standing side by side, each graded from its own top.

    Every block bottom and top is a layer; the other layers of all blocks are
    merged, dropping a layer closer than ``fine / 3`` to one already kept (so no
    sliver cells where two blocks' gradings interleave).
    """
    forced = np.unique(np.round(np.concatenate([bottoms, tops]), 12))
    graded = np.concatenate([bottom + _height_coordinates(top - bottom, fine) for bottom, top in zip(bottoms, tops)])
    kept = list(forced)
    for z in np.sort(graded):
        if np.min(np.abs(np.asarray(kept) - z)) >= fine / 3.0:
            kept.append(float(z))
    return np.array(sorted(kept))


def soft_blocks(
    name: str,
    blocks,
    material,
    resolution="default",
    friction: float = DEFAULT_FRICTION,
    strain_limit: float = DEFAULT_STRAIN_LIMIT,
    strain_radius: float = DEFAULT_STRAIN_RADIUS,
    minimum_print_cells: float = DEFAULT_MINIMUM_PRINT_CELLS,
) -> tuple[DeformableObject, list]:
    """One deformable solid made of axis-aligned blocks side by side, its base fixed.

    A soft step (a low tread beside a tall ledge) or a seat with its back: a
    foot on one block and a hand on another press the same body, and each print
    moves the other (one contact system per body, see
    :class:`stances.deformable.DeformableContact`). The blocks are meshed
    together on one tensor grid through every block edge, spacing h over the
    whole footprint and each block's layers graded from its own top face
    (:func:`soft_box_coordinates` for one block); the cells inside some block
    are kept. The nodes on the lowest face (the floor) are fixed. The body
    frame is at the centre of the footprint's bounding rectangle, on the base,
    with the world's axes.

    Parameters
    ----------
    name : str
        Object name.
    blocks : sequence of (str, (3,) float, (3,) float)
        ``(block name, size, center)`` of each block, metres, world frame.
        Blocks touch along faces and do not overlap; no block stands on
        another's top face (each top face is a free contact surface).
    material : fem.LinearElasticMaterial
    resolution : {"coarse", "default"} or float
        Fine spacing h, metres, or a preset (:data:`RESOLUTIONS`).
    friction : float
        Friction coefficient of the top faces.
    strain_limit : float
        Largest principal strain allowed in a stance.
    strain_radius : float
        Metres over which the strain is averaged before its bound applies (see
        :class:`DeformableObject`).
    minimum_print_cells : float
        Fewest surface cells a flat print must cover (:data:`DEFAULT_MINIMUM_PRINT_CELLS`).

    Returns
    -------
    (DeformableObject, list of ContactSurface)
        The object and the top face of each block, named ``<name>_<block>``,
        frame at the face centre, z up.

    Raises
    ------
    SceneError
        On bad sizes, overlapping or disconnected blocks, a block on another's
        top face, a base not on one level, or a mesh beyond
        :data:`MAX_SOFT_BOX_NODES` nodes.
    """
    fem = _fem()
    if not isinstance(blocks, (list, tuple)) or not blocks:
        raise SceneError(f"object {name!r}: blocks must be a non-empty list of (name, size, center)")
    names, lows, highs = [], [], []
    for block_name, size, center in blocks:
        size = readonly_array(size, (3,), f"object {name!r} block {block_name!r} size")
        if np.any(size <= 0.0):
            raise SceneError(f"object {name!r} block {block_name!r}: size must be > 0 on every axis, got {size.tolist()}")
        center = readonly_array(center, (3,), f"object {name!r} block {block_name!r} center")
        if block_name in names:
            raise SceneError(f"object {name!r}: two blocks are named {block_name!r}; block names must be unique")
        names.append(block_name)
        lows.append(center - 0.5 * size)
        highs.append(center + 0.5 * size)
    lows, highs = np.array(lows), np.array(highs)
    base = float(lows[:, 2].min())
    tolerance = 1e-9 * float(np.max(highs - lows))
    for i in range(len(names)):
        for j in range(len(names)):
            overlap = np.minimum(highs[i], highs[j]) - np.maximum(lows[i], lows[j])
            if i < j and np.all(overlap > tolerance):
                raise SceneError(f"object {name!r}: blocks {names[i]!r} and {names[j]!r} overlap; make them touch along a face")
            if i != j and abs(lows[j, 2] - highs[i, 2]) <= tolerance and np.all(overlap[:2] > tolerance):
                raise SceneError(
                    f"object {name!r}: block {names[j]!r} stands on the top face of {names[i]!r}, which would then not "
                    "be a free contact surface; make one taller block instead, or put them side by side"
                )
    fine = _fine_spacing(resolution)
    xs = _breakpoint_coordinates(np.concatenate([lows[:, 0], highs[:, 0]]), fine)
    ys = _breakpoint_coordinates(np.concatenate([lows[:, 1], highs[:, 1]]), fine)
    zs = _merged_heights(lows[:, 2], highs[:, 2], fine)
    if xs.size * ys.size * zs.size > MAX_SOFT_BOX_NODES:
        raise SceneError(
            f"object {name!r}: resolution {fine:g} m gives a grid of {xs.size * ys.size * zs.size} nodes, more than "
            f"{MAX_SOFT_BOX_NODES} (environments.deformable.MAX_SOFT_BOX_NODES); use a coarser resolution"
        )
    centres = np.stack(np.meshgrid(0.5 * (xs[1:] + xs[:-1]), 0.5 * (ys[1:] + ys[:-1]), 0.5 * (zs[1:] + zs[:-1]),
                                   indexing="ij"), axis=-1)
    cells = np.zeros(centres.shape[:3], dtype=bool)
    for low, high in zip(lows, highs):
        cells |= np.all((centres > low) & (centres < high), axis=-1)
    origin = np.array([0.5 * (xs[0] + xs[-1]), 0.5 * (ys[0] + ys[-1]), base])
    mesh = fem.tensor_mesh(xs - origin[0], ys - origin[1], zs - base, cells=cells)
    _check_one_solid(name, mesh, names, lows - origin, highs - origin)
    fixed_nodes = np.flatnonzero(np.asarray(mesh.nodes)[:, 2] <= tolerance)
    body = fem.DeformableBody(mesh, material, fixed_nodes)
    transform_body_to_world = transform_from_rotation_translation(np.eye(3), origin)
    obj = DeformableObject(name, body, transform_body_to_world, "base (the lowest face, on the floor) fixed",
                           float(strain_limit), strain_radius, _box_faces(lows - origin, highs - origin),
                           minimum_print_cells=minimum_print_cells)
    surfaces = [
        ContactSurface(
            f"{name}_{block_name}",
            name,
            rectangle(high[0] - low[0], high[1] - low[1]),
            transform_from_rotation_translation(np.eye(3), [0.5 * (low[0] + high[0]), 0.5 * (low[1] + high[1]), high[2]]),
            friction,
            deformable=True,
        )
        for block_name, low, high in zip(names, lows, highs)
    ]
    return obj, surfaces


def _box_faces(lows, highs) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (8 per box) and outward triangles (12 per box) of axis-aligned boxes."""
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
    # Two triangles per face, counter-clockwise seen from outside (corner index = 4i + 2j + k).
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    vertices = np.concatenate([low + corners * (high - low) for low, high in zip(lows, highs)])
    triangles = np.concatenate([faces + 8 * b for b in range(len(lows))])
    return vertices, triangles


def _check_one_solid(name, mesh, names, lows, highs) -> None:
    """Refuse blocks that do not make one connected solid, naming one cut off."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    tets = np.asarray(mesh.tets)
    rows = np.repeat(tets[:, 0], 3)
    cols = tets[:, 1:].ravel()
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(mesh.n_nodes, mesh.n_nodes))
    count, labels = connected_components(graph, directed=False)
    if count == 1:
        return
    nodes = np.asarray(mesh.nodes)
    first = labels[np.argmin(np.linalg.norm(nodes - 0.5 * (lows[0] + highs[0]), axis=1))]
    for block_name, low, high in zip(names, lows, highs):
        inside = np.all((nodes >= low - 1e-12) & (nodes <= high + 1e-12), axis=1)
        if np.any(labels[inside] != first):
            raise SceneError(
                f"object {name!r}: block {block_name!r} does not touch the others along a face; the blocks of a "
                "soft_blocks object must form one solid (use separate objects for separate bodies)"
            )
