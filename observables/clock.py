"""The sampling clock of a flock's samples: its interval, its phase, the stamps' precision, and how it was found.

Trackers sample at a fixed rate and write each sample's time as a frame number or as a time stamp, in
double or in single precision (MATLAB files often hold single-precision seconds). ``sampling_clock(t, ind,
frame_seconds=None, fallback=None) -> Clock`` recovers the grid those samples lie on:

* **interval** h: ``frame_seconds`` for frame clocks (seconds per frame, 1/fps: the frame numbers are
  the grid, so h is exact); else from the time stamps, without rounding: the median spacing h0 between
  consecutive samples of an individual gives every step its whole number of intervals, h1 = (sum of
  those steps' spans) / (their interval count), every sample its grid index k = round((t - t_min) / h1),
  and the least-squares line t = c + k h through all samples gives h, exact to the stamps' precision.
  Of the intervals near it, the simplest that fits the stamps as well is kept (:func:`_candidates`: the
  rate to 1, 2, ... significant digits, then the interval so; 60 fps gives 1/60 s, not 0.0166666667);
* **precision**, from the samples' residuals r = t - (c + k h) from that grid: ``"exact"`` when every
  |r| <= :data:`SNAP` h (double-precision stamps of a regular sampling), ``"single"`` when every |r| is
  within :data:`SINGLE_UNITS` of the stamp (2^-22 |t|, four single-precision rounding units: stamps
  written as float32, or printed from float32), otherwise ``"irregular"`` (jittered stamps, a glitch in
  the clock, several phases: samples off the grid are interpolated by :mod:`.resample`, and h is the
  median spacing, cleared of its float noise); a frame clock is exact;
* **tolerance** of a sample (:meth:`Clock.tolerance`): a record's grid time and a sample's time are the
  same time within SNAP x the record interval, widened for single-precision stamps by their rounding
  (2^-22 |t|), so a float32 stamp 4e-6 s off its frame at t = 100 s is that frame's sample, not a reason
  to interpolate;
* **grid start** (:func:`grid_start`): on a regular clock the grid time of the first sample; for
  irregular stamps the first sample time plus the sampling phase (:func:`grid_phase`, the circular mean
  of the sample times modulo the record interval).

Without ``ind`` (sample times of unknown individuals) and with ``fallback`` the samples are taken to be
``fallback`` apart (:func:`_on_grid`: their phase and precision on that grid); ``fallback`` is also the
interval when the stamps cannot tell one (no individual with two samples), else that is a ValueError.
``Clock.how`` says in words how the interval was found (``measure.json``, the runs table, the report).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SNAP = 1e-6               # grid and sample times closer than SNAP x interval are the same time
SINGLE_UNITS = 2.0 ** -22  # relative: four single-precision rounding units (unit roundoff 2^-24)
PRECISIONS = ("exact", "single", "irregular")


@dataclass(frozen=True)
class Clock:
    """A flock's sampling grid (see the module docstring): t = intercept + k x interval."""

    interval: float            # seconds between samples (h), the sampling's own
    intercept: float           # seconds: the grid time of k = 0
    precision: str             # "exact", "single" or "irregular"
    how: str                   # how the interval was found, in words
    samples: int = 0           # samples the precision was judged on

    @property
    def regular(self) -> bool:
        """Samples lie on the grid (to their stamps' precision)."""
        return self.precision != "irregular"

    def tolerance(self, t: np.ndarray, spacing: float | None = None) -> np.ndarray:
        """Seconds within which a sample at time ``t`` and a grid time are the same time (per sample):
        SNAP x ``spacing`` (the record interval; default the sampling interval), plus the rounding of
        single-precision stamps."""
        base = SNAP * (self.interval if spacing is None else spacing)
        t = np.asarray(t, dtype=np.float64)
        if self.precision != "single":
            return np.full(t.shape, base)
        return base + SINGLE_UNITS * np.abs(t)

    def index(self, t: np.ndarray) -> np.ndarray:
        """The grid index k of each time (nearest)."""
        return np.rint((np.asarray(t, dtype=np.float64) - self.intercept) / self.interval).astype(np.int64)

    def describe(self) -> str:
        return f"{self.interval!r} s: {self.how}"


def grid_phase(t: np.ndarray, interval: float) -> float:
    """Offset in [0, h) of the sampling phase from the first sample time: the circular mean of the sample
    times modulo h when they cluster (mean resultant length >= 0.5: a regular sampling, also with jittered
    stamps), else 0 (samples denser than h, or without a common phase)."""
    angle = 2.0 * np.pi * ((t - t.min()) / interval)
    x, y = np.cos(angle).mean(), np.sin(angle).mean()
    if np.hypot(x, y) < 0.5:
        return 0.0
    offset = (np.arctan2(y, x) / (2.0 * np.pi)) % 1.0 * interval
    return 0.0 if offset <= SNAP * interval or offset >= (1 - SNAP) * interval else float(offset)


def _steps(t: np.ndarray, ind: np.ndarray | None) -> np.ndarray:
    """Positive time differences between consecutive samples of an individual (samples sorted by
    individual, then time; without ``ind`` the distinct times of all samples)."""
    if ind is None:
        dt = np.diff(np.unique(t))
    else:
        same = np.diff(ind) == 0
        dt = np.diff(t)[same]
    return dt[dt > 0]


def _fit(t: np.ndarray, k: np.ndarray) -> tuple[float, float]:
    """Least-squares (intercept, slope) of t = c + k h."""
    km, tm = k.mean(), t.mean()
    dk = k - km
    var = float(dk @ dk)
    if var == 0:
        return float(t.min()), math.nan
    h = float(dk @ (t - tm)) / var
    return float(tm - h * km), h


def _candidates(h: float):
    """Intervals near ``h``, simplest first: 1 / (the rate to 1, 2, ... significant digits), then h to
    1, 2, ... significant digits, then h itself (60 fps before 0.0166...7 s)."""
    for digits in range(1, 18):
        yield 1.0 / float(f"{1.0 / h:.{digits}g}")
        yield float(f"{h:.{digits}g}")
    yield h


def _shortest(value: float, within: float) -> float:
    """The shortest decimal (fewest significant digits) within ``within`` of ``value``."""
    for digits in range(1, 18):
        rounded = float(f"{value:.{digits}g}")
        if abs(rounded - value) <= within:
            return rounded
    return value


def _classify(t: np.ndarray, k: np.ndarray, intercept: float, interval: float) -> str:
    residual = np.abs(t - (intercept + k * interval))
    if residual.max() <= SNAP * interval:
        return "exact"
    if (residual <= SNAP * interval + SINGLE_UNITS * np.abs(t)).all():
        return "single"
    return "irregular"


def _from_stamps(t: np.ndarray, ind: np.ndarray | None) -> Clock:
    dt = _steps(t, ind)
    if dt.size == 0:
        raise ValueError("no individual has two samples at different times; cannot infer the sampling interval")
    h0 = float(np.median(dt))
    counts = np.maximum(np.rint(dt / h0), 1.0)
    fits = np.abs(dt - counts * h0) <= 0.25 * h0
    h1 = float(dt[fits].sum() / counts[fits].sum()) if fits.any() else h0
    k = np.rint((t - t.min()) / h1)
    intercept, h = _fit(t, k)
    if not (math.isfinite(h) and h > 0):
        intercept, h = float(t.min()), h1
    precision = _classify(t, k, intercept, h)
    residual = t - (intercept + k * h)
    if precision == "exact":
        # the simplest interval (or rate) that fits the stamps as well as the least-squares line: 1/60 s
        worst = 2.0 * float(np.abs(residual).max()) + 4.0 * float(np.spacing(np.abs(t).max()))
        for candidate in _candidates(h):
            shift = float(np.mean(t - k * candidate))
            if np.abs(t - (shift + k * candidate)).max() <= worst:
                h, intercept = candidate, shift
                break
    elif precision == "single":   # the simplest rate (or interval) within the fit's own standard error
        dk = k - k.mean()
        se = float(np.sqrt((residual @ residual) / max(len(t) - 2, 1) / max(float(dk @ dk), 1e-300)))
        h = next(c for c in _candidates(h) if abs(c - h) <= max(se, 4.0 * float(np.spacing(h))))
        intercept = float(np.mean(t - k * h))
    else:   # jittered: the median spacing (robust to a glitch), cleared of the stamps' rounding
        h = _shortest(h0, 4.0 * float(np.spacing(np.abs(t).max())))
        intercept = float(t.min())
    words = {"exact": "on a regular grid (double precision)",
             "single": "on a regular grid in single precision (matched to their frames within their rounding)",
             "irregular": "irregular or jittered (their median spacing)"}[precision]
    words = f"the time stamps of {len(t):,} samples, {words}"
    return Clock(interval=h, intercept=intercept, precision=precision, how=words, samples=len(t))


def sampling_clock(t, ind=None, frame_seconds: float | None = None, fallback: float | None = None) -> Clock:
    """The sampling clock of sample times ``t`` (seconds; sorted by individual ``ind``, then time), see the
    module docstring. ``frame_seconds``: the times are frame numbers times this (a frame clock).
    ``fallback``: the interval to assume when the stamps cannot tell one (no individual with two samples);
    without it that is a ValueError."""
    t = np.asarray(t, dtype=np.float64)
    if t.size == 0:
        return Clock(float(frame_seconds or fallback or 1.0), 0.0, "exact", "no samples")
    if frame_seconds is not None:
        k = np.rint((t - t.min()) / frame_seconds)
        intercept = float(t.min())
        return Clock(float(frame_seconds), intercept, _classify(t, k, intercept, frame_seconds),
                     f"frame numbers at {1.0 / frame_seconds:g} frames per second", samples=len(t))
    if ind is None and fallback is not None:
        return _on_grid(t, float(fallback))
    try:
        return _from_stamps(t, None if ind is None else np.asarray(ind))
    except ValueError:
        if fallback is None:
            raise
        return _on_grid(t, float(fallback))


def _on_grid(t: np.ndarray, interval: float) -> Clock:
    """The clock of samples taken to be ``interval`` apart: their phase and precision on that grid."""
    k = np.rint((t - t.min()) / interval)
    intercept = float(np.mean(t - k * interval))
    precision = _classify(t, k, intercept, interval)
    if precision == "irregular":
        intercept = float(t.min())
    return Clock(interval, intercept, precision, "given", samples=len(t))


def grid_start(clock: Clock, times: np.ndarray, spacing: float) -> float:
    """The first record time over sample times ``times`` (sorted, distinct): the first sample's grid time
    on a regular clock, else the first sample time plus the sampling phase at ``spacing``."""
    if clock.regular:
        return float(clock.intercept + clock.index(times[:1])[0] * clock.interval)
    return float(times[0] + grid_phase(times, spacing))
