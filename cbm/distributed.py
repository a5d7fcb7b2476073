"""Many stance checks on a Dask cluster, written as a Parquet dataset.

The same call runs on a laptop (a local cluster of worker processes, started
and stopped here) and on a cluster (``address`` of a running Dask scheduler;
its workers need this package installed, and the robot description files the
checks name). A check carries its scenario's YAML, so workers need no shared
folder for scenarios; each worker process builds a given robot and scene once.

Why Dask distributed rather than Ray, measured on this 2-core machine
(``bench/bench_batch.py``, ``bench/results/batch.md``): a local Dask cluster
started in 1.4-2.5 s, Ray in about 8 s, and their solving throughput was the
same within the noise; Dask installs as 24 MB of pure Python with the
scientific stack's idioms (``Client``, ``LocalCluster``, futures), Ray as a
240 MB binary runtime whose features (actors, object store, autoscaling) these
independent checks do not use.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from .batch import run_check
from .errors import CbmError

__all__ = ["solve_many", "write_dataset", "DATASET_COLUMNS"]

logger = logging.getLogger(__name__)

#: Columns of the dataset, one row per check, in the checks' order.
DATASET_COLUMNS = (
    "id", "scenario", "robot", "stance", "feasible", "reason", "q",
    "force_frames", "force_points", "forces", "solve_time", "check_time",
)


def solve_many(checks, *, address=None, workers=2, solver_options=None, progress=False):
    """Solve and verify many checks on a Dask cluster; answers in the checks' order.

    Parameters
    ----------
    checks : sequence of cbm.batch.Check
        E.g. from :func:`cbm.batch.read_checks`.
    address : str, optional
        A running scheduler, e.g. ``"tcp://10.0.0.5:8786"``. Default: a local
        cluster of ``workers`` processes, one thread each, for this call.
    workers : int
        Processes of the local cluster (ignored with ``address``).
    solver_options : dict, optional
        Keyword arguments of ``stances.solve``, for every check.
    progress : bool
        Log each answer as it arrives (INFO).

    Returns
    -------
    list of cbm.batch.CheckOutcome
        The same answers, bit for bit, as :func:`cbm.batch.run_check` on each
        check one by one (each check is solved cold, independently).

    Raises
    ------
    CbmError
        If ``workers`` is not a positive integer, or Dask distributed is not
        installed (``pip install "softcbm[batch]"``).
    """
    from .parallel import check_workers

    check_workers(workers)
    checks = list(checks)
    if not checks:
        return []
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise CbmError('batch checks run on Dask distributed: pip install "softcbm[batch]"') from None
    options = dict(solver_options or {})
    cluster = None
    if address is None:
        # Processes, not threads: a solve holds the GIL for most of its time.
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        with Client(address if cluster is None else cluster) as client:
            # pure=False: two identical checks are two tasks, each answering its row.
            futures = [client.submit(run_check, check, options, pure=False) for check in checks]
            if progress:
                for done, future in enumerate(as_completed(futures), start=1):
                    logger.info("%d/%d checks answered", done, len(futures))
            return client.gather(futures)
    finally:
        if cluster is not None:
            cluster.close()


def write_dataset(outcomes, folder):
    """Write outcomes as a Parquet dataset: ``folder/checks.parquet``, one row per check.

    Parameters
    ----------
    outcomes : sequence of cbm.batch.CheckOutcome
    folder : path
        Created if missing.

    Returns
    -------
    pathlib.Path
        The file written. Columns: :data:`DATASET_COLUMNS`; ``stance`` is JSON
        text, ``q`` a list of floats (nq), ``force_points`` and ``forces``
        lists of ``[x, y, z]`` (metres, newtons, world frame), times in seconds.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    triples = pa.list_(pa.list_(pa.float64(), 3))
    schema = pa.schema(
        [
            ("id", pa.string()), ("scenario", pa.string()), ("robot", pa.string()), ("stance", pa.string()),
            ("feasible", pa.bool_()), ("reason", pa.string()), ("q", pa.list_(pa.float64())),
            ("force_frames", pa.list_(pa.string())), ("force_points", triples), ("forces", triples),
            ("solve_time", pa.float64()), ("check_time", pa.float64()),
        ]
    )
    columns = {
        "id": [o.id for o in outcomes],
        "scenario": [o.scenario for o in outcomes],
        "robot": [o.robot for o in outcomes],
        "stance": [json.dumps(o.stance, sort_keys=True) for o in outcomes],
        "feasible": [o.feasible for o in outcomes],
        "reason": [o.reason for o in outcomes],
        "q": [o.q.tolist() for o in outcomes],
        "force_frames": [list(o.force_frames) for o in outcomes],
        "force_points": [o.force_points.tolist() for o in outcomes],
        "forces": [o.forces.tolist() for o in outcomes],
        "solve_time": [o.solve_time for o in outcomes],
        "check_time": [o.check_time for o in outcomes],
    }
    path = folder / "checks.parquet"
    pq.write_table(pa.table(columns, schema=schema), path)
    return path
