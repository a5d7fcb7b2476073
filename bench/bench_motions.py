"""Benchmark of the motions between a plan's stances: found, held contacts' strays, cost.

For each scenario (by default the seven built-in ones with a goal and a motion of every
kind: soles, palms, point feet, soft and rigid supports), the plan is made once, then its
motions twice in this process, CPU time of each (``time.process_time``, one BLAS thread):

- baseline: :func:`cbm.motion.plan_motions` with the held-contact bound off
  (``held_drift=1e9``): the motions as they were before strays were checked;
- library: :func:`cbm.motion.plan_motions_reposing`, what ``cbm plan --motion`` runs on
  each plan it makes (strays kept within :data:`cbm.motion.HELD_DRIFT`, a stance whose
  posture its motion cannot reach solved again; :func:`cbm.plan_with_motions` searches
  again only where a motion still fails, which none of the seven plans' does).

For each: motions found, samples (configurations of the found motions), the largest
stray of a held contact between samples (:func:`cbm.motion.held_strays`, millimetres),
the steps over 1 mm, stances reposed, and whether every found motion passes
:func:`cbm.motion.verify_motion` and the plan :meth:`cbm.Plan.check`. Prints a markdown
table and writes it to ``bench/results/motions.md``.

Run from the repository root::

    .venv/bin/python bench/bench_motions.py [scenario ...]
    .venv/bin/python bench/bench_motions.py --replan [scenario ...]

With ``--replan``, each scenario (by default every built-in one with a goal and every
suite scene) goes through :func:`cbm.plan_with_motions`, what ``cbm plan --motion``
runs: searches, steps avoided, motions found, whether every found motion passes
``verify_motion`` and the plan ``Plan.check``, CPU of the whole; written to
``bench/results/motions-replan.md``.
"""

from __future__ import annotations

import os

# One BLAS thread, set before numpy loads (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmark_info import code_version, machine  # noqa: E402

import environments  # noqa: E402
import stances  # noqa: E402
from cbm.motion import held_strays, plan_motions, plan_motions_reposing, verify_motion  # noqa: E402
from cbm.planner import plan as make_plan  # noqa: E402
from cbm.replan import plan_with_motions  # noqa: E402

SCENARIOS = ("cross-soft-block", "climb-with-soft-support", "quadruped-walk", "quadruped-foam",
             "cross-two-mats", "soft-shortcut", "foot-on-block")
UNBOUNDED = 1e9  # metres: a held-contact bound no step reaches
RESULTS = Path(__file__).resolve().parent / "results"


def measure(plan, motions, scenario, robot, seconds):
    """A row's cells for one set of motions of a plan."""
    found = [m for m in motions if m.feasible]
    strays = [d for m in found for _, _, d in held_strays(m, plan, scenario, robot)]
    problems = sum(len(verify_motion(m, plan, scenario, robot)) for m in found)
    return {
        "found": f"{len(found)} of {len(motions)}",
        "samples": sum(len(m.configurations) for m in found),
        "stray": 1e3 * max(strays, default=0.0),
        "over": sum(d > 1e-3 for d in strays),
        "steps": len(strays),
        "reposed": sum(m.reposed for m in motions),
        "verified": "yes" if problems == 0 and plan.check(scenario, robot).ok else f"no ({problems} problems)",
        "cpu": seconds,
    }


def run(name):
    scenario = environments.load(name)
    robot = stances.Robot.load(scenario.robot)
    plan = make_plan(scenario, robot=robot)
    if not plan.success:
        return name, None, None
    tic = time.process_time()
    baseline_plan, baseline = plan_motions(plan, scenario, robot, held_drift=UNBOUNDED)
    baseline_row = measure(baseline_plan, baseline, scenario, robot, time.process_time() - tic)
    tic = time.process_time()
    reposed_plan, motions = plan_motions_reposing(plan, scenario, robot)
    library_row = measure(reposed_plan, motions, scenario, robot, time.process_time() - tic)
    return name, baseline_row, library_row


def table(rows):
    lines = [
        "| scenario | motions found: baseline / library | samples | largest stray, mm | steps over 1 mm "
        "| stances reposed | verified | motion CPU s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, base, lib in rows:
        if base is None:
            lines.append(f"| {name} | no plan | - | - | - | - | - | - |")
            continue
        lines.append(
            f"| {name} | {base['found']} / {lib['found']} | {base['samples']} / {lib['samples']} "
            f"| {base['stray']:.2f} / {lib['stray']:.2f} | {base['over']} of {base['steps']} / {lib['over']} of "
            f"{lib['steps']} | {lib['reposed']} | {base['verified']} / {lib['verified']} "
            f"| {base['cpu']:.1f} / {lib['cpu']:.1f} |"
        )
    return "\n".join(lines)


def main(names):
    rows = []
    for name in names:
        rows.append(run(name))
        print(f"{name}: done", flush=True)
    text = "\n".join([
        f"# Motions between stances ({code_version()})",
        "",
        f"Machine: {machine()}.",
        "",
        "Each cell: baseline (`plan_motions`, held-contact bound off) / library "
        "(`plan_motions_reposing`, what `cbm plan --motion` runs), on the same plan.",
        "",
        table(rows),
        "",
    ])
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "motions.md").write_text(text)


def every_scene():
    """Every built-in scenario with a goal, then every suite scene (``bench/scenes``)."""
    built_in = [n for n in environments.scenario.scenario_names() if environments.load(n).goal is not None]
    suite = sorted(str(p) for p in (Path(__file__).resolve().parent / "scenes").glob("*.yaml"))
    return built_in + suite


def replan_row(name):
    """One scenario through plan_with_motions: a markdown row."""
    scenario = environments.load(name)
    robot = stances.Robot.load(scenario.robot)
    tic = time.process_time()
    moving = plan_with_motions(scenario, robot=robot)
    cpu = time.process_time() - tic
    plan, motions = moving.plan, moving.motions
    label = Path(name).stem
    if not plan.success:
        return f"| {label} | {moving.plans} | - | no plan: {plan.reason[:80]} | - | {cpu:.1f} |"
    found = [m for m in motions if m.feasible]
    problems = sum(len(verify_motion(m, plan, scenario, robot)) for m in found)
    verified = "yes" if problems == 0 and plan.check(scenario, robot).ok else f"no ({problems} problems)"
    avoided = "; ".join(step.move for step in moving.avoided) or "-"
    return f"| {label} | {moving.plans} | {avoided} | {len(found)} of {len(motions)} | {verified} | {cpu:.1f} |"


def main_replan(names):
    lines = [
        f"# Plans with motions (`cbm.plan_with_motions`, {code_version()})",
        "",
        f"Machine: {machine()}.",
        "",
        "| scenario | searches | steps avoided (no motion in an earlier plan) | motions found | verified | CPU s |",
        "|---|---|---|---|---|---|",
    ]
    for name in names:
        lines.append(replan_row(name))
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "motions-replan.md").write_text(text)
    print(text)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--replan"]:
        main_replan(sys.argv[2:] or every_scene())
    else:
        main(sys.argv[1:] or SCENARIOS)
