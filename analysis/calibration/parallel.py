"""Where a calibration's simulations run: in this process, in local worker processes, or on Dask.

``Evaluator(executor="serial", workers=None, scheduler=None)`` is a context manager with one method,
``map(fn, items) -> list``: ``[fn(item) for item in items]``, in the order of ``items`` whatever order
the work finishes in. Callers make every task a pure function of its item (a parameter vector and the
seed key of its simulations), so the results do not depend on the executor or the number of workers:
the same configuration and seed give a bit-identical chain serially, on 2 local processes or on a
cluster.

* ``serial`` (default): in this process. ``simcore.simulate_batch`` already spreads one evaluation's
  replicates over all cores with compiled threads (a local pool of whole evaluations measured 7% faster
  on 2 cores, bench/RESULTS.md).
* ``local``: a pool of ``workers`` processes (default: all cores), spawned (a fresh interpreter that
  loads the cached compiled kernels, about a second at start-up); each worker
  runs its compiled kernels on ``cores // workers`` threads so the pool does not oversubscribe the
  machine. Functions are shipped with cloudpickle, so closures work.
* ``dask``: a ``dask.distributed`` Client at ``scheduler`` (``tcp://host:8786``), or a ``LocalCluster``
  of ``workers`` single-threaded processes when no address is given. This is how a calibration uses a
  cluster: emcee's half-ensemble of proposals (``walkers / 2`` evaluations) runs at once.

Importing this module starts nothing; pools start in ``__enter__`` and stop in ``__exit__``.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

EXECUTORS = ("serial", "local", "dask")


def _context():
    # spawn, not fork: this process has usually run threaded compiled kernels already, and forking a
    # process whose OpenMP runtime has started is unsafe (the child aborts)
    return multiprocessing.get_context("spawn")


def _init_worker(threads: int) -> None:
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))


def _call_pickled(payload):
    import cloudpickle

    blob, item = payload
    return cloudpickle.loads(blob)(item)


class Evaluator:
    """Ordered ``map`` over an executor; see the module docstring."""

    def __init__(self, executor: str = "serial", workers: int | None = None, scheduler: str | None = None):
        if executor not in EXECUTORS:
            raise ValueError(f"executor: got {executor!r}; allowed: {', '.join(EXECUTORS)}")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers: got {workers!r}; expected an integer >= 1")
        if scheduler and executor != "dask":
            raise ValueError("scheduler: only used with executor 'dask'")
        self.executor = executor
        self.workers = workers or os.cpu_count() or 1
        self.scheduler = scheduler
        self._pool = None
        self._client = None
        self._cluster = None

    def __enter__(self) -> "Evaluator":
        if self.executor == "local" and self.workers > 1:
            threads = max(1, (os.cpu_count() or 1) // self.workers)
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=_context(),
                                             initializer=_init_worker, initargs=(threads,))
        elif self.executor == "dask":
            from dask.distributed import Client, LocalCluster

            if self.scheduler:
                self._client = Client(self.scheduler)
            else:
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                             dashboard_address=None, silence_logs=40)
                self._client = Client(self._cluster)
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    @property
    def description(self) -> str:
        if self.executor == "serial" or (self.executor == "local" and self._pool is None):
            return "serial (this process, threaded batches)"
        if self.executor == "local":
            return f"local ({self.workers} processes)"
        return f"dask ({self.scheduler or f'LocalCluster of {self.workers}'})"

    def map(self, fn, items) -> list:
        items = list(items)
        if len(items) <= 1 or (self._pool is None and self._client is None):
            return [fn(item) for item in items]
        if self._pool is not None:
            import cloudpickle

            blob = cloudpickle.dumps(fn)
            return list(self._pool.map(_call_pickled, [(blob, item) for item in items]))
        futures = self._client.map(fn, items, pure=False)
        return self._client.gather(futures)
