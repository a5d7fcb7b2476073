"""Mesh construction, validation, surface extraction, I/O and gmsh meshing."""

import numpy as np
import pytest

from fem import (
    MeshError,
    TetMesh,
    box_mesh,
    mesh_from_surface,
    nodes_in_polygon,
    PrintError,
    read_mesh,
    tensor_mesh,
    write_mesh,
)

UNIT_TET_NODES = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])


@pytest.fixture
def graded_box():
    return box_mesh((1.0, 0.8, 0.6), (4, 3, 5), origin=(-0.5, 0.1, 0.0), grading=4.0)


def test_box_mesh_volumes_sum_to_box_volume(graded_box):
    assert np.all(graded_box.volumes > 0)
    assert graded_box.volumes.sum() == pytest.approx(1.0 * 0.8 * 0.6, rel=1e-12)


def test_grading_makes_top_layers_thinner():
    zs = np.unique(box_mesh((1, 1, 1), (2, 2, 6), grading=8.0).nodes[:, 2])
    heights = np.diff(zs)
    assert np.all(np.diff(heights) < 0)
    assert heights[0] / heights[-1] == pytest.approx(8.0)


def test_tensor_mesh_is_conforming_every_interior_face_shared_twice():
    mesh = tensor_mesh([0, 0.1, 0.5, 1.0], [0, 0.3, 1.0], [0, 0.2, 0.25, 1.0])
    # A closed conforming mesh of a box has exactly the box's surface as boundary.
    assert mesh.surface_areas.sum() == pytest.approx(6.0, rel=1e-12)
    assert mesh.volumes.sum() == pytest.approx(1.0, rel=1e-12)


def test_tensor_mesh_cells_are_mirror_images_so_it_is_symmetric_about_every_grid_plane():
    # Splitting every cell around the same diagonal (Kuhn) has no such symmetry: its
    # mirror image about a grid plane is a different mesh.
    mesh = tensor_mesh(np.linspace(0.0, 0.4, 5), [0.0, 0.1, 0.2, 0.35], [0.0, 0.02, 0.04, 0.1])
    points = mesh.nodes.round(12)
    own = {tuple(sorted(map(tuple, points[t].tolist()))) for t in mesh.tets}
    nodes = {tuple(p) for p in points.tolist()}
    for axis, plane in ((0, 0.1), (0, 0.2), (0, 0.3), (1, 0.1), (2, 0.02)):
        mirrored = points.copy()
        mirrored[:, axis] = (2.0 * plane - mirrored[:, axis]).round(12)
        on_nodes = np.array([tuple(p) in nodes for p in mirrored.tolist()])
        kept = mesh.tets[on_nodes[mesh.tets].all(axis=1)]  # tets whose image lies on the grid
        images = [tuple(sorted(map(tuple, mirrored[t].tolist()))) for t in kept]
        assert len(images) >= 24 and all(image in own for image in images), (axis, plane)


def test_a_vertical_load_moves_a_top_node_straight_down_and_a_centred_print_gets_no_sideways_force():
    # One diagonal everywhere moved a node pressed down sideways by 0.12 of its sinking,
    # toward (-x, -y), and pushed a centred print on this pad sideways by 2-4 % of its load.
    from fem import DeformableBody, LinearElasticMaterial, print_coverage

    mesh = box_mesh((0.4, 0.4, 0.1), (16, 16, 4))
    body = DeformableBody(mesh, LinearElasticMaterial(1e6, 0.45), np.flatnonzero(mesh.nodes[:, 2] == 0.0), cache=False)
    top = np.flatnonzero(np.isclose(mesh.nodes[:, 2], 0.1))
    for x, y in ((0.2, 0.2), (0.15, 0.25), (0.175, 0.2)):
        node = top[np.argmin(np.linalg.norm(mesh.nodes[top, :2] - [x, y], axis=1))]
        column = body.compliance([node])[:, 2]
        # Off the centre the pad's edges pull it sideways a little (continuum, not mesh).
        assert np.abs(column[:2]).max() < 0.01 * column[2], (x, y, column)
    half = np.array([0.05, 0.025])
    polygon = [[0.2 + sx * half[0], 0.2 + sy * half[1], 0.1] for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    ids, coverage = print_coverage(mesh, polygon)
    forces = body.contact_patch(ids, coverage).reaction_forces(np.tile([0.0, 0.0, -0.002], (ids.size, 1))).sum(axis=0)
    assert np.abs(forces[:2]).max() < 1e-9 * forces[2]


def test_surface_normals_point_outward(graded_box):
    mesh = graded_box
    weighted = (mesh.surface_normals * mesh.surface_areas[:, None]).sum(axis=0)
    assert np.allclose(weighted, 0.0, atol=1e-12)
    centroid = mesh.nodes.mean(axis=0)
    tri_centres = mesh.nodes[mesh.surface_triangles].mean(axis=1)
    assert np.all(((tri_centres - centroid) * mesh.surface_normals).sum(axis=1) > 0)
    assert np.allclose(np.linalg.norm(mesh.surface_normals, axis=1), 1.0)


def test_surface_triangles_belong_to_their_owner_tet(graded_box):
    mesh = graded_box
    owners = mesh.tets[mesh.surface_triangle_tets]
    assert np.all((mesh.surface_triangles[:, :, None] == owners[:, None, :]).any(axis=2))


def test_surface_nodes_of_box_are_on_its_faces(graded_box):
    lo, hi = graded_box.bounding_box
    x = graded_box.nodes[graded_box.surface_nodes]
    on_face = np.isclose(x, lo).any(axis=1) | np.isclose(x, hi).any(axis=1)
    assert on_face.all()
    assert graded_box.surface_nodes.size == graded_box.n_nodes - 3 * 2 * 4  # interior nodes: 3 x 2 x 4


def test_mesh_arrays_are_read_only(graded_box):
    with pytest.raises(ValueError):
        graded_box.nodes[0, 0] = 1.0
    with pytest.raises(ValueError):
        graded_box.tets[0, 0] = 1


def test_inverted_tet_is_rejected_with_its_index():
    tets = np.array([[0, 1, 2, 3], [0, 2, 1, 4]])
    nodes = np.vstack([UNIT_TET_NODES, [0.3, 0.3, -1.0]])
    # tet 1 with nodes 0,2,1,4 lies below z=0: (0,1,2,4) would be negative, so (0,2,1,4) is positive
    TetMesh(nodes, tets)
    with pytest.raises(MeshError, match=r"tet 1 is inverted .*fix_orientation=True"):
        TetMesh(nodes, np.array([[0, 1, 2, 3], [0, 1, 2, 4]]))
    fixed = TetMesh(nodes, np.array([[0, 1, 2, 3], [0, 1, 2, 4]]), fix_orientation=True)
    assert np.all(fixed.volumes > 0)


def test_flat_tet_is_rejected():
    nodes = np.vstack([UNIT_TET_NODES, [0.5, 0.5, 0.0]])
    with pytest.raises(MeshError, match=r"tet 1 is flat"):
        TetMesh(nodes, np.array([[0, 1, 2, 3], [0, 1, 2, 4]]))


def test_duplicate_nodes_are_rejected():
    nodes = np.vstack([UNIT_TET_NODES, UNIT_TET_NODES[3]])
    with pytest.raises(MeshError, match=r"nodes \[3, 4\] are duplicates"):
        TetMesh(nodes, np.array([[0, 1, 2, 3], [0, 1, 2, 4]]))


@pytest.mark.parametrize(
    "nodes, tets, message",
    [
        (np.vstack([UNIT_TET_NODES[:3], [np.nan, 0, 1]]), [[0, 1, 2, 3]], "non-finite"),
        (UNIT_TET_NODES, [[0, 1, 2, 4]], "outside"),
        (UNIT_TET_NODES, [[0, 1, 2]], "shape"),
        (np.vstack([UNIT_TET_NODES, [5, 5, 5]]), [[0, 1, 2, 3]], "belong to no tet"),
    ],
    ids=["nan-node", "index-out-of-range", "three-node-cells", "unused-node"],
)
def test_invalid_mesh_input_raises_mesh_error(nodes, tets, message):
    with pytest.raises(MeshError, match=message):
        TetMesh(nodes, np.array(tets))


def test_tensor_mesh_rejects_non_increasing_coordinates():
    with pytest.raises(MeshError, match="strictly increasing"):
        tensor_mesh([0, 1, 1], [0, 1], [0, 1])


@pytest.mark.parametrize("suffix", [".vtu", ".msh"])
def test_mesh_file_round_trip_preserves_nodes_and_tets(tmp_path, graded_box, suffix):
    path = tmp_path / f"box{suffix}"
    write_mesh(path, graded_box)
    back = read_mesh(path)
    assert np.allclose(back.nodes, graded_box.nodes)
    assert np.array_equal(back.tets, graded_box.tets)


def test_reading_a_file_without_tets_says_so(tmp_path):
    import meshio

    path = tmp_path / "tri.vtu"
    meshio.write(path, meshio.Mesh(UNIT_TET_NODES, [("triangle", np.array([[0, 1, 2]]))]))
    with pytest.raises(MeshError, match="no linear 'tetra' cells"):
        read_mesh(path)


def test_gmsh_meshes_a_trimesh_box_with_the_right_volume():
    # trimesh and gmsh are dependencies: a broken import fails here, never skips.
    import trimesh

    surface = trimesh.creation.box((1.0, 0.5, 0.4))
    mesh = mesh_from_surface(surface, 0.2, refine_box=[[-0.1, -0.1, 0.15], [0.1, 0.1, 0.2]], refine_size=0.05)
    assert np.all(mesh.volumes > 0)
    assert mesh.volumes.sum() == pytest.approx(0.2, rel=1e-9)
    # the refinement region holds smaller tets than the rest
    centres = mesh.nodes[mesh.tets].mean(axis=1)
    near = np.all(np.abs(centres[:, :2]) < 0.1, axis=1) & (centres[:, 2] > 0.1)
    assert mesh.volumes[near].mean() < 0.5 * mesh.volumes[~near].mean()


def test_nodes_in_polygon_finds_nonconvex_print_with_boundary_nodes():
    mesh = box_mesh((1, 1, 1), (4, 4, 2))
    # L-shaped polygon on the top face covering the cells [0,.5]x[0,.25] and [0,.25]x[0,.5]
    polygon = [[0, 0, 1], [0.5, 0, 1], [0.5, 0.25, 1], [0.25, 0.25, 1], [0.25, 0.5, 1], [0, 0.5, 1]]
    ids = nodes_in_polygon(mesh, polygon)
    expected = {(0, 0), (0.25, 0), (0.5, 0), (0, 0.25), (0.25, 0.25), (0.5, 0.25), (0, 0.5), (0.25, 0.5)}
    got = {tuple(np.round(p[:2], 6)) for p in mesh.nodes[ids]}
    assert got == expected
    assert np.all(mesh.nodes[ids, 2] == 1.0)


def test_nodes_in_polygon_rejects_non_planar_and_short_polygons():
    mesh = box_mesh((1, 1, 1), (2, 2, 2))
    with pytest.raises(PrintError, match="not planar"):
        nodes_in_polygon(mesh, [[0, 0, 1], [1, 0, 1], [1, 1, 1.1], [0, 1, 1]])
    with pytest.raises(PrintError, match="k >= 3"):
        nodes_in_polygon(mesh, [[0, 0, 1], [1, 0, 1]])


def test_a_face_shared_by_three_tets_is_named_as_not_a_manifold():
    nodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0.2, 0.2, 2]]
    mesh = TetMesh(np.array(nodes, float), np.array([[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5]]))
    with pytest.raises(MeshError) as error:
        mesh.surface_triangles
    # The first tet's face opposite its node 3 (outward order 0, 2, 1).
    assert str(error.value) == "face [0, 2, 1] is shared by more than two tets; the mesh is not a manifold solid"


@pytest.mark.parametrize("divisions", [(3, 4, 5), (6, 5, 4)], ids=["3x4x5", "6x5x4"])
def test_box_surface_is_every_boundary_face_once(divisions):
    """A box of nx x ny x nz cells (6 tets each) has 2 triangles per boundary cell
    face, whose areas add up to the box's and whose nodes all lie on its faces."""
    nx, ny, nz = divisions
    size = np.array([1.0, 0.7, 0.4])
    mesh = box_mesh(tuple(size), divisions)
    triangles = mesh.surface_triangles
    assert len(triangles) == 4 * (nx * ny + ny * nz + nz * nx)
    assert len({tuple(sorted(t)) for t in triangles.tolist()}) == len(triangles)
    corners = mesh.nodes[triangles]
    areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    assert areas.sum() == pytest.approx(2 * (size[0] * size[1] + size[1] * size[2] + size[2] * size[0]), rel=1e-12)
    on_a_face = np.isclose(corners, 0.0, atol=1e-12) | np.isclose(corners, size, atol=1e-12)
    assert on_a_face.any(axis=2).all()


def test_two_tets_touching_at_a_node_have_all_eight_faces_on_the_surface():
    """Node ids chosen so that faces (0, 2, 4) and (1, 2, 3) share their middle id and
    the sum of the other two: a face key that is not one-to-one merges them."""
    nodes = np.array([
        [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0],
    ])
    mesh = TetMesh(nodes, [[0, 2, 4, 6], [1, 2, 3, 5]], fix_orientation=True)
    faces = {tuple(sorted(t)) for t in mesh.surface_triangles.tolist()}
    expected = {(0, 2, 4), (0, 2, 6), (0, 4, 6), (2, 4, 6), (1, 2, 3), (1, 2, 5), (1, 3, 5), (2, 3, 5)}
    assert faces == expected and len(mesh.surface_triangles) == 8


def test_surface_search_finds_every_triangle_a_ball_of_radius_r_reaches():
    # Brute force: a triangle within r of x (its nearest corner, for these small triangles a
    # bound from above on the distance) has its centroid within r + the longest edge.
    mesh = box_mesh((0.3, 0.2, 0.1), (6, 5, 3), grading=1.3)
    tree, longest = mesh.surface_search
    corners = mesh.nodes[mesh.surface_triangles]
    edges = np.linalg.norm(corners - corners[:, [1, 2, 0]], axis=2)
    assert longest == pytest.approx(edges.max(), rel=1e-15)
    rng = np.random.default_rng(4)
    for x in rng.uniform([-0.05, -0.05, -0.05], [0.35, 0.25, 0.15], size=(20, 3)):
        r = rng.uniform(0.005, 0.05)
        reached = np.flatnonzero(np.linalg.norm(corners - x, axis=2).min(axis=1) <= r)
        found = set(tree.query_ball_point(x, r + longest))
        assert set(reached.tolist()) <= found
