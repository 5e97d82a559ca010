"""The one executor: where sweeps, calibrations and SBC compute their tasks.

``Executor(kind="serial", workers=None, scheduler=None)`` is a context manager (pools start in
``__enter__``, stop in ``__exit__``; importing this module starts nothing) with two ways to run a
function over items:

* ``map(fn, items) -> list``: ``[fn(item) for item in items]`` in the order of ``items``, whatever order
  the work finishes in; a task's exception is raised here;
* ``as_completed(fn, items)``: an iterator of :class:`Outcome` (index, item, value, error) in the order
  tasks finish; a task that raised or whose worker died is an outcome with ``error`` set (and ``value``
  None), so the caller records it and goes on.

Callers make every task a pure function of its item, so results never depend on the kind of executor,
the number of workers or the finishing order.

Kinds:

* ``serial``: in this process, in order (also ``local`` with one worker);
* ``local``: a pool of ``workers`` processes on this machine (default: all cores), started with
  ``spawn`` (a fresh interpreter: safe after this process has run threaded compiled kernels, where a
  fork is not; each worker loads the kernels from numba's cache). Functions travel with cloudpickle,
  so closures work. Each worker runs compiled threaded kernels on ``cores // workers`` threads and
  exits when the process that started it dies (a watchdog thread waits on the parent's sentinel);
* ``dask``: a ``dask.distributed`` Client at ``scheduler`` (``tcp://host:8786``), or a ``LocalCluster`` of
  ``workers`` single-threaded processes started here when no address is given.
"""
from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any, NamedTuple

EXECUTORS = ("serial", "local", "dask")
START_METHOD = "spawn"


class Outcome(NamedTuple):
    index: int                       # position of the item in the items given
    item: Any
    value: Any                       # the task's result (None when it failed)
    error: BaseException | None      # what went wrong, or None

    @property
    def reason(self) -> str:
        """One line on why the task failed ('' when it did not)."""
        if self.error is None:
            return ""
        if isinstance(self.error, BrokenProcessPool):
            return f"worker process died: {self.error}"
        return f"task failed: {type(self.error).__name__}: {self.error}"


def _watch_parent() -> None:
    """Exit this worker as soon as the process that started it is gone."""
    parent = multiprocessing.parent_process()
    if parent is None:
        return
    from multiprocessing.connection import wait

    def watch():
        wait([parent.sentinel])
        os._exit(3)

    threading.Thread(target=watch, name="parent-watchdog", daemon=True).start()


def _init_worker(threads: int) -> None:
    _watch_parent()
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))


def _call_pickled(payload):
    import cloudpickle

    blob, item = payload
    return cloudpickle.loads(blob)(item)


class Executor:
    """Ordered ``map`` and ``as_completed`` over a kind of executor; see the module docstring."""

    def __init__(self, kind: str = "serial", workers: int | None = None, scheduler: str | None = None):
        if kind not in EXECUTORS:
            raise ValueError(f"executor: got {kind!r}; allowed: {', '.join(EXECUTORS)}")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers: got {workers!r}; expected an integer >= 1")
        if scheduler and kind != "dask":
            raise ValueError("scheduler: only used with executor 'dask'")
        self.kind = kind
        self.workers = workers or os.cpu_count() or 1
        self.scheduler = scheduler
        self._pool = None
        self._client = None
        self._cluster = None

    # -- life cycle ----------------------------------------------------------------------------------
    def __enter__(self) -> "Executor":
        if self.kind == "local" and self.workers > 1:
            threads = max(1, (os.cpu_count() or 1) // self.workers)
            self._pool = ProcessPoolExecutor(max_workers=self.workers,
                                             mp_context=multiprocessing.get_context(START_METHOD),
                                             initializer=_init_worker, initargs=(threads,))
        elif self.kind == "dask":
            from dask.distributed import Client, LocalCluster

            if self.scheduler:
                self._client = Client(self.scheduler)
            else:
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                             dashboard_address=None, silence_logs=40)
                self._client = Client(self._cluster)
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(wait=exc_type is None)

    def close(self, wait: bool = True) -> None:
        """Stop the pool or cluster; ``wait=False`` (after an error) does not wait for running tasks."""
        if self._pool is not None:
            self._pool.shutdown(wait=wait, cancel_futures=True)
            self._pool = None
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    @property
    def in_process(self) -> bool:
        return self._pool is None and self._client is None

    @property
    def description(self) -> str:
        if self.in_process:
            return "serial (this process, threaded batches)"
        if self._pool is not None:
            return f"local ({self.workers} processes)"
        return f"dask ({self.scheduler or f'LocalCluster of {self.workers}'})"

    # -- running -------------------------------------------------------------------------------------
    def map(self, fn: Callable, items: Iterable) -> list:
        """``[fn(item) for item in items]``, in order; the first failing task's exception is raised."""
        items = list(items)
        if len(items) <= 1 or self.in_process:
            return [fn(item) for item in items]
        out = [None] * len(items)
        for outcome in self.as_completed(fn, items):
            if outcome.error is not None:
                raise outcome.error
            out[outcome.index] = outcome.value
        return out

    def as_completed(self, fn: Callable, items: Iterable) -> Iterator[Outcome]:
        """:class:`Outcome` of every task as it finishes; failures are outcomes, never raised."""
        items = list(items)
        if self.in_process:
            yield from self._serial(fn, items)
        elif self._pool is not None:
            yield from self._local(fn, items)
        else:
            yield from self._dask(fn, items)

    def _serial(self, fn, items):
        for index, item in enumerate(items):
            try:
                value = fn(item)
            except Exception as err:  # noqa: BLE001 - reported as the task's outcome
                yield Outcome(index, item, None, err)
                continue
            yield Outcome(index, item, value, None)

    def _local(self, fn, items):
        import cloudpickle

        blob = cloudpickle.dumps(fn)
        futures = {self._pool.submit(_call_pickled, (blob, item)): index for index, item in enumerate(items)}
        try:
            for future in as_completed(futures):
                index = futures[future]
                error = future.exception()
                yield Outcome(index, items[index], None if error else future.result(), error)
        finally:
            for future in futures:
                future.cancel()

    def _dask(self, fn, items):
        from dask.distributed import as_completed as dask_completed

        futures = self._client.map(fn, items, pure=False)
        position = {future.key: index for index, future in enumerate(futures)}
        try:
            for future in dask_completed(futures):
                index = position[future.key]
                try:
                    value = future.result()
                except Exception as err:  # noqa: BLE001 - a lost worker or a scheduler error: an outcome
                    yield Outcome(index, items[index], None, err)
                    continue
                yield Outcome(index, items[index], value, None)
        finally:
            for future in futures:
                future.cancel()
