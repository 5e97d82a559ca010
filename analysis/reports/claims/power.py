"""How much can a claim's test see? Power by simulation from the observed spread.

``analyse(test, data, alpha, target, effect, simulations, max_replicates, rng) -> Power`` answers, for
one leaf test (trend, compare, sign) and its data (:class:`.kinds.LeafData`):

* ``power``: the chance that the test, at significance level ``alpha``, finds an effect of size
  ``effect`` (the smallest effect of interest, in the metric's units) in the claimed direction with the
  replicates it has now;
* ``mde``: the minimum detectable effect now, the smallest effect found with probability ``target``;
* ``replicates``: when ``power`` is below ``target``, the replicates per design point that would find
  ``effect`` with probability ``target`` (``None`` when the power is enough now, or when more than
  ``max_replicates`` would be needed: ``power >= target`` tells which).

The simulation keeps the observed spread and plants a location shift. The data's values are split
into *groups* (a trend's factor levels, a comparison's two groups, a sign test's one sample), design
*points* and *cells* (the levels of the other factors, :class:`.kinds.LeafData`); for each value

    y = G[group] + C[cell] + I[point] + e

with G the group means, C the cell effects (the mean of point mean - group mean over the cell's
points; 0 when no cell holds two points), I the rest of a point's mean (the factor x cell interaction)
and e the replicate spread (each value minus its point's mean, scaled by sqrt(n_p / (n_p - 1)) to
undo the fit). C and I are shrunk so that their variances lose the replicate noise their estimates
carry (sigma^2 / runs per cell, sigma^2 / runs per point). A simulated data set keeps C (the design's
other factors, the same at every level, so without an effect every group has the same distribution:
the null of a rank test), gives every point an I drawn from all points' and every run an e drawn from
the replicate spread, both with replacement: more replicates shrink e only. With one run per point I
and e cannot be told apart: every run draws from y - G - C (model "pooled", where more replicates look
more useful than they are). The groups' means are replaced by the planted ones: a
trend's m + s effect (x - mean x) / (range of x), a comparison's m -+ effect / 2 (lower / higher), a
sign test's value + s effect with its values first centred on the test's location (mean, median or
pseudo-median, :func:`.kinds.location`; m the observed mean, s the claimed direction). A metric with
only the values 0 and 1 (e.g. ``fragmented``) is drawn as Bernoulli(planted + C + I, clipped to [0, 1])
instead. Each simulated data set is tested exactly as the data were (:func:`.kinds.run_rows`); it counts
when p < alpha and the direction is the claimed one. The same draws serve every effect size (common
random numbers), so the power curve is monotone up to the clipping of probabilities. ``spread`` is the
sd of the simulated values around their planted means. A ``zero`` sign test is a check and has no power.

The replicates needed are searched from the normal approximation's guess (:func:`_predicted`) by doubling
steps, then bisection (:func:`_fewest`); r replicates draw their data sets from their own stream ``[base,
r]``, so whether r is enough is a function of r, not of the search's order.

The simulated data sets are tested in batches of at most :data:`CHUNK` values; a power evaluation's
batches run on up to :data:`THREADS` threads (numpy sorts without holding the GIL) and only their
hit counts are summed, so the answer is the same on one thread or two.
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from .kinds import LeafData, location, run_rows

CHUNK = 4_000_000          # simulated values per batch (memory bound)
THREADS = min(2, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
BISECTION_STEPS = 8


@dataclass
class Power:
    effect: float
    effect_source: str       # "declared" or "half the spread"
    power: float
    mde: float               # inf when not reached within the search
    replicates: int | None   # per design point for target power at ``effect`` (searched only when the
                             # power now is below target); None: enough now, or more than max_replicates
    replicates_now: float    # median replicates per design point now
    points: int
    spread: float
    model: str               # "within-point" | "pooled" (+ " bernoulli")
    alpha: float
    target: float


@dataclass
class _Model:
    x_point: np.ndarray      # trend: x per point; compare: 1.0 higher / 0.0 lower; sign: zeros
    cell: np.ndarray         # C per point (fixed)
    interaction: np.ndarray  # I per point (resampled, weighted by runs)
    pool: np.ndarray         # e (resampled)
    counts: np.ndarray       # runs per point now
    base: float              # observed mean (one sample: mean minus location)
    binary: bool
    model: str


def _weighted_means(codes: np.ndarray, values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per code, the weighted mean of values (codes 0..k-1)."""
    total = np.bincount(codes, weights=values * weights)
    return total / np.maximum(np.bincount(codes, weights=weights), 1e-300)


def _shrunk(effects: np.ndarray, weights: np.ndarray, noise: float) -> np.ndarray:
    """Effects scaled so that their weighted variance loses ``noise`` (the replicate noise they carry)."""
    spread = np.average(effects ** 2, weights=weights)
    return effects * np.sqrt(max(spread - noise, 0.0) / spread) if spread > 0 else effects


def _model(test, data: LeafData) -> _Model:
    y = data.y
    one_sample = data.x is None
    binary = bool(np.isin(y, (0.0, 1.0)).all())
    if one_sample:   # centred on the test's location, so that no effect is the test's null
        y = y - location(y, test.method)
    codes, point = np.unique(data.point, return_inverse=True)
    k = codes.size
    counts = np.bincount(point, minlength=k)
    point_mean = np.bincount(point, weights=y, minlength=k) / np.maximum(counts, 1)
    x_point = np.zeros(k)
    if not one_sample:
        x_point[point] = data.x
    group = np.unique(x_point, return_inverse=True)[1]
    group_mean = _weighted_means(group, point_mean, counts)[group]
    cell_of_value = data.cell if data.cell is not None else data.point
    cell_point = np.zeros(k, dtype=int)
    cell_point[point] = np.unique(cell_of_value, return_inverse=True)[1]
    coarse = np.bincount(cell_point).max() >= 2          # some cell holds several points: C is estimable
    cell = _weighted_means(cell_point, point_mean - group_mean, counts)[cell_point] if coarse else np.zeros(k)
    if np.median(counts) >= 2:
        keep = counts[point] >= 2
        scale = np.sqrt(counts / np.maximum(counts - 1, 1))
        pool = ((y - point_mean[point]) * scale[point])[keep]
        sigma2 = float(np.var(pool)) if pool.size else 0.0
        runs_per_cell = np.bincount(cell_point, weights=counts)[cell_point]
        cell = _shrunk(cell, counts, sigma2 / np.average(runs_per_cell, weights=counts)) if coarse else cell
        interaction = _shrunk(point_mean - group_mean - cell, counts, sigma2 / np.average(counts, weights=counts))
        model = "within-point"
    else:
        interaction = np.zeros(k)
        pool = y - group_mean[point] - cell[point]
        fitted = np.unique(group).size + (np.unique(cell_point).size - 1 if coarse else 0)
        pool = pool * np.sqrt(y.size / max(y.size - fitted, 1))
        model = "pooled"
    return _Model(x_point, cell, interaction, pool, counts, float(y.mean()), binary,
                  model + (" bernoulli" if binary else ""))


def _planted(test, m: _Model, effect: float) -> np.ndarray:
    """The planted mean per design point (module docstring)."""
    s = test.claimed_sign
    if test.kind == "trend":
        span = m.x_point.max() - m.x_point.min()
        centred = (m.x_point - np.average(m.x_point, weights=m.counts)) / span
        return m.base + s * effect * centred
    if test.kind == "compare" and not test.paired:
        return m.base + effect * (m.x_point - 0.5)
    reference = 0.0 if test.kind == "compare" else test.value
    return np.full(m.x_point.size, reference + s * effect + m.base)


class _Simulation:
    """Draws for one layout (runs per point), reused for every effect size: per simulated data set an
    interaction per design point and a residual per run."""

    def __init__(self, test, m: _Model, counts: np.ndarray, simulations: int, rng: np.random.Generator):
        self.test, self.m = test, m
        self.point = np.repeat(np.arange(counts.size), counts)
        self.data = LeafData(np.zeros(self.point.size), None if test.kind == "sign" or test.paired
                             else m.x_point[self.point], self.point, None, 0)
        n = self.point.size
        drawn = rng.choice(m.interaction, size=(simulations, counts.size), p=m.counts / m.counts.sum())
        self.offsets = drawn[:, self.point] + m.cell[self.point]
        self.noise = (rng.random((simulations, n)) if m.binary
                      else rng.choice(m.pool, size=(simulations, n), replace=True) if m.pool.size
                      else np.zeros((simulations, n)))

    def power(self, effect: float, alpha: float) -> float:
        planted = _planted(self.test, self.m, effect)[self.point]
        want = self.test.claimed_sign if not (self.test.kind == "compare" and not self.test.paired) else 1
        rows = max(1, CHUNK // max(self.point.size, 1))

        def hits(start: int) -> int:
            noise, mean = self.noise[start:start + rows], planted + self.offsets[start:start + rows]
            Y = (noise < np.clip(mean, 0.0, 1.0)).astype(float) if self.m.binary else mean + noise
            _, p, sign = run_rows(self.test, self.data, Y)
            return int(((p < alpha) & (sign == want)).sum())

        starts = range(0, self.noise.shape[0], rows)
        if len(starts) == 1 or THREADS == 1:
            return sum(map(hits, starts)) / self.noise.shape[0]
        with ThreadPoolExecutor(THREADS) as pool:   # numpy sorts without the GIL: the batches overlap
            return sum(pool.map(hits, starts)) / self.noise.shape[0]

    def spread(self) -> float:
        values = self.offsets + (0.0 if self.m.binary else self.noise)
        return float(values.std())


def _smallest_effect(sim: _Simulation, alpha: float, target: float, start: float) -> float:
    """The smallest effect with power >= target: inf when even 2^20 x ``start`` falls short; else a
    bisection of the exponent (to within a factor 2), then of the effect."""
    if sim.power(start * 2.0 ** 20, alpha) < target:
        return math.inf
    low, high = -10, 20                      # exponents of 2 around start
    while high - low > 1:
        middle = (low + high) // 2
        if sim.power(start * 2.0 ** middle, alpha) >= target:
            high = middle
        else:
            low = middle
    low_effect, high_effect = start * 2.0 ** low, start * 2.0 ** high
    for _ in range(BISECTION_STEPS):
        middle = 0.5 * (low_effect + high_effect)
        if sim.power(middle, alpha) >= target:
            high_effect = middle
        else:
            low_effect = middle
    return high_effect


def _replicates_needed(test, m: _Model, effect, alpha, target, simulations, cap, rng, power_now: float) -> int | None:
    """The fewest replicates per design point (above the median now, at most ``cap``) with power >=
    target at ``effect``; None when even ``cap`` falls short. Each layout's simulated data sets come from
    its own stream (``[base, r]``), so "enough at r" is a function of r alone and the answer does not
    depend on the order the search tries them in (:func:`_fewest`)."""
    base = int(rng.integers(2 ** 63))

    def enough(r: int) -> bool:
        counts = np.full(m.counts.size, r)
        sim = _Simulation(test, m, counts, simulations, np.random.default_rng([base, r]))
        return sim.power(effect, alpha) >= target

    low = int(np.median(m.counts))           # not enough now (the caller only asks then)
    if cap <= low:
        return None
    return _fewest(enough, low, cap, _predicted(low, power_now, alpha, target))


def _predicted(now: int, power_now: float, alpha: float, target: float) -> int:
    """The replicates the normal approximation asks for: power = Phi(delta sqrt(n) - z_alpha), so n grows
    with the square of (z_target + z_alpha) / (z_now + z_alpha); twice the replicates now when the power
    now is too low to scale from. Only the search's first guess: :func:`_fewest` checks it."""
    normal = NormalDist()
    z_alpha = normal.inv_cdf(1.0 - min(max(alpha, 1e-12), 0.5))
    z_now = normal.inv_cdf(min(max(power_now, 1e-9), 1.0 - 1e-9)) + z_alpha
    if z_now <= 0.25:
        return 2 * max(now, 1)
    return int(math.ceil(max(now, 1) * ((normal.inv_cdf(target) + z_alpha) / z_now) ** 2))


def _fewest(enough, low: int, cap: int, guess: int) -> int | None:
    """The smallest r in (low, cap] with ``enough(r)``, for a predicate false at ``low`` that turns true
    once and stays true (None when false at ``cap``): from ``guess``, steps doubling down (or up) until
    the answer is bracketed, then bisection. A good guess costs a few calls near it, not calls at ``cap``."""
    guess = min(max(guess, low + 1), cap)
    if enough(guess):
        high, step = guess, 1
        while high - low > 1:
            probe = max(high - step, low + 1)
            if not enough(probe):
                low = probe
                break
            high, step = probe, 2 * step
    else:
        low, step = guess, max(1, guess // 2)
        while True:
            if low >= cap:
                return None
            probe = min(low + step, cap)
            if enough(probe):
                high = probe
                break
            low, step = probe, 2 * step
    while high - low > 1:
        middle = (low + high) // 2
        if enough(middle):
            high = middle
        else:
            low = middle
    return high


def analyse(test, data: LeafData, alpha: float, target: float, effect: float | None, simulations: int,
            max_replicates: int, rng: np.random.Generator) -> Power | None:
    """The power analysis of one leaf test (module docstring); None for a check or too few values."""
    if (test.kind == "sign" and test.direction == "zero") or data.n < 3:
        return None
    m = _model(test, data)
    now = _Simulation(test, m, m.counts, simulations, rng)
    share = float(data.y.mean())
    spread = float(np.sqrt(share * (1.0 - share))) if m.binary else now.spread()
    source = "declared"
    if effect is None:
        effect, source = 0.5 * spread, "half the spread"
    if not effect > 0:
        return None
    power = now.power(effect, alpha)
    mde = _smallest_effect(now, alpha, target, 0.25 * (spread or effect))
    replicates = None
    if power < target:  # how many would it take? (enough now: no search)
        replicates = _replicates_needed(test, m, effect, alpha, target, simulations, max_replicates, rng, power)
    return Power(effect, source, power, mde, replicates, float(np.median(m.counts)), int(m.counts.size), spread,
                 m.model, alpha, target)
