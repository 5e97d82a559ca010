"""The one executor (sweeps.executors): order, failures as outcomes, a dead worker, and workers that exit
when the process that started them dies."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from sweeps.executors import Executor


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


def test_map_raises_the_failing_tasks_error():
    with Executor("local", 2) as pool:
        with pytest.raises(ValueError, match="three is bad"):
            pool.map(fail_on_three, range(5))


def test_a_dead_worker_is_an_outcome_naming_it():
    with Executor("local", 2) as pool:
        outcomes = list(pool.as_completed(die_on_two, range(4)))
    died = [o for o in outcomes if o.error is not None]
    assert 2 in [o.item for o in died]
    assert all(o.reason.startswith("worker process died") for o in died)


PARENT = """
import os, sys, time
from sweeps.executors import Executor

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
