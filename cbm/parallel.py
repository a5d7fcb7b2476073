"""Posture checks in worker processes, for a search that solves ahead.

Each worker process builds the robot and the scene once, from a
:class:`WorldRecipe` (the scenario's YAML text and the robot's description
source), then answers stance checks with its own
:class:`~cbm.planner.PostureOracle`: nothing mutable is shared. A check's
answer depends only on the stance and the warm start sent with it, so a
search that consumes the answers in its own order plans the same, bit for
bit, with any number of workers (:func:`cbm.search.best_first_search`'s
``submit``).

Workers are started with the ``spawn`` method: a fresh interpreter, as on
macOS and Windows, never a fork of a process running BLAS or tqdm threads.
A script calling ``cbm.plan(..., workers=2)`` must therefore guard its
top level with ``if __name__ == "__main__":`` (spawned workers import it).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import threading
import time
from dataclasses import dataclass
from typing import Any

from .errors import CbmError

__all__ = ["WorldRecipe", "PosturePool", "check_workers"]

logger = logging.getLogger(__name__)

# This worker process's oracle, made once by _start_worker: process-local, never shared.
_ORACLE = None
# CPU seconds this worker has spent and not yet reported (its start-up, until its first answer).
_UNREPORTED_CPU = 0.0
# Seconds PosturePool.close waits for multiprocessing's terminate before it kills the
# workers itself: a worker killed while it holds the result queue's lock leaves the
# pool's task thread waiting on that lock for good (seen once in CI: the test of one and
# two workers hung in Pool.terminate, both workers already dead).
_TERMINATE_WAIT = 10.0


def check_workers(workers):
    """A validated number of worker processes (int >= 1).

    Raises
    ------
    CbmError
        If ``workers`` is not a positive integer.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise CbmError(f"workers must be a positive integer (1: no worker process), got {workers!r}")
    return workers


@dataclass(frozen=True)
class WorldRecipe:
    """How a worker process builds the robot and the scene again.

    Parameters
    ----------
    scenario_text : str
        The scenario's YAML.
    scenario_path : str or None
        Its file (for relative mesh paths and messages).
    scenario_name : str
    robot_source : str
        ``stances.Robot.load`` argument: a built-in name or a description file.
    """

    scenario_text: str
    scenario_path: str | None
    scenario_name: str
    robot_source: str

    @classmethod
    def of(cls, scenario, robot):
        """The recipe of a scenario loaded from YAML and a robot loaded by ``Robot.load``.

        Raises
        ------
        CbmError
            For a scenario or robot built in code: a worker process could
            not build it again.
        """
        text = getattr(scenario, "text", None)
        source = str(getattr(robot, "source", "") or "")
        if text is None:
            raise CbmError(
                f"workers > 1 needs a scenario read from YAML (a file, a built-in name or "
                f"environments.load_string); scenario {scenario.name!r} was built in code"
            )
        if not source:
            raise CbmError(
                f"workers > 1 needs a robot loaded with stances.Robot.load; robot {robot.name!r} was built in code"
            )
        path = getattr(scenario, "path", None)
        return cls(text, None if path is None else os.fspath(path), scenario.name, source)

    def build(self):
        """``(robot, scene)`` built from the recipe."""
        import environments
        import stances

        scenario = environments.load_string(self.scenario_text, self.scenario_path, self.scenario_name)
        return stances.Robot.load(self.robot_source), scenario.scene


class _WarmStart:
    """The part of a parent's check a posture oracle reads: its result (its posture, the
    warm start, and its prints' slips, the history), without displacement fields."""

    def __init__(self, result):
        self.result = result


def _start_worker(recipe, solver_options, retry_cold, deadline, prefilter=True):
    from .planner import PostureOracle

    # Ctrl-C reaches the whole process group: the planner handles it and ends the pool.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    global _ORACLE, _UNREPORTED_CPU
    try:
        robot, scene = recipe.build()
        _settle_collision_queries(robot, scene)
        _ORACLE = PostureOracle(
            robot, scene, solver_options, retry_cold=retry_cold, deadline=deadline, prefilter=prefilter
        )
    except Exception as error:  # noqa: BLE001 - sent to the planner: a pool restarts a worker whose start raises, forever
        _ORACLE = error
    # Reported with the first answer: building the robot and the scene is the plan's work too.
    _UNREPORTED_CPU = time.process_time()


def _settle_collision_queries(robot, scene):
    """One collision query, so that this process answers like one that has solved before.

    Measured (cross-soft-block, coal 3.0.3): a posture solved as the first
    collision work of a process differs in the last bits (8e-15 in q) from the
    same solve after any other (the answers agree from then on, whatever the
    order). A serial planner's solves after its first run in that state, so a
    worker enters it before its first check. The cause is below ``stances``
    (in the distance queries' state) and is left to be fixed there.
    """
    import pinocchio as pin
    from stances.collision import CollisionChecker

    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, robot.reference_configuration)
    CollisionChecker(robot, scene.collision_objects()).pairs(robot.model, data)


def _check(stance, parent_result):
    """Run in a worker: the oracle's answer, made picklable."""
    from stances.portable import portable

    from .planner import StanceCheck

    global _UNREPORTED_CPU
    if isinstance(_ORACLE, Exception):
        raise CbmError(f"a worker process could not build the robot and scene: {_ORACLE}") from _ORACLE
    started = time.process_time()
    check = _ORACLE(stance, None, None if parent_result is None else _WarmStart(parent_result))
    result = None if check.result is None else portable(check.result)
    answer = StanceCheck(check.feasible, check.reason, result, check.rejected_by, check.bad_input)
    spent, _UNREPORTED_CPU = time.process_time() - started + _UNREPORTED_CPU, 0.0
    return answer, spent


class _Answer:
    """Future of one check: ``result()`` waits for it and restores its displacement fields."""

    def __init__(self, pool, pending):
        self._pool = pool
        self._pending = pending

    def done(self):
        return self._pending.ready()

    def result(self) -> Any:
        from stances.portable import restore_deformations

        check, _ = self._pending.get()
        if check.result is None:
            return check
        result = restore_deformations(self._pool.robot, self._pool.scene, check.result)
        return type(check)(check.feasible, check.reason, result, check.rejected_by)


class PosturePool:
    """Worker processes answering stance checks like a :class:`~cbm.planner.PostureOracle`.

    Parameters
    ----------
    workers : int
        Processes.
    scenario : environments Scenario
        Read from YAML (see :meth:`WorldRecipe.of`).
    robot : stances Robot
        Loaded with ``stances.Robot.load``.
    solver_options : dict, optional
        Keyword arguments of ``stances.solve``.
    retry_cold : bool
        As :class:`~cbm.planner.PostureOracle`'s.
    deadline : float, optional
        ``time.perf_counter()`` value (a system-wide monotonic clock on Linux
        and macOS, so the workers read it as this process does).
    prefilter : bool
        As :class:`~cbm.planner.PostureOracle`'s.

    Attributes
    ----------
    worker_cpu : float
        CPU seconds the workers spent: building the robot and the scene (reported
        with each worker's first answer) and the checks they finished, answers the
        search never used included (a plan's CPU time adds them).

    Notes
    -----
    Use as a context manager: leaving it terminates the workers, even those
    still solving a stance the search no longer needs.
    """

    def __init__(self, workers, scenario, robot, solver_options=None, retry_cold=True, deadline=None, prefilter=True):
        recipe = WorldRecipe.of(scenario, robot)
        self.robot, self.scene = robot, scenario.scene
        self.workers = check_workers(workers)
        self.worker_cpu = 0.0
        self._lock = threading.Lock()  # the pool's result thread adds to worker_cpu
        context = multiprocessing.get_context("spawn")
        self._pool = context.Pool(
            workers, _start_worker, (recipe, dict(solver_options or {}), retry_cold, deadline, prefilter)
        )

    def submit(self, stance, parent=None, parent_check=None):
        """Start checking ``stance``, warm-started from ``parent_check``'s posture, its kept
        prints from where that answer left them.

        Returns
        -------
        future
            ``result()`` gives the :class:`~cbm.planner.StanceCheck`, ``done()``
            whether it is ready.
        """
        from stances.portable import portable

        parent_result = None
        if parent_check is not None and parent_check.result is not None:
            parent_result = portable(parent_check.result)
        return _Answer(self, self._pool.apply_async(_check, (stance, parent_result), callback=self._count))

    def _count(self, answer):
        """Add a finished check's CPU seconds (run in the pool's result thread)."""
        with self._lock:
            self.worker_cpu += answer[1]

    def close(self):
        """Terminate the workers (checks still running are abandoned).

        multiprocessing's terminate runs in a thread of its own; if it has not returned
        within ``_TERMINATE_WAIT`` seconds, the workers are killed and that thread (a
        daemon, as are the pool's own) is left waiting: the planner goes on.
        """
        closer = threading.Thread(target=self._terminate, name="PosturePool.close", daemon=True)
        closer.start()
        closer.join(_TERMINATE_WAIT)
        if closer.is_alive():
            logger.warning("the posture workers did not stop within %g s: killed", _TERMINATE_WAIT)
            for process in list(getattr(self._pool, "_pool", ())):  # the pool's worker processes
                process.kill()

    def _terminate(self):
        self._pool.terminate()
        self._pool.join()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()
