"""The evidence behind a claim's verdict, drawn: one panel per leaf test of the claim.

``claim_figure(outcome, path, seed=0)`` (``outcome`` a :class:`.evaluate.ClaimOutcome`) draws, for each
leaf test, the very values the test used (the runs meeting its condition):

* a trend: the metric's mean at each level of the factor with its 95% bootstrap CI
  (:func:`analysis.reports.stats.main_effect`), the runs as faint dots, and the least-squares line;
* a comparison: the two groups' means with 95% bootstrap CIs and their runs (a paired comparison: the
  differences, as a sign test);
* a sign test or check: the runs, their mean with its CI, and the reference value as a line.

Each panel's title is the part's label and verdict; its note, below the plot (never over the runs), gives
the statistic, p (Holm), n, and in words the power: the chance the test had to find the claim's effect of
interest with these runs, and the smallest effect it would find 80 % of the time. Axes are labelled in
words and units (:mod:`analysis.reports.labels`). The format follows the extension
(:mod:`analysis.reports.plotting`).
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from ..labels import metric_label, parameter_label
from ..plotting import pyplot, save
from ..stats import bootstrap_mean_ci, main_effect

NOTE_WIDTH = 64   # characters per line of a panel's note (a panel is about 4.4 inches wide)
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
        lines.append(power_words(power.power, power.effect, power.mde, power.replicates))
    return "\n".join(lines)


def power_words(power: float, effect: float, mde: float, replicates=None) -> str:
    """The power line of a note, in words: what the test could see with these runs."""
    chance = f"chance to detect an effect of {effect:.3g}: {power:.0%}"
    smallest = f"; 80% sure from {mde:.3g}" if np.isfinite(mde) else "; no effect is found 80% of the time"
    if power < 0.05:
        more = f" ({replicates} replicates per point would)" if replicates else ""
        return f"{chance}, too few runs for so small an effect{more}{smallest}"
    return chance + smallest


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
    ax.set_xticks(levels, [f"{v:g}" for v in levels])
    return parameter_label(test.factor)


def _groups(ax, leaf, rng, seed: int) -> None:
    test, data = leaf.test, leaf.data
    for position, (name, mask) in enumerate((("lower", data.x < 0.5), ("higher", data.x > 0.5))):
        values = data.y[mask]
        ax.scatter(position + _jitter(values.size, rng, 0.15), values, s=4, alpha=0.15, color="#777777", lw=0)
        low, high, _ = bootstrap_mean_ci(values, n_resamples=1000, seed=seed + position)
        mean = float(values.mean()) if values.size else math.nan
        ax.errorbar([position], [mean], yerr=[[np.nan_to_num(mean - low)], [np.nan_to_num(high - mean)]], fmt="o",
                    color="black", capsize=4, ms=5, zorder=3)
    ax.set_xticks([0, 1], [f"lower:\n{test.lower.text}", f"higher:\n{test.higher.text}"], fontsize=7)
    ax.set_xlim(-0.6, 1.6)
    return "the two groups' runs, mean and 95% CI"


def _one_sample(ax, leaf, rng, seed: int) -> None:
    test, data = leaf.test, leaf.data
    reference = 0.0 if test.kind == "compare" else test.value
    ax.scatter(_jitter(data.n, rng, 0.2), data.y, s=5, alpha=0.25, color="#777777", lw=0)
    if data.n:   # the mean and its CI on the runs themselves, drawn over them
        low, high, _ = bootstrap_mean_ci(data.y, n_resamples=1000, seed=seed)
        mean = float(data.y.mean())
        ax.errorbar([0.0], [mean], yerr=[[np.nan_to_num(mean - low)], [np.nan_to_num(high - mean)]], fmt="o",
                    color="black", capsize=6, ms=6, lw=1.6, zorder=3, label="mean, 95% CI")
    ax.axhline(reference, color="#c05000", ls="--", lw=1, label=f"reference {reference:g}")
    ax.set_xlim(-0.5, 0.5)
    if test.kind == "compare":
        ax.set_xticks([0.0], [f"{data.n} pairs: ({test.higher.text}) - ({test.lower.text})"], fontsize=7)
        return "each pair's difference; its mean and 95% CI; 0 = no difference"
    ax.set_xticks([0.0], [f"{data.n} runs"], fontsize=7)
    return f"the runs, their mean and 95% CI; the line: the reference {reference:g}"


def _focus(ax, values: np.ndarray) -> int:
    """The y range of the runs between their 1st and 99th percentiles, widened to keep every mean and
    CI drawn, so a few far runs do not flatten the evidence; returns how many runs it leaves outside
    (the note says so)."""
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
    return int(((values < low - pad) | (values > high + pad)).sum())


def _metric_text(text: str) -> str:
    """A claim's metric in words and unit when it is a plain column; an expression stays as written."""
    return metric_label(text) if text.replace("_", "").isalnum() else text


def claim_figure(outcome, path, seed: int = 0) -> Path:
    plt = pyplot()
    leaves = outcome.outcome.leaves()
    ncols = min(3, len(leaves))
    nrows = math.ceil(len(leaves) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.4 * ncols, 4.4 * nrows), squeeze=False)
    rng = np.random.default_rng(seed)
    for ax, leaf in zip(axes.flat, leaves):
        test = leaf.test
        what = ""
        if leaf.data is None or leaf.data.n == 0:
            ax.text(0.5, 0.5, "no runs", ha="center", va="center", transform=ax.transAxes)
        elif test.kind == "trend":
            what = _trend(ax, leaf, rng, seed)
        elif test.kind == "compare" and not test.paired:
            what = _groups(ax, leaf, rng, seed)
        else:
            what = _one_sample(ax, leaf, rng, seed)
        if leaf.data is not None and leaf.data.n > 20:
            outside = _focus(ax, leaf.data.y)
            what += f" ({outside} run{'s' if outside > 1 else ''} outside the axis)" if outside else ""
        ax.set_title(f"{test.label}: {leaf.verdict}", fontsize=9, color=COLOURS.get(leaf.verdict, "black"))
        ax.set_ylabel(_metric_text(test.metric.text), fontsize=8)
        note = _note(leaf, len(outcome.claim.test.conditions))   # below the plot: never over the runs
        lines = [wrapped for part in (what, note) if part for line in part.splitlines()
                 for wrapped in textwrap.wrap(line, NOTE_WIDTH, subsequent_indent="  ")]
        ax.set_xlabel("\n".join(lines), fontsize=7, loc="left")
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(leaves):]:
        ax.set_visible(False)
    condition = " and ".join(c.text for c in outcome.claim.test.conditions)
    fig.suptitle(f"({outcome.claim.id}) {outcome.verdict}" + (f"; where {condition}" if condition else ""),
                 fontsize=10, color=COLOURS.get(outcome.verdict, "black"))
    return save(fig, path)
