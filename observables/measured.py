"""Measured tracks -> the tables of a sweep: one row per flock, one time series per flock.

``measure_tracks(table, settings, interval=None, max_gap=None, velocity_interval=None, progress=False)
-> Measurement``
takes a read track file (:func:`~observables.tracks.load_tracks`) and, flock by flock:

0. finds its sampling clock (:func:`flock_clock`: frame numbers give 1/fps, time stamps their own exact
   interval and precision, :mod:`~observables.clock`), drops its zero padding and applies the trim
   (:mod:`~observables.trimming`);
1. checks it (:func:`~observables.validation.check_flock`: duplicates, impossible speeds,
   recorded velocities, gaps); errors of every flock are collected and raised together as one
   :class:`~observables.validation.TrackError`;
2. resamples it onto its record grid (:func:`~observables.resample.resample`; ``interval``
   None: each flock's own sampling interval, from its clock;
   ``velocity_interval`` None: differences over one interval);
3. measures it with :func:`~observables.summary.measure_run`, the step every sweep and
   calibration uses (``settings``: :func:`track_settings`).

``Measurement.runs`` has one row per flock: ``run_id`` (the flock's name), ``flock``, ``status`` ("ok",
or "failed" with the reason in ``error``: a flock too short for the velocity interval), ``individuals``,
``records``, ``dims``, ``t_start`` (the file's clock at t = 0 of its records), ``duration``,
``interval``, ``clock`` (how the interval was found), ``velocity_interval``, ``length_unit`` ("BL" or "m"), then the summary columns of
:func:`~observables.summary.summary_columns` (without leadership) and ``tracked_mean`` /
``tracked_final``, the tank's wall scalars when the tracks declare their tank
(:data:`~observables.columns.WALL_METRIC_NAMES`, :mod:`~observables.walls`), and the directional correlation delays of Nagy et al. 2010 (``dcd_corr_mean``,
``dcd_delay_mean``, ``dcd_edges``, ``dcd_leader_delay``: :mod:`~observables.directional_correlation`,
delays up to ``settings.dcd_max_delay`` s, over the individuals present and the records at or after the
warm-up, by :func:`~observables.summary.measure_run` as for a simulated run). ``Measurement.timeseries`` has run_id, t and one column per metric plus ``tracked``.
``Measurement.issues`` lists what the reading and the checks found (notes and warnings, and an error per
flock that could not be measured: too short for the velocity interval, no record at or after the
warm-up, or measured values that came out infinite, as coordinates near 1e305 make them). When no flock
could be measured, a
:class:`~observables.validation.TrackError` lists why for each (``flocksweep measure`` exits with status 2).

Steps 0-1 are :func:`prepare_flocks` (-> :class:`Prepared` flocks and the issues), steps 0-2
:func:`observe_tracks` (the resampled flocks without metrics: what the viewer shows).
"""
from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass

import numpy as np
import pandas as pd
from tqdm import tqdm

from .directional_correlation import DCD_MAX_DELAY, DCD_METRIC_NAMES
from .metrics import FRAGMENTATION_COHESION
from .observed import ObservedFlock
from .clock import sampling_clock
from .resample import MAX_GAP_INTERVALS, RECORDED, check_size, resample
from .summary import MetricSettings, measure_run, summary_columns
from .tracks import TrackTable, raw_flocks
from .trimming import drop_padding, parse_trim, trim_flock
from .validation import BurstRule, Issue, TrackError, check_flock, check_tank
from .walls import tank_walls

def track_settings(group_radius: float, warmup: float = 0.0,
                   fragmentation_cohesion: float = FRAGMENTATION_COHESION,
                   dcd_max_delay: float = DCD_MAX_DELAY) -> MetricSettings:
    """Metric settings for measured flocks: the group radius (analysis length units) is required, there is
    no periodic box and no leadership (the escape duration is not applicable: nan); the directional
    correlation delays are on, up to ``dcd_max_delay`` s."""
    if group_radius is None:
        raise ValueError("group radius: measured flocks need one (in the tracks' length units); there is no "
                         "model perception range to default to")
    return MetricSettings(warmup=warmup, group_radius=float(group_radius), fragmentation_cohesion=fragmentation_cohesion,
                          leadership=False, box=None, escape_duration=math.nan, dcd=True,
                          dcd_max_delay=dcd_max_delay)


@dataclass(frozen=True, eq=False)
class Measurement:
    runs: pd.DataFrame
    timeseries: pd.DataFrame
    issues: list
    flocks: list            # ObservedFlock per measured flock (failed ones left out)
    table: TrackTable


def _row(name: str, status: str, error: str, table: TrackTable, interval: float, velocity_interval) -> dict:
    return {"run_id": name, "flock": name, "status": status, "error": error, "individuals": 0, "records": 0,
            "dims": table.dims, "t_start": math.nan, "duration": math.nan, "interval": interval, "clock": "",
            "velocity_interval": str(velocity_interval), "length_unit": table.unit_label}


def _measure_flock(flock: ObservedFlock, row: dict, settings: MetricSettings) -> pd.DataFrame:
    series, summary = measure_run(flock, settings)
    row.update(individuals=int(flock.n), records=int(len(flock.times)), t_start=flock.t_start,
               duration=float(flock.times[-1] - flock.times[0]))
    row.update(summary)
    return pd.DataFrame({"run_id": flock.name, "t": flock.times, **series})


OVERFLOW = ("positions or velocities too large (or times too close) for their squares, differences and speeds "
            "to be numbers; check the units and columns")


def _unmeasurable(flock: ObservedFlock, settings: MetricSettings) -> str:
    """Why a resampled flock cannot be measured ('' when it can): nobody present, no record at or after the
    warm-up, or velocities that overflowed."""
    if np.isinf(flock.vel).any() or np.isinf(flock.pos).any():
        return f"non-finite derived values (velocities): {OVERFLOW}"
    if not flock.present.any():
        return "no record has an individual with a known position and velocity"
    if not np.any(flock.times >= settings.warmup):
        return (f"no record at or after the warm-up of {settings.warmup:g} s (the flock's records end at "
                f"{flock.times[-1]:g} s), so every window mean is undefined; choose a warm-up below that")
    return ""


def _not_finite(row: dict, series: pd.DataFrame) -> str:
    """The measured values that came out infinite (an overflow, 'speed_mean_mean = inf, ...'), or ''."""
    bad = [f"{key} = {value}" for key, value in row.items()
           if isinstance(value, float) and math.isinf(value)]
    numbers = series.select_dtypes("number")
    bad += [f"{name} (series)" for name in numbers.columns if np.isinf(numbers[name].to_numpy()).any()
            and not any(item.startswith(name) for item in bad)]
    return ", ".join(bad[:4]) + (f" and {len(bad) - 4} more" if len(bad) > 4 else "")


def measure_tracks(table: TrackTable, settings: MetricSettings, interval: float | None = None,
                   max_gap: float | None = None, velocity_interval=None, progress: bool = False) -> Measurement:
    """Check, resample and measure every flock of ``table`` (see the module docstring); ``progress`` shows a
    progress bar over the flocks."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):   # overflows are checked and named
        return _measure_tracks(table, settings, interval, max_gap, velocity_interval, progress)


def flock_clock(raw, source, interval: float | None = None):
    """(the sampling clock of a flock's samples, how its record interval was found): frame numbers give
    1/fps exactly, time stamps their own interval (:func:`~observables.clock.sampling_clock`); an explicit
    ``interval`` is the record interval."""
    frame_seconds = source.seconds_per_time_unit if source.time_unit == "frame" else None
    clock = sampling_clock(raw.t, raw.ind, frame_seconds, fallback=interval)
    if interval is not None:
        return clock, f"given ({interval!r} s; the samples: {clock.how})"
    if frame_seconds is not None:
        return clock, f"{clock.how} (fps: {source.origin('fps')})"
    return clock, clock.how


@dataclass(frozen=True)
class Prepared:
    """A flock ready to be resampled: its samples (padding and trim applied, checked), record interval,
    gap limit, sampling clock and how the interval was found."""

    raw: object
    interval: float
    max_gap: float
    clock: object
    how: str


def prepare_flocks(table: TrackTable, interval: float | None = None, max_gap: float | None = None):
    """(the flocks ready to resample, the issues found): each flock's clock, padding, trim and checks; a
    TrackError lists every flock's errors together."""
    raws, issues = raw_flocks(table)
    issues = list(table.issues) + issues
    source = table.source
    trim = parse_trim(source.trim) if source.trim else None
    burst = BurstRule(source.burst_share, source.burst_frames, source.burst_jump)
    tank = source.tank()
    prepared, errors = [], []
    for raw in raws:
        try:
            clock, how = flock_clock(raw, source, interval)
        except ValueError as err:
            errors.append(Issue("error", "interval", f"flock {raw.name!r}: {err}", flock=raw.name))
            continue
        raw, found = drop_padding(raw, source.keep_padding)
        issues += found
        raw, found = trim_flock(raw, trim, clock)
        if any(i.level == "error" for i in found):
            errors += found
            continue
        issues += found
        step = interval if interval is not None else clock.interval
        try:
            check_size(raw.t, len(raw.ids), step, clock)
        except ValueError as err:
            errors.append(Issue("error", "interval", str(err), flock=raw.name))
            continue
        gap = MAX_GAP_INTERVALS * step if max_gap is None else max_gap
        if gap < step:
            errors.append(Issue("error", "max_gap", f"max_gap {gap:g} s is below the sampling interval {step:g} s: "
                                "consecutive samples would not be joined", flock=raw.name))
            continue
        raw, found = check_flock(raw, step, gap, source.max_speed, source.bad_speeds, table.unit_label, burst)
        found = found + check_tank(raw, tank, table.unit_label)
        errors += [i for i in found if i.level == "error"]
        issues += [i for i in found if i.level != "error"]
        prepared.append(Prepared(raw, step, gap, clock, how))
    if errors:
        raise TrackError(errors, table.path, table.line_offset)
    return prepared, issues


def observe_tracks(table: TrackTable, interval: float | None = None, max_gap: float | None = None,
                   velocity_interval="auto") -> tuple[list, list]:
    """(the flocks of ``table`` on their record grids, the issues found), as :func:`measure_tracks` makes
    them but without measuring (the viewer's input); ``velocity_interval`` "auto": the tracks' velocities
    when they have them, else one interval. A flock that cannot be resampled is an error issue."""
    if velocity_interval == "auto":
        velocity_interval = RECORDED if table.has_velocity else None
    prepared, issues = prepare_flocks(table, interval, max_gap)
    flocks = []
    for ready in prepared:
        velocity = ready.interval if velocity_interval is None else velocity_interval
        try:
            flocks.append(resample(ready.raw, ready.interval, ready.max_gap, velocity, ready.clock))
        except ValueError as err:
            issues.append(Issue("error", "not resampled", str(err), flock=ready.raw.name))
    return flocks, issues


def _measure_tracks(table, settings, interval, max_gap, velocity_interval, progress) -> Measurement:
    checked, issues = prepare_flocks(table, interval, max_gap)
    walls = tank_walls(table.source.tank())   # the tank the tracks declare: their wall scalars
    if walls is not None:
        settings = dataclasses.replace(settings, walls=walls)
    rows, frames, flocks = [], [], []
    for ready in tqdm(checked, desc="flocks", unit="flock", disable=not progress, file=sys.stderr, mininterval=0.5):
        raw, step, gap = ready.raw, ready.interval, ready.max_gap
        velocity = step if velocity_interval is None else velocity_interval
        row = _row(raw.name, "ok", "", table, step, velocity)
        row["clock"] = ready.how
        try:
            flock = resample(raw, step, gap, velocity, ready.clock)
        except ValueError as err:
            row.update(status="failed", error=str(err))
            rows.append(row)
            continue
        unusable = _unmeasurable(flock, settings)
        frame = None if unusable else _measure_flock(flock, row, settings)
        overflowed = "" if unusable else _not_finite(row, frame)
        if unusable or overflowed:
            row.update(status="failed", error=unusable or f"non-finite derived values ({overflowed}): {OVERFLOW}")
            rows.append(row)
            continue
        frames.append(frame)
        rows.append(row)
        flocks.append(flock)
    failed = [Issue("error", "not measured", row["error"], flock=row["flock"]) for row in rows if row["status"] != "ok"]
    if not flocks:
        empty = "the tracks hold no flock" + (": the file has no rows of detections" if table.frame.empty else "")
        raise TrackError(failed or [Issue("error", "not measured", empty)], table.path, table.line_offset)
    issues += failed
    runs = pd.DataFrame(rows)
    for column in (summary_columns(leadership=False, walls=walls is not None) + ("tracked_mean", "tracked_final")
                   + DCD_METRIC_NAMES):
        if column not in runs:
            runs[column] = np.nan
    timeseries = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["run_id", "t"])
    return Measurement(runs=runs, timeseries=timeseries, issues=issues, flocks=flocks, table=table)


def velocity_label(velocity_interval, interval: float | None) -> str:
    """How the velocities were obtained, in words."""
    if velocity_interval == RECORDED:
        return "the tracks' recorded velocities"
    if velocity_interval is None:
        step = "one sampling interval" if interval is None else f"{interval:g} s (one sampling interval)"
        return f"velocities from positions differenced over {step}"
    return f"velocities from positions differenced over {float(velocity_interval):g} s"
