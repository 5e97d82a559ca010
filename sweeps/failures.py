"""One clear message and a documented exit status for every failure the command line meets.

The ``flocksweep`` command (:mod:`flocksweep.cli`) turns an exception into one line on stderr and an exit
status with :func:`explain`; the statuses (docs/errors.md):

====  ===========================================================================================
0     done (failed runs are results: they are counted and listed by ``flocksweep status``)
2     bad input: a config file or value, a command-line value, a damaged input folder, an
      unreachable dask scheduler; nothing was written
3     the results folder is in use by another runner (or by processes a dead runner left behind)
4     a write failed (disk full, read-only file system, permission): the message names the file
      and the errno; everything saved before it is kept, and the same command resumes
5     incomplete: runs whose worker processes died (after retries) were left missing; the same
      command computes them
6     the simulation failed: ``flocksweep simulate``'s one run ended in a non-finite state (the step
      and boid named) or its plug-in's code crashed (:class:`SimulationFailed`); nothing was written
130   interrupted by SIGINT (Ctrl-C); 143: stopped by SIGTERM. Finished work is saved; the message
      says how to resume
====  ===========================================================================================

Anything else is a bug in flocksweep and keeps Python's traceback.

Helpers for the command line's own values: ``check_count(flag, value, minimum, maximum=None)``,
``check_out(flag, path)`` (a folder we may create: not an existing file, not below one, not a symbolic link that
leads nowhere or in a loop, no NUL character),
``check_out_file(flag, path)`` (a file we may write or overwrite: not a folder, not below a file, no NUL character),
``check_workers(value, executor)`` (at most :data:`WORKERS_PER_CORE` local processes per core),
``parse_numbers(flag, text)`` (comma-separated finite numbers > 0), and
``show_warnings()``, which prints the ``flocksweep`` logger's warnings (damaged files moved aside,
...) as ``flocksweep: warning: ...`` lines.
"""
from __future__ import annotations

import errno
import logging
import os
import sys
from pathlib import Path

from flocksweep.simcore.schema import ConfigError

from .files import Unreadable, WriteFailed
from .interrupts import exit_status
from .lock import StoreLocked

OK, BAD_INPUT, LOCKED, WRITE_FAILED, INCOMPLETE, RUN_FAILED = 0, 2, 3, 4, 5, 6
WORKERS_PER_CORE = 8


class SimulationFailed(RuntimeError):
    """The one simulation of ``flocksweep simulate`` failed (the reason: non-finite state at a step and
    boid, a crash of a plug-in's compiled code)."""


def _executor_error(err: BaseException, name: str) -> bool:
    """Is ``err`` the executors' exception ``name``? Checked without importing :mod:`sweeps.executors`
    (multiprocessing, concurrent.futures: every command would load them): no such error can exist unless
    that module was imported."""
    executors = sys.modules.get(f"{__package__}.executors")
    return executors is not None and isinstance(err, getattr(executors, name))


def explain(err: BaseException) -> tuple[int, str] | None:
    """(exit status, message) for an expected failure, or None for a bug (let it raise)."""
    if isinstance(err, KeyboardInterrupt):
        name = "SIGTERM" if exit_status(err) == 143 else "SIGINT"
        return exit_status(err), f"interrupted ({name})"
    if isinstance(err, ConfigError):
        return BAD_INPUT, f"config error: {err}"
    if isinstance(err, Unreadable) or _executor_error(err, "SchedulerUnreachable"):
        return BAD_INPUT, str(err)
    if isinstance(err, StoreLocked):
        return LOCKED, str(err)
    if isinstance(err, SimulationFailed):
        return RUN_FAILED, f"the simulation failed: {err}; nothing was written"
    if _executor_error(err, "WorkerLost"):
        return INCOMPLETE, f"a worker process died: {err}"
    if isinstance(err, WriteFailed):
        return WRITE_FAILED, (f"{err}; what was saved before is kept: free space or fix the folder, then run "
                              "the same command again to resume")
    if isinstance(err, OSError):
        where = f" {err.filename}" if getattr(err, "filename", None) else ""
        return WRITE_FAILED, f"input/output error{where}: {err.strerror or err}"
    return None


def check_count(flag: str, value, minimum: int, maximum: int | None = None) -> None:
    """A command-line integer within [minimum, maximum] (None: not given, fine)."""
    if value is None:
        return
    if value < minimum or (maximum is not None and value > maximum):
        allowed = f">= {minimum}" if maximum is None else f"between {minimum} and {maximum:,}"
        raise ConfigError(flag, f"got {value}; expected an integer {allowed}")


def parse_numbers(flag: str, text: str) -> list[float]:
    """Comma-separated finite numbers > 0 (ConfigError naming the flag otherwise)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or not all(0 < v < float("inf") for v in values):
        raise ConfigError(flag, f"got {text!r}; expected comma-separated numbers > 0, e.g. 0.05,0.1")
    return values


def check_workers(value, executor: str) -> None:
    """--workers: >= 1, and on this machine at most WORKERS_PER_CORE processes per core."""
    cores = os.cpu_count() or 1
    check_count("--workers", value, 1)
    if value is not None and executor in ("local", "dask") and value > WORKERS_PER_CORE * cores:
        raise ConfigError("--workers", f"got {value}; this machine has {cores} cores: at most "
                                       f"{WORKERS_PER_CORE * cores} local worker processes")


def check_out(flag: str, path) -> None:
    """An output folder: not an existing file, no NUL character."""
    if path is None:
        return
    path = _path_of(flag, path)
    if path.exists() and not path.is_dir():
        raise ConfigError(flag, f"{path} is a file; expected a folder (new or one flocksweep wrote)")
    for part in (path, *path.parents):
        broken = _broken_link(part)
        if broken:
            raise ConfigError(flag, f"{part} is a symbolic link {broken}; expected a folder (new or one flocksweep "
                                    "wrote), or a link to one")
    _no_file_above(flag, path, "cannot be a folder")


def check_out_file(flag: str, path) -> None:
    """An output file (written again when it exists): not a folder, not below a file, no NUL character."""
    if path is None:
        return
    path = _path_of(flag, path)
    if path.is_dir():
        raise ConfigError(flag, f"{path} is a folder; expected a file to write (e.g. {path / 'posteriors.csv'})")
    _no_file_above(flag, path, "cannot be written below it")


def _path_of(flag: str, path) -> Path:
    text = str(path)
    if "\0" in text:
        raise ConfigError(flag, f"got {text!r}; a path cannot contain a NUL character")
    return Path(path)


def _no_file_above(flag: str, path: Path, what: str) -> None:
    """The nearest existing folder above ``path`` is a folder, not a file."""
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise ConfigError(flag, f"{parent} is a file, so {path} {what}")
            break


def _broken_link(path: Path) -> str:
    """How ``path`` is a symbolic link that leads to no file ('to X, which does not exist', 'in a loop'),
    or '' (not a link, or a link that leads somewhere)."""
    if not path.is_symlink():
        return ""
    try:
        os.stat(path)
    except FileNotFoundError:
        return f"to {os.readlink(path)!r}, which does not exist"
    except OSError as err:
        if err.errno == errno.ELOOP:
            return "in a loop (it leads back to itself)"
        return f"that cannot be followed ({err.strerror})"
    return ""


class _Line(logging.Handler):
    def emit(self, record) -> None:
        print(f"flocksweep: warning: {record.getMessage()}", file=sys.stderr)


def show_warnings() -> None:
    """Print the flocksweep logger's warnings as 'flocksweep: warning: ...' (once per process)."""
    log = logging.getLogger("flocksweep")
    if not any(isinstance(h, _Line) for h in log.handlers):
        log.addHandler(_Line(logging.WARNING))
