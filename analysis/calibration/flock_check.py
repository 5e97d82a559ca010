"""Predictive checks that look at the flock, not only at the fitted statistics: every posterior predictive
run reports the whole flock (groups, fragmentation, nearest-neighbour distance, speed, ...), and any of
those that disagrees with the observed flock is flagged, target or not (a fit can match its targets while
its flocks split into 2-4 groups where the observed birds were one).

Shapes: P predictive runs, k targets, f flock statistics.

Contract
--------
``FLOCK_STATS``: the statistics of the flock every predictive run reports besides the targets
(polarization, n_groups, fragmented, stray_fraction, nn_distance, speed_mean, speed_cv, cohesion,
gyration_radius, elongation, milling), each in the targets' summary (``<stat>_mean`` or ``_final``;
``fragmented`` is per run: 1 when the flock split during the run).

``flock_columns(config) -> tuple``: those summary columns that are not targets, in that order.

``observed_flock(config) -> dict``: column -> the observed flock's value, for the columns known besides
the targets: ``[targets] flock = { n_groups = 1, ... }`` (statistic names as in ``stats``, numbers; the
observed flock's own statistics, not fitted), and with ``from_tracks`` the mean over the measured flocks
of every flock column the tracks give (typed values win).

``flock_check(config, targets_pred (P, k), flock_pred (P, f)) -> DataFrame``: one row per column of the
row, the targets first (observed: the targets' mean) and then the flock columns (observed: NaN when
unknown): ``target`` (bool), ``pred_mean``, ``pred_sd``, ``pred_q2.5``, ``pred_q97.5``, the two-sided
tail probability ``p`` (as :func:`~analysis.calibration.diagnostics.predictive_check`) and
``disagrees``: ``p`` below 0.05 / (the number of non-target columns whose observed value is known), a
Bonferroni bound: with nine statistics checked at 0.05 each, a well-fitted flock would be flagged about
one time in three by chance (with 100 predictive runs p moves in steps of 0.02, so with several known
statistics only an observed value outside every run's is flagged, as one group against 2-4).
The flock columns carry no measurement noise (none is stated for them); the targets' predictive values
carry the targets' noise, as ``predictive.csv``.

``flock_messages(table) -> list[str]``: one verdict sentence per non-target that disagrees (the targets'
own tails are in the predictive check's sentences).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from flocksweep.simcore.schema import ConfigError, suggest

from .diagnostics import predictive_check

FLOCK_STATS = ("polarization", "n_groups", "fragmented", "stray_fraction", "nn_distance", "speed_mean", "speed_cv",
               "cohesion", "gyration_radius", "elongation", "milling")
RUN_LEVEL = ("fragmented",)      # per run: no _mean / _final
P_FLOCK = 0.05


def stat_column(stat: str, summary: str) -> str:
    return stat if stat in RUN_LEVEL else f"{stat}_{summary}"


def flock_columns(config) -> tuple[str, ...]:
    targets = config.targets
    columns = (stat_column(s, targets.summary) for s in FLOCK_STATS)
    return tuple(c for c in columns if c not in targets.columns)


def check_flock_table(flock, summary: str, target_columns) -> dict:
    """``[targets] flock`` -> {column: value}; ConfigError naming the key for an unknown or non-numeric one."""
    if flock is None:
        return {}
    if not isinstance(flock, dict):
        raise ConfigError("targets.flock", f"got {flock!r}; expected a table such as {{ n_groups = 1 }}")
    out = {}
    for stat, value in flock.items():
        if stat not in FLOCK_STATS:
            raise ConfigError(f"targets.flock.{stat}", f"not a flock statistic{suggest(stat, FLOCK_STATS)}; "
                                                       f"allowed: {', '.join(FLOCK_STATS)}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"targets.flock.{stat}", f"got {value!r}; expected a finite number")
        column = stat_column(stat, summary)
        if column in target_columns:
            raise ConfigError(f"targets.flock.{stat}", "is a target already (in stats); give it there only")
        out[column] = float(value)
    return out


def observed_flock(config) -> dict:
    """The observed flock's known non-target columns (module docstring)."""
    targets = config.targets
    known = {}
    runs = getattr(targets, "flock_runs", None)
    if runs is not None:
        for column in flock_columns(config):
            if column in runs:
                values = pd.to_numeric(runs[column], errors="coerce").to_numpy(dtype=float)
                if values.size and np.isfinite(values).all():
                    known[column] = float(values.mean())
    known.update(targets.flock)
    return known


def flock_check(config, targets_pred, flock_pred) -> pd.DataFrame:
    """Every column of the predictive runs against the observed flock (module docstring)."""
    targets = config.targets
    columns = flock_columns(config)
    known = observed_flock(config)
    observed = np.array([known.get(c, np.nan) for c in columns])
    parts = [predictive_check(targets.observed, targets_pred, targets.columns).assign(target=True)]
    if columns:
        flock = predictive_check(np.where(np.isfinite(observed), observed, 0.0), flock_pred, columns)
        flock.loc[~np.isfinite(observed), ["observed", "p"]] = np.nan
        parts.append(flock.assign(target=False))
    table = pd.concat(parts)
    table["disagrees"] = table["p"].lt(P_FLOCK / max(1, int(np.isfinite(observed).sum())))
    return table[["observed", "target", "pred_mean", "pred_sd", "pred_q2.5", "pred_q97.5", "p", "disagrees",
                  "n_pred"]]


def flock_messages(table: pd.DataFrame | None) -> list[str]:
    """Verdict sentences for the non-targets that disagree with the observed flock."""
    if table is None:
        return []
    return [f"flock check: {column} is {row['observed']:.4g} in the observed flock but {row['pred_mean']:.3g} in the "
            f"posterior predictive runs (95%: {row['pred_q2.5']:.3g}-{row['pred_q97.5']:.3g}, p = {row['p']:.2g}); "
            "not a target, yet the fitted flocks do not look like the observed one"
            for column, row in table.iterrows() if row["disagrees"] and not row["target"]]
