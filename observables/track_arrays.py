"""Tracks held in arrays, read by a declared layout: MATLAB ``.mat`` files (format ``mat``: v4 to v7 through
scipy.io, v7.3 through h5py) and numpy ``.npy``/``.npz`` files (format ``npy``).

``read_arrays(path, fmt, layout) -> (frame, defaults)`` gives the long table of :mod:`.track_formats` (one
row per sample, columns named by role) and the settings the layout implies. The layout (``--layout
KEY=VALUE ...`` or ``layout = {...}``; any other key is refused with a did-you-mean) says what the array is:

* a **cube** (3 dimensions): ``channels`` names each channel by role (x, y, z, vx, vy, vz, t), ``-`` for a
  channel to skip (``channels = "x,y,vx,vy,-,-,-"``: accelerations and more after the velocities), or
  picks channels by index (``channels = "x:0,y:1,vx:2,vy:3"``, the rest skipped); ``axes`` orders the
  dimensions (a permutation of individual, channel and sample; default ``individual,channel,sample``);
  ``time`` names a variable of one time per sample; without a ``t`` channel or ``time`` the sample index
  is the frame number (``fps``). Individual k of the array (from 0) is id k + 1;
* a **detection table** (2 dimensions, one row per individual per sample): ``columns`` names each
  column by role (flock, id, t or frame, x, y, z, vx, vy, vz; ``-`` to skip, or ``role:index``); ``t`` is
  in ``units.time`` (default seconds), ``frame`` in frames (``fps``); ``axes = "column,detection"`` reads
  a table stored one column per detection (MATLAB's transposed export);
* ``variable`` names the array (``.mat``: its variable; ``.npz``: its key; not for ``.npy``, which holds
  one); by default the file's only numeric array of the layout's kind.

nan positions are missed detections. Before anything is read, every array's declared shape and type are
checked against the file's size (an uncompressed array cannot hold more bytes than its file, a compressed
one more than :data:`DEFLATE_RATIO` times them, HDF5 no more than it stores), so a 2 KB file declaring a
huge array is refused before memory is allocated. A file whose arrays fit no layout is refused with a
message listing the arrays it holds and the layouts (or the long CSV) that would read them. Only numeric
arrays are read: text, cells, structs and object arrays are never converted.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flocksweep.simcore.schema import ConfigError, suggest

from .npy_file import DEFLATE_RATIO

if TYPE_CHECKING:
    import pandas as pd

AXES = ("individual", "channel", "sample")
TABLE_AXES = ("detection", "column")
CHANNELS = ("x", "y", "z", "vx", "vy", "vz", "t")
TABLE_ROLES = ("flock", "id", "t", "frame", "x", "y", "z", "vx", "vy", "vz")
LAYOUT_KEYS = ("variable", "axes", "channels", "columns", "time")
SKIP = "-"
MAT_CLASSES = {"double": 8, "single": 4, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2, "int32": 4, "uint32": 4,
               "int64": 8, "uint64": 8, "logical": 1}
ROUTES = ("a 3-D array (individuals x channels x samples in any order) with --layout channels=x,y,vx,vy "
          "[axes=...] (- skips a channel); a 2-D detection table (one row per individual per sample) with "
          "--layout columns=id,t,x,y,z,... (- skips a column); or export a long CSV (one row per detection: "
          "id, t, x, y[, z])")


@dataclass(frozen=True)
class ArrayInfo:
    """An array as a file declares it, before it is read."""

    name: str
    shape: tuple
    kind: str          # "numeric" or what it is instead ("char", "cell", "struct", "object", ...)
    nbytes: int        # declared size of its data

    def describe(self) -> str:
        return f"{self.name} ({' x '.join(map(str, self.shape)) or 'scalar'}{'' if self.kind == 'numeric' else ', ' + self.kind})"


# ---------------------------------------------------------------------------------------------- headers

def _mat_version(path: Path) -> int:
    import scipy.io
    try:
        return scipy.io.matlab.matfile_version(str(path))[0]
    except Exception as err:  # noqa: BLE001 - an unreadable file is the user's input problem
        raise ConfigError(str(path), f"cannot read it as a MATLAB .mat file: {err}") from None


def _hdf5_infos(path: Path) -> dict:
    import h5py
    infos = {}
    with h5py.File(path, "r") as handle:
        for name, item in handle.items():
            if not isinstance(item, h5py.Dataset):
                infos[name] = ArrayInfo(name, (), "group", 0)
                continue
            numeric = item.dtype.kind in "fiub"
            nbytes = int(np.prod(item.shape, dtype=object)) * item.dtype.itemsize
            stored = item.id.get_storage_size()
            if numeric and nbytes > DEFLATE_RATIO * max(stored, 1):
                raise ConfigError(str(path), f"variable {name!r} declares {tuple(reversed(item.shape))} "
                                             f"({nbytes:,} bytes) but the file stores {stored:,} bytes of it: a "
                                             "damaged or crafted file (refused before reading)")
            infos[name] = ArrayInfo(name, tuple(reversed(item.shape)), "numeric" if numeric else str(item.dtype),
                                    nbytes)
    return infos


def _mat_infos(path: Path) -> dict:
    import h5py
    import scipy.io
    if h5py.is_hdf5(path):     # v7.3: HDF5, arrays stored with their dimensions reversed
        try:
            return _hdf5_infos(path)
        except ConfigError:
            raise
        except Exception as err:  # noqa: BLE001
            raise ConfigError(str(path), f"cannot read it as a MATLAB 7.3 (HDF5) file: {err}") from None
    version = _mat_version(path)
    try:
        listed = scipy.io.whosmat(str(path))
    except Exception as err:  # noqa: BLE001
        raise ConfigError(str(path), f"cannot read it as a MATLAB .mat file: {err}") from None
    limit = os.path.getsize(path) * (1 if version == 0 else DEFLATE_RATIO)
    infos = {}
    for name, shape, kind in listed:
        itemsize = MAT_CLASSES.get(kind)
        nbytes = int(np.prod(shape, dtype=object)) * (itemsize or 1)
        if nbytes > limit:
            raise ConfigError(str(path), f"variable {name!r} declares {tuple(shape)} ({nbytes:,} bytes), more than "
                                         f"a file of {os.path.getsize(path):,} bytes can hold: a damaged or crafted "
                                         "file (refused before reading)")
        infos[name] = ArrayInfo(name, tuple(shape), "numeric" if itemsize else kind, nbytes)
    return infos


def _npy_infos(path: Path) -> dict:
    from .npy_file import NotData, npy_header, npz_headers
    try:
        if path.suffix.lower() == ".npz":
            headers = npz_headers(path)
        else:
            headers = {"": npy_header(path)}
    except (NotData, ValueError) as err:
        raise ConfigError(str(path), f"cannot read it as numpy arrays: {err}") from None
    return {name or path.name: ArrayInfo(name or path.name, shape, "numeric" if dtype.kind in "fiub" else
                                         ("object" if dtype.hasobject else f"{dtype}"), nbytes)
            for name, (shape, dtype, nbytes) in headers.items()}


def array_infos(path, fmt: str) -> dict:
    """Every array of a ``mat`` or ``npy`` file as declared (name -> :class:`ArrayInfo`), checked against the
    file's size; nothing is read."""
    path = Path(path)
    return _mat_infos(path) if fmt == "mat" else _npy_infos(path)


def _read(path: Path, fmt: str, names: list) -> dict:
    """The named numeric arrays (declared sizes already checked), as float64 where they are not integers."""
    import h5py
    import scipy.io
    try:
        if fmt == "npy":
            from .npy_file import read_npy, read_npz
            if path.suffix.lower() == ".npz":
                return read_npz(path, names)
            return {names[0]: read_npy(path)}
        if h5py.is_hdf5(path):
            with h5py.File(path, "r") as handle:
                return {name: np.asarray(handle[name]).T for name in names}
        data = scipy.io.loadmat(str(path), variable_names=names)
        return {name: data[name] for name in names}
    except Exception as err:  # noqa: BLE001 - an unreadable file is the user's input problem
        raise ConfigError(str(path), f"cannot read {', '.join(n or path.name for n in names)}: {err}") from None


# ---------------------------------------------------------------------------------------------- layouts

def _items(layout: dict, key: str, allowed: tuple) -> list:
    """The roles of ``layout[key]`` by position (``-`` skips), from "role,role,-" or "role:index,..."."""
    text = str(layout[key])
    parts = [p.strip() for p in text.split(",")]
    indexed = [p for p in parts if ":" in p]
    if indexed and len(indexed) != len(parts):
        raise ConfigError(f"layout.{key}", f"got {text!r}; name every item by position (role or -) or every one by "
                                           "index (role:index), not both")
    if indexed:
        picks = {}
        for part in parts:
            role, _, index = part.partition(":")
            if not index.strip().isdigit():
                raise ConfigError(f"layout.{key}", f"got {part!r}; expected role:index with a whole index from 0")
            picks[int(index)] = role.strip()
        roles = [SKIP] * (max(picks) + 1)
        for index, role in picks.items():
            if roles[index] != SKIP:
                raise ConfigError(f"layout.{key}", f"index {index} is named twice")
            roles[index] = role
    else:
        roles = parts
    for role in roles:
        if role != SKIP and role not in allowed:
            raise ConfigError(f"layout.{key}", f"unknown role {role!r}{suggest(role, allowed)}; roles: "
                                               f"{', '.join(allowed)}, or {SKIP} to skip one")
    named = [r for r in roles if r != SKIP]
    twice = sorted({r for r in named if named.count(r) > 1})
    if twice:
        raise ConfigError(f"layout.{key}", f"role {twice[0]!r} is named twice")
    missing = [r for r in ("x", "y") if r not in named]
    if missing:
        raise ConfigError(f"layout.{key}", f"got {text!r}; needs x and y (missing: {', '.join(missing)})")
    return roles


def _fit_count(roles: list, count: int, key: str, what: str, indexed: bool) -> list:
    """``roles`` for an axis of ``count`` entries: indexed picks are padded with skips; positional names
    must match the count."""
    if indexed and len(roles) <= count:
        return roles + [SKIP] * (count - len(roles))
    if len(roles) != count:
        fix = ",".join(roles + [SKIP] * (count - len(roles))) if len(roles) < count else ""
        hint = (f" (name the others {SKIP} to skip them: {fix})" if fix else
                f" (the array has only {count})")
        raise ConfigError(f"layout.{key}", f"names {len(roles)} {what}, the array has {count}{hint}")
    return roles


def check_layout(layout: dict | None) -> dict:
    """The layout with its keys checked (an unknown key is refused with a did-you-mean)."""
    layout = dict(layout or {})
    for key in layout:
        if key not in LAYOUT_KEYS:
            raise ConfigError(f"layout.{key}", f"unknown layout key{suggest(key, LAYOUT_KEYS)}; keys: "
                                               f"{', '.join(LAYOUT_KEYS)}")
    if "channels" in layout and "columns" in layout:
        raise ConfigError("layout", "give channels (a 3-D array) or columns (a 2-D detection table), not both")
    return layout


def _refusal(path: Path, infos: dict, why: str) -> ConfigError:
    held = ", ".join(i.describe() for i in infos.values()) or "no arrays"
    return ConfigError(str(path), f"{why}; it holds: {held}. Routes that read tracks from arrays: {ROUTES}")


def _choose(path: Path, infos: dict, layout: dict, ndim: int) -> ArrayInfo:
    variable = layout.get("variable")
    numeric = {k: v for k, v in infos.items() if v.kind == "numeric"}
    if variable is not None:
        if path.suffix.lower() == ".npy":
            raise ConfigError("layout.variable", f"a .npy file holds one array ({path.name}); variable is for .mat "
                                                 "and .npz files")
        if variable not in infos:
            raise ConfigError("layout.variable", f"got {variable!r}{suggest(variable, infos)}; {path.name} holds: "
                                                 f"{', '.join(i.describe() for i in infos.values()) or 'nothing'}")
        if variable not in numeric:
            raise ConfigError("layout.variable", f"{infos[variable].describe()} is not a numeric array")
        info = numeric[variable]
    else:
        fitting = [v for v in numeric.values() if len(v.shape) == ndim and min(v.shape, default=0) > 1]
        if len(fitting) != 1:
            kind = "3-D arrays" if ndim == 3 else "2-D tables (both sides > 1)"
            raise _refusal(path, infos, f"{len(fitting)} numeric {kind} "
                                        f"({', '.join(v.name for v in fitting) or 'none'}): name one with "
                                        "layout variable=NAME" if fitting else
                                        f"no numeric {kind} for this layout")
        info = fitting[0]
    if len(info.shape) != ndim:
        raise ConfigError("layout", f"{info.describe()} has {len(info.shape)} dimensions; "
                                    + ("channels are for 3-D arrays (a 2-D detection table takes columns=...)"
                                       if ndim == 3 else "columns are for 2-D detection tables (a 3-D array "
                                                         "takes channels=...)"))
    return info


def _axes(layout: dict, allowed: tuple) -> tuple:
    default = ",".join(allowed)
    axes = tuple(a.strip() for a in str(layout.get("axes", default)).split(","))
    if sorted(axes) != sorted(allowed):
        raise ConfigError("layout.axes", f"got {layout.get('axes')!r}; expected the order of {' and '.join(allowed)}"
                                         f", e.g. '{default}'")
    return axes


def long_table(ids, values: dict, keep) -> pd.DataFrame:
    """Individual-major long table of (individuals, samples) arrays, samples kept where ``keep``."""
    import pandas as pd
    n, s = keep.shape
    frame = {"id": np.repeat(np.asarray(ids), s)[keep.reshape(-1)]}
    for role, array in values.items():
        frame[role] = np.broadcast_to(array, (n, s)).reshape(-1)[keep.reshape(-1)]
    return pd.DataFrame(frame)


def _cube(path: Path, fmt: str, infos: dict, layout: dict) -> tuple[pd.DataFrame, dict]:
    info = _choose(path, infos, layout, 3)
    axes = _axes(layout, AXES)
    count = info.shape[axes.index("channel")]
    roles = _fit_count(_items(layout, "channels", CHANNELS), count, "channels", "channels",
                       ":" in str(layout["channels"]))
    names = [info.name] + ([layout["time"]] if layout.get("time") else [])
    if layout.get("time") and layout["time"] not in infos:
        raise ConfigError("layout.time", f"got {layout['time']!r}{suggest(layout['time'], infos)}; {path.name} "
                                         f"holds: {', '.join(infos)}")
    arrays = _read(path, fmt, names)
    cube = np.transpose(np.asarray(arrays[info.name], dtype=np.float64), [axes.index(a) for a in AXES])
    n, _, s = cube.shape
    values = {role: cube[:, k, :] for k, role in enumerate(roles) if role != SKIP}
    defaults = {}
    if "t" not in values:
        if layout.get("time"):
            times = np.asarray(arrays[layout["time"]], dtype=np.float64).reshape(-1)
            if times.size != s:
                raise ConfigError("layout.time", f"got {layout['time']!r} ({times.size} values); expected one time "
                                                 f"per sample ({s}) in {path.name}")
            values["t"] = times[None, :]
        else:
            values["t"] = np.arange(s, dtype=np.float64)[None, :]
            defaults["units"] = {"time": "frame"}
    skipped = [k for k, role in enumerate(roles) if role == SKIP]
    return long_table(np.arange(1, n + 1), values, np.ones((n, s), dtype=bool)), defaults | (
        {"skipped": f"channels {', '.join(map(str, skipped))} of {info.name!r} skipped"} if skipped else {})


def _whole(values: np.ndarray) -> np.ndarray:
    """Ids as integers when every one is a whole number (1.0 -> 1), else as they are."""
    finite = np.isfinite(values)
    if finite.all() and np.array_equal(values, np.round(values)) and np.abs(values).max(initial=0) < 2 ** 53:
        return values.astype(np.int64)
    return values


def _table(path: Path, fmt: str, infos: dict, layout: dict) -> tuple[pd.DataFrame, dict]:
    import pandas as pd
    info = _choose(path, infos, layout, 2)
    axes = _axes(layout, TABLE_AXES)
    count = info.shape[axes.index("column")]
    roles = _fit_count(_items(layout, "columns", TABLE_ROLES), count, "columns", "columns",
                       ":" in str(layout["columns"]))
    if "t" in roles and "frame" in roles:
        raise ConfigError("layout.columns", "name one clock: t (seconds, units.time) or frame (frame numbers, fps)")
    clock = "t" if "t" in roles else "frame" if "frame" in roles else None
    if clock is None or "id" not in roles:
        missing = [name for name, ok in (("id", "id" in roles), ("t or frame", clock)) if not ok]
        raise ConfigError("layout.columns", f"a detection table needs {' and '.join(missing)} (one row per "
                                            "individual per sample)")
    if "time" in layout:
        raise ConfigError("layout.time", "a detection table has its own time column (t or frame)")
    table = np.asarray(_read(path, fmt, [info.name])[info.name], dtype=np.float64)
    if axes[0] == "column":
        table = table.T
    frame = {}
    for k, role in enumerate(roles):
        if role == SKIP:
            continue
        column = table[:, k]
        frame["t" if role == "frame" else role] = _whole(column) if role in ("id", "flock") else column
    for role in ("id", "flock"):
        values = np.asarray(frame.get(role, np.zeros(0)), dtype=np.float64)
        if not np.isfinite(values).all():
            rows = np.flatnonzero(~np.isfinite(values)) + 1
            raise ConfigError(str(path), f"column {roles.index(role)} ({role}) of {info.name!r} is not a number at "
                                         f"rows {', '.join(map(str, rows[:8]))}")
    defaults = {"units": {"time": "frame"}} if clock == "frame" else {}
    skipped = [k for k, role in enumerate(roles) if role == SKIP]
    if skipped:
        defaults["skipped"] = f"columns {', '.join(map(str, skipped))} of {info.name!r} skipped"
    return pd.DataFrame(frame), defaults


def read_arrays(path, fmt: str, layout: dict | None) -> tuple[pd.DataFrame, dict]:
    """(the long table, the settings the layout implies) of a ``mat`` or ``npy`` file (module docstring)."""
    path = Path(path)
    layout = check_layout(layout)
    infos = array_infos(path, fmt)
    if "columns" in layout:
        return _table(path, fmt, infos, layout)
    if "channels" not in layout:
        cubes = [i for i in infos.values() if i.kind == "numeric" and len(i.shape) == 3]
        tables = [i for i in infos.values() if i.kind == "numeric" and len(i.shape) == 2 and min(i.shape) > 1]
        if tables and not cubes:
            raise _refusal(path, infos, "layout: no 3-D array to name channels of; a 2-D table is read as one row "
                                        "per detection with layout columns=... (e.g. columns=id,t,x,y,z)")
        name = layout.get("variable") or (cubes[0].name if len(cubes) == 1 else "the array")
        if not cubes and not tables:
            raise _refusal(path, infos, "no numeric array of 2 or 3 dimensions")
        raise ConfigError("layout.channels", f"missing: name the channels of {name!r} by role ({', '.join(CHANNELS)}; "
                                             f"{SKIP} skips one), e.g. channels=x,y,vx,vy")
    return _cube(path, fmt, infos, layout)
