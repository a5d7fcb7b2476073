"""Plan robots that are not Talos on a scene made of mesh files, and verify every stance.

Issue 10's "done when": a user plans for an example-robot-data robot with an SRDF by
writing a short description file, on a scene of mesh files, some soft, and every stance
of the plan verifies. The scene (``bench/scenes/mesh-files/hyq-mesh-scene.yaml``) is a floor, a
rigid step read from an STL file with ``surfaces: auto`` and a soft foam pad meshed from
a closed STL (``type: soft_mesh``); HyQ is described by the user file
``bench/scenes/mesh-files/robots/hyq.yaml``. ``humanoid-mesh-scene.yaml`` puts the built-in Romeo and iCub on
the same files.

For each plan: its wall time (``cbm.plan``: sampling, search, solves), stances, the check
of the saved plan read back from disk (``Plan.load(...).check()``, what ``cbm check
plan.json`` runs), and, on the robot's full collision meshes from its URDF (not the
convex hulls the solver uses; turned as the description's ``mesh_rotations`` say), the smallest distance between links on every pair the
SRDF enables (the pairs the description ignores included) and from each link to each
scene object (the soft pad at rest: a foot's depth there is its indentation). Writes
``bench/results/mesh_scenes.md``.

Run from the repository root::

    .venv/bin/python bench/bench_mesh_scenes.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

import environments
import stances
from benchmark_info import write_report
from cbm.plan import Plan
from cbm.planner import plan
from stances.description import read_description
from stances.mesh_rotations import turn_meshes
from stances.narrow_phase import scene_shape

SCENES = Path(__file__).resolve().parent / "scenes" / "mesh-files"
RUNS = (
    ("hyq-mesh-scene.yaml", SCENES / "robots" / "hyq.yaml"),
    ("humanoid-mesh-scene.yaml", "romeo"),
    ("humanoid-mesh-scene.yaml", "icub"),
)


def full_mesh_distances(robot_name_or_file, saved: Plan, scenario) -> tuple:
    """Smallest full-mesh distances over the plan's stances, metres.

    Returns
    -------
    (float, str), dict of str to (float, str)
        The closest pair of links (SRDF-enabled pairs) with its stance and names; for
        each scene object, the closest contact geometry (a surface's own) and the
        closest other geometry, as ``{"<object>, feet": (distance, where), ...}``.
    """
    description = read_description(robot_name_or_file)
    robot = stances.Robot.load(robot_name_or_file)
    model = robot.model
    geometry = pin.buildGeomFromUrdf(
        model, str(description.urdf), pin.GeometryType.COLLISION, package_dirs=[str(d) for d in description.package_dirs]
    )
    turn_meshes(model, geometry, description.mesh_rotations)  # where the description turns them (iCub)
    geometry.addAllCollisionPairs()
    pin.removeCollisionPairs(model, geometry, str(description.srdf), False)
    names = [g.name for g in geometry.geometryObjects]
    contact = {name for surface in robot.surfaces.values() for name in surface.contact_geometries}
    objects = {name: scene_shape(name, shape) for name, shape in scenario.scene.collision_objects()}
    data, geometry_data = model.createData(), pin.GeometryData(geometry)
    closest_pair = (np.inf, "")
    closest_object = {}
    for index, planned in enumerate(saved.stances):
        q = np.asarray(planned.q, dtype=float)
        pin.computeDistances(model, data, geometry, geometry_data, q)
        for k, pair in enumerate(geometry.collisionPairs):
            distance = geometry_data.distanceResults[k].min_distance
            if distance < closest_pair[0]:
                closest_pair = (distance, f"stance {index}, {names[pair.first]} - {names[pair.second]}")
        for g, placed in enumerate(geometry_data.oMg):
            kind = "feet/soles" if names[g] in contact or not contact else "other links"
            for object_name, (shape, rotation, translation) in objects.items():
                distance = coal.distance(
                    geometry.geometryObjects[g].geometry, coal.Transform3s(placed.rotation, placed.translation),
                    shape, coal.Transform3s(rotation, translation), coal.DistanceRequest(), coal.DistanceResult(),
                )
                key = f"{object_name}, {kind}"
                if distance < closest_object.get(key, (np.inf,))[0]:
                    closest_object[key] = (distance, f"stance {index}, {names[g]}")
    return closest_pair, closest_object


def run(scene_file: str, robot_name_or_file) -> list:
    scenario = environments.load(SCENES / scene_file)
    robot = stances.Robot.load(robot_name_or_file)
    started = time.perf_counter()
    result = plan(scenario, robot=robot)
    wall = time.perf_counter() - started
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "plan.json"
        result.save(path)
        saved = Plan.load(path)
        check = saved.check(scenario=scenario, robot=robot)
    s = result.statistics
    soft = sum(any(scenario.scene.surfaces[c.contact_print.surface].deformable for c in p.stance.contacts)
               for p in result.stances)
    lines = [
        f"## {scene_file}, robot {Path(str(robot_name_or_file)).name}\n",
        f"- plan: {'found' if result.success else 'not found (' + result.reason + ')'}, {len(result.stances)} stances "
        f"({soft} with a print on the soft pad), {wall:.1f} s wall in `cbm.plan` ({s.expanded} expanded, "
        f"{s.solver_calls} solver calls)",
        "- saved plan read back and checked (`Plan.load(...).check()`): "
        + ("every stance verifies" if check.ok else "; ".join(check.problems)),
    ]
    if result.stances:
        pair, objects = full_mesh_distances(robot_name_or_file, saved, scenario)
        lines.append(f"- full collision meshes (URDF, not hulls), closest link pair on the SRDF's pairs: "
                     f"{1e3 * pair[0]:.1f} mm ({pair[1]})")
        for key, (distance, where) in sorted(objects.items()):
            lines.append(f"- full meshes to {key}: {1e3 * distance:.1f} mm ({where})")
    return lines + [""]


def main():
    started = time.perf_counter()
    lines = []
    for scene_file, robot in RUNS:
        lines += run(scene_file, robot)
    preamble = (
        "`bench/bench_mesh_scenes.py`: `cbm.plan` with its defaults (200 expansions, 300 s) on scenes made of "
        "STL files (`bench/scenes/mesh-files/`, regenerated by `make_meshes.py`): a rigid step with `surfaces: auto`, "
        "a soft foam pad from a closed STL (`type: soft_mesh`, E = 5e5 Pa). A negative distance to the pad is a "
        "foot's indentation into its rest shape. The link pairs are all those the SRDF enables, including the "
        "ones a robot's load leaves unchecked because their hulls touch at the reference posture (iCub's "
        "root_link_0 - torso_1_0 among them)."
    )
    write_report(str(Path(__file__).resolve().parent / "results" / "mesh_scenes.md"),
                 "Plans on a scene of mesh files (issue 10)", started, preamble, lines)


if __name__ == "__main__":
    main()
