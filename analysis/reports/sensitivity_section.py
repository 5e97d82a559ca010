"""The report's sensitivity-analysis section for a sweep's continuous factors (a ``[design]`` or
``[sample]`` block), chosen by :mod:`analysis.reports.report` from the design kind.

``sensitivity_section(ctx, design, figure, save_table)`` appends blocks to ``ctx.blocks`` and tables
(``sobol_indices``, ``morris_indices``, ``rank_correlations``, ``partial_dependence``) through the
report's ``figure(ctx, name, draw, caption)`` and ``save_table(ctx, name, frame)``; ``ctx`` holds
``runs`` (the ok runs), ``metrics``, ``factors`` (the grid factors: the analysis is done per
combination of their levels, a "stratum") and ``seed``. What it computes is
:mod:`analysis.reports.sensitivity`; figures :mod:`analysis.reports.sensitivity_figures`.

* Saltelli designs: Sobol' first-order and total indices with 95% bootstrap CIs, factors ranked by
  their total index, and a plain sentence per metric naming the ranking and the interactions
  (1 - sum of S1).
* Morris designs: mu*, its CI, and sigma.
* Every continuous design: point means against each factor with a smoothing spline (beyond
  ``MAX_SCATTER_POINTS`` points the figure draws that many, at random, and says so; the spline uses
  all), partial dependence of a boosted-trees fit (with its cross-validated R^2; fitted to at most
  ``sensitivity.MAX_FIT_POINTS`` points, said in the caption), Spearman and PRCC with CIs. For a
  Saltelli design the correlations use the independent base matrices A and B only.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from . import sensitivity_figures as figs
from .document import Heading, Para, Table
from .labels import metric_label, parameter_label
from .sensitivity import (MAX_FIT_POINTS, ContinuousDesign, correlations, morris_indices, noise_share,
                          partial_dependence, point_means, sample_outputs, smoother, sobol_indices, subsample)

MAX_STRATA_FIGURES = 4
MAX_SCATTER_POINTS = 3000   # a scatter figure draws at most this many design points (drawn at random)


def _strata(runs: pd.DataFrame, grid: list[str]):
    if not grid:
        yield "", {}, runs
        return
    for values, rows in runs.groupby(grid, sort=True, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        where = dict(zip(grid, values))
        yield ", ".join(f"{k} = {v}" for k, v in where.items()), where, rows


def _independent_rows(design: ContinuousDesign) -> np.ndarray:
    """Row mask of the sample rows that are independent draws: A and B of a Saltelli design, all else."""
    rows = len(design.rows)
    if design.kind != "saltelli":
        return np.ones(rows, dtype=bool)
    spec = design.design
    size = (2 * spec.d + 2) if spec.second_order else (spec.d + 2)
    position = np.arange(rows) % size
    return (position == 0) | (position == size - 1)


def _ci(value, low, high) -> str:
    return f"{value:.3f} [{low:.3f}, {high:.3f}]" if math.isfinite(value) else "n/a"


def _ranking_sentence(metric: str, table: pd.DataFrame, stratum: str) -> str:
    order = "; ".join(f"{parameter_label(r.factor)} ST {_ci(r.ST, r.ST_low, r.ST_high)}" for r in table.itertuples())
    interactions = 1.0 - float(table["S1"].clip(lower=0).sum())
    where = f" ({stratum})" if stratum else ""
    return (f"**{metric_label(metric)}**{where}: factors by total index: {order}. First-order indices sum to "
            f"{1 - interactions:.2f}, so about {max(interactions, 0):.0%} of the variance comes from interactions "
            "(or run-to-run noise).")


def _indices(ctx, design: ContinuousDesign, stratum: str, where: dict, runs: pd.DataFrame, out: dict) -> None:
    for metric in ctx.metrics:
        X, Y = sample_outputs(design, runs, metric)
        if design.kind == "saltelli":
            table, note = sobol_indices(design, Y, ctx.seed)
            out["sobol"].append(table.assign(metric=metric, **where, noise_share=noise_share(runs, design.keys, metric)))
        else:
            table, note = morris_indices(design, X, Y, ctx.seed)
            out["morris"].append(table.assign(metric=metric, **where))
        if note:
            out["notes"].append(f"{metric_label(metric)} {stratum}: {note}")
        independent = _independent_rows(design)
        corr = correlations(X[independent], Y[independent], design.keys)
        out["corr"].append(corr.assign(metric=metric, **where))


def _sampled_correlations(ctx, design: ContinuousDesign, where: dict, runs: pd.DataFrame, out: dict) -> None:
    for metric in ctx.metrics:
        means = point_means(runs, design.keys, metric)
        corr = correlations(means[design.keys].to_numpy(float), means["mean"].to_numpy(float), design.keys)
        out["corr"].append(corr.assign(metric=metric, **where))


def _intro(ctx, design: ContinuousDesign) -> None:
    bounds = ", ".join(parameter_label(k) for k in design.keys)
    what = {"saltelli": "a Saltelli design (Sobol' sequence, SALib): Sobol' first-order and total indices",
            "morris": "a Morris design (elementary effects, SALib): mu* and sigma"}.get(
        design.kind, f"a sampled design ({design.kind}): no variance-based indices, which need a Saltelli or "
                     "Morris design")
    strata = f" The analysis is done separately for every combination of the grid factors {', '.join(ctx.factors)}." \
        if ctx.factors else ""
    ctx.blocks += [Heading("Sensitivity analysis of the continuous factors"),
                   Para(f"Continuous factors: {bounds}. The sweep is {what}; for every continuous design, "
                        "point means against each factor with a smoothing spline, partial dependence and rank "
                        "correlations (Spearman, PRCC) with 95% confidence intervals. Each design point's output "
                        f"is the mean over its replicates.{strata}")]


def _index_blocks(ctx, design, out, figure, save_table, strata_labels) -> None:
    if design.kind == "saltelli" and out["sobol"]:
        table = save_table(ctx, "sobol_indices", pd.concat(out["sobol"], ignore_index=True))
        ctx.blocks.append(Heading("Sobol' indices", 3))
        ctx.blocks.append(Para("ST is the share of the output variance a factor is involved in (alone or with "
                               "others); S1 its share alone. Intervals: 95% bootstrap CIs (SALib). Run-to-run noise "
                               "left in the point means raises every ST and lowers every S1 by up to the "
                               "`noise_share` column."))
        for stratum, where in strata_labels:
            rows = _in_stratum(table, where)
            for metric in ctx.metrics:
                block = rows[rows["metric"] == metric]
                if len(block):
                    ctx.blocks.append(Para(_ranking_sentence(metric, block, stratum)))
        shown = table[["metric", *ctx.factors, "factor", "rank", "ST", "ST_low", "ST_high", "S1", "S1_low",
                       "S1_high", "noise_share"]]
        ctx.blocks.append(Table(shown.assign(factor=shown["factor"].map(parameter_label)),
                                "Sobol' indices, factors ranked by total index", max_rows=80))
        for k, (stratum, where) in enumerate(strata_labels[:MAX_STRATA_FIGURES]):
            rows = _in_stratum(table, where)
            figure(ctx, f"sobol_indices{k or ''}", lambda p, r=rows: figs.sobol_figure(r, p),
                   f"Sobol' total (ST) and first-order (S1) indices with 95% CIs{': ' + stratum if stratum else ''}.")
    if design.kind == "morris" and out["morris"]:
        table = save_table(ctx, "morris_indices", pd.concat(out["morris"], ignore_index=True))
        ctx.blocks.append(Heading("Morris elementary effects", 3))
        ctx.blocks.append(Para("mu* (mean absolute elementary effect, in the metric's units per full factor "
                               "range over the grid step) ranks the factors; sigma large against mu* means a "
                               "non-linear effect or interactions. Intervals: 95% bootstrap CIs of mu* (SALib)."))
        ctx.blocks.append(Table(table.assign(factor=table["factor"].map(parameter_label)), "Morris statistics",
                                max_rows=80))
        for k, (stratum, where) in enumerate(strata_labels[:MAX_STRATA_FIGURES]):
            rows = _in_stratum(table, where)
            figure(ctx, f"morris{k or ''}", lambda p, r=rows: figs.morris_figure(r, p),
                   f"Morris sigma against mu*{': ' + stratum if stratum else ''}.")


def _shape_blocks(ctx, design: ContinuousDesign, strata, figure, save_table) -> None:
    """Scatter with smoother and partial dependence per metric (first strata only)."""
    curves_all = []
    ctx.blocks.append(Heading("How each metric depends on each continuous factor", 3))
    for k, (stratum, where, runs) in enumerate(strata[:MAX_STRATA_FIGURES]):
        suffix = f" ({stratum})" if stratum else ""
        for metric in ctx.metrics:
            means = point_means(runs, design.keys, metric)
            smooth = {key: smoother(means[key], means["mean"]) for key in design.keys}
            shown = means.iloc[subsample(len(means), MAX_SCATTER_POINTS, ctx.seed)]
            drawn = (f" ({len(shown):,} of the {len(means):,} points drawn at random; the spline uses all)"
                     if len(shown) < len(means) else "")
            figure(ctx, f"scatter_{metric}{k or ''}",
                   lambda p, m=shown, s=smooth, mt=metric: figs.scatter_figure(m, design.keys, mt, p, s),
                   f"{metric_label(metric)}: design-point means against each factor with a smoothing spline"
                   f"{drawn}{suffix}.", svg=False)
            finite = int(np.isfinite(means["mean"].to_numpy(float)).sum())
            curves, r2 = partial_dependence(means[design.keys].to_numpy(float), means["mean"].to_numpy(float),
                                            design.keys, ctx.seed)
            fitted = (f", fitted to {MAX_FIT_POINTS:,} of the {finite:,} points drawn at random"
                      if finite > MAX_FIT_POINTS else "")
            if len(curves):
                curves_all.append(curves.assign(metric=metric, r2=r2, **where))
                figure(ctx, f"partial_dependence_{metric}{k or ''}",
                       lambda p, c=curves, mt=metric, q=r2: figs.partial_dependence_figure(c, mt, p, q),
                       f"{metric_label(metric)}: partial dependence on each factor (boosted trees{fitted}, "
                       f"cross-validated R^2 = {r2:.2f}){suffix}.")
    if curves_all:
        save_table(ctx, "partial_dependence", pd.concat(curves_all, ignore_index=True))


def sensitivity_section(ctx, design: ContinuousDesign, figure, save_table) -> None:
    """Append the sensitivity-analysis section (see the module docstring)."""
    _intro(ctx, design)
    strata = list(_strata(ctx.runs, list(ctx.factors)))
    out = {"sobol": [], "morris": [], "corr": [], "notes": []}
    for stratum, where, runs in strata:
        if design.kind in ("saltelli", "morris"):
            _indices(ctx, design, stratum, where, runs, out)
        else:
            _sampled_correlations(ctx, design, where, runs, out)
    labels = [(stratum, where) for stratum, where, _ in strata]
    _index_blocks(ctx, design, out, figure, save_table, labels)
    for note in out["notes"]:
        ctx.blocks.append(Para(f"Note: {note}."))
    corr = save_table(ctx, "rank_correlations", pd.concat(out["corr"], ignore_index=True))
    ctx.blocks.append(Heading("Rank correlations", 3))
    ctx.blocks.append(Para("Spearman's rho (monotone association) and the partial rank correlation coefficient "
                           "(PRCC: the association left after the other factors' ranks are regressed out), with "
                           "Fisher-z 95% CIs and p-values" +
                           (" over the independent base rows A and B of the Saltelli sample." if design.kind == "saltelli"
                            else " over the design points.")))
    ctx.blocks.append(Table(corr.assign(factor=corr["factor"].map(parameter_label)), "Rank correlations",
                            max_rows=80))
    for k, (stratum, where) in enumerate(labels[:MAX_STRATA_FIGURES]):
        rows = _in_stratum(corr, where)
        figure(ctx, f"rank_correlations{k or ''}", lambda p, r=rows: figs.correlation_figure(r, p),
               f"PRCC and Spearman's rho with 95% CIs{': ' + stratum if stratum else ''}.")
    _shape_blocks(ctx, design, strata, figure, save_table)


def _in_stratum(table: pd.DataFrame, where: dict) -> pd.DataFrame:
    """The rows of ``table`` at one combination of the grid factors' levels (``{column: level}``)."""
    for key, value in where.items():
        table = table[table[key] == value]
    return table
