"""``flocksweep report``: what does each factor do to the flock? Statistics, figures and findings from a
sweep's results directory.

``build_report(results_dir, out_dir=None, metrics=None, by=None, formats=("html", "md"), seed=0,
claims_files=())`` writes into ``out_dir`` (default ``<results_dir>/report``), a folder it owns
(:class:`sweeps.owned.OwnedFolder`, record ``.flocksweep-report.json``): a rebuild removes the files of the previous build first, and never
a file it did not write; a non-empty folder it did not write is refused (ConfigError at ``--out``)
before anything is written, except the default folder, whose other files are left alone:

* ``report.html``: self-contained (figures embedded); ``report.md`` with ``figures/*.png`` and ``.svg``;
* ``tables/*.csv``: every table behind the report (tests, main effects, adjacent comparisons, two-way
  tests, cell summaries with CI half-widths, claims and their tests, showcase checks).

The analysis follows the design: grid factors (axes) get the analysis below; the continuous factors
of a ``[design]`` (Saltelli, Morris) or ``[sample]`` block get the sensitivity analysis of
:mod:`analysis.reports.sensitivity_section` (Sobol' or Morris indices, smoothers, partial dependence,
rank correlations), per combination of the grid factors' levels when both are present. Explicit
``[[points]]`` of a sweep (e.g. added by an emulator's refinement) are left out of both.

Sections: overview and provenance; per metric the main effect of every factor (mean and 95% bootstrap
CI over replicates and the other factors), a Kruskal-Wallis test per factor with epsilon squared and
Holm correction over the whole family, a rank-based two-way ANOVA for a pair of factors, adjacent-level
comparisons; heatmaps over field x direction of vision (panels per range, rows per mode and flock size
when swept); time series of chosen cells; 3-D trace thumbnails of the ``[report.showcase]`` runs,
re-simulated from their seeds (and checked against the table), each with an interactive 3-D viewer page
(``viewer/<name>.html``, linked from its still; analysis/viewer); replicate adequacy (CI half-width per
cell); the sweep's claims, tested (its ``[[claims]]`` and included claims files, plus ``claims_files``:
verdicts, evidence figures and power, :mod:`analysis.reports.claims`); with ``leadership.x`` swept, the
leadership metrics against X. Factors and metrics are read from the results, so any sweep works.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.observables.metrics import polarization
from flocksweep.simcore import simulate
from flocksweep.simcore.params import canonical_key
from flocksweep.sweeps.design import rebuild
from flocksweep.sweeps.files import write_text
from flocksweep.sweeps.owned import OwnedFolder
from flocksweep.sweeps.progress import Phases
from flocksweep.sweeps.results import Results, load_results
from flocksweep.sweeps.status import computed
from flocksweep.sweeps.store import ResultsStore

from . import figures, stats
from .document import Figure, Heading, Para, Table, to_html, to_markdown
from .drawing import Figures
from .labels import metric_label, metric_unit, metric_words, parameter_label
from .plain_words import disagreement_note, plain_findings
from .sensitivity import continuous_design, design_runs
from .sensitivity_section import sensitivity_section
from .claims.evaluate import evaluate
from .claims.load import claims_of
from .claims.section import claims_section
from .viewer_pages import viewer_blocks

DEFAULT_METRICS = ("cohesion", "polarization", "stray_fraction", "n_groups", "elongation", "speed_mean")
ALIASES = {"alignment": "polarization", "groups": "n_groups", "stray": "stray_fraction", "speed": "speed_mean",
           "strays": "stray_fraction", "fragmentation": "time_to_fragmentation"}
RANGE = "perception.range"
FIELD = "perception.field_deg"
DIRECTION = "perception.direction_deg"
LEAD = "leadership.x"
REPORT_RECORD = ".flocksweep-report.json"   # the files a build wrote (OwnedFolder)
STALE = ("figures/*.png", "figures/*.svg", "tables/*.csv", "viewer/*.html", "report.md", "report.html")


class ReportError(ValueError):
    pass


def resolve_metrics(results: Results, names) -> list[str]:
    """Metric columns from names like 'cohesion', 'alignment' or full columns like 'cohesion_final'."""
    out = []
    for name in names or DEFAULT_METRICS:
        name = ALIASES.get(name, name)
        column = name if name in results.runs.columns else f"{name}_mean"
        if column not in results.runs.columns:
            raise ReportError(f"--metrics: unknown metric {name!r}; available: "
                              f"{', '.join(sorted({m.rsplit('_', 1)[0] for m in results.metrics}))}")
        out.append(column)
    return out


def label(metric: str) -> str:
    return metric_label(metric)


@dataclass
class Context:
    results: Results
    runs: pd.DataFrame  # ok runs
    metrics: list[str]
    factors: list[str]
    out: Path
    fig_dir: Path
    table_dir: Path
    seed: int
    blocks: list
    tables: dict
    continuous: list = None  # the continuous factors (a [design] or [sample] block's keys)
    cells: list = None       # the runs shown as time series, 3-D traces and viewer pages
    figures: Figures = None  # where _figure's figures are drawn (beside the other sections' work)


def _shown_runs(ctx: Context) -> None:
    """The showcase (or default) runs, re-simulated; their time series."""
    ctx.cells = _showcase_rows(ctx) or _default_cells(ctx)
    _timeseries(ctx, ctx.cells)


def _sections(ctx: Context, continuous, declared) -> list[tuple[str, object]]:
    """The report's sections in order: (name shown in the progress lines, function of the context);
    ``declared`` is ``claims_of``'s answer, read and checked before anything was written."""
    steps = [("overview", _overview), ("claims", lambda c: _claims(c, declared)), ("leadership", _leadership)]
    if continuous and continuous.keys:
        steps.append(("sensitivity analysis", lambda c: sensitivity_section(c, continuous, _figure, _save_table)))
    if ctx.factors or not continuous:
        steps += [("statistics and main effects", lambda c: _metric_sections(c, _statistics(c))),
                  ("heatmaps", _heatmaps)]
    return steps + [("showcase runs re-simulated, time series", _shown_runs),
                    ("3-D traces", lambda c: _thumbnails(c, c.cells)),
                    ("viewer pages", lambda c: c.blocks.extend(viewer_blocks(c.results.path, c.out, c.cells)
                                                               if _resimulable(c) else [])),
                    ("replicate adequacy", _adequacy)]


def _save_table(ctx: Context, name: str, df: pd.DataFrame) -> pd.DataFrame:
    ctx.tables[name] = df
    df.to_csv(ctx.table_dir / f"{name}.csv", index=False)
    return df


def _figure(ctx: Context, name: str, draw, caption: str, svg: bool = True) -> None:
    """Draw a figure as PNG (embedded in the HTML) and, for the light ones, also as SVG (vector copy
    beside the Markdown)."""
    png = ctx.fig_dir / f"{name}.png"
    svg_path = ctx.fig_dir / f"{name}.svg" if svg else None
    # one figure, laid out once, written in both formats; drawn in a child process while the report goes on
    ctx.figures.submit(draw, [png, svg_path] if svg_path else png)
    ctx.blocks.append(Figure(png, caption, svg_path))


def _overview(ctx: Context) -> None:
    r = ctx.results
    m = r.manifest
    runs = r.runs
    n_design = len(r.design)
    ok = int((runs["status"] == "ok").sum())
    failed = int((runs["status"] == "failed").sum())
    ctx.blocks += [Heading(f"Sweep report: {r.name}", 1),
                   Para(m.get("description") or r.sweep.get("description", "")),
                   Heading("Overview"),
                   Para(f"**{n_design}** runs in the design: **{ok}** ok, **{failed}** failed, "
                        f"**{n_design - ok - failed}** missing. Replicates per cell: "
                        f"{m.get('replicates', '?')}; sweep seed {m.get('seed', '?')}; common random numbers: "
                        f"{m.get('common_random_numbers', False)}.")]
    levels = pd.DataFrame([{"factor": f, "levels": len(r.levels(f)), "values": _levels_text(r.levels(f))}
                           for f in r.factors])
    ctx.blocks.append(Table(_save_table(ctx, "design", levels), "Factors and levels"))
    pkgs = m.get("packages", {})
    prov = pd.DataFrame([
        {"item": "config hash", "value": m.get("config_hash")},
        {"item": "git revision", "value": m.get("git_revision")},
        {"item": "model version", "value": m.get("model_version")},
        {"item": "results computed", "value": computed(m)},
        {"item": "executor / workers", "value": f"{m.get('executor')} / {m.get('workers')}"},
        {"item": "machine", "value": str(m.get("machine", {}).get("platform"))},
        {"item": "packages", "value": ", ".join(f"{k} {v}" for k, v in pkgs.items() if v)}])
    ctx.blocks.append(Table(prov, "Provenance"))
    if failed:
        fails = runs[runs["status"] == "failed"][["run_id", "error"] + r.factors].head(20)
        ctx.blocks.append(Table(fails, "Failed runs (first 20)"))


def _levels_text(levels: list, most: int = 12) -> str:
    if len(levels) > most and all(isinstance(v, (int, float, np.number)) for v in levels):
        return f"continuous: {len(levels)} values from {_short(min(levels))} to {_short(max(levels))}"
    return ", ".join(map(_short, levels))


def _short(value) -> str:
    if isinstance(value, (float, np.floating)) and float(value).is_integer():
        return str(int(value))
    return str(value)


def _statistics(ctx: Context) -> dict:
    report = stats.factor_report(ctx.runs, ctx.factors, ctx.metrics, seed=ctx.seed)
    tests = _save_table(ctx, "factor_tests", report["tests"])
    effects = _save_table(ctx, "main_effects", report["main_effects"])
    adjacent = _save_table(ctx, "adjacent_comparisons", report["adjacent"])
    pair = _two_way_pair(ctx)
    two_way = []
    if pair:
        for metric in ctx.metrics:
            table = stats.two_way_test(ctx.runs, pair[0], pair[1], metric)
            table.insert(0, "metric", metric)
            two_way.append(table)
    two_way = _save_table(ctx, "two_way_tests", pd.concat(two_way, ignore_index=True) if two_way else pd.DataFrame())
    return {"tests": tests, "effects": effects, "adjacent": adjacent, "two_way": two_way, "pair": pair}


def _two_way_pair(ctx: Context):
    if FIELD in ctx.factors and DIRECTION in ctx.factors:
        return FIELD, DIRECTION
    return tuple(ctx.factors[:2]) if len(ctx.factors) >= 2 else None


def _plain_words(ctx: Context, st: dict) -> pd.DataFrame:
    """The section that answers first: what each factor does to each metric, in a sentence each
    (:mod:`analysis.reports.plain_words`), and a note where a trend and an omnibus test disagree."""
    findings = _save_table(ctx, "findings", plain_findings(ctx.runs, st["tests"], st["effects"], ctx.factors,
                                                           ctx.metrics))
    ctx.blocks.append(Heading("What each factor does, in plain words"))
    ctx.blocks.append(Para("A sentence per metric and factor: the change of the metric's mean from the lowest to "
                           "the highest level (a numeric factor, with its trend test) or between the levels with "
                           "the smallest and largest mean; p-values Holm-adjusted over the report's family. Details "
                           "and figures follow per metric; every row is in `tables/findings.csv`."))
    for metric in ctx.metrics:
        rows = findings[findings["metric"] == metric]
        clear = [r.sentence for r in rows.itertuples() if r.finding != "no clear effect"]
        unclear = [parameter_label(r.factor) for r in rows.itertuples() if r.finding == "no clear effect"]
        text = " ".join(clear) if clear else "No factor has a clear effect."
        if unclear and clear:
            text += f" No clear effect: {', '.join(unclear)}."
        ctx.blocks.append(Para(f"**{label(metric)}**: {text}"))
    note = disagreement_note(findings)
    if note:
        ctx.blocks.append(Para(note))
    return findings


def _metric_sections(ctx: Context, st: dict) -> None:
    findings = _plain_words(ctx, st)
    ctx.blocks.append(Heading("Which factor matters for which metric"))
    ctx.blocks.append(Para("Kruskal-Wallis test per factor and metric (runs pooled over the other factors), "
                           "effect size epsilon squared, p-values Holm-adjusted over the whole family."))
    _figure(ctx, "effect_sizes", lambda p: figures.effect_sizes_figure(st["tests"], p),
            "Effect size (epsilon squared) of each factor on each metric; marked cells are significant "
            "after Holm correction.")
    for metric in ctx.metrics:
        ctx.blocks.append(Heading(f"{label(metric)} (`{metric}`)"))
        said = findings[findings["metric"] == metric]["sentence"]
        if len(said):
            ctx.blocks.append(Para(" ".join(said)))
        effects = st["effects"][st["effects"]["metric"] == metric]
        _figure(ctx, f"main_effects_{metric}", lambda p, e=effects: figures.main_effects_figure(e, metric, p),
                f"Main effects on {label(metric)}: mean and 95% bootstrap CI per level.")
        tests = st["tests"][st["tests"]["metric"] == metric]
        ctx.blocks.append(Table(_worded(tests.drop(columns=["metric"])), f"Kruskal-Wallis per factor: {label(metric)}"))
        if st["pair"] and len(st["two_way"]):
            tw = st["two_way"][st["two_way"]["metric"] == metric].drop(columns=["metric"])
            tw = tw.assign(source=tw["source"].map(lambda v: " x ".join(parameter_label(f) for f in str(v).split(":"))))
            ctx.blocks.append(Table(tw, f"Rank-based two-way ANOVA, {parameter_label(st['pair'][0])} x "
                                        f"{parameter_label(st['pair'][1])}: {label(metric)}"))
        adj = st["adjacent"][st["adjacent"]["metric"] == metric].drop(columns=["metric"])
        ctx.blocks.append(Table(_worded(adj), f"Adjacent levels compared (Mann-Whitney, Cliff's delta, Holm): "
                                              f"{label(metric)}", max_rows=30))


def _worded(table: pd.DataFrame) -> pd.DataFrame:
    """A table as shown: its factor column in words and units (the CSV keeps the keys)."""
    return table.assign(factor=table["factor"].map(parameter_label)) if "factor" in table else table


def _cells(ctx: Context, metric: str, factors: list[str]) -> pd.DataFrame:
    return stats.cell_summary(ctx.runs, factors, metric)


def _heatmaps(ctx: Context) -> None:
    if FIELD in ctx.factors and DIRECTION in ctx.factors:
        x, y = FIELD, DIRECTION
    elif len(ctx.factors) >= 2:
        x, y = ctx.factors[0], ctx.factors[1]
    else:
        return
    panel = RANGE if RANGE in ctx.factors and RANGE not in (x, y) else None
    rows = [f for f in ctx.factors if f not in (x, y, panel)][:2] or None
    ctx.blocks.append(Heading(f"Heatmaps over {parameter_label(x)} x {parameter_label(y)}"))
    ctx.blocks.append(Para("Mean over replicates per cell" + (f"; one panel per {parameter_label(panel)}" if panel else "")
                           + (f"; one row per {' and '.join(map(parameter_label, rows))}" if rows else "") + "."))
    by = [f for f in (x, y, panel) if f] + (rows or [])
    for metric in ctx.metrics:
        cells = _cells(ctx, metric, by)
        _figure(ctx, f"heatmap_{metric}",
                lambda p, c=cells, m=metric: figures.heatmap_figure(c, m, x, y, p, panel=panel, rows=rows),
                f"{label(metric)} over {parameter_label(x)} (columns) and {parameter_label(y)} (rows).", svg=False)


def _showcase_rows(ctx: Context) -> list[tuple[str, pd.DataFrame]]:
    showcase = ctx.results.sweep.get("report", {}).get("showcase", {})
    out = []
    for name, where in showcase.items():
        mask = np.ones(len(ctx.runs), dtype=bool)
        for column, value in where.items():
            column = canonical_key(column)
            if column not in ctx.runs:
                mask[:] = False
                break
            mask &= (ctx.runs[column] == value).to_numpy()
        if mask.any():
            out.append((name, ctx.runs[mask]))
    return out


def _default_cells(ctx: Context) -> list[tuple[str, pd.DataFrame]]:
    metric = "cohesion_mean" if "cohesion_mean" in ctx.runs else ctx.metrics[0]
    factors = list(ctx.factors) + list(ctx.continuous or [])
    if not factors:
        return [("all runs", ctx.runs)]
    means = ctx.runs.groupby(factors, dropna=False)[metric].mean().dropna().sort_values()
    if means.empty:
        return []
    picks = {"lowest " + metric: means.index[0], "median " + metric: means.index[len(means) // 2],
             "highest " + metric: means.index[-1]}
    out = []
    for name, key in picks.items():
        key = key if isinstance(key, tuple) else (key,)
        mask = np.ones(len(ctx.runs), dtype=bool)
        for f, v in zip(factors, key):
            mask &= (ctx.runs[f] == v).to_numpy()
        out.append((name, ctx.runs[mask]))
    return out


def _timeseries(ctx: Context, cells: list[tuple[str, pd.DataFrame]]) -> None:
    if not cells:
        return
    run_ids = [rid for _, rows in cells for rid in rows["run_id"]]
    ts = ResultsStore(ctx.results.path).timeseries(run_ids)
    if ts.empty:
        return
    names = [m[:-5] for m in ctx.metrics if m.endswith("_mean") and m[:-5] in ts.columns]
    ctx.blocks.append(Heading("Time series of chosen cells"))
    mapping = {name: list(rows["run_id"]) for name, rows in cells}
    _figure(ctx, "timeseries", lambda p: figures.timeseries_figure(ts, mapping, names, p),
            "Metrics over time (mean over the cell's replicates, band: +-1 sd or min-max).")


def _resimulable(ctx: Context) -> bool:
    """Whether the sweep's runs can be re-simulated: not those of an external command (sweeps.external),
    whose output was measured and not kept."""
    return "command" not in ResultsStore(ctx.results.path).model()


def _thumbnails(ctx: Context, cells: list[tuple[str, pd.DataFrame]]) -> None:
    record = ResultsStore(ctx.results.path).model()
    if not record or not cells or not _resimulable(ctx):
        return
    items, checks = [], []
    for name, rows in cells:
        row = rows.sort_values("replicate").iloc[0].to_dict()
        preset, _ = rebuild(record, row)
        run = preset.run
        every = math.gcd(run.record_every, 6)
        obs = simulate(preset.model, preset.init, int(row["seed"]), run.duration, run.dt, every)
        final = float(polarization(obs.vel[-1]))
        stored = float(row.get("polarization_final", float("nan")))
        checks.append({"showcase": name, "run_id": row["run_id"], "seed": int(row["seed"]),
                       "final_polarization_resimulated": final, "final_polarization_in_table": stored,
                       "identical": final == stored})
        pattern = obs.pattern if len(np.unique(obs.pattern)) > 1 else None
        scene = {"obstacles": preset.model.world.obstacles, "predator": obs.predator, "prey": obs.prey}
        items.append((f"{name}: cohesion {row.get('cohesion_mean', float('nan')):.2f}", obs.pos, pattern, scene))
    ctx.blocks.append(Heading("Showcase runs"))
    ctx.blocks.append(Para("Each run is re-simulated from its seed and resolved parameters; the table below "
                           "checks that the re-simulation reproduces the stored final polarization bit for bit."))
    _figure(ctx, "showcase_traces", lambda p: figures.thumbnails_figure(items, p),
            "3-D traces of the showcase runs (replicate 0 of each cell).", svg=False)
    ctx.blocks.append(Table(_save_table(ctx, "showcase_checks", pd.DataFrame(checks)), "Re-simulation check"))


def _adequacy(ctx: Context) -> None:
    if not ctx.factors:
        return
    rows = []
    summaries = []
    for metric in ctx.metrics:
        cells = _cells(ctx, metric, ctx.factors)
        cells.insert(0, "metric", metric)
        summaries.append(cells)
        hw = cells["ci_halfwidth"]
        bounded = hw[np.isfinite(hw)]   # a cell with n < 2 has no finite bound (+inf)
        rows.append({"metric": metric, "cells": len(cells), "replicates (median)": cells["n"].median(),
                     "CI half-width median": hw.median(), "CI half-width max": bounded.max(),
                     "cells without CI (n < 2)": int((cells["n"] < 2).sum())})
    _save_table(ctx, "cell_summaries", pd.concat(summaries, ignore_index=True))
    ctx.blocks.append(Heading("Replicate adequacy"))
    ctx.blocks.append(Para("Half-width of the 95% Student-t confidence interval of each cell's mean over its "
                           "replicates (all cells in `tables/cell_summaries.csv`). To add replicates only where "
                           "needed: `flocksweep run SWEEP --until-ci METRIC=HALFWIDTH --max-replicates R`."))
    ctx.blocks.append(Table(pd.DataFrame(rows), "CI half-width per metric over cells"))


def _claims(ctx: Context, declared) -> None:
    """The sweep's declared claims (and those of the claims files), ``claims_of``'s answer, tested on the
    ok runs."""
    claims, columns, skipped = declared
    outcomes = evaluate(claims, ctx.runs, columns.factors, seed=ctx.seed)
    blocks, tables = claims_section(outcomes, ctx.fig_dir, ctx.seed)
    for name, table in tables.items():
        _save_table(ctx, name, table)
    ctx.blocks += blocks
    if skipped:
        ctx.blocks.append(Para("Not tested (the stored results lack what they name; rerun the sweep with "
                               "`--force` to recompute them): " + "; ".join(f"({i}) {why}" for i, why in skipped)
                               + "."))


LEADERSHIP_METRICS = ("trigger_rate", "leaders_mean", "leader_time_fraction", "follow_corr_max",
                      "follow_lag_max", "heading_change_deg", "n_groups_mean", "cohesion_mean",
                      "stray_fraction_mean", "polarization_mean")


def _leadership(ctx: Context) -> None:
    """Change of leadership: metrics against X with bootstrap CIs, and Hartman & Benes' claims."""
    if LEAD not in ctx.factors or "trigger_rate" not in ctx.runs:
        return
    metrics = [m for m in LEADERSHIP_METRICS if m in ctx.runs and ctx.runs[m].notna().any()]
    effects = []
    for metric in metrics:
        table = stats.main_effect(ctx.runs, LEAD, metric, n_resamples=1000, seed=ctx.seed)
        effects.append(table.assign(factor=metric, metric=metric))
    effects = _save_table(ctx, "leadership_effects", pd.concat(effects, ignore_index=True))
    ctx.blocks.append(Heading("Change of leadership"))
    ctx.blocks.append(Para("Leadership metrics against X, mean and 95% bootstrap CI over replicates and the other "
                           "factors (definitions in `docs/metrics.md`): trigger events per boid per minute, "
                           "simultaneous leaders, the follow response (heading correlation between a leader and "
                           "its group after a trigger, at its best lag), the group's turn over an escape, and "
                           "fragmentation."))
    _figure(ctx, "leadership_vs_x",
            lambda p: figures.main_effects_figure(effects, "", p, ncols=5, sharey=False,
                                                  xlabel=parameter_label(LEAD), panel_title=metric_words,
                                                  panel_ylabel=lambda m: metric_unit(m) or "(no unit)"),
            "Leadership metrics against X (mean and 95% CI). Hartman & Benes' findings are tested as claims "
            "(configs/claims/hartman_benes.toml) when the sweep includes them.")


def build_report(results_dir, out_dir=None, metrics=None, by=None, formats=("html", "md"), seed: int = 0,
                 claims_files=(), progress: bool = False) -> dict:
    """Write a sweep's report (``flocksweep report``; docs/report.md): statistics, figures, tested claims.

    Parameters
    ----------
    results_dir : str or pathlib.Path
        The sweep's results directory.
    out_dir : str or pathlib.Path, optional
        Where the report goes (default ``results_dir/report``).
    metrics : list of str, optional
        Metric names (``cohesion``) or columns (``cohesion_final``); default: the standard set.
    by : list of str, optional
        Factors to analyse (default: every swept factor).
    formats : tuple of str, default ("html", "md")
        ``"html"`` (self-contained page) and/or ``"md"`` (Markdown with figure files).
    seed : int, default 0
        Seed of the bootstrap resampling and of the claims' power simulations.
    claims_files : sequence of path, optional
        Claims files (or sweep files) whose claims are tested too.
    progress : bool, default False
        Print each section on stderr as it starts (``report: [3/11] heatmaps (12 s so far)``).

    Returns
    -------
    dict
        ``paths`` (format -> written file), ``tables`` (name -> DataFrame, also written as CSV), ``out``
        (the report folder) and ``seconds``.
    """
    started = time.perf_counter()
    results = load_results(results_dir)
    if results.ok.empty:
        raise ReportError(f"{results_dir}: no finished runs to report on")
    continuous = continuous_design(results)
    continuous_keys = list(continuous.keys) if continuous else []
    factors = list(by) if by else [f for f in results.factors if f not in continuous_keys]
    for f in factors:
        if f not in results.runs.columns:
            raise ReportError(f"--by: unknown factor {f!r}; factors of this sweep: {', '.join(results.factors)}")
    default = results.path / "report"
    out = Path(out_dir) if out_dir else default
    metric_columns = resolve_metrics(results, metrics)
    declared = claims_of(results, claims_files)   # every input read and checked before anything is written
    owned = OwnedFolder(out, REPORT_RECORD, adopt=out.resolve() == default.resolve()).claim()
    ctx = Context(results, design_runs(results), metric_columns, factors, out,
                  out / "figures", out / "tables", seed, [], {}, continuous_keys)
    for stale in owned.stale(STALE):
        stale.unlink()  # a rebuilt report holds only what this build wrote (never a file it did not write)
    for folder in (ctx.fig_dir, ctx.table_dir):
        folder.mkdir(parents=True, exist_ok=True)
    steps = _sections(ctx, continuous, declared)
    phases = Phases("report", len(steps) + 2, progress)
    with Figures() as ctx.figures:
        for name, step in steps:
            phases.start(name)
            step(ctx)
        phases.start("the last figures")
        ctx.figures.wait()
    phases.start("writing " + " and ".join(formats))
    written = {}
    if "md" in formats:
        written["md"] = out / "report.md"
        write_text(written["md"], to_markdown(ctx.blocks, out))
    if "html" in formats:
        written["html"] = out / "report.html"
        write_text(written["html"], to_html(ctx.blocks, f"flocksweep report: {results.name}"))
    phases.done()
    owned.finish()
    return {"paths": written, "tables": ctx.tables, "seconds": time.perf_counter() - started, "out": out}
