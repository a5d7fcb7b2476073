"""Tests of the scene data types: prints, stances, surfaces, objects, scenes, goals."""

import math

import numpy as np
import pytest

import environments
import fem
from conftest import scene_distance, sphere
from environments import (
    Contact,
    ContactPrint,
    ContactSurface,
    Goal,
    GoalRegion,
    Scene,
    SceneError,
    Stance,
    box,
    box_surfaces,
    floor,
    rectangle,
)
from environments.deformable import soft_box_coordinates
from environments.geometry import rotation_about_z


def contact(robot_surface, surface="floor", x=0.0, y=0.0, theta=0.0):
    return Contact(robot_surface, ContactPrint(surface, x, y, theta))


@pytest.fixture
def table_scene():
    ground = floor()
    table = box("table", (0.6, 0.8, 0.8), center=(0.65, -0.25, 0.4), yaw=0.3)
    surfaces = box_surfaces(ground, top_name="floor") + box_surfaces(table, sides=True)
    return Scene("table", [ground, table], [], surfaces)


# ------------------------------------------------------------------ prints, stances
def test_public_names_are_exported():
    for name in environments.__all__:
        assert hasattr(environments, name), name


def test_contact_print_wraps_theta_so_equal_angles_compare_equal():
    assert ContactPrint("floor", 0, 0, 2 * math.pi + 0.5) == ContactPrint("floor", 0, 0, 0.5)
    assert ContactPrint("floor", 0, 0, -math.pi) == ContactPrint("floor", 0, 0, math.pi)


@pytest.mark.parametrize("bad", [dict(x=float("nan")), dict(y="a"), dict(theta=True), dict(surface="")])
def test_contact_print_rejects_bad_values(bad):
    values = dict(surface="floor", x=0.0, y=0.0, theta=0.0) | bad
    with pytest.raises(SceneError):
        ContactPrint(**values)


def test_stance_is_canonical_in_order_hash_and_equality():
    left, right, palm = contact("left_sole", y=0.085), contact("right_sole", y=-0.085), contact("right_palm")
    a, b = Stance((palm, right, left)), Stance((left, right, palm))
    assert a == b and hash(a) == hash(b)
    assert a.robot_surfaces == ("left_sole", "right_palm", "right_sole")
    assert len({a, b}) == 1
    assert list(a) == list(a.contacts) and len(a) == 3


def test_stance_refuses_two_contacts_on_one_robot_surface():
    with pytest.raises(SceneError, match="left_sole"):
        Stance((contact("left_sole"), contact("left_sole", x=0.3)))


def test_with_contact_replaces_the_same_robot_surface_and_without_removes_it():
    stance = Stance((contact("left_sole", y=0.085), contact("right_sole", y=-0.085)))
    moved = stance.with_contact(contact("left_sole", x=0.3, y=0.085))
    assert len(moved) == 2 and moved.contact("left_sole").contact_print.x == 0.3
    assert stance.contact("left_sole").contact_print.x == 0.0  # the original is unchanged
    added = stance.with_contact(contact("right_palm"))
    assert added.robot_surfaces == ("left_sole", "right_palm", "right_sole")
    assert stance.without("right_sole").robot_surfaces == ("left_sole",)
    with pytest.raises(SceneError, match="in contact: left_sole, right_sole"):
        stance.without("left_palm")


def test_stance_dict_round_trip_and_degrees():
    stance = Stance((contact("left_sole", y=0.085, theta=0.25), contact("right_palm", "table_top", -0.2, 0.0)))
    assert Stance.from_dict(stance.to_dict()) == stance
    in_degrees = Stance.from_dict({"left_sole": {"surface": "floor", "y": 0.085, "theta_deg": 90}})
    assert in_degrees.contact("left_sole").contact_print.theta == pytest.approx(math.pi / 2)
    with pytest.raises(SceneError, match="not both"):
        Stance.from_dict({"left_sole": {"surface": "floor", "theta": 0, "theta_deg": 0}})


# ------------------------------------------------------------------------ surfaces
@pytest.mark.parametrize(
    "polygon, message",
    [
        ([[0, 0], [0, 1], [1, 1], [1, 0]], "counter-clockwise"),
        ([[0, 0], [2, 0], [1, 0.2], [2, 1], [0, 1]], "convex"),
        ([[0, 0], [1, 0]], "at least 3"),
    ],
    ids=["clockwise", "reflex-corner", "two-vertices"],
)
def test_contact_surface_rejects_polygons_that_are_not_convex_counter_clockwise(polygon, message):
    with pytest.raises(SceneError, match=message):
        ContactSurface("s", "o", polygon, np.eye(4), 0.7)


def test_contact_surface_rejects_non_rigid_transforms_and_bad_friction():
    reflection = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(SceneError, match="reflection"):
        ContactSurface("s", "o", rectangle(1, 1), reflection, 0.7)
    with pytest.raises(SceneError, match="orthonormal"):
        ContactSurface("s", "o", rectangle(1, 1), np.diag([2.0, 1.0, 1.0, 1.0]), 0.7)
    with pytest.raises(SceneError, match="friction"):
        ContactSurface("s", "o", rectangle(1, 1), np.eye(4), 0.0)


def test_transform_print_to_world_composes_translation_then_rotation_about_the_normal():
    rng = np.random.default_rng(0)
    axis_angle = rng.normal(size=3)
    angle = np.linalg.norm(axis_angle)
    k = axis_angle / angle
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    rotation = np.eye(3) + math.sin(angle) * skew + (1 - math.cos(angle)) * skew @ skew
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = rotation, [0.3, -0.2, 1.1]
    surface = ContactSurface("s", "o", rectangle(2, 2), transform, 0.7)
    x, y, theta = 0.4, -0.3, 0.7
    result = surface.transform_print_to_world(x, y, theta)
    # Origin: surface point (x, y, 0); axes: surface axes turned theta about the normal.
    np.testing.assert_allclose(result[:3, 3], rotation @ [x, y, 0] + transform[:3, 3], atol=1e-12)
    np.testing.assert_allclose(result[:3, :3], rotation @ rotation_about_z(theta), atol=1e-12)
    np.testing.assert_allclose(result[:3, 2], rotation[:, 2], atol=1e-12)
    # A robot polygon vertex (1, 0) lands at (x + cos theta, y + sin theta) in the surface.
    vertex = surface.print_polygon_in_world([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]], x, y, theta)[0]
    np.testing.assert_allclose(vertex, rotation @ [x + math.cos(theta), y + math.sin(theta), 0] + transform[:3, 3])


def test_contains_uses_the_polygon_shrunk_by_the_margin():
    surface = ContactSurface("s", "o", rectangle(1.0, 0.5), np.eye(4), 0.7)
    points = [[0.0, 0.0], [0.45, 0.0], [0.55, 0.0], [0.0, 0.2], [0.5, 0.25]]
    assert surface.contains(points).tolist() == [True, True, False, True, True]
    assert surface.contains(points, margin=0.1).tolist() == [True, False, False, False, False]
    assert surface.area == pytest.approx(0.5)
    np.testing.assert_allclose(surface.centroid, [0.0, 0.0], atol=1e-15)


def _inside_convex_mesh(mesh, points):
    """Strictly inside a convex closed mesh: behind every face plane."""
    offsets = np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles[:, 0])
    return np.all(points @ mesh.face_normals.T < offsets - 1e-9, axis=1)


def test_box_surface_frames_are_rigid_and_point_out_of_their_box(table_scene):
    table = table_scene.objects["table"]
    mesh = table.mesh_in_world()
    assert mesh.is_convex
    names = [s.name for s in table_scene.surfaces.values() if s.object_name == "table"]
    assert sorted(names) == ["table_back", "table_front", "table_left", "table_right", "table_top"]
    for name in names:
        surface = table_scene.surface(name)
        rotation = surface.transform_surface_to_world[:3, :3]
        np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
        assert np.linalg.det(rotation) == pytest.approx(1.0)
        centre = surface.point_in_world(*surface.centroid)
        normal = surface.normal_in_world
        inside = _inside_convex_mesh(mesh, np.array([centre + 0.01 * normal, centre - 0.01 * normal]))
        assert inside.tolist() == [False, True], name
        # The polygon covers the face: its corners are corners of the mesh.
        corners = surface.print_polygon_in_world(surface.polygon, 0.0, 0.0, 0.0)
        distance = np.min(np.linalg.norm(mesh.vertices[None] - corners[:, None], axis=2), axis=1)
        np.testing.assert_allclose(distance, 0.0, atol=1e-9)


def test_floor_top_is_the_plane_z_zero():
    ground = floor()
    assert ground.mesh_in_world().bounds[1, 2] == pytest.approx(0.0)
    (top,) = box_surfaces(ground, top_name="floor")
    np.testing.assert_allclose(top.transform_surface_to_world, np.eye(4), atol=1e-12)


# --------------------------------------------------------------------------- scene
def test_scene_lookup_errors_list_the_valid_names(table_scene):
    with pytest.raises(SceneError, match="known surfaces: floor, table_back"):
        table_scene.surface("flor")
    with pytest.raises(SceneError, match=r"deformable objects: \(none\)"):
        table_scene.deformable("table")
    assert table_scene.deformable_of_surface("table_top") is None


def test_scene_refuses_a_surface_on_an_unknown_object():
    ground = floor()
    stray = ContactSurface("stray", "ghost", rectangle(1, 1), np.eye(4), 0.7)
    with pytest.raises(SceneError, match="unknown object 'ghost'"):
        Scene("s", [ground], [], [stray])


def test_distance_between_two_box_objects_equals_the_analytic_gap():
    a = box("a", (0.4, 0.4, 0.4), center=(0.0, 0.0, 1.0))
    b = box("b", (0.2, 0.6, 0.2), center=(0.55, 0.1, 1.05), yaw=0.0)
    scene = Scene("boxes", [a, b], [], [])
    objects = dict(scene.collision_objects())
    assert objects["a"].box_size.tolist() == [0.4, 0.4, 0.4]
    distance = scene_distance(objects["a"], objects["b"])
    # Faces x = 0.2 and x = 0.45 face each other and overlap in y and z.
    assert distance == pytest.approx(0.25, abs=1e-9)
    assert scene.collision_objects()[0][1] is objects["a"]  # built once


def test_mesh_objects_collide_like_their_boxes():
    import trimesh

    mesh = environments.mesh_object("m", trimesh.creation.box(extents=(0.4, 0.4, 0.4)), center=(0, 0, 1))
    b = box("b", (0.2, 0.2, 0.2), center=(0.0, 0.0, 1.5))
    objects = dict(Scene("s", [mesh, b], [], []).collision_objects())
    assert objects["m"].box_size is None and len(objects["m"].triangles) == 12
    distance = scene_distance(objects["m"], objects["b"])
    assert distance == pytest.approx(0.2, abs=1e-6)


# ---------------------------------------------------------------------------- goal
def test_goal_regions_are_satisfied_only_when_every_print_origin_is_inside(table_scene):
    goal = Goal(regions=(GoalRegion("left_sole", (0.8, -0.5), (1.5, 0.5)), GoalRegion("right_sole", (0.8, -0.5), (1.5, 0.5))))
    start = Stance((contact("left_sole", y=0.085), contact("right_sole", y=-0.085)))
    half = start.with_contact(contact("left_sole", x=0.9, y=0.085))
    done = half.with_contact(contact("right_sole", x=0.9, y=-0.085))
    assert not goal.is_satisfied(start, table_scene)
    assert not goal.is_satisfied(half, table_scene)
    assert goal.is_satisfied(done, table_scene)
    assert goal.distance(start, table_scene) == pytest.approx(1.6)
    assert goal.distance(half, table_scene) == pytest.approx(0.8)
    assert goal.distance(done, table_scene) == 0.0


def test_goal_distance_is_positive_for_a_missing_robot_surface(table_scene):
    goal = Goal(regions=(GoalRegion("right_sole", (0.8, -0.5), (1.5, 0.5)),))
    only_left_beyond = Stance((contact("left_sole", x=0.9, y=0.085),))
    assert not goal.is_satisfied(only_left_beyond, table_scene)
    assert goal.distance(only_left_beyond, table_scene) > 0.0


def test_goal_contacts_need_the_same_print_and_distance_measures_in_the_world(table_scene):
    target = contact("right_palm", "table_top", -0.2, 0.0)
    goal = Goal(contacts=(target,))
    feet = Stance((contact("left_sole", y=0.085), contact("right_sole", y=-0.085)))
    assert not goal.is_satisfied(feet, table_scene)
    assert goal.is_satisfied(feet.with_contact(target), table_scene)
    shifted = feet.with_contact(contact("right_palm", "table_top", -0.1, 0.0))
    assert goal.distance(shifted, table_scene) == pytest.approx(0.1)
    turned = feet.with_contact(contact("right_palm", "table_top", -0.2, 0.0, theta=0.5))
    assert not goal.is_satisfied(turned, table_scene)
    assert goal.distance(turned, table_scene) == pytest.approx(0.05)
    # Missing: at least the world distance from the nearest contact.
    palm_world = table_scene.print_origin_in_world(target)
    nearest = min(np.linalg.norm(palm_world - [0, y, 0]) for y in (0.085, -0.085))
    assert goal.distance(feet, table_scene) >= nearest


# ----------------------------------------------------------------------- soft boxes
PALM, SOLE = (0.10, 0.07), (0.20, 0.11)


def _worst_nodes_under_prints(top_nodes_xy, size_xy, print_size, rng, samples=300):
    """Fewest top nodes under a rectangle print placed anywhere fully on the top, at any angle."""
    half_print = 0.5 * np.array(print_size)
    reach = np.hypot(*half_print)
    fewest = None
    for _ in range(samples):
        theta = rng.uniform(0, math.pi)
        centre = rng.uniform(-0.5 * np.array(size_xy) + reach, 0.5 * np.array(size_xy) - reach)
        local = (top_nodes_xy - centre) @ rotation_about_z(theta)[:2, :2]
        count = int(np.sum(np.all(np.abs(local) <= half_print + 1e-9, axis=1)))
        fewest = count if fewest is None else min(fewest, count)
    return fewest


@pytest.mark.parametrize("size", [(1.0, 1.0, 1.0), (0.3, 0.3, 0.3), (0.3, 1.2, 0.1)], ids=["cube-1m", "cube-0.3m", "foam"])
def test_default_soft_box_grid_puts_nine_nodes_under_any_palm_print(size):
    xs, ys, zs = soft_box_coordinates(size, "default")
    grid = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    rng = np.random.default_rng(1)
    assert _worst_nodes_under_prints(grid, size[:2], PALM, rng) >= 9
    assert _worst_nodes_under_prints(grid, size[:2], SOLE, rng) >= 20
    assert zs[0] == 0.0 and zs[-1] == pytest.approx(size[2])
    assert np.all(np.diff(zs)[::-1][:-1] <= np.diff(zs)[::-1][1:] + 1e-12)  # thinnest on top


def test_default_one_metre_cube_grid_has_a_modest_node_count():
    xs, ys, zs = soft_box_coordinates((1.0, 1.0, 1.0), "default")
    # 46 x 46 x 15 since the layers are graded like the cells in plane (3 layers before,
    # 40 % too stiff); keep it where CHOLMOD factorises it in a few seconds.
    assert 2000 <= xs.size * ys.size * zs.size <= 35000
    coarse = soft_box_coordinates((1.0, 1.0, 1.0), "coarse")
    assert np.prod([c.size for c in coarse]) < xs.size * ys.size * zs.size / 3


def test_refine_region_is_fine_and_the_rest_coarser():
    xs, _, _ = soft_box_coordinates((1.0, 1.0, 1.0), "default", refine=[[-0.1, -0.5], [0.1, 0.5]])
    spacing = np.diff(xs)
    middle = (xs[:-1] >= -0.1 - 1e-12) & (xs[1:] <= 0.1 + 1e-12)
    assert spacing[middle].max() <= 0.0225 + 1e-12
    assert spacing[~middle].max() > 2 * 0.0225
    assert xs[0] == -0.5 and xs[-1] == 0.5 and np.all(spacing > 0)


def test_soft_box_fixes_its_base_and_exposes_a_deformable_top():
    material = fem.LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4, density=1e3)
    obj, top = environments.soft_box("cube", (1.0, 1.0, 1.0), (0.9, -0.3, 0.5), material, resolution="coarse")
    nodes_world = obj.points_in_world(obj.mesh.nodes)
    fixed = np.asarray(obj.body.fixed_nodes)
    np.testing.assert_allclose(nodes_world[fixed, 2], 0.0, atol=1e-12)
    assert fixed.size == np.sum(np.isclose(nodes_world[:, 2], 0.0))
    assert top.deformable and top.name == "cube_top"
    np.testing.assert_allclose(top.transform_surface_to_world[:3, 3], [0.9, -0.3, 1.0])
    np.testing.assert_allclose(top.normal_in_world, [0, 0, 1])
    triangles = obj.deformed_surface(np.zeros_like(obj.mesh.nodes))
    assert triangles.shape[1:] == (3, 3) and triangles[..., 2].max() == pytest.approx(1.0)
    lifted = obj.deformed_surface(np.tile([0.0, 0.0, 0.01], (obj.mesh.nodes.shape[0], 1)))
    np.testing.assert_allclose(lifted - triangles, np.broadcast_to([0, 0, 0.01], triangles.shape), atol=1e-12)


def test_palm_and_sole_prints_anywhere_on_a_default_cube_hold_nine_nodes():
    material = fem.LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4, density=1e3)
    obj, top = environments.soft_box("cube", (1.0, 1.0, 1.0), (0.9, -0.3, 0.5), material)
    transform_world_to_body = np.linalg.inv(obj.transform_body_to_world)
    rng = np.random.default_rng(2)
    for print_size in (PALM, SOLE):
        for _ in range(10):
            x, y = rng.uniform(-0.35, 0.35, size=2)
            polygon_world = top.print_polygon_in_world(rectangle(*print_size), x, y, rng.uniform(0, math.pi))
            polygon_body = polygon_world @ transform_world_to_body[:3, :3].T + transform_world_to_body[:3, 3]
            assert len(fem.nodes_in_polygon(obj.mesh, polygon_body, 1e-6)) >= 9


def test_deformable_top_frame_points_out_of_the_body_and_collision_uses_its_rest_box():
    material = fem.LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4, density=1e3)
    obj, top = environments.soft_box("cube", (0.3, 0.3, 0.3), (0.0, -0.16, 0.15), material, resolution="coarse")
    low, high = obj.points_in_world(obj.mesh.nodes).min(axis=0), obj.points_in_world(obj.mesh.nodes).max(axis=0)
    centre = top.point_in_world(0.0, 0.0)
    inside = lambda p: bool(np.all(p > low) and np.all(p < high))  # noqa: E731
    assert not inside(centre + 0.01 * top.normal_in_world) and inside(centre - 0.01 * top.normal_in_world)
    ground = floor()
    scene = Scene("s", [ground], [obj], box_surfaces(ground, top_name="floor") + [top])
    assert scene.deformable_of_surface("cube_top") is obj
    objects = dict(scene.collision_objects())
    assert objects["cube"].box_size is not None
    assert scene_distance(objects["cube"], sphere(0.05, (0.0, -0.16, 0.5))) == pytest.approx(0.15, abs=1e-6)


@pytest.mark.parametrize("margin", [0.0, 0.1, -0.05], ids=["boundary", "shrunk", "grown"])
def test_points_in_a_turned_moved_square_are_those_at_least_the_margin_from_every_edge(margin):
    from environments.geometry import points_in_convex_polygon

    # A 1 m square turned by 0.7 rad and moved off the origin; in its own frame a
    # point (u, v) is inside the shrunk square iff min(u, 1 - u, v, 1 - v) >= margin.
    turn = rotation_about_z(0.7)[:2, :2]
    offset = np.array([2.0, -1.0])
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    polygon = corners @ turn.T + offset
    uv = np.random.default_rng(0).uniform(-0.3, 1.3, size=(2000, 2))
    depth = np.min(np.column_stack([uv[:, 0], 1.0 - uv[:, 0], uv[:, 1], 1.0 - uv[:, 1]]), axis=1)
    away = np.abs(depth - margin) > 1e-9  # no point on the shrunk boundary itself
    inside = points_in_convex_polygon(polygon, uv @ turn.T + offset, margin)
    assert np.array_equal(inside[away], (depth >= margin)[away])
    assert points_in_convex_polygon(polygon, polygon.mean(axis=0), margin) is True


def test_polygon_centroid_is_the_area_weighted_mean_of_its_triangles_centroids():
    from environments.geometry import polygon_area, polygon_centroid

    # A convex quadrilateral whose centroid is not its vertices' mean, split along a diagonal.
    quad = np.array([[0.0, 0.0], [2.0, 0.0], [1.5, 1.0], [0.0, 3.0]]) + [0.7, -0.4]
    halves = [quad[[0, 1, 2]], quad[[0, 2, 3]]]
    areas = np.array([polygon_area(t) for t in halves])
    expected = sum(a * t.mean(axis=0) for a, t in zip(areas, halves)) / areas.sum()
    assert np.allclose(polygon_centroid(quad), expected, rtol=0.0, atol=1e-12)
    assert not np.allclose(expected, quad.mean(axis=0), atol=1e-3)
    assert np.allclose(polygon_centroid(quad[:3]), quad[:3].mean(axis=0), rtol=0.0, atol=1e-12)


def test_collision_shapes_read_as_their_size_and_place():
    """A shape's repr (in logs and errors) gives its box size or triangle count and its origin."""
    from environments.geometry import CollisionShape

    to_world = np.eye(4)
    to_world[:3, 3] = [0.4, -0.6, 0.45]
    assert repr(CollisionShape(to_world, box_size=(0.8, 0.8, 0.9))) == "CollisionShape(box 0.8 x 0.8 x 0.9 m at (0.4, -0.6, 0.45))"
    triangle = CollisionShape(np.eye(4), vertices=np.eye(3), triangles=[[0, 1, 2]])
    assert repr(triangle) == "CollisionShape(mesh of 1 triangles at (0, 0, 0))"
