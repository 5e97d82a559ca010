"""Raw samples -> a flock on a regular record grid, with velocities: the one way tracks become records.

Measured tracks (:mod:`.tracks`) and simulated runs seen through an observation model
(:mod:`.observation`) both pass through :func:`resample`, so their statistics are measured alike.

``resample(raw, interval, max_gap=None, velocity_interval=None) -> ObservedFlock``:

* **size**: records x individuals is counted before anything is allocated and refused beyond
  :data:`MAX_RECORD_VALUES` (``check_size``: the figure and the smallest interval that fits);
* **grid**: t_k = t_0 + k h, k = 0 .. floor((t_last - t_0)/h), with h = ``interval``, t_last the
  flock's last sample time and t_0 its first sample's time on the samples' sampling clock (``clock``, a
  :class:`~observables.clock.Clock`; default :func:`~observables.clock.sampling_clock` of the samples):
  on a regular clock the first sample's grid time, else the first sample time plus the sampling phase
  (:func:`grid_phase`: the circular mean of the sample times modulo h when they cluster; 0 for samples
  denser than h), so a regular sampling with jittered time stamps gets records at its nominal times. A
  grid time within the clock's tolerance of a sample time (1e-6 h; plus their rounding for
  single-precision stamps) is that sample's time: for double-precision and jittered stamps the grid time
  becomes the sample's time exactly (regular data keep their own times and values, bit for bit); for
  single-precision stamps the grid keeps its own times, the better clock.
* **positions** at t_k, per individual: the sample at t_k (within the tolerance); else the linear
  interpolation between the samples just before and after t_k when they are at most ``max_gap`` apart
  (default 2.5 h: one missed sample of a regular track is bridged, also when the time stamps jitter by up
  to a quarter interval; two missed samples are not; ``max_gap`` < h is an error, since then even
  consecutive samples of jittered tracks would not be joined); else missing (nan).
* **velocities**: ``velocity_interval`` D = m h (m a whole number >= 1; default h, m = 1) differences
  positions over m intervals, v_k = (p_{k+a} - p_{k-b}) / (t_{k+a} - t_{k-b}) with a = ceil(m/2),
  b = floor(m/2): centred for even m, half an interval ahead for odd m. The first b and last a grid
  times only end differences and are not records. ``velocity_interval = "recorded"`` uses the samples'
  own velocities, resampled like the positions (every grid time is a record).
* an individual is **present** at a record when its position and velocity there are known.

Record times are seconds since the first grid time t_0 (``t_start`` keeps t_0 in the source's clock).
Position noise sd s on each coordinate gives velocity noise sd s sqrt(2) / D per coordinate, so a short
``velocity_interval`` on noisy positions lowers polarization and raises speed statistics
(docs/measured.md gives the numbers).
"""
from __future__ import annotations

import numpy as np

from .clock import SNAP, Clock, grid_phase, grid_start, sampling_clock  # noqa: F401 - grid_phase: part of this face
from .observed import ObservedFlock
from .track_names import RECORDED  # noqa: F401 - declared there (read without numpy), part of this module's face

MAX_RECORD_VALUES = 20_000_000   # records x individuals of one flock (positions and velocities: ~0.9 GiB)
MAX_GAP_INTERVALS = 2.5  # default max_gap, in sampling intervals


def check_interval(interval: float, what: str = "interval") -> float:
    if isinstance(interval, bool) or not (np.isfinite(interval) and interval > 0):
        raise ValueError(f"{what}: got {interval!r}; expected a number of seconds > 0")
    return float(interval)


def velocity_steps(velocity_interval, interval: float) -> int | None:
    """m = velocity_interval / interval (a whole number >= 1), or None for recorded velocities."""
    if velocity_interval is None:
        return 1
    if isinstance(velocity_interval, str):
        if velocity_interval != RECORDED:
            raise ValueError(f'velocity_interval: got {velocity_interval!r}; expected seconds or "recorded"')
        return None
    ratio = check_interval(velocity_interval, "velocity_interval") / interval
    m = int(round(ratio))
    if m < 1 or abs(ratio - m) > SNAP * max(1.0, ratio):
        raise ValueError(f"velocity_interval: got {velocity_interval!r}; must be a whole multiple of the sampling "
                         f"interval {interval!r} s")
    return m


def _grid_start_count(times: np.ndarray, interval: float, clock: Clock) -> tuple[float, int]:
    start = grid_start(clock, times, interval)
    slack = float(clock.tolerance(times[-1:], interval)[0]) / interval
    return start, max(int(np.floor((times[-1] - start) / interval + slack)) + 1, 1)


def _clock(t: np.ndarray, interval: float, clock: Clock | None) -> Clock:
    return clock if clock is not None else sampling_clock(t, fallback=interval)


def check_size(t: np.ndarray, individuals: int, interval: float, clock: Clock | None = None) -> int:
    """The number of grid times over the sample times ``t``, counted before anything is allocated;
    ValueError when records x individuals exceeds :data:`MAX_RECORD_VALUES` (the figure and what to
    change in the message)."""
    times = np.unique(t)
    span = float(times[-1] - times[0]) if len(times) else 0.0
    estimate = span / interval + 2   # the count of _grid_start_count, without its float overflow
    if estimate * max(individuals, 1) > MAX_RECORD_VALUES:
        raise ValueError(f"interval: {interval:g} s over {span:g} s of tracks gives {estimate:.3g} records x "
                         f"{individuals} individuals = {estimate * max(individuals, 1):.3g} positions, over the limit "
                         f"of {MAX_RECORD_VALUES:,} (about {MAX_RECORD_VALUES * 48 / 2**30:.1f} GiB); choose a "
                         f"larger --interval (at least {span * max(individuals, 1) / MAX_RECORD_VALUES:.3g} s) or "
                         "measure a shorter stretch")
    return _grid_start_count(times, interval, _clock(times, interval, clock))[1] if len(times) else 0


def record_grid(t: np.ndarray, interval: float, clock: Clock | None = None) -> np.ndarray:
    """The grid over the sample times ``t``, in phase with them and snapped to them (module docstring);
    ``clock`` the samples' :class:`~observables.clock.Clock` (default: inferred from ``t``)."""
    times = np.unique(t)
    clock = _clock(times, interval, clock)
    start, count = _grid_start_count(times, interval, clock)
    grid = start + np.arange(max(count, 1)) * interval
    if clock.precision == "single":   # the stamps are rounded: the grid's own times are the better clock
        return grid
    j = np.clip(np.searchsorted(times, grid), 1, len(times) - 1) if len(times) > 1 else np.zeros(len(grid), int)
    for candidate in (times[j - 1] if len(times) > 1 else times[j], times[j]):
        close = np.abs(candidate - grid) <= SNAP * interval
        grid = np.where(close, candidate, grid)
    return grid


def at_times(t: np.ndarray, values: np.ndarray, grid: np.ndarray, max_gap: float, interval: float,
             tol: np.ndarray | None = None) -> np.ndarray:
    """(R, 3) values of one individual at the grid times: exact samples (within ``tol``, per sample; default
    SNAP x interval), bridged gaps, else nan."""
    out = np.full((len(grid), values.shape[1]), np.nan)
    if len(t) == 0:
        return out
    tol = np.full(len(t), SNAP * interval) if tol is None else np.asarray(tol)
    j = np.searchsorted(t, grid)                               # first sample at or after the grid time
    after = j < len(t)
    before = j > 0
    j_after, j_before = np.minimum(j, len(t) - 1), np.maximum(j - 1, 0)
    exact_after = after & (np.abs(t[j_after] - grid) <= tol[j_after])
    exact_before = before & ~exact_after & (np.abs(grid - t[j_before]) <= tol[j_before])
    span = t[j_after] - t[j_before]
    between = before & after & ~exact_after & ~exact_before & (span <= max_gap * (1 + 1e-9))
    out[exact_after] = values[j_after[exact_after]]
    out[exact_before] = values[j_before[exact_before]]
    if between.any():
        w = ((grid - t[j_before]) / np.where(between, span, 1.0))[between, None]
        lo, hi = values[j_before[between]], values[j_after[between]]
        out[between] = lo + w * (hi - lo)
    return out


def resample(raw, interval: float, max_gap: float | None = None, velocity_interval=None,
             clock: Clock | None = None) -> ObservedFlock:
    """The flock on its record grid (see the module docstring); ``clock`` the samples' sampling clock
    (:func:`~observables.clock.sampling_clock`; default: inferred from the sample times)."""
    interval = check_interval(interval)
    max_gap = MAX_GAP_INTERVALS * interval if max_gap is None else float(max_gap)
    if not max_gap >= interval:
        raise ValueError(f"max_gap: got {max_gap!r}; must be at least the sampling interval {interval!r} s (consecutive "
                         f"samples are that far apart; default {MAX_GAP_INTERVALS:g} intervals)")
    m = velocity_steps(velocity_interval, interval)
    if m is None and raw.vel is None:
        raise ValueError(f'flock {raw.name!r}: velocity_interval = "recorded" but the tracks have no velocities')
    clock = sampling_clock(raw.t, raw.ind, fallback=interval) if clock is None else clock
    check_size(raw.t, len(raw.ids), interval, clock)
    grid = record_grid(raw.t, interval, clock)
    tol = clock.tolerance(raw.t, interval)
    n = len(raw.ids)
    pos = np.full((len(grid), n, 3), np.nan)
    vel = np.full((len(grid), n, 3), np.nan)
    bounds = raw.bounds()
    for i in range(n):
        mine = slice(bounds[i], bounds[i + 1])
        pos[:, i] = at_times(raw.t[mine], raw.pos[mine], grid, max_gap, interval, tol[mine])
        if m is None:
            vel[:, i] = at_times(raw.t[mine], raw.vel[mine], grid, max_gap, interval, tol[mine])
    keep = slice(None)
    if m is not None:
        ahead, behind = (m + 1) // 2, m // 2
        last = len(grid) - 1 - ahead
        if last < behind:
            raise ValueError(f"flock {raw.name!r}: {len(grid)} grid times are too few for a velocity interval of "
                             f"{m} sampling intervals")
        span = grid[behind + ahead:] - grid[:len(grid) - behind - ahead]
        vel[behind:last + 1] = (pos[behind + ahead:] - pos[:len(grid) - behind - ahead]) / span[:, None, None]
        keep = slice(behind, last + 1)
    pos, vel = pos[keep], vel[keep]
    present = np.isfinite(pos).all(axis=2) & np.isfinite(vel).all(axis=2)
    return ObservedFlock(name=raw.name, ids=raw.ids, times=grid[keep] - grid[0], pos=pos, vel=vel,
                         present=present, dims=raw.dims, pattern=raw.pattern, t_start=float(grid[0]),
                         interval=interval)
