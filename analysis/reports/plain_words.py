"""What each factor does to each metric, in plain words: the report's answer before its tables.

``plain_findings(runs, tests, effects, factors, metrics) -> DataFrame`` gives one row per (metric,
factor): ``metric, factor, kind`` (``trend`` for a numeric factor of 3 or more levels, else
``levels``), ``low_level, high_level`` (the levels compared: the lowest and highest for a numeric factor;
the levels with the smallest and largest mean otherwise), ``low_mean, high_mean, change`` (high - low),
``kw_p_holm`` (the Kruskal-Wallis test of the report, Holm-adjusted over its family), ``trend_rho,
trend_p, trend_p_holm`` (Spearman's rank correlation between the factor's value and the metric over runs,
Holm-adjusted over the report's trend tests; blank for ``levels``), ``finding`` (``raises``, ``lowers``,
``changes`` (not steadily), ``differs``, ``no clear effect``), ``disagree`` (the trend test and the
Kruskal-Wallis test reach different verdicts at 0.05) and ``sentence``::

    field of vision phi raises cohesion (share in the largest group): +0.131 from 30 to 180 deg (trend:
    Spearman rho 0.15, p (Holm) 0.0011; any level differing: Kruskal-Wallis p (Holm) 0.15).

``disagreement_note(rows)`` is the paragraph shown wherever a trend test and an omnibus test disagree:
they answer different questions. The trend test asks "does the metric move one way as the factor
grows?" and spends all its power on that one pattern; the Kruskal-Wallis test asks "does any level
differ from the others, in any pattern?" and spreads its power over every pattern. A steady but modest
trend is therefore often significant by the first and not by the second; an effect that rises and falls
again, the reverse. A claim tested as a trend (docs/claims.md) asks the first question.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from .labels import metric_unit, metric_words, parameter_unit, parameter_words
from .stats import holm, monotone_trend

ALPHA = 0.05
COLUMNS = ["metric", "factor", "kind", "low_level", "high_level", "low_mean", "high_mean", "change",
           "kw_p_holm", "trend_rho", "trend_p", "trend_p_holm", "finding", "disagree", "sentence"]


def _numeric(levels) -> bool:
    return len(levels) >= 3 and all(isinstance(v, (int, float, np.integer, np.floating))
                                    and not isinstance(v, (bool, np.bool_)) for v in levels)


def _fmt(value) -> str:
    if isinstance(value, (float, np.floating)):
        return str(int(value)) if float(value).is_integer() else f"{float(value):.3g}"
    return str(value)


def _p(p) -> str:
    return "n/a" if not np.isfinite(p) else f"{p:.2g}"


def _row(runs, tests, effects, factor: str, metric: str) -> dict:
    block = effects[(effects["metric"] == metric) & (effects["factor"] == factor)].dropna(subset=["mean"])
    test = tests[(tests["metric"] == metric) & (tests["factor"] == factor)]
    kw = float(test["p_holm"].iloc[0]) if len(test) and "p_holm" in test else np.nan
    levels = list(block["level"])
    row = dict.fromkeys(COLUMNS, np.nan) | {"metric": metric, "factor": factor, "kw_p_holm": kw,
                                            "disagree": False}
    if len(block) < 2:
        return row | {"kind": "levels", "finding": "no clear effect"}
    if _numeric(levels):
        ordered = block.assign(_x=block["level"].astype(float)).sort_values("_x")
        low, high = ordered.iloc[0], ordered.iloc[-1]
        trend = monotone_trend(runs, factor, metric)
        row |= {"kind": "trend", "trend_rho": trend["rho"], "trend_p": trend["p"]}
    else:
        ordered = block.sort_values("mean")
        low, high = ordered.iloc[0], ordered.iloc[-1]
        row |= {"kind": "levels"}
    return row | {"low_level": low["level"], "high_level": high["level"], "low_mean": float(low["mean"]),
                  "high_mean": float(high["mean"]), "change": float(high["mean"] - low["mean"])}


def _judge(row: dict) -> dict:
    kw_sig = np.isfinite(row["kw_p_holm"]) and row["kw_p_holm"] < ALPHA
    if row["kind"] == "trend":
        trend_sig = np.isfinite(row["trend_p_holm"]) and row["trend_p_holm"] < ALPHA
        if trend_sig:
            finding = "raises" if row["trend_rho"] > 0 else "lowers"
        else:
            finding = "changes" if kw_sig else "no clear effect"
        return row | {"finding": finding, "disagree": bool(trend_sig != kw_sig)}
    return row | {"finding": "differs" if kw_sig else "no clear effect"}


def _sentence(row: dict) -> str:
    factor, metric = row["factor"], row["metric"]
    f_words, f_unit = parameter_words(factor), parameter_unit(factor)
    m_words, m_unit = metric_words(metric), metric_unit(metric)
    m_unit = f" {m_unit}" if m_unit else ""
    f_unit = f" {f_unit}" if f_unit else ""
    kw = f"Kruskal-Wallis p (Holm) {_p(row['kw_p_holm'])}"
    if not np.isfinite(row.get("change", np.nan)):
        return f"{f_words}: no clear effect on {m_words} (too few levels with runs)."
    low, high = _fmt(row["low_level"]), _fmt(row["high_level"])
    change = f"{row['change']:+.3g}{m_unit}"
    if row["kind"] == "trend":
        trend = f"Spearman rho {row['trend_rho']:.2f}, p (Holm) {_p(row['trend_p_holm'])}"
        if row["finding"] in ("raises", "lowers") and np.sign(row["change"]) != np.sign(row["trend_rho"]):
            return (f"{f_words} {row['finding']} {m_words} over its levels as a whole (trend: {trend}; any level "
                    f"differing: {kw}), but not steadily: the mean at {high}{f_unit} is {change} from that at {low}.")
        if row["finding"] in ("raises", "lowers"):
            return (f"{f_words} {row['finding']} {m_words}: {change} from {low} to {high}{f_unit} (trend: {trend}; "
                    f"any level differing: {kw}).")
        if row["finding"] == "changes":
            return (f"{f_words} changes {m_words}, but not steadily one way: {change} from {low} to {high}{f_unit}, "
                    f"the levels differ ({kw}) without a monotone trend ({trend}).")
        return (f"{f_words}: no clear effect on {m_words} ({change} from {low} to {high}{f_unit}; trend: {trend}; "
                f"{kw}).")
    if row["finding"] == "differs":
        return (f"{m_words} depends on {f_words}: highest at {high} ({row['high_mean']:.3g}{m_unit}), lowest at "
                f"{low} ({row['low_mean']:.3g}{m_unit}), a difference of {abs(row['change']):.3g}{m_unit} ({kw}).")
    return (f"{f_words}: no clear effect on {m_words} (level means from {row['low_mean']:.3g} to "
            f"{row['high_mean']:.3g}{m_unit}; {kw}).")


def plain_findings(runs: pd.DataFrame, tests: pd.DataFrame, effects: pd.DataFrame, factors, metrics) -> pd.DataFrame:
    """One row per (metric, factor) with its finding in words (see the module docstring)."""
    rows = [_row(runs, tests, effects, f, m) for m in metrics for f in factors]
    if not rows:
        return pd.DataFrame(columns=COLUMNS)
    trend_p = np.array([r["trend_p"] if r["kind"] == "trend" else np.nan for r in rows], dtype=float)
    adjusted = holm(trend_p)
    out = []
    for row, p in zip(rows, adjusted):
        row = _judge(row | {"trend_p_holm": float(p)})
        out.append(row | {"sentence": _sentence(row)})
    return pd.DataFrame(out, columns=COLUMNS)


def disagreement_note(rows: pd.DataFrame) -> str:
    """The paragraph explaining a disagreement between the trend and the omnibus test ("" when none)."""
    shown = rows[rows["disagree"].astype(bool)]
    if shown.empty:
        return ""
    pairs = "; ".join(f"{parameter_words(r.factor)} on {metric_words(r.metric)} (trend p (Holm) "
                      f"{_p(r.trend_p_holm)}, Kruskal-Wallis p (Holm) {_p(r.kw_p_holm)})" for r in shown.itertuples())
    return ("Two tests, two questions. The trend test (Spearman) asks whether the metric moves one way as the factor "
            "grows, and spends all its power on that one pattern; the Kruskal-Wallis test asks whether any level "
            "differs from the others in any pattern, and spreads its power over every pattern. A steady but modest "
            "trend is often significant by the first and not by the second, an effect that rises and falls again the "
            "reverse: neither result contradicts the other. A claim tested as a trend asks the first question. Here "
            f"they disagree for: {pairs}.")
