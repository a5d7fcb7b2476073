"""Robots the planner loads by name or file: loaded once while their files are unchanged."""

import os
import shutil

import pytest

import stances
from stances.description import BUILTIN_DIRECTORY

import cbm
import cbm.planner
from cbm.planner import load_robot


def test_a_robot_named_twice_is_loaded_once():
    first = load_robot("anymal")
    assert load_robot("anymal") is first
    assert load_robot(BUILTIN_DIRECTORY / "anymal.yaml") is first  # its file names the same robot
    assert first.name == "anymal" and first.model.nv == 18


def test_a_description_changed_on_disk_is_loaded_again(tmp_path):
    path = tmp_path / "my_anymal.yaml"
    shutil.copy(BUILTIN_DIRECTORY / "anymal.yaml", path)
    first = load_robot(path)
    assert load_robot(str(path)) is first
    stamp = os.stat(path).st_mtime_ns
    os.utime(path, ns=(stamp + 10**9, stamp + 10**9))
    second = load_robot(path)
    assert second is not first and second.model.nv == first.model.nv
    assert load_robot(path) is second


def test_an_unknown_robot_is_the_loaders_error():
    with pytest.raises(stances.RobotNotFound, match="unknown robot 'no-such-robot'.*built-in robots: .*talos"):
        load_robot("no-such-robot")


def test_plans_by_name_share_the_loaded_robot(monkeypatch):
    scenario = cbm.load_scenario("quadruped-walk")  # rigid, with a goal
    asked = []

    class Stop(Exception):
        pass

    def recording(source):
        asked.append(source)
        raise Stop

    monkeypatch.setattr(cbm.planner, "load_robot", recording)
    for robot in (None, "talos"):
        with pytest.raises(Stop):
            cbm.plan(scenario, robot=robot)
    assert asked == [scenario.robot, "talos"]
