"""Measured trajectories in long format: reading a track file into flocks of raw samples, and writing one.

A track file (CSV, also gzipped, or Parquet) has one row per detection of one individual at one time:

* ``flock``: flock / event id (optional; without it the whole file is one flock, named after the file);
* ``id``: individual id (numbers sort numerically, anything else as text);
* ``t``: time, in ``units.time`` (s, ms, min, h; ``datetime``: timestamps; ``frame``: frame numbers, with
  ``fps`` frames per second);
* ``x``, ``y``: position, in ``units.length`` (m, cm, mm, km; or ``bl``: body lengths);
* ``z``: third coordinate (optional; without it the tracks are 2-D, marked as such, with z = 0);
* ``vx``, ``vy``, ``vz``: velocities in the same units per time unit (per second with timestamps and frames), all of
  them or none (optional; 2-D tracks have ``vx`` and ``vy`` only, and get vz = 0);
* ``pattern``: an integer label per individual, constant over time (optional).

A column map (:attr:`TrackSource.columns`, role -> column name) names other columns. Empty position
cells are missed detections (reported, then left out); any other bad cell (not a finite number, or a
coordinate or velocity beyond ``MAX_MAGNITUDE`` = 1e100 analysis units, whose squares would overflow) stops
the reading with the row and column named (:class:`~observables.validation.TrackError`). Rows are numbered from 1 in
file order; in a CSV file row k is line k + 1 (the header is line 1).

Units. Positions are converted to metres; with ``body_length`` (metres) they are then divided by it,
so lengths are in body lengths (BL) and speeds in BL/s, the simulator's own units (a boid's body
length is 1). ``units.length = "bl"`` means the file is already in body lengths (tracks written by
``flocksweep simulate``); ``body_length`` is then not allowed. Times become seconds.

A sidecar JSON file with the same stem (``tracks.csv.gz`` -> ``tracks.json``) may give defaults for
``columns``, ``units`` and ``body_length`` (any :class:`TrackSource` setting; and a ``description`` shown in
reports); what a command line or calibration file gives explicitly wins (tables such as ``units`` key by
key). A format's own settings (idtracker.ai's pixels, frames, frame rate and body length; TRex's
centimetres) fill what neither gave, and only then are the settings checked against each other
(:meth:`TrackSource.check_units`: frame numbers need a frame rate, pixels a body length in pixels), so a
unit is merged before it is checked; an option the format does not use (a layout for a CSV, a column map
for arrays, a frame rate for times in seconds) is refused by name. ``TrackSource.origins`` records where
each setting came from ("file", "sidecar"; absent: given or default) and ``TrackSource.scales()`` every
unit and scale used with its source. ``keep_padding`` and ``trim`` (:mod:`.trimming`) and the speed
check's burst rule (``burst_share``, ``burst_frames``, ``burst_jump``: :mod:`.validation`) are settings
too. Other keys are information
(``SIDECAR_INFORMATION``: ``description``, ``notes``, ``truth``, ...; any other name too), but an unlisted
one close to a setting's name (``colums``) is refused as a typo with a did-you-mean.

``load_tracks(path, source) -> TrackTable`` reads and converts (the table holds the source row of every
sample, and notes on what reading did: decimal commas read, channels skipped, stamps converted to UTC); ``raw_flocks(table)`` splits it into :class:`RawFlock` s, samples sorted by individual and time.
``tracks_frame(obs, flock)`` is the inverse for a simulator run: its records as a long table in body
lengths (``flocksweep simulate --tracks``; a run in the plane z = 0 without z and vz, so it reads back 2-D).
"""
from __future__ import annotations

import dataclasses
import json
import math
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Literal, TYPE_CHECKING

import numpy as np

from flocksweep.simcore.schema import ConfigError, build, check_positive, check_within, suggest

from .track_arrays import check_layout
from .track_formats import NOTES, detect_format, read_table, read_wide
from .track_names import (ARRAY_FORMATS, COLUMN_FORMATS, LENGTH_UNITS, RECORDED, ROLES,  # noqa: F401 - part of this face
                          WIDE_FORMATS)
from .trimming import parse_trim
from .validation import BURST_FRAMES, BURST_JUMP, BURST_SHARE, Issue, TrackError

if TYPE_CHECKING:  # pandas is imported where it is used: importing this module stays light
    import pandas as pd

REQUIRED = ("id", "t", "x", "y")
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "min": 60.0, "h": 3600.0, "datetime": None, "frame": None}


SETTING_FLAGS = {"fps": "--fps", "body_length": "--body-length", "body_length_px": "--body-length-px",
                 "units.length": "--units length=", "units.time": "--units time=", "layout": "--layout",
                 "columns": "--columns", "trim": "--trim", "keep_padding": "--keep-padding"}
ORIGINS = ("file", "sidecar", "given", "default")


@dataclass(frozen=True)
class TrackSource:
    """How to read a track file: column map, units, body length, padding and trim, the speed check (see the
    module docstring). ``origins`` says where settings came from (setting -> "sidecar" or "file"; a setting
    absent from it was given, or is the default): filled by :func:`track_source` and :func:`load_tracks`."""

    columns: dict = field(default_factory=dict)   # role -> column name in the file
    units: dict = field(default_factory=dict)     # {"length": "m", "time": "s"} (these are the defaults)
    body_length: float | None = None              # metres; lengths then in body lengths
    max_speed: float | None = None                # analysis units per s; None: 10 x the flock's median step speed
    bad_speeds: Literal["error", "keep", "drop"] = "error"
    format: Literal["auto", "csv", "parquet", "mat", "npy", "idtracker", "trex", "trajr", "movebank"] = "auto"
    fps: float | None = None                      # frames per second: times in frames (units.time = "frame")
    body_length_px: float | None = None           # pixels: tracks in pixels (units.length = "px") -> body lengths
    layout: dict | None = None                    # an array file's layout (observables.track_arrays)
    keep_padding: bool = False                    # keep trailing/leading all-zero-velocity samples (trimming)
    trim: str | None = None                       # "START:END" of each flock's samples (observables.trimming)
    burst_share: float = BURST_SHARE              # the speed check: share of the group that makes a burst
    burst_frames: float = BURST_FRAMES            # ... within this many sampling intervals
    burst_jump: float = BURST_JUMP                # ... each faster than this many times its own recent speed
    origins: dict = field(default_factory=dict, compare=False)
    arena: dict | None = None                     # the tank filmed in: kind, centre, radius/size/height (file units)

    def __post_init__(self):
        for role, name in self.columns.items():
            if role not in ROLES:
                raise ConfigError(f"columns.{role}", f"unknown role{suggest(role, ROLES)}; roles: {', '.join(ROLES)}")
            if not isinstance(name, str) or not name:
                raise ConfigError(f"columns.{role}", f"got {name!r}; expected the column's name in the file")
        names = list(self.columns.values())
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ConfigError("columns", f"column {twice[0]!r} is mapped to two roles")
        for key, value in self.units.items():
            allowed = {"length": LENGTH_UNITS, "time": TIME_UNITS}.get(key)
            if allowed is None:
                raise ConfigError(f"units.{key}", f"unknown unit kind{suggest(key, ('length', 'time'))}; "
                                                  "allowed: length, time")
            if value not in allowed:
                raise ConfigError(f"units.{key}", f"got {value!r}; allowed: {', '.join(allowed)}"
                                                  f"{suggest(str(value), allowed)}")
        if self.body_length is not None and (isinstance(self.body_length, bool) or
                                             not (math.isfinite(self.body_length) and self.body_length > 0)):
            raise ConfigError("body_length", f"got {self.body_length!r}; expected metres > 0")
        for key in ("fps", "body_length_px"):
            value = getattr(self, key)
            if value is not None and (isinstance(value, bool) or not (math.isfinite(value) and value > 0)):
                raise ConfigError(key, f"got {value!r}; expected a number > 0")
        if self.max_speed is not None and not (math.isfinite(self.max_speed) and self.max_speed > 0):
            raise ConfigError("max_speed", f"got {self.max_speed!r}; expected a number > 0 (length units per s)")
        if self.layout is not None:
            check_layout(self.layout)
        if self.trim is not None:
            try:
                parse_trim(self.trim)
            except ValueError as err:
                raise ConfigError("trim", str(err)) from None
        check_within("burst_share", self.burst_share, 0.0, 1.0, lo_open=True)
        check_positive("burst_frames", self.burst_frames)
        check_within("burst_jump", self.burst_jump, 1.0, math.inf, lo_open=True)
        for key, origin in self.origins.items():
            if origin not in ORIGINS:
                raise ConfigError("origins", f"{key}: got {origin!r}; allowed: {', '.join(ORIGINS)}")
        if self.arena is not None:
            self.tank()   # checked here: ConfigError naming arena.<key>
        self.check_units(given_only=True)

    def check_units(self, given_only: bool = False) -> None:
        """The settings that depend on each other: a body length with tracks in metres, frame numbers with a
        frame rate, pixels with a body length in pixels. With ``given_only`` only what was stated outright
        (a format may still imply units: they are merged before the full check, :func:`load_tracks`)."""
        length = self.units.get("length") if given_only else self.length_unit
        time = self.units.get("time") if given_only else self.time_unit
        if self.body_length is not None and length in ("bl", "px"):
            raise ConfigError("body_length", f"not with units.length = {length!r}: the tracks are "
                                             + ("already in body lengths" if length == "bl" else
                                                "in pixels (give body_length_px)"))
        if self.body_length_px is not None and length is not None and length != "px":
            raise ConfigError("body_length_px", f"only for tracks in pixels; the length unit is {length!r}"
                                                f"{self._from('units.length')}")
        if given_only:
            return
        if time == "frame" and self.fps is None:
            raise ConfigError("fps", "the times are frame numbers (units.time = \"frame\""
                                     f"{self._from('units.time')}): give the frame rate, e.g. --fps 30")
        if length == "px" and self.body_length_px is None:
            raise ConfigError("body_length_px", "the positions are in pixels (units.length = \"px\""
                                                f"{self._from('units.length')}): give the body length in pixels "
                                                "(--body-length-px), or the file's length unit")

    def _from(self, key: str) -> str:
        origin = self.origin(key)
        return {"file": ", from the file", "sidecar": ", from the sidecar"}.get(origin, "")

    def origin(self, key: str) -> str:
        """Where a setting came from: "file", "sidecar", "given" or "default"."""
        if key in self.origins:
            return self.origins[key]
        if key.startswith("units."):
            return "given" if key.split(".", 1)[1] in self.units else "default"
        return "given" if getattr(self, key, None) not in (None, {}, False) else "default"

    @property
    def length_scale(self) -> float:
        """Analysis length units per unit of the file's positions (the factor :func:`load_tracks` applies)."""
        scale = LENGTH_UNITS[self.length_unit] or 1.0
        if self.body_length is not None:
            scale = scale / self.body_length
        if self.body_length_px is not None:
            scale = 1.0 / self.body_length_px
        return scale

    def tank(self):
        """The arena the tracks declare (``arena``: ``kind`` cylinder or box, ``centre``, ``radius`` or
        ``size``, ``height``; in the file's length unit) in the analysis unit, as a
        :class:`flocksweep.simcore.arena.Arena` (the same table a preset's ``[arena]`` is, its wall term at
        the defaults), or None; ConfigError naming ``arena.<key>``."""
        if self.arena is None:
            return None
        from flocksweep.simcore.arena import GEOMETRY, Arena

        if not isinstance(self.arena, dict):
            raise ConfigError("arena", f"expected a table (kind, centre, radius or size), got {self.arena!r}")
        for key in self.arena:
            if key not in GEOMETRY:
                raise ConfigError(f"arena.{key}", f"unknown key{suggest(key, GEOMETRY)}; a track file's arena "
                                                  f"declares its geometry: {', '.join(GEOMETRY)}")
        if self.arena.get("kind", "none") == "none":
            raise ConfigError("arena.kind", "required: 'cylinder' (a circle in 2-D) or 'box' (a rectangle)")
        raw = build(Arena, self.arena, "arena")
        k = self.length_scale
        return dataclasses.replace(raw, centre=tuple(c * k for c in raw.centre), radius=raw.radius * k,
                                   size=tuple(c * k for c in raw.size),
                                   height=None if raw.height is None else raw.height * k)

    @property
    def length_unit(self) -> str:
        return self.units.get("length", "m")

    @property
    def time_unit(self) -> str:
        return self.units.get("time", "s")

    @property
    def unit_label(self) -> str:
        """The analysis length unit: "BL" (body lengths) or "m"."""
        return "BL" if self.length_unit in ("bl", "px") or self.body_length is not None else "m"

    @property
    def seconds_per_time_unit(self) -> float | None:
        """Seconds per unit of the time column (None for timestamps)."""
        return 1.0 / self.fps if self.time_unit == "frame" else TIME_UNITS[self.time_unit]

    def column(self, role: str) -> str:
        return self.columns.get(role, role)

    def scales(self) -> dict:
        """Every unit and scale used, each with where it came from: {name: {"value": ..., "from": ...}}."""
        out = {"length unit": {"value": self.length_unit, "from": self.origin("units.length")},
               "time unit": {"value": self.time_unit, "from": self.origin("units.time")}}
        if self.time_unit == "frame":
            out["fps"] = {"value": self.fps, "from": self.origin("fps")}
        if self.body_length is not None:
            out["body length (m)"] = {"value": self.body_length, "from": self.origin("body_length")}
        if self.body_length_px is not None:
            out["body length (px)"] = {"value": self.body_length_px, "from": self.origin("body_length_px")}
        out["analysis length unit"] = {"value": self.unit_label, "from": "derived"}
        return out


# sidecar keys that are information for people, never settings (never taken for a misspelt setting)
SIDECAR_INFORMATION = ("description", "notes", "note", "comment", "source", "citation", "license", "synthetic",
                       "truth", "species", "author", "date")
MERGED = ("units", "columns", "layout")   # tables merged key by key (what is given wins, key by key)


def sidecar_path(path) -> Path:
    """``tracks.csv.gz`` -> ``tracks.json`` (every suffix replaced)."""
    path = Path(path)
    return path.with_name(path.name.split(".")[0] + ".json")


def read_sidecar(path) -> dict:
    """The sidecar JSON of a track file ({} when there is none)."""
    side = sidecar_path(path)
    if not side.is_file():
        return {}
    try:
        data = json.loads(side.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(str(side), f"not valid JSON: {err}") from None
    if not isinstance(data, dict):
        raise ConfigError(str(side), "expected a JSON object")
    return data


def track_source(path, given: dict, where: str = "", cls=None) -> TrackSource:
    """The :class:`TrackSource` (or subclass ``cls``) of ``path``: the sidecar's settings, overridden by
    ``given`` (tables such as ``units`` key by key); ``origins`` records what came from the sidecar."""
    cls = TrackSource if cls is None else cls
    known = [f.name for f in fields(cls) if f.name != "origins"]
    sidecar = read_sidecar(path)
    for key in sidecar:
        hint = "" if key in known or key in SIDECAR_INFORMATION else suggest(key, known)
        if hint or key == "origins":
            raise ConfigError(f"{sidecar_path(path)}: {key}", f"unknown setting{hint}; settings: {', '.join(known)} "
                                                              "(other keys are information, e.g. description)")
    if "origins" in given:
        raise ConfigError(f"{where}.origins" if where else "origins", f"unknown key; allowed keys: {', '.join(known)}")
    settings = {k: v for k, v in sidecar.items() if k in known}
    origins = {}
    for key, value in settings.items():
        if key in MERGED and isinstance(value, dict):
            origins.update({f"{key}.{k}": "sidecar" for k in value})
        else:
            origins[key] = "sidecar"
    for key, value in given.items():
        if value is None:
            continue
        if key in MERGED and isinstance(value, dict) and isinstance(settings.get(key), dict):
            settings[key] = {**settings[key], **value}
            for k in value:
                origins.pop(f"{key}.{k}", None)
        else:
            settings[key] = value
            origins.pop(key, None)
            if key in MERGED and isinstance(value, dict):
                for k in [o for o in origins if o.startswith(f"{key}.")]:
                    origins.pop(k)
    return build(cls, {**settings, "origins": origins}, where)


# ------------------------------------------------------------------------------------------- reading

@dataclass(frozen=True, eq=False)
class TrackTable:
    """A track file read and converted: ``frame`` has row, flock, id, t (s), x, y, z (analysis units) and,
    when given, vx, vy, vz and pattern; ``issues`` what reading found (notes and warnings only)."""

    frame: pd.DataFrame
    path: Path
    source: TrackSource
    dims: int
    has_velocity: bool
    has_pattern: bool
    line_offset: int | None      # CSV: line = row + 1; Parquet: None
    t_origin: str = ""           # datetime tracks: the timestamp of t = 0
    issues: tuple = ()

    @property
    def unit_label(self) -> str:
        return self.source.unit_label


def _numeric(frame: pd.DataFrame, role: str, name: str, errors: list, allow_missing: bool) -> np.ndarray:
    import pandas as pd
    raw = frame[name]
    values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=np.float64)
    bad = np.isnan(values) & raw.notna().to_numpy()
    bad |= np.isinf(values)
    if not allow_missing:
        bad |= raw.isna().to_numpy()
    if bad.any():
        rows = np.flatnonzero(bad) + 1
        example = raw.iloc[rows[0] - 1]
        errors.append(Issue("error", "bad value", f"{role}: not a finite number (first: {example!r})",
                            rows=tuple(rows), column=name))
    return values


MAX_MAGNITUDE = 1e100   # a coordinate or velocity beyond this (in analysis units) is no physical length


def _too_large(values: np.ndarray, role: str, name: str, errors: list) -> None:
    """An error naming the column and rows whose values (converted) exceed MAX_MAGNITUDE: their squares,
    distances and speeds would overflow to infinity."""
    with np.errstate(invalid="ignore"):
        big = np.abs(values) > MAX_MAGNITUDE
    if big.any():
        rows = np.flatnonzero(big) + 1
        errors.append(Issue("error", "bad value", f"{role}: {values[rows[0] - 1]:.4g} is beyond {MAX_MAGNITUDE:g} "
                            "analysis units; distances and speeds derived from it would not be finite (check the "
                            "units and the column)", rows=tuple(rows), column=name))


def _timestamps(column: pd.Series) -> tuple[pd.Series, list]:
    """Timestamps parsed; stamps with different UTC offsets converted to UTC (a note says so)."""
    import pandas as pd
    try:
        return pd.to_datetime(column, errors="coerce"), []
    except (ValueError, TypeError):    # mixed UTC offsets (or offsets beside stamps without one)
        stamps = pd.to_datetime(column, errors="coerce", utc=True, format="mixed")
        return stamps, ["time stamps with different UTC offsets converted to UTC (stamps without an offset taken "
                        "as UTC)"]


def _times(frame: pd.DataFrame, name: str, unit: str, seconds: float | None, errors: list,
           notes: list) -> tuple[np.ndarray, str]:
    if unit != "datetime":
        return _numeric(frame, "t", name, errors, allow_missing=False) * seconds, ""
    stamps, said = _timestamps(frame[name])
    notes += said
    bad = stamps.isna().to_numpy()
    if bad.any():
        rows = np.flatnonzero(bad) + 1
        errors.append(Issue("error", "bad value", f"t: not a timestamp (first: {frame[name].iloc[rows[0] - 1]!r})",
                            rows=tuple(rows), column=name))
        return np.zeros(len(frame)), ""
    origin = stamps.min()
    return (stamps - origin).dt.total_seconds().to_numpy(dtype=np.float64), str(origin)


def _present_roles(frame: pd.DataFrame, source: TrackSource, path: Path) -> dict:
    """Role -> column name of the file; every missing required (or mapped) column in one TrackError."""
    columns = [str(c) for c in frame.columns]
    roles, missing = {}, []
    for role in ROLES:
        name = source.column(role)
        if name in columns:
            roles[role] = name
        elif role in REQUIRED or role in source.columns:
            mapped = f" (mapped to {name!r})" if role in source.columns else ""
            missing.append(Issue("error", "missing column", f"no column for role {role!r}{mapped}"
                                 f"{suggest(name, columns)}; the file has: {', '.join(columns)}; map one with "
                                 f"columns {role}=NAME", column=name))
    velocity = [r for r in ("vx", "vy", "vz") if r in roles]
    need = ["vx", "vy"] + (["vz"] if "z" in roles else [])
    if velocity and sorted(velocity) != sorted(need):
        missing.append(Issue("error", "missing column", f"velocities need all of {need}, the file maps {velocity}"))
    if missing:
        raise TrackError(missing, path)
    return roles


def _unmapped(frame: pd.DataFrame, roles: dict) -> list[Issue]:
    """A warning listing the file's columns that no role uses (they are not read)."""
    used = set(roles.values())
    left = [str(c) for c in frame.columns if str(c) not in used]
    if not left:
        return []
    hints = [f"{name} (a {role}?)" for name in left for role in ROLES
             if role not in roles and (re.split(r"[^a-z0-9]", name.lower())[0] == role or suggest(name, [role]))]
    return [Issue("warning", "unmapped columns", f"{len(left)} column(s) not used: {', '.join(left)}"
                  + (f"; perhaps {', '.join(hints)}" if hints else "") + "; map one with columns ROLE=NAME "
                  f"(roles: {', '.join(ROLES)})")]


def _refuse_unused(source: TrackSource, fmt: str) -> None:
    """A ConfigError naming each setting the format does not use (before the file is read)."""
    def said(key):
        return source.origin(key) in ("given", "sidecar")
    if said("layout") and source.layout and fmt not in ARRAY_FORMATS:
        raise ConfigError("layout", f"the {fmt} format has no array layout (--layout is for the array formats: "
                                    f"{', '.join(ARRAY_FORMATS)})")
    if source.columns and fmt not in COLUMN_FORMATS:
        raise ConfigError("columns", f"the {fmt} format names its own columns (a column map is for "
                                     f"{', '.join(COLUMN_FORMATS)} files; arrays take --layout)")
    if fmt == "movebank":
        other = sorted(set(source.columns) - {"id", "t", "flock", "z"})
        if other:
            raise ConfigError(f"columns.{other[0]}", "Movebank positions come from location-long and location-lat; "
                                                     "map only id, t, flock and z")
        for kind, fixed in (("length", "m"), ("time", "datetime")):
            if kind in source.units and source.units[kind] != fixed:
                raise ConfigError(f"units.{kind}", f"got {source.units[kind]!r}; Movebank tracks are projected to "
                                                   f"metres with UTC time stamps (units.{kind} = {fixed!r}); give "
                                                   "body_length for body lengths")


def _refuse_unused_after(source: TrackSource, fmt: str) -> None:
    """Settings that the file, once read, turns out not to use."""
    if source.fps is not None and source.time_unit != "frame" and source.origin("fps") in ("given", "sidecar"):
        raise ConfigError("fps", f"the {fmt} file's times are in {source.time_unit!r}, not frame numbers, so a frame "
                                 "rate is not used; give units time=frame if the times are frame numbers")


def _read_any(path: Path, source: TrackSource) -> tuple[pd.DataFrame, TrackSource, list]:
    """The file's long table, the source it is read with (the format resolved, a tracker's file turned into
    the long table, its column map used up, with the settings it implies as defaults, marked "file" in
    ``origins``; every setting checked against the others) and notes on what reading did."""
    fmt = detect_format(path, source.layout) if source.format == "auto" else source.format
    _refuse_unused(source, fmt)
    if fmt not in WIDE_FORMATS:
        frame = read_table(path, fmt)
        resolved, notes = dataclasses.replace(source, format=fmt), list(frame.attrs.get(NOTES, []))
    else:
        frame, implied = read_wide(path, fmt, source)
        origins = dict(source.origins)
        units = {**implied.get("units", {}), **source.units}
        origins.update({f"units.{kind}": "file" for kind in implied.get("units", {}) if kind not in source.units})
        settings = {"format": fmt, "units": units, "columns": source.columns if fmt == "trajr" else {}}
        for key in ("fps", "body_length_px"):
            if getattr(source, key) is None and key in implied and not (key == "body_length_px" and
                                                                         units.get("length") != "px"):
                settings[key] = implied[key]
                origins[key] = "file"
        resolved = dataclasses.replace(source, **settings, origins=origins)
        notes = list(implied.get("notes", [])) + ([implied["skipped"]] if "skipped" in implied else [])
    resolved.check_units()
    _refuse_unused_after(resolved, fmt)
    return frame, resolved, notes


def load_tracks(path, source: TrackSource) -> TrackTable:
    """Read ``path`` and convert it (see the module docstring); TrackError lists every bad cell."""
    import pandas as pd
    path = Path(path)
    frame, source, notes = _read_any(path, source)
    roles = _present_roles(frame, source, path)
    errors: list[Issue] = []
    out = {"row": np.arange(1, len(frame) + 1)}
    flock_name = path.name.split(".")[0]
    out["flock"] = frame[roles["flock"]].astype(str).to_numpy() if "flock" in roles else np.full(len(frame), flock_name)
    for role in ("flock", "id"):
        if role in roles and frame[roles[role]].isna().any():
            errors.append(Issue("error", "bad value", f"{role}: missing",
                                rows=tuple(np.flatnonzero(frame[roles[role]].isna()) + 1), column=roles[role]))
    ids = frame[roles["id"]]
    out["id"] = ids.to_numpy()
    out["t"], origin = _times(frame, roles["t"], source.time_unit, source.seconds_per_time_unit, errors, notes)
    scale = LENGTH_UNITS[source.length_unit] or 1.0
    if source.body_length is not None:
        scale = scale / source.body_length
    if source.body_length_px is not None:
        scale = 1.0 / source.body_length_px
    for role in ("x", "y", "z", "vx", "vy", "vz"):
        if role in roles:
            values = _numeric(frame, role, roles[role], errors, allow_missing=True)
            if role.startswith("v") and source.time_unit not in ("datetime", "frame"):
                values = values / source.seconds_per_time_unit
            out[role] = values if scale == 1.0 else values * scale
            _too_large(out[role], role, roles[role], errors)
    if "z" not in roles:
        out["z"] = np.zeros(len(frame))
        if "vx" in roles:
            out["vz"] = np.zeros(len(frame))
    if "pattern" in roles:
        pattern = _numeric(frame, "pattern", roles["pattern"], errors, allow_missing=False)
        if np.any(pattern != np.round(pattern)):
            errors.append(Issue("error", "bad value", "pattern: not an integer", column=roles["pattern"],
                                rows=tuple(np.flatnonzero(pattern != np.round(pattern)) + 1)))
        out["pattern"] = pattern
    line_offset = 1 if source.format == "csv" else None
    if errors:
        raise TrackError(errors, path, line_offset)
    table = pd.DataFrame(out)
    return _drop_undetected(TrackTable(frame=table, path=path, source=source, dims=3 if "z" in roles else 2,
                                       has_velocity="vx" in roles, has_pattern="pattern" in roles,
                                       line_offset=line_offset, t_origin=origin,
                                       issues=tuple(_unmapped(frame, roles)) + tuple(
                                           Issue("note", "reading", note) for note in notes)))


def _drop_undetected(table: TrackTable) -> TrackTable:
    """Rows without a complete position are missed detections: reported as a note, then left out."""
    frame = table.frame
    missing = frame[["x", "y", "z"]].isna().any(axis=1).to_numpy()
    if not missing.any():
        return table
    note = Issue("note", "missed detection", f"{int(missing.sum())} rows have no (complete) position: "
                 "treated as not detected at that time", rows=tuple(frame["row"].to_numpy()[missing]))
    return dataclasses.replace(table, frame=frame[~missing].reset_index(drop=True), issues=table.issues + (note,))


# -------------------------------------------------------------------------------------------- flocks

@dataclass(frozen=True, eq=False)
class RawFlock:
    """One flock's samples as detected: sorted by individual, then time (see :func:`raw_flocks`)."""

    name: str
    ids: np.ndarray                 # (N,) individual ids, sorted
    t: np.ndarray                   # (S,) seconds
    ind: np.ndarray                 # (S,) int64 index into ids, non-decreasing
    pos: np.ndarray                 # (S, 3) analysis units
    vel: np.ndarray | None = None   # (S, 3) or None
    pattern: np.ndarray | None = None  # (N,) int64 or None
    dims: int = 3
    rows: np.ndarray | None = None  # (S,) source rows, None for simulated samples

    def bounds(self) -> np.ndarray:
        """(N + 1,) start of each individual's samples in the arrays."""
        return np.searchsorted(self.ind, np.arange(len(self.ids) + 1))

    def source_rows(self, samples) -> tuple:
        """Source rows of the given sample indices (empty for simulated flocks)."""
        return () if self.rows is None else tuple(int(r) for r in self.rows[np.asarray(samples, dtype=int)])


def _sorted_ids(ids: np.ndarray) -> np.ndarray:
    import pandas as pd
    unique = pd.unique(ids)
    try:
        return np.array(sorted(unique))
    except TypeError:  # mixed types: sort as text
        return np.array(sorted(unique, key=str), dtype=object)


def raw_flocks(table: TrackTable) -> tuple[list[RawFlock], list[Issue]]:
    """The flocks of a table, in order of first appearance, and notes on rows that were out of order."""
    import pandas as pd
    flocks, issues = [], []
    frame = table.frame
    for name, group in frame.groupby("flock", sort=False):
        ids = _sorted_ids(group["id"].to_numpy())
        ind = pd.Index(ids).get_indexer(group["id"].to_numpy()).astype(np.int64)
        t = group["t"].to_numpy(dtype=np.float64)
        order = np.lexsort((t, ind))
        by_file = np.argsort(ind, kind="stable")       # each individual's samples in file order
        backwards = np.flatnonzero((np.diff(ind[by_file]) == 0) & (np.diff(t[by_file]) < 0)) + 1
        if backwards.size:
            rows = group["row"].to_numpy()[by_file][backwards]
            issues.append(Issue("note", "unsorted", f"{backwards.size} samples come after a later time of the "
                                "same individual in the file; sorted by time", flock=str(name), rows=tuple(rows)))
        pos = group[["x", "y", "z"]].to_numpy(dtype=np.float64)[order]
        vel = group[["vx", "vy", "vz"]].to_numpy(dtype=np.float64)[order] if table.has_velocity else None
        if vel is not None and table.dims == 2:
            vel[:, 2] = 0.0
        pattern = None
        if table.has_pattern:
            per_id = group.groupby(ind)["pattern"].agg(["min", "max"])
            mixed = per_id.index[per_id["min"] != per_id["max"]]
            if len(mixed):
                raise TrackError([Issue("error", "bad value", "pattern changes over time for an individual",
                                        flock=str(name), id=str(ids[mixed[0]]),
                                        column=table.source.column("pattern"))], table.path, table.line_offset)
            pattern = per_id["min"].to_numpy().astype(np.int64)
        flocks.append(RawFlock(name=str(name), ids=ids, t=t[order], ind=ind[order], pos=pos, vel=vel,
                               pattern=pattern, dims=table.dims, rows=group["row"].to_numpy()[order]))
    return flocks, issues


# ------------------------------------------------------------------------------------------- writing

def tracks_frame(obs, flock: str) -> pd.DataFrame:
    """A simulator run's records as a long track table (flock, id, t, x, y, z, vx, vy, vz, pattern), in
    body lengths and seconds, one row per boid and record, record-major. Values are the simulator's own
    float64 numbers, so reading the table back gives them exactly. A run in the plane z = 0 (a 2-D model's:
    every z and vz exactly 0) has no z and vz columns, so it reads back as 2-D tracks."""
    import pandas as pd
    n_records, n = obs.pos.shape[:2]
    planar = not (np.any(obs.pos[:, :, 2]) or np.any(obs.vel[:, :, 2]))
    axes = "xy" if planar else "xyz"
    return pd.DataFrame({
        "flock": flock,
        "id": np.tile(np.arange(n), n_records),
        "t": np.repeat(obs.times, n),
        **{axis: obs.pos[:, :, k].reshape(-1) for k, axis in enumerate(axes)},
        **{f"v{axis}": obs.vel[:, :, k].reshape(-1) for k, axis in enumerate(axes)},
        "pattern": np.tile(np.asarray(obs.pattern, dtype=np.int64), n_records),
    })


TRACKS_SIDECAR = {"units": {"length": "bl", "time": "s"}}
