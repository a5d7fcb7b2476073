"""Fixtures shared by the posture-solver and planner tests."""

from __future__ import annotations

import functools
import importlib.util
import os
import shutil
import tempfile
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

import environments
from stances import Robot
from stances.narrow_phase import DistanceQuery, scene_shape


_CACHE_DIRECTORY = None


def sphere(radius, center):
    """A ball scene object of ``radius`` at ``center``, metres, world frame (a coal object)."""
    return coal.CollisionObject(coal.Sphere(float(radius)), coal.Transform3s(np.eye(3), np.asarray(center, dtype=float)))


def scene_distance(a, b) -> float:
    """Signed distance, metres, between two placed scene objects, measured as the
    posture solver measures them (``stances.narrow_phase``)."""
    placed = [scene_shape(name, shape) for name, shape in (("a", a), ("b", b))]
    return DistanceQuery().distance(*(item for s, r, t in placed for item in (s, coal.Transform3s(r, t))))


def pytest_configure(config):
    """Point the fem disk cache at a fresh directory for this run (inherited by subprocesses).

    So tests never read or fill the user's cache, and run as on a fresh machine. Under
    pytest-xdist the controller makes the directory and its workers, which inherit it,
    share it: the cache writes each entry atomically, and a body one worker factorised the
    other reads.
    """
    global _CACHE_DIRECTORY
    if os.environ.get("PYTEST_XDIST_WORKER") and os.environ.get("SOFTCBM_TEST_CACHE_DIR"):
        os.environ["SOFTCBM_CACHE_DIR"] = os.environ["SOFTCBM_TEST_CACHE_DIR"]
        return
    _CACHE_DIRECTORY = tempfile.mkdtemp(prefix="softcbm-test-cache-")
    os.environ["SOFTCBM_CACHE_DIR"] = os.environ["SOFTCBM_TEST_CACHE_DIR"] = _CACHE_DIRECTORY


def pytest_unconfigure(config):
    """Remove this run's cache directory (the process that made it)."""
    if _CACHE_DIRECTORY is not None:
        shutil.rmtree(_CACHE_DIRECTORY, ignore_errors=True)


@pytest.fixture(scope="session")
def robot():
    """Talos, loaded once per test session."""
    return Robot.load("talos")


@pytest.fixture(scope="session")
def anymal():
    """ANYmal, the built-in quadruped with ball feet, loaded once per test session."""
    return Robot.load("anymal")


@pytest.fixture(scope="session")
def walk():
    """The scenario quadruped-walk (rigid floor and step), loaded once per test session."""
    return environments.load("quadruped-walk")


@functools.lru_cache(maxsize=None)
def coarse_scenario(name: str, resolution: str = "0.04", young_modulus: float | None = None,
                    density: float | None = None):
    """A built-in scenario with its deformable meshes coarsened for fast tests.

    A 4 cm top spacing still seats >= 3 nodes in a palm print, which the
    deformable contact needs, and keeps factorisations to a fraction of a second; its
    soft boxes accept prints on any number of cells (``minimum_print_cells: 0``).
    ``young_modulus`` and ``density`` (kg/m^3) replace the soft objects' E and rho.
    """
    text = environments.builtin_scenario_path(name).read_text()
    text = text.replace("resolution: default", f"resolution: {resolution}")
    # At 4 cm Romeo's and iCub's palms cover about 3 cells, under a soft box's minimum
    # (environments.DEFAULT_MINIMUM_PRINT_CELLS): accepted here, where speed matters and
    # forces are checked against the tests' own expectations, not a converged mesh.
    if "minimum_print_cells" not in text:  # (hand-on-coarse-cube's sets it already)
        text = text.replace("    type: soft_box\n", "    type: soft_box\n    minimum_print_cells: 0\n")
    if young_modulus is not None:
        text = text.replace("E: 1.0e+6", f"E: {young_modulus:.6e}").replace("E: 5.0e+5", f"E: {young_modulus:.6e}")
    if density is not None:
        text = text.replace("rho: 1.0e+3", f"rho: {density:.6e}").replace("rho: 100.0", f"rho: {density:.6e}")
    return environments.load_string(text, name=name)


BENCH = Path(__file__).resolve().parents[1] / "bench"


def bench_module(name: str):
    """The benchmark script ``bench/<name>.py``, imported as a module (bench/ is no package)."""
    spec = importlib.util.spec_from_file_location(name, BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def solved_stance(robot, scenario, stance: str, **options):
    """``stances.solve`` of one of ``scenario``'s stances, asserted feasible (its reason shown if not)."""
    import stances

    result = stances.solve(robot, scenario.scene, scenario.stance(stance), **options)
    assert result.feasible, result.reason
    return result


def fingerprint(result) -> tuple:
    """(feasible, iterations, SHA-1 of q and the forces' bits) of a posture result:
    equal fingerprints mean the same answer bit for bit."""
    import hashlib

    import numpy as np

    forces = np.array([p.force for p in result.point_forces])
    return result.feasible, result.iterations, hashlib.sha1(np.asarray(result.q).tobytes() + forces.tobytes()).hexdigest()


# A hand-made biped for planner tests without kinematics: Talos's sole and palm
# rectangles, legs 0.8 m long from hips 0.2 m apart, shoulders 1.35 m above the
# feet and 0.4 m apart, arms reaching 0.65 m once the extension ratio applies.
SOLE = ((-0.10, -0.065), (0.11, -0.065), (0.11, 0.065), (-0.10, 0.065))
PALM = ((-0.05, -0.035), (0.05, -0.035), (0.05, 0.035), (-0.05, 0.035))
LEG, ARM_REACH = 0.8, 0.65


def hand_made_biped():
    """``(surfaces, reach)``: RobotSurface by name and the matching cbm ReachModel."""
    import numpy as np

    from cbm.reach import LimbReach, ReachLimits, ReachModel
    from stances.robot import RobotSurface

    limbs = {"left_sole": "left_leg", "right_sole": "right_leg", "left_palm": "left_arm", "right_palm": "right_arm"}
    surfaces = {
        name: RobotSurface(
            name, f"{name}_contact", SOLE if "sole" in name else PALM, role="foot" if "sole" in name else "hand", limb=limb
        )
        for name, limb in limbs.items()
    }
    extension = ReachLimits().limb_extension
    reach = ReachModel(
        roles={name: surface.role for name, surface in surfaces.items()},
        limbs_of=limbs,
        limbs={
            "left_leg": LimbReach("left_leg", np.array([0.0, 0.1, LEG]), LEG),
            "right_leg": LimbReach("right_leg", np.array([0.0, -0.1, LEG]), LEG),
            "left_arm": LimbReach("left_arm", np.array([0.0, 0.2, 1.35]), ARM_REACH / extension),
            "right_arm": LimbReach("right_arm", np.array([0.0, -0.2, 1.35]), ARM_REACH / extension),
        },
        foot_size=np.array([0.21, 0.13]),
    )
    return surfaces, reach


def assert_point_feet_are_their_spheres(robot):
    """Each point foot's only contact geometry is a sphere of the foot's radius centred on its contact frame."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.reference_configuration)
    geometry_data = robot.collision_model.createData()
    pin.updateGeometryPlacements(robot.model, data, robot.collision_model, geometry_data)
    names = [g.name for g in robot.collision_model.geometryObjects]
    for surface in robot.surfaces.values():
        assert surface.is_point
        (sphere,) = surface.contact_geometries
        index = names.index(sphere)
        assert robot.collision_model.geometryObjects[index].geometry.radius == pytest.approx(surface.radius, abs=1e-12)
        centre = data.oMf[robot.frame_id(surface.frame)].translation
        np.testing.assert_allclose(geometry_data.oMg[index].translation, centre, atol=1e-9)
