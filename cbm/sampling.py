"""Contact-print sampling on the scene's surfaces (reach pruning: :mod:`cbm.reach`).

The paper's Sec. V explains why prints on a deformable support must be fixed
beforehand: the FEM print (the set of surface nodes under the link) changes
discontinuously with the print pose. So the planner searches over a finite
grid of prints ``(x, y, theta)`` sampled on every contact surface, rigid or
deformable; :mod:`cbm.reach` then prunes them by simple distances before any
posture solve.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from environments.geometry import wrap_angle
from environments.stance import ContactPrint

from .errors import CbmError

__all__ = [
    "SamplingOptions",
    "PrintSet",
    "grid_values",
    "sample_prints",
]

#: Most candidate prints (grid points x headings, summed over the surfaces each
#: robot surface may touch) one sampling may consider. The built-in scenarios
#: consider about 30 000; each candidate costs a few hundred bytes of temporary
#: arrays and the kept ones a node of the search graph, so a spacing that exceeds
#: this is taken for a mistake and refused before any array is allocated.
MAX_PRINT_CANDIDATES = 1_000_000


@dataclass(frozen=True)
class SamplingOptions:
    """How prints are sampled.

    Parameters
    ----------
    spacing : float
        Grid step in x and y, metres, surface frame.
    theta_values : tuple of float
        Print rotations about the surface normal, radians.
    margin : float
        Distance every print vertex keeps inside the surface polygon, metres.
    max_sole_tilt : float
        Feet (robot surfaces of role ``"foot"``) only go on surfaces whose
        outward normal is within this angle of world +z, radians (floors and
        box tops, not walls).
    clearance : float
        Height above a print, metres, that must be free of other objects.
    region_lower, region_upper : (2,) float or None
        If given, only prints whose origin lies in this world xy box, metres.
    """

    spacing: float = 0.1
    theta_values: tuple = (0.0,)
    margin: float = 0.0
    max_sole_tilt: float = math.radians(20.0)
    clearance: float = 0.02
    region_lower: tuple | None = None
    region_upper: tuple | None = None

    def __post_init__(self):
        if not (math.isfinite(self.spacing) and self.spacing > 0):
            raise CbmError(f"print spacing must be a positive number of metres, got {self.spacing!r}")
        thetas = tuple(float(t) for t in self.theta_values)
        if not thetas or not all(math.isfinite(t) for t in thetas):
            raise CbmError(f"theta_values must be a non-empty list of finite radians, got {self.theta_values!r}")
        object.__setattr__(self, "theta_values", thetas)
        for name in ("region_lower", "region_upper"):
            value = getattr(self, name)
            if value is not None:
                value = tuple(float(v) for v in value)
                if len(value) != 2:
                    raise CbmError(f"{name} must be a world (x, y) pair, metres, got {value!r}")
                object.__setattr__(self, name, value)
        if self.margin < 0:
            raise CbmError(f"margin must be >= 0 metres, got {self.margin!r}")


@dataclass(frozen=True, eq=False)
class PrintSet:
    """Candidate prints of one robot surface, with their world placement.

    Parameters
    ----------
    robot_surface : str
        Robot contact surface they are for.
    prints : tuple of ContactPrint
        The prints, n of them.
    origins_in_world : (n, 3) float
        Print origins, metres, world frame.
    x_axes_in_world : (n, 3) float
        Print x axes (the robot surface's forward direction), world frame.
    """

    robot_surface: str
    prints: tuple
    origins_in_world: np.ndarray = field(repr=False)
    x_axes_in_world: np.ndarray = field(repr=False)

    def __len__(self):
        return len(self.prints)


def grid_values(lower, upper, spacing):
    """Grid coordinates covering ``[lower, upper]`` with a given step, centred.

    Parameters
    ----------
    lower, upper : float
        Interval bounds, metres.
    spacing : float
        Step, metres.

    Returns
    -------
    (m,) float
        ``m = floor((upper - lower) / spacing) + 1`` values ``spacing`` apart,
        the leftover split evenly at both ends.

    Examples
    --------
    >>> grid_values(-0.25, 0.25, 0.2).round(6).tolist()
    [-0.2, 0.0, 0.2]
    """
    count = int(math.floor((upper - lower) / spacing + 1e-9)) + 1
    start = lower + 0.5 * ((upper - lower) - (count - 1) * spacing)
    return start + spacing * np.arange(count)


def _faces_feet(surface, options):
    """Whether a scene surface can take a foot: its normal within the tilt bound of world up."""
    transform = np.asarray(surface.transform_surface_to_world, dtype=float)
    return transform[2, 2] >= math.cos(options.max_sole_tilt)


def _candidate_surfaces(surfaces, robot_surfaces, options):
    """(robot surface, surface name) pairs sampled, in sampling order: feet only on surfaces facing up."""
    return [
        (robot_surface, name)
        for robot_surface, declared in robot_surfaces.items()
        for name in sorted(surfaces)
        if declared.role != "foot" or _faces_feet(surfaces[name], options)
    ]


def check_goal_regions(regions, surfaces, robot_surfaces, options=SamplingOptions()):
    """Refuse goal regions no print can lie in, before a search looks for them.

    A region of a robot surface the planner places is unreachable when it misses the
    sampling region or overlaps no surface the robot surface may go on (feet only on
    surfaces facing up): a search would spend its whole budget, then blame the grid.
    Checked on the surfaces' world xy bounds, so a region that passes may still hold no
    print of a coarse grid. A region of a surface the planner does not place (not in
    ``robot_surfaces``) is left to the start stance, which alone can meet it.

    Parameters
    ----------
    regions : sequence of environments GoalRegion
    surfaces, robot_surfaces, options
        As for :func:`sample_prints`.

    Raises
    ------
    CbmError
        Naming the region, why no print can lie in it, and what to change.
    """
    region_lower = np.full(2, -np.inf) if options.region_lower is None else np.asarray(options.region_lower)
    region_upper = np.full(2, np.inf) if options.region_upper is None else np.asarray(options.region_upper)
    pairs = _candidate_surfaces(surfaces, robot_surfaces, options)
    extents = {}  # surface name -> its world xy bounds, (2,) lower and upper
    for _, name in pairs:
        if name not in extents:
            # The surface's own outline, as a print of it at its origin.
            corners = surfaces[name].print_polygon_in_world(surfaces[name].polygon, 0.0, 0.0, 0.0)
            extents[name] = (corners[:, :2].min(axis=0), corners[:, :2].max(axis=0))
    for region in regions:
        if region.robot_surface not in robot_surfaces:
            # Not placed by the planner (options.robot_surfaces): only the start can meet it.
            continue
        where = (f"the goal region of {region.robot_surface} (x {region.lower[0]:g}..{region.upper[0]:g}, "
                 f"y {region.lower[1]:g}..{region.upper[1]:g} m)")
        lower, upper = np.asarray(region.lower, dtype=float), np.asarray(region.upper, dtype=float)
        if np.any(upper < region_lower) or np.any(lower > region_upper):
            raise CbmError(
                f"{where} lies outside the sampling region (x {region_lower[0]:g}..{region_upper[0]:g}, "
                f"y {region_lower[1]:g}..{region_upper[1]:g} m, options.sampling_region), the only place prints are "
                "sampled; widen the sampling region or move the goal region into it")
        bounds = {name: extents[name] for robot_surface, name in pairs if robot_surface == region.robot_surface}
        if not any(np.all(upper >= low) and np.all(lower <= high) for low, high in bounds.values()):
            listed = "; ".join(f"{name} x {low[0]:g}..{high[0]:g}, y {low[1]:g}..{high[1]:g}"
                               for name, (low, high) in sorted(bounds.items()))
            raise CbmError(f"{where} overlaps no surface {region.robot_surface} can go on "
                           f"({listed or 'none'}); move the region onto one of them")


def count_candidate_prints(surfaces, robot_surfaces, options=SamplingOptions()):
    """How many candidate prints :func:`sample_prints` would test, without sampling.

    Parameters
    ----------
    surfaces, robot_surfaces, options
        As for :func:`sample_prints`.

    Returns
    -------
    float
        Grid points times headings, summed over the (robot surface, surface)
        pairs; a float because a tiny spacing makes it overflow to inf.
    """
    total = 0.0
    for _, name in _candidate_surfaces(surfaces, robot_surfaces, options):
        polygon = np.asarray(surfaces[name].polygon, dtype=float)
        per_axis = 1.0
        for extent in (float(np.ptp(polygon[:, 0])), float(np.ptp(polygon[:, 1]))):
            steps = extent / options.spacing + 1e-9  # grid_values' count, as a float
            per_axis *= (math.floor(steps) if math.isfinite(steps) else steps) + 1.0
        total += per_axis * len(options.theta_values)
    return total


def check_print_budget(surfaces, robot_surfaces, options=SamplingOptions()):
    """Refuse a sampling that would test more than :data:`MAX_PRINT_CANDIDATES` prints.

    Raises
    ------
    CbmError
        Giving the count, the limit and the smallest print spacing that fits.
    """
    count = count_candidate_prints(surfaces, robot_surfaces, options)
    if count <= MAX_PRINT_CANDIDATES:
        return
    # The count falls as the spacing grows: bisect (log scale) on the count alone.
    low = options.spacing
    high = max(
        [low]
        + [float(np.ptp(np.asarray(s.polygon, dtype=float), axis=0).max()) for s in surfaces.values()]
    )
    for _ in range(60):
        middle = math.sqrt(low * high)
        trial = dataclasses.replace(options, spacing=middle)
        if count_candidate_prints(surfaces, robot_surfaces, trial) > MAX_PRINT_CANDIDATES:
            low = middle
        else:
            high = middle
    scale = 10.0 ** (math.floor(math.log10(high)) - 2)
    fits = f"{math.ceil(high / scale - 1e-9) * scale:.3g}"  # rounded up, so that it still fits
    shown = f"about {count:.3g}" if math.isfinite(count) else "countless"
    raise CbmError(
        f"print_spacing {options.spacing:g} m would sample {shown} candidate prints ({len(options.theta_values)} "
        f"heading(s), {len(robot_surfaces)} robot surface(s)), more than the limit of {MAX_PRINT_CANDIDATES} "
        f"(cbm.sampling.MAX_PRINT_CANDIDATES); use a print_spacing of at least {fits} m, or fewer headings"
    )


def _rotations_2d(thetas):
    c, s = np.cos(thetas), np.sin(thetas)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (t, 2, 2)


def obstacle_boxes(scene):
    """Oriented bounding boxes of the scene's objects, for occupancy pruning.

    Parameters
    ----------
    scene : environments Scene
        Its rigid objects (``box_size`` or mesh bounds) and deformable objects
        (rest mesh bounds).

    Returns
    -------
    list of tuple (str, (4, 4) float, (3,) float, (3,) float)
        ``(object name, transform_world_to_object, lower, upper)``: the box
        in the object frame, metres.
    """
    boxes = []
    for obj in scene.rigid_objects:
        transform = np.asarray(obj.transform_object_to_world, dtype=float)
        lower, upper = obj.bounds_in_object
        boxes.append((obj.name, np.linalg.inv(transform), lower, upper))
    for obj in scene.deformable_objects:
        nodes = np.asarray(obj.mesh.nodes, dtype=float)
        transform = np.asarray(obj.transform_body_to_world, dtype=float)
        boxes.append((obj.name, np.linalg.inv(transform), nodes.min(axis=0), nodes.max(axis=0)))
    return boxes


def sample_prints(surfaces, robot_surfaces, options=SamplingOptions(), obstacles=()):
    """Sample the prints of every robot surface on every scene surface.

    Parameters
    ----------
    surfaces : mapping of str to environments ContactSurface
        The scene's contact surfaces (rigid and deformable).
    robot_surfaces : mapping of str to stances RobotSurface
        The robot contact surfaces to place: their ``polygon`` ((k, 2)
        float, metres, contact frame) and ``role`` (feet only go on surfaces
        facing up).
    options : SamplingOptions
        Grid step, rotations, margin, foot tilt.
    obstacles : sequence, optional
        Boxes of :func:`obstacle_boxes`. A print is dropped if a point
        ``options.clearance`` above one of its vertices (along the surface
        normal) lies inside the box of an object other than the surface's own:
        a print on the floor under a block is not a print.

    Returns
    -------
    dict of str to PrintSet
        For each robot surface, every print whose robot polygon lies inside
        the surface polygon (shrunk by the margin). Feet only on surfaces
        facing up; hands on any surface. Surfaces in name order, then x, y,
        theta: the order is deterministic.

    Raises
    ------
    CbmError
        If more than :data:`MAX_PRINT_CANDIDATES` prints would be tested (see
        :func:`check_print_budget`).
    """
    check_print_budget(surfaces, robot_surfaces, options)
    thetas = np.asarray(options.theta_values, dtype=float)
    rotations = _rotations_2d(thetas)
    pairs = _candidate_surfaces(surfaces, robot_surfaces, options)
    sets = {}
    for robot_surface, declared in robot_surfaces.items():
        robot_polygon = np.asarray(declared.polygon, dtype=float)
        prints, origins, x_axes = [], [], []
        for name in [name for rs, name in pairs if rs == robot_surface]:
            surface = surfaces[name]
            transform = np.asarray(surface.transform_surface_to_world, dtype=float)
            polygon = np.asarray(surface.polygon, dtype=float)
            xs = grid_values(polygon[:, 0].min(), polygon[:, 0].max(), options.spacing)
            ys = grid_values(polygon[:, 1].min(), polygon[:, 1].max(), options.spacing)
            gx, gy = np.meshgrid(xs, ys, indexing="ij")
            centres = np.column_stack([gx.ravel(), gy.ravel()])  # (c, 2)
            # Vertices of every (centre, theta) print, surface frame: (c, t, k, 2).
            turned = np.einsum("tij,kj->tki", rotations, robot_polygon)
            vertices = centres[:, None, None, :] + turned[None]
            # The surface polygon is convex, so vertices inside <=> print inside.
            inside = surface.contains(vertices.reshape(-1, 2), options.margin)
            inside = np.asarray(inside).reshape(vertices.shape[:3]).all(axis=2)  # (c, t)
            rotation, translation = transform[:3, :3], transform[:3, 3]
            origins_grid = np.column_stack([centres, np.zeros(len(centres))]) @ rotation.T + translation
            raised = np.concatenate(
                [vertices, np.full(vertices.shape[:3] + (1,), options.clearance)], axis=3
            ) @ rotation.T + translation  # (c, t, k, 3), world frame
            for object_name, transform_world_to_object, lower, upper in obstacles:
                if object_name == getattr(surface, "object_name", None):
                    continue
                local = raised @ transform_world_to_object[:3, :3].T + transform_world_to_object[:3, 3]
                blocked = np.all((local > lower) & (local < upper), axis=3).any(axis=2)
                inside &= ~blocked
            if options.region_lower is not None:
                inside &= np.all(origins_grid[:, None, :2] >= options.region_lower, axis=2)
            if options.region_upper is not None:
                inside &= np.all(origins_grid[:, None, :2] <= options.region_upper, axis=2)
            for c, t in zip(*np.nonzero(inside)):
                x, y = centres[c]
                prints.append(ContactPrint(name, float(x), float(y), float(thetas[t])))
                origins.append(rotation @ np.array([x, y, 0.0]) + translation)
                x_axes.append(rotation @ np.array([math.cos(thetas[t]), math.sin(thetas[t]), 0.0]))
        origins = np.array(origins, dtype=float).reshape(-1, 3)
        x_axes = np.array(x_axes, dtype=float).reshape(-1, 3)
        origins.setflags(write=False)
        x_axes.setflags(write=False)
        sets[robot_surface] = PrintSet(robot_surface, tuple(prints), origins, x_axes)
    return sets


def with_prints(print_sets, contacts, surfaces):
    """The print sets with the prints of given contacts added where the grid missed them.

    A goal that names its prints (``goal: {stance: ...}``) is reachable only if
    those exact prints are candidates; a print off the sampling grid (the palm of
    ``hand-on-cube`` at y = 0.05 on a 0.1 m grid) would otherwise leave the search
    wandering among neighbours that never equal the goal.

    Parameters
    ----------
    print_sets : dict of str to PrintSet
        As :func:`sample_prints` returns.
    contacts : iterable of environments Contact
        Contacts whose prints must be candidates (robot surfaces not in
        ``print_sets`` are skipped: the planner does not move them).
    surfaces : mapping of str to environments ContactSurface

    Returns
    -------
    dict of str to PrintSet
        The same sets, each missing print appended (deterministic order).
    """
    out = dict(print_sets)
    for contact in contacts:
        current = out.get(contact.robot_surface)
        if current is None or contact.contact_print in current.prints:
            continue
        p = contact.contact_print
        transform = surfaces[p.surface].transform_print_to_world(p.x, p.y, p.theta)
        origins = np.vstack([current.origins_in_world, transform[:3, 3]])
        x_axes = np.vstack([current.x_axes_in_world, transform[:3, 0]])
        origins.setflags(write=False)
        x_axes.setflags(write=False)
        out[contact.robot_surface] = PrintSet(contact.robot_surface, current.prints + (p,), origins, x_axes)
    return out


def contacts_in_world(stance, surfaces):
    """World placement of a stance's prints.

    Parameters
    ----------
    stance : environments Stance
        Its contacts.
    surfaces : mapping of str to ContactSurface
        The scene's surfaces.

    Returns
    -------
    dict of str to tuple ((3,) float, (3,) float)
        Robot surface -> (print origin, print x axis), metres, world frame.
    """
    placed = {}
    for contact in stance:
        p = contact.contact_print
        transform = surfaces[p.surface].transform_print_to_world(p.x, p.y, p.theta)
        placed[contact.robot_surface] = (np.asarray(transform[:3, 3]), np.asarray(transform[:3, 0]))
    return placed


#: Grid steps per step length in the default print spacing.
_STEPS_PER_STRIDE = 4


def default_print_spacing(step_length: float) -> float:
    """The print grid step when neither the user nor the scenario sets one, metres.

    A quarter of the robot's longest step, at most :attr:`SamplingOptions.spacing`'s
    default (0.1 m): a step then reaches several grid points in every direction
    (measured: Solo-12, whose step is 0.17 m, found no way onto a foam patch in
    200 expansions on the 0.1 m grid nor on a 0.056 m one, and planned in
    0.5-0.8 s on 0.05, 0.045 and 0.042 m ones).
    Talos (0.41 m step) keeps 0.1 m, Romeo (0.34 m) gets 0.085 m.

    Parameters
    ----------
    step_length : float
        Metres (:attr:`cbm.reach.ReachModel.step_length`).
    """
    return min(SamplingOptions.spacing, float(step_length) / _STEPS_PER_STRIDE)


def coarse_grid_hint(spacing: float, step_length: float) -> str:
    """What to add to a failed plan's reason when its print grid is coarser than the robot's default.

    A scenario's ``print_spacing`` is chosen for the robot it names; another
    robot's step may reach no print of that grid (iCub's 0.24 m step on
    cross-soft-block's 0.1 m grid: from the last floor print before the foam,
    the nearest foam print is 0.27 m away, and 200 expansions find no plan; on
    its default 0.06 m grid it plans in 13 stances).

    Parameters
    ----------
    spacing : float
        The grid step the plan used, metres.
    step_length : float
        The robot's step, metres (:attr:`cbm.reach.ReachModel.step_length`).

    Returns
    -------
    str
        ``""`` if ``spacing`` is at most :func:`default_print_spacing`, else a
        clause starting with ``"; "`` that names the robot's default grid.

    Examples
    --------
    >>> coarse_grid_hint(0.1, 0.4)
    ''
    >>> coarse_grid_hint(0.1, 0.24)
    '; the print grid (0.1 m) is coarser than a quarter of the 0.24 m step of this robot, so a step reaches few prints: its default grid is print_spacing 0.06 (cbm plan --print-spacing 0.06)'
    """
    default = default_print_spacing(step_length)
    if spacing <= default + 1e-9:
        return ""
    return (
        f"; the print grid ({spacing:.3g} m) is coarser than a quarter of the {step_length:.2f} m step of this robot, "
        f"so a step reaches few prints: its default grid is print_spacing {default:.2g} "
        f"(cbm plan --print-spacing {default:.2g})"
    )


#: Headings closer than this (radians) are one heading.
_SAME_HEADING = 1e-9


def _yaw(axis) -> float | None:
    """Angle of a world vector's horizontal projection about world z, radians; None if vertical."""
    if math.hypot(axis[0], axis[1]) < 1e-6:
        return None
    return math.atan2(axis[1], axis[0])


def _distinct(angles):
    """Sorted angles, each kept once (angles closer than :data:`_SAME_HEADING` are one)."""
    kept = []
    for angle in sorted(angles):
        if not kept or angle - kept[-1] >= _SAME_HEADING:
            kept.append(angle)
    return kept


def _arc(yaws, max_step):
    """Yaws on the shortest arc through all of ``yaws``, consecutive ones at most ``max_step`` apart.

    The arc leaves out the largest gap between neighbouring yaws around the circle,
    so a turn from 170 to -170 degrees goes through 180, not through 0.
    """
    ordered = _distinct(wrap_angle(y) for y in yaws)
    gaps = [(ordered[(i + 1) % len(ordered)] - y) % (2.0 * math.pi) for i, y in enumerate(ordered)]
    first = (int(np.argmax(gaps)) + 1) % len(ordered)  # the arc starts after its largest gap
    unwrapped = [ordered[first]]
    for k in range(1, len(ordered)):
        unwrapped.append(unwrapped[0] + (ordered[(first + k) % len(ordered)] - ordered[first]) % (2.0 * math.pi))
    filled = [unwrapped[0]]
    for a, b in zip(unwrapped, unwrapped[1:]):
        steps = max(1, math.ceil((b - a) / max_step - 1e-9))
        filled.extend(a + (b - a) * k / steps for k in range(1, steps + 1))
    return filled


def default_headings(contacts, surfaces, feet, max_step, options=SamplingOptions()):
    """Print headings to sample when neither the user nor the scenario lists any, radians.

    The feet must turn from the start's headings to the goal's, and two feet differ
    by at most ``max_step`` in heading (:attr:`cbm.reach.ReachLimits.max_foot_yaw_difference`),
    so the headings sampled are the world headings of the start's and the goal's
    foot prints and, between them, enough evenly spaced ones that consecutive
    headings are at most ``max_step`` apart (start at 0 and goal at 90 degrees with
    a 45 degree bound: 0, 45, 90). A plan whose feet keep one heading samples that
    heading only, as a single heading of 0 did before. Each heading is given in
    the frame of every surface a foot may stand on (a surface's ``theta`` is about
    its own x axis), so a yawed box gets the same world headings as the floor.

    Parameters
    ----------
    contacts : iterable of environments Contact
        The start's and the goal's contacts.
    surfaces : mapping of str to environments ContactSurface
        The scene's surfaces.
    feet : collection of str
        Robot surfaces that are feet (only their headings are followed).
    max_step : float
        Radians, > 0.
    options : SamplingOptions
        Its ``max_sole_tilt`` says which surfaces take feet.

    Returns
    -------
    tuple of float
        Sorted headings in (-pi, pi], radians, surface frames; ``(0.0,)`` when no
        foot print has a heading (no feet among the contacts).
    """
    if not (math.isfinite(max_step) and max_step > 0):
        raise CbmError(f"the largest heading step must be a positive angle in radians, got {max_step!r}")
    yaws = []
    for contact in contacts:
        if contact.robot_surface not in feet:
            continue
        p = contact.contact_print
        yaw = _yaw(np.asarray(surfaces[p.surface].transform_print_to_world(p.x, p.y, p.theta))[:3, 0])
        if yaw is not None:
            yaws.append(yaw)
    if not yaws:
        return (0.0,)
    headings = _arc(yaws, max_step)
    thetas = []
    for surface in surfaces.values():
        if not _faces_feet(surface, options):
            continue
        own = _yaw(np.asarray(surface.transform_surface_to_world, dtype=float)[:3, 0]) or 0.0
        for heading in headings:
            theta = wrap_angle(heading - own)
            theta = math.pi if theta <= _SAME_HEADING - math.pi else theta  # ContactPrint's range, (-pi, pi]
            thetas.append(0.0 if abs(theta) < _SAME_HEADING else theta)
    return tuple(_distinct(thetas)) or (0.0,)


def options_from_scenario(scenario_options: Mapping | None, spacing=None, default_spacing=None, default_thetas=None):
    """Sampling options from a scenario's ``options`` and a user override.

    Parameters
    ----------
    scenario_options : mapping or None
        May hold ``print_spacing`` (metres), ``theta_values_deg`` (degrees),
        ``print_margin`` (metres) and ``sampling_region`` (``{lower, upper}``
        world xy, metres), and ``robot_surfaces`` (read by the planner); see
        :data:`environments.options.SCENARIO_OPTIONS`.
    spacing : float, optional
        User's spacing, metres; wins over the scenario's.
    default_spacing : float, optional
        Metres, when neither the user nor the scenario gives one (e.g.
        :func:`default_print_spacing` of the robot's step); else
        :class:`SamplingOptions`' own default.
    default_thetas : tuple of float, optional
        Radians, when the scenario lists no ``theta_values_deg`` (e.g.
        :func:`default_headings` of the start and goal); else
        :class:`SamplingOptions`' own default.

    Returns
    -------
    SamplingOptions

    Raises
    ------
    environments.ScenarioError
        On an unknown key, or a value of the wrong type or out of range (checked
        again here for options that did not come from a scenario file).
    CbmError
        On a bad ``spacing``.
    """
    from environments.options import validate_options

    scenario_options = validate_options(scenario_options)
    kwargs = {}
    if spacing is not None:
        kwargs["spacing"] = float(spacing)
    elif "print_spacing" in scenario_options:
        kwargs["spacing"] = scenario_options["print_spacing"]
    elif default_spacing is not None:
        kwargs["spacing"] = float(default_spacing)
    if "theta_values_deg" in scenario_options:
        kwargs["theta_values"] = tuple(math.radians(t) for t in scenario_options["theta_values_deg"])
    elif default_thetas is not None:
        kwargs["theta_values"] = tuple(default_thetas)
    region = scenario_options.get("sampling_region")
    if region is not None:
        kwargs["region_lower"] = tuple(region["lower"])
        kwargs["region_upper"] = tuple(region["upper"])
    if "print_margin" in scenario_options:
        kwargs["margin"] = scenario_options["print_margin"]
    return SamplingOptions(**kwargs)


__all__ += [
    "check_goal_regions",
    "with_prints",
    "contacts_in_world",
    "options_from_scenario",
    "default_print_spacing",
    "coarse_grid_hint",
    "default_headings",
    "obstacle_boxes",
    "count_candidate_prints",
    "check_print_budget",
    "MAX_PRINT_CANDIDATES",
]
