"""The evidence behind a claim's verdict, drawn: one panel per leaf test of the claim.

``claim_figure(outcome, path, seed=0)`` (``outcome`` a :class:`.evaluate.ClaimOutcome`) draws, for each
leaf test, the very values the test used (the runs meeting its condition):

* a trend: the metric's mean at each level of the factor with its 95% bootstrap CI
  (:func:`analysis.reports.stats.main_effect`), the runs as faint dots, and the least-squares line;
* a comparison: the two groups' means with 95% bootstrap CIs and their runs (a paired comparison: the
  differences, as a sign test);
* a sign test or check: the runs, their mean with its CI, and the reference value as a line.

Each panel's title is the part's label and verdict; its note gives the statistic, p (Holm), n, and the
power at the effect of interest. The format follows the extension (:mod:`analysis.reports.plotting`).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..plotting import pyplot, save
from ..stats import bootstrap_mean_ci, main_effect

COLOURS = {"supported": "#0a6b2a", "partly supported": "#2f6f9f", "not supported": "#a11111",
           "inconclusive": "#9a6700"}


def _note(leaf, inherited: int) -> str:
    result, power = leaf.result, leaf.power
    own = " and ".join(c.text for c in leaf.test.conditions[inherited:])
    where = [f"where {own}"] if own else []
    if result.method == "check":
        return "\n".join(where + [result.detail])
    lines = where + [f"{result.method}: {result.statistic:.3g}, p (Holm) {leaf.p_holm:.2g}, n {result.n}"]
    if power is not None:
        lines.append(f"power {power.power:.2f} at effect {power.effect:.3g}; MDE {power.mde:.3g}")
    return "\n".join(lines)


def _jitter(n: int, rng, width: float) -> np.ndarray:
    return rng.uniform(-width, width, n)


def _trend(ax, leaf, rng, seed: int) -> None:
    test, data = leaf.test, leaf.data
    frame = pd.DataFrame({"x": data.x, "y": data.y})
    effects = main_effect(frame, "x", "y", n_resamples=1000, seed=seed)
    levels = effects["level"].to_numpy(dtype=float)
    span = (levels.max() - levels.min()) or 1.0
    ax.scatter(data.x + _jitter(data.n, rng, 0.015 * span), data.y, s=4, alpha=0.15, color="#777777", lw=0)
    low = (effects["mean"] - effects["ci_low"]).to_numpy(dtype=float)
    high = (effects["ci_high"] - effects["mean"]).to_numpy(dtype=float)
    ax.errorbar(levels, effects["mean"], yerr=[np.nan_to_num(low), np.nan_to_num(high)], fmt="o-", color="black",
                capsize=3, lw=1.2, ms=4, label="mean, 95% CI")
    if data.n >= 2 and np.ptp(data.x) > 0:
        slope, intercept = np.polyfit(data.x, data.y, 1)
        ax.plot(levels, intercept + slope * levels, ls="--", color="#c05000", lw=1, label="least squares")
    ax.set_xlabel(test.factor)


def _groups(ax, leaf, rng, seed: int) -> None:
    test, data = leaf.test, leaf.data
    for position, (name, mask) in enumerate((("lower", data.x < 0.5), ("higher", data.x > 0.5))):
        values = data.y[mask]
        ax.scatter(position + _jitter(values.size, rng, 0.15), values, s=4, alpha=0.15, color="#777777", lw=0)
        low, high, _ = bootstrap_mean_ci(values, n_resamples=1000, seed=seed + position)
        mean = float(values.mean()) if values.size else math.nan
        ax.errorbar([position], [mean], yerr=[[np.nan_to_num(mean - low)], [np.nan_to_num(high - mean)]], fmt="o",
                    color="black", capsize=4, ms=5)
    ax.set_xticks([0, 1], [f"lower:\n{test.lower.text}", f"higher:\n{test.higher.text}"], fontsize=7)
    ax.set_xlim(-0.6, 1.6)


def _one_sample(ax, leaf, rng, seed: int) -> None:
    test, data = leaf.test, leaf.data
    reference = 0.0 if test.kind == "compare" else test.value
    ax.scatter(_jitter(data.n, rng, 0.2), data.y, s=5, alpha=0.25, color="#777777", lw=0)
    if data.n:
        low, high, _ = bootstrap_mean_ci(data.y, n_resamples=1000, seed=seed)
        mean = float(data.y.mean())
        ax.errorbar([0.4], [mean], yerr=[[np.nan_to_num(mean - low)], [np.nan_to_num(high - mean)]], fmt="o",
                    color="black", capsize=4, ms=5, label="mean, 95% CI")
    ax.axhline(reference, color="#c05000", ls="--", lw=1, label=f"reference {reference:g}")
    ax.set_xticks([])
    ax.set_xlim(-0.5, 0.7)
    if test.kind == "compare":
        ax.set_xlabel(f"paired: ({test.higher.text}) - ({test.lower.text})", fontsize=7)


def _focus(ax, values: np.ndarray) -> None:
    """The y range of the runs between their 1st and 99th percentiles, widened to keep every mean and
    CI drawn, so a few far runs do not flatten the evidence (the note says so when runs are cut off)."""
    low, high = np.percentile(values, [1, 99])
    drawn_low, drawn_high = ax.get_ylim()
    lines = [line.get_ydata() for line in ax.get_lines()]
    marks = np.concatenate([np.asarray(y, dtype=float).ravel() for y in lines]) if lines else np.zeros(0)
    marks = marks[np.isfinite(marks)]
    for collection in ax.collections[1:]:                      # error bars (the first collection is the runs)
        for segment in getattr(collection, "get_segments", lambda: [])():
            marks = np.concatenate([marks, np.asarray(segment)[:, 1]])
    low = min(low, marks.min()) if marks.size else low
    high = max(high, marks.max()) if marks.size else high
    pad = 0.08 * (high - low or 1.0)
    ax.set_ylim(max(drawn_low, low - pad), min(drawn_high, high + pad))
    hidden = int(((values < low - pad) | (values > high + pad)).sum())
    if hidden:
        ax.text(0.98, 0.02, f"{hidden} runs outside the axis", transform=ax.transAxes, ha="right", va="bottom",
                fontsize=6, color="#777777")


def claim_figure(outcome, path, seed: int = 0) -> Path:
    plt = pyplot()
    leaves = outcome.outcome.leaves()
    ncols = min(3, len(leaves))
    nrows = math.ceil(len(leaves) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.4 * nrows), squeeze=False)
    rng = np.random.default_rng(seed)
    for ax, leaf in zip(axes.flat, leaves):
        test = leaf.test
        if leaf.data is None or leaf.data.n == 0:
            ax.text(0.5, 0.5, "no runs", ha="center", va="center", transform=ax.transAxes)
        elif test.kind == "trend":
            _trend(ax, leaf, rng, seed)
        elif test.kind == "compare" and not test.paired:
            _groups(ax, leaf, rng, seed)
        else:
            _one_sample(ax, leaf, rng, seed)
        if leaf.data is not None and leaf.data.n > 20:
            _focus(ax, leaf.data.y)
        ax.set_title(f"{test.label}: {leaf.verdict}", fontsize=9, color=COLOURS.get(leaf.verdict, "black"))
        ax.set_ylabel(test.metric.text, fontsize=8)
        ax.text(0.02, 0.98, _note(leaf, len(outcome.claim.test.conditions)), transform=ax.transAxes, va="top", ha="left", fontsize=7,
                bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(leaves):]:
        ax.set_visible(False)
    condition = " and ".join(c.text for c in outcome.claim.test.conditions)
    fig.suptitle(f"({outcome.claim.id}) {outcome.verdict}" + (f"; where {condition}" if condition else ""),
                 fontsize=10, color=COLOURS.get(outcome.verdict, "black"))
    return save(fig, path)
