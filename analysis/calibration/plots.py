"""Calibration figures: MCMC traces, corner plot, posterior predictive check and SBC rank figures.

Same contract as :mod:`analysis.reports.figures`: each function takes data and an output ``path``
(format by extension, ``.png`` or ``.svg``; parent directories created), draws with the Agg backend
selected inside the function, saves atomically, closes the figure and returns the ``Path`` written
(:mod:`analysis.reports.plotting`). Importing this module does not import matplotlib.

``trace_figure(chain, names, path, burn=None)``
    one panel per parameter, every walker's trace vs step, burn-in shaded.
``corner_figure(samples, names, path, truths=None, labels=None)``
    ``corner.corner``: marginal histograms with the 5%, 50% and 95% quantiles (dashed, and in the titles),
    2-D histograms with contours holding 50% and 90% of the samples (points drawn below 500 samples),
    ``truths`` (the parameters the targets were simulated at) as red lines; ``labels`` for the axes
    (default the names).
``rank_figure(idata, path)``
    ArviZ's rank plot (``arviz.plot_rank``, bars): per parameter the rank histogram of every walker
    (stacked) against the uniform expectation; walkers that mix well all look flat.
``predictive_figure(check_df, predictive, observed, names, path)``
    one panel per statistic: histogram of the predictive, observed value marked, tail probability ``p``
    in the title (``check_df`` from :func:`analysis.calibration.diagnostics.predictive_check`).
``sbc_figure(ranks, S, bins, names, path)``
    rank histograms with the uniform expectation and a 99% binomial band.
``ecdf_figure(ranks, S, names, band, path, level=0.95)``
    ECDF of the fractional ranks minus the uniform CDF with a simultaneous band (band from
    :func:`analysis.calibration.sbc_report.ecdf_band`), one panel per parameter.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy import stats

from flocksweep.analysis.reports.plotting import pyplot, save

from .diagnostics import _bin_probs, _names, ecdf_counts, sbc_histogram

SCATTER_MAX = 500
CORNER_QUANTILES = (0.05, 0.5, 0.95)   # the marginal 90% interval and the median
CORNER_LEVELS = (0.5, 0.9)             # 2-D contours holding 50% and 90% of the samples


def _panels(n: int, width: float, height: float, ncols_max: int = 4):
    """(figure, flat axes) of a grid of ``n`` panels of ``width`` x ``height`` inches, unused ones hidden."""
    ncols = min(n, ncols_max)
    nrows = int(math.ceil(n / ncols))
    fig, axes = pyplot().subplots(nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False)
    flat = axes.ravel()
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat


def trace_figure(chain, names: Sequence[str] | None, path, burn: int | None = None) -> Path:
    chain = np.asarray(chain, dtype=float)
    if chain.ndim != 3:
        raise ValueError(f"chain must have shape (steps, walkers, d), got {chain.shape}")
    steps, walkers, d = chain.shape
    names = _names(names, d)
    fig, axes = pyplot().subplots(d, 1, figsize=(8, 1.8 * d + 0.6), sharex=True, squeeze=False)
    t = np.arange(steps)
    alpha = max(0.05, min(0.6, 8.0 / walkers))
    for j, ax in enumerate(axes[:, 0]):
        ax.plot(t, chain[:, :, j], color="k", lw=0.5, alpha=alpha)
        if burn:
            ax.axvspan(0, burn, color="tab:red", alpha=0.12, lw=0, label="burn-in" if j == 0 else None)
        ax.set_ylabel(names[j])
        ax.set_xlim(0, max(steps - 1, 1))
    if burn:
        axes[0, 0].legend(loc="upper right", fontsize="small")
    axes[-1, 0].set_xlabel("step")
    return save(fig, path)


def corner_figure(samples, names: Sequence[str] | None, path, truths=None, labels: Sequence[str] | None = None) -> Path:
    """The pairwise posterior through the ``corner`` package (see the module docstring)."""
    import corner  # imported here: it loads matplotlib

    x = np.asarray(samples, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f"samples must have shape (S, d), got {x.shape}")
    x = x[np.all(np.isfinite(x), axis=1)]
    S, d = x.shape
    names = _names(names, d)
    truths = None if truths is None else np.asarray(truths, dtype=float).ravel()
    if truths is not None and truths.size != d:
        raise ValueError(f"got {truths.size} truths for {d} parameters")
    size = max(2.2, min(3.0, 10.0 / d))
    fig = pyplot().figure(figsize=(size * d, size * d))
    if S:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # corner warns about too few points for contours on tiny samples
            one = d == 1        # corner draws truth lines on a grid of axes: one parameter has a single one
            corner.corner(x, fig=fig, labels=list(labels or names), quantiles=CORNER_QUANTILES, show_titles=True,
                          title_quantiles=CORNER_QUANTILES, title_fmt=".3g", levels=CORNER_LEVELS,
                          plot_datapoints=S < SCATTER_MAX, fill_contours=True, smooth=1.0 if S >= SCATTER_MAX else None,
                          truths=None if truths is None or one else list(truths), truth_color="tab:red",
                          bins=int(np.clip(np.sqrt(S) / 2, 10, 40)))
            if one and truths is not None:
                fig.axes[0].axvline(float(truths[0]), color="tab:red")
    return save(fig, path)


def rank_figure(idata, path) -> Path:
    """ArviZ rank plot of the posterior (see the module docstring)."""
    from .inference import arviz

    names = list(idata.posterior.data_vars)
    fig, axes = pyplot().subplots(1, len(names), figsize=(4.2 * len(names), 3.4), squeeze=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        arviz().plot_rank(idata, var_names=names, kind="bars", ax=axes[0])
    for ax in axes[0]:
        ax.set_xlabel("rank among all walkers' draws", fontsize=9)
        ax.set_ylabel("walker", fontsize=9)
        ax.title.set_fontsize(10)
    return save(fig, path)


def predictive_figure(check_df, predictive, observed, names: Sequence[str] | None, path) -> Path:
    pred = np.asarray(predictive, dtype=float)
    if pred.ndim == 1:
        pred = pred[:, None]
    k = pred.shape[1]
    names = _names(names, k)
    obs = np.asarray(observed, dtype=float)
    if obs.ndim == 1:
        obs = obs[None, :]
    fig, flat = _panels(k, 3.2, 2.6)
    for j, name in enumerate(names):
        ax = flat[j]
        p = pred[:, j][np.isfinite(pred[:, j])]
        if p.size:
            ax.hist(p, bins=int(np.clip(np.sqrt(p.size), 10, 40)), color="tab:blue", alpha=0.6)
        x = float(check_df.loc[name, "observed"]) if name in check_df.index else float(np.nanmean(obs[:, j]))
        if np.isfinite(x):
            ax.axvline(x, color="tab:red", lw=1.5, label="observed")
        pval = float(check_df.loc[name, "p"]) if name in check_df.index and "p" in check_df else math.nan
        ax.set_title(f"{name}  (p = {pval:.2f})", fontsize="medium")
        ax.set_yticks([])
    flat[0].legend(fontsize="small")
    return save(fig, path)


def sbc_figure(ranks, S: int, bins: int, names: Sequence[str] | None, path) -> Path:
    counts, expected = sbc_histogram(ranks, S, bins)
    n_bins, d = counts.shape
    L = int(np.asarray(ranks).shape[0])
    names = _names(names, d)
    _, probs = _bin_probs(int(S), int(bins))
    low = stats.binom.ppf(0.005, L, probs)
    high = stats.binom.ppf(0.995, L, probs)
    fig, flat = _panels(d, 3.2, 2.6)
    edges = np.arange(n_bins + 1)
    for j, name in enumerate(names):
        ax = flat[j]
        ax.fill_between(edges, np.append(low, low[-1]), np.append(high, high[-1]), step="post",
                        color="0.8", label="99% band")
        ax.bar(edges[:-1], counts[:, j], width=1.0, align="edge", color="tab:blue", alpha=0.7,
               edgecolor="white", lw=0.5)
        ax.step(edges, np.append(expected, expected[-1]), where="post", color="k", lw=1.0,
                label="uniform")
        ax.set_xlim(0, n_bins)
        ax.set_title(name, fontsize="medium")
        ax.set_xlabel(f"rank bin (S = {int(S)})")
    flat[0].legend(fontsize="small")
    return save(fig, path)


def ecdf_figure(ranks, S: int, names: Sequence[str], band, path, level: float = 0.95) -> Path:
    """ECDF of the fractional ranks minus the uniform CDF, one panel per parameter, with the ``level``
    simultaneous band ``band`` = (z, lower, upper, ...)."""
    ranks = np.asarray(ranks)
    L, d = ranks.shape
    z, lower, upper = band[:3]
    counts = ecdf_counts(ranks.T, S) / L
    fig, flat = _panels(d, 3.6, 2.8)
    for j, name in enumerate(names):
        ax = flat[j]
        ax.fill_between(z, lower - z, upper - z, step="post", color="0.85", label=f"{level:.0%} simultaneous band")
        ax.step(z, counts[j] - z, where="post", color="tab:blue", lw=1.5, label="ECDF - uniform")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xlim(0, 1)
        ax.set_title(name, fontsize="medium")
        ax.set_xlabel(f"fractional rank (L = {L}, S = {S})")
    flat[0].legend(fontsize="small", loc="lower left")
    return save(fig, path)
