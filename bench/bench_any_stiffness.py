"""Benchmark: every built-in soft stance from a foam to harder than steel, against the rigid support.

Run as ``.venv/bin/python bench/bench_any_stiffness.py [--moduli 1e5,1e6,...]``; prints a
markdown table and writes it to ``bench/results/any_stiffness.md``.

Issue 8.5 asks that from E = 1e4 to 1e11 Pa the solve converge and that, as E grows, the
forces tend to the rigid support's (within 2 % at 1e10); this sweeps 1e5 to 1e12, the
largest modulus accepted (``fem.MAX_YOUNG_MODULUS``). For each built-in scenario and each stance of it
with a print on a soft body, every soft object's Young modulus is set to each value of
``MODULI`` (its density to 0: at 1e5 Pa a foam would strain under its own weight), and
``stances.solve`` answers with its defaults on the default meshes. The baseline, in the
same run: the same stance with every soft object made rigid (``environments.rigid_twin``).
Each cell is the relative difference of one link's total force on the soft body (the sum
of its point forces, world frame) to that link's force on the rigid twin; ``SL`` marks an
answer of the stiff limit (``statistics["stiff_limit"]``); a refused stance shows the
start of its reason. A second table gives the CPU seconds (``time.process_time``, one BLAS
thread) of a third solve at each modulus, after two that pay the setup (mesh,
factorisation, compliance, the strain's ball means: the fem disk cache as configured).
"""

from __future__ import annotations

import argparse
import datetime
import os
import re
import sys
import time

# One BLAS thread, set before numpy loads (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import code_version, machine  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402

MODULI = (1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 2e11, 1e12)
OUT = os.path.join(os.path.dirname(__file__), "results", "any_stiffness.md")


def with_modulus(text: str, young_modulus: float) -> str:
    """A scenario's YAML with every soft object's E set to ``young_modulus`` and its density to 0."""
    text = re.sub(r"(\bE:\s*)[-+0-9.eE]+", lambda m: f"{m.group(1)}{young_modulus:.3e}", text)
    return re.sub(r"(\brho:\s*)[-+0-9.eE]+", lambda m: f"{m.group(1)}0.0", text)


def check_modulus(scenario, young_modulus: float) -> None:
    """Raise if a soft object of ``scenario`` did not take ``young_modulus`` (a YAML that spells
    its material otherwise than ``with_modulus`` reads would be measured at its own E)."""
    for obj in scenario.scene.deformable_objects:
        if obj.body.material.young_modulus != float(f"{young_modulus:.3e}"):
            raise RuntimeError(f"{scenario.name}: {obj.name} kept E = {obj.body.material.young_modulus:g} Pa")


def link_forces(robot, scene, result) -> dict:
    """Each link's total force on a soft body, world frame, newtons: link -> (3,)."""
    soft = {name for name, surface in scene.surfaces.items() if surface.deformable}
    forces = {}
    for contact in result.stance:
        if contact.contact_print.surface in soft:
            frame = robot.surface(contact.robot_surface).frame
            forces[contact.robot_surface] = sum(
                (np.asarray(p.force) for p in result.point_forces if p.frame == frame), np.zeros(3))
    return forces


def soft_stances():
    """(scenario name, its YAML, stance name) of every built-in stance with a print on a soft body."""
    for name in environments.scenario_names():
        scenario = environments.load(name)
        soft = {n for n, surface in scenario.scene.surfaces.items() if surface.deformable}
        for stance_name, stance in scenario.stances.items():
            if any(c.contact_print.surface in soft for c in stance):
                yield name, environments.builtin_scenario_path(name).read_text(), stance_name


def timed(robot, scene, stance):
    """CPU seconds of one ``stances.solve`` with its defaults, and its answer."""
    start = time.process_time()
    result = stances.solve(robot, scene, stance)
    return time.process_time() - start, result


def difference(robot, scene, result, rigid_forces, link) -> float:
    """Relative difference of ``link``'s force on the soft body in ``result`` to the rigid twin's."""
    force = link_forces(robot, scene, result)[link]
    return float(np.linalg.norm(force - rigid_forces[link]) / np.linalg.norm(rigid_forces[link]))


def cell(robot, scene, result, rigid_forces, link) -> str:
    """A table cell: the difference (``SL`` for a stiff-limit answer), or the start of the refusal's reason."""
    if not result.feasible:
        return "refused: " + result.reason.split(" (")[0][:60]
    stiff = " SL" if result.statistics.get("stiff_limit") else ""
    return f"{difference(robot, scene, result, rigid_forces, link):.2%}{stiff}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--moduli", default=",".join(f"{m:g}" for m in MODULI), help="Young moduli, Pa, comma-separated")
    parser.add_argument("--out", default=OUT)
    args = parser.parse_args()
    moduli = [float(m) for m in args.moduli.split(",")]
    header = f"`bench/bench_any_stiffness.py`, {code_version()}, {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; {machine()}."
    heads = " | ".join(f"{m:.0e}" for m in moduli)
    forces = [f"| scenario / stance | link | {heads} |", "|---|---|" + "---|" * len(moduli)]
    times = [f"| scenario / stance | rigid twin | {heads} |", "|---|---|" + "---|" * len(moduli)]
    robots, worst, refused = {}, {}, 0
    for name, text, stance_name in soft_stances():
        base = environments.load_string(text, name=name)
        robot = robots.setdefault(base.robot, stances.Robot.load(base.robot))
        twin = environments.rigid_twin(base)
        rigid_seconds, rigid = timed(robot, twin.scene, twin.stance(stance_name))
        rigid_forces = link_forces(robot, base.scene, rigid)  # the twin's surfaces keep the soft ones' names
        answers = []
        for young_modulus in moduli:
            scenario = environments.load_string(with_modulus(text, young_modulus), name=name)
            check_modulus(scenario, young_modulus)
            stance = scenario.stance(stance_name)
            for _ in range(2):  # setup; the second builds a body's strain ball-mean matrix (fem.strain_average)
                timed(robot, scenario.scene, stance)
            answers.append((scenario.scene, *timed(robot, scenario.scene, stance)))
            print(f"{name} / {stance_name} E = {young_modulus:.0e}: {answers[-1][2].feasible}", flush=True)
        for link in rigid_forces:
            forces.append(f"| {name} / {stance_name} | {link} | "
                          + " | ".join(cell(robot, scene, result, rigid_forces, link) for scene, _, result in answers) + " |")
            for young_modulus, (scene, _, result) in zip(moduli, answers):
                if result.feasible and young_modulus >= 1e10:
                    worst[young_modulus] = max(worst.get(young_modulus, (0.0, "")),
                                               (difference(robot, scene, result, rigid_forces, link),
                                                f"{name} / {stance_name} {link}"))
        refused += sum(not result.feasible for _, _, result in answers)
        times.append(f"| {name} / {stance_name} | {rigid_seconds:.3f} | " + " | ".join(f"{s:.3f}" for _, s, _ in answers) + " |")
    summary = [f"- E = {m:.0e} Pa: the largest difference {d:.2%} ({where})" for m, (d, where) in sorted(worst.items())]
    text = "\n".join(
        ["# Every built-in soft stance at any stiffness (issue 8.5)", "", header, "",
         "Relative difference of each link's force on the soft body to the rigid twin's (SL: the stiff limit's answer):",
         "", *forces, "", f"Stances refused (stance and modulus): {refused}.", "", *summary, "",
         "CPU seconds of a third solve (the first two paid the setup):", "", *times, ""])
    print(text)
    with open(args.out, "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    main()
