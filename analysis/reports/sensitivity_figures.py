"""Figures of the sensitivity analysis of continuous factors (:mod:`analysis.reports.sensitivity`).

Same contract as :mod:`analysis.reports.figures`: data and an output ``path`` in, the format by its
extension, matplotlib's Agg backend selected inside, saved atomically and closed
(:mod:`analysis.reports.plotting`), the ``Path`` returned; importing draws nothing. Axes carry readable
names with units (:mod:`analysis.reports.labels`), never raw column names.

``sobol_figure(indices, path)``
    ``indices``: long table ``metric, factor, S1, S1_low, S1_high, ST, ST_low, ST_high``. One panel per
    metric: horizontal bars of the total (ST) and first-order (S1) indices with their CIs, factors
    sorted by ST (largest on top).
``morris_figure(indices, path)``
    ``metric, factor, mu_star, mu_star_low, mu_star_high, sigma``: one panel per metric, sigma against
    mu* with mu*'s CI, each point named; the line sigma = mu* separates mostly additive (below) from
    non-linear or interacting effects (above).
``correlation_figure(table, path)``
    ``metric, factor, prcc, prcc_low, prcc_high, spearman, spearman_low, spearman_high``: one panel per
    metric, PRCC and Spearman's rho with CIs per factor.
``scatter_figure(points, keys, metric, path, smooth=None)``
    ``points``: per design point the key columns and ``mean`` (over replicates); one panel per factor,
    point means against the factor with ``smooth[key] = (x, y)`` drawn as a line.
``partial_dependence_figure(curves, metric, path, r2=nan)``
    ``curves``: ``factor, value, average``; one panel per factor on a shared y axis, R^2 in the title.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from .labels import metric_label, parameter_label
from .plotting import pyplot, save


def _panels(n: int, ncols: int, width: float, height: float, sharey: bool = False):
    ncols = max(1, min(ncols, n))
    nrows = math.ceil(n / ncols)
    fig, axes = pyplot().subplots(nrows, ncols, figsize=(width * ncols, height * nrows + 0.4), squeeze=False,
                                  sharey=sharey)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat)


def _interval(table: pd.DataFrame, value: str) -> np.ndarray:
    centre = table[value].to_numpy(float)
    low = np.clip(centre - table[f"{value}_low"].to_numpy(float), 0, None)
    high = np.clip(table[f"{value}_high"].to_numpy(float) - centre, 0, None)
    return np.nan_to_num(np.vstack([low, high]))


def sobol_figure(indices: pd.DataFrame, path) -> Path:
    metrics = list(pd.unique(indices["metric"]))
    d = indices["factor"].nunique()
    fig, axes = _panels(len(metrics), 2, 5.2, 0.45 * d + 1.2)
    for ax, metric in zip(axes, metrics):
        rows = indices[indices["metric"] == metric].sort_values("ST", ascending=True)
        ys = np.arange(len(rows))
        ax.barh(ys + 0.2, rows["ST"], height=0.38, xerr=_interval(rows, "ST"), color="C3", alpha=0.8,
                capsize=3, label="total ST")
        ax.barh(ys - 0.2, rows["S1"], height=0.38, xerr=_interval(rows, "S1"), color="C0", alpha=0.8,
                capsize=3, label="first order S1")
        ax.set_yticks(ys)
        ax.set_yticklabels([parameter_label(f) for f in rows["factor"]], fontsize=8)
        ax.axvline(0, color="k", lw=0.6)
        ax.set_xlabel("share of the output variance", fontsize=8)
        ax.set_title(metric_label(metric), fontsize=9)
        ax.grid(True, axis="x", alpha=0.3, lw=0.5)
    axes[0].legend(fontsize=7, loc="lower right")
    return save(fig, path)


def morris_figure(indices: pd.DataFrame, path) -> Path:
    metrics = list(pd.unique(indices["metric"]))
    fig, axes = _panels(len(metrics), 3, 3.8, 3.4)
    for ax, metric in zip(axes, metrics):
        rows = indices[indices["metric"] == metric]
        xerr = _interval(rows, "mu_star")
        ax.errorbar(rows["mu_star"], rows["sigma"], xerr=xerr, fmt="o", color="C0", capsize=3, ms=5)
        for _, row in rows.iterrows():
            ax.annotate(parameter_label(row["factor"]), (row["mu_star"], row["sigma"]), fontsize=7,
                        xytext=(4, 3), textcoords="offset points")
        top = float(np.nanmax(np.r_[rows["mu_star_high"], rows["sigma"], 1e-12])) * 1.1
        ax.plot([0, top], [0, top], color="0.5", lw=0.8, ls="--")
        ax.set_xlim(0, top)
        ax.set_ylim(0, top)
        ax.set_xlabel("mu* (mean |elementary effect|)", fontsize=8)
        ax.set_ylabel("sigma (sd of elementary effects)", fontsize=8)
        ax.set_title(metric_label(metric), fontsize=9)
        ax.grid(True, alpha=0.3, lw=0.5)
    return save(fig, path)


def correlation_figure(table: pd.DataFrame, path) -> Path:
    metrics = list(pd.unique(table["metric"]))
    d = table["factor"].nunique()
    fig, axes = _panels(len(metrics), 3, 4.2, 0.4 * d + 1.3, sharey=True)
    for ax, metric in zip(axes, metrics):
        rows = table[table["metric"] == metric]
        ys = np.arange(len(rows))
        ax.errorbar(rows["prcc"], ys + 0.12, xerr=_interval(rows, "prcc"), fmt="o", color="C3", capsize=3,
                    ms=4, label="PRCC")
        ax.errorbar(rows["spearman"], ys - 0.12, xerr=_interval(rows, "spearman"), fmt="s", color="C0",
                    capsize=3, ms=4, label="Spearman")
        ax.set_yticks(ys)
        ax.set_yticklabels([parameter_label(f) for f in rows["factor"]], fontsize=8)
        ax.axvline(0, color="k", lw=0.6)
        ax.set_xlim(-1.05, 1.05)
        ax.set_xlabel("rank correlation (95% CI)", fontsize=8)
        ax.set_title(metric_label(metric), fontsize=9)
        ax.grid(True, axis="x", alpha=0.3, lw=0.5)
    axes[0].legend(fontsize=7)
    return save(fig, path)


def scatter_figure(points: pd.DataFrame, keys, metric: str, path, smooth: dict | None = None) -> Path:
    keys = list(keys)
    fig, axes = _panels(len(keys), 4, 3.0, 2.7, sharey=True)
    alpha = float(np.clip(40.0 / max(len(points), 1), 0.08, 0.8))
    for k, (ax, key) in enumerate(zip(axes, keys)):
        ax.scatter(points[key], points["mean"], s=6, color="C0", alpha=alpha, lw=0)
        if smooth and smooth.get(key) is not None:
            x, y = smooth[key]
            ax.plot(x, y, color="C3", lw=1.8, label="smoothing spline")
        ax.set_xlabel(parameter_label(key), fontsize=8)
        if k % 4 == 0:
            ax.set_ylabel(metric_label(metric), fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3, lw=0.5)
    if smooth and any(v is not None for v in smooth.values()):
        axes[0].legend(fontsize=7)
    return save(fig, path)


def partial_dependence_figure(curves: pd.DataFrame, metric: str, path, r2: float = math.nan) -> Path:
    factors = list(pd.unique(curves["factor"]))
    fig, axes = _panels(len(factors), 4, 3.0, 2.6, sharey=True)
    for k, (ax, factor) in enumerate(zip(axes, factors)):
        rows = curves[curves["factor"] == factor]
        ax.plot(rows["value"], rows["average"], color="C2", lw=1.8)
        ax.set_xlabel(parameter_label(factor), fontsize=8)
        if k % 4 == 0:
            ax.set_ylabel(f"partial dependence of\n{metric_label(metric)}", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3, lw=0.5)
    fig.suptitle(f"boosted-trees fit, cross-validated R^2 = {r2:.2f}", fontsize=9)
    return save(fig, path)
