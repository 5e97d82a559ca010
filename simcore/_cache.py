"""Keeping numba's on-disk cache in step with the sources.

numba checks only the timestamp of the file that defines a cached function, but the run loop in
``kernel.py`` inlines code from ``perception.py``, ``rules.py``, ``dynamics.py`` and the rest, so an edit
there would otherwise be served from a stale cache. Nor does numba record the name a module was imported
under, and a cached kernel refers to the modules it uses by name: one compiled when the layers were
top-level packages (``observables.kernels``) fails to load under ``flocksweep.observables``.
``refresh(package_dir, package)`` hashes every ``*.py`` of the package together with its import name and,
when the hash differs from the one recorded in ``__pycache__``, removes the package's cached kernels
(``*.nbi``, ``*.nbc``) before anything loads them, then records the new hash. Every package with
compiled kernels calls it on import (``simcore``, ``observables``). It touches
nothing but those files, never raises, and costs a millisecond. (With ``NUMBA_CACHE_DIR`` set, numba
keeps its cache elsewhere and the cleaning is left to the user.)
"""
from __future__ import annotations

import hashlib
from pathlib import Path

STAMP = "flocksweep-sources.sha256"


def sources_digest(package_dir: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(package_dir.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def refresh(package_dir, package: str = "") -> bool:
    """Drop stale cached kernels of ``package_dir`` (imported as ``package``); returns True when it removed
    anything."""
    package_dir = Path(package_dir)
    cache = package_dir / "__pycache__"
    try:
        digest = sources_digest(package_dir) + (f" {package}" if package else "")
        stamp = cache / STAMP
        if stamp.exists() and stamp.read_text().strip() == digest:
            return False
        removed = False
        for path in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            path.unlink(missing_ok=True)
            removed = True
        cache.mkdir(exist_ok=True)
        tmp = cache / f".{STAMP}.tmp"
        tmp.write_text(digest)
        tmp.replace(stamp)
        return removed
    except OSError:
        return False
