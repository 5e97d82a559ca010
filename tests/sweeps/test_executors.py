"""The one executor (sweeps.executors): order, failures as outcomes, heartbeats, a dead worker retried
alone and given up as lost (never a task failure), workers killed at once on an interrupt, and workers
that exit when the process that started them dies."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from paths import ROOT
from flocksweep.sweeps.executors import MAX_ATTEMPTS, Executor, WorkerLost


def square(x):
    return x * x


def fail_on_three(x):
    if x == 3:
        raise ValueError("three is bad")
    return x


def die_on_two(x):
    if x == 2:
        os._exit(9)   # the worker process dies mid-task
    time.sleep(0.2)
    return x


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
@pytest.mark.parametrize("kind, workers", [("serial", 1), ("local", 1), ("local", 2)])
def test_map_keeps_order_and_as_completed_reports_every_item(kind, workers):
    with Executor(kind, workers) as pool:
        assert pool.map(square, range(6)) == [0, 1, 4, 9, 16, 25]
        outcomes = list(pool.as_completed(fail_on_three, range(5)))
    assert sorted(o.index for o in outcomes) == [0, 1, 2, 3, 4]
    failed = [o for o in outcomes if o.error is not None]
    assert [o.item for o in failed] == [3] and isinstance(failed[0].error, ValueError)
    assert failed[0].reason == "task failed: ValueError: three is bad" and failed[0].value is None
    assert all(o.value == o.item and o.reason == "" for o in outcomes if o.error is None)


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_map_raises_the_failing_tasks_error():
    with Executor("local", 2) as pool:
        with pytest.raises(ValueError, match="three is bad"):
            pool.map(fail_on_three, range(5))


@pytest.mark.slow
def test_a_task_whose_worker_always_dies_is_lost_the_others_finish():
    with Executor("local", 2) as pool:
        outcomes = list(pool.as_completed(die_on_two, range(4)))
        restarts = pool.restarts
    died = [o for o in outcomes if o.error is not None]
    assert [o.item for o in died] == [2]
    assert isinstance(died[0].error, WorkerLost) and died[0].error.attempts == MAX_ATTEMPTS
    assert died[0].reason.startswith("worker process died") and "worker exit status 9" in died[0].reason
    assert sorted(o.value for o in outcomes if o.error is None) == [0, 1, 3]   # not failed with it
    assert restarts == MAX_ATTEMPTS


def die_once(marker):
    def task(x):
        if x == 1 and not os.path.exists(marker):
            open(marker, "w").close()
            os._exit(9)
        return x
    return task


@pytest.mark.slow
def test_a_worker_that_dies_once_is_replaced_and_its_task_run_again(tmp_path):
    with Executor("local", 2) as pool:
        assert pool.map(die_once(str(tmp_path / "died")), range(5)) == [0, 1, 2, 3, 4]
        assert pool.restarts == 1


def nap(x):
    time.sleep(0.6)
    return x


def long_nap(x):
    time.sleep(60)
    return x


def test_heartbeats_come_while_nothing_finishes():
    with Executor("serial") as pool:
        events = list(pool.as_completed(square, range(3), idle=1.0))
    assert [e if e is None else e.value for e in events] == [None, 0, None, 1, None, 4]


@pytest.mark.slow
def test_a_pool_heartbeats_while_its_tasks_run_and_stops_at_once_when_told():
    with Executor("local", 2) as pool:
        events = list(pool.as_completed(nap, range(2), idle=0.1))
        assert events.count(None) >= 2 and sorted(e.value for e in events if e is not None) == [0, 1]
        running = pool.as_completed(long_nap, range(2), idle=0.1)
        assert next(running) is None                        # both workers are 60 s into their naps
        workers = list(pool._pool._processes.values())
        start = time.perf_counter()
        pool.close(wait=False)                              # as after Ctrl-C
    # the pids, not Process.is_alive(): the pool's manager thread may reap a killed worker first, and then
    # is_alive() (its waitpid fails with ECHILD) reports a dead worker as alive
    assert time.perf_counter() - start < 5 and not any(alive(w.pid) for w in workers)


PARENT = """
import os, sys, time
from paths import ROOT
from flocksweep.sweeps.executors import MAX_ATTEMPTS, Executor, WorkerLost

def pid(_):
    time.sleep(0.5)
    return os.getpid()

if __name__ == "__main__":
    with Executor("local", 2) as pool:
        pids = sorted(set(pool.map(pid, range(8))))
        print(" ".join(map(str, pids)), flush=True)
        time.sleep(600)
"""


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as handle:   # a zombie is dead for our purpose
        return handle.read().split()[2] != "Z"


@pytest.mark.slow
@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to see worker processes")
def test_workers_exit_when_their_parent_is_killed(tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        pids = [int(p) for p in parent.stdout.readline().split()]
        assert len(pids) == 2 and all(alive(p) for p in pids)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=30)
        deadline = time.monotonic() + 30
        while any(alive(p) for p in pids) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(alive(p) for p in pids), "workers outlived their parent"
    finally:
        parent.kill()


INTERRUPTED_SPAWN = """
import os, queue, signal, sys, threading, time
import multiprocessing.util as util
from flocksweep.sweeps.executors import Executor

requests, done, spawned, sent = queue.Queue(), queue.Queue(), [], [0]

def interrupter():
    # started before any worker, so SIGINT is not blocked in this thread (as in tqdm's monitor thread):
    # the kernel hands the signal to this thread and Python raises it in the main thread
    while True:
        requests.get()
        os.kill(os.getpid(), signal.SIGINT)
        sent[0] += 1
        done.put(None)

real_spawn = util.spawnv_passfds

def spawn_then_interrupt(*args, **kwargs):
    pid = real_spawn(*args, **kwargs)
    if "spawn_main" in " ".join(map(str, args[1])):
        spawned.append(pid)
        requests.put(None)
        done.get()            # a Ctrl-C after the worker exists, before it has its start-up data
        time.sleep(0.05)
    return pid

def square(x):
    return x * x

def gone(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    with open(f"/proc/{pid}/stat") as handle:
        return handle.read().split()[2] == "Z"

if __name__ == "__main__":
    # as a terminal's process: Ctrl-C raises. A test runner's process may pass SIGINT on ignored or blocked
    # (seen under pytest-xdist in CI: "spawned 2, interrupts sent 2" and no interrupt); say what came in
    states = [line.split()[:2] for line in open("/proc/self/status") if line.startswith(("SigBlk", "SigIgn"))]
    print("inherited", *states, signal.getsignal(signal.SIGINT), file=sys.stderr, flush=True)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.default_int_handler)
    threading.Thread(target=interrupter, daemon=True).start()
    util.spawnv_passfds = spawn_then_interrupt
    try:
        with Executor("local", workers=2) as pool:
            pool.map(square, [1, 2, 3])
    except KeyboardInterrupt:
        print("interrupted", flush=True)
    deadline = time.monotonic() + 30
    while not all(gone(pid) for pid in spawned) and time.monotonic() < deadline:
        time.sleep(0.05)
    print("workers gone" if all(gone(pid) for pid in spawned) else "workers left", flush=True)
    print(f"spawned {len(spawned)}, interrupts sent {sent[0]}", flush=True)
"""


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to see worker processes")
def test_a_ctrl_c_while_a_worker_starts_leaves_no_half_started_worker(tmp_path):
    """A Ctrl-C taken by another thread while a worker is being spawned used to close the worker's start-up
    pipe before its data was written: the orphan printed "EOFError: Ran out of input"."""
    script = tmp_path / "spawn.py"
    script.write_text(INTERRUPTED_SPAWN)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert done.stdout.split("\n")[:2] == ["interrupted", "workers gone"], done.stdout + done.stderr
    assert done.stdout.split("\n")[2] == "spawned 1, interrupts sent 1", done.stdout   # the Ctrl-C came at the first
    assert "Traceback" not in done.stderr and "EOFError" not in done.stderr, done.stderr


def test_semaphore_names_pass_over_proxies_whose_object_is_gone():
    """gc.get_objects() holds weak proxies; a proxy of a dead lock passes isinstance but cannot be read."""
    import multiprocessing
    import weakref

    from flocksweep.sweeps.executors import _semaphore_names

    lock = multiprocessing.get_context("spawn").Lock()
    kept = multiprocessing.get_context("spawn").Lock()
    proxies = [weakref.proxy(lock), weakref.proxy(kept)]
    name = lock._semlock.name
    del lock
    names = _semaphore_names()
    assert kept._semlock.name in names and name not in names and len(proxies) == 2


POOL_SCRIPT = """
import multiprocessing.util, sys
from flocksweep.sweeps.executors import Executor

def task(folder):
    def mark(name):
        open(f"{folder}/{name}", "w").close()
    multiprocessing.util.Finalize(None, mark, args=(multiprocessing.current_process().name,), exitpriority=1)
    print("printed by a worker, never flushed", end="")
    return multiprocessing.current_process().name

if __name__ == "__main__":
    with Executor("local", 2) as pool:
        names = set(pool.map(task, [sys.argv[1]] * 8))
    print("", len(names), "workers", flush=True)
"""


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_local_workers_quick_exit_still_flushes_their_output_and_runs_their_finalizers(tmp_path):
    """Pool workers end without the interpreter's teardown (``_QuickExitProcess``), but only after what
    multiprocessing's own exit does: the finalizers registered in them ran and their unflushed output
    reached the parent's stdout."""
    script = tmp_path / "pool.py"
    script.write_text(POOL_SCRIPT)
    (tmp_path / "marks").mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, str(script), str(tmp_path / "marks")], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-1000:]
    workers = int(done.stdout.split()[-2])
    assert done.stdout.count("printed by a worker, never flushed") == 8
    assert len(list((tmp_path / "marks").iterdir())) == workers >= 1


PRELOAD_SCRIPT = """
import os, sys, time
from flocksweep.sweeps.executors import Executor

if __name__ == "__main__":
    sys.path.insert(0, sys.argv[1])   # spawned workers get this process's path
    marks = os.path.join(sys.argv[1], "marks")
    with Executor("local", 2, preload=("marker",)) as pool:
        deadline = time.monotonic() + 120
        while len(os.listdir(marks)) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        print(len(os.listdir(marks)), "workers imported it before any task")
"""


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_preload_starts_every_worker_at_once_and_imports_the_modules_before_any_task(tmp_path):
    (tmp_path / "marks").mkdir()
    (tmp_path / "marker.py").write_text("import os\nopen(os.path.join(os.path.dirname(__file__), 'marks', "
                                        "str(os.getpid())), 'w').close()\n")
    script = tmp_path / "preload.py"
    script.write_text(PRELOAD_SCRIPT)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, str(script), str(tmp_path)], env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-1000:]
    assert done.stdout.startswith("2 workers imported it before any task")


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_a_preload_entry_with_a_function_calls_it_after_the_import(tmp_path):
    (tmp_path / "marks").mkdir()
    (tmp_path / "marker.py").write_text("import os\ndef mark():\n    open(os.path.join(os.path.dirname(__file__), "
                                        "'marks', 'called-' + str(os.getpid())), 'w').close()\n")
    script = tmp_path / "preload.py"
    script.write_text(PRELOAD_SCRIPT.replace('preload=("marker",)', 'preload=("marker:mark",)')
                      .replace("workers imported it", "workers called it"))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, str(script), str(tmp_path)], env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-1000:]
    assert done.stdout.startswith("2 workers called it before any task")
    assert all(name.startswith("called-") for name in os.listdir(tmp_path / "marks"))


def test_the_sweep_workers_preparation_compiles_nothing():
    from numba.core import event

    from flocksweep.sweeps import worker

    compiled = []

    class Count(event.Listener):
        def on_start(self, ev):
            compiled.append(ev)

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Count()):
        worker.prepare()
    assert not compiled


class _Part:
    """A stand-in for dask's Client or cluster: records its close, raises when told to."""

    def __init__(self, error=None):
        self.error, self.closed = error, False

    def close(self, timeout=None):
        self.closed = True
        if self.error is not None:
            raise self.error


def test_a_client_that_will_not_close_still_closes_the_cluster_and_gives_dask_its_scheduler_back():
    dask = pytest.importorskip("dask")
    executor = Executor("dask", workers=1)
    executor._client, executor._cluster = _Part(TimeoutError("close timed out")), _Part()
    executor._dask_scheduler = None   # as _start_dask records it: no scheduler set before the client
    cluster = executor._cluster
    with dask.config.set(scheduler="dask.distributed"):   # what a client made dask's default leaves
        with pytest.raises(TimeoutError, match="close timed out"):
            executor.close(wait=True)
        assert cluster.closed
        assert dask.config.get("scheduler", None) is None   # else xarray's to_netcdf fails later


def test_an_address_that_is_not_dask_is_refused_and_leaves_dasks_scheduler_as_it_was():
    """A client that fails to start has made itself dask's default; connect() puts the setting back."""
    import socket
    import threading

    dask = pytest.importorskip("dask.distributed") and pytest.importorskip("dask")
    from flocksweep.sweeps.executors import SchedulerUnreachable, connect

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)

    def answer_in_http():   # a web server where the scheduler was expected: bytes that are not dask frames
        while True:
            try:
                peer, _ = server.accept()
            except OSError:
                return
            peer.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)
            peer.close()

    threading.Thread(target=answer_in_http, daemon=True).start()
    try:
        before = dask.config.get("scheduler", None)
        with pytest.raises(SchedulerUnreachable, match="not a dask address"):
            connect("nonsense")
        assert dask.config.get("scheduler", None) == before
        with pytest.raises(SchedulerUnreachable, match="is not a dask scheduler"):
            connect(f"tcp://127.0.0.1:{server.getsockname()[1]}")
        assert dask.config.get("scheduler", None) == before
    finally:
        server.close()
