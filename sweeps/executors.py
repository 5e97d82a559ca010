"""Executors: where batches of runs are computed. Results never depend on which one, on the number of
workers or on finishing order (each run is a pure function of its spec; tables are sorted by design
index when consolidated).

``execute(batches, executor, workers, scheduler, out_dir)`` yields ``(batch, rows, timeseries)`` as
batches finish:

* ``serial``: in this process, in order (debugging, profiling);
* ``local``: a process pool of ``workers`` on this machine (forked where available, so workers start
  with the compiled kernels already loaded);
* ``dask``: a ``dask.distributed`` Client at ``scheduler`` (e.g. ``tcp://host:8786``), or a
  ``LocalCluster`` of ``workers`` single-threaded processes started here when no address is given.

A batch whose worker dies yields its runs as failed with the reason, so the sweep records them and goes on.
"""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool

from .worker import _base_row, execute_batch

EXECUTORS = ("serial", "local", "dask")


def failed_rows(batch, reason: str) -> list[dict]:
    rows = []
    for spec in batch:
        row = _base_row(spec)
        row.update(status="failed", error=reason, sim_s=float("nan"), wall_s=float("nan"))
        rows.append(row)
    return rows


def _serial(batches, out_dir):
    for batch in batches:
        rows, ts = execute_batch(batch, out_dir)
        yield batch, rows, ts


def _context():
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("fork" if "fork" in methods else "spawn")


def _local(batches, workers, out_dir):
    with ProcessPoolExecutor(max_workers=workers, mp_context=_context()) as pool:
        futures = {pool.submit(execute_batch, batch, out_dir): batch for batch in batches}
        for future in as_completed(futures):
            batch = futures[future]
            try:
                rows, ts = future.result()
            except BrokenProcessPool as err:
                yield batch, failed_rows(batch, f"worker process died: {err}"), None
                continue
            yield batch, rows, ts


def _dask(batches, workers, scheduler, out_dir):
    from dask.distributed import Client, LocalCluster, as_completed as dask_completed

    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    try:
        futures = client.map(execute_batch, batches, out_dir=out_dir, pure=False)
        owner = {f.key: batch for f, batch in zip(futures, batches)}
        for future in dask_completed(futures):
            batch = owner[future.key]
            try:
                rows, ts = future.result()
            except Exception as err:  # a lost worker or a scheduler error: record, go on
                yield batch, failed_rows(batch, f"dask task failed: {type(err).__name__}: {err}"), None
                continue
            yield batch, rows, ts
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def execute(batches, executor: str = "local", workers: int = 2, scheduler: str | None = None, out_dir=None):
    if executor == "serial" or (executor == "local" and workers <= 1):
        return _serial(batches, out_dir)
    if executor == "local":
        return _local(batches, workers, out_dir)
    if executor == "dask":
        return _dask(batches, workers, scheduler, out_dir)
    raise ValueError(f"executor: got {executor!r}; allowed: {', '.join(EXECUTORS)}")
