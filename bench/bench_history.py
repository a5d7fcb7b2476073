"""Benchmark of the contact history: what starting kept soft prints where the stance before left them costs.

Under Coulomb friction a plan's stance starts each soft print it keeps from the stance
before where that answer left its link points (``stances.solve``'s ``history``,
``held_slips``). The baseline is the same solve from rest (``history=None``), the
posture each stance was solved from before the history existed.

Each scene of the planner suite (``bench/bench_suite.py``) with a soft object is planned for a few
seeds; every solve its search made with a history that held slips is then solved again,
with that history and without it, from the same arguments (both after the plan, so
both find the scene's prints set up, the two in turn first). Per scene the table gives the
solves compared, how their verdicts agree (feasible with the history and from rest;
refused with the history only, a stance the history loses; refused from rest only;
refused both ways), their CPU time in all each way, the longest solve each way and how
many took over 1 s (issue 9's bound on a single solve), and the SQP iterations each
way (a count the host's load does not move).

Run from the repository root::

    nice -n 10 .venv/bin/python bench/bench_history.py [--seeds N] [--scenes a,b]

It writes ``bench/results/history.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import cbm
import cbm.planner

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_suite import RESULTS, SCENES, TARGET_LONGEST_SOLVE, load_scene  # noqa: E402
from benchmark_info import code_version, machine  # noqa: E402


def recorded_solves(scenario, seed, time_limit):
    """Plan ``scenario`` with ``seed``: ``(args, kwargs)`` of every posture solve its search
    made with a history whose answer held slips (through ``cbm.planner.posture_api``, where
    the planner looks its solver up; not the plan assembly's re-solves of
    ``cbm.slip_chain.chained``, which call ``stances.solve`` themselves, nor solves in worker
    processes: the plan runs in this one)."""
    solve, verify = cbm.planner.posture_api()
    calls = []

    def recording(*args, **kwargs):
        result = solve(*args, **kwargs)
        if kwargs.get("history") is not None and result.held_slips:
            calls.append((args, kwargs))
        return result

    original = cbm.planner.posture_api
    cbm.planner.posture_api = lambda: (recording, verify)
    try:
        cbm.plan(scenario, robot=None, seed=seed, time_limit=time_limit)
    finally:
        cbm.planner.posture_api = original
    return calls


def timed(solve, args, kwargs):
    """``(answer, CPU seconds, SQP iterations with the warm starts')`` of one solve."""
    cpu = time.process_time()
    result = solve(*args, **kwargs)
    cpu = time.process_time() - cpu
    return result, cpu, result.iterations + result.statistics.get("rigid_warm_start_iterations", 0)


def compare(name, seeds, time_limit):
    """One scene's row: every recorded solve again with its history and from rest (None for a
    scene without soft objects: its plans keep no soft print)."""
    scenario, _ = load_scene(name)
    if not scenario.scene.deformable_objects:
        return None
    solve, _ = cbm.planner.posture_api()
    pairs = []
    for seed in seeds:
        for args, kwargs in recorded_solves(scenario, seed, time_limit):
            ways = (kwargs, {**kwargs, "history": None})
            # In turn first: what the first solve leaves set up (a print's strain set, the
            # factorisations its contact keeps) favours neither way.
            order = (0, 1) if len(pairs) % 2 == 0 else (1, 0)
            answers = {way: timed(solve, args, ways[way]) for way in order}
            pairs.append((answers[0], answers[1]))
    return row(name, tally(pairs))


def tally(pairs):
    """Counts over ``(kept, rest)`` pairs of :func:`timed` answers: ``verdicts`` (Counter of
    (feasible kept, feasible from rest)), and per way (``"kept"``, ``"rest"``) the CPU
    seconds in all, the longest, the solves over 1 s and the SQP iterations."""
    counts = {"verdicts": Counter(), "cpu": Counter(), "longest": Counter(), "slow": Counter(), "iterations": Counter()}
    for kept, rest in pairs:
        counts["verdicts"][(kept[0].feasible, rest[0].feasible)] += 1
        for way, (_, seconds, iterations) in (("kept", kept), ("rest", rest)):
            counts["cpu"][way] += seconds
            counts["longest"][way] = max(counts["longest"][way], seconds)
            counts["slow"][way] += seconds > TARGET_LONGEST_SOLVE
            counts["iterations"][way] += iterations
    return counts


def row(name, counts):
    """A scene's markdown row of :func:`tally`'s counts."""
    verdicts, cpu, longest = counts["verdicts"], counts["cpu"], counts["longest"]
    return (f"| {name} | {sum(verdicts.values())} | {verdicts[(True, True)]} | {verdicts[(False, True)]} "
            f"| {verdicts[(True, False)]} | {verdicts[(False, False)]} | {cpu['kept']:.1f} / {cpu['rest']:.1f} "
            f"| {longest['kept']:.2f} / {longest['rest']:.2f} | {counts['slow']['kept']} / {counts['slow']['rest']} "
            f"| {counts['iterations']['kept']} / {counts['iterations']['rest']} |")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=4, help="seeds 0..N-1 per scene (default 4)")
    parser.add_argument("--scenes", default=",".join(SCENES), help="comma-separated suite scenes (default: all)")
    parser.add_argument("--time-limit", type=float, default=60.0, help="seconds per plan (default 60)")
    parser.add_argument("--out", type=Path, default=RESULTS / "history.md")
    args = parser.parse_args(argv)
    names = [n for n in args.scenes.split(",") if n]
    unknown = sorted(set(names) - set(SCENES))
    if unknown:
        parser.error(f"unknown scenes {unknown}; suite scenes: {', '.join(SCENES)}")
    header = f"`bench/bench_history.py`, {code_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {machine()}."
    rows = [row for row in (compare(name, range(args.seeds), args.time_limit) for name in names) if row is not None]
    text = "\n".join([
        "# Contact history: kept soft prints from where the stance before left them, against from rest",
        "",
        header,
        "",
        f"Every solve that plans of seeds 0-{args.seeds - 1} made with a history holding slips, solved again "
        "after the plan with that history (kept) and without it (rest, the baseline), the two in turn first; "
        "CPU time of this process.",
        "",
        "| scene | solves | feasible both | refused kept only | refused rest only | refused both | CPU s kept / rest "
        f"| longest s kept / rest | over {TARGET_LONGEST_SOLVE:g} s kept / rest | SQP iterations kept / rest |",
        "|---|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
    ])
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
