"""Benchmark of posture solves on deformable supports, against the same stance held rigid.

Run as ``.venv/bin/python bench/bench_deformable.py``; prints markdown tables and writes
them to ``bench/results/deformable.md``.

For each deformable scenario (``hand-on-cube``, ``step-on-cube``, ``hand-on-soft-cube``) at
its default mesh, the main stance is solved with the default options (FEM forces, rigid
warm start) and with ``deformable_as_rigid=True``, then with each reaction model
("consistent", "traction"). Reported per solve:

* setup: loading the scenario and the first ``build_problem`` (mesh, stiffness,
  factorisation, print compliance), paid once per scene and print; excluded from the
  solve times;
* solve: wall clock of ``stances.sqp.solve`` (both SQP phases, problem builds, verify),
  and the split between the rigid warm start and the deformable SQP (their ``solve_time``);
* iterations of the deformable SQP and of the rigid warm start;
* print depth: the largest nodal displacement norm of the body (``result.deformations``);
* the total reaction on the robot surface touching the deformable object;
* FEM share: time inside the deformable contact's methods (``_state``, ``forces``,
  ``force_jacobians``, and separately with ``blocks`` and ``cost``) over the time of
  ``PostureProblem.linearize``, during the deformable SQP only. The methods are wrapped
  with timers by this script (outermost call counted once); nothing in the library changes.
"""

from __future__ import annotations

import datetime
import functools
import os
import sys
import time

# One BLAS thread, set before numpy loads: threaded OpenBLAS spins on the cores other
# processes hold on this shared 2-core machine (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmark_info import code_version, machine  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402
import stances.sqp as sqp  # noqa: E402
from stances.deformable import DeformableContact  # noqa: E402
from stances.problem import PostureOptions, PostureProblem, build_problem  # noqa: E402

SCENARIOS = ("hand-on-cube", "step-on-cube", "hand-on-soft-cube")
REPEATS = 3  # median of this many solves per configuration
TARGET = 0.200  # s per solve


class Timers:
    """Accumulated seconds of wrapped methods, counting only outermost calls."""

    def __init__(self):
        self.enabled = False
        self.depth = {"core": 0, "all": 0, "field": 0}
        self.seconds = {"core": 0.0, "all": 0.0, "linearize": 0.0, "field": 0.0}
        self.calls = {"linearize": 0}

    def reset(self):
        self.seconds = {"core": 0.0, "all": 0.0, "linearize": 0.0, "field": 0.0}
        self.calls = {"linearize": 0}

    def wrap(self, owner, name, groups):
        original = getattr(owner, name)

        @functools.wraps(original)
        def timed(*args, **kwargs):
            if not self.enabled:
                return original(*args, **kwargs)
            outer = [g for g in groups if self.depth[g] == 0]
            for g in groups:
                self.depth[g] += 1
            tic = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - tic
                for g in groups:
                    self.depth[g] -= 1
                for g in outer:
                    self.seconds[g] += elapsed

        setattr(owner, name, timed)

    def install(self):
        for name in ("_state", "forces", "force_jacobians"):
            self.wrap(DeformableContact, name, ("core", "all"))
        for name in ("blocks", "cost"):
            self.wrap(DeformableContact, name, ("all",))
        # The whole-body field for result.deformations, computed after solve_time is taken.
        self.wrap(DeformableContact, "displacement_field", ("field",))
        original = PostureProblem.linearize

        @functools.wraps(original)
        def linearize(problem, *args, **kwargs):
            deformable = any(c.kind == "deformable" for c in problem.contacts)
            if not (self.enabled and deformable):
                return original(problem, *args, **kwargs)
            tic = time.perf_counter()
            try:
                return original(problem, *args, **kwargs)
            finally:
                self.seconds["linearize"] += time.perf_counter() - tic
                self.calls["linearize"] += 1

        PostureProblem.linearize = linearize


TIMERS = Timers()
PHASES = []  # solve_time and iterations of each solve_problem call of the current solve
_solve_problem = sqp.solve_problem


def _recording_solve_problem(problem, *args, **kwargs):
    deformable = any(c.kind == "deformable" for c in problem.contacts)
    TIMERS.enabled = deformable
    try:
        result = _solve_problem(problem, *args, **kwargs)
    finally:
        TIMERS.enabled = False
    PHASES.append(("deformable" if deformable else "rigid", result.solve_time, result.iterations))
    return result


def deformable_contact(scene, stance):
    """(robot surface, object name) of the stance's contact on a deformable surface."""
    for contact in stance:
        surface = scene.surface(contact.contact_print.surface)
        if surface.deformable:
            return contact.robot_surface, scene.deformable_of_surface(surface.name).name
    raise ValueError("the stance touches no deformable surface")


def run(robot, scene, stance, **options):
    """Solve REPEATS times; medians of the timings and the last result's physics."""
    walls, phases, fem = [], [], []
    result = None
    for _ in range(REPEATS):
        PHASES.clear()
        TIMERS.reset()
        tic = time.perf_counter()
        result = sqp.solve(robot, scene, stance, **options)
        walls.append(time.perf_counter() - tic)
        phases.append(list(PHASES))
        fem.append((TIMERS.seconds["core"], TIMERS.seconds["all"], TIMERS.seconds["linearize"],
                    TIMERS.calls["linearize"], TIMERS.seconds["field"]))
    rigid_phase = [sum(t for kind, t, _ in p if kind == "rigid") for p in phases]
    deformable_phase = [sum(t for kind, t, _ in p if kind == "deformable") for p in phases]
    core, every, linearize, calls, field = np.median(np.array(fem), axis=0)
    rest = [w - r - d - f[4] for w, r, d, f in zip(walls, rigid_phase, deformable_phase, fem)]
    return {
        "result": result,
        "wall": float(np.median(walls)),
        "warm_time": float(np.median(rigid_phase)),
        "sqp_time": float(np.median(deformable_phase)),
        "fem_core": core,
        "fem_all": every,
        "linearize": linearize,
        "linearize_calls": int(calls),
        "field": field,
        "rest": float(np.median(rest)),
    }


def physics(robot, result, robot_surface, object_name):
    """(depth mm, print-node max |U_P| component mm, total reaction on the robot surface N)."""
    field = result.deformations.get(object_name)
    depth = float(np.linalg.norm(field, axis=1).max()) * 1e3 if field is not None else 0.0
    measures = result.verification.measures if result.verification is not None else {}
    print_depth = next((1e3 * v for k, v in measures.items() if k.startswith("indentation of")), 0.0)
    frame = robot.surface(robot_surface).frame
    total = np.sum([p.force for p in result.forces_on(frame)], axis=0)
    return depth, print_depth, total


def main():
    sqp.solve_problem = _recording_solve_problem  # sqp.solve calls it by its module name
    TIMERS.install()
    robot = stances.Robot.load("talos")
    main_rows, model_rows, notes = [], [], []
    for name in SCENARIOS:
        tic = time.perf_counter()
        scenario = environments.load(name)
        scene, stance = scenario.scene, scenario.stances[name]
        load_time = time.perf_counter() - tic
        robot_surface, object_name = deformable_contact(scene, stance)
        setup = {}
        for model in ("consistent", "traction"):
            tic = time.perf_counter()
            build_problem(robot, scene, stance, PostureOptions(reaction_model=model))
            setup[model] = time.perf_counter() - tic
        # One untimed solve per scene: first calls of collision and pinocchio routines.
        sqp.solve(robot, scene, stance)

        runs = {
            "consistent": run(robot, scene, stance),
            "traction": run(robot, scene, stance, reaction_model="traction"),
            "rigid": run(robot, scene, stance, deformable_as_rigid=True),
        }
        mesh = scene.deformable(object_name).mesh
        for label, key in (("deformable (consistent, default)", "consistent"), ("same stance, rigid support", "rigid")):
            r = runs[key]
            result = r["result"]
            depth, print_depth, total = physics(robot, result, robot_surface, object_name)
            warm = result.statistics.get("rigid_warm_start_iterations", 0)
            iterations = f"{result.iterations} + {warm} warm" if warm else f"{result.iterations}"
            share = (f"{r['fem_core'] / r['linearize']:.0%} / {r['fem_all'] / r['linearize']:.0%}"
                     if r["linearize"] > 0 else "-")
            per_call = (f"{1e3 * r['fem_all'] / r['linearize_calls']:.2f} vs "
                        f"{1e3 * (r['linearize'] - r['fem_all']) / r['linearize_calls']:.2f}"
                        if r["linearize_calls"] else "-")
            setup_text = f"{1e3 * (load_time + setup['consistent']):.0f}" if key == "consistent" else "-"
            main_rows.append(
                f"| {name} | {label} | {'yes' if result.feasible else 'NO'} | {setup_text} "
                f"| {1e3 * r['wall']:.0f} | {1e3 * r['warm_time']:.0f} / {1e3 * r['sqp_time']:.0f} / "
                f"{1e3 * r['field']:.0f} / {1e3 * r['rest']:.0f} "
                f"| {iterations} | {depth:.1f} | {total[2]:.1f} ({np.linalg.norm(total):.1f}) | {share} | {per_call} |"
            )
            if not result.feasible:
                notes.append(f"- {name}, {label}: {result.reason}")
            elif key == "consistent" and r["wall"] > TARGET:
                notes.append(f"- {name}: deformable solve {1e3 * r['wall']:.0f} ms, over the {1e3 * TARGET:.0f} ms target")
            if key == "consistent" and r["linearize_calls"] and r["fem_all"] > r["linearize"] - r["fem_all"]:
                notes.append(f"- {name}: FEM terms cost more than the rigid-body terms per linearisation ({per_call} ms)")
        for model in ("consistent", "traction"):
            r = runs[model]
            result = r["result"]
            depth, print_depth, total = physics(robot, result, robot_surface, object_name)
            model_rows.append(
                f"| {name} | {model} | {'yes' if result.feasible else 'NO'} | {1e3 * setup[model]:.0f} "
                f"| {1e3 * r['wall']:.0f} | {1e3 * r['sqp_time']:.0f} | {result.iterations} "
                f"| {depth:.1f} | {print_depth:.1f} | {total[2]:.1f} "
                f"| {r['fem_all'] / max(r['linearize'], 1e-12):.0%} |"
            )
            if print_depth > 1e3 * PostureOptions().max_indentation - 0.01:
                notes.append(f"- {name}, {model}: a print node sits on the max_indentation bound "
                             f"({1e3 * PostureOptions().max_indentation:.0f} mm)")
            if not result.feasible and model == "traction":
                notes.append(f"- {name}, traction: {result.reason}")
        notes.append(f"- {name}: mesh of {object_name!r} has {mesh.n_nodes} "
                     f"nodes, {mesh.n_tets} tets; scene load {1e3 * load_time:.0f} ms")
        print(f"done {name}", file=sys.stderr)

    text = f"""# Deformable-support posture benchmark

Date: {datetime.date.today().isoformat()}
Machine: {machine()}
Code: {code_version()}
Scenarios: {", ".join(SCENARIOS)} at their default mesh; times are medians of {REPEATS} solves.

Setup = scenario load + first `build_problem` (stiffness, factorisation, print compliance),
paid once per scene and print, not in the solve times. Solve = wall clock of `stances.sqp.solve`
with default options (problem builds, rigid warm start, deformable SQP, verify); "warm / SQP /
field / rest" splits it (each a median of its own) into the two SQP phases' own `solve_time`, the whole-body displacement
field for `result.deformations` (computed after `solve_time` is taken), and the remainder
(problem builds, collision checker, verify). Depth = largest nodal displacement norm of
the body. Reaction = sum of the point forces on the robot surface touching the deformable object,
z (norm), N. FEM share = time in `DeformableContact._state/forces/force_jacobians` / the same plus
`blocks` and `cost`, over `PostureProblem.linearize` time, deformable SQP only. "FEM vs rest" =
per linearisation, ms, deformable-contact terms vs everything else in `linearize` (kinematics,
static torques, rigid contacts, collisions).

| scenario | support | feasible | setup ms | solve ms | warm / SQP / field / rest ms | iterations | depth mm | reaction N | FEM share | FEM vs rest ms |
|---|---|---|---|---|---|---|---|---|---|---|
{chr(10).join(main_rows)}

Reaction models (default options otherwise):

| scenario | reaction model | feasible | setup ms (build_problem) | solve ms | SQP ms | iterations | depth mm | print indentation mm | reaction z N | FEM share (all terms) |
|---|---|---|---|---|---|---|---|---|---|---|
{chr(10).join(model_rows)}

Targets: each deformable solve under {1e3 * TARGET:.0f} ms; FEM terms no costlier than the
rigid-body terms per iteration.

Notes:

{chr(10).join(notes)}
"""
    print(text)
    out = os.path.join(os.path.dirname(__file__), "results", "deformable.md")
    with open(out, "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    main()
