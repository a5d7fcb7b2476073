"""A robot's drawn meshes in the disk cache (``cbm.robot_mesh``): the same bits as read
from its files, read again without them, and read from the files again when one changes."""

from __future__ import annotations

import numpy as np
import pytest

import stances
from cbm import robot_mesh


@pytest.fixture(scope="module")
def icub():
    return stances.Robot.load("icub")


@pytest.fixture
def cache_directory(tmp_path, monkeypatch):
    """A fresh cache directory, and no meshes kept in the process."""
    monkeypatch.setenv("SOFTCBM_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("SOFTCBM_CACHE", raising=False)
    robot_mesh._load.cache_clear()
    yield tmp_path
    robot_mesh._load.cache_clear()


def _same(a, b):
    assert [m.name for m in a.meshes] == [m.name for m in b.meshes]
    for x, y in zip(a.meshes, b.meshes):
        assert x.joint == y.joint
        assert np.array_equal(x.transform_mesh_to_joint, y.transform_mesh_to_joint)
        assert np.array_equal(x.vertices, y.vertices) and x.vertices.dtype == y.vertices.dtype
        assert np.array_equal(x.triangles, y.triangles) and x.triangles.dtype == y.triangles.dtype


def _files_unread(monkeypatch):
    """Make reading the URDF's visual geometry fail: what is drawn must come from the cache."""
    def unread(*args):
        raise AssertionError("the visual meshes were read from their files")

    monkeypatch.setattr(robot_mesh, "_visual_geometry", unread)


def test_a_robots_meshes_come_back_from_the_disk_cache_bit_for_bit(icub, cache_directory, monkeypatch):
    read = robot_mesh.robot_meshes(icub)
    assert list(cache_directory.rglob(f"{robot_mesh._ENTRY}.entry"))
    robot_mesh._load.cache_clear()  # a new process
    _files_unread(monkeypatch)
    cached = robot_mesh.robot_meshes(icub)
    _same(cached, read)
    # Drawn alike: the posed soup is the same too.
    for x, y in zip(cached.posed(icub.model, icub.reference_configuration), read.posed(icub.model, icub.reference_configuration)):
        assert np.array_equal(x, y)


def test_a_changed_mesh_file_is_read_again(icub, cache_directory, monkeypatch):
    read = robot_mesh.robot_meshes(icub)
    robot_mesh._load.cache_clear()
    stamp = robot_mesh._stamp
    changed = []

    def touched(path):
        # One of the files the entry was read from now has another modification time.
        known = stamp(path)
        if not changed:
            changed.append(path)
            return [known[0], known[1] + 1]
        return known

    monkeypatch.setattr(robot_mesh, "_stamp", touched)
    calls = []
    visual_geometry = robot_mesh._visual_geometry
    monkeypatch.setattr(robot_mesh, "_visual_geometry", lambda *key: calls.append(key) or visual_geometry(*key))
    again = robot_mesh.robot_meshes(icub)
    assert changed and calls, "the entry was used although a mesh file it came from changed"
    _same(again, read)


def test_no_entry_is_written_with_the_cache_off(icub, cache_directory, monkeypatch):
    monkeypatch.setenv("SOFTCBM_CACHE", "off")
    robot_mesh.robot_meshes(icub)
    assert not list(cache_directory.rglob("*.entry"))


def test_an_entry_of_another_cell_size_is_not_read(icub, cache_directory, monkeypatch):
    robot_mesh.robot_meshes(icub)
    robot_mesh._load.cache_clear()
    calls = []
    visual_geometry = robot_mesh._visual_geometry
    monkeypatch.setattr(robot_mesh, "_visual_geometry", lambda *key: calls.append(key) or visual_geometry(*key))
    coarser = robot_mesh.robot_meshes(icub, cell=0.04)
    assert calls and coarser.triangle_count < robot_mesh.robot_meshes(icub).triangle_count
