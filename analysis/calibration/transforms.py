"""Statistics transformed so that they carry information at their bounds: what the npe learner and BSL's
Gaussian (and the optimiser's objective) see.

A statistic packed against a bound (a flock's polarization above 0.99, a fraction near 0) is nearly
constant on a linear scale: standardised linearly, the values that tell a heading noise of 0.1 from one
of 0.3 differ by a sliver of one standard deviation of the training set, and a Gaussian of them is skewed
against the bound. A transform that opens the bound up (log(1 - polarization) behaves like the logit
below) spreads them out again.

Contract
--------
``RANGES``: {statistic: (low, high, atom)}, each statistic's declared range (docs/metrics.md) and whether
it often sits exactly at a bound (``atom``: counts and shares of boids that are 0 in many runs). The
automatic transform (``auto``) follows from it:

* ``logit`` for a continuous statistic with two finite bounds: z = log((x - low + e) / (high - x + e)),
  e = :data:`LOGIT_EPS` x (high - low) (polarization 0.999 and 0.9999 stay apart: -6.8 and -8.5);
* ``log`` for a continuous statistic bounded below by low >= 0 only (a positive scale or a count >= 1):
  z = log(x + :data:`LOG_EPS`);
* ``none`` (z = x) for the rest: no declared range, or an ``atom`` (an exact bound value in many runs
  would become a second cluster far out).

Before a transform a value is clipped into the declared range (measurement noise added to a polarization
of 0.995 can exceed 1: the instrument saturates), so every finite value has a finite image.

``transforms_from(given, stats, columns) -> Transforms``: the ``[targets] transform`` key: absent or
``"auto"`` (the automatic transform of every statistic), ``"none"`` (the linear scale of flocksweep up to
2026-12: results of that time are reproduced with it), or a table ``{ polarization = "logit",
nn_distance = "none", ... }`` overriding some statistics (the others ``auto``). A
:class:`~simcore.schema.ConfigError` names ``targets.transform[.<stat>]`` for an unknown statistic or
transform, and for ``logit`` / ``log`` on a statistic whose range does not allow it.

:class:`Transforms`: ``apply(x (n, k), clip=True) -> (n, k)``; ``wrap(fn)`` (a simulator ``theta, * ->
(n, k)`` whose rows come out transformed); ``record() -> {column: {"transform", "range"}}`` (what
``convergence.json`` and the estimator's identity record; an unbounded end is null) and
``Transforms.from_record(record, columns)`` (the same transforms rebuilt from it); ``describe()`` (one line,
in the chain file); ``names``; ``identity`` (True when every transform is ``none``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flocksweep.simcore.schema import ConfigError, suggest

LOGIT_EPS = 1e-4
LOG_EPS = 1e-6
NAMES = ("auto", "none", "log", "logit")
INF = math.inf

RANGES = {
    # per-record series (their window mean or final record), docs/metrics.md
    "polarization": (0.0, 1.0, False), "polarization_largest": (0.0, 1.0, False), "milling": (0.0, 1.0, False),
    "n_groups": (1.0, INF, False), "cohesion": (0.0, 1.0, False), "stray_fraction": (0.0, 1.0, True),
    "nn_distance": (0.0, INF, False), "gyration_radius": (0.0, INF, False), "elongation": (1.0, INF, False),
    "aspect_heading": (0.0, INF, False), "speed_mean": (0.0, INF, False), "speed_cv": (0.0, INF, False),
    "visible_mean": (0.0, INF, True), "visible_sd": (0.0, INF, True), "binocular_share": (0.0, 1.0, False),
    "segregation": (-1.0, 1.0, False), "elongation_heading": (0.0, INF, False), "overtake_rate": (0.0, INF, True),
    # per-run scalars
    "fragmented": (0.0, 1.0, True), "time_to_fragmentation": (0.0, INF, True),
    "trigger_rate": (0.0, INF, True), "leader_time_fraction": (0.0, 1.0, True), "leaders_mean": (0.0, INF, True),
    "follow_corr_lag0": (-1.0, 1.0, False), "follow_corr_max": (-1.0, 1.0, False), "follow_lag_max": (0.0, INF, True),
    "follow_corr_before": (-1.0, 1.0, False), "heading_change_deg": (0.0, 180.0, False),
    "escape_gain": (0.0, INF, False),
    "dcd_corr_mean": (-1.0, 1.0, False), "dcd_delay_mean": (-INF, INF, False), "dcd_edges": (0.0, INF, True),
    "dcd_leader_delay": (-INF, INF, False),
    # observables of collective motion: neighbours in the focal frame and the density profile (per record)
    "nn_ahead_fraction": (0.0, 1.0, False), "nn_bearing_deg": (0.0, 180.0, False), "nn_anisotropy": (0.0, 1.0, False),
    "knn_ahead_fraction": (0.0, 1.0, False), "knn_bearing_deg": (0.0, 180.0, False),
    "knn_anisotropy": (0.0, 1.0, False), "corr_length": (0.0, INF, False),
    "edge_spacing_ratio": (0.0, INF, False), "front_spacing_ratio": (0.0, INF, False),
    # ... and their per-run scalars: decay times, turning-rate and speed distributions, state fractions
    "heading_autocorr_time": (0.0, INF, False), "speed_autocorr_time": (0.0, INF, False),
    "turn_rate_mean": (0.0, INF, False), "turn_rate_q10": (0.0, INF, True), "turn_rate_q50": (0.0, INF, False),
    "turn_rate_q90": (0.0, INF, False), "speed_q10": (0.0, INF, False), "speed_q50": (0.0, INF, False),
    "speed_q90": (0.0, INF, False), "speed_cv_pooled": (0.0, INF, False),
    "swarming_fraction": (0.0, 1.0, True), "polarized_fraction": (0.0, 1.0, True), "milling_fraction": (0.0, 1.0, True),
    # the tank's walls (a distance is negative outside the tank: no bound)
    "wall_distance_mean": (-INF, INF, False), "wall_distance_q10": (-INF, INF, False),
    "wall_distance_q50": (-INF, INF, False), "wall_facing_near": (0.0, 1.0, False),
}


def automatic(stat: str) -> str:
    """The automatic transform of ``stat`` (module docstring)."""
    low, high, atom = RANGES.get(stat, (-INF, INF, False))
    if atom:
        return "none"
    if math.isfinite(low) and math.isfinite(high):
        return "logit"
    if math.isfinite(low) and low >= 0:
        return "log"
    return "none"


def _allowed(stat: str, name: str, where: str) -> None:
    low, high, _ = RANGES.get(stat, (-INF, INF, False))
    if name == "logit" and not (math.isfinite(low) and math.isfinite(high)):
        raise ConfigError(where, f"logit needs a statistic with two finite bounds; {stat} has the range "
                                 f"[{low:g}, {high:g}]: use log or none")
    if name == "log" and not (math.isfinite(low) and low >= 0):
        raise ConfigError(where, f"log needs a statistic bounded below by 0 or more; {stat} has the range "
                                 f"[{low:g}, {high:g}]: use none")


@dataclass(frozen=True, eq=False)
class Transforms:
    """The transform of every target column (module docstring)."""

    stats: tuple[str, ...]
    columns: tuple[str, ...]
    names: tuple[str, ...]
    ranges: tuple | None = None       # (low, high) per column; None: the declared RANGES of the stats

    @classmethod
    def from_record(cls, record: dict, columns) -> "Transforms":
        """The transforms a :meth:`record` wrote (an estimator's identity), for ``columns`` in that order."""
        entries = [record.get(c, {"transform": "none", "range": [None, None]}) for c in columns]
        bound = (lambda v, default: default if v is None else float(v))
        return cls(tuple(columns), tuple(columns), tuple(e["transform"] for e in entries),
                   tuple((bound(e["range"][0], -INF), bound(e["range"][1], INF)) for e in entries))

    @property
    def identity(self) -> bool:
        return all(name == "none" for name in self.names)

    def range(self, j: int) -> tuple[float, float]:
        if self.ranges is not None:
            return self.ranges[j]
        low, high, _ = RANGES.get(self.stats[j], (-INF, INF, False))
        return low, high

    def apply(self, x, clip: bool = True) -> np.ndarray:
        """(n, k) -> (n, k): every column through its transform (values clipped into the range first)."""
        x = np.array(x, dtype=np.float64, copy=True)
        if self.identity:
            return x
        with np.errstate(divide="ignore", invalid="ignore"):
            for j, name in enumerate(self.names):
                if name == "none":
                    continue
                low, high = self.range(j)
                column = np.clip(x[..., j], low, high) if clip else x[..., j]
                if name == "logit":
                    eps = LOGIT_EPS * (high - low)
                    x[..., j] = np.log((column - low + eps) / (high - column + eps))
                else:
                    x[..., j] = np.log(column + LOG_EPS)
        return np.where(np.isfinite(x), x, np.nan)

    def wrap(self, fn):
        """``fn(theta, *rest) -> (n, k)`` with its rows transformed (the identity returns ``fn`` itself)."""
        if self.identity:
            return fn
        return _Wrapped(fn, self)

    def record(self) -> dict:
        return {column: {"transform": name, "range": [self.range(j)[0], self.range(j)[1]]}
                for j, (column, name) in enumerate(zip(self.columns, self.names))}

    def describe(self) -> str:
        """One line: the transformed columns and their transforms, or that none is."""
        shown = [f"{column}: {name}" for column, name in zip(self.columns, self.names) if name != "none"]
        return ", ".join(shown) if shown else "none (linear scale)"


class _Wrapped:
    """A simulator whose rows come out transformed (picklable, for process pools)."""

    def __init__(self, fn, transforms: Transforms):
        self.fn, self.transforms = fn, transforms

    def __call__(self, theta, *rest):
        return self.transforms.apply(self.fn(theta, *rest))


def transforms_from(given, stats, columns) -> Transforms:
    """The transforms of ``[targets] transform`` (module docstring)."""
    stats, columns = tuple(stats), tuple(columns)
    if given is None or given == "auto":
        chosen = {}
        default = "auto"
    elif given == "none":
        chosen, default = {}, "none"
    elif isinstance(given, dict):
        chosen, default = dict(given), "auto"
        for stat, name in chosen.items():
            if stat not in stats:
                raise ConfigError(f"targets.transform.{stat}", f"not a target statistic{suggest(stat, stats)}; "
                                                               f"targets: {', '.join(stats)}")
            if name not in NAMES:
                raise ConfigError(f"targets.transform.{stat}", f"got {name!r}; allowed: {', '.join(NAMES)}")
            _allowed(stat, name, f"targets.transform.{stat}")
    else:
        raise ConfigError("targets.transform", f"got {given!r}; expected \"auto\", \"none\" or a table such as "
                                               "{ polarization = \"logit\", nn_distance = \"none\" }")
    names = []
    for stat in stats:
        name = chosen.get(stat, default)
        names.append(automatic(stat) if name == "auto" else name)
    return Transforms(stats, columns, tuple(names))
