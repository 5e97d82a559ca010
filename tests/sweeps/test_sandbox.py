"""The sandbox (sweeps.sandbox): a child process that runs tasks, so that a crash, a hang or an interrupt
ends the child and never the caller. Each property on a real child: values and exceptions come back, a
SIGSEGV is TaskCrashed naming the signal and the next task gets a fresh child, a task over its time is
killed (TaskTimedOut), the child sees the caller's sys.path, and closing ends it."""
from __future__ import annotations

import ctypes
import math
import os
import sys
import time

import pytest

from flocksweep.sweeps.sandbox import Sandbox, TaskCrashed, TaskTimedOut, describe_status


def gone(pid: int) -> bool:
    """Whether ``pid`` has exited (reaped or a zombie), waiting at most 10 s for the kernel."""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{pid}/stat") as stat:
                if stat.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return True
        except FileNotFoundError:
            return True
        time.sleep(0.02)
    return False


def test_values_and_exceptions_come_back_and_the_child_is_reused():
    with Sandbox() as box:
        assert box.call(math.sqrt, 16.0) == 4.0
        first = box.pid
        assert box.call(os.getpid) == first != os.getpid()
        with pytest.raises(ValueError, match="math domain error"):
            box.call(math.sqrt, -1.0)
        assert box.call(os.getpid) == first   # an exception of the task's does not cost the child
    assert gone(first)


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_a_crash_is_task_crashed_and_the_next_task_gets_a_new_child():
    with Sandbox() as box:
        first = box.call(os.getpid)
        with pytest.raises(TaskCrashed, match=r"its process died \(killed by SIGSEGV\)"):
            box.call(ctypes.string_at, 0)   # reads address 0
        assert gone(first)
        assert box.call(os.getpid) not in (first, None)


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_a_task_over_its_time_is_killed():
    with Sandbox() as box:
        pid = box.call(os.getpid)
        started = time.monotonic()
        with pytest.raises(TaskTimedOut, match="timed out after 0.5 s"):
            box.call(time.sleep, 60, timeout=0.5)
        assert time.monotonic() - started < 30 and gone(pid)
        assert box.call(math.sqrt, 9.0) == 3.0


def test_the_child_imports_what_the_caller_can(tmp_path, monkeypatch):
    """A plug-in module on the caller's path (PYTHONPATH, a notebook's folder) is importable in the child."""
    (tmp_path / "only_here.py").write_text("def answer():\n    return 42\n")
    monkeypatch.setattr(sys, "path", [str(tmp_path), *sys.path])
    monkeypatch.delitem(sys.modules, "only_here", raising=False)
    import importlib

    only_here = importlib.import_module("only_here")
    with Sandbox() as box:
        assert box.call(only_here.answer) == 42   # pickled by reference: the child imports only_here
        with pytest.raises(TypeError, match="cannot pickle 'module' object"):   # an answer that cannot travel
            box.call(importlib.import_module, "only_here")
        assert box.call(only_here.answer) == 42


def test_statuses_are_named():
    assert describe_status(-11) == "killed by SIGSEGV" and describe_status(3) == "exit status 3"
    assert describe_status(None) == "status unknown"


def test_an_interrupt_while_waiting_ends_the_child():
    """Ctrl-C while a task runs: the caller gets its KeyboardInterrupt and the child is killed (here the
    task itself sends the caller SIGINT, so the signal surely lands while the caller waits). Python's own
    Ctrl-C handler is installed for the test, whatever an earlier test's library left behind."""
    import signal

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with Sandbox() as box:
            pid = box.call(os.getpid)
            with pytest.raises(KeyboardInterrupt):
                box.call(os.kill, os.getpid(), signal.SIGINT)
            assert gone(pid) and box.pid is None
    finally:
        signal.signal(signal.SIGINT, before)


def test_a_child_killed_while_idle_is_replaced_not_blamed_on_the_next_task():
    """A sandbox killed from outside between tasks (a tidy-up, the OOM killer) has run none of them: the
    next call starts a new child instead of reporting that task as crashed."""
    import signal

    with Sandbox() as box:
        first = box.call(os.getpid)
        os.kill(first, signal.SIGKILL)
        box._process.wait()                 # surely dead before the next call (no race with a sleep)
        second = box.call(os.getpid)
        assert second != first and gone(first)
