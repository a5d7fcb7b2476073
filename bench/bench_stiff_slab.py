"""A robot leaning on a steel-stiff soft slab, wherever its mesh lies (issue 8, item 5).

Run as ``.venv/bin/python bench/bench_stiff_slab.py [--fine]``; prints a markdown table and
writes it to ``bench/results/stiff_slab.md``.

Talos stands with both soles on a 0.8 x 1.0 x 0.2 m slab of E = 1e10 Pa (weightless, its
base held), its centre of mass held ahead of the soles' centres by a row of the caller's
(``stances.CentreOfMassBounds``), so that the soles' centres of pressure move toward
their toes: at 0.11 m they reach the toe edge (x = 0.11 m in the sole's frame), the tipping
limit, which the rigid support holds with all the load on the toes' corners and no support of
finite stiffness holds (the soft answer refuses it: a held print's centre of pressure stays
inside its outline; until session r a row of partly covered nodes past the toes let it be
accepted at two grid placements, which an independent audit found wrong). Each stance is solved on the slab held rigid (the baseline, in the
same run) and soft (the default options: the stiff limit, :mod:`stances.stages`), with the
slab's grid lines moved under the soles by 0, 1/4, 1/2 and 3/4 of a cell (the soles stay
where they are in the world), since where the node rows fall under a sole's toe sets how far
forward its nodes carry a load. Columns: whether each answer is feasible (the soft one
verified on the full FEM model), whether the soft one came from the stiff limit, its CPU
seconds, the largest difference of a sole's normal load to the rigid support's (relative),
and the reason of a refusal. ``--fine``: the same stances near the toes on a 10 mm mesh under
the soles (its setup takes about a minute the first time, then it is cached).
"""

from __future__ import annotations

import datetime
import os
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

CELL = 0.0225  # m, the default spacing where prints land
SHIFTS = (0.0, 0.25, 0.5, 0.75)  # of a cell, the grid moved under the soles
AHEAD = (0.05, 0.08, 0.095, 0.101, 0.105, 0.11)  # m, the centre of mass ahead of the soles' centres
FINE_AHEAD = (0.101, 0.105, 0.11)
TOE_EDGE = 0.11  # m, the centre of mass this far ahead puts the soles' centres of pressure on their toe edges
TIME_BUDGET = 60.0  # s, a soft solve's

SLAB = """
robot: talos
objects:
  - {{name: floor, type: floor}}
  - name: slab
    type: soft_box
    size: [0.8, 1.0, 0.2]
    center: [{dx}, {dy}, 0.1]
    material: {{E: 1.0e+10, nu: 0.3, rho: 0.0}}
    strain_limit: 0.3
    resolution: {resolution}
    refine: {refine}
stances:
  stand:
    left_sole: {{surface: slab_top, x: {sx}, y: {left}}}
    right_sole: {{surface: slab_top, x: {sx}, y: {right}}}
"""


def slab(shift, resolution="default", refine="[[-0.3, -0.3], [0.3, 0.3]]"):
    """The scenario with the slab's grid moved by ``shift`` cells (x, and 0.6 of it along y)."""
    dx, dy = shift * CELL, 0.6 * shift * CELL
    text = SLAB.format(dx=dx, dy=dy, sx=-dx, left=0.09 - dy, right=-0.09 - dy, resolution=resolution, refine=refine)
    return environments.load_string(text, name=f"stiff-slab-{shift}")


def sole_loads(result) -> np.ndarray:
    """Each sole's normal load, newtons, world z, by contact frame name."""
    frames = sorted({p.frame for p in result.point_forces})
    return np.array([sum(p.force[2] for p in result.point_forces if p.frame == f) for f in frames])


def run(robot, scenario, ahead_values, label):
    stance = scenario.stance("stand")
    stances.solve(robot, scenario.scene, stance)  # pays the setup
    # Stances the rigid support holds and of those solved soft: inside the toe edge, and on it.
    rows, counts = [], np.zeros(4, dtype=int)
    for ahead in ahead_values:
        extra = [stances.CentreOfMassBounds(lower=(ahead, -np.inf, -np.inf), label="ahead")]
        rigid = stances.solve(robot, scenario.scene, stance, constraints=extra, deformable_as_rigid=True)
        tic = time.process_time()
        soft = stances.solve(robot, scenario.scene, stance, constraints=extra, time_budget=TIME_BUDGET)
        cpu = time.process_time() - tic
        difference = ""
        if soft.feasible and rigid.feasible:
            a, b = sole_loads(soft), sole_loads(rigid)
            difference = f"{np.abs(a - b).max() / np.abs(b).max():.1e}"
        reason = soft.reason[:110].replace("|", "/") + ("..." if len(soft.reason) > 110 else "")
        rows.append(f"| {label} | {ahead:.3f} | {'yes' if rigid.feasible else 'no'} | {'yes' if soft.feasible else 'no'} "
                    f"| {'yes' if soft.statistics.get('stiff_limit') else 'no'} | {cpu:.2f} | {difference} | {reason} |")
        print(rows[-1], flush=True)
        edge = 2 * (ahead >= TOE_EDGE)
        counts[edge : edge + 2] += [rigid.feasible, rigid.feasible and soft.feasible]
    return rows, counts


def main():
    fine = "--fine" in sys.argv
    robot = stances.Robot.load("talos")
    header = ["| mesh under the soles | centre of mass ahead (m) | rigid support | soft, verified | stiff limit "
              "| soft CPU s | sole loads vs rigid | soft refusal's reason |", "|---|---|---|---|---|---|---|---|"]
    print("\n".join(header))
    rows, counts = [], np.zeros(4, dtype=int)
    cases = [(slab(shift), AHEAD, f"22.5 mm, moved {shift:g} cell") for shift in SHIFTS]
    if fine:
        cases.append((slab(0.0, resolution=0.011, refine="[[-0.16, -0.2], [0.16, 0.2]]"), FINE_AHEAD, "11 mm"))
    for scenario, ahead_values, label in cases:
        more, counted = run(robot, scenario, ahead_values, label)
        rows, counts = rows + more, counts + counted
    summary = (f"Solved soft where the rigid support holds: {counts[1]} of {counts[0]} with the soles' centres "
               f"of pressure inside their toe edges, {counts[3]} of {counts[2]} on them (the tipping limit).")
    text = "\n".join([
        "# A robot leaning on a steel-stiff slab, wherever its mesh lies",
        "",
        f"Date: {datetime.date.today().isoformat()}",
        f"Machine: {machine()}",
        f"Code: {code_version()}",
        "",
        __doc__.split("\n\n", 1)[1].strip(),
        "",
        *header, *rows,
        "",
        summary,
    ])
    out = os.path.join(os.path.dirname(__file__), "results", "stiff_slab.md")
    with open(out, "w") as handle:
        handle.write(text + "\n")
    print(f"\n{summary} Written to {out}")


if __name__ == "__main__":
    main()
