"""Per-run observables of collective motion: how fast headings and speeds decorrelate, how sharply
individuals turn, how their speeds are spread, and how long the group spends swarming, polarized or
milling.

Input: velocities ``vel`` (R, N, 3) on a regular record grid of spacing ``interval`` (s), nan where an
individual is not seen (a measured flock, or a run seen through an observation model) and the record
times ``times`` (R,); only the records with ``times >= warmup`` (the window of the row's means) count.
v_hat = v / |v| is an individual's heading (none when it is stopped or unseen); s = |v| its speed.
docs/metrics.md ("Observables of collective motion") gives the definitions with units and citations.

* ``turn_rate_mean``, ``turn_rate_q10``, ``turn_rate_q50``, ``turn_rate_q90`` (degrees/s): the turning
  rates angle(v_hat_i(t), v_hat_i(t + interval)) / interval of every individual with a heading at both of
  two consecutive window records, pooled; their mean and 10, 50 and 90 % quantiles (``numpy.quantile``'s
  linear rule).
* ``heading_autocorr_time`` (s): the decay time of C_h(tau) = mean over (i, t) of
  v_hat_i(t) . v_hat_i(t + tau), tau = j x interval, j = 1 .. J, J = floor((R_w - 1) / 2) for R_w window
  records (:func:`decay_time`).
* ``speed_autocorr_time`` (s): the same of the speed fluctuations, ds_i(t) = s_i(t) - (i's mean speed
  over the window): C_s(tau) = mean over (i, t) of ds_i(t) ds_i(t + tau) / mean over (i, t) of ds_i(t)^2;
  nan when the speeds do not fluctuate (the mean square below (1e-12 x the mean speed)^2: a constant-speed
  model).
* ``speed_q10``, ``speed_q50``, ``speed_q90`` (length/s) and ``speed_cv_pooled`` (1): quantiles and
  sd / mean (population sd) of every seen speed of the window, pooled over individuals and records
  (``speed_cv``, a series, is the spread across individuals at one record).
* ``swarming_fraction``, ``polarized_fraction``, ``milling_fraction`` (1): the share of window
  records (with both a polarization P and a milling M) in each state of Tunstrom et al. 2013:
  swarming P < low and M < low, polarized P > high and M < low, milling M > high and P < low; the rest
  is transitional, so the three need not sum to 1. ``high`` and ``low`` are settings (0.65 and 0.35).

Each is nan when it has no term (a run shorter than two window records, nobody moving).

:func:`decay_time` (lags, C): the first lag where C falls to 1/e, interpolated between the lags around it
on log C (exact for an exponential; linear when a C there is <= 0), C(0) = 1; when C stays above 1/e up to
the last lag tau_J, the decay time of the exponential through (tau_J, C(tau_J)), -tau_J / ln C(tau_J)
(nan when C(tau_J) >= 1 - 1e-9: no decorrelation at all, as in a perfectly straight flight); lags whose C
is nan (no pair) are skipped.
"""
from __future__ import annotations

import math

import numpy as np

from .columns import MOTION_METRIC_NAMES  # noqa: F401 - declared there, part of this module's face

STATE_HIGH = 0.65   # Tunstrom et al. 2013: an order parameter above this is high ...
STATE_LOW = 0.35    # ... and below this low
TINY = 1e-12
FLAT = 1e-9         # C within this of 1 at the last lag: no decorrelation (the FFT sums are exact to ~1e-12)


def decay_time(lags: np.ndarray, corr: np.ndarray) -> float:
    """The 1/e decay time of a correlation function sampled at ``lags`` > 0 (see the module docstring)."""
    target = math.exp(-1.0)
    t0, c0 = 0.0, 1.0
    last = None
    for tau, c in zip(np.asarray(lags, dtype=float), np.asarray(corr, dtype=float)):
        if not np.isfinite(c):
            continue
        if c <= target:
            if c0 > 0.0 and c > 0.0:
                share = (math.log(c0) + 1.0) / (math.log(c0) - math.log(c))
            else:
                share = (c0 - target) / (c0 - c)
            return t0 + share * (tau - t0)
        t0, c0, last = tau, c, (tau, c)
    if last is None:
        return math.nan
    tau, c = last
    return -tau / math.log(c) if c < 1.0 - FLAT else math.nan


def _quantiles(values: np.ndarray, qs) -> list[float]:
    if values.size == 0:
        return [math.nan] * len(qs)
    return [float(q) for q in np.quantile(values, qs)]


def _lagged_means(a: np.ndarray, lags: int) -> np.ndarray:
    """(J,) for j = 1..J the mean over the (t, i) with a[t, i] and a[t + j, i] known of a[t, i] . a[t + j, i]
    (a (R, N, d), nan unknown; nan at a lag without such a pair). The sums over t, i and the components for
    every lag at once by FFT: the summed power spectrum of the zero-filled series (and of the known mask,
    for the counts), padded to a power of two >= 2R, transformed back once: O(N R log R) rather than
    O(N R J). The counts are whole numbers, rounded."""
    out = np.full(lags, np.nan)
    if lags < 1:
        return out
    known = np.isfinite(a).all(axis=-1)
    size = 1 << int(2 * len(a) - 1).bit_length()

    def summed(series: np.ndarray) -> np.ndarray:      # (R, C) -> sum over C of sum_t s[t] s[t + j], j = 1..J
        spectrum = np.fft.rfft(np.ascontiguousarray(series.T), size, axis=-1)
        power = (spectrum.real ** 2 + spectrum.imag ** 2).sum(axis=0)
        return np.fft.irfft(power, size)[1:lags + 1]

    total = summed(np.where(known[..., None], a, 0.0).reshape(len(a), -1))
    count = np.rint(summed(known.astype(np.float64)))
    np.divide(total, count, out=out, where=count > 0)
    return out


def turning_rate_grid(heading: np.ndarray, interval: float) -> np.ndarray:
    """(R - 1, N): the turning rate (degrees/s) of each individual between records r and r + 1 of unit
    headings (R, N, 3), nan where a heading is unknown at either."""
    a, b = heading[:-1], heading[1:]
    along = np.sum(a * b, axis=-1)
    across = np.linalg.norm(np.cross(a, b), axis=-1)
    known = np.isfinite(along) & np.isfinite(across)
    out = np.full(along.shape, np.nan)
    out[known] = np.degrees(np.arctan2(across[known], along[known])) / interval
    return out


def turning_rates(heading: np.ndarray, interval: float) -> np.ndarray:
    """Every turning rate (degrees/s) between consecutive records of unit headings (R, N, 3), nan unknown."""
    grid = turning_rate_grid(heading, interval)
    return grid[np.isfinite(grid)]


def motion_metrics(vel: np.ndarray, times: np.ndarray, interval: float, warmup: float,
                   polarization: np.ndarray, milling: np.ndarray, state_high: float = STATE_HIGH,
                   state_low: float = STATE_LOW) -> dict[str, float]:
    """The scalars of ``MOTION_METRIC_NAMES`` of one run (see the module docstring); ``polarization`` and
    ``milling`` are the run's per-record series."""
    if not (np.isfinite(interval) and interval > 0):
        raise ValueError(f"interval: got {interval!r}; expected seconds > 0")
    window = np.asarray(times, dtype=np.float64) >= warmup
    v = np.asarray(vel, dtype=np.float64)[window]
    speed = np.linalg.norm(v, axis=-1)                              # nan where unseen
    with np.errstate(invalid="ignore", divide="ignore"):
        heading = np.where((speed > 0)[..., None], v / speed[..., None], np.nan)
    lags = max((len(v) - 1) // 2, 0)
    lag_times = np.arange(1, lags + 1) * interval
    out: dict[str, float] = {}

    turns = turning_rates(heading, interval) if len(v) > 1 else np.empty(0)
    out["heading_autocorr_time"] = decay_time(lag_times, _lagged_means(heading, lags))
    out["turn_rate_mean"] = float(turns.mean()) if turns.size else math.nan
    out["turn_rate_q10"], out["turn_rate_q50"], out["turn_rate_q90"] = _quantiles(turns, (0.1, 0.5, 0.9))

    seen = speed[np.isfinite(speed)]
    fluct = speed - individual_means(speed)
    square = fluct[np.isfinite(fluct)] ** 2
    mean_speed = seen.mean() if seen.size else math.nan
    if square.size and square.mean() > (TINY * mean_speed) ** 2:
        corr = _lagged_means(fluct[..., None], lags) / square.mean()
        out["speed_autocorr_time"] = decay_time(lag_times, corr)
    else:
        out["speed_autocorr_time"] = math.nan
    out["speed_q10"], out["speed_q50"], out["speed_q90"] = _quantiles(seen, (0.1, 0.5, 0.9))
    out["speed_cv_pooled"] = float(seen.std() / mean_speed) if seen.size and mean_speed > 0 else math.nan

    out.update(state_fractions(np.asarray(polarization)[window], np.asarray(milling)[window], state_high, state_low))
    return out


def individual_means(speed: np.ndarray) -> np.ndarray:
    """(N,) each individual's mean speed over its seen records (nan when never seen)."""
    known = np.isfinite(speed)
    count = known.sum(axis=0)
    total = np.where(known, speed, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def state_fractions(polarization: np.ndarray, milling: np.ndarray, high: float = STATE_HIGH,
                    low: float = STATE_LOW) -> dict[str, float]:
    """Shares of the records (with both order parameters) swarming, polarized and milling (Tunstrom et al.
    2013; the module docstring)."""
    p, m = np.asarray(polarization, dtype=np.float64), np.asarray(milling, dtype=np.float64)
    known = np.isfinite(p) & np.isfinite(m)
    if not known.any():
        return {"swarming_fraction": math.nan, "polarized_fraction": math.nan, "milling_fraction": math.nan}
    p, m = p[known], m[known]
    return {"swarming_fraction": float(np.mean((p < low) & (m < low))),
            "polarized_fraction": float(np.mean((p > high) & (m < low))),
            "milling_fraction": float(np.mean((m > high) & (p < low)))}

