"""The SQP's QP subproblems, recorded from real posture solves and replayed offline.

:func:`record` runs ``stances.solve`` with every :class:`stances.qp.QPWorkspace`
call logged: one *sequence* per workspace (a posture solve uses one for its steps and
one for its restoration steps, and a soft stance several solves), in call order, so
that a replay in one workspace sees the QPs in the SQP's order (a policy with warm
starts, such as the old one, starts each from the previous answer).
:func:`replay` solves the sequences again with a *policy* (an object with
``reset()`` and ``solve(data, accuracy, options) -> (x, iterations)``; ``options`` what else
the SQP gave the workspace: its iteration limit and start point, where it gave them), timing each QP in CPU
time (``time.process_time``; the median over repeats), and :func:`quality` compares an
answer with a tight reference solution.
"""

from __future__ import annotations

import time

import numpy as np

import stances
import stances.qp

FIELDS = ("hessian", "gradient", "inequality", "lower", "upper", "box_lower", "box_upper")
_ABSENT = 1e19  # bounds beyond this are the QP builder's stand-in for "no bound"


def record(robot, cases):
    """Solve each case once and return its QPs.

    Parameters
    ----------
    robot : stances.Robot
    cases : list of (name, scene, stance)

    Returns
    -------
    list of dict
        One per QP: ``case``, ``sequence`` (an integer naming the workspace, unique over
        all cases), ``accuracy`` (the absolute accuracy the SQP asked for), ``options``
        (the other keywords it passed: ``max_iterations``, ``start``) and the arrays of
        :data:`FIELDS`.
    """
    qps = []
    original = stances.qp.QPWorkspace.solve
    sequences = []

    def logging_solve(workspace, *data, accuracy=1e-6, **options):
        # Not keyed by id(): a later workspace may reuse a collected one's address.
        if not any(workspace is seen for seen in sequences):
            sequences.append(workspace)
        sequence = next(i for i, seen in enumerate(sequences) if seen is workspace)
        qps.append({"case": current[0], "sequence": sequence, "accuracy": accuracy, "options": dict(options),
                    **{name: np.array(value, float) for name, value in zip(FIELDS, data)}})
        return original(workspace, *data, accuracy=accuracy, **options)

    current = [None]
    stances.qp.QPWorkspace.solve = logging_solve
    try:
        for name, scene, stance in cases:
            current[0] = name
            stances.solve(robot, scene, stance)
    finally:
        stances.qp.QPWorkspace.solve = original
    return qps


def save(path, qps):
    """Write recorded QPs to an ``.npz`` file (arrays named ``<index>_<field>``)."""
    arrays = {}
    for index, qp in enumerate(qps):
        arrays[f"{index}_case"] = np.array(qp["case"])
        arrays[f"{index}_sequence"] = np.array(qp["sequence"])
        arrays[f"{index}_accuracy"] = np.array(qp["accuracy"])
        options = qp.get("options", {})
        arrays[f"{index}_max_iterations"] = np.array(options.get("max_iterations", -1))
        arrays[f"{index}_start"] = np.asarray(options.get("start", np.zeros(0)), dtype=float)
        for name in FIELDS:
            arrays[f"{index}_{name}"] = qp[name]
    np.savez_compressed(path, count=len(qps), **arrays)


def load(path):
    """Read QPs written by :func:`save`."""
    with np.load(path) as data:
        return [
            {"case": str(data[f"{i}_case"]), "sequence": int(data[f"{i}_sequence"]),
             "accuracy": float(data[f"{i}_accuracy"]), "options": _options(data, i),
             **{name: data[f"{i}_{name}"] for name in FIELDS}}
            for i in range(int(data["count"]))
        ]


def _options(data, index):
    """The solve options of recorded QP ``index`` in a loaded ``.npz`` (those it was given)."""
    options = {}
    if int(data.get(f"{index}_max_iterations", -1)) >= 0:
        options["max_iterations"] = int(data[f"{index}_max_iterations"])
    if f"{index}_start" in data and data[f"{index}_start"].size:
        options["start"] = data[f"{index}_start"]
    return options


def data_of(qp):
    """The positional arguments of :meth:`stances.qp.QPWorkspace.solve` for a recorded QP."""
    return tuple(qp[name] for name in FIELDS)


def replay(policy, qps, repeats=5):
    """Solve every recorded QP with ``policy``, sequence by sequence, ``repeats`` times.

    Returns
    -------
    times : (n,) float, seconds of CPU time, the median over repeats of each QP
    iterations : (n,) int, the policy's solver iterations (last repeat)
    answers : list of (m,) float, the step of each QP (last repeat)
    """
    times = np.zeros((repeats, len(qps)))
    iterations = np.zeros(len(qps), int)
    answers = [None] * len(qps)
    for repeat in range(repeats):
        previous = None
        for index, qp in enumerate(qps):
            if qp["sequence"] != previous:
                policy.reset()
                previous = qp["sequence"]
            data = data_of(qp)
            tic = time.process_time()
            x, count = policy.solve(data, qp["accuracy"], qp.get("options", {}))
            times[repeat, index] = time.process_time() - tic
            iterations[index], answers[index] = count, x
    return np.median(times, axis=0), iterations, answers


def objective(qp, x):
    """The QP's objective ``1/2 x^T H x + g^T x`` at ``x``."""
    return 0.5 * x @ qp["hessian"] @ x + qp["gradient"] @ x


def violation(qp, x):
    """Largest violation of the QP's rows and bounds at ``x`` (rows are scaled, so unitless)."""
    rows = qp["inequality"] @ x
    return float(max(
        np.max(rows - qp["upper"], initial=0.0), np.max(qp["lower"] - rows, initial=0.0),
        np.max(x - qp["box_upper"], initial=0.0), np.max(qp["box_lower"] - x, initial=0.0),
    ))


def quality(qp, x, reference):
    """How far an answer is from the reference: (violation, relative objective excess, step distance).

    The objective excess is ``(f(x) - f(reference)) / (1 + |f(reference)|)``, negative when
    ``x`` is better (possible only by violating a little more).
    """
    if x is None or not np.all(np.isfinite(x)):
        return np.inf, np.inf, np.inf
    best = objective(qp, reference)
    return violation(qp, x), (objective(qp, x) - best) / (1.0 + abs(best)), float(np.max(np.abs(x - reference)))


def reference_solution(qp):
    """A tight solution, the yardstick of :func:`quality`: piqp (dense, eps_abs 1e-10), or None without piqp.

    An interior-point method reaches that accuracy in a few dozen iterations where
    proxsuite's augmented Lagrangian crawls (minutes over the recorded QPs).
    """
    try:
        policy = Piqp(sparse=False, accuracy=1e-10)
    except ImportError:
        return None
    return policy.solve(data_of(qp), 1e-10, {})[0]


class LegacyWorkspace(stances.qp.QPWorkspace):
    """:class:`stances.qp.QPWorkspace` as it was before its proxsuite policy was tuned (commit d11d41b).

    Kept here, and only here, as the benchmark's "old policy": proxsuite's automatic
    backend and default cold guess, warm starts with the weights the previous solve
    ended with, proxsuite's first proximal weight on inequalities (0.1) and its full
    Ruiz equilibration (10 iterations); everything else (settings) is the library's.
    """

    backend = "Automatic"
    cold_guess = "EQUALITY_CONSTRAINED_INITIAL_GUESS"
    warm_start = True
    first_proximal_in = 0.1
    preconditioner_iterations = 10  # proxsuite's default (3 since a4541c1)

    def solve(self, *data, start=None, **options):
        """As the library's, but a cold start begins at proxsuite's own guess, not at ``start``
        (the library's elastic QPs start at :func:`stances.qp.elastic_start` since 07c9391)."""
        return super().solve(*data, **options)


class Workspace:
    """A policy that solves each sequence with one workspace (the library's, or another with its interface)."""

    def __init__(self, factory=stances.qp.QPWorkspace, label="proxsuite dense, library policy"):
        self.factory = factory
        self.label = label
        self.workspace = None

    def reset(self):
        self.workspace = self.factory()

    def solve(self, data, accuracy, options):
        x = self.workspace.solve(*data, accuracy=accuracy, **options)
        return x, self.workspace.iterations


class Piqp:
    """piqp, dense or sparse, set up afresh for every QP (an interior-point method has no warm start)."""

    def __init__(self, sparse=False, accuracy=None):
        import piqp

        self.accuracy = accuracy  # when given, replaces the accuracy the SQP asked for

        self.piqp = piqp
        self.sparse = sparse
        self.failures = 0
        self.label = f"piqp {'sparse' if sparse else 'dense'}"

    def reset(self):
        pass

    def solve(self, data, accuracy, options):
        """piqp's answer and iterations (its own iteration limit and start: ``options`` are proxsuite's)."""
        import scipy.sparse

        hessian, gradient, inequality, lower, upper, box_lower, box_upper = data
        # piqp reads infinite bounds as absent; the builder's 1e20 would be a real bound.
        def absent(values):
            return np.where(values >= _ABSENT, np.inf, np.where(values <= -_ABSENT, -np.inf, values))

        if self.sparse:
            solver = self.piqp.SparseSolver()
            matrices = scipy.sparse.csc_matrix(np.triu(hessian)), scipy.sparse.csc_matrix(inequality)
        else:
            solver = self.piqp.DenseSolver()
            matrices = np.asfortranarray(hessian), np.asfortranarray(inequality)
        solver.settings.eps_abs = accuracy if self.accuracy is None else self.accuracy
        solver.settings.eps_rel = 0.0
        solver.settings.verbose = False
        solver.setup(matrices[0], gradient, None, None, matrices[1], absent(lower), absent(upper),
                     absent(box_lower), absent(box_upper))
        status = solver.solve()
        if status != self.piqp.PIQP_SOLVED:
            # Its best iterate is still a step, as with proxsuite at its iteration limit.
            self.failures += 1
        return np.array(solver.result.x), int(solver.result.info.iter)


STANCES = (("hand-on-table", "hand-on-table"), ("stand", "stand"), ("foot-on-block", "foot-on-block"),
           ("step-on-cube", "step-on-cube"), ("cross-soft-block", "both-on-foam"),
           ("cross-two-mats", "one-on-each"))


def policies():
    """The policies of the side-by-side table, and a note on those that are absent."""
    chosen = [Workspace(stances.qp.QPWorkspace, "proxsuite dense, new policy (library)"),
              Workspace(LegacyWorkspace, "proxsuite dense, old policy")]
    try:
        chosen += [Piqp(sparse=False), Piqp(sparse=True)]
        note = ""
    except ImportError:
        note = "piqp is not installed (pip install -e .[bench]): its rows are missing."
    return chosen, note


def table(robot, repeats=5, path="/tmp/softcbm_qps.npz"):
    """Record the QPs of :data:`STANCES`, replay them with every policy, return a markdown table."""
    import environments

    cases = []
    for scenario_name, stance_name in STANCES:
        scenario = environments.load(scenario_name)
        cases.append((f"{scenario_name}/{stance_name}", scenario.scene, scenario.stances[stance_name]))
    for case in cases:  # first solves pay the fem setup and caches, not recorded
        stances.solve(robot, *case[1:])
    qps = record(robot, cases)
    save(path, qps)
    references = [reference_solution(qp) for qp in qps]
    chosen, note = policies()
    rows = ["| QP solver | total iterations | median ms / QP | max ms / QP | total ms | max violation "
            "| median objective excess | max objective excess |", "|---|---|---|---|---|---|---|---|"]
    for policy in chosen:
        times, iterations, answers = replay(policy, qps, repeats)
        if references[0] is not None:
            measures = np.array([quality(qp, x, ref) for qp, x, ref in zip(qps, answers, references)])
            measured = f"{measures[:, 0].max():.1e} | {np.median(measures[:, 1]):.1e} | {measures[:, 1].max():.1e}"
        else:
            measured = f"{max(violation(qp, x) for qp, x in zip(qps, answers)):.1e} | - | -"
        ms = 1e3 * times
        rows.append(f"| {policy.label} | {iterations.sum()} | {np.median(ms):.2f} | {ms.max():.1f} "
                    f"| {ms.sum():.0f} | {measured} |")
    variables = [qp["gradient"].size for qp in qps]
    constraint_rows = [qp["inequality"].shape[0] for qp in qps]
    header = (f"{len(qps)} QPs recorded from `stances.solve` on {', '.join(c[0] for c in cases)} "
              f"(saved to {path}); {min(variables)}-{max(variables)} variables, {min(constraint_rows)}-"
              f"{max(constraint_rows)} rows, plus box bounds. "
              f"CPU time (`time.process_time`), median of {repeats} replays of every QP, each sequence "
              "in one workspace (warm starts where a policy has them). Quality (against piqp at eps_abs 1e-10, when installed): largest row or bound "
              "violation (rows are scaled: 1 = one row scale), objective excess (f - f*) / (1 + |f*|).")
    return "\n".join([header, "", *rows, *([""] + [note] if note else [])])
