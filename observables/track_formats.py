"""Track files as trackers and loggers write them, each turned into the long table of :mod:`.tracks`.

``read_table(path, fmt)`` reads a long CSV or Parquet file as it is; ``read_wide(path, fmt, source) -> (frame, defaults)``: ``frame`` has one row per sample and columns named
by role (``id``, ``t``, ``x``, ``y`` and, when the file has them, ``flock``, ``z``, ``vx``, ``vy``,
``vz``); ``defaults`` are the settings the file implies (``units``, ``fps``, ``body_length_px``), which
what the user gives overrides. Rows are numbered in the order of that table. The formats
(``detect_format`` picks one from the file when ``format = "auto"``):

* ``mat``: MATLAB .mat, v4 to v7 (scipy.io) and v7.3 (HDF5, h5py), holding one numeric array of a
  declared layout, ``layout = {variable = "tracks", axes = "individual,channel,sample",
  channels = "x,y,vx,vy"}``: ``axes`` orders the array's dimensions (a permutation of individual,
  channel and sample; default as shown), ``channels`` names each channel by role (x, y, z, vx, vy, vz,
  t), ``variable`` names the array (default: the file's only numeric array of 3 dimensions). Without a
  ``t`` channel the times are ``layout.time`` (a variable of one time per sample) or the sample index
  in frames (``fps``). nan positions are missed detections.
* ``idtracker``: idtracker.ai's ``trajectories.npy`` (a dictionary saved by numpy, read as data only:
  arrays, numbers and text, never a class or function the file names, see :mod:`.npy_file`), a bare
  (frames, individuals, 2) array, or an ``.npz`` with the same keys: ``trajectories`` (frames, individuals, 2) in pixels, nan where an
  individual was not seen, ``frames_per_second`` and ``body_length`` (pixels), which become the
  defaults of ``fps`` and ``body_length_px`` (lengths in body lengths).
* ``trex``: TRex's per-individual exports, a folder of ``<video>_fish<k>.npz`` (or ``.csv``) files, or
  one of them: ``X``, ``Y`` (centimetres, TRex's ``cm_per_pixel`` conversion: give ``units`` when yours
  differ), ``time`` (s) or ``frame`` (with ``fps``), and when present ``VX``, ``VY`` and ``missing``
  (1: not detected); the individual is the number after ``fish`` (else the file's stem); infinite
  values (TRex's missing marker) are missed detections.
* ``trajr``: a folder of CSV files, one individual each (the layout R's trajr reads with TrajsBuild):
  the individual is the file's stem, the columns are those of the long format (``x``, ``y``[, ``z``],
  ``t`` or a mapped ``time``; the column map applies to every file), other columns are passed on (and
  listed as unmapped).
* ``movebank``: a Movebank CSV: ``individual-local-identifier``, ``timestamp`` (UTC),
  ``location-long`` and ``location-lat`` (WGS84 degrees), projected with pyproj onto a local azimuthal
  equidistant plane centred at the mean fix of the file (x east, y north, metres; distances from the
  centre are exact, others off by about (d/R)^2/6 relative at d from the centre, R = 6371 km: 1e-5 at
  50 km). The column map renames ``id``, ``t`` and ``flock``, and ``z`` (e.g. ``height-above-ellipsoid``)
  makes the tracks 3-D; without it they are 2-D (GPS heights are much noisier than positions).

A file that is not what its format expects is a :class:`~simcore.schema.ConfigError` naming the file and
what was expected; missing channels or columns are named all at once.
"""
from __future__ import annotations

import gzip
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flocksweep.simcore.schema import ConfigError, suggest

from .track_names import FORMATS, LONG_FORMATS, WIDE_FORMATS  # noqa: F401 - declared there, part of this face

if TYPE_CHECKING:
    import pandas as pd

AXES = ("individual", "channel", "sample")
CHANNELS = ("x", "y", "z", "vx", "vy", "vz", "t")
MOVEBANK = {"id": "individual-local-identifier", "t": "timestamp", "lon": "location-long", "lat": "location-lat"}
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


# ------------------------------------------------------------------------------------------ long tables

def _exact_floats(pd) -> dict:
    """read_csv options reading CSV numbers back exactly as written (pandas >= 3 does by default and
    deprecates the option)."""
    return {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}


def _delimiter(path: Path) -> str:
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as handle:
        header = handle.readline()
    for sep in (",", "\t", ";"):
        if sep in header:
            return sep
    return r"\s+"


def file_format(path, fmt: str = "auto") -> str:
    """"parquet" or "csv": ``fmt``, or with "auto" Parquet for .parquet/.pq files and CSV otherwise."""
    if fmt != "auto":
        return fmt
    return "parquet" if Path(path).suffix in (".parquet", ".pq") else "csv"


def read_table(path, fmt: str = "auto") -> pd.DataFrame:
    """The raw table of a long track file (see :func:`file_format`)."""
    import pandas as pd
    path = Path(path)
    if not path.is_file():
        raise ConfigError(str(path), "no such track file")
    fmt = file_format(path, fmt)
    try:
        if fmt == "parquet":
            return pd.read_parquet(path)
        return pd.read_csv(path, sep=_delimiter(path), **_exact_floats(pd))
    except Exception as err:  # noqa: BLE001 - an unreadable file is the user's input problem
        raise ConfigError(str(path), f"cannot read it as {fmt}: {err}") from None



# -------------------------------------------------------------------------------------------- detection

def _csv_header(path: Path) -> str:
    opener = gzip.open if path.suffix == ".gz" else open
    try:
        with opener(path, "rt", errors="replace") as handle:
            return handle.readline()
    except OSError:
        return ""


def detect_format(path) -> str:
    """The format of ``path`` from its name and first bytes (see the module docstring)."""
    path = Path(path)
    if path.is_dir():
        if any(path.glob("*.npz")):
            return "trex"
        files = sorted(path.glob("*.csv"))
        if not files:
            raise ConfigError(str(path), "a folder of tracks holds TRex exports (*.npz or *.csv with X, Y) or one CSV "
                                         "per individual (trajr); this one has neither")
        header = _csv_header(files[0])
        return "trex" if re.search(r"(^|[,;\t ])X([,;\t ]|$)", header) and "Y" in header else "trajr"
    if not path.is_file():
        raise ConfigError(str(path), "no such track file or folder")
    with open(path, "rb") as handle:
        head = handle.read(128)
    suffix = path.suffix.lower()
    if suffix == ".mat" or head.startswith(b"MATLAB") or (head.startswith(HDF5_SIGNATURE) and suffix != ".h5"):
        return "mat"
    if suffix in (".parquet", ".pq"):
        return "parquet"
    if suffix == ".npy":
        return "idtracker"
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            return "idtracker" if "trajectories" in data.files else "trex"
    return "movebank" if "location-long" in _csv_header(path) else "csv"


def read_wide(path, fmt: str, source) -> tuple[pd.DataFrame, dict]:
    """(long table with role columns, the settings the file implies) of a tracker's or logger's file."""
    return {"mat": _mat, "idtracker": _idtracker, "trex": _trex, "trajr": _trajr, "movebank": _movebank}[fmt](
        Path(path), source)


def _long(ids, values: dict, keep) -> pd.DataFrame:
    """Individual-major long table of (individuals, samples) arrays, samples kept where ``keep``."""
    import pandas as pd
    n, s = keep.shape
    frame = {"id": np.repeat(np.asarray(ids), s)[keep.reshape(-1)]}
    for role, array in values.items():
        frame[role] = np.broadcast_to(array, (n, s)).reshape(-1)[keep.reshape(-1)]
    return pd.DataFrame(frame)


# -------------------------------------------------------------------------------------------------- MATLAB

def _mat_arrays(path: Path) -> dict:
    import h5py
    import scipy.io
    try:
        if h5py.is_hdf5(path):     # v7.3: HDF5, arrays stored with their dimensions reversed
            with h5py.File(path, "r") as handle:
                return {k: np.asarray(v).T for k, v in handle.items() if isinstance(v, h5py.Dataset)}
        data = scipy.io.loadmat(path)
        return {k: v for k, v in data.items() if not k.startswith("__")}
    except Exception as err:  # noqa: BLE001 - an unreadable file is the user's input problem
        raise ConfigError(str(path), f"cannot read it as a MATLAB .mat file: {err}") from None


def _layout(layout: dict, arrays: dict, path: Path) -> tuple[str, tuple, tuple]:
    numeric = {k: v for k, v in arrays.items() if isinstance(v, np.ndarray) and v.dtype.kind in "fiu"}
    variable = layout.get("variable")
    if variable is None:
        cubes = [k for k, v in numeric.items() if v.ndim == 3]
        if len(cubes) != 1:
            raise ConfigError("layout.variable", f"{path.name} has {len(cubes)} numeric 3-D arrays "
                                                 f"({', '.join(cubes) or 'none'}); name the one with the tracks")
        variable = cubes[0]
    if variable not in numeric:
        raise ConfigError("layout.variable", f"got {variable!r}; {path.name} has the numeric arrays: "
                                             f"{', '.join(numeric) or 'none'}{suggest(variable, numeric)}")
    axes = tuple(a.strip() for a in str(layout.get("axes", ",".join(AXES))).split(","))
    if sorted(axes) != sorted(AXES):
        raise ConfigError("layout.axes", f"got {layout.get('axes')!r}; expected the order of individual, channel "
                                         "and sample, e.g. 'individual,channel,sample'")
    if "channels" not in layout:
        raise ConfigError("layout.channels", f"missing: name the channels of {variable!r} by role "
                                             f"({', '.join(CHANNELS)}), e.g. channels = 'x,y,vx,vy'")
    channels = tuple(c.strip() for c in str(layout["channels"]).split(","))
    unknown = [c for c in channels if c not in CHANNELS]
    if unknown:
        raise ConfigError("layout.channels", f"unknown channel {unknown[0]!r}{suggest(unknown[0], CHANNELS)}; "
                                             f"channels: {', '.join(CHANNELS)}")
    missing = [c for c in ("x", "y") if c not in channels]
    if missing or len(set(channels)) != len(channels):
        raise ConfigError("layout.channels", f"got {layout['channels']!r}; need x and y once each "
                                             f"(missing: {', '.join(missing) or 'none'})")
    shape = numeric[variable].shape
    if numeric[variable].ndim != 3 or shape[axes.index("channel")] != len(channels):
        raise ConfigError("layout", f"{variable!r} has shape {shape}; with axes {','.join(axes)} its channel axis "
                                    f"must have the {len(channels)} channels {','.join(channels)}")
    return variable, axes, channels


def _mat(path: Path, source) -> tuple[pd.DataFrame, dict]:
    arrays = _mat_arrays(path)
    layout = dict(source.layout or {})
    variable, axes, channels = _layout(layout, arrays, path)
    cube = np.transpose(np.asarray(arrays[variable], dtype=np.float64),
                        [axes.index(a) for a in AXES])          # (individuals, channels, samples)
    n, _, s = cube.shape
    values = {c: cube[:, k, :] for k, c in enumerate(channels)}
    defaults = {}
    if "t" not in values:
        if layout.get("time"):
            times = np.asarray(arrays.get(layout["time"], np.empty(0)), dtype=np.float64).reshape(-1)
            if times.size != s:
                raise ConfigError("layout.time", f"got {layout['time']!r}; expected a variable with one time per "
                                                 f"sample ({s}) in {path.name}")
            values["t"] = times[None, :]
        else:
            values["t"] = np.arange(s, dtype=np.float64)[None, :]
            defaults["units"] = {"time": "frame"}
    keep = np.ones((n, s), dtype=bool)
    return _long(np.arange(1, n + 1), values, keep), defaults


# -------------------------------------------------------------------------------------------- idtracker.ai

IDTRACKER_CONVERT = ("if the file is yours and you trust it, convert it once to .npz in Python: d = np.load(path, "
                     "allow_pickle=True).item(); np.savez('trajectories.npz', trajectories=d['trajectories'], "
                     "frames_per_second=d['frames_per_second'], body_length=d['body_length'])")


def _idtracker_data(path: Path) -> dict:
    """The keys of an idtracker.ai file: an ``.npy`` read as data only (:mod:`.npy_file`), or an ``.npz``."""
    from .npy_file import NotData, read_npy
    try:
        if path.suffix.lower() == ".npz":
            with np.load(path, allow_pickle=False) as archive:
                return {key: archive[key] for key in archive.files}
        data = read_npy(path)
    except NotData as err:
        raise ConfigError(str(path), f"not opened: {err}; {IDTRACKER_CONVERT}") from None
    except Exception as err:  # noqa: BLE001 - an unreadable file is the user's input problem
        raise ConfigError(str(path), f"cannot read it as idtracker.ai trajectories: {err}") from None
    if data.dtype == object and data.shape == ():
        data = data.item()
    if isinstance(data, np.ndarray):
        return {"trajectories": data}
    if not isinstance(data, dict):
        raise ConfigError(str(path), f"not idtracker.ai trajectories: it holds a {type(data).__name__}, not a "
                                     "dictionary or an array")
    return data


def _positive_number(value) -> float | None:
    """``value`` as a float when it is one finite positive number (a stored setting), else None."""
    try:
        number = float(value) if value is not None and np.ndim(value) == 0 else None
    except (TypeError, ValueError):
        return None
    return number if number is not None and np.isfinite(number) and number > 0 else None


def _idtracker(path: Path, source) -> tuple[pd.DataFrame, dict]:
    data = _idtracker_data(path)
    if "trajectories" not in data:
        raise ConfigError(str(path), f"not idtracker.ai trajectories: no 'trajectories' (keys: {', '.join(data)})")
    try:
        traj = np.asarray(data["trajectories"], dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(str(path), "trajectories holds values that are not numbers; expected (frames, "
                                     "individuals, 2) positions in pixels") from None
    if traj.ndim != 3 or traj.shape[2] != 2:
        raise ConfigError(str(path), f"trajectories has shape {traj.shape}; expected (frames, individuals, 2)")
    defaults = {"units": {"length": "px", "time": "frame"}}
    for key, setting in (("frames_per_second", "fps"), ("body_length", "body_length_px")):
        value = _positive_number(data.get(key))
        if value is not None:
            defaults[setting] = value
    s, n, _ = traj.shape
    frames = np.arange(s, dtype=np.float64)[None, :]
    keep = np.ones((n, s), dtype=bool)
    return _long(np.arange(1, n + 1), {"t": frames, "x": traj[:, :, 0].T, "y": traj[:, :, 1].T}, keep), defaults


# ------------------------------------------------------------------------------------------------------ TRex

def _individual(path: Path) -> str:
    found = re.search(r"fish(\d+)", path.stem)
    return found.group(1) if found else path.stem


def _trex_file(path: Path) -> dict:
    import pandas as pd
    try:
        if path.suffix.lower() == ".npz":
            with np.load(path, allow_pickle=False) as data:
                return {k: np.asarray(data[k]) for k in data.files}
        return {k: v.to_numpy() for k, v in pd.read_csv(path).items()}
    except Exception as err:  # noqa: BLE001
        raise ConfigError(str(path), f"cannot read it as a TRex export: {err}") from None


def _trex(path: Path, source) -> tuple[pd.DataFrame, dict]:
    import pandas as pd
    files = [path] if path.is_file() else sorted(path.glob("*.npz")) or sorted(path.glob("*.csv"))
    parts, frame_times = [], False
    for file in files:
        data = _trex_file(file)
        clock = "time" if "time" in data else "frame" if "frame" in data else None
        missing = [c for c in ("X", "Y") if c not in data] + ([] if clock else ["time or frame"])
        if missing:
            raise ConfigError(str(file), f"not a TRex export: no {', '.join(missing)} (it has: {', '.join(data)})")
        frame_times |= clock == "frame"
        part = {"id": _individual(file), "t": np.asarray(data[clock], dtype=np.float64)}
        gone = np.asarray(data.get("missing", np.zeros(len(part["t"]))), dtype=bool).reshape(-1)
        for role, key in (("x", "X"), ("y", "Y"), ("vx", "VX"), ("vy", "VY")):
            if key in data:
                values = np.asarray(data[key], dtype=np.float64).reshape(-1).copy()
                values[gone | ~np.isfinite(values)] = np.nan
                part[role] = values
        parts.append(pd.DataFrame(part))
    units = {"length": "cm", "time": "frame" if frame_times else "s"}
    frame = pd.concat(parts, ignore_index=True)
    if {"vx", "vy"} - set(frame.columns) and {"vx", "vy"} & set(frame.columns):
        frame = frame.drop(columns=[c for c in ("vx", "vy") if c in frame.columns])
    return frame, {"units": units}


# ----------------------------------------------------------------------------------------------------- trajr

def _trajr(path: Path, source) -> tuple[pd.DataFrame, dict]:
    import pandas as pd
    files = [path] if path.is_file() else sorted(path.glob("*.csv"))
    parts = []
    for file in files:
        try:
            part = pd.read_csv(file, sep=_delimiter(file), **_exact_floats(pd))
        except Exception as err:  # noqa: BLE001
            raise ConfigError(str(file), f"cannot read it as csv: {err}") from None
        if "id" in part.columns:
            raise ConfigError(str(file), "a trajr folder has one individual per file (named by the file); this file "
                                         "has an id column: read it as csv instead (--format csv)")
        parts.append(part.assign(id=file.stem))
    return pd.concat(parts, ignore_index=True), {}


# -------------------------------------------------------------------------------------------------- Movebank

def project_wgs84(lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(x east, y north) in metres on the azimuthal equidistant plane centred at the mean fix, and that
    centre (lon0, lat0)."""
    from pyproj import CRS, Transformer
    ok = np.isfinite(lon) & np.isfinite(lat)
    centre = (float(np.mean(lon[ok])), float(np.mean(lat[ok])))
    plane = CRS.from_dict({"proj": "aeqd", "lon_0": centre[0], "lat_0": centre[1], "datum": "WGS84", "units": "m"})
    x, y = Transformer.from_crs("EPSG:4326", plane, always_xy=True).transform(lon, lat)
    return np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64), centre


def _movebank(path: Path, source) -> tuple[pd.DataFrame, dict]:
    import pandas as pd
    table = read_table(path, "csv")
    names = {role: source.columns.get(role, default) for role, default in MOVEBANK.items()}
    names.update({role: source.columns[role] for role in ("flock", "z") if role in source.columns})
    columns = [str(c) for c in table.columns]
    missing = [f"{role} ({name!r}{suggest(name, columns)})" for role, name in names.items() if name not in columns]
    if missing:
        raise ConfigError(str(path), f"not a Movebank CSV as mapped: no column for {', '.join(missing)}; the file "
                                     f"has: {', '.join(columns)}")
    coords = {k: pd.to_numeric(table[names[k]], errors="coerce").to_numpy(dtype=np.float64) for k in ("lon", "lat")}
    bad = (np.abs(coords["lat"]) > 90) | (np.abs(coords["lon"]) > 180)
    if bad.any():
        rows = np.flatnonzero(bad) + 1
        raise ConfigError(str(path), f"latitude/longitude outside [-90, 90] x [-180, 180] at rows "
                                     f"{', '.join(map(str, rows[:8]))}: Movebank coordinates are WGS84 degrees")
    if not (np.isfinite(coords["lon"]) & np.isfinite(coords["lat"])).any():
        raise ConfigError(str(path), "no row has a location (location-long, location-lat)")
    x, y, _ = project_wgs84(coords["lon"], coords["lat"])
    frame = pd.DataFrame({"id": table[names["id"]], "t": table[names["t"]], "x": x, "y": y})
    for role in ("flock", "z"):
        if role in names:
            frame[role] = table[names[role]]
    return frame, {"units": {"length": "m", "time": "datetime"}}
