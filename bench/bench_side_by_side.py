"""The posture solver against an older commit of itself, on the same host, in the same minutes.

The speed targets of issues 8 and 9 are for a quiet host this machine is not, and a host's
speed moves by tens of percent between runs; a ratio to another code timed beside it does
not. This benchmark times ``stances.solve`` (build, solve and final check: what a caller
waits for) of this checkout and of an older one, processes alternating, on

- the 60 random rigid stances of ``bench_posture.py`` (same seed, same draw), and
- the built-in soft stances both checkouts have,

and prints each side's medians and their ratio. With ``--instructions`` it also counts the
instructions the 60 rigid solves execute on each side (valgrind's callgrind, two runs a side:
with the solves and without, the difference theirs): a count does not move with the host's
load, which moved the time ratio by a fifth between rounds of one run (about ten more
minutes). The older checkout runs in its own virtual environment (its dependencies differ:
python-fcl before coal). For the code the issues were filed on::

    git worktree add --detach /tmp/old a83c2c6
    python3 -m venv /tmp/venv_old
    /tmp/venv_old/bin/pip install numpy==2.4.6 scipy==1.17.1 pin==4.1.0 proxsuite==0.8.0 \\
        example-robot-data==6.0.0 cvxopt==1.3.3 gmsh==4.15.2 meshio==5.3.5 networkx==3.6.1 \\
        PyYAML==6.0.4 matplotlib==3.11.2 tqdm==4.70.1 trimesh==5.2.0 python-fcl
    /tmp/venv_old/bin/pip install --no-deps -e /tmp/old
    .venv/bin/python bench/bench_side_by_side.py /tmp/old /tmp/venv_old/bin/python [--rounds 3] [--instructions]

(the versions pinned are this checkout's own, so that only the code differs). Writes
``bench/results/side_by_side.md``. A recent checkout needs no environment of its own: against
85fe6b3, the code measured on the quiet host, ``git worktree add --detach /tmp/old85 85fe6b3``
and ``.venv/bin/python bench/bench_side_by_side.py /tmp/old85 .venv/bin/python --instructions``
(that run is kept as ``bench/results/side_by_side-85fe6b3.md``). With ``--instructions`` it
counts each built-in soft stance's solve too; ``--soft-instructions OLD PYTHON`` counts those
alone (``bench/results/side_by_side_soft_instructions.md``): against 85fe6b3, whose soft
stances were timed on the quiet host (``results/posture-85fe6b3-quiet.md``), each count's
ratio times that time estimates the stance's time there.
"""

from __future__ import annotations

import concurrent.futures
import datetime
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

# One BLAS thread, for this process and the workers it starts (see bench_posture.py).
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SOFT_REPEATS = 3  # a soft stance's time: the least of this many solves, after one that pays its setup
_MARK = "zlib_adler32"  # the C function of zlib.adler32, the soft count worker's mark between solves


def rigid_cases(repository: str):
    """The robot and the 60 rigid stances, with ``repository``'s code, after one solve that
    pays the imports and first-call caches."""
    sys.path[:0] = [repository, os.path.join(repository, "bench")]
    import numpy as np

    import bench_posture
    import stances

    if not os.path.abspath(stances.__file__).startswith(os.path.abspath(repository)):
        raise SystemExit(f"stances was imported from {stances.__file__}, not from {repository}")
    robot = stances.Robot.load("talos")
    cases = bench_posture.random_stances(robot, np.random.default_rng(bench_posture.SEED))
    stances.solve(robot, cases[0][1], cases[0][2])
    return stances, robot, cases


def measure(repository: str) -> dict:
    """CPU seconds of ``stances.solve`` on the rigid and soft stances, with ``repository``'s code.

    Runs in a process of its own (``--worker``): the code measured is imported from
    ``repository`` only.
    """
    stances, robot, cases = rigid_cases(repository)
    import environments

    rigid, verified = [], 0
    for _, scene, stance in cases:
        cpu = time.process_time()
        result = stances.solve(robot, scene, stance)
        rigid.append(time.process_time() - cpu)
        verified += bool(result.feasible)
    soft = {}
    for name, solve in soft_solves(stances, environments, {"talos": robot}):
        times = []
        for _ in range(SOFT_REPEATS):
            cpu = time.process_time()
            result = solve()
            times.append(time.process_time() - cpu)
        soft[name] = (min(times), bool(result.feasible))
    return {"rigid": rigid, "rigid_scenarios": [name for name, _, _ in cases], "rigid_verified": verified,
            "soft": soft}


def soft_solves(stances, environments, robots):
    """``(scenario/stance, solve)`` of every built-in stance with a print on a soft surface,
    each ``solve()`` its ``stances.solve`` call, run once here to pay its setup (mesh,
    factorisation, compliance). The stances as bench_posture.soft_stances finds them, written
    out: the older checkouts' bench_posture (a83c2c6's) has no such function."""
    out = []
    for name in environments.scenario.scenario_names():
        scenario = environments.load(name)
        for stance_name, stance in scenario.stances.items():
            if not any(scenario.scene.surface(c.contact_print.surface).deformable for c in stance):
                continue
            if scenario.robot not in robots:
                robots[scenario.robot] = stances.Robot.load(scenario.robot)
            solve = (lambda r=robots[scenario.robot], s=scenario.scene, st=stance: stances.solve(r, s, st))
            solve()
            out.append((f"{name}/{stance_name}", solve))
    return out


def instructions(python: str, repository: str, solve: bool) -> int:
    """Instructions callgrind counts in a process that sets up the rigid stances (and, with
    ``solve``, solves them once), with ``repository``'s code."""
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "callgrind.out")
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", python,
                        os.path.abspath(__file__), "--count-worker", repository, str(int(solve))],
                       capture_output=True, text=True, check=True, env={**os.environ, "PYTHONHASHSEED": "0"})
        with open(out) as handle:
            summary = next(line for line in handle if line.startswith(("summary:", "totals:")))
    return int(summary.split()[1])


def soft_instructions(python: str, repository: str) -> dict:
    """Instructions callgrind counts in each soft stance's solve (one after the one that
    paid its setup), with ``repository``'s code: scenario/stance -> count.

    The worker (``--soft-count-worker``) calls ``zlib.adler32``, which neither side's code
    calls, between the solves; callgrind dumps its counts before each call, so each dump
    between two marks holds one solve's instructions.
    """
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "callgrind.out")
        completed = subprocess.run(
            ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", f"--dump-before={_MARK}", python,
             os.path.abspath(__file__), "--soft-count-worker", repository],
            capture_output=True, text=True, check=True, env={**os.environ, "PYTHONHASHSEED": "0"})
        names = json.loads(completed.stdout.strip().splitlines()[-1])
        counts = []
        for index in range(2, len(names) + 2):  # dump 1: up to the first mark (the setup)
            with open(f"{out}.{index}") as handle:
                counts.append(int(next(line for line in handle if line.startswith(("summary:", "totals:"))).split()[1]))
        if os.path.exists(f"{out}.{len(names) + 2}"):
            raise RuntimeError(f"more marks than solves in {repository}'s run: something else called {_MARK}")
    return dict(zip(names, counts))


def soft_counts(sides) -> dict:
    """:func:`soft_instructions` of both sides, side -> scenario/stance -> count."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:  # one process a core
        return dict(zip(sides, pool.map(lambda side: soft_instructions(*sides[side]), sides)))


def soft_instruction_rows(counts) -> list:
    """Each soft stance's solve instructions on each side (:func:`soft_counts`), their ratios
    and median, as markdown."""
    common = sorted(set(counts["old"]) & set(counts["new"]))
    ratios = [counts["new"][name] / counts["old"][name] for name in common]
    return ["Instructions of each built-in soft stance's solve (callgrind; `stances.solve` once after the "
            "solve that paid its setup):", "",
            "| soft stance | old (G) | new (G) | ratio |", "|---|---|---|---|",
            *(f"| {name} | {counts['old'][name] / 1e9:.3f} | {counts['new'][name] / 1e9:.3f} | {ratio:.3f} |"
              for name, ratio in zip(common, ratios)),
            "", f"Median ratio over the {len(common)} stances: {statistics.median(ratios):.3f}.", ""]


def instruction_rows(sides) -> list:
    """The instructions of the 60 rigid solves on each side, and their ratio, as markdown."""
    jobs = {(side, solve): (python, repository, solve) for side, (python, repository) in sides.items()
            for solve in (False, True)}
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:  # one process a core
        counts = dict(zip(jobs, pool.map(lambda job: instructions(*job), jobs.values())))
    solves = {side: counts[side, True] - counts[side, False] for side in sides}
    return ["Instructions of the 60 rigid solves (callgrind, `stances.solve` with build and final check; "
            "a run with them less a run with the setup alone):", "",
            "| side | setup alone (G) | with the solves (G) | the solves (G) |", "|---|---|---|---|",
            *(f"| {side} | {counts[side, False] / 1e9:.3f} | {counts[side, True] / 1e9:.3f} | {solves[side] / 1e9:.3f} |"
              for side in sides),
            "", f"Ratio new / old: {solves['new'] / solves['old']:.3f}.", ""]


def commit(path: str) -> str:
    """The short commit of the checkout at ``path``."""
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=path, capture_output=True,
                          text=True, check=True).stdout.strip()


def run_worker(python: str, repository: str) -> dict:
    completed = subprocess.run([python, os.path.abspath(__file__), "--worker", repository],
                               capture_output=True, text=True, check=True)
    return json.loads(completed.stdout.strip().splitlines()[-1])


def main(old_repository: str, old_python: str, rounds: int, count_instructions: bool = False) -> None:
    sys.path.insert(0, HERE)
    import numpy as np

    from benchmark_info import code_version, machine

    sides = {"old": (old_python, old_repository), "new": (sys.executable, ROOT)}
    runs = {"old": [], "new": []}
    for index in range(rounds):
        for side in (("old", "new") if index % 2 == 0 else ("new", "old")):  # alternating
            runs[side].append(run_worker(*sides[side]))
            print(f"round {index + 1}: {side} done", file=sys.stderr, flush=True)
    common = sorted(set(runs["old"][0]["soft"]) & set(runs["new"][0]["soft"]))

    def rigid_median(run):
        return float(np.median(run["rigid"]))

    def soft_median(run):
        return float(np.median([run["soft"][name][0] for name in common]))

    rows = ["| round | old rigid median (ms) | new rigid median (ms) | ratio | old soft median (ms) | "
            "new soft median (ms) | ratio |", "|---|---|---|---|---|---|---|"]
    for index, (old, new) in enumerate(zip(runs["old"], runs["new"])):
        rows.append(f"| {index + 1} | {1e3 * rigid_median(old):.1f} | {1e3 * rigid_median(new):.1f} | "
                    f"{rigid_median(new) / rigid_median(old):.3f} | {1e3 * soft_median(old):.1f} | "
                    f"{1e3 * soft_median(new):.1f} | {soft_median(new) / soft_median(old):.3f} |")
    # Per rigid scenario: each stance's least time over the rounds, then their median.
    per_scenario = ["| rigid scenario | old median CPU ms | new median CPU ms | ratio |", "|---|---|---|---|"]
    least = {side: np.min([run["rigid"] for run in runs[side]], axis=0) for side in runs}
    names = np.array(runs["new"][0]["rigid_scenarios"])
    for scenario in dict.fromkeys(names):
        old, new = (float(np.median(least[side][names == scenario])) for side in ("old", "new"))
        per_scenario.append(f"| {scenario} | {1e3 * old:.1f} | {1e3 * new:.1f} | {new / old:.3f} |")
    per_stance = [f"| soft stance | old CPU ms (least of {rounds * SOFT_REPEATS}) | new CPU ms | ratio |",
                  "|---|---|---|---|"]
    for name in common:
        old = min(run["soft"][name][0] for run in runs["old"])
        new = min(run["soft"][name][0] for run in runs["new"])
        flags = "".join(f" ({side} not verified)" for side in ("old", "new")
                        if not all(run["soft"][name][1] for run in runs[side]))
        per_stance.append(f"| {name}{flags} | {1e3 * old:.1f} | {1e3 * new:.1f} | {new / old:.3f} |")
    verified = {side: [run["rigid_verified"] for run in runs[side]] for side in runs}
    text = "\n".join([
        f"# The posture solver side by side with {commit(old_repository)} ({datetime.date.today()})",
        "",
        f"Machine: {machine()}.",
        f"Code: new {code_version()}, old {commit(old_repository)} ({old_repository}, {old_python}).",
        "",
        f"CPU time of `stances.solve` (build, solve, final check), {rounds} rounds, processes alternating. "
        f"Rigid: the 60 stances of `bench_posture.py`, verified {verified['old']} (old) and {verified['new']} "
        f"(new). Soft: the {len(common)} built-in soft stances both have, each the least of {SOFT_REPEATS} "
        "solves after one that pays its setup.",
        "",
        *rows,
        "",
        *per_scenario,
        "",
        *per_stance,
        "",
        *(instruction_rows(sides) if count_instructions else []),
        *(soft_instruction_rows(soft_counts(sides)) if count_instructions else []),
    ])
    print(text)
    with open(os.path.join(HERE, "results", "side_by_side.md"), "w") as handle:
        handle.write(text)


if __name__ == "__main__":
    arguments = sys.argv[1:]
    if arguments[:1] == ["--worker"]:
        print(json.dumps(measure(arguments[1])))
    elif arguments[:1] == ["--soft-instructions"]:
        # The soft stances' counts alone (two callgrind runs, about 35 minutes on a loaded
        # 2-core host), written to results/side_by_side_soft_instructions.md.
        old_repository, old_python = arguments[1:3]
        sys.path.insert(0, HERE)
        from benchmark_info import code_version, machine

        counts = soft_counts({"old": (old_python, old_repository), "new": (sys.executable, ROOT)})
        old_commit = commit(old_repository)
        text = "\n".join([f"# Soft stances' instructions side by side with {old_commit} ({datetime.date.today()})", "",
                          f"Machine: {machine()}.", f"Code: new {code_version()}, old {old_commit} ({old_repository}).",
                          "", *soft_instruction_rows(counts), "```json", json.dumps(counts), "```", ""])
        print(text)
        with open(os.path.join(HERE, "results", "side_by_side_soft_instructions.md"), "w") as handle:
            handle.write(text)
    elif arguments[:1] == ["--soft-count-worker"]:
        import zlib

        stances, robot, _ = rigid_cases(arguments[1])
        import environments

        solves = soft_solves(stances, environments, {"talos": robot})
        for _, solve in solves:
            zlib.adler32(b"")  # the mark: callgrind dumps before it (see soft_instructions)
            solve()
        zlib.adler32(b"")
        print(json.dumps([name for name, _ in solves]))
    elif arguments[:1] == ["--count-worker"]:
        stances, robot, cases = rigid_cases(arguments[1])
        for _, scene, stance in cases if arguments[2] == "1" else ():
            stances.solve(robot, scene, stance)
    else:
        count = 3
        count_instructions = "--instructions" in arguments
        if count_instructions:
            arguments.remove("--instructions")
        if "--rounds" in arguments:
            at = arguments.index("--rounds")
            count = int(arguments[at + 1])
            del arguments[at : at + 2]
        if len(arguments) != 2:
            raise SystemExit(__doc__)
        main(arguments[0], arguments[1], count, count_instructions)
