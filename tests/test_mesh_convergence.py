"""Soft-box meshes: bounded cell shapes, and a rigid print's force converging under refinement.

A rigid rectangular print is pressed 5 mm straight down (the same displacement on
every print node) into a soft box meshed by ``soft_box_coordinates`` at the spacing h
and at h / 2, h / 4, ...; the total vertical force must converge monotonically with a
positive observed order. Prints and the refined region are laid on a lattice of pitch
h (the default spacing): the refined region is uniform with a spacing that divides h,
so its grid lines at h are grid lines at h / 2 and h / 4 and every mesh's print covers
exactly the same rectangle (a print's node set would otherwise change with the mesh
and move the force by more than the discretisation error). The lattice makes the
palm 5 x 3 pitches (0.1125 m x 0.0675 m) and the sole 9 x 5 (0.2025 m x 0.1125 m).

The total force is computed by one Dirichlet solve (print and base nodes imposed);
it is the force ``ContactPatch.reaction_forces`` gives for the same print, checked
below, at the cost of one solve instead of three per print node.

The longer study (the 1 m cube, h / 4 where it fits) is bench/bench_mesh_convergence.py
with its table in bench/results/mesh_convergence.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pytest

from environments.deformable import RESOLUTIONS, soft_box_coordinates
from fem import DeformableBody, LinearElasticMaterial, nodes_in_polygon, print_coverage, tensor_mesh
from fem.ordering import nested_dissection, node_adjacency
from fem.solvers import factorize

DEFAULT = RESOLUTIONS["default"]  # the lattice pitch, metres
INDENTATION = 0.005  # metres, straight down
POISSON_RATIO = 0.4
# The target: the default mesh's print force within 5 % of the mesh refined
# twice in every direction.
TARGET = 0.05


@dataclass(frozen=True)
class PrintStudy:
    """A soft box (base fixed) and a rectangular print centred on its top, on the lattice.

    Parameters
    ----------
    body : str
        Name of the body in tables.
    size : (3,) float
        Side lengths of the box, metres.
    young_modulus : float
        Pascals.
    print_name : str
        Name of the print in tables.
    print_cells : (2,) int
        Print side lengths in lattice pitches.
    margin_cells : (2,) int
        Refined margin around the print on each side, in lattice pitches.
    """

    body: str
    size: tuple[float, float, float]
    young_modulus: float
    print_name: str
    print_cells: tuple[int, int]
    margin_cells: tuple[int, int]

    def __post_init__(self) -> None:
        region = (np.array(self.print_cells) + 2 * np.array(self.margin_cells)) * DEFAULT
        if np.any(region > np.array(self.size[:2]) + 1e-12):
            raise ValueError(f"{self.body}: print plus margins ({region.tolist()} m) exceed the top face {self.size[:2]}")

    @property
    def print_half_size(self) -> np.ndarray:
        """(2,) float, metres: half the print's sides."""
        return 0.5 * DEFAULT * np.array(self.print_cells)

    @property
    def refine(self) -> np.ndarray:
        """(2, 2) float, metres, top-surface frame: the refined region around the print."""
        half = self.print_half_size + DEFAULT * np.array(self.margin_cells)
        return np.array([-half, half])

    @property
    def polygon_in_body(self) -> np.ndarray:
        """(4, 3) float, metres, body frame: the print rectangle on the top face."""
        hx, hy = self.print_half_size
        top = self.size[2]
        return np.array([[-hx, -hy, top], [hx, -hy, top], [hx, hy, top], [-hx, hy, top]])

    def placed_polygon(self, offset: float, angle_deg: float) -> np.ndarray:
        """(4, 3) float, metres, body frame: the print moved off the lattice.

        Rotated by ``angle_deg`` about its centre, then shifted by ``offset`` pitches
        along x and half that along y, so its edges cross grid lines at places that
        change with ``offset``.
        """
        angle = math.radians(angle_deg)
        rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
        corners = self.polygon_in_body[:, :2] @ rotation.T + offset * DEFAULT * np.array([1.0, 0.5])
        return np.column_stack([corners, self.polygon_in_body[:, 2]])

    def expected_print_nodes(self, level: int) -> int:
        """Nodes of a lattice-aligned print on the mesh refined ``level`` times."""
        cx, cy = (2**level * c for c in self.print_cells)
        return (cx + 1) * (cy + 1)

    def coordinates(self, level: int, depth_level: int | None = None):
        """Grid of the box at spacing ``DEFAULT / 2**level`` (layers at ``depth_level``)."""
        xs, ys, zs = soft_box_coordinates(self.size, DEFAULT / 2**level, self.refine)
        if depth_level is not None and depth_level != level:
            zs = soft_box_coordinates(self.size, DEFAULT / 2**depth_level, self.refine)[2]
        return xs, ys, zs

    def body_at(self, level: int, depth_level: int | None = None) -> DeformableBody:
        """The FEM body meshed at ``level``, base fixed (built once per module run: the
        fixtures below press many prints into the same bodies, and a body keeps its
        factorisation)."""
        return _body(self, level, depth_level)


@lru_cache(maxsize=None)
def _body(study: PrintStudy, level: int, depth_level: int | None) -> DeformableBody:
    mesh = tensor_mesh(*study.coordinates(level, depth_level))
    material = LinearElasticMaterial(study.young_modulus, POISSON_RATIO)
    return DeformableBody(mesh, material, mesh.nodes[:, 2] <= 1e-9 * study.size[2])


CUBE_PALM = PrintStudy("1 m cube, E = 1e6 Pa", (1.0, 1.0, 1.0), 1e6, "palm", (5, 3), (4, 4))
CUBE_SOLE = PrintStudy("1 m cube, E = 1e6 Pa", (1.0, 1.0, 1.0), 1e6, "sole", (9, 5), (4, 4))
# Like cross-soft-block's foam; 1 pitch of margin across the 0.3 m side, 4 along it.
MAT_SOLE = PrintStudy("foam mat 0.3 x 1.2 x 0.1 m, E = 3e5 Pa", (0.3, 1.2, 0.1), 3e5, "sole", (9, 5), (1, 4))
MAT_PALM = PrintStudy("foam mat 0.3 x 1.2 x 0.1 m, E = 3e5 Pa", (0.3, 1.2, 0.1), 3e5, "palm", (5, 3), (3, 4))


def indentation_force(body: DeformableBody, polygon_in_body) -> tuple[float, int]:
    """Vertical force a rigid print pressed ``INDENTATION`` straight down receives.

    Parameters
    ----------
    body : DeformableBody
    polygon_in_body : (k, 3) float
        The print, metres, body frame, on the top face.

    Returns
    -------
    force : float
        Newtons, on the robot, + z (up) when pressing down.
    print_nodes : int
        Number of mesh nodes under the print.
    """
    mesh = body.mesh
    prints = nodes_in_polygon(mesh, polygon_in_body)
    imposed = body.fixed_mask.copy()
    imposed[prints] = True
    unknown_nodes = np.flatnonzero(~imposed)
    unknown = (3 * unknown_nodes[:, None] + np.arange(3)).ravel()
    print_dofs = (3 * prints[:, None] + np.arange(3)).ravel()
    u_print = np.tile([0.0, 0.0, -INDENTATION], prints.size)
    stiffness = body.stiffness.tocsr()
    # Nested dissection: several times less fill than CHOLMOD's AMD on these meshes.
    graph = node_adjacency(mesh.tets, mesh.n_nodes)[unknown_nodes][:, unknown_nodes]
    order = nested_dissection(mesh.nodes[unknown_nodes], graph)
    k_uu = stiffness[unknown][:, unknown]
    u = np.zeros(mesh.n_dofs)
    u[print_dofs] = u_print
    u[unknown] = factorize(k_uu, ordering=(3 * order[:, None] + np.arange(3)).ravel()).solve(
        -(stiffness[unknown][:, print_dofs] @ u_print)
    )
    # K u at the print is the force the robot applies on the body; the body pushes back.
    force_on_body = (stiffness[print_dofs] @ u).reshape(-1, 3)
    return float(-force_on_body[:, 2].sum()), int(prints.size)


def richardson(forces) -> tuple[float, float]:
    """Observed order and extrapolated limit of three values on meshes h, h / 2, h / 4.

    Parameters
    ----------
    forces : (3,) float
        Newtons, coarsest first.

    Returns
    -------
    order : float
        p in F(h) = F + C h^p; NaN unless the differences shrink with one sign.
    limit : float
        Newtons, the extrapolated F(0); NaN with the order.
    """
    f0, f1, f2 = forces
    ratio = (f0 - f1) / (f1 - f2) if f1 != f2 else math.nan
    if not ratio > 1.0:
        return math.nan, math.nan
    return math.log2(ratio), f2 - (f1 - f2) / (ratio - 1.0)


def richardson_two(forces, order: float) -> float:
    """Extrapolated limit of two values on meshes h, h / 2, for an assumed order p > 0."""
    f0, f1 = forces
    return f1 + (f1 - f0) / (2.0**order - 1.0)


# ------------------------------------------------------------------ mesh shape
SCENE_BOXES = {
    "hand-on-cube": ((1.0, 1.0, 1.0), None),
    "climb-with-soft-support": ((0.5, 0.5, 0.9), [[-0.25, -0.05], [0.25, 0.25]]),
    "cross-soft-block": ((0.3, 1.2, 0.1), [[-0.15, -0.35], [0.15, 0.35]]),
    "step-on-cube": ((0.3, 0.3, 0.3), None),
}


def cell_sides(xs, ys, zs) -> np.ndarray:
    """(nx - 1, ny - 1, nz - 1, 3) float, metres: the sides of every grid cell."""
    dx, dy, dz = np.meshgrid(np.diff(xs), np.diff(ys), np.diff(zs), indexing="ij")
    return np.stack([dx, dy, dz], axis=-1)


@pytest.mark.parametrize("resolution", ["coarse", "default", DEFAULT / 2], ids=["coarse", "default", "half"])
@pytest.mark.parametrize("scene", list(SCENE_BOXES))
def test_cells_under_the_refined_region_have_bounded_aspect_ratio(scene, resolution):
    size, refine = SCENE_BOXES[scene]
    xs, ys, zs = soft_box_coordinates(size, resolution, refine)
    sides = cell_sides(xs, ys, zs)
    aspect = sides.max(axis=-1) / sides.min(axis=-1)
    region = np.array(refine) if refine is not None else 0.5 * np.array([[-size[0], -size[1]], size[:2]])
    in_x = (xs[:-1] >= region[0, 0] - 1e-9) & (xs[1:] <= region[1, 0] + 1e-9)
    in_y = (ys[:-1] >= region[0, 1] - 1e-9) & (ys[1:] <= region[1, 1] + 1e-9)
    under = aspect[np.ix_(in_x, in_y)]
    # The size field caps cells at 4 h; rounding cell counts up shrinks the fine cells
    # by at most one part in the count, hence the small allowance.
    assert under.max() <= 4.5, f"cell aspect ratio {under.max():.2f} under the refined region"
    assert aspect.max() <= 5.0, f"cell aspect ratio {aspect.max():.2f} somewhere in the box"


@pytest.mark.parametrize("resolution", ["coarse", "default", DEFAULT / 2], ids=["coarse", "default", "half"])
@pytest.mark.parametrize("scene", list(SCENE_BOXES))
def test_layers_are_about_h_at_the_top_and_thicken_geometrically_downward(scene, resolution):
    size, refine = SCENE_BOXES[scene]
    h = RESOLUTIONS.get(resolution, resolution)
    _, _, zs = soft_box_coordinates(size, resolution, refine)
    layers = np.diff(zs)[::-1]  # top first
    assert zs[0] == 0.0 and zs[-1] == pytest.approx(size[2])
    assert 0.5 * h <= layers[0] <= 1.25 * h, f"top layer {layers[0]:.4f} m for h = {h} m"
    growth = layers[1:] / layers[:-1]
    assert np.all(growth >= 1.0 - 1e-9), f"layers must not thin downward: {layers}"
    assert np.all(growth <= 1.5), f"layer growth ratios {growth} exceed 1.5"
    assert layers.max() <= 4.0 * h * (1 + 1e-9)


def test_halving_the_spacing_halves_the_cells_in_every_direction():
    size, refine = (1.0, 1.0, 1.0), [[-0.2, -0.2], [0.2, 0.2]]
    coarse = soft_box_coordinates(size, DEFAULT, refine)
    fine = soft_box_coordinates(size, DEFAULT / 2, refine)
    for axis, (a, b) in enumerate(zip(coarse, fine)):
        cells_a, cells_b = a.size - 1, b.size - 1
        assert 2 * cells_a - 2 <= cells_b <= 2 * cells_a + 1, f"axis {axis}: {cells_a} then {cells_b} cells"
        # The local cell size at any point halves, within the rounding of cell counts.
        probes = np.linspace(a[0], a[-1], 41)[1:-1]
        size_a = np.diff(a)[np.searchsorted(a, probes) - 1]
        size_b = np.diff(b)[np.searchsorted(b, probes) - 1]
        ratio = size_a / size_b
        assert np.all((ratio > 1.5) & (ratio < 2.7)), f"axis {axis}: local refinement ratios {ratio.round(2)}"


# ------------------------------------------------------------------ convergence
@pytest.fixture(scope="module")
def mat_sole_forces():
    """Sole print forces on the foam mat at h, h / 2, h / 4 (levels 0, 1, 2), coarsest first."""
    results = [indentation_force(MAT_SOLE.body_at(level), MAT_SOLE.polygon_in_body) for level in (0, 1, 2)]
    for level, (_, nodes) in zip((0, 1, 2), results):
        # The print covers the same rectangle on every mesh: exactly its lattice nodes.
        assert nodes == MAT_SOLE.expected_print_nodes(level)
    return np.array([force for force, _ in results])


def test_dirichlet_force_equals_the_contact_patch_reaction():
    body = MAT_SOLE.body_at(0)
    force, _ = indentation_force(body, MAT_SOLE.polygon_in_body)
    patch = body.contact_patch(nodes_in_polygon(body.mesh, MAT_SOLE.polygon_in_body))
    reaction = patch.reaction_forces(np.tile([0.0, 0.0, -INDENTATION], (patch.n_nodes, 1)))
    assert force == pytest.approx(reaction[:, 2].sum(), rel=1e-8)


def test_print_force_decreases_monotonically_with_a_positive_observed_order(mat_sole_forces):
    # Displacement finite elements are too stiff: the force falls as the mesh refines.
    assert np.all(np.diff(mat_sole_forces) < 0), f"forces at h, h/2, h/4: {mat_sole_forces}"
    order, limit = richardson(mat_sole_forces)
    # Measured 1.31 (also on the mat's palm and, with the print as refined region, the
    # cube's palm); a rigid print's edge is singular, so below 2, but above 1/2.
    assert 0.5 < order < 3.0, f"observed order {order:.2f} from {mat_sole_forces}"
    assert 0.0 < limit < mat_sole_forces[-1]


def test_default_mesh_print_force_changes_by_under_20_percent_when_refined_twice(mat_sole_forces):
    # Measured 13.6 % here, 7-18 % for the palm and sole on the mat and the 1 m cube: a
    # guard against regressions; the 5 % target is not met (the xfail below).
    change = abs(mat_sole_forces[1] / mat_sole_forces[0] - 1.0)
    assert change < 0.20, f"force changes by {change:.1%} from h to h/2"


def test_nodes_inside_an_aligned_print_miss_the_target_by_a_row_of_nodes(mat_sole_forces):
    # The paper's print (the nodes inside the polygon, kept for the traction method): a
    # print whose edges lie on grid lines takes a whole extra row of nodes on each side,
    # its effective edge half a cell out. Measured 13.6 %. The covered print below,
    # which the consistent model uses, meets the target at every placement.
    change = abs(mat_sole_forces[1] / mat_sole_forces[0] - 1.0)
    assert change > TARGET, f"force changes by {change:.1%} from h to h/2"


# A print landing anywhere: rotated 30 degrees and shifted by 0, 1/6, ..., 5/6 of a pitch
# (along x, half that along y), so its edges cross grid lines at changing places.
PLACEMENT_OFFSETS = tuple(k / 6 for k in range(6))
PLACEMENT_ANGLE = 30.0  # degrees


@pytest.fixture(scope="module", params=[MAT_SOLE, MAT_PALM], ids=["sole", "palm"])
def placed_forces(request):
    """(2, 6) float, newtons: the placed prints' forces at h and h / 2, and the study."""
    study = request.param
    forces = []
    for level in (0, 1):
        body = study.body_at(level)
        forces.append([indentation_force(body, study.placed_polygon(o, PLACEMENT_ANGLE))[0] for o in PLACEMENT_OFFSETS])
    return study, np.array(forces)


def test_default_mesh_force_averaged_over_placements_is_within_target_of_twice_refined_mesh(placed_forces):
    # Measured +2.4 % (sole) and +0.0 % (palm). Node-in-polygon selection puts a print's
    # effective edge half a cell out when the edge lies on a node row and up to half a
    # cell in otherwise; over placements the two balance. (A selection inset by 0.25 h
    # also changes by only 2-3 % here, but lies 7.7 % below the limit: the test on the
    # limit below catches it.)
    _, forces = placed_forces
    change = forces[1].mean() / forces[0].mean() - 1.0
    assert abs(change) < TARGET, f"mean force over placements changes by {change:.1%} from h to h/2: {forces.round(1)}"


def test_placement_scatter_of_the_print_force_shrinks_with_the_cell(placed_forces):
    # A row of nodes entering or leaving the print moves its edge by about a cell: the
    # scatter over placements is O(h). Measured 4.5 % -> 1.4 % (sole), 16 % -> 3.2 % (palm).
    _, forces = placed_forces
    scatter = np.ptp(forces, axis=1) / forces.mean(axis=1)
    assert scatter[1] < scatter[0] / 1.5, f"scatter over placements at h, h/2: {scatter.round(3)}"


def test_default_mesh_sole_force_averaged_over_placements_is_within_target_of_the_limit(mat_sole_forces):
    # The limit is the Richardson extrapolation of the aligned print (h, h/2, h/4): the
    # same rectangle, whose converged force does not depend on the lattice. Measured +4.05 %.
    _, limit = richardson(mat_sole_forces)
    body = MAT_SOLE.body_at(0)
    forces = [indentation_force(body, MAT_SOLE.placed_polygon(o, PLACEMENT_ANGLE))[0] for o in PLACEMENT_OFFSETS]
    error = np.mean(forces) / limit - 1.0
    assert abs(error) < TARGET, f"mean default-mesh force {np.mean(forces):.1f} N, limit {limit:.1f} N ({error:+.1%})"


def test_refining_only_the_layers_changes_the_cube_palm_force_by_under_5_percent():
    # Measured 2.6 %. The old 3-layer mesh (cells 22 x 22 x 769 mm) was 24 % stiffer
    # than with 6 layers here, 41 % than with 13-24 in the audit; with layers graded like
    # the cells in plane, depth is no longer the main error.
    default = indentation_force(CUBE_PALM.body_at(0), CUBE_PALM.polygon_in_body)[0]
    layers_halved = indentation_force(CUBE_PALM.body_at(0, depth_level=1), CUBE_PALM.polygon_in_body)[0]
    assert layers_halved < default
    assert default / layers_halved - 1.0 < 0.05, f"default {default:.1f} N, layers halved {layers_halved:.1f} N"


# ------------------------------------------------------------------ covered prints
def covered_print_force(body: DeformableBody, polygon_in_body) -> float:
    """Vertical force on a rigid print pressed ``INDENTATION`` down, every node whose cell
    it covers coupled by the covered fraction (``fem.print_coverage``, the consistent
    model of the posture solver). Newtons, + z."""
    ids, coverage = print_coverage(body.mesh, polygon_in_body)
    patch = body.contact_patch(ids, coverage)
    return float(patch.reaction_forces(np.tile([0.0, 0.0, -INDENTATION], (len(ids), 1)))[:, 2].sum())


@pytest.fixture(scope="module", params=[MAT_SOLE, MAT_PALM], ids=["sole", "palm"])
def covered_forces(request):
    """(2, 7) float, newtons: the covered print's force at h and h / 2, lattice-aligned
    first, then at the six placements of PLACEMENT_OFFSETS."""
    study = request.param
    polygons = [study.polygon_in_body] + [study.placed_polygon(o, PLACEMENT_ANGLE) for o in PLACEMENT_OFFSETS]
    return np.array([[covered_print_force(study.body_at(level), p) for p in polygons] for level in (0, 1)])


def test_default_mesh_print_force_is_within_target_of_twice_refined_mesh_at_every_placement(covered_forces):
    # The target, print by print. Measured 4.1-4.6 % (sole), 2.9-3.4 % (palm);
    # the nodes inside the polygon gave 13.6 % and 17.8 % for the aligned prints.
    change = covered_forces[0] / covered_forces[1] - 1.0
    assert np.abs(change).max() < TARGET, f"force changes from h to h/2 by {change.round(3)}"


def test_the_covered_print_force_barely_depends_on_its_placement(covered_forces):
    # Measured 0.5 % (sole) and 1.3 % (palm) at h, where the nodes inside the polygon
    # scatter by 26 % and 42 % (aligned included).
    scatter = np.ptp(covered_forces, axis=1) / covered_forces.mean(axis=1)
    assert scatter[0] < 0.02 and scatter[1] < 0.02, f"scatter over placements at h, h/2: {scatter.round(4)}"


def test_the_covered_print_converges_to_the_nodes_limit(mat_sole_forces):
    # Both models of the same rectangle tend to one continuum answer: the Richardson
    # limit of the aligned node prints (h, h/2, h/4). Measured -0.4 % at h, -2.8 % at h/2
    # (the limit itself is uncertain by a few percent: its three meshes' print edges fall
    # on rows of the mirrored cells of different kinds, observed order 1.66; with one
    # diagonal everywhere, before 2026-12-03: +5.3 % and +1.0 %).
    _, limit = richardson(mat_sole_forces)
    error = np.array([covered_print_force(MAT_SOLE.body_at(level), MAT_SOLE.polygon_in_body) for level in (0, 1)]) / limit - 1.0
    assert abs(error[1]) < 0.035 and abs(error[0]) < 0.08, error.round(4)
