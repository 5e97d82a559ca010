"""Report figures of a sweep: main effects, heatmaps, time series, trace thumbnails, effect sizes.

Contract, shared by every function here:

* it takes data (pandas / numpy, already aggregated by the caller) and an output ``path`` (or a list of
  paths: one figure written in each format, laid out once; the first is returned); the format
  follows the extension (``.png`` at 150 dpi, ``.svg`` vector; anything matplotlib knows, e.g. ``.pdf``);
  missing parent directories are created;
* it draws with matplotlib's Agg backend (selected inside the function), lays the figure out tightly
  (constrained layout for figures with a colorbar or a figure legend, otherwise tight layout and a tight
  bounding box), saves it atomically, closes it and returns the ``Path`` written
  (:mod:`analysis.reports.plotting`);
* importing this module draws nothing and does not import matplotlib.

Functions:

``main_effects_figure(effects, metric, path)``
    ``effects``: long format, one row per (factor, level) with columns ``factor, level, n, mean, ci_low,
    ci_high`` for one metric. One small panel per factor (in order of appearance), mean vs level with a
    shaded CI band for numeric factors, points with error bars for categorical ones; panels share the y
    axis, labelled ``metric``.
``heatmap_figure(cells, metric, x, y, path, panel=None, rows=None)``
    ``cells``: one row per cell with the factor columns and ``mean``. Mean over ``x`` (columns) by ``y``
    (rows) as heatmaps; one grid column per level of ``panel``, one grid row per combination of levels of
    ``rows``. Cells sharing (x, y, panel, rows) levels are averaged (other factors are marginalised).
    One colour scale with a colorbar; values annotated when a heatmap is at most 8 x 8; NaN or missing
    cells grey.
``timeseries_figure(ts, cells, metrics, path)``
    ``ts``: (run_id, t, metric columns...); ``cells``: label -> run_ids. One panel per metric: for each
    cell the mean over its runs vs t, with a band of +-1 sd where at least 3 runs have a value at that t,
    min-max where fewer; one colour per cell; one legend for the figure.
``thumbnails_figure(items, path, ncols=3)``
    ``items``: (title, pos (R, N, 3), pattern (N,) or None[, {"obstacles", "predator", "prey"}]); a grid of
    3-D trace thumbnails drawn with ``analysis.reports.traces.draw_traces`` (obstacles and agent paths
    too), with one figure legend for the pattern colours.
``effect_sizes_figure(tests, path)``
    ``tests``: columns ``metric, factor, epsilon2`` (and ``p_holm``); heatmap of epsilon^2, metrics as
    rows and factors as columns, annotated, significant cells (``p_holm < 0.05``) marked with ``*`` and
    outlined.

Levels are ordered numerically when numeric (numpy scalars included), otherwise as strings.
"""
from __future__ import annotations

import math
import numbers
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .labels import metric_label, parameter_label, parameter_unit, parameter_words
from .plotting import pyplot, save
from .traces import boid_colours, draw_traces

ANNOTATE_TOTAL_MAX = 300  # value labels over all panels of one heatmap figure
ANNOTATE_MAX = 8           # annotate heatmaps up to this many rows and columns
NAN_COLOUR = "#c8c8c8"


# -- helpers ------------------------------------------------------------------------------------------

def _is_number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _level_key(value):
    if _is_number(value):
        return (0, float(value), "")
    return (1, 0.0, str(value))


def _sorted_levels(values) -> list:
    return sorted(pd.unique(pd.Series(list(values)).dropna()), key=_level_key)


def _fmt_level(value) -> str:
    if _is_number(value):
        value = float(value)
        return str(int(value)) if value.is_integer() else f"{value:g}"
    return str(value)


def _fmt_value(value: float) -> str:
    if not np.isfinite(value):
        return "–"
    magnitude = abs(value)
    if magnitude >= 100:
        return f"{value:.0f}"
    if magnitude >= 10:
        return f"{value:.1f}"
    return f"{value:.2f}"


def _level_words(factor: str, level) -> str:
    """``field of vision phi = 60 deg``: a factor at one of its levels, in words."""
    unit = parameter_unit(factor)
    return f"{parameter_words(factor)} = {_fmt_level(level)}{' ' + unit if unit else ''}"


def _text_colour(rgba) -> str:
    r, g, b = rgba[:3]
    return "black" if 0.299 * r + 0.587 * g + 0.114 * b > 0.55 else "white"


def _grid_shape(n: int, ncols: int) -> tuple[int, int]:
    ncols = max(1, min(ncols, n))
    return math.ceil(n / ncols), ncols


def _require(frame: pd.DataFrame, columns, what: str) -> None:
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise ValueError(f"{what}: missing column(s) {missing}; have {list(frame.columns)}")


def _cell_colours(n: int):
    import matplotlib

    if n <= 10:
        cmap = matplotlib.colormaps["tab10"]
        return [cmap(k) for k in range(n)]
    if n <= 20:
        cmap = matplotlib.colormaps["tab20"]
        return [cmap(k) for k in range(n)]
    cmap = matplotlib.colormaps["turbo"]
    return [cmap(k / (n - 1)) for k in range(n)]


# -- 1. main effects ----------------------------------------------------------------------------------

def main_effects_figure(effects: pd.DataFrame, metric: str, path, ncols: int = 5, title: str = "",
                        sharey: bool = True, xlabel: str = "", panel_title=parameter_label,
                        panel_ylabel=None) -> Path:
    """One panel per factor: mean of ``metric`` vs level with its CI (band or error bars). With
    ``sharey=False`` each panel keeps its own y scale (e.g. one panel per metric against one factor,
    the panel titles naming the metrics and ``xlabel`` the factor). ``panel_title(name)`` words each
    panel's title (default: the factor's words and unit); ``panel_ylabel(name)`` its own y label."""
    _require(effects, ["factor", "level", "mean", "ci_low", "ci_high"], "main_effects_figure")
    if effects.empty:
        raise ValueError("main_effects_figure: no effects to draw")
    plt = pyplot()
    factors = list(pd.unique(effects["factor"]))
    nrows, ncols = _grid_shape(len(factors), ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(2.7 * ncols, 2.5 * nrows + 0.3), sharey=sharey,
                             squeeze=False)
    for k, factor in enumerate(factors):
        ax = axes.flat[k]
        rows = effects[effects["factor"] == factor]
        order = sorted(range(len(rows)), key=lambda i: _level_key(rows["level"].iloc[i]))
        rows = rows.iloc[order]
        levels = list(rows["level"])
        mean = rows["mean"].to_numpy(float)
        low = rows["ci_low"].to_numpy(float)
        high = rows["ci_high"].to_numpy(float)
        numeric = len(levels) > 1 and all(_is_number(v) for v in levels)
        if numeric:
            xs = np.array([float(v) for v in levels])
            ax.fill_between(xs, low, high, color="C0", alpha=0.25, linewidth=0, label="CI")
            ax.plot(xs, mean, "o-", color="C0", markersize=3.5, linewidth=1.4)
            ax.set_xticks(xs)
            ax.set_xticklabels([_fmt_level(v) for v in levels], fontsize=7,
                               rotation=45 if len(levels) > 6 else 0)
        else:
            xs = np.arange(len(levels))
            yerr = np.vstack([np.nan_to_num(mean - low, nan=0.0), np.nan_to_num(high - mean, nan=0.0)])
            ax.errorbar(xs, mean, yerr=np.clip(yerr, 0, None), fmt="o", color="C0", markersize=5,
                        capsize=4, linewidth=1.4)
            ax.set_xticks(xs)
            labels = [textwrap.fill(_fmt_level(v), 14) for v in levels]   # long level names on a few lines
            longest = max(len(line) for label in labels for line in label.splitlines())
            ax.set_xticklabels(labels, fontsize=7, rotation=30 if longest > 6 and len(levels) > 3 else 0)
            ax.set_xlim(-0.5, len(levels) - 0.5)
        ax.set_title(panel_title(factor), fontsize=9)
        ax.tick_params(axis="y", labelsize=7)
        ax.grid(True, alpha=0.3, linewidth=0.5)
        if sharey and k % ncols == 0:   # wrapped to the panel's height: rows' labels never meet
            ax.set_ylabel(textwrap.fill(metric_label(metric), 26), fontsize=9)
        elif panel_ylabel is not None:
            ax.set_ylabel(textwrap.fill(panel_ylabel(factor), 26), fontsize=8)
        if xlabel:
            ax.set_xlabel(xlabel, fontsize=8)
    for ax in axes.flat[len(factors):]:
        ax.set_visible(False)
    if title:
        fig.suptitle(title, fontsize=10)
    return save(fig, path)


# -- 2. heatmaps --------------------------------------------------------------------------------------

def heatmap_figure(cells: pd.DataFrame, metric: str, x: str, y: str, path, panel: str | None = None,
                   rows: list[str] | str | None = None, cmap: str = "viridis", title: str = "") -> Path:
    """Mean ``metric`` over ``x`` by ``y``; grid columns = levels of ``panel``, grid rows = combinations
    of levels of ``rows``; one colour scale."""
    rows = [rows] if isinstance(rows, str) else list(rows or [])
    keys = [x, y] + ([panel] if panel else []) + rows
    if len(set(keys)) != len(keys):
        raise ValueError(f"heatmap_figure: x, y, panel and rows must be distinct, got {keys}")
    _require(cells, keys + ["mean"], "heatmap_figure")
    plt = pyplot()
    import matplotlib

    data = cells[keys + ["mean"]].copy()
    data["mean"] = pd.to_numeric(data["mean"], errors="coerce")
    x_levels = _sorted_levels(data[x])
    y_levels = _sorted_levels(data[y])
    panel_levels = _sorted_levels(data[panel]) if panel else [None]
    if rows:
        combos = data[rows].drop_duplicates().itertuples(index=False, name=None)
        row_levels = sorted(combos, key=lambda c: [_level_key(v) for v in c])
    else:
        row_levels = [()]
    if not x_levels or not y_levels:
        raise ValueError("heatmap_figure: no cells to draw")

    def matrix(row_combo, panel_level):
        sub = data
        for factor, level in zip(rows, row_combo):
            sub = sub[sub[factor] == level]
        if panel:
            sub = sub[sub[panel] == panel_level]
        out = np.full((len(y_levels), len(x_levels)), np.nan)
        if len(sub):
            means = sub.groupby([y, x], sort=False)["mean"].mean()
            yi = {_level_key(v): i for i, v in enumerate(y_levels)}
            xi = {_level_key(v): i for i, v in enumerate(x_levels)}
            for (yv, xv), value in means.items():
                out[yi[_level_key(yv)], xi[_level_key(xv)]] = value
        return out

    matrices = [[matrix(rc, pl) for pl in panel_levels] for rc in row_levels]
    finite = np.concatenate([m[np.isfinite(m)] for row in matrices for m in row] + [np.empty(0)])
    vmin, vmax = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if vmin == vmax:
        vmin, vmax = vmin - 0.5, vmax + 0.5
    colormap = matplotlib.colormaps[cmap].with_extremes(bad=NAN_COLOUR)
    norm = matplotlib.colors.Normalize(vmin, vmax)

    nx, ny = len(x_levels), len(y_levels)
    n_rows, n_cols = len(row_levels), len(panel_levels)
    cell_w = 0.42 if nx <= ANNOTATE_MAX else max(0.12, 3.4 / nx)
    cell_h = 0.34 if ny <= ANNOTATE_MAX else max(0.10, 2.8 / ny)
    panel_w, panel_h = nx * cell_w + 0.9, ny * cell_h + 0.8
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(panel_w * n_cols + 1.6, panel_h * n_rows + 0.4),
                             squeeze=False, layout="constrained")
    # value labels only where they stay readable and cheap: small grids, few panels
    annotate = nx <= ANNOTATE_MAX and ny <= ANNOTATE_MAX and nx * ny * n_rows * n_cols <= ANNOTATE_TOTAL_MAX
    font = 7 if max(nx, ny) <= 6 else 6
    image = None
    x_labels = [_fmt_level(v) for v in x_levels]
    y_labels = [_fmt_level(v) for v in y_levels]
    for r, row_combo in enumerate(row_levels):
        for c, panel_level in enumerate(panel_levels):
            ax = axes[r, c]
            values = matrices[r][c]
            image = ax.imshow(np.ma.masked_invalid(values), cmap=colormap, norm=norm, origin="lower",
                              aspect="auto", interpolation="nearest")
            if annotate:
                for i in range(ny):
                    for j in range(nx):
                        v = values[i, j]
                        colour = _text_colour(colormap(norm(v))) if np.isfinite(v) else "#555555"
                        ax.text(j, i, _fmt_value(v), ha="center", va="center", fontsize=font, color=colour,
                                in_layout=False)
            ax.set_xticks(range(nx))
            ax.set_yticks(range(ny))
            if r == n_rows - 1:
                long = max(map(len, x_labels)) > 4 and nx > 3
                ax.set_xticklabels(x_labels, fontsize=7, rotation=45 if long else 0)
                ax.set_xlabel(parameter_label(x), fontsize=8)
            else:
                ax.set_xticklabels([])
            if c == 0:
                ax.set_yticklabels(y_labels, fontsize=7)
                row_name = ", ".join(_level_words(f, v) for f, v in zip(rows, row_combo))
                ax.set_ylabel(f"{row_name}\n{parameter_label(y)}" if row_name else parameter_label(y), fontsize=8)
            else:
                ax.set_yticklabels([])
            if r == 0 and panel:
                ax.set_title(_level_words(panel, panel_level), fontsize=9)
            ax.tick_params(length=2)
    bar = fig.colorbar(image, ax=axes.ravel().tolist(), shrink=min(1.0, 0.9 if n_rows > 1 else 1.0),
                       aspect=max(20, 12 * n_rows))
    bar.set_label(f"{metric_label(metric)}, mean", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    return save(fig, path)


# -- 3. time series -----------------------------------------------------------------------------------

def timeseries_figure(ts: pd.DataFrame, cells: dict[str, list[str]], metrics: list[str], path,
                      ncols: int = 3, title: str = "") -> Path:
    """One panel per metric: each cell's mean over its runs vs t, with a +-1 sd (or min-max) band."""
    metrics = [metrics] if isinstance(metrics, str) else list(metrics)
    if not metrics:
        raise ValueError("timeseries_figure: no metrics")
    _require(ts, ["run_id", "t"] + metrics, "timeseries_figure")
    plt = pyplot()
    nrows, ncols = _grid_shape(len(metrics), ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 2.6 * nrows + 0.6), sharex=True,
                             squeeze=False, layout="constrained")
    colours = _cell_colours(max(len(cells), 1))
    handles, labels = [], []
    drawn = 0
    for colour, (label, run_ids) in zip(colours, cells.items()):
        sub = ts[ts["run_id"].isin(list(run_ids))]
        n_runs = sub["run_id"].nunique()
        if n_runs == 0:
            warnings.warn(f"timeseries_figure: no time series for cell {label!r}", stacklevel=2)
            continue
        drawn += 1
        for k, metric in enumerate(metrics):
            ax = axes.flat[k]
            stats = sub.groupby("t")[metric].agg(["mean", "std", "count", "min", "max"]).sort_index()
            t = stats.index.to_numpy(float)
            use_sd = stats["count"].to_numpy() >= 3
            low = np.where(use_sd, stats["mean"] - stats["std"], stats["min"])
            high = np.where(use_sd, stats["mean"] + stats["std"], stats["max"])
            ax.fill_between(t, low, high, color=colour, alpha=0.2, linewidth=0)
            (line,) = ax.plot(t, stats["mean"].to_numpy(float), color=colour, linewidth=1.3)
            if k == 0:
                handles.append(line)
                labels.append(f"{label} (n={n_runs})")
    if not drawn:
        plt.close(fig)
        raise ValueError("timeseries_figure: none of the cells has time series in ts")
    for k, metric in enumerate(metrics):
        ax = axes.flat[k]
        ax.set_title(metric_label(metric), fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3, linewidth=0.5)
        if k >= len(metrics) - ncols:
            ax.set_xlabel("time t (s)", fontsize=8)
            ax.xaxis.set_tick_params(labelbottom=True)
    for ax in axes.flat[len(metrics):]:
        ax.set_visible(False)
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(handles), 4), fontsize=7,
               title="band: ±1 sd (min–max where < 3 runs)", title_fontsize=7, frameon=False)
    if title:
        fig.suptitle(title, fontsize=10)
    return save(fig, path)


# -- 4. trace thumbnails ------------------------------------------------------------------------------

def thumbnails_figure(items: list[tuple], path, ncols: int = 3,
                      color_by: str = "auto", wrap_jump: float | None = None, title: str = "") -> Path:
    """A grid of 3-D trace thumbnails; ``items`` are (title, pos (R, N, 3), pattern (N,) or None), or
    the same with a fourth element, a dict of ``draw_traces``' ``obstacles``, ``predator``, ``prey``."""
    checked, scenes = [], []
    for name, pos, pattern, *extra in items:
        scenes.append(extra[0] if extra else {})
        pos = np.asarray(pos, dtype=float)
        if pos.ndim != 3 or pos.shape[2] != 3:
            raise ValueError(f"thumbnails_figure: item {name!r}: pos must be (R, N, 3), got {pos.shape}")
        if pattern is not None:
            pattern = np.asarray(pattern)
            if pattern.shape != (pos.shape[1],):
                raise ValueError(f"thumbnails_figure: item {name!r}: pattern must be ({pos.shape[1]},), "
                                 f"got {pattern.shape}")
        checked.append((name, pos, pattern))
    if not checked:
        raise ValueError("thumbnails_figure: no items")
    plt = pyplot()
    nrows, ncols = _grid_shape(len(checked), ncols)
    fig = plt.figure(figsize=(3.3 * ncols, 3.1 * nrows + 0.3), layout="constrained")
    legend = {}
    for k, (name, pos, pattern) in enumerate(checked):
        mode = "boid" if pattern is None and color_by == "pattern" else color_by
        ax = fig.add_subplot(nrows, ncols, k + 1, projection="3d")
        by_pattern = boid_colours(pos.shape[1], pattern, mode)[1] or {}
        draw_traces(ax, pos, pattern, mode, wrap_jump, str(name), **scenes[k])
        if ax.get_legend() is not None:
            ax.get_legend().remove()
        legend.update(by_pattern)
        ax.tick_params(pad=0)
        ax.xaxis.labelpad = ax.yaxis.labelpad = ax.zaxis.labelpad = -2
    if legend:   # above the panels, for those coloured by pattern only (the others: one colour per boid)
        handles = [plt.Line2D([], [], color=colour, linewidth=2) for colour in legend.values()]
        names = [f"pattern {int(value):08b}" for value in legend]
        fig.legend(handles, names, loc="outside upper center", ncols=min(len(names), 4), frameon=False,
                   title="colour in pattern-mode runs (others: one colour per boid)")
    if title:
        fig.suptitle(title)
    return save(fig, path)


# -- 5. effect sizes ----------------------------------------------------------------------------------

def effect_sizes_figure(tests: pd.DataFrame, path, alpha: float = 0.05, cmap: str = "magma_r",
                        title: str = "") -> Path:
    """Heatmap of epsilon^2 per metric (rows) x factor (columns); significant cells marked."""
    _require(tests, ["metric", "factor", "epsilon2"], "effect_sizes_figure")
    if tests.empty:
        raise ValueError("effect_sizes_figure: no tests to draw")
    plt = pyplot()
    import matplotlib

    metrics = list(pd.unique(tests["metric"]))
    factors = list(pd.unique(tests["factor"]))
    grouped = tests.groupby(["metric", "factor"], sort=False)
    effect = grouped["epsilon2"].mean().unstack("factor").reindex(index=metrics, columns=factors)
    values = effect.to_numpy(float)
    if "p_holm" in tests.columns:
        p = grouped["p_holm"].min().unstack("factor").reindex(index=metrics, columns=factors).to_numpy(float)
        significant = np.nan_to_num(p, nan=1.0) < alpha
    else:
        significant = np.zeros_like(values, dtype=bool)
    finite = values[np.isfinite(values)]
    vmin = min(0.0, float(finite.min())) if finite.size else 0.0
    vmax = max(float(finite.max()), vmin + 1e-3) if finite.size else 1.0
    colormap = matplotlib.colormaps[cmap].with_extremes(bad=NAN_COLOUR)
    norm = matplotlib.colors.Normalize(vmin, vmax)

    nm, nf = len(metrics), len(factors)
    longest_factor = max(len(parameter_label(f)) for f in factors)
    fig, ax = plt.subplots(figsize=(0.85 * nf + 3.2, 0.32 * nm + 1.4 + 0.05 * longest_factor),
                           layout="constrained")
    image = ax.imshow(np.ma.masked_invalid(values), cmap=colormap, norm=norm, aspect="auto",
                      interpolation="nearest")
    for i in range(nm):
        for j in range(nf):
            v = values[i, j]
            colour = _text_colour(colormap(norm(v))) if np.isfinite(v) else "#555555"
            text = ("–" if not np.isfinite(v) else f"{v:.2f}") + ("*" if significant[i, j] else "")
            ax.text(j, i, text, ha="center", va="center", fontsize=7, color=colour,
                    fontweight="bold" if significant[i, j] else "normal", in_layout=False)
            if significant[i, j]:
                ax.add_patch(matplotlib.patches.Rectangle((j - 0.44, i - 0.42), 0.88, 0.84, fill=False,
                                                          edgecolor="#1f77b4", linewidth=1.5))
    ax.set_xticks(range(nf))
    ax.set_xticklabels([parameter_label(f) for f in factors], fontsize=7, rotation=35, ha="right",
                       rotation_mode="anchor")
    ax.set_yticks(range(nm))
    ax.set_yticklabels([metric_label(m) for m in metrics], fontsize=7)
    ax.tick_params(length=2)
    ax.set_xlabel("factor", fontsize=8)
    ax.set_ylabel("metric", fontsize=8)
    ax.set_title(title or f"effect size ε² (* outlined: p_holm < {alpha:g})", fontsize=9)
    bar = fig.colorbar(image, ax=ax, shrink=min(1.0, max(0.4, 6 / max(nm, 1))))
    bar.set_label("ε²", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    return save(fig, path)
