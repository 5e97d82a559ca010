"""Quarantine: a stored file that cannot be read is moved aside with a warning, never deleted.

``quarantine(root, path, reason) -> Path`` moves ``path`` (a file inside the results folder ``root``) to
``<root>/quarantine/<its path relative to root>.<YYYYmmddTHHMMSS>`` (a counter is added when that name
exists) and logs a warning naming the file, the reason and where it went on the ``flocksweep`` logger
(:data:`log`; the command line prints it as ``flocksweep: warning: ...``). Only a process holding the
folder's lock moves files; readers report what they skipped (``warn``) and leave the folder alone.

Nothing under ``quarantine/`` is read again; the user may inspect it and delete it.
"""
from __future__ import annotations

import logging
import os
import time
from pathlib import Path

from .files import write_failed

FOLDER = "quarantine"
log = logging.getLogger("flocksweep")


def quarantine(root, path, reason: str, quiet: bool = False) -> Path:
    """Move ``path`` into ``<root>/quarantine/`` and log a warning (see the module docstring); ``quiet``:
    no warning (the caller says in one warning why several files went)."""
    root, path = Path(root), Path(path)
    relative = path.relative_to(root)
    target = root / FOLDER / relative.parent / f"{relative.name}.{time.strftime('%Y%m%dT%H%M%S')}"
    count = 1
    while target.exists():
        target = target.with_name(f"{relative.name}.{time.strftime('%Y%m%dT%H%M%S')}-{count}")
        count += 1
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(path, target)
    except OSError as err:
        raise write_failed(target, err) from None
    if not quiet:
        log.warning("%s %s; moved to %s", relative, reason, target.relative_to(root))
    return target


def warn(message: str, *args) -> None:
    """A warning on the ``flocksweep`` logger (for readers that skip what they cannot read)."""
    log.warning(message, *args)


def quarantined(root) -> list[Path]:
    """Every file in ``<root>/quarantine/`` (sorted)."""
    folder = Path(root) / FOLDER
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.is_dir() else []
