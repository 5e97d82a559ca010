"""A child process for code we cannot trust to return: a crash, a hang or an overrun ends the child, never the caller.

``Sandbox(threads=None)`` holds one child Python process (started on first use, reused for every later task)
and runs tasks in it one at a time: ``call(fn, *args, timeout=None)`` sends ``fn`` (a module-level function,
pickled by reference) and ``args`` (pickled), waits at most ``timeout`` seconds for the answer and returns
``fn(*args)``, or raises what ``fn`` raised. Three ways a task can end the child instead, each an exception of
the caller's and a fresh child for the next task:

* :class:`TaskCrashed`: the child died while running it (SIGSEGV from an out-of-bounds write in compiled code,
  SIGABRT, out of memory); the message names the signal or exit status;
* :class:`TaskTimedOut`: it was still running after ``timeout`` seconds; the child is killed (SIGKILL: compiled
  code cannot be interrupted any other way);
* an interrupt (KeyboardInterrupt, SIGTERM as one) while waiting: the child is killed, the interrupt raised.

A child that ended while idle, between tasks (killed from outside), ran none of them: the next call starts
a new one instead of blaming that task.

The child is a new interpreter (``python -m flocksweep.sweeps.sandbox``, not a fork: the caller may run
threaded compiled kernels), started with the caller's ``sys.path`` (a plug-in module the caller imports, the
child imports) and numba thread count, stdin closed, stdout and stderr the caller's. It ignores SIGINT and
lives in its own session (a Ctrl-C is the caller's to handle: it kills the child), and on Linux the kernel
kills it when the thread that started it dies (:func:`dies_with_parent`), so it never outlives a killed
worker; it also exits when the caller closes its end of the pipe. Tasks and answers travel as pickles over
two pipes between these two processes only (both ends are ours: nothing from a file is unpickled).

Used by :mod:`sweeps.worker` for the runs that must be contained: plug-in dynamics (a user's compiled code)
and every run with a wall-time limit (``run.timeout_s``).
"""
from __future__ import annotations

import ctypes
import os
import pickle
import signal
import subprocess
import sys
from multiprocessing.connection import Connection

PR_SET_PDEATHSIG = 1       # linux/prctl.h


class TaskCrashed(RuntimeError):
    """The sandbox's process died while running the task."""


class TaskTimedOut(RuntimeError):
    """The task was still running when its time was up; its process was killed."""


def dies_with_parent():
    """A ``preexec_fn`` that has the kernel kill the child (SIGKILL) when the thread that started it dies
    (Linux's PR_SET_PDEATHSIG; a worker killed outright cannot kill its children itself); None elsewhere.
    Resolved before the fork, so the child only makes the one system call."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    args = (ctypes.c_int(PR_SET_PDEATHSIG), ctypes.c_ulong(signal.SIGKILL), ctypes.c_ulong(0), ctypes.c_ulong(0),
            ctypes.c_ulong(0))
    return lambda: prctl(*args)


def describe_status(status: int | None) -> str:
    """'killed by SIGSEGV', 'exit status 1', ... of a child's return code."""
    if status is None:
        return "status unknown"
    if status < 0:
        try:
            return f"killed by {signal.Signals(-status).name}"
        except ValueError:
            return f"killed by signal {-status}"
    return f"exit status {status}"


class Sandbox:
    """One child process running tasks (see the module docstring). A context manager: closed on exit."""

    def __init__(self, threads: int | None = None):
        self.threads = threads
        self._process: subprocess.Popen | None = None
        self._tasks: Connection | None = None
        self._answers: Connection | None = None

    def __enter__(self) -> "Sandbox":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def pid(self) -> int | None:
        return None if self._process is None else self._process.pid

    def _start(self) -> None:
        task_read, task_write = os.pipe()
        answer_read, answer_write = os.pipe()
        try:
            self._process = subprocess.Popen(
                [sys.executable, "-m", __name__, str(task_read), str(answer_write)],
                pass_fds=(task_read, answer_write), stdin=subprocess.DEVNULL, start_new_session=True,
                preexec_fn=dies_with_parent())
        except BaseException:
            for fd in (task_read, task_write, answer_read, answer_write):
                os.close(fd)
            raise
        os.close(task_read)
        os.close(answer_write)
        self._tasks = Connection(task_write, readable=False)
        self._answers = Connection(answer_read, writable=False)
        threads = self.threads
        if threads is None and "numba" in sys.modules:
            threads = sys.modules["numba"].get_num_threads()
        self._tasks.send({"path": list(sys.path), "threads": threads})

    def call(self, fn, *args, timeout: float | None = None):
        """``fn(*args)`` in the child, within ``timeout`` seconds (None: no limit); see the module docstring."""
        if self._process is not None and self._process.poll() is not None:   # ended while idle (killed from
            self.close(kill=True)                                             # outside): no task of ours died
        if self._process is None:
            self._start()
        try:
            try:
                self._tasks.send((fn, args))
            except OSError:   # it died before it could read the task
                raise self._crashed() from None
            if not self._answers.poll(timeout):
                self.close(kill=True)
                raise TaskTimedOut(f"timed out after {timeout:g} s; its process was killed")
            try:
                done, value = self._answers.recv()
            except (EOFError, OSError):
                raise self._crashed() from None
        except BaseException:   # an interrupt while waiting, or one of the above: the child goes
            self.close(kill=True)
            raise
        if done:
            return value
        raise value

    def _crashed(self) -> TaskCrashed:
        process = self._process
        try:
            status = process.wait(timeout=10) if process is not None else None
        except subprocess.TimeoutExpired:
            status = None
        return TaskCrashed(f"its process died ({describe_status(status)})")

    def close(self, kill: bool = False) -> None:
        """End the child: ``kill`` at once, else by closing its pipe (it exits when it reads the end)."""
        process, self._process = self._process, None
        for name in ("_tasks", "_answers"):
            connection = getattr(self, name)
            setattr(self, name, None)
            if connection is not None:
                connection.close()
        if process is None:
            return
        if kill:
            try:
                process.kill()
            except ProcessLookupError:
                pass
        try:
            process.wait(timeout=None if kill else 10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def _answer(task: bytes) -> bytes:
    """The pickled answer to a pickled task: (True, fn(*args)) or (False, what unpickling the task, the
    task itself or pickling its value raised; as its text when it does not pickle)."""
    try:
        fn, args = pickle.loads(task)
        return pickle.dumps((True, fn(*args)))
    except Exception as err:  # noqa: BLE001 - the task's exception is the caller's
        try:
            return pickle.dumps((False, err))
        except Exception:  # noqa: BLE001 - an exception that does not pickle goes as its text
            return pickle.dumps((False, RuntimeError(f"{type(err).__name__}: {err}")))


def serve(task_fd: int, answer_fd: int) -> None:
    """The child's loop: set up as the caller asks, then answer tasks until the caller closes the pipe."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    tasks, answers = Connection(task_fd, writable=False), Connection(answer_fd, readable=False)
    try:
        setup = tasks.recv()
    except EOFError:
        return
    sys.path[:] = setup["path"]
    if setup.get("threads"):
        import numba

        numba.set_num_threads(min(int(setup["threads"]), numba.config.NUMBA_NUM_THREADS))
    while True:
        try:
            task = tasks.recv_bytes()
        except EOFError:
            return
        answers.send_bytes(_answer(task))


if __name__ == "__main__":
    serve(int(sys.argv[1]), int(sys.argv[2]))
