"""Benchmark of posture solves on deformable supports: one and two soft bodies, any stiffness.

Run as ``.venv/bin/python bench/bench_deformable.py``; prints markdown tables and writes
them to ``bench/results/deformable.md``.

Table 1, per built-in soft stance at its default mesh, CPU seconds (``time.process_time``,
one BLAS thread) of ``stances.solve`` with the default model (Coulomb contact at every
print node, rigid then bonded warm starts), the median of ``REPEATS`` solves after a first
one that pays the setup (mesh, factorisation, print compliance); baselines in the same
run: the same stance with the paper's bonded model (``contact_law="bonded"``) and with the
soft supports held rigid (``deformable_as_rigid=True``). This process runs with the fem
disk cache off (``SOFTCBM_CACHE=off``): these columns are the uncached baseline. The setup
columns come from two fresh processes sharing a new, empty cache directory, each loading
the scenario and solving twice: setup = load + first solve - second solve, CPU seconds;
the first process fills the cache (no cache), the second reads it (disk cache), as a
second ``cbm plan`` on the same scene would; then the size of the cache directory.
Each answer is verified
(``result.feasible`` includes :func:`stances.verify`, which loads the full FEM model with
the reported forces and checks Signorini and Coulomb at every node).

Tables 2 to 4, the stiffness sweeps: ``step-on-cube`` and ``hand-on-cube`` with the
cube's Young modulus from 1e4 to 1e11 Pa, against the rigid support: the force of the link
on the soft cube and the posture's distance to the rigid answer; the last with the soles on
a foam mat (a stiff body and a soft one in one stance), against the palm held rigid on the
same soft mat. ``--sweeps`` runs these alone and writes ``bench/results/stiffness.md``.
"""

from __future__ import annotations

import datetime
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

# One BLAS thread, set before numpy loads: threaded OpenBLAS spins on the cores other
# processes hold on this shared 2-core machine (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
# The baseline columns measure the uncached body; the setup processes get their own cache.
os.environ["SOFTCBM_CACHE"] = "off"

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import code_version, machine  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402

STANCES = (
    ("hand-on-cube", "hand-on-cube"),
    ("hand-on-soft-cube", "hand-on-soft-cube"),
    ("step-on-cube", "step-on-cube"),
    ("cross-soft-block", "both-on-foam"),
    ("cross-two-mats", "one-on-each"),
    ("foot-and-hand-on-foam", "foot-and-hand"),
)
REPEATS = 3
STIFFNESS = (1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11)


def timed_solve(robot, scene, stance, **options):
    tic = time.process_time()
    result = stances.solve(robot, scene, stance, **options)
    return time.process_time() - tic, result


SETUP_SCRIPT = """
import sys, time
sys.path.insert(0, {root!r})
import environments, stances
robot = stances.Robot.load("talos")
tic = time.process_time()
scenario = environments.load({name!r})
stances.solve(robot, scenario.scene, scenario.stance({stance!r}))
first = time.process_time() - tic
tic = time.process_time()
stances.solve(robot, scenario.scene, scenario.stance({stance!r}))
print(first - (time.process_time() - tic))
"""


def setup_seconds(name, stance_name):
    """Setup CPU seconds of two fresh processes sharing a new cache, and the cache's size in MB."""
    directory = tempfile.mkdtemp(prefix="softcbm-bench-cache-")
    environment = dict(os.environ, SOFTCBM_CACHE="on", SOFTCBM_CACHE_DIR=directory)
    code = SETUP_SCRIPT.format(root=os.path.join(os.path.dirname(__file__), ".."), name=name, stance=stance_name)
    try:
        seconds = [
            float(subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True,
                                 check=True).stdout.split()[-1])
            for _ in range(2)
        ]
        size = sum(os.path.getsize(os.path.join(folder, f)) for folder, _, files in os.walk(directory) for f in files)
    finally:
        shutil.rmtree(directory, ignore_errors=True)
    return seconds[0], seconds[1], size / 1e6


def soft_forces(robot, result, scene, body=None):
    """Total force on the robot from the links touching a soft body (``body``, or any),
    world frame, newtons."""
    soft = {name for name, surface in scene.surfaces.items()
            if surface.deformable and body in (None, surface.object_name)}
    frames = {robot.surface(c.robot_surface).frame for c in result.stance if c.contact_print.surface in soft}
    return sum((np.array(p.force) for p in result.point_forces if p.frame in frames), np.zeros(3))


def stance_table(robot):
    rows = ["| stance | soft bodies (nodes) | first solve s | setup s: no cache / disk cache (fresh processes) | "
            "cache MB | Coulomb s | iterations (+ warm starts) | verified | "
            "bonded (paper) s | rigid support s | stick / slip / lift nodes |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, stance_name in STANCES:
        scenario = environments.load(name)
        stance = scenario.stance(stance_name)
        nodes = ", ".join(f"{o.name} {o.body.mesh.n_nodes}" for o in scenario.scene.deformable_objects)
        setup, _ = timed_solve(robot, scenario.scene, stance)
        times, results = [], []
        for _ in range(REPEATS):
            seconds, result = timed_solve(robot, scenario.scene, stance)
            times.append(seconds)
            results.append(result)
        bonded = statistics.median(timed_solve(robot, scenario.scene, stance, contact_law="bonded")[0] for _ in range(REPEATS))
        rigid = statistics.median(
            timed_solve(robot, scenario.scene, stance, deformable_as_rigid=True)[0] for _ in range(REPEATS)
        )
        result = results[-1]
        modes = _mode_counts(robot, scenario, stance, result)
        uncached, cached, megabytes = setup_seconds(name, stance_name)
        rows.append(
            f"| {name}/{stance_name} | {nodes} | {setup:.2f} | {uncached:.2f} / {cached:.2f} | {megabytes:.0f} | "
            f"{statistics.median(times):.2f} | "
            f"{result.iterations} (+{result.statistics.get('rigid_warm_start_iterations', 0)}) | "
            f"{'yes' if result.feasible else 'no: ' + result.reason[:60]} | {bonded:.2f} | {rigid:.2f} | {modes} |"
        )
        print(rows[-1], flush=True)
    return rows


def _mode_counts(robot, scenario, stance, result):
    """Node modes of the Coulomb solve at the answer, recomputed from its forces."""
    import pinocchio as pin

    from stances.problem import build_problem

    problem = build_problem(robot, scenario.scene, stance)
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, result.q)
    counts = np.zeros(3, dtype=int)
    for contact, loads in zip(problem.contacts, problem.load_slices):
        if contact.kind == "deformable":
            forces = np.array([p.force for p in result.point_forces[loads]]) @ contact.rotation_body
            field = contact.deformable_object.body.displacement_under_loads(contact.node_ids, -forces)
            # Link point minus its node's coupling end (partly covered nodes stretch their coupling).
            ends = field[contact.node_ids] - (contact.patch.coupling_compliance @ forces.reshape(-1)).reshape(-1, 3)
            relative = np.einsum("pij,pj->pi", contact.node_frames, contact.displacements(robot.model, data) - ends)
            phi = np.einsum("pij,pj->pi", contact.node_frames, forces)
            lift = phi[:, 2] <= 1e-9 * np.abs(phi).max()
            slip = ~lift & (np.abs(relative[:, :2]).max(axis=1) > 1e-7)
            counts += [int((~lift & ~slip).sum()), int(slip.sum()), int(lift.sum())]
    return " / ".join(str(c) for c in counts)


#: Stiffness sweeps: (scenario, stance, what touches the soft cube, the rigid support's
#: options), the cube's E = 1e6 Pa set to each of STIFFNESS. The last has its soles on a foam
#: mat (a stiff body and a soft one in one stance): its rigid support holds the palm rigid and
#: leaves the mat soft.
RIGID = {"deformable_as_rigid": True}
SWEEPS = (("step-on-cube", "step-on-cube", "sole", RIGID),
          ("hand-on-cube", "hand-on-cube", "palm", RIGID),
          (os.path.join(os.path.dirname(__file__), "scenes", "stiffness", "hand-on-cube-from-a-mat.yaml"),
           "hand-on-cube", "palm", {"rigid_prints": ("right_palm",)}))


def scenario_text(name) -> str:
    """A built-in scenario's YAML, or a file's."""
    path = name if os.path.isfile(name) else environments.builtin_scenario_path(name)
    with open(path) as handle:
        return handle.read()


def stiffness_table(robot, name="step-on-cube", stance_name="step-on-cube", soft_link="sole", reference=None):
    text = scenario_text(name)
    name = os.path.splitext(os.path.basename(name))[0]
    base = environments.load_string(text, name=name)
    stance = base.stance(stance_name)
    _, rigid = timed_solve(robot, base.scene, stance, **(reference or RIGID))
    runs = []
    for young_modulus in STIFFNESS:
        # Weightless: at 1e4 Pa a 1,000 kg/m^3 cube cannot hold its own weight within
        # linear elasticity (21 % strain on step-on-cube's) and is refused.
        scenario = environments.load_string(
            text.replace("E: 1.0e+6", f"E: {young_modulus:.1e}").replace("rho: 1.0e+3", "rho: 0.0"), name=name)
        timed_solve(robot, scenario.scene, stance)  # setup
        seconds, result = timed_solve(robot, scenario.scene, stance)
        # The same stance started from the rigid support's posture: where the load's split
        # between several supports barely moves the objective, the SQP's answer depends on
        # where it starts, and a common start separates the model's limit from that spread.
        _, same_start = timed_solve(robot, scenario.scene, stance, q_init=rigid.q)
        runs.append((young_modulus, seconds, result, soft_forces(robot, result, scenario.scene, "cube"),
                     soft_forces(robot, same_start, scenario.scene, "cube") if same_start.feasible else None))
        print(f"{name} E = {young_modulus:.0e}: {result.feasible}, {seconds:.2f} s", flush=True)
    stiffest = runs[-1][3]
    held = soft_forces(robot, rigid, base.scene, "cube")
    rows = [f"| E (Pa) | feasible | stiff limit | CPU s | iterations (+ warm starts) | soft {soft_link} force (N) | "
            "difference to the rigid support | the same from its posture | change to E = 1e11 | "
            "posture vs rigid support (max abs q) | largest strain |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    rows.append(f"| rigid support | {rigid.feasible} | - | - | {rigid.iterations} | {np.round(held, 1).tolist()} | - | - | - | - | - |")
    for young_modulus, seconds, result, force, force_same_start in runs:
        strain = result.verification.measures.get("largest strain of cube", float("nan")) if result.verification else float("nan")
        stiff = "yes" if "stiff_limit" in result.statistics else "no"
        rows.append(
            f"| {young_modulus:.0e} | {result.feasible} | {stiff} | {seconds:.2f} | {result.iterations} "
            f"(+{result.statistics.get('rigid_warm_start_iterations', 0)}) | {np.round(force, 1).tolist()} | "
            f"{np.linalg.norm(force - held) / np.linalg.norm(held):.2%} | "
            f"{'infeasible' if force_same_start is None else format(np.linalg.norm(force_same_start - held) / np.linalg.norm(held), '.2%')} | "
            f"{np.linalg.norm(force - stiffest) / np.linalg.norm(stiffest):.1%} | "
            f"{np.abs(np.array(result.q) - np.array(rigid.q)).max():.2e} | {strain:.3g} |"
        )
    return rows


def main():
    robot = stances.Robot.load("talos")
    header = [
        f"# Deformable supports ({datetime.date.today()}, {code_version()})",
        "",
        f"Machine: {machine()}.",
        "",
        "## Soft stances at the default meshes (CPU seconds, median of "
        f"{REPEATS} solves after a first one that pays the setup)",
        "",
    ]
    print("\n".join(header), flush=True)
    sweeps_only = "--sweeps" in sys.argv[1:]
    rows = [] if sweeps_only else stance_table(robot)
    sweeps = []
    for name, stance_name, soft_link, reference in SWEEPS:
        mat = ", the soles on a 5 cm foam mat at 1e6 Pa (the rigid support: the palm held rigid, the mat soft)"
        sweep_header = ["", f"## Stiffness sweep ({os.path.splitext(os.path.basename(name))[0]}: the {soft_link} on "
                        f"the soft cube, weightless: rho = 0{'' if reference is RIGID else mat})", ""]
        print("\n".join(sweep_header), flush=True)
        sweeps += sweep_header + stiffness_table(robot, name, stance_name, soft_link, reference)
    text = "\n".join(header + rows + sweeps) + "\n"
    path = os.path.join(os.path.dirname(__file__), "results", "stiffness.md" if sweeps_only else "deformable.md")
    with open(path, "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    main()
