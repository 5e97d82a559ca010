"""Initial state from a file: ``init.from_file = "state.npz"`` (and ``flocksweep simulate --init-state``).

The file is a numpy ``.npz`` archive with, for N boids:

* ``pos``     float (N, 3): positions (required);
* ``vel``     float (N, 3): velocities, headings taken as vel/|vel| (no boid may be at rest), **or**
  ``fwd`` float (N, 3) unit headings with ``speed`` float (N,) >= 0 (a boid may rest, keeping its heading);
* ``up``      float (N, 3), optional: unit up vectors orthogonal to ``fwd`` (default: world y made
  orthogonal to the heading, OpenSteer's reset); side = normalize(fwd x up);
* ``acc``     float (N, 3), optional: smoothed accelerations (default zeros);
* ``pattern`` integer (N,), optional: bit patterns, used in pattern mode (default: drawn from the seed).

A trajectory written by ``flocksweep simulate --out`` (``pos``, ``vel`` of shape (R, N, 3)) is accepted
too: its last record is used, so a run can be continued (its other arrays are ignored). Unit vectors must
be unit to 1e-5 and up orthogonal to fwd to 1e-5 (:data:`simcore.schema.FILE_UNIT_TOLERANCE`:
single-precision frames pass); values are used as given, not renormalised, so
a state exported from another simulator is reproduced exactly. Every problem is a
:class:`~simcore.schema.ConfigError` naming ``init.from_file``, the array and what is wrong.

Relative paths are relative to the working directory. The file's SHA-256 is part of the resolved spec
(``init.from_file_sha256``), so a changed file makes new run ids, and a run refuses a file whose content
no longer matches its spec.
"""
from __future__ import annotations

import functools
import hashlib
import os
import zipfile
from pathlib import Path

import numpy as np

from .schema import FILE_UNIT_TOLERANCE, ConfigError, input_file

KEY = "init.from_file"
STATE_LIMIT = 4 << 30   # bytes: 10^7 boids' pos, vel, up, acc in float64 are about 1 GiB


def file_digest(path) -> str:
    """SHA-256 (hex) of the file's bytes."""
    return _cached(str(path))[1]


def boid_count(path) -> int:
    """Number of boids in a state file (validated)."""
    return len(_cached(str(path))[0]["pos"])


def read_state_file(path) -> dict:
    """Validated arrays of a state file: pos, vel, fwd, up (or None), acc (or None), pattern (or None)."""
    return dict(_cached(str(path))[0])


def _cached(path: str):
    try:
        os.stat(path)
    except (OSError, ValueError):
        raise ConfigError(KEY, f"got {path!r}: no such file (relative paths start at the working directory "
                               f"{os.getcwd()})") from None
    stat = input_file(path, KEY, "the state file", STATE_LIMIT)   # no folder, FIFO, device; bounded size
    return _read(os.path.abspath(path), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=16)
def _read(path: str, mtime_ns: int, size: int):
    data = Path(path).read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    try:
        with np.load(path, allow_pickle=False) as archive:
            raw = {name: np.asarray(archive[name]) for name in archive.files}
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        raise ConfigError(KEY, f"{path}: not a readable .npz archive ({err})") from None
    return _validate(path, raw), digest


def _array(path, raw, name, shape_tail, n=None):
    """Array ``name`` as float64 with shape (N,) + shape_tail, the last record of a (R, N, ...) trajectory."""
    value = raw[name]
    want = len(shape_tail) + 1
    if value.ndim == want + 1 and name in ("pos", "vel"):
        value = value[-1]
    if value.ndim != want or value.shape[1:] != shape_tail or (n is not None and len(value) != n):
        expected = f"({'N' if n is None else n}{''.join(', ' + str(s) for s in shape_tail)})"
        raise ConfigError(KEY, f"{path}: '{name}' has shape {raw[name].shape}; expected {expected}")
    if not np.issubdtype(value.dtype, np.number) or np.iscomplexobj(value):
        raise ConfigError(KEY, f"{path}: '{name}' has dtype {value.dtype}; expected real numbers")
    value = value.astype(np.float64)
    if not np.isfinite(value).all():
        raise ConfigError(KEY, f"{path}: '{name}' has non-finite values")
    return np.ascontiguousarray(value)


def _check_unit(path, name, v):
    length = np.sqrt((v * v).sum(axis=1))
    bad = np.flatnonzero(np.abs(length - 1.0) > FILE_UNIT_TOLERANCE)
    if len(bad):
        raise ConfigError(KEY, f"{path}: '{name}' of boid {bad[0]} has length {length[bad[0]]!r}; expected unit "
                               f"vectors (to {FILE_UNIT_TOLERANCE})")


def _validate(path, raw) -> dict:
    # a state's arrays, and the others of a trajectory file (sweeps.trajectory), whose last record is used
    known = {"pos", "vel", "fwd", "speed", "up", "acc", "pattern", "times", "visible", "binocular", "leader", "seed",
             "predator", "prey"}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ConfigError(KEY, f"{path}: unknown arrays {unknown}; allowed: pos, vel or fwd + speed, up, acc, "
                               "pattern")
    if "pos" not in raw:
        raise ConfigError(KEY, f"{path}: no 'pos' array (positions, shape (N, 3))")
    pos = _array(path, raw, "pos", (3,))
    n = len(pos)
    if n < 1:
        raise ConfigError(KEY, f"{path}: 'pos' holds no boid")
    if "vel" in raw and ("fwd" in raw or "speed" in raw):
        raise ConfigError(KEY, f"{path}: give either 'vel' or 'fwd' and 'speed', not both")
    if "vel" in raw:
        vel = _array(path, raw, "vel", (3,), n)
        speed = np.sqrt((vel * vel).sum(axis=1))
        if (speed == 0.0).any():
            raise ConfigError(KEY, f"{path}: boid {int(np.argmax(speed == 0.0))} has zero velocity, so no heading; "
                                   "give 'fwd' and 'speed' instead of 'vel'")
        fwd = vel / speed[:, None]
    elif "fwd" in raw and "speed" in raw:
        fwd = _array(path, raw, "fwd", (3,), n)
        _check_unit(path, "fwd", fwd)
        speed = _array(path, raw, "speed", (), n)
        if (speed < 0).any():
            raise ConfigError(KEY, f"{path}: 'speed' has negative values")
        vel = fwd * speed[:, None]
    else:
        raise ConfigError(KEY, f"{path}: no velocities: give 'vel' (N, 3), or 'fwd' (N, 3) and 'speed' (N,)")
    up = None
    if "up" in raw:
        up = _array(path, raw, "up", (3,), n)
        _check_unit(path, "up", up)
        along = np.abs((fwd * up).sum(axis=1))
        if (along > FILE_UNIT_TOLERANCE).any():
            raise ConfigError(KEY, f"{path}: 'up' of boid {int(np.argmax(along))} is not orthogonal to its heading "
                                   f"(|fwd . up| = {along.max()!r})")
    acc = _array(path, raw, "acc", (3,), n) if "acc" in raw else None
    pattern = None
    if "pattern" in raw:
        value = raw["pattern"]
        if value.shape != (n,) or not np.issubdtype(value.dtype, np.integer) or (value < 0).any() or \
                (value > 0xFFFFFFFF).any():
            raise ConfigError(KEY, f"{path}: 'pattern' must be {n} integers in [0, 2^32); got shape {value.shape}, "
                                   f"dtype {value.dtype}")
        pattern = value.astype(np.uint32)
    return {"pos": pos, "vel": vel, "fwd": np.ascontiguousarray(fwd), "up": up, "acc": acc, "pattern": pattern}
