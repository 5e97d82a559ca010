"""Atomic file writes and the one JSON convention of everything we store.

``atomic_path(path)`` yields a temporary path next to ``path`` (same suffix, so writers that pick a format
by extension work); on success it is fsynced and renamed onto ``path``. A reader (or a resumed run after
a crash) sees either the old file or the complete new one, never a partial write. ``write_text``,
``write_json``, ``write_csv`` and ``write_parquet`` write through it. The file gets the permissions any
new file gets here (0666 less the process umask), not the temporary file's 0600. Any ``OSError`` while
writing (disk full, read-only file system, permission) becomes :class:`WriteFailed` naming ``path`` and
the errno: an infrastructure fault, never a run's failure. Temporary files left by a killed writer are
hidden (``.<stem>.*.tmp<suffix>``) and ``remove_stale_temporaries(folder)`` clears them.

``read_json(path, missing)`` raises :class:`Unreadable` (a ``ValueError`` naming the file) for a file
that is not valid JSON.

``json_ready(value)`` is the one conversion to JSON-ready data: numpy scalars and arrays become Python
numbers and lists, other unknown objects (paths, ...) their ``str``, and NaN and +-inf become ``None``
(JSON has no such numbers), everywhere and at any depth. ``write_json`` writes ``json_ready(data)``
with sorted keys, so a file never fails to write because a statistic is undefined.

``user_cache(environ=None)`` is flocksweep's one cache folder for what is remembered across runs and
never part of results (status counts, JAX's compiled programs): ``$FLOCKSWEEP_CACHE_DIR``, else
``$XDG_CACHE_HOME/flocksweep``, else ``~/.cache/flocksweep``.
"""
from __future__ import annotations

import errno
import json
import os
import re
import tempfile
from contextlib import contextmanager
from pathlib import Path

TEMPORARY = re.compile(r"^\..+\.[a-z0-9_]{8}\.tmp(\.\w+)?$")   # what atomic_path's mkstemp names look like


def user_cache(environ=None) -> Path:
    """flocksweep's cache folder (module docstring), decided from ``environ`` (default ``os.environ``)."""
    environ = os.environ if environ is None else environ
    if environ.get("FLOCKSWEEP_CACHE_DIR"):
        return Path(environ["FLOCKSWEEP_CACHE_DIR"])
    return Path(environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "flocksweep"


class WriteFailed(OSError):
    """Writing a results file failed: ``filename`` is the file, ``errno``/``strerror`` say why."""

    def __str__(self) -> str:
        if self.errno is None:
            return f"cannot write {self.filename}: {self.strerror}"
        name = errno.errorcode.get(self.errno, "")
        code = f"{name}, errno {self.errno}" if name else f"errno {self.errno}"
        return f"cannot write {self.filename}: {self.strerror} ({code})"


class Unreadable(ValueError):
    """A stored file exists but cannot be read (truncated, garbage, wrong format)."""


def write_failed(path, err: OSError) -> WriteFailed:
    """``err`` (raised while writing ``path``) as a :class:`WriteFailed` naming ``path``."""
    if isinstance(err, WriteFailed):
        return err
    code = err.errno if isinstance(err.errno, int) else _errno_in(str(err))
    reason = err.strerror or (os.strerror(code) if code else str(err))
    return WriteFailed(code, reason, str(path))


def _errno_in(text: str) -> int | None:
    """The errno a library quoted in its message ('[Errno 28]', 'errno = 28', 'errno 28'), if any."""
    found = re.search(r"errno\s*=?\s*(\d+)", text, re.IGNORECASE)
    return int(found.group(1)) if found else None


def umask() -> int:
    """This process' umask now (read without changing it where /proc allows)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    current = os.umask(0o022)
    os.umask(current)
    return current


@contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; on success it is renamed onto ``path``."""
    path = Path(path)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=path.parent)
        os.close(fd)
        os.chmod(tmp, 0o666 & ~umask())
        yield Path(tmp)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except OSError as err:
        raise write_failed(path, err) from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def remove_stale_temporaries(folder) -> list[Path]:
    """Remove the temporary files a killed writer left in ``folder`` (not recursive); returns them."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    stale = [p for p in folder.iterdir() if p.is_file() and TEMPORARY.match(p.name)]
    for path in stale:
        path.unlink(missing_ok=True)
    return stale


def json_ready(value):
    """JSON-ready copy of ``value`` (see the module docstring)."""
    def default(obj):
        return obj.tolist() if hasattr(obj, "tolist") else str(obj)
    return json.loads(json.dumps(value, default=default), parse_constant=lambda _: None)


def write_text(path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_json(path, data) -> None:
    write_text(path, json.dumps(json_ready(data), indent=2, sort_keys=True, allow_nan=False) + "\n")


def read_json(path, missing=None):
    """The parsed JSON file at ``path``, or ``missing`` when there is none."""
    path = Path(path)
    if not path.exists():
        return missing
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as err:
        raise Unreadable(f"{path}: not valid JSON ({err})") from None


def write_csv(path, frame, **options) -> None:
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, **options)


def write_parquet(path, frame) -> None:
    with atomic_path(path) as tmp:
        frame.to_parquet(tmp, index=False)
