"""The persistent compilation cache of flocksweep's JAX work (the npe flows, :mod:`analysis.calibration.npe_flow`):
XLA's compiled programs kept on disk in the user's cache folder, so that a second process (a second
``flocksweep posterior``, a second calibration's flows) loads them instead of compiling them again.

Contract
--------
``cache_setting(environ=os.environ) -> CacheSetting(folder, source)``: the decision, made from the
environment alone (no JAX import):

* ``FLOCKSWEEP_JAX_CACHE`` = ``0`` / ``off`` / ``false`` / ``no``: off (``folder`` None, ``source``
  ``"FLOCKSWEEP_JAX_CACHE"``): flocksweep sets nothing, JAX compiles in every process as it does by default;
* otherwise, ``JAX_COMPILATION_CACHE_DIR`` set: the user's own JAX cache (``source``
  ``"JAX_COMPILATION_CACHE_DIR"``); JAX reads it itself and flocksweep changes none of JAX's options (the
  same when the caller's code set ``jax.config``'s ``jax_compilation_cache_dir`` before: :func:`enable_cache`);
* otherwise flocksweep's own folder, ``<user cache>/jax/jax-<version>-jaxlib-<version>/`` where the user
  cache is ``$FLOCKSWEEP_CACHE_DIR``, else ``$XDG_CACHE_HOME/flocksweep``, else ``~/.cache/flocksweep``
  (the folder ``flocksweep status`` remembers its counts in): one subfolder per installed jax and jaxlib, so
  an upgrade starts a fresh one and never reads the old one's programs (JAX keys each entry itself by the
  program, the compiler's options, the jax version and the backend; the subfolder is a second guard and
  makes old entries easy to delete).

``enable_cache(jax) -> CacheSetting``: applies the setting to the imported ``jax`` module, once per process,
before its first compilation (``npe_flow.require_jax`` calls it: the cache is turned on when a calibration
or a posterior starts JAX work, never when a module is imported). flocksweep's own folder is created
private to the user (mode 0700); a folder that exists but is owned by someone else or writable by others is
not used (JAX runs what its cache holds: a cache others can write is code they can run), with one line on
stderr. Every program is kept, however quick its compile (``jax_persistent_cache_min_compile_time_secs``
0: the flows' many small programs add up to most of their compile time). Sibling version subfolders
unused for :data:`STALE_DAYS` days are removed. A cache that cannot be set up (a read-only home) is
skipped: JAX compiles as without it, the results are the same.

A program read from the cache is the one XLA would compile again (the cache key covers the program and
every compiler option), so results are bit for bit those of a fresh compile.
"""
from __future__ import annotations

import os
import shutil
import stat
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from flocksweep.sweeps.files import user_cache

SWITCH = "FLOCKSWEEP_JAX_CACHE"
JAX_OWN = "JAX_COMPILATION_CACHE_DIR"
OFF = ("0", "off", "false", "no")
STALE_DAYS = 30             # a version subfolder unused this long is removed (an old jax's programs)


@dataclass(frozen=True)
class CacheSetting:
    """Where JAX's compiled programs go (``folder`` None: flocksweep sets no cache) and what decided it."""

    folder: Path | None
    source: str

    def describe(self) -> str:
        if self.source == SWITCH:
            return f"off ({SWITCH}=0)"
        if self.source == JAX_OWN:
            return f"{self.folder} (your {JAX_OWN})"
        return f"{self.folder}" + ("" if self.folder else " (off: the cache folder could not be used)")


def version_folder() -> str:
    """``jax-<version>-jaxlib-<version>`` of the installed packages, read from their metadata (no import)."""
    from importlib.metadata import PackageNotFoundError, version

    def installed(name):
        try:
            return version(name)
        except PackageNotFoundError:
            return "none"
    return f"jax-{installed('jax')}-jaxlib-{installed('jaxlib')}"


def cache_setting(environ=None) -> CacheSetting:
    """The cache this process uses (module docstring), decided from ``environ`` alone."""
    environ = os.environ if environ is None else environ
    if environ.get(SWITCH, "").strip().lower() in OFF:
        return CacheSetting(None, SWITCH)
    if environ.get(JAX_OWN):
        return CacheSetting(Path(environ[JAX_OWN]), JAX_OWN)
    return CacheSetting(user_cache(environ) / "jax" / version_folder(), "flocksweep")


def private_folder(folder: Path) -> bool:
    """Create ``folder`` (mode 0700) when missing; True when it is a folder of this user that no one else
    may write, the only kind JAX's cache may live in."""
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = folder.stat()
    except OSError:
        return False
    owner_ok = not hasattr(os, "getuid") or info.st_uid == os.getuid()
    return stat.S_ISDIR(info.st_mode) and owner_ok and not info.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def remove_stale(folder: Path, days: float = STALE_DAYS) -> list[Path]:
    """Remove the sibling version subfolders of ``folder`` not used for ``days`` days (their modification
    time: a folder in use is touched by :func:`enable_cache`); the removed folders."""
    removed = []
    limit = time.time() - days * 86400
    try:
        siblings = [p for p in folder.parent.iterdir() if p != folder and p.name.startswith("jax-") and p.is_dir()]
    except OSError:
        return removed
    for sibling in siblings:
        try:
            if sibling.stat().st_mtime < limit:
                shutil.rmtree(sibling)
                removed.append(sibling)
        except OSError:
            continue
    return removed


_ENABLED: list[CacheSetting] = []


def enable_cache(jax) -> CacheSetting:
    """Apply :func:`cache_setting` to the imported ``jax`` (once per process; module docstring)."""
    if _ENABLED:
        return _ENABLED[0]
    setting = cache_setting()
    if setting.source == "flocksweep" and jax.config.jax_compilation_cache_dir:   # set by the caller's own code
        setting = CacheSetting(Path(jax.config.jax_compilation_cache_dir), JAX_OWN)
    if setting.source == "flocksweep":
        if private_folder(setting.folder):
            os.utime(setting.folder)
            remove_stale(setting.folder)
            jax.config.update("jax_compilation_cache_dir", str(setting.folder))
            jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
            jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
        else:
            print(f"flocksweep: JAX's compilation cache {setting.folder} is not a private folder of yours (or "
                  f"cannot be created): not used, the flows compile in this process (set {SWITCH}=0 to silence "
                  f"this, or {JAX_OWN} to a folder of your own)", file=sys.stderr)
            setting = CacheSetting(None, "flocksweep")
    _ENABLED.append(setting)
    return setting
