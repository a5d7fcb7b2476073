"""Fixtures shared by the posture-solver and planner tests."""

from __future__ import annotations

import functools

import pytest

import environments
from stances import Robot


@pytest.fixture(scope="session")
def robot():
    """Talos, loaded once per test session."""
    return Robot.load("talos")


@functools.lru_cache(maxsize=None)
def coarse_scenario(name: str, resolution: str = "0.04", young_modulus: float | None = None):
    """A built-in scenario with its deformable meshes coarsened for fast tests.

    A 4 cm top spacing still seats >= 3 nodes in a palm print, which the
    deformable contact needs, and keeps factorisations to a fraction of a second.
    """
    text = environments.builtin_scenario_path(name).read_text()
    text = text.replace("resolution: default", f"resolution: {resolution}")
    if young_modulus is not None:
        text = text.replace("E: 1.0e+6", f"E: {young_modulus:.6e}").replace("E: 5.0e+5", f"E: {young_modulus:.6e}")
    return environments.load_string(text, name=name)
