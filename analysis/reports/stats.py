"""Statistics over a sweep's run table: effects of the swept factors on the summary metrics.

Every function takes ``runs``, a DataFrame with one row per run (``load_results(dir).runs``, or
``.ok`` to leave failed runs out: nothing here filters on ``status``), the name(s) of factor
column(s) and the name of one metric column.

Contract, shared by all functions:

* **Missing values.** Rows whose factor value is missing are left out. NaN metric values (e.g.
  ``time_to_fragmentation`` of a run that never fragmented) are dropped per computation; every result
  reports ``n``, the number of values actually used, and ``n_missing``, the number of NaN metric values
  dropped from the rows it looked at.
* **Level order.** Levels of a factor are sorted numerically when they are numbers (``2 < 10``), by
  their text otherwise (so a nominal factor such as ``mode`` comes out alphabetically). "Adjacent"
  levels are neighbours in this order.
* **Randomness.** Only the bootstrap is random; it draws from ``seed`` (an int, a SeedSequence or a
  ``numpy.random.Generator``). The same int seed gives the same numbers on every call.
* **Degenerate inputs never raise.** A test that cannot be formed (fewer than two non-empty levels,
  no residual degrees of freedom) gives ``nan`` statistics and p-value; a metric with no variation at
  all gives a zero statistic, effect size 0 and p = 1. A single value has no confidence interval
  (``nan``); a constant sample's interval is the point ``[mean, mean]``.
  Misuse (a missing column, a non-numeric factor for ``monotone_trend``) does raise.

Functions:

* ``main_effect(runs, factor, metric, confidence=0.95, n_resamples=2000, seed=0)``: per level
  ``level, n, n_missing, mean, sd, ci_low, ci_high, ci_method``; the CI is a bootstrap CI of the mean
  over all runs at that level (pooling replicates and all other factors): ``scipy.stats.bootstrap``
  BCa, falling back to the percentile method when BCa fails or is degenerate (``ci_method`` says which).
* ``factor_test(runs, factor, metric)``: Kruskal-Wallis across the levels, dict with ``H, df, p,
  epsilon2, n, n_missing, n_levels``; epsilon^2 = H (n + 1) / (n^2 - 1) = H / (n - 1), in [0, 1].
* ``two_way_test(runs, factor_a, factor_b, metric)``: two-way ANOVA of the rank-transformed metric
  (Conover & Iman 1981: rank all values, average ranks for ties, then an ordinary ANOVA), type II sums
  of squares from least-squares fits of dummy-coded designs, valid for unbalanced data and empty cells.
  Rows ``source`` (factor_a, factor_b, ``factor_a:factor_b``) with ``SS, df, F, p, partial_eta2,
  df_resid, n, model, note``; partial eta^2 = SS / (SS + SS_resid). When no cell holds more than one
  run the interaction cannot be separated from the error: its row is dropped and the additive model is
  fitted (``model == 'additive'``, explained in ``note``). Caveat: the rank-transform test of the
  interaction is only approximate when both main effects are large (Sawilowsky 1990).
* ``holm(pvalues)``: Holm-Bonferroni adjusted p-values, same shape; NaN stays NaN and is not counted
  in the family.
* ``cliffs_delta(x, y)``: P(X > Y) - P(X < Y), in [-1, 1].
* ``adjacent_comparisons(runs, factor, metric)``: one row per pair of adjacent levels ``level_a <
  level_b``: ``n_a, n_b, median_a, median_b, median_diff`` (b - a), Mann-Whitney ``U`` (of b against
  a), two-sided ``p``, ``cliffs_delta`` (of b against a: positive when the higher level gives larger
  values) and ``p_holm`` (Holm across the pairs of this factor).
* ``cell_summary(runs, factors, metric, confidence=0.95)``: per cell (combination of levels) ``n,
  n_missing, mean, sd, ci_halfwidth``; the half-width is Student-t, t_{(1+c)/2, n-1} sd / sqrt(n), +inf
  when n < 2 (no finite bound; :func:`sweeps.confidence.ci_halfwidth`, the rule ``--until-ci`` uses);
  sd is NaN when n < 2.
* ``factor_report(runs, factors, metrics, seed=0, confidence=0.95, n_resamples=1000)``: dict of
  DataFrames ``tests`` (factor_test for every (metric, factor), with ``p_holm`` across that whole
  family), ``main_effects`` and ``adjacent`` (long format, keyed by ``metric, factor``). With an int
  seed each (metric, factor) block equals the direct ``main_effect`` call with the same seed.
* ``monotone_trend(runs, factor, metric, alternative='two-sided')``: Spearman ``rho`` and ``p``
  between a numeric factor and the metric over runs, with ``direction`` = sign(rho) (+1, -1, or 0 when
  undefined), for claims such as "a wider field gives a higher cohesion" (``alternative='greater'``).
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from flocksweep.sweeps.confidence import ci_halfwidth

__all__ = [
    "main_effect", "bootstrap_mean_ci", "factor_test", "two_way_test", "holm", "cliffs_delta",
    "adjacent_comparisons", "cell_summary", "factor_report", "monotone_trend", "sorted_levels",
]

MAIN_EFFECT_COLUMNS = ["level", "n", "n_missing", "mean", "sd", "ci_low", "ci_high", "ci_method"]
ADJACENT_COLUMNS = ["level_a", "level_b", "n_a", "n_b", "median_a", "median_b", "median_diff", "U", "p",
                    "cliffs_delta", "p_holm"]
TWO_WAY_COLUMNS = ["source", "SS", "df", "F", "p", "partial_eta2", "df_resid", "n", "model", "note"]


# ----------------------------------------------------------------------------------------------- helpers

def _as_generator(seed) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def _level_key(value):
    if isinstance(value, (int, float, np.integer, np.floating, bool, np.bool_)):
        return (0, float(value), "")
    return (1, 0.0, str(value))


def sorted_levels(values) -> list:
    """The distinct non-missing values of ``values``, numbers numerically first, then the rest by text."""
    series = pd.Series(values)
    return sorted(series.dropna().unique().tolist(), key=_level_key)


def _finite_values(values) -> np.ndarray:
    x = np.asarray(values, dtype=float)
    return x[~np.isnan(x)]


def _level_groups(runs: pd.DataFrame, factor: str, metric: str):
    """[(level, metric values without NaN, number of NaN dropped)] in level order."""
    column = runs[factor]
    present = column.notna().to_numpy()
    keys = column[present]
    raw = runs[metric].to_numpy(dtype=float)[present]
    levels = sorted_levels(keys)
    codes = pd.Index(levels).get_indexer(keys.to_numpy())
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(len(levels) + 1))
    groups = []
    for i, level in enumerate(levels):
        values = raw[order[bounds[i]:bounds[i + 1]]]
        finite = values[~np.isnan(values)]
        groups.append((level, finite, int(values.size - finite.size)))
    return groups


def _is_constant(x: np.ndarray) -> bool:
    return x.size > 0 and bool(np.all(x == x[0]))


# -------------------------------------------------------------------------------------------- main effect

def _mean_last_axis(x, axis=-1):
    return np.mean(x, axis=axis)


def bootstrap_mean_ci(values, confidence: float = 0.95, n_resamples: int = 2000, seed=0):
    """(low, high, method) bootstrap CI of the mean of ``values`` (NaN dropped).

    BCa first, then percentile if BCa raises, warns that it is degenerate or gives a non-finite bound;
    both draw from the same seed. ``method`` is 'BCa', 'percentile', 'constant' (all values equal: the
    interval is the point) or 'none' (fewer than two values: nan, nan)."""
    x = _finite_values(values)
    if x.size < 2:
        return np.nan, np.nan, "none"
    if _is_constant(x):
        return float(x[0]), float(x[0]), "constant"
    if isinstance(seed, np.random.Generator):
        seed = int(seed.integers(2**63 - 1))
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                result = stats.bootstrap((x,), _mean_last_axis, n_resamples=n_resamples, vectorized=True,
                                         confidence_level=confidence, method=method,
                                         rng=np.random.default_rng(seed))
            except (ValueError, FloatingPointError, ZeroDivisionError):
                continue
        degenerate = any(issubclass(w.category, stats.DegenerateDataWarning) for w in caught)
        low, high = float(result.confidence_interval.low), float(result.confidence_interval.high)
        if not degenerate and np.isfinite(low) and np.isfinite(high):
            return low, high, method
    return np.nan, np.nan, "none"


def main_effect(runs: pd.DataFrame, factor: str, metric: str, confidence: float = 0.95,
                n_resamples: int = 2000, seed=0) -> pd.DataFrame:
    """One row per level of ``factor``: level, n, n_missing, mean, sd, ci_low, ci_high, ci_method.

    The mean and its bootstrap CI are over all runs at the level, pooling replicates and every other
    factor. Each level draws from its own stream, spawned from ``seed`` in level order."""
    groups = _level_groups(runs, factor, metric)
    rng = _as_generator(seed)
    level_seeds = rng.integers(2**63 - 1, size=len(groups))
    rows = []
    for (level, x, missing), level_seed in zip(groups, level_seeds):
        low, high, method = bootstrap_mean_ci(x, confidence, n_resamples, int(level_seed))
        rows.append({
            "level": level, "n": int(x.size), "n_missing": missing,
            "mean": float(x.mean()) if x.size else np.nan,
            "sd": float(x.std(ddof=1)) if x.size > 1 else np.nan,
            "ci_low": low, "ci_high": high, "ci_method": method,
        })
    return pd.DataFrame(rows, columns=MAIN_EFFECT_COLUMNS)


# --------------------------------------------------------------------------------------- Kruskal-Wallis

def factor_test(runs: pd.DataFrame, factor: str, metric: str) -> dict:
    """Kruskal-Wallis test of ``metric`` across the levels of ``factor``.

    Returns factor, metric, H, df, p, epsilon2 (= H (n+1) / (n^2 - 1)), n, n_missing, n_levels (the
    non-empty levels used). Fewer than two non-empty levels: H, p, epsilon2 nan. No variation at all:
    H = 0, p = 1, epsilon2 = 0."""
    groups = _level_groups(runs, factor, metric)
    samples = [x for _, x, _ in groups if x.size]
    n = int(sum(x.size for x in samples))
    k = len(samples)
    out = {"factor": factor, "metric": metric, "H": np.nan, "df": max(k - 1, 0), "p": np.nan,
           "epsilon2": np.nan, "n": n, "n_missing": int(sum(m for _, _, m in groups)), "n_levels": k}
    if k < 2:
        return out
    pooled = np.concatenate(samples)
    if _is_constant(pooled):
        out.update(H=0.0, p=1.0, epsilon2=0.0)
        return out
    h, p = stats.kruskal(*samples)
    out.update(H=float(h), p=float(p), epsilon2=float(h) * (n + 1) / (n * n - 1))
    return out


# ----------------------------------------------------------------------------------- two-way rank ANOVA

def _dummies(codes: np.ndarray, k: int) -> np.ndarray:
    """Treatment coding: one 0/1 column per level but the first."""
    return (codes[:, None] == np.arange(1, k)[None, :]).astype(float)


def _fit(y: np.ndarray, *blocks: np.ndarray) -> tuple[float, int]:
    """(residual sum of squares, rank) of the least-squares fit of y on an intercept and the blocks."""
    design = np.column_stack([np.ones(y.size), *blocks])
    beta, _, rank, _ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ beta
    return float(resid @ resid), int(rank)


def two_way_test(runs: pd.DataFrame, factor_a: str, factor_b: str, metric: str) -> pd.DataFrame:
    """Two-way type II ANOVA of the ranked ``metric`` on ``factor_a``, ``factor_b`` and their
    interaction; see the module docstring for the columns and the no-replication rule."""
    frame = runs[[factor_a, factor_b, metric]]
    frame = frame[frame[factor_a].notna() & frame[factor_b].notna()]
    raw = frame[metric].to_numpy(dtype=float)
    keep = ~np.isnan(raw)
    frame, y = frame[keep], stats.rankdata(raw[keep])
    n = int(y.size)
    levels_a, levels_b = sorted_levels(frame[factor_a]), sorted_levels(frame[factor_b])
    codes_a = pd.Categorical(frame[factor_a], categories=levels_a).codes.astype(int)
    codes_b = pd.Categorical(frame[factor_b], categories=levels_b).codes.astype(int)
    da, db = _dummies(codes_a, len(levels_a)), _dummies(codes_b, len(levels_b))
    dab = (da[:, :, None] * db[:, None, :]).reshape(n, da.shape[1] * db.shape[1])

    rss_a, rank_a = _fit(y, da)
    rss_b, rank_b = _fit(y, db)
    rss_add, rank_add = _fit(y, da, db)
    rss_full, rank_full = _fit(y, da, db, dab)
    interaction = n - rank_full > 0
    if interaction:
        model, note = "full", ""
        rss_res, df_res = rss_full, n - rank_full
    else:
        model = "additive"
        note = ("no replication within cells (one run per cell): interaction not testable, "
                "additive model")
        rss_res, df_res = rss_add, n - rank_add

    sources = [(factor_a, rss_b - rss_add, rank_add - rank_b),
               (factor_b, rss_a - rss_add, rank_add - rank_a)]
    if interaction:
        sources.append((f"{factor_a}:{factor_b}", rss_add - rss_full, rank_full - rank_add))
    total_ss = float(((y - y.mean()) ** 2).sum()) if n else 0.0
    scale = max(total_ss, 1.0)
    rows = []
    for source, ss, df in sources:
        ss = max(ss, 0.0) if abs(ss) > 1e-12 * scale else 0.0
        f = p = eta2 = np.nan
        if df > 0 and df_res > 0:
            if total_ss <= 1e-12 * scale:          # the metric does not vary: no effect at all
                f, p, eta2 = 0.0, 1.0, 0.0
            elif rss_res > 1e-12 * scale:
                f = (ss / df) / (rss_res / df_res)
                p = float(stats.f.sf(f, df, df_res))
                eta2 = ss / (ss + rss_res)
            else:                                  # exact fit with variation left: infinitely significant
                f, p, eta2 = np.inf, 0.0, 1.0
        rows.append({"source": source, "SS": ss, "df": int(df), "F": f, "p": p, "partial_eta2": eta2,
                     "df_resid": int(df_res), "n": n, "model": model, "note": note})
    return pd.DataFrame(rows, columns=TWO_WAY_COLUMNS)


# ----------------------------------------------------------------------------------------- Holm, Cliff

def holm(pvalues) -> np.ndarray:
    """Holm-Bonferroni adjusted p-values, in the input's shape.

    With the m non-NaN p-values sorted, p_(1) <= ... <= p_(m), the adjusted value of p_(i) is
    min(1, max_{j <= i} (m - j + 1) p_(j)); NaN entries stay NaN and do not count in m."""
    p = np.asarray(pvalues, dtype=float)
    flat = p.ravel()
    out = np.full(flat.shape, np.nan)
    finite = np.flatnonzero(~np.isnan(flat))
    m = finite.size
    if m:
        order = finite[np.argsort(flat[finite], kind="stable")]
        adjusted = np.maximum.accumulate((m - np.arange(m)) * flat[order])
        out[order] = np.minimum(adjusted, 1.0)
    return out.reshape(p.shape)


def cliffs_delta(x, y) -> float:
    """Cliff's delta P(X > Y) - P(X < Y) over all pairs, NaN dropped; nan when a sample is empty."""
    x, y = _finite_values(x), np.sort(_finite_values(y))
    if x.size == 0 or y.size == 0:
        return np.nan
    below = np.searchsorted(y, x, side="left").sum()               # pairs with y < x
    above = (y.size - np.searchsorted(y, x, side="right")).sum()   # pairs with y > x
    return float(below - above) / (x.size * y.size)


def adjacent_comparisons(runs: pd.DataFrame, factor: str, metric: str) -> pd.DataFrame:
    """Mann-Whitney U test and Cliff's delta between each pair of adjacent levels (see module doc)."""
    groups = _level_groups(runs, factor, metric)
    rows = []
    for (level_a, a, _), (level_b, b, _) in zip(groups[:-1], groups[1:]):
        row = {"level_a": level_a, "level_b": level_b, "n_a": int(a.size), "n_b": int(b.size),
               "median_a": float(np.median(a)) if a.size else np.nan,
               "median_b": float(np.median(b)) if b.size else np.nan,
               "U": np.nan, "p": np.nan, "cliffs_delta": np.nan}
        row["median_diff"] = row["median_b"] - row["median_a"]
        if a.size and b.size:
            row["cliffs_delta"] = cliffs_delta(b, a)
            if _is_constant(np.concatenate([a, b])):
                row.update(U=a.size * b.size / 2.0, p=1.0)
            else:
                u, p = stats.mannwhitneyu(b, a, alternative="two-sided")
                row.update(U=float(u), p=float(p))
        rows.append(row)
    table = pd.DataFrame(rows, columns=ADJACENT_COLUMNS)
    table["p_holm"] = holm(table["p"].to_numpy(dtype=float))
    return table


# ------------------------------------------------------------------------------------------ cell summary

def cell_summary(runs: pd.DataFrame, factors, metric: str, confidence: float = 0.95) -> pd.DataFrame:
    """Per combination of the levels of ``factors`` (a name or a list): n, n_missing, mean, sd and the
    Student-t half-width of the CI of the mean over the cell's runs (+inf when n < 2,
    :func:`sweeps.confidence.ci_halfwidth`)."""
    factors = [factors] if isinstance(factors, str) else list(factors)
    frame = runs[factors + [metric]]
    grouped = frame.groupby(factors, sort=True, dropna=True, observed=True)[metric]
    stats = grouped.agg(["count", "size", "mean", "std"])
    table = stats.index.to_frame(index=False)   # the factors' levels; then the statistics (names never collide)
    table["n"] = stats["count"].to_numpy().astype(int)
    table["n_missing"] = stats["size"].to_numpy().astype(int) - table["n"]
    table["mean"] = stats["mean"].to_numpy()
    table["sd"] = stats["std"].to_numpy()
    n = table["n"].to_numpy(dtype=float)
    sd = table["sd"].to_numpy(dtype=float)
    table["sd"] = np.where(n >= 2, sd, np.nan)
    table["ci_halfwidth"] = ci_halfwidth(n, sd, confidence)
    if factors:
        order = sorted(range(len(table)), key=lambda i: tuple(_level_key(table[f].iat[i]) for f in factors))
        table = table.iloc[order].reset_index(drop=True)
    return table[factors + ["n", "n_missing", "mean", "sd", "ci_halfwidth"]]


# ---------------------------------------------------------------------------------------------- report

def factor_report(runs: pd.DataFrame, factors: Sequence[str], metrics: Sequence[str], seed=0,
                  confidence: float = 0.95, n_resamples: int = 1000) -> dict[str, pd.DataFrame]:
    """Kruskal-Wallis tests, main effects and adjacent comparisons for every (metric, factor).

    ``tests``: metric, factor, H, df, p, epsilon2, n, n_missing, n_levels, p_holm (Holm across all
    metric x factor tests). ``main_effects``: metric, factor + main_effect columns. ``adjacent``:
    metric, factor + adjacent_comparisons columns (p_holm within each factor, as there)."""
    tests, effects, adjacent = [], [], []
    for metric in metrics:
        for factor in factors:
            tests.append(factor_test(runs, factor, metric))
            effect = main_effect(runs, factor, metric, confidence=confidence, n_resamples=n_resamples,
                                 seed=seed)
            effects.append(effect.assign(metric=metric, factor=factor))
            adjacent.append(adjacent_comparisons(runs, factor, metric).assign(metric=metric, factor=factor))
    tests_table = pd.DataFrame(tests, columns=["metric", "factor", "H", "df", "p", "epsilon2", "n",
                                               "n_missing", "n_levels"])
    tests_table["p_holm"] = holm(tests_table["p"].to_numpy(dtype=float))
    keys = ["metric", "factor"]

    def _long(parts, columns):
        if not parts:
            return pd.DataFrame(columns=keys + columns)
        return pd.concat(parts, ignore_index=True)[keys + columns]

    return {"tests": tests_table,
            "main_effects": _long(effects, MAIN_EFFECT_COLUMNS),
            "adjacent": _long(adjacent, ADJACENT_COLUMNS)}


# ---------------------------------------------------------------------------------------------- trend

def monotone_trend(runs: pd.DataFrame, factor: str, metric: str, alternative: str = "two-sided") -> dict:
    """Spearman correlation between a numeric ``factor`` and ``metric`` over runs.

    Returns factor, metric, rho, p, n, n_missing, n_levels, direction (sign of rho: +1 increasing,
    -1 decreasing, 0 when rho is 0 or undefined, e.g. a single level or a constant metric).
    ``alternative`` is passed to scipy.stats.spearmanr ('greater' tests for an increasing trend)."""
    frame = runs[[factor, metric]]
    frame = frame[frame[factor].notna()]
    level_values = frame[factor]
    if not (pd.api.types.is_numeric_dtype(level_values) or pd.api.types.is_bool_dtype(level_values)):
        raise ValueError(f"monotone_trend needs a numeric factor; {factor!r} is {level_values.dtype}")
    x = level_values.to_numpy(dtype=float)
    y = frame[metric].to_numpy(dtype=float)
    keep = ~np.isnan(y)
    x, y = x[keep], y[keep]
    out = {"factor": factor, "metric": metric, "rho": np.nan, "p": np.nan, "n": int(y.size),
           "n_missing": int((~keep).sum()), "n_levels": int(np.unique(x).size), "direction": 0}
    if y.size < 3 or _is_constant(x) or _is_constant(y):
        return out
    result = stats.spearmanr(x, y, alternative=alternative)
    rho = float(result.statistic)
    out.update(rho=rho, p=float(result.pvalue), direction=int(np.sign(rho)) if np.isfinite(rho) else 0)
    return out
