"""Per-individual features of a run or a measured flock, and a fixed-length window of its per-record
series: the raw inputs a learned summary (:mod:`analysis.calibration.learned`) is computed from, defined
once for simulated runs and measured tracks alike.

Input: observations with ``times`` (R,), ``pos`` and ``vel`` (R, N, 3) and, for an observed flock
(:class:`~observables.observed.ObservedFlock`: measured tracks, or a run seen through an observation model),
``present`` (R, N) (without it everyone is present at every record). Only the window's records count
(``times >= warmup``), as for the row's means. Individual i at record r is *present* when its position and
velocity are known there; it is *moving* when also |v_i| > 0 (its heading h_i = v_i / |v_i|).

``individual_frames(pos, vel, present, box=None) -> (nn_distance (R, N), nn_ahead (R, N))``: at each record
the distance of i's nearest present neighbour (minimum image in a periodic box of side ``box``), and
whether it sits ahead of i's heading (1 ahead, d.h > 0; 0.5 abeam, d.h = 0; 0 behind), the terms of the
flock series ``nn_distance`` and ``nn_ahead_fraction`` (:mod:`observables.metrics`): their record means over
the individuals with a term are those series (tested). nan where i is not present, has no present
neighbour at a distance > 0, or (``nn_ahead``) is not moving.

``individual_features(obs, warmup, interval, box=None) -> (N, F)``: for every individual its window means
(nan when it has no term), columns :data:`INDIVIDUAL_FEATURES`:

* ``speed`` (length/s): mean |v_i| over its present records (:func:`observables.motion.individual_means`);
* ``turn_rate`` (degrees/s): mean turning rate between consecutive present records
  (:func:`observables.motion.turning_rate_grid`, the terms of ``turn_rate_mean``);
* ``nn_distance`` (length): mean nearest-neighbour distance (:func:`individual_frames`);
* ``nn_ahead`` (1): share of its records with its nearest neighbour ahead (:func:`individual_frames`).

``window_series(series, names, times, warmup, length) -> (length, S)``: the run's per-record series ``names``
(of :func:`observables.summary.measure_run`) over the window, cut into ``length`` consecutive bins of as
equal a number of records as can be (``numpy.array_split``) and averaged in each (records where a series
is nan left out; a bin where it has no value is nan). A window of fewer than ``length`` records raises
ValueError.
"""
from __future__ import annotations

import numpy as np

from .motion import individual_means, turning_rate_grid

INDIVIDUAL_FEATURES = ("speed", "turn_rate", "nn_distance", "nn_ahead")


def _present(obs) -> np.ndarray:
    present = getattr(obs, "present", None)
    if present is not None:
        return np.asarray(present, dtype=bool)
    known = np.isfinite(obs.pos).all(axis=-1) & np.isfinite(obs.vel).all(axis=-1)
    return known


def individual_frames(pos, vel, present, box: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(nn_distance, nn_ahead), each (R, N): see the module docstring."""
    pos, vel = np.asarray(pos, dtype=np.float64), np.asarray(vel, dtype=np.float64)
    present = np.asarray(present, dtype=bool)
    records, n = present.shape
    distance = np.full((records, n), np.nan)
    ahead = np.full((records, n), np.nan)
    for r in range(records):
        who = np.flatnonzero(present[r])
        if len(who) < 2:
            continue
        p = pos[r, who]
        offset = p[None, :, :] - p[:, None, :]                     # offset[a, b] = p_b - p_a
        if box:
            offset = offset - box * np.round(offset / box)
        squared = np.einsum("abc,abc->ab", offset, offset)
        squared[~(squared > 0.0)] = np.inf                         # itself, and anyone at the same spot
        nearest = np.argmin(squared, axis=1)                       # ties: the lower index, as the kernels
        best = squared[np.arange(len(who)), nearest]
        has = np.isfinite(best)
        distance[r, who[has]] = np.sqrt(best[has])
        v = vel[r, who]
        speed = np.linalg.norm(v, axis=1)
        moving = has & (speed > 0.0)
        d = offset[np.arange(len(who)), nearest]
        along = np.einsum("ac,ac->a", d, v)
        share = np.where(along > 0.0, 1.0, np.where(along == 0.0, 0.5, 0.0))
        ahead[r, who[moving]] = share[moving]
    return distance, ahead


def _column_means(values: np.ndarray) -> np.ndarray:
    """(N,) the mean of each column's finite values (nan when none)."""
    known = np.isfinite(values)
    count = known.sum(axis=0)
    total = np.where(known, values, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def individual_features(obs, warmup: float, interval: float, box: float | None = None) -> np.ndarray:
    """(N, F): every individual's window means of :data:`INDIVIDUAL_FEATURES` (module docstring)."""
    window = np.asarray(obs.times, dtype=np.float64) >= warmup
    present = _present(obs)[window]
    pos = np.where(present[..., None], np.asarray(obs.pos, dtype=np.float64)[window], np.nan)
    vel = np.where(present[..., None], np.asarray(obs.vel, dtype=np.float64)[window], np.nan)
    speed = np.linalg.norm(vel, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        heading = np.where((speed > 0)[..., None], vel / speed[..., None], np.nan)
    turns = turning_rate_grid(heading, interval) if len(vel) > 1 else np.full((1, vel.shape[1]), np.nan)
    distance, ahead = individual_frames(pos, vel, present, box)
    return np.column_stack([individual_means(speed), _column_means(turns), _column_means(distance),
                            _column_means(ahead)])


def window_series(series: dict, names, times, warmup: float, length: int) -> np.ndarray:
    """(length, S): the window's series ``names`` averaged in ``length`` bins (module docstring)."""
    window = np.asarray(times, dtype=np.float64) >= warmup
    count = int(window.sum())
    if count < length:
        raise ValueError(f"the window holds {count} records, fewer than the {length} bins of the learned summary's "
                         "series (series_length): record longer, sample more often, or choose fewer bins")
    out = np.full((length, len(names)), np.nan)
    for j, name in enumerate(names):
        values = np.asarray(series[name], dtype=np.float64)[window]
        for b, part in enumerate(np.array_split(values, length)):
            known = part[np.isfinite(part)]
            if known.size:
                out[b, j] = known.mean()
    return out
