"""The one executor: where sweeps, calibrations and SBC compute their tasks.

``Executor(kind="serial", workers=None, scheduler=None, preload=(), cluster=None)`` is a context manager (pools start in
``__enter__``, stop in ``__exit__``; importing this module starts nothing) with two ways to run a
function over items:

* ``map(fn, items, tick=None) -> list``: ``[fn(item) for item in items]`` in the order of ``items``,
  whatever order the work finishes in; a task's exception is raised here; ``tick()`` is called as each
  task finishes (a progress bar's ``update``);
* ``as_completed(fn, items, idle=None)``: an iterator of :class:`Outcome` (index, item, value, error) in
  the order tasks finish; a task that raised is an outcome with ``error`` set (and ``value`` None), so the
  caller records it and goes on. With ``idle`` (seconds) the iterator also yields ``None``, a heartbeat
  meaning "nothing finished yet, and the executor may keep you waiting": local and dask yield one after
  every ``idle`` seconds without a finished task, serial one before each task (it computes in the
  caller's thread). Callers use it to save finished work on time.

Callers make every task a pure function of its item, so results never depend on the kind of executor,
the number of workers or the finishing order.

Kinds:

* ``serial``: in this process, in order (also ``local`` with one worker);
* ``local``: a pool of ``workers`` processes on this machine (default: all cores), started with
  ``spawn`` (a fresh interpreter: safe after this process has run threaded compiled kernels, where a
  fork is not; each worker loads the kernels from numba's cache). Functions travel with cloudpickle,
  so closures work. Each worker runs compiled threaded kernels on ``cores // workers`` threads, ignores
  SIGINT (Ctrl-C is the parent's to handle: it stops the pool) and exits when the process that started
  it dies (a watchdog thread waits on the parent's sentinel). At most ``workers`` tasks are in flight.
  A pool starts its workers as tasks come, unless ``preload`` names modules: then every worker starts in
  ``__enter__`` and imports them (an entry ``"module:function"`` also calls that function), while the
  caller prepares its tasks (a sweep's workers import ``sweeps.worker`` and call its ``prepare``, about
  1 s, while the sweep is read and designed). A worker whose loop has ended
  exits once multiprocessing's own exit steps are done (finalizers, streams flushed), without the
  interpreter's teardown of numpy, pandas and numba, which the pool's shutdown would wait for;
* ``dask``: a ``dask.distributed`` Client at ``scheduler`` (``tcp://host:8786``; a scheduler that does
  not answer within :data:`CONNECT_TIMEOUT` seconds is :class:`SchedulerUnreachable`), or a
  ``LocalCluster`` of ``workers`` single-threaded processes started here when no address is given.
  Its processes start with SIGINT ignored (:func:`_workers_ignore_sigint`: Ctrl-C is this process's to
  handle, and one pressed while the cluster starts is raised once it is whole, so it is closed whole,
  never lost); their logs are silenced (a task's error reaches the caller as its outcome), and so are
  this process's distributed loggers while an interrupted cluster is closed.
* ``cluster``: a ``dask.distributed`` Client on a batch-scheduled cluster (SLURM, PBS, SGE, LSF): the
  workers are batch jobs that ``cluster`` (a :class:`sweeps.cluster.ClusterSettings`) describes,
  submitted in ``__enter__`` and cancelled when the executor closes (:mod:`sweeps.cluster`); tasks run
  as with ``dask``, and ``workers`` is the jobs' worker processes in all.

Lost workers are an infrastructure fault, never a task's failure. When a local worker dies (killed,
out of memory, a crash in compiled code), the pool is restarted and the tasks it was running are run
again, each alone, so a task that kills its worker is singled out; a task whose worker died
:data:`MAX_ATTEMPTS` times is an outcome whose error is :class:`WorkerLost` (``map`` raises it). Dask
retries tasks of lost workers itself; its ``KilledWorker`` becomes :class:`WorkerLost` too.

The pool's queues hold named semaphores that multiprocessing's resource tracker (a helper process)
unlinks if this process dies. When the tracker itself is killed, the next use of it starts a new one
(with a warning) which does not know those names and prints a ``KeyError`` traceback for each one
later released: so before every start, turn and stop of the pool the executor checks the tracker, and
when it died starts a new one quietly and registers the live names with it again (the semaphores stay
tracked, nothing is printed).

``close(wait=False)`` (also on leaving the ``with`` block by an exception, e.g. Ctrl-C) kills the
workers at once instead of waiting for their tasks.
"""
from __future__ import annotations

import contextlib
import importlib
import logging
import multiprocessing
import multiprocessing.context
import multiprocessing.util
import os
import signal
import sys
import threading
import time
import warnings
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, NamedTuple

from .interrupts import deferred, raise_if_received
from . import main_guard

EXECUTORS = ("serial", "local", "dask", "cluster")
START_METHOD = "spawn"
MAX_ATTEMPTS = 3        # runs of a task whose worker died before it is given up as lost
CONNECT_TIMEOUT = 10.0  # seconds to reach a dask scheduler


class WorkerLost(RuntimeError):
    """A task's worker process died while running it (``attempts`` times): an infrastructure fault."""

    def __init__(self, message: str, attempts: int = 1):
        super().__init__(message)
        self.attempts = attempts

    def __reduce__(self):
        return type(self), (str(self), self.attempts)


class SchedulerUnreachable(ConnectionError):
    """No dask scheduler answered at the address given."""


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
        if isinstance(self.error, WorkerLost):
            return f"worker process died: {self.error}"
        return f"task failed: {type(self.error).__name__}: {self.error}"


def _watch_parent() -> None:
    """Exit this worker as soon as the process that started it is gone."""
    parent = multiprocessing.parent_process()
    if parent is None:
        return
    from multiprocessing.connection import wait as wait_for

    def watch():
        wait_for([parent.sentinel])
        os._exit(3)

    threading.Thread(target=watch, name="parent-watchdog", daemon=True).start()


@contextmanager
def _sigint_blocked():
    """Block SIGINT in this thread while worker processes are started: they inherit the blocked mask, so
    a Ctrl-C during their start-up waits until ``_init_worker`` ignores it (here it is delivered on exit).
    The mask covers this thread only: a thread started earlier (tqdm's monitor) may still take the signal
    and Python then raises in the main thread, so submissions also run under ``interrupts.deferred``,
    which holds the interrupt until the new worker has been handed its start-up data."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


IMMUNE_PYTHON = """#!/bin/sh
# flocksweep: start a dask worker process with SIGINT ignored (Ctrl-C is its parent's to handle)
trap '' INT
exec "$FLOCKSWEEP_PYTHON" "$@"
"""


@contextmanager
def _workers_ignore_sigint():
    """Inside the block, processes started by multiprocessing's spawn (dask's workers and nannies) begin
    with SIGINT ignored: their interpreter is started through a two-line shell script that ignores it and
    execs Python, so a Ctrl-C to the process group (the terminal's) never reaches them, whether
    half-started, running or restarted after a death; stopping them is the parent's to do. This process
    keeps its own handlers, so nothing pressed meanwhile is lost."""
    import tempfile
    from multiprocessing import spawn

    python = spawn.get_executable()
    with tempfile.TemporaryDirectory(prefix="flocksweep-") as folder:
        script = os.path.join(folder, "python")
        with open(script, "w") as out:
            out.write(IMMUNE_PYTHON)
        os.chmod(script, 0o700)
        os.environ["FLOCKSWEEP_PYTHON"] = os.fsdecode(python)
        spawn.set_executable(script)
        try:
            yield
        finally:
            spawn.set_executable(python)


@contextmanager
def _quiet_distributed():
    """dask.distributed's loggers in this process silenced (an interrupted shutdown makes them log
    "Stream is closed" errors of connections being closed on purpose)."""
    logger = logging.getLogger("distributed")
    before = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        logger.setLevel(before)


def _semaphore_names() -> list[str]:
    """The names of the named semaphores alive in this process (a process pool's or dask's queues)."""
    import gc
    import weakref
    from multiprocessing.synchronize import SemLock

    names = []
    for part in gc.get_objects():
        if isinstance(part, weakref.ProxyTypes):   # a proxy passes isinstance, its object may be gone
            continue
        if isinstance(part, SemLock) and getattr(part, "_semlock", None) is not None and part._semlock.name:
            names.append(part._semlock.name)
    return names


def _mend_every_relaunch(tracker) -> None:
    """Make ``tracker`` (this process's resource tracker) register the live resources again whenever it
    relaunches a dead tracker process, quietly, whoever asked for it: multiprocessing relaunches it itself
    when a semaphore is created or released after the kill (between two calls of
    :func:`mend_resource_tracker`), and the new process would print a KeyError traceback for each name it
    is later told to release. The live names are those this process registered and has not released (its
    messages to the tracker are followed from here on; the semaphores alive now seed them), so a name
    released by a finalizer after its object is gone is known too. Installed once per process (instance
    attributes over the methods)."""
    if getattr(tracker, "_flocksweep_mended", False):
        return
    live = {(name, "semaphore") for name in _semaphore_names()}
    relaunch, send = tracker.ensure_running, tracker._send

    def ensure_running():
        before = tracker._pid
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # "resource_tracker: process died unexpectedly, relaunching"
            relaunch()
        if before is not None and tracker._pid not in (None, before):   # relaunched just now
            for name, rtype in sorted(live):
                send("REGISTER", name, rtype)

    def followed_send(cmd, name, rtype):
        send(cmd, name, rtype)   # first: a relaunch on the way re-registers the name it then releases
        if cmd == "REGISTER":
            live.add((name, rtype))
        elif cmd == "UNREGISTER":
            live.discard((name, rtype))

    tracker.ensure_running, tracker._send = ensure_running, followed_send
    tracker._flocksweep_mended = True


def mend_resource_tracker() -> bool:
    """Restart multiprocessing's resource tracker if it died, quietly, and register this process's named
    semaphores with the new one (else it prints a KeyError traceback for each name released later). True
    when it had died. A tracker never started (no spawn-context semaphore yet) is left alone."""
    from multiprocessing import resource_tracker

    tracker = resource_tracker._resource_tracker
    _mend_every_relaunch(tracker)
    if getattr(tracker, "_fd", None) is None or tracker._check_alive():
        return False
    tracker.ensure_running()   # relaunched quietly, the live names registered again (above)
    return True


class _QuickExitProcess(multiprocessing.context.SpawnProcess):
    """A pool worker that, once its loop has ended normally, finishes as multiprocessing would (its
    finalizers, the standard streams flushed) and exits without the interpreter's teardown of numpy,
    pandas and numba (0.3-0.5 s that the pool's shutdown would wait for; bench/RESULTS.md)."""

    def run(self):
        super().run()
        multiprocessing.util._exit_function()
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):
                stream.flush()
        os._exit(0)


class _QuickExitContext(multiprocessing.context.SpawnContext):
    Process = _QuickExitProcess


def _pool_context():
    return _QuickExitContext() if START_METHOD == "spawn" else multiprocessing.get_context(START_METHOD)


def _started() -> None:
    """The task that makes a pool start a worker (:attr:`Executor.preload`)."""


def _init_worker(threads: int, preload: tuple[str, ...] = ()) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C reaches the whole process group: the parent handles it
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    _watch_parent()
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    for entry in preload:   # "module" or "module:function" (then called)
        name, _, function = entry.partition(":")
        module = importlib.import_module(name)
        if function:
            getattr(module, function)()


def _call_pickled(payload):
    import cloudpickle

    blob, item = payload
    return cloudpickle.loads(blob)(item)


def describe_exit(statuses: list[int]) -> str:
    """'exit status 1', 'killed by SIGKILL', ... of dead workers (``Process.exitcode``: -N is signal N)."""
    words = []
    for status in sorted(set(statuses)):
        if status < 0:
            try:
                words.append(f"killed by {signal.Signals(-status).name}")
            except ValueError:
                words.append(f"killed by signal {-status}")
        else:
            words.append(f"exit status {status}")
    return "worker " + ", ".join(words) if words else "worker exit status unknown"


def _is_lost_worker(error: BaseException) -> bool:
    """A dask error that means the task's worker went away (not the task's own exception)."""
    return type(error).__name__ in ("KilledWorker", "FutureCancelledError") or isinstance(error, BrokenProcessPool)


def _local_cluster(workers: int):
    """A dask LocalCluster of ``workers`` single-threaded processes; a worker process that dies while it
    starts (killed, out of memory) fails the whole start ("Nanny failed to start"), which is tried again
    (:data:`MAX_ATTEMPTS` times in all) before it is :class:`WorkerLost`."""
    from dask.distributed import LocalCluster

    for attempt in range(1, MAX_ATTEMPTS + 1):
        try:
            with _quiet_distributed():
                return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                    dashboard_address=None, silence_logs=logging.CRITICAL)
        except RuntimeError as err:   # the cluster closes what it had started before raising
            if attempt == MAX_ATTEMPTS:
                raise WorkerLost(f"dask's workers died while the cluster started, {attempt} times ({err})",
                                 attempt) from None


def connect(address: str):
    """A dask Client at ``address``; :class:`SchedulerUnreachable` when the address is malformed, no
    scheduler answers within :data:`CONNECT_TIMEOUT` seconds or what answers does not speak dask. dask's
    global ``scheduler`` setting is left as it was when no client starts (a failed client has set it)."""
    import dask

    before = dask.config.get("scheduler", None)
    try:
        return _client(address)
    except BaseException:
        _restore_dask_scheduler(before)
        raise


def _client(address: str):
    from dask.distributed import Client
    from distributed.comm.addressing import get_address_host_port

    try:   # the address's form first: a Client refused at once would wait 20 s as it is collected
        get_address_host_port(address)
        return Client(address, timeout=CONNECT_TIMEOUT)
    except (ValueError, TypeError) as err:
        raise SchedulerUnreachable(f"--scheduler: got {address!r}, not a dask address ({err}); expected "
                                   "tcp://HOST:PORT") from None
    except OSError as err:  # TimeoutError and refused connections are OSErrors
        raise SchedulerUnreachable(f"--scheduler: no dask scheduler answered at {address!r} within "
                                   f"{CONNECT_TIMEOUT:g} s ({type(err).__name__}: {err}); start one (dask "
                                   "scheduler) or check the address") from None
    except MemoryError:   # something answered with bytes that are not dask's frames (read as a huge length)
        raise SchedulerUnreachable(f"--scheduler: what answers at {address!r} is not a dask scheduler (its "
                                   "reply is not dask's protocol); check the address and port") from None


def _restore_dask_scheduler(before) -> None:
    """Put dask's global ``scheduler`` setting back: a client made dask's default sets it to
    "dask.distributed", and left so after the client is gone, later dask users in this process (xarray
    writing a calibration's posterior.nc) fail with "Requested dask.distributed scheduler but no Client"."""
    import dask

    if before is None:
        dask.config.config.pop("scheduler", None)
    else:
        dask.config.set(scheduler=before)


def check_scheduler(address: str) -> None:
    """Connect to the scheduler at ``address`` and leave (SchedulerUnreachable as :func:`connect`)."""
    connect(address).close()


class Executor:
    """Ordered ``map`` and ``as_completed`` over a kind of executor; see the module docstring."""

    def __init__(self, kind: str = "serial", workers: int | None = None, scheduler: str | None = None,
                 preload: tuple[str, ...] = (), cluster=None):
        if kind not in EXECUTORS:
            raise ValueError(f"executor: got {kind!r}; allowed: {', '.join(EXECUTORS)}")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers: got {workers!r}; expected an integer >= 1")
        if scheduler and kind != "dask":
            raise ValueError("scheduler: only used with executor 'dask'")
        if (cluster is None) != (kind != "cluster"):
            raise ValueError("cluster: the settings of executor 'cluster', and only of it")
        self.kind = kind
        self.cluster = cluster
        self.workers = cluster.workers if cluster is not None else workers or os.cpu_count() or 1
        self.scheduler = scheduler
        self.preload = tuple(preload)   # local pools: modules each worker imports as it starts, all started at once
        self.restarts = 0   # local pools restarted after a worker died
        self._pool = None
        self._client = None
        self._cluster = None

    # -- life cycle ----------------------------------------------------------------------------------
    def __enter__(self) -> "Executor":
        if (self.kind == "local" and self.workers > 1) or (self.kind == "dask" and not self.scheduler):
            main_guard.refuse_in_spawned_import()   # a worker re-running an unguarded script: one line, exit
            main_guard.check_caller_guarded()       # the script itself: UnguardedScript before any worker starts
            # before the first worker starts: a tracker killed earlier, or while the cluster starts (it
            # creates the nannies' queues), is relaunched knowing the names registered with the dead one
            mend_resource_tracker()
        if self.kind == "local" and self.workers > 1:
            self._start_pool()
        elif self.kind in ("dask", "cluster"):
            self._start_dask()
        return self

    def _start_pool(self) -> None:
        mend_resource_tracker()
        threads = max(1, (os.cpu_count() or 1) // self.workers)
        self._pool = ProcessPoolExecutor(max_workers=self.workers,
                                         mp_context=_pool_context(),
                                         initializer=_init_worker, initargs=(threads, self.preload))
        if self.preload:   # start every worker now (a pool starts them as tasks come): they import meanwhile
            for _ in range(self.workers):
                with deferred(), _sigint_blocked():
                    self._pool.submit(_started)

    def _start_dask(self) -> None:
        import dask
        from dask.distributed import Client

        self._dask_scheduler = dask.config.get("scheduler", None)   # the client becomes dask's default
        try:
            if self.scheduler:
                self._client = connect(self.scheduler)
            elif self.cluster is not None:
                from .cluster import start_cluster

                with deferred():   # a Ctrl-C while the jobs are submitted: raised once they are, to cancel them
                    self._cluster = start_cluster(self.cluster)
                self._client = Client(self._cluster)
            else:
                self._immune = _workers_ignore_sigint()
                self._immune.__enter__()
                with deferred():   # a Ctrl-C while the cluster starts: raised once it is whole, to close it
                    self._cluster = _local_cluster(self.workers)
                self._client = Client(self._cluster)
        except BaseException:   # an interrupt held while the cluster started: __exit__ will not run
            self.close(wait=False)
            raise

    def __exit__(self, exc_type, *exc) -> None:
        self.close(wait=exc_type is None)

    def close(self, wait: bool = True) -> None:
        """Stop the pool or cluster; ``wait=False`` (after an error or an interrupt) kills the workers
        instead of waiting for their tasks."""
        mend_resource_tracker()
        try:
            self._close_parts(wait)
        finally:   # even when closing raised (a cluster that would not stop in time)
            if "_immune" in vars(self):   # the cluster is gone: spawn starts Python directly again
                vars(self).pop("_immune").__exit__(None, None, None)
            if "_dask_scheduler" in vars(self):   # set when a client was started
                _restore_dask_scheduler(vars(self).pop("_dask_scheduler"))

    def _close_parts(self, wait: bool) -> None:
        if self._pool is not None:
            self._stop_pool(wait)
        failure = None
        for name in ("_client", "_cluster"):   # the cluster is closed even when the client would not close
            part, timeout = getattr(self, name), None if wait else 5
            setattr(self, name, None)
            if part is None:
                continue
            try:
                if wait:
                    part.close(timeout=timeout)
                    continue
                with _quiet_distributed():   # after an error or an interrupt: best effort, the original
                    part.close(timeout=timeout)   # exception is what matters
            except Exception as err:  # noqa: BLE001 - dask may complain about workers still starting
                failure = failure or (err if wait else None)
        if failure is not None:
            raise failure

    def _stop_pool(self, wait: bool, settle: bool = False) -> list[int]:
        """Stop the pool; returns the exit statuses of the workers that had died before it was stopped
        (``settle``: after a break, give a dying worker half a second to finish exiting first)."""
        pool, self._pool = self._pool, None
        mend_resource_tracker()
        processes = list((getattr(pool, "_processes", None) or {}).values())
        manager = getattr(pool, "_executor_manager_thread", None)
        if settle:   # a worker whose death broke the pool may still be exiting: let it finish (its status)
            deadline = time.monotonic() + 0.5
            for process in processes:
                process.join(timeout=max(0.0, deadline - time.monotonic()))
        dead = [process for process in processes if not process.is_alive()]
        if not wait:
            for process in processes:
                if process.is_alive():
                    process.kill()
        pool.shutdown(wait=wait, cancel_futures=True)
        for process in processes:
            process.join(timeout=10)
        if manager is not None:   # else, at exit, Python may wake it through a pipe it is closing:
            manager.join(timeout=10)   # "Exception ignored ... OSError: [Errno 9] Bad file descriptor"
        return [process.exitcode for process in dead if process.exitcode is not None]

    @property
    def in_process(self) -> bool:
        return self._pool is None and self._client is None

    @property
    def description(self) -> str:
        if self.in_process:
            return "serial (this process, threaded batches)"
        if self._pool is not None:
            return f"local ({self.workers} processes)"
        if self.cluster is not None:
            return self.cluster.describe()
        return f"dask ({self.scheduler or f'LocalCluster of {self.workers}'})"

    # -- running -------------------------------------------------------------------------------------
    def map(self, fn: Callable, items: Iterable, tick: Callable[[], object] | None = None) -> list:
        """``[fn(item) for item in items]``, in order; the first failing task's exception is raised.
        ``tick()`` is called as each task finishes (a progress bar's ``update``)."""
        items = list(items)
        tick = tick or (lambda: None)
        out = [None] * len(items)
        if len(items) <= 1 or self.in_process:
            for index, item in enumerate(items):
                out[index] = fn(item)
                tick()
            return out
        for outcome in self.as_completed(fn, items):
            if outcome.error is not None:
                raise outcome.error
            out[outcome.index] = outcome.value
            tick()
        return out

    def as_completed(self, fn: Callable, items: Iterable, idle: float | None = None) -> Iterator[Outcome | None]:
        """:class:`Outcome` of every task as it finishes (and ``None`` heartbeats with ``idle``); failures
        are outcomes, never raised."""
        items = list(items)
        if self.in_process:
            yield from self._serial(fn, items, idle)
        elif self._pool is not None:
            yield from self._local(fn, items, idle)
        else:
            yield from self._dask(fn, items, idle)

    def _serial(self, fn, items, idle):
        for index, item in enumerate(items):
            raise_if_received()
            if idle is not None:
                yield None
            try:
                value = fn(item)
            except Exception as err:  # noqa: BLE001 - reported as the task's outcome
                yield Outcome(index, item, None, err)
                continue
            yield Outcome(index, item, value, None)

    def _local(self, fn, items, idle):
        """At most ``workers`` tasks in flight; a broken pool is restarted and its tasks run again alone."""
        import cloudpickle

        blob = cloudpickle.dumps(fn)
        fresh, suspects = deque(range(len(items))), deque()
        attempts = [0] * len(items)
        running: dict = {}
        while fresh or suspects or running:
            raise_if_received()
            mend_resource_tracker()
            lost: list[int] = []
            if not self._submit(blob, items, fresh, suspects, running):
                done, _ = wait(running, timeout=idle, return_when=FIRST_COMPLETED)
                if not done:
                    yield None
                    continue
                for future in done:
                    index = running.pop(future)
                    error = future.exception()
                    if isinstance(error, BrokenProcessPool):
                        lost.append(index)
                        continue
                    yield Outcome(index, items[index], None if error else future.result(), error)
                if not lost:
                    continue
            # the pool is broken: every task still running went down with it
            wait(running)
            for future, index in list(running.items()):
                error = future.exception()
                if isinstance(error, BrokenProcessPool):
                    lost.append(index)
                else:
                    yield Outcome(index, items[index], None if error else future.result(), error)
            running.clear()
            statuses = self._restart_pool()
            for index in sorted(lost):
                attempts[index] += 1
                if attempts[index] >= MAX_ATTEMPTS:
                    yield Outcome(index, items[index], None, WorkerLost(
                        f"the worker running this task died {attempts[index]} times (killed, out of memory "
                        f"or crashed; last {describe_exit(statuses)})", attempts[index]))
                else:
                    suspects.append(index)

    def _submit(self, blob, items, fresh, suspects, running) -> bool:
        """Fill the pool: a suspect (a task whose worker died) runs alone, others up to ``workers`` at
        once. Returns True when the pool turned out to be broken (the task being submitted goes back)."""
        queue = suspects if suspects else fresh
        while queue and len(running) < (1 if queue is suspects else self.workers):
            if queue is suspects and running:
                break
            index = queue.popleft()
            try:
                with deferred(), _sigint_blocked():   # a submission may start a worker process
                    running[self._pool.submit(_call_pickled, (blob, items[index]))] = index
            except BrokenProcessPool:
                queue.appendleft(index)   # never started: not counted as an attempt
                return True
        return False

    def _restart_pool(self) -> list[int]:
        """A new pool for a broken one; the dead workers' exit statuses. A worker that died importing an
        unguarded main script (:mod:`sweeps.main_guard`) stops everything: :class:`UnguardedScript`."""
        statuses = self._stop_pool(wait=False, settle=True)
        # a broken pool terminates (SIGTERM) its surviving workers itself: those are not the cause
        statuses = [status for status in statuses if status != -signal.SIGTERM] or statuses
        if main_guard.UNGUARDED_EXIT in statuses:
            raise main_guard.UnguardedScript(main_guard.message())
        self.restarts += 1
        self._start_pool()
        return statuses

    def _dask(self, fn, items, idle):
        from dask.distributed import TimeoutError as DaskTimeout
        from dask.distributed import wait as dask_wait

        futures = self._client.map(fn, items, pure=False)
        position = {future.key: index for index, future in enumerate(futures)}
        pending = set(futures)
        try:
            while pending:
                raise_if_received()
                mend_resource_tracker()
                try:
                    done, pending = dask_wait(list(pending), timeout=idle, return_when="FIRST_COMPLETED")
                except DaskTimeout:
                    yield None
                    continue
                pending = set(pending)
                for future in done:
                    index = position[future.key]
                    try:
                        value = future.result()
                    except Exception as err:  # noqa: BLE001 - the task's error, or a lost worker: an outcome
                        if _is_lost_worker(err):
                            err = WorkerLost(f"dask lost the workers running this task ({err})")
                        yield Outcome(index, items[index], None, err)
                        continue
                    yield Outcome(index, items[index], value, None)
        finally:
            for future in futures:
                future.cancel()
