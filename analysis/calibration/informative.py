"""Which summary statistics tell most about the free parameters, judged on a sweep BEFORE any posterior:
the rule used to choose an emulator calibration's targets (docs/calibration.md, "Choosing the statistics").

Shapes: P parameter points (each with replicates), k candidate statistics.

Contract
--------
``rank_statistics(training, *, min_ratio=5.0, max_correlation=0.85, sd_share=0.025) -> DataFrame``
    ``training`` is a :class:`~.training.TrainingSet` (per-point means and replicate variances, e.g. the
    sweep's grid cells at the calibration's fixed settings). Per statistic j:

    * ``ratio`` = the variance of the point means over the points / the mean replicate variance: how
      far the statistic moves across the design compared with its run-to-run spread (the F statistic
      of a one-way ANOVA divided by the replicates per point). A statistic that does not move (both
      variances zero) gets 0.
    * ``range`` = the largest minus the smallest point mean, and ``measurement_sd`` = ``sd_share x
      range`` to one significant figure: the measurement-error convention (an observer's error a fixed
      share of the statistic's span over the prior).

    Rows sorted by ``ratio`` (largest first, ties by name). ``chosen``: greedily in that order, a
    statistic is chosen when its ratio is at least ``min_ratio`` and its point means correlate (Pearson,
    over the points) at most ``max_correlation`` in absolute value with every statistic chosen before it;
    ``reason`` says why not otherwise (``"ratio < min_ratio"`` or ``"|r| = .. with <stat>"``).
    Deterministic; it reads no posterior and no targets.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .training import TrainingSet


def _one_significant_figure(value: float) -> float:
    if not math.isfinite(value) or value <= 0:
        return 0.0
    exponent = math.floor(math.log10(value))
    return round(value, -exponent)


def _ratio(means: np.ndarray, variances: np.ndarray) -> float:
    between = float(np.var(means, ddof=1)) if len(means) > 1 else 0.0
    within = float(np.mean(variances))
    if within <= 0:
        return 0.0 if between <= 0 else math.inf
    return between / within


def rank_statistics(training: TrainingSet, *, min_ratio: float = 5.0, max_correlation: float = 0.85,
                    sd_share: float = 0.025) -> pd.DataFrame:
    """Candidate statistics ranked by between-point over within-point variance (see the module docstring)."""
    means, variances = np.asarray(training.mean, dtype=float), np.asarray(training.var, dtype=float)
    table = pd.DataFrame({
        "statistic": list(training.columns),
        "ratio": [_ratio(means[:, j], variances[:, j]) for j in range(training.k)],
        "within_sd": np.sqrt(variances.mean(axis=0)),
        "range": np.ptp(means, axis=0),
    })
    table["measurement_sd"] = [_one_significant_figure(sd_share * span) for span in table["range"]]
    table = table.sort_values(["ratio", "statistic"], ascending=[False, True], kind="stable")
    with np.errstate(divide="ignore", invalid="ignore"):
        correlation = np.corrcoef(means, rowvar=False).reshape(training.k, training.k)
    chosen, reasons = [], []
    for j in table.index:
        reason = ""
        if not table.at[j, "ratio"] >= min_ratio:
            reason = f"ratio < {min_ratio:g}"
        else:
            for c in chosen:
                r = correlation[j, c]
                if np.isfinite(r) and abs(r) > max_correlation:
                    reason = f"|r| = {abs(r):.2f} with {training.columns[c]}"
                    break
        if not reason:
            chosen.append(j)
        reasons.append(reason)
    table["chosen"] = [j in chosen for j in table.index]
    table["reason"] = reasons
    return table.reset_index(drop=True)
