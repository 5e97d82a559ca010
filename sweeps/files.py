"""Atomic file writes and the one JSON convention of everything we store.

``atomic_path(path)`` yields a temporary path next to ``path`` (same suffix, so writers that pick a format
by extension work); on success it is fsynced and renamed onto ``path``. A reader (or a resumed run after
a crash) sees either the old file or the complete new one, never a partial write. ``write_text``,
``write_json``, ``write_csv`` and ``write_parquet`` write through it.

``json_ready(value)`` is the one conversion to JSON-ready data: numpy scalars and arrays become Python
numbers and lists, other unknown objects (paths, ...) their ``str``, and NaN and +-inf become ``None``
(JSON has no such numbers), everywhere and at any depth. ``write_json`` writes ``json_ready(data)``
with sorted keys, so a file never fails to write because a statistic is undefined.
"""
from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; on success it is renamed onto ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


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
    return json.loads(path.read_text()) if path.exists() else missing


def write_csv(path, frame, **options) -> None:
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, **options)


def write_parquet(path, frame) -> None:
    with atomic_path(path) as tmp:
        frame.to_parquet(tmp, index=False)
