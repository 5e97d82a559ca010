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

The simulation keeps what was observed and plants the effect. Data are grouped by what the test
compares (a trend's factor levels, a comparison's two groups, a sign test's one sample) and by design
point. With replicates (at least two at most points) a point's *offset* (its mean minus its group's)
is kept fixed, and the *replicate spread* (each value minus its point's mean, scaled by
sqrt(n_p / (n_p - 1)) to undo the fit) is resampled with replacement; with one run per point the two
cannot be told apart, so all the spread around the group means is resampled (model "pooled"). A
simulated value is ``planted mean + offset + resampled residual`` with the planted mean of a trend
m + s effect (x - mean x) / (range of x), of a comparison m -+ effect / 2 for the lower / higher group,
of a sign test value + s effect (m the observed mean, s the claimed direction). A metric with only the
values 0 and 1 (e.g. ``fragmented``) is drawn as Bernoulli(planted mean + offset, clipped to [0, 1])
instead. Each simulated data set is tested exactly as the data were (:func:`.kinds.run_rows`); it counts
when p < alpha and the direction is the claimed one. The same draws serve every effect size
(common random numbers), so the power curve is monotone up to the clipping of probabilities.
``spread`` is the sd the simulation draws from (residuals, plus offsets). A ``zero`` sign test is a
check and has no power.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .kinds import LeafData, run_rows

CHUNK = 4_000_000          # simulated values per batch (memory bound)
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
    group: np.ndarray        # group code per design point (trend level index / higher flag / 0)
    x_point: np.ndarray      # trend: x per point; compare: 1.0 higher / 0.0 lower; sign: zeros
    offset: np.ndarray       # per point
    pool: np.ndarray         # residuals to resample
    counts: np.ndarray       # runs per point now
    base: float              # observed mean
    binary: bool
    model: str


def _model(test, data: LeafData) -> _Model:
    y = data.y
    codes, point = np.unique(data.point, return_inverse=True)
    k = codes.size
    counts = np.bincount(point, minlength=k)
    point_mean = np.bincount(point, weights=y, minlength=k) / np.maximum(counts, 1)
    if data.x is not None:
        x_point = np.zeros(k)
        x_point[point] = data.x
    else:
        x_point = np.zeros(k)
    group = np.unique(x_point, return_inverse=True)[1]
    group_mean = np.array([point_mean[group == g] @ counts[group == g] / counts[group == g].sum()
                           for g in range(group.max() + 1)])[group]
    binary = bool(np.isin(y, (0.0, 1.0)).all())
    replicated = np.median(counts) >= 2
    if replicated:
        offset = point_mean - group_mean
        keep = counts[point] >= 2
        scale = np.sqrt(counts / np.maximum(counts - 1, 1))
        pool = ((y - point_mean[point]) * scale[point])[keep]
        model = "within-point"
    else:
        offset = np.zeros(k)
        group_counts = np.bincount(group[point], minlength=group.max() + 1)
        scale = np.sqrt(group_counts / np.maximum(group_counts - 1, 1))[group[point]]
        pool = (y - group_mean[point]) * scale
        model = "pooled"
    return _Model(group, x_point, offset, pool, counts, float(y.mean()), binary,
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
    return np.full(m.x_point.size, reference + s * effect)


class _Simulation:
    """Draws for one layout (runs per point), reused for every effect size."""

    def __init__(self, test, m: _Model, counts: np.ndarray, simulations: int, rng: np.random.Generator):
        self.test, self.m = test, m
        self.point = np.repeat(np.arange(counts.size), counts)
        self.data = LeafData(np.zeros(self.point.size), None if test.kind == "sign" or test.paired
                             else m.x_point[self.point], self.point, None, 0)
        n = self.point.size
        self.noise = (rng.random((simulations, n)) if m.binary
                      else rng.choice(m.pool, size=(simulations, n), replace=True) if m.pool.size
                      else np.zeros((simulations, n)))

    def power(self, effect: float, alpha: float) -> float:
        mean = (_planted(self.test, self.m, effect) + self.m.offset)[self.point]
        want = self.test.claimed_sign if not (self.test.kind == "compare" and not self.test.paired) else 1
        hits = 0
        rows = max(1, CHUNK // max(self.point.size, 1))
        for start in range(0, self.noise.shape[0], rows):
            noise = self.noise[start:start + rows]
            Y = (noise < np.clip(mean, 0.0, 1.0)).astype(float) if self.m.binary else mean + noise
            _, p, sign = run_rows(self.test, self.data, Y)
            hits += int(((p < alpha) & (sign == want)).sum())
        return hits / self.noise.shape[0]


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


def _replicates_needed(test, m: _Model, effect, alpha, target, simulations, cap, rng) -> int | None:
    """The fewest replicates per design point (above the median now, at most ``cap``) with power >=
    target at ``effect``; None when even ``cap`` falls short."""
    def enough(r: int) -> bool:
        counts = np.full(m.counts.size, r)
        return _Simulation(test, m, counts, simulations, rng).power(effect, alpha) >= target

    low = int(np.median(m.counts))           # not enough now (the caller only asks then)
    if cap <= low or not enough(cap):
        return None
    high = cap
    while high - low > 1:
        middle = int(round(math.sqrt(max(low, 1) * high))) if high > 2 * max(low, 1) else (low + high) // 2
        middle = min(max(middle, low + 1), high - 1)
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
    spread = float(np.sqrt(np.var(m.pool) + np.average(m.offset ** 2, weights=m.counts))) if m.pool.size else 0.0
    if m.binary:
        spread = float(np.sqrt(m.base * (1 - m.base)))
    source = "declared"
    if effect is None:
        effect, source = 0.5 * spread, "half the spread"
    if not effect > 0:
        return None
    now = _Simulation(test, m, m.counts, simulations, rng)
    power = now.power(effect, alpha)
    mde = _smallest_effect(now, alpha, target, 0.25 * (spread or effect))
    replicates = None
    if power < target:  # how many would it take? (enough now: no search)
        replicates = _replicates_needed(test, m, effect, alpha, target, simulations, max_replicates, rng)
    return Power(effect, source, power, mde, replicates, float(np.median(m.counts)), int(m.counts.size), spread,
                 m.model, alpha, target)
