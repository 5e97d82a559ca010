"""Track files as trackers and loggers write them, each turned into the long table of :mod:`.tracks`.

``read_table(path, fmt)`` reads a long CSV or Parquet file as it is; ``read_wide(path, fmt, source) -> (frame,
defaults)``: ``frame`` has one row per sample and columns named by role (``id``, ``t``, ``x``, ``y`` and,
when the file has them, ``flock``, ``z``, ``vx``, ``vy``, ``vz``); ``defaults`` are the settings the file
implies (``units``, ``fps``, ``body_length_px``), which what the user gives overrides (and ``notes``: what
reading did, reported as notes). Rows are numbered in the order of that table. The formats
(``detect_format`` picks one from the file when ``format = "auto"``):

* ``mat`` and ``npy``: MATLAB ``.mat`` files and numpy ``.npy``/``.npz`` arrays of a declared layout
  (a 3-D array of individuals, channels and samples, or a 2-D detection table), :mod:`.track_arrays`;
* ``idtracker``: idtracker.ai's ``trajectories.npy`` (a dictionary saved by numpy, read as data only:
  arrays, numbers and text, never a class or function the file names, see :mod:`.npy_file`), a bare
  (frames, individuals, 2) array, or an ``.npz`` with the same keys: ``trajectories`` (frames, individuals, 2) in pixels, nan where an
  individual was not seen, ``frames_per_second`` and ``body_length`` (pixels), which become the
  defaults of ``fps`` and ``body_length_px`` (lengths in body lengths). Column k of the array (from 0) is
  the individual with id k + 1 (idtracker.ai's own numbering);
* ``trex``: TRex's per-individual exports, a folder of ``<video>_fish<k>.npz`` (or ``.csv``) files, or
  one of them: ``X``, ``Y`` (centimetres, TRex's ``cm_per_pixel`` conversion: give ``units`` when yours
  differ), ``time`` (s) or ``frame`` (with ``fps``; with ``fps`` given, ``frame`` is used when every file has
  it: an exact clock), and when present ``VX``, ``VY`` and ``missing`` (1: not detected); the individual is
  the number after ``fish`` (else the file's stem); infinite values (TRex's missing marker) are missed
  detections;
* ``trajr``: a folder of CSV files, one individual each (the layout R's trajr reads with TrajsBuild):
  the individual is the file's stem, the columns are those of the long format (``x``, ``y``[, ``z``],
  ``t`` or a mapped ``time``; the column map applies to every file), other columns are passed on (and
  listed as unmapped);
* ``movebank``: a Movebank CSV: ``individual-local-identifier``, ``timestamp`` (UTC; stamps with
  different UTC offsets are converted to UTC), ``location-long`` and ``location-lat`` (WGS84 degrees),
  projected with pyproj onto a local azimuthal equidistant plane centred at the mean fix of the file (the
  mean of the fixes as unit vectors, so tracks across the antimeridian are centred where they are; x
  east, y north, metres; distances from the centre are exact, others off by about (d/R)^2/6 relative at d
  from the centre, R = 6371 km: 1e-5 at 50 km). The column map renames ``id``, ``t`` and ``flock``, and
  ``z`` (e.g. ``height-above-ellipsoid``) makes the tracks 3-D; without it they are 2-D.

The files of a folder must agree: the same columns (TRex: the same arrays), the same clock (time or
frame) and velocities in all or none, or the read is refused naming the file and the difference; a folder
holding both ``.npz`` and ``.csv`` files is refused (never half read); every entry read must be a regular
file (a FIFO, device, socket or a link to one is refused by name, as at the top level). CSV files:
decimal commas in a file separated by ``;``, tabs or spaces are read as decimal points (a note says so);
in a comma-separated file a row with more or fewer fields than its header (a decimal comma splits a
number) is refused naming its line.

A file that is not what its format expects is a :class:`~simcore.schema.ConfigError` naming the file and
what was expected; missing channels or columns are named all at once.
"""
from __future__ import annotations

import csv
import gzip
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flocksweep.simcore.schema import ConfigError, input_file, suggest

from .track_arrays import long_table, read_arrays
from .track_names import FORMATS, LONG_FORMATS, WIDE_FORMATS  # noqa: F401 - declared there, part of this face

if TYPE_CHECKING:
    import pandas as pd

MOVEBANK = {"id": "individual-local-identifier", "t": "timestamp", "lon": "location-long", "lat": "location-lat"}
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
TRACK_FILE_LIMIT = 1 << 40      # bytes: no track file is larger; a device or FIFO is refused before this
DECIMAL_COMMA = re.compile(r"^\s*[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?\s*$")
TREX_KEYS = ("X", "Y", "VX", "VY", "time", "frame", "missing")
NOTES = "flocksweep_notes"      # DataFrame.attrs key: what reading did (decimal commas read, ...)


def regular_file(path, what: str = "track file") -> Path:
    """``path`` when it is a regular file (a link to one is followed); a ConfigError naming it otherwise
    (missing, a folder, a FIFO, a device, a socket, a link to one of these or to nothing)."""
    input_file(path, "", what, TRACK_FILE_LIMIT)
    return Path(path)


# ------------------------------------------------------------------------------------------ long tables

def _exact_floats(pd) -> dict:
    """read_csv options reading CSV numbers back exactly as written (pandas >= 3 does by default and
    deprecates the option)."""
    return {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}


def _open_text(path: Path):
    return gzip.open(path, "rt", errors="replace") if path.suffix == ".gz" else open(path, errors="replace")


def _delimiter(path: Path) -> str:
    with _open_text(path) as handle:
        header = handle.readline()
    for sep in (",", "\t", ";"):
        if sep in header:
            return sep
    return r"\s+"


def _decimal_commas(frame: pd.DataFrame) -> list:
    """Columns of text whose every value is a number written with a decimal comma: converted in place
    (exactly: the comma becomes a point); their names."""
    import pandas as pd
    converted = []
    for name in frame.columns:
        column = frame[name]
        if column.dtype != object and not pd.api.types.is_string_dtype(column):
            continue
        text = column.dropna().astype(str)
        if text.empty or not text.str.match(DECIMAL_COMMA.pattern).any():
            continue
        plain = text.str.strip().str.replace(",", ".", regex=False)
        numbers = pd.to_numeric(plain, errors="coerce")
        if numbers.isna().any():
            continue        # not a column of numbers: left for the checks to name
        frame[name] = pd.to_numeric(column.astype(str).str.strip().str.replace(",", ".", regex=False)
                                    .where(column.notna()), errors="coerce")
        converted.append(str(name))
    return converted


def _short_rows(path: Path, columns: int) -> list:
    """Line numbers (from 1) of a comma-separated file whose rows have another number of fields than its
    header (the first ten)."""
    bad = []
    with _open_text(path) as handle:
        for line, row in enumerate(csv.reader(handle), start=1):
            if line > 1 and row and len(row) != columns:
                bad.append((line, len(row)))
                if len(bad) >= 10:
                    break
    return bad


def read_csv(path, what: str = "csv") -> pd.DataFrame:
    """A CSV (or gzipped CSV) file as a table, read exactly; decimal commas handled or refused (module
    docstring); ``frame.attrs[NOTES]`` lists what was done."""
    import pandas as pd
    path = regular_file(path)
    sep = _delimiter(path)
    try:
        frame = pd.read_csv(path, sep=sep, **_exact_floats(pd))
    except Exception as err:  # noqa: BLE001 - an unreadable file is the user's input problem
        hint = ("; a decimal comma in a comma-separated file splits its number in two: write decimals with a point, "
                "or separate the fields with ';'") if sep == "," and "fields" in str(err) else ""
        raise ConfigError(str(path), f"cannot read it as {what}: {err}{hint}") from None
    notes = []
    if not isinstance(frame.index, pd.RangeIndex):
        raise ConfigError(str(path), f"its rows have more fields than its header ({len(frame.columns)}): a decimal "
                                     "comma in a comma-separated file? Write decimals with a point, or separate the "
                                     "fields with ';'")
    if sep == "," and len(frame.columns) > 1 and frame.iloc[:, -1].isna().any():
        short = _short_rows(path, len(frame.columns))
        if short:
            lines = ", ".join(f"line {line} ({count})" for line, count in short)
            raise ConfigError(str(path), f"rows with another number of fields than the header's "
                                         f"{len(frame.columns)}: {lines}; a decimal comma in a comma-separated file "
                                         "splits a number in two: write decimals with a point, or separate the fields "
                                         "with ';'")
    if sep != ",":
        converted = _decimal_commas(frame)
        if converted:
            notes.append(f"decimal commas read as decimal points in column(s) {', '.join(converted)}")
    frame.attrs[NOTES] = notes
    return frame


def file_format(path, fmt: str = "auto") -> str:
    """"parquet" or "csv": ``fmt``, or with "auto" Parquet for .parquet/.pq files and CSV otherwise."""
    if fmt != "auto":
        return fmt
    return "parquet" if Path(path).suffix in (".parquet", ".pq") else "csv"


def read_table(path, fmt: str = "auto") -> pd.DataFrame:
    """The raw table of a long track file (see :func:`file_format`)."""
    import pandas as pd
    path = Path(path)
    if path.is_dir():
        raise ConfigError(str(path), "a folder, not a track file (a folder of exports: give --format trex or trajr)")
    regular_file(path)
    fmt = file_format(path, fmt)
    if fmt == "csv":
        return read_csv(path)
    try:
        frame = pd.read_parquet(path)
    except Exception as err:  # noqa: BLE001 - an unreadable file is the user's input problem
        raise ConfigError(str(path), f"cannot read it as {fmt}: {err}") from None
    frame.attrs[NOTES] = []
    return frame


# -------------------------------------------------------------------------------------------- detection

def folder_files(path: Path, suffixes=(".npz", ".csv")) -> list[Path]:
    """The exports in a folder (files ending in ``suffixes``, sorted), each checked to be a regular file;
    a folder holding both ``.npz`` and ``.csv`` exports is refused."""
    found = {suffix: sorted(p for p in path.iterdir() if p.name.lower().endswith(suffix)) for suffix in (".npz", ".csv")}
    if found[".npz"] and found[".csv"]:
        raise ConfigError(str(path), f"holds both .npz ({len(found['.npz'])}: {found['.npz'][0].name}, ...) and .csv "
                                     f"({len(found['.csv'])}: {found['.csv'][0].name}, ...) exports; a folder is read "
                                     "whole, from one kind: move the other kind out")
    files = [p for suffix in suffixes for p in found.get(suffix, [])]
    for file in files:
        regular_file(file, "the folder's file")
    return files


def _csv_header(path: Path) -> str:
    try:
        with _open_text(path) as handle:
            return handle.readline()
    except OSError:
        return ""


def _is_trex_header(header: str) -> bool:
    return bool(re.search(r"(^|[,;\t ])X([,;\t ]|$)", header)) and bool(re.search(r"(^|[,;\t ])Y([,;\t ]|$)", header))


def detect_format(path, layout: dict | None = None) -> str:
    """The format of ``path`` from its name and first bytes (see the module docstring); ``layout`` given:
    an ``.npy``/``.npz`` file is read as arrays of that layout (``npy``)."""
    path = Path(path)
    if path.is_dir():
        files = folder_files(path)
        if not files:
            raise ConfigError(str(path), "a folder of tracks holds TRex exports (*.npz or *.csv with X, Y) or one CSV "
                                         "per individual (trajr); this one has neither")
        if files[0].suffix.lower() == ".npz":
            return "trex"
        return "trex" if _is_trex_header(_csv_header(files[0])) else "trajr"
    regular_file(path)
    with open(path, "rb") as handle:
        head = handle.read(128)
    suffix = path.suffix.lower()
    if suffix == ".mat" or head.startswith(b"MATLAB") or (head.startswith(HDF5_SIGNATURE) and suffix != ".h5"):
        return "mat"
    if suffix in (".parquet", ".pq"):
        return "parquet"
    if suffix in (".npy", ".npz") and layout:
        return "npy"
    if suffix == ".npy":
        return "idtracker"
    if suffix == ".npz":
        from .npy_file import npz_headers
        try:
            keys = npz_headers(path)
        except ValueError as err:
            raise ConfigError(str(path), f"cannot read it as numpy arrays: {err}") from None
        return "idtracker" if "trajectories" in keys else "trex"
    return "movebank" if "location-long" in _csv_header(path) else "csv"


def read_wide(path, fmt: str, source) -> tuple[pd.DataFrame, dict]:
    """(long table with role columns, the settings the file implies) of a tracker's or logger's file."""
    path = Path(path)
    if fmt in ("mat", "npy"):
        regular_file(path)
        return read_arrays(path, fmt, source.layout)
    readers = {"idtracker": _idtracker, "trex": _trex, "trajr": _trajr, "movebank": _movebank}
    return readers[fmt](path, source)


# -------------------------------------------------------------------------------------------- idtracker.ai

IDTRACKER_CONVERT = ("if the file is yours and you trust it, convert it once to .npz in Python: d = np.load(path, "
                     "allow_pickle=True).item(); np.savez('trajectories.npz', trajectories=d['trajectories'], "
                     "frames_per_second=d['frames_per_second'], body_length=d['body_length'])")


def _idtracker_data(path: Path) -> dict:
    """The keys of an idtracker.ai file: an ``.npy`` read as data only (:mod:`.npy_file`), or an ``.npz``."""
    from .npy_file import NotData, read_npy, read_npz
    regular_file(path)
    try:
        if path.suffix.lower() == ".npz":
            return read_npz(path)
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


def _positive_number(value, path: Path, key: str) -> float | None:
    """``value`` as a float when it is one finite positive number (a stored setting), None when absent;
    a ConfigError naming the key when it is something else (text, an array, a negative number)."""
    if value is None:
        return None
    if isinstance(value, (bytes, str)) or np.ndim(value) != 0 or np.asarray(value).dtype.kind not in "fiu":
        raise ConfigError(str(path), f"{key}: got {value!r}; expected one number > 0 (give it yourself with "
                                     f"--{'fps' if key == 'frames_per_second' else 'body-length-px'})")
    number = float(value)
    if not (np.isfinite(number) and number > 0):
        raise ConfigError(str(path), f"{key}: got {number!r}; expected a number > 0")
    return number


def _numbers(value, path: Path, key: str) -> np.ndarray:
    """An array of numbers (float64) from a file's value; text or objects other than numbers refused."""
    array = np.asarray(value)
    if array.dtype.kind in "USa" or (array.dtype == object and any(isinstance(v, (str, bytes)) for v in array.flat)):
        raise ConfigError(str(path), f"{key} holds text; expected numbers (positions in pixels)")
    try:
        return np.asarray(array, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(str(path), f"{key} holds values that are not numbers; expected (frames, individuals, 2) "
                                     "positions in pixels") from None


def _idtracker(path: Path, source) -> tuple[pd.DataFrame, dict]:
    data = _idtracker_data(path)
    if "trajectories" not in data:
        raise ConfigError(str(path), f"not idtracker.ai trajectories: no 'trajectories' (keys: {', '.join(data)})")
    traj = _numbers(data["trajectories"], path, "trajectories")
    if traj.ndim != 3 or traj.shape[2] != 2:
        raise ConfigError(str(path), f"trajectories has shape {traj.shape}; expected (frames, individuals, 2)")
    defaults = {"units": {"length": "px", "time": "frame"}}
    for key, setting in (("frames_per_second", "fps"), ("body_length", "body_length_px")):
        value = _positive_number(data.get(key), path, key)
        if value is not None:
            defaults[setting] = value
    s, n, _ = traj.shape
    frames = np.arange(s, dtype=np.float64)[None, :]
    keep = np.ones((n, s), dtype=bool)
    return long_table(np.arange(1, n + 1), {"t": frames, "x": traj[:, :, 0].T, "y": traj[:, :, 1].T}, keep), defaults


# ------------------------------------------------------------------------------------------------------ TRex

def _individual(path: Path) -> str:
    found = re.search(r"fish(\d+)", path.stem)
    return found.group(1) if found else path.stem


def _trex_file(path: Path) -> dict:
    from .npy_file import NotData, read_npz
    try:
        if path.suffix.lower() == ".npz":
            data = read_npz(path)
        else:
            data = {k: v.to_numpy() for k, v in read_csv(path, "a TRex export").items()}
    except ConfigError:
        raise
    except (NotData, Exception) as err:  # noqa: BLE001
        raise ConfigError(str(path), f"cannot read it as a TRex export: {err}") from None
    clock = "time" if "time" in data else "frame" if "frame" in data else None
    missing = [c for c in ("X", "Y") if c not in data] + ([] if clock else ["time or frame"])
    if missing:
        raise ConfigError(str(path), f"not a TRex export: no {', '.join(missing)} (it has: {', '.join(data)})")
    kept = {k: np.asarray(v).reshape(-1) if np.ndim(v) == 2 and 1 in np.shape(v) else np.asarray(v)
            for k, v in data.items() if k in TREX_KEYS}
    lengths = {k: v.shape for k, v in kept.items()}
    if any(len(shape) != 1 for shape in lengths.values()) or len({shape[0] for shape in lengths.values()}) > 1:
        shown = ", ".join(f"{k} {shape}" for k, shape in lengths.items())
        raise ConfigError(str(path), f"its arrays differ in length or are not one value per frame ({shown}); a TRex "
                                     "export holds one value per frame in each")
    for key, values in kept.items():
        if values.dtype.kind not in "fiub":
            raise ConfigError(str(path), f"{key} holds {values.dtype} values, not numbers")
    return kept


def _trex_signature(data: dict) -> dict:
    return {"columns": tuple(k for k in TREX_KEYS if k in data), "velocities": "VX" in data and "VY" in data}


def _agree(files: list, signatures: list, what: str) -> None:
    """Every file's signature equals the first's, or a ConfigError naming the first that differs and how."""
    first = signatures[0]
    for file, signature in zip(files[1:], signatures[1:]):
        for key, value in signature.items():
            if value != first[key]:
                def text(v):
                    return ", ".join(v) if isinstance(v, tuple) else ("yes" if v is True else "no" if v is False else v)
                raise ConfigError(str(file), f"its {key} ({text(value)}) differ from {files[0].name}'s "
                                             f"({text(first[key])}); the files of one {what} folder must agree in "
                                             "columns, clock and velocities: fix or move the odd file out")


def _trex(path: Path, source) -> tuple[pd.DataFrame, dict]:
    import pandas as pd
    if path.is_dir():
        files = folder_files(path)
        if not files:
            raise ConfigError(str(path), "no TRex exports (*.npz or *.csv with X, Y) in this folder")
    else:
        files = [regular_file(path)]
    datas = [_trex_file(file) for file in files]
    _agree(files, [_trex_signature(d) for d in datas], "TRex")
    by_frame = source.fps is not None and all("frame" in d for d in datas)
    clock = "frame" if by_frame or "time" not in datas[0] else "time"
    parts = []
    for file, data in zip(files, datas):
        part = {"id": _individual(file), "t": np.asarray(data[clock], dtype=np.float64)}
        gone = np.asarray(data.get("missing", np.zeros(len(part["t"]))), dtype=bool)
        for role, key in (("x", "X"), ("y", "Y"), ("vx", "VX"), ("vy", "VY")):
            if key in data:
                values = np.asarray(data[key], dtype=np.float64).copy()
                values[gone | ~np.isfinite(values)] = np.nan
                part[role] = values
        parts.append(pd.DataFrame(part))
    units = {"length": "cm", "time": "frame" if clock == "frame" else "s"}
    frame = pd.concat(parts, ignore_index=True)
    if {"vx", "vy"} - set(frame.columns) and {"vx", "vy"} & set(frame.columns):
        frame = frame.drop(columns=[c for c in ("vx", "vy") if c in frame.columns])
    notes = [f"the frame column as the clock (exact at {source.fps:g} fps)"] if clock == "frame" and by_frame else []
    return frame, {"units": units, "notes": notes}


# ----------------------------------------------------------------------------------------------------- trajr

def _clock_kind(part: pd.DataFrame, name: str) -> str:
    import pandas as pd
    if name not in part.columns:
        return "none"
    return "numbers" if pd.api.types.is_numeric_dtype(part[name]) else "text (timestamps?)"


def _trajr(path: Path, source) -> tuple[pd.DataFrame, dict]:
    import pandas as pd
    if path.is_dir():
        files = folder_files(path, (".csv",))
        if not files:
            raise ConfigError(str(path), "no CSV files in this folder (trajr: one CSV per individual)")
    else:
        files = [regular_file(path)]
    parts, signatures, notes = [], [], []
    for file in files:
        part = read_csv(file)
        notes += [f"{file.name}: {note}" for note in part.attrs.get(NOTES, [])]
        if "id" in part.columns:
            raise ConfigError(str(file), "a trajr folder has one individual per file (named by the file); this file "
                                         "has an id column: read it as csv instead (--format csv)")
        signatures.append({"columns": tuple(sorted(str(c) for c in part.columns)),
                           "clock": _clock_kind(part, source.column("t"))})
        parts.append(part.assign(id=file.stem))
    _agree(files, signatures, "trajr")
    frame = pd.concat(parts, ignore_index=True)
    return frame, {"notes": notes}


# -------------------------------------------------------------------------------------------------- Movebank

def centre_of(lon: np.ndarray, lat: np.ndarray) -> tuple[float, float]:
    """(lon0, lat0) of the mean of the fixes as unit vectors: the middle of tracks that cross the
    antimeridian is where they are, not on the far side of the globe."""
    lam, phi = np.radians(lon), np.radians(lat)
    x, y, z = (np.mean(np.cos(phi) * np.cos(lam)), np.mean(np.cos(phi) * np.sin(lam)), np.mean(np.sin(phi)))
    return float(np.degrees(np.arctan2(y, x))), float(np.degrees(np.arctan2(z, np.hypot(x, y))))


def project_wgs84(lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(x east, y north) in metres on the azimuthal equidistant plane centred at the mean fix
    (:func:`centre_of`), and that centre (lon0, lat0)."""
    from pyproj import CRS, Transformer
    ok = np.isfinite(lon) & np.isfinite(lat)
    centre = centre_of(lon[ok], lat[ok])
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
    x, y, centre = project_wgs84(coords["lon"], coords["lat"])
    frame = pd.DataFrame({"id": table[names["id"]], "t": table[names["t"]], "x": x, "y": y})
    for role in ("flock", "z"):
        if role in names:
            frame[role] = table[names[role]]
    notes = list(table.attrs.get(NOTES, [])) + [f"longitude and latitude projected onto the plane centred at "
                                                f"({centre[0]:.6f}, {centre[1]:.6f})"]
    return frame, {"units": {"length": "m", "time": "datetime"}, "notes": notes}

