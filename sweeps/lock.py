"""The lock of a results folder: one writer at a time, a dead holder recognised, and who holds it.

``hold(root)`` is a context manager holding an exclusive ``flock`` on ``<root>/.lock`` while one process
writes in ``root``; the file records the holder (``pid P on HOST since T``). The kernel drops the lock
when the holder's last descriptor closes, so a runner killed by any signal (SIGKILL included) frees
the folder at once: the descriptor is close-on-exec and the executor's workers are spawned, never
forked, so no child keeps it.

When the folder is locked, ``hold`` waits :data:`SETTLE` seconds (a reader probing the lock, a runner
that is just exiting); then, if the recorded holder is a process of this machine that no longer runs,
the lock is held by processes it left behind: ``hold`` waits up to :data:`ORPHAN_GRACE` seconds for them
to exit (the executor's workers exit with their parent) and, failing that, :class:`StoreLocked` names
them. A live holder is :class:`StoreLocked` naming it.

``holder(root)`` says who holds the lock now (the record, or ``None`` when nobody does) without taking
it for more than an instant and without creating anything: ``flocksweep status`` uses it to tell a
running sweep from an interrupted one.
"""
from __future__ import annotations

import errno
import fcntl
import os
import re
import socket
import time
from contextlib import contextmanager
from pathlib import Path

from .files import write_failed

SETTLE = 1.0          # seconds a busy lock is retried before it counts as held
ORPHAN_GRACE = 20.0   # seconds to wait for processes a dead holder left behind
LOCK_NAME = ".lock"


class StoreLocked(RuntimeError):
    pass


def _try_lock(handle) -> bool:
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False


def _record(handle) -> str:
    handle.seek(0)
    return handle.read().strip()


def _dead_holder(record: str) -> int | None:
    """The recorded holder's pid when it is a process of this machine that no longer runs."""
    found = re.match(r"pid (\d+) on (\S+)", record)
    if not found or found.group(2) != socket.gethostname():
        return None
    pid = int(found.group(1))
    return None if pid_alive(pid) else pid


def pid_alive(pid: int) -> bool:
    """True when process ``pid`` exists (and is not a zombie)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def processes_holding(path: Path) -> list[int]:
    """Pids of the processes with ``path`` open (from /proc; empty where /proc is missing)."""
    try:
        target = path.stat()
    except OSError:
        return []
    pids = []
    for fd_dir in Path("/proc").glob("[0-9]*/fd"):
        try:
            for fd in fd_dir.iterdir():
                info = fd.stat()
                if (info.st_dev, info.st_ino) == (target.st_dev, target.st_ino):
                    pids.append(int(fd_dir.parent.name))
                    break
        except OSError:
            continue
    return sorted(set(pids) - {os.getpid()})


def _wait_for(handle, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if _try_lock(handle):
            return True
        time.sleep(0.05)
    return _try_lock(handle)


def _acquire(root: Path, handle, path: Path) -> None:
    if _wait_for(handle, SETTLE):
        return
    record = _record(handle) or "unknown process"
    dead = _dead_holder(record)
    if dead is not None and _wait_for(handle, ORPHAN_GRACE):
        return
    handle.close()
    if dead is not None:
        left = processes_holding(path)
        names = f" (pids {', '.join(map(str, left))})" if left else ""
        raise StoreLocked(f"{root} is locked by processes left behind by runner pid {dead}, which is no longer "
                          f"running{names}; stop them (kill {' '.join(map(str, left)) or 'PID'}) and run again "
                          "(finished runs are kept)")
    raise StoreLocked(f"{root} is in use by another flocksweep runner ({record}); wait for it to finish or "
                      "stop it, then run again (finished runs are kept)")


@contextmanager
def hold(root):
    """Exclusive lock on the folder ``root`` for one writer (see the module docstring)."""
    root = Path(root)
    path = root / LOCK_NAME
    try:
        if root.exists() and not root.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, "not a folder", str(root))
        root.mkdir(parents=True, exist_ok=True)
        handle = open(path, "a+")
    except OSError as err:
        raise write_failed(err.filename or path, err) from None
    _acquire(root, handle, path)
    try:
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()} on {socket.gethostname()} since {time.strftime('%Y-%m-%d %H:%M:%S')}")
        handle.flush()
    except OSError as err:
        handle.close()
        raise write_failed(path, err) from None
    try:
        yield
    finally:
        try:
            handle.truncate(0)
        except OSError:
            pass   # a full or read-only disk: the record stays, the lock still goes with the descriptor
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()


def holder(root) -> str | None:
    """Who holds the folder's lock now (its record), or None when nobody does."""
    path = Path(root) / LOCK_NAME
    try:
        handle = open(path)
    except OSError:
        return None
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _record(handle) or "unknown process"
        fcntl.flock(handle, fcntl.LOCK_UN)
        return None
