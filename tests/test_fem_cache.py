"""Disk cache of a body's stiffness and compliance columns: same bits, robust to bad entries."""

from __future__ import annotations

import logging
import os
import subprocess
import sys

import numpy as np
import pytest

from fem import DeformableBody, LinearElasticMaterial, box_mesh, nodes_in_polygon
from fem.cache import DiskCache, default_cache

MATERIAL = LinearElasticMaterial(1e6, 0.4, 1e3)
SQUARE = [[0.3, 0.3, 1.0], [0.7, 0.3, 1.0], [0.7, 0.7, 1.0], [0.3, 0.7, 1.0]]


@pytest.fixture
def cache(tmp_path):
    """A disk cache in a fresh temporary directory."""
    return DiskCache(tmp_path / "cache")


@pytest.fixture(scope="module")
def mesh():
    return box_mesh((1.0, 1.0, 1.0), (8, 8, 6))


def make_body(mesh, cache, material=MATERIAL, solver="auto"):
    return DeformableBody(mesh, material, mesh.nodes[:, 2] == 0.0, solver=solver, cache=cache)


def outputs(body):
    """Everything the stance pipeline takes from a body for one print, as exact bytes."""
    patch = body.contact_patch(nodes_in_polygon(body.mesh, SQUARE))
    displacements = np.tile([0.002, -0.001, -0.01], (patch.n_nodes, 1))
    forces = patch.reaction_forces(displacements)
    field = body.displacement_under_loads(patch.node_ids, -forces)
    return {
        "forces": forces.tobytes(),
        "traction": patch.reaction_forces(displacements, method="traction").tobytes(),
        "compliance": patch.compliance.tobytes(),
        "strain_map": patch.strain_map.tobytes(),
        "field": field.tobytes(),
        "stiffness": (body.stiffness @ field.ravel()).tobytes(),
    }


@pytest.mark.parametrize("solver", ["cholmod", "scipy"])
def test_a_cached_body_gives_the_same_bits_as_an_uncached_one(mesh, cache, solver):
    if solver == "cholmod":
        import cvxopt.cholmod  # noqa: F401 - a dependency: a broken import fails here, never skips
    uncached = outputs(make_body(mesh, False, solver=solver))
    first = outputs(make_body(mesh, cache, solver=solver))
    warm = make_body(mesh, cache, solver=solver)
    second = outputs(warm)
    assert first == uncached
    assert second == uncached
    # Everything came from the disk: the warm body never factorised.
    assert warm._factor is None


def test_a_warm_body_reads_its_columns_instead_of_solving(mesh, cache):
    ids = nodes_in_polygon(mesh, SQUARE)
    make_body(mesh, cache).compliance_columns(ids)
    names = sorted(path.name for path in cache.path(make_body(mesh, cache).cache_key, "x").parent.iterdir())
    assert names == sorted([f"columns-{node}.entry" for node in ids] + ["stiffness.entry"])
    warm = make_body(mesh, cache)
    assert np.array_equal(warm.compliance_columns(ids), make_body(mesh, False).compliance_columns(ids))
    assert warm._factor is None


def test_the_matrix_of_every_ball_mean_is_kept_and_read_back(mesh, cache):
    """Built at a body's second strain check and stored under the mesh's key; the same
    mesh met again (a planner's next plan, or another material on it: a stiffness sweep)
    reads it at its first check: the same matrix, the same answer."""
    voigt = np.random.default_rng(2).normal(size=(mesh.n_tets, 6))
    cold = make_body(mesh, cache)
    first = cold.strain_averages.largest_principal(voigt, 0.2)  # screened, nothing stored
    assert not cache.path(cold.mesh_key, "ball_means_0.2").exists()
    assert cold.strain_averages.largest_principal(voigt, 0.2) == first  # builds and stores the matrix
    assert cache.path(cold.mesh_key, "ball_means_0.2").exists()
    stiffer = make_body(mesh, cache, LinearElasticMaterial(1e9, 0.3))
    assert stiffer.cache_key != cold.cache_key and stiffer.mesh_key == cold.mesh_key
    warm = stiffer.strain_averages
    assert warm._all_means(0.2)  # found at the first question
    matrix = warm.mean_matrix(0.2)
    built = cold.strain_averages.mean_matrix(0.2)
    assert all(np.array_equal(getattr(matrix, a), getattr(built, a)) for a in ("data", "indices", "indptr"))
    assert warm.largest_principal(voigt, 0.2) == first


def _flip_bytes_inside(path):
    """Invert 100 bytes near the end of the array data."""
    data = bytearray(path.read_bytes())
    data[-400:-300] = bytes(b ^ 0xFF for b in data[-400:-300])
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(
    "damage",
    [
        pytest.param(lambda path: path.write_bytes(b""), id="empty"),
        pytest.param(lambda path: path.write_bytes(path.read_bytes()[: path.stat().st_size // 2]), id="truncated"),
        pytest.param(lambda path: path.write_bytes(b"not a cache entry at all" * 100), id="garbage"),
        pytest.param(_flip_bytes_inside, id="flipped-bytes"),
    ],
)
def test_a_corrupt_cache_file_is_ignored_and_rebuilt(mesh, cache, damage):
    expected = outputs(make_body(mesh, False))
    outputs(make_body(mesh, cache))
    directory = cache.path(make_body(mesh, cache).cache_key, "x").parent
    for path in directory.iterdir():
        damage(path)
    body = make_body(mesh, cache)
    assert outputs(body) == expected
    # Rebuilt: a third body finds good entries again and does not factorise.
    third = make_body(mesh, cache)
    assert outputs(third) == expected
    assert third._factor is None


def test_an_entry_round_trips_its_arrays_exactly_and_any_damage_is_caught(cache):
    arrays = {"columns": np.random.default_rng(2).normal(size=(7, 3)), "node": np.int64(4),
              "indices": np.arange(5, dtype=np.int32)}
    cache.store("0" * 64, "entry", arrays)
    loaded = cache.load("0" * 64, "entry")
    for key, value in arrays.items():
        assert loaded[key].dtype == np.asarray(value).dtype and loaded[key].shape == np.shape(value)
        assert np.array_equal(loaded[key], value) and not loaded[key].flags.writeable
    # Aligned (BLAS may round an unaligned operand otherwise) and read-only views.
    assert all(array.flags.aligned for array in loaded.values())
    # An edited header (its shape no longer matches its bytes): ignored, and removed.
    path = cache.path("0" * 64, "entry")
    original = path.read_bytes()
    path.write_bytes(original.replace(b'"shape": [7, 3]', b'"shape": [9, 3]'))
    assert cache.load("0" * 64, "entry") is None
    assert not path.exists()
    # A bit flipped anywhere never gives other numbers: the CRC-32s of the header and of
    # each array catch it, unless it falls in the alignment padding, which nothing reads.
    caught = 0
    for position in range(0, len(original), 7):
        damaged = bytearray(original)
        damaged[position] ^= 1 << (position % 8)
        path.write_bytes(bytes(damaged))
        again = cache.load("0" * 64, "entry")
        if again is None:
            caught += 1
            continue
        assert again.keys() == arrays.keys(), position
        for key, value in arrays.items():
            assert again[key].dtype == np.asarray(value).dtype and np.array_equal(again[key], value), position
    assert caught > 0.6 * len(range(0, len(original), 7))
    with pytest.raises(TypeError, match="only plain numeric arrays"):
        cache.store("0" * 64, "records", {"x": np.zeros(2, dtype=[("a", float), ("b", int)])})


def test_an_entry_written_for_other_inputs_is_ignored(mesh, cache):
    soft, stiff = make_body(mesh, cache), make_body(mesh, cache, LinearElasticMaterial(1e9, 0.3))
    node = int(nodes_in_polygon(mesh, SQUARE)[0])
    soft.compliance_columns([node])
    # Plant the soft body's entry where the stiff body looks for its own.
    source = cache.path(soft.cache_key, f"columns-{node}")
    target = cache.path(stiff.cache_key, f"columns-{node}")
    target.parent.mkdir(parents=True)
    target.write_bytes(source.read_bytes())
    assert cache.load(stiff.cache_key, f"columns-{node}") is None
    assert np.array_equal(stiff.compliance_columns([node]), make_body(mesh, False, LinearElasticMaterial(1e9, 0.3)).compliance_columns([node]))


def test_the_key_names_mesh_material_and_fixed_set(mesh):
    key = make_body(mesh, False).cache_key
    assert make_body(mesh, False).cache_key == key
    assert make_body(mesh, False, LinearElasticMaterial(1e6, 0.3)).cache_key != key
    assert make_body(mesh, False, LinearElasticMaterial(2e6, 0.4)).cache_key != key
    other_fixed = DeformableBody(mesh, MATERIAL, mesh.nodes[:, 0] == 0.0, cache=False)
    assert other_fixed.cache_key != key
    moved = box_mesh((1.0, 1.0, 1.001), (8, 8, 6))
    assert make_body(moved, False).cache_key != key


def test_the_cache_stays_under_its_size_bound_and_says_when_it_evicts(mesh, tmp_path, caplog):
    column_bytes = 3 * mesh.n_dofs * 8
    small = DiskCache(tmp_path / "small", max_bytes=10 * column_bytes)
    top = np.flatnonzero((mesh.nodes[:, 2] == 1.0))
    with caplog.at_level(logging.WARNING, logger="fem.cache"):
        make_body(mesh, small).compliance_columns(top[:30])
    assert small.size() <= 10 * column_bytes
    # A sweep that fills the bound rebuilds what it evicts inside later solves: said, with the fix.
    said = [r.getMessage() for r in caplog.records if "reached its bound" in r.getMessage()]
    assert said and all("raise SOFTCBM_CACHE_MAX_MB to keep more" in m for m in said)
    # The newest entries are the ones kept.
    assert small.load(make_body(mesh, False).cache_key, f"columns-{top[29]}") is not None


def test_an_unwritable_cache_directory_only_turns_the_cache_off(mesh, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("a file where the cache directory should be")
    body = make_body(mesh, DiskCache(blocker))
    assert outputs(body) == outputs(make_body(mesh, False))


def test_the_environment_sets_the_directory_or_turns_the_cache_off(mesh, tmp_path, monkeypatch):
    monkeypatch.setenv("SOFTCBM_CACHE_DIR", str(tmp_path / "from-env"))
    monkeypatch.delenv("SOFTCBM_CACHE", raising=False)
    body = make_body(mesh, True)
    assert body.disk_cache.directory.parent == tmp_path / "from-env"
    monkeypatch.setenv("SOFTCBM_CACHE", "off")
    assert default_cache() is None
    assert make_body(mesh, True).disk_cache is None


SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from conftest import coarse_scenario, fingerprint
import stances
robot = stances.Robot.load("talos")
scenario = coarse_scenario("step-on-cube")
result = stances.solve(robot, scenario.scene, scenario.stance("step-on-cube"))
factorised = any(o.body._factor is not None for o in scenario.scene.deformable_objects)
print(factorised, *fingerprint(result))
"""


def test_a_soft_stance_is_the_same_without_cache_cold_and_warm(tmp_path):
    code = SCRIPT.format(tests=os.path.dirname(__file__))

    def run(**variables):
        environment = dict(os.environ, SOFTCBM_CACHE_DIR=str(tmp_path / "cache"), **variables)
        output = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300, env=environment
        ).stdout.split()
        return output[1:], output[0]  # (feasible, iterations, hash), factorised

    uncached, uncached_factorised = run(SOFTCBM_CACHE="off")
    cold, cold_factorised = run(SOFTCBM_CACHE="on")
    warm, warm_factorised = run(SOFTCBM_CACHE="on")
    assert uncached[0] == "True"
    assert uncached == cold == warm
    assert (uncached_factorised, cold_factorised, warm_factorised) == ("True", "True", "False")


@pytest.mark.parametrize("index", [-1, "n"], ids=["negative", "past-the-end"])
def test_a_stiffness_entry_with_column_indices_out_of_range_is_rebuilt(mesh, cache, index):
    """A well-formed entry under the right key whose sparse indices point outside the
    matrix (a foreign or tampered file) is not read: K is assembled again."""
    expected = make_body(mesh, False).stiffness
    body = make_body(mesh, cache)
    k = body.stiffness
    indices = k.indices.copy()
    indices[len(indices) // 2] = mesh.n_dofs if index == "n" else index
    cache.store(body.cache_key, "stiffness", {"data": k.data, "indices": indices, "indptr": k.indptr})
    assert cache.load(body.cache_key, "stiffness") is not None  # the entry itself passes the cache's checks
    rebuilt = make_body(mesh, cache).stiffness
    assert rebuilt.shape == expected.shape and (rebuilt != expected).nnz == 0
    assert np.array_equal(rebuilt.indices, expected.indices)


def test_entries_of_an_earlier_format_are_removed_and_later_ones_kept(tmp_path):
    from fem.cache import FORMAT_VERSION

    older, newer = tmp_path / f"fem-v{FORMAT_VERSION - 1}", tmp_path / f"fem-v{FORMAT_VERSION + 1}"
    for directory in (older, newer):
        (directory / ("0" * 64)).mkdir(parents=True)
        (directory / ("0" * 64) / "columns-1.npz").write_bytes(b"x" * 100)
    DiskCache(tmp_path)
    assert not older.exists() and newer.exists()


def test_a_deadline_stops_the_column_solves_and_keeps_what_they_computed(mesh):
    """Within ``fem.deadline``, a print's compliance columns stop once it has passed (a
    SetupTimeout, a FemError, that says what was under way); the columns already solved
    stay, and the next call, without the deadline, gives the same bits as a body never
    stopped."""
    import time

    from fem import SetupTimeout, deadline

    ids = nodes_in_polygon(mesh, SQUARE)
    body = make_body(mesh, False)
    body.compliance_columns(ids[:3])  # solved before the deadline: kept in memory
    with deadline(time.perf_counter() - 1.0), pytest.raises(SetupTimeout) as stopped:
        body.compliance_columns(ids)
    assert str(stopped.value) == (f"the deadline passed during the compliance columns of {ids.size} nodes of a "
                                  "print (3 ready); what was computed is kept for the next call")
    fresh = make_body(mesh, False).compliance_columns(ids)
    with deadline(time.perf_counter() - 1.0):
        assert np.array_equal(body.compliance_columns(ids[:3]), fresh[:, :9])  # no solve: no check
    with deadline(None):
        assert np.array_equal(body.compliance_columns(ids), fresh)
