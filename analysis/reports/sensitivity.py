"""Global sensitivity analysis of a sweep's continuous factors: Sobol' and Morris indices (SALib),
Spearman and partial rank correlations, smoothers and partial dependence.

Shapes: d continuous factors, P design points, R rows of a SALib sample (rows may share a point).

Contract
--------
``continuous_design(results) -> ContinuousDesign | None``
    The sweep's sampled block, from its stored files: ``kind`` (``"saltelli"`` / ``"morris"`` for a
    ``[design]`` block, ``"lhs"`` / ``"sobol"`` / ``"random"`` for ``[sample]``), ``keys`` (its factor
    columns), and for a ``[design]`` block the full SALib sample ``rows`` (R, d) rebuilt from the
    stored sweep (its seed, bounds and the stored preset's integer keys, :mod:`sweeps.sensitivity`).
    None when the sweep has no sampled block.
``design_runs(results) -> DataFrame``: the ok runs of the product (explicit ``[[points]]`` left out).
``point_means(runs, keys, metric) -> DataFrame``: per design point (the keys' values) ``mean``,
    ``var`` (over replicates, ddof 1) and ``n`` of the finite metric values.
``sample_outputs(design, runs, metric) -> (X (R, d), Y (R,))``: each SALib row's output, the mean
    over the replicates of its point (NaN where the point has no finite value).
``sobol_indices(design, Y, seed, conf=0.95, resamples=1000) -> (DataFrame, note)``
    ``SALib.analyze.sobol.analyze`` on the complete Saltelli blocks (a base row with its d + 2 (or
    2d + 2) rows; blocks with a missing output are dropped, which keeps the estimator valid with a
    smaller N): per factor ``S1, S1_low, S1_high, ST, ST_low, ST_high`` (CI = index -+ SALib's bootstrap
    half-width at ``conf``), ``n_base`` and the rank by ``ST``; second-order indices as ``S2_<other>``
    columns when the design has them.
``morris_indices(design, X, Y, seed, conf=0.95, resamples=1000) -> (DataFrame, note)``
    ``SALib.analyze.morris.analyze`` on the complete trajectories: ``mu, mu_star, mu_star_low,
    mu_star_high, sigma``, ``n_trajectories``, rank by ``mu_star``.
``correlations(X (P, d), Y (P,), names, conf=0.95) -> DataFrame``
    per factor Spearman's rho and the partial rank correlation coefficient (PRCC: ranks, every other
    factor regressed out linearly, residuals correlated) with Fisher-z confidence intervals
    (``tanh(atanh(r) -+ z / sqrt(n - 3 - c))``, c = the factors controlled for) and two-sided p-values
    (t test with ``n - 2 - c`` degrees of freedom).
``smoother(x, y) -> (grid (G,), fitted (G,))``: a cubic smoothing spline of the point means
    (``scipy.interpolate.make_smoothing_spline``, penalty by generalised cross-validation; tied x
    averaged, and beyond 80 distinct x the means over 80 quantile bins, weighted by their counts);
    None below 5 distinct x.
``partial_dependence(X, Y, names, seed, grid=30, most=MAX_FIT_POINTS) -> (DataFrame, r2)``: a
    gradient-boosted regression (``sklearn.ensemble.GradientBoostingRegressor``: 100 trees of depth 3,
    subsample 0.8, ``random_state`` = seed; single-threaded, so a busy machine does not slow it down)
    fitted to the points (beyond ``most`` finite points, to ``most`` of them drawn at random with the
    seed, :func:`subsample`: the fit's cost grows with the points, its curves barely do), its partial
    dependence on each factor (``sklearn.inspection.partial_dependence``, long format ``factor, value,
    average``) and its 3-fold cross-validated R^2 (how far to trust the curves).
``subsample(n, most, seed) -> index array``: ``most`` of ``range(n)`` drawn without replacement by
    ``numpy.random.default_rng(seed)``, in increasing order (all of them when ``n <= most``).
``noise_share(runs, keys, metric) -> float``: the run-to-run variance left in a point mean (mean
    within-point variance / replicates) over the variance of the point means; NaN without replicates.
    Noise adds to every total index and lowers every first-order index by up to this share.

Randomness: only the bootstrap of the indices and the boosted trees' subsampling, each seeded.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from flocksweep.simcore.params import canonical_key, preset_from_dict
from flocksweep.simcore.schema import build
from flocksweep.sweeps.config import parse_design
from flocksweep.sweeps.design import integer_keys
from flocksweep.sweeps.results import Results
from flocksweep.sweeps.sensitivity import DesignTable, SensitivityDesign
from flocksweep.sweeps.store import ResultsStore

SAMPLE_KINDS = ("lhs", "sobol", "random")


@dataclass
class ContinuousDesign:
    kind: str
    keys: list[str]
    design: SensitivityDesign | None = None
    rows: np.ndarray | None = None   # (R, d) the full SALib sample, rounded as the runs were


def continuous_design(results: Results) -> ContinuousDesign | None:
    """The sweep's sampled block (see the module docstring)."""
    sweep = results.sweep
    if "design" in sweep:
        record = ResultsStore(results.path).model()
        design = parse_design(build(DesignTable, _bounds_in_design_order(sweep["design"], record), "design"))
        base = preset_from_dict(record["preset"])
        rows = np.array(design.rows(int(sweep.get("seed", 0)), integer_keys(base, design.keys)), dtype=float)
        keys = [k for k in design.keys if k in results.runs.columns]
        return ContinuousDesign(kind=design.kind, keys=keys, design=design, rows=rows)
    if "sample" in sweep:
        sample = sweep["sample"]
        keys = [k for k in _block_keys(sample) if k in results.factors]
        return ContinuousDesign(kind=sample.get("method", "lhs"), keys=keys) if keys else None
    return None


def _bounds_in_design_order(table: dict, record: dict) -> dict:
    """The stored ``[design]`` table with its bounds in the order the sweep gave them (the stored JSON
    sorts keys; ``model.json``'s swept keys keep the order, which fixes the sample's columns)."""
    order = {key: i for i, key in enumerate(record.get("swept_keys", []))}
    bounds = sorted(table.get("bounds", {}).items(), key=lambda item: order.get(canonical_key(item[0]), len(order)))
    return {**table, "bounds": dict(bounds)}


def _block_keys(block: dict) -> list[str]:
    return [canonical_key(k) for k in block.get("bounds", {})]


def design_runs(results: Results) -> pd.DataFrame:
    """The ok runs of the product: explicit ``[[points]]`` (the last point indices) left out."""
    runs = results.ok
    explicit = len(results.sweep.get("points", []))
    if explicit and "point_index" in results.design:
        product = int(results.design["point_index"].max()) + 1 - explicit
        runs = runs[runs["point_index"] < product]
    return runs.reset_index(drop=True)


def point_means(runs: pd.DataFrame, keys, metric: str) -> pd.DataFrame:
    """Per design point: mean, var (ddof 1) and n of the finite metric values."""
    finite = runs[np.isfinite(runs[metric].to_numpy(dtype=float))]
    grouped = finite.groupby(list(keys), sort=False)[metric]
    return pd.DataFrame({"mean": grouped.mean(), "var": grouped.var(ddof=1), "n": grouped.count()}).reset_index()


def sample_outputs(design: ContinuousDesign, runs: pd.DataFrame, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """(X (R, d), Y (R,)): each SALib row's output, the mean over its point's replicates (NaN if none)."""
    means = point_means(runs, design.keys, metric)
    lookup = {tuple(float(v) for v in row[:-3]): row[-3]
              for row in means[list(design.keys) + ["mean", "var", "n"]].itertuples(index=False)}
    X = design.rows
    Y = np.array([lookup.get(tuple(float(v) for v in row), np.nan) for row in X])
    return X, Y


def _complete_blocks(Y: np.ndarray, size: int) -> tuple[np.ndarray, int]:
    """Keep the blocks of ``size`` consecutive rows whose outputs are all finite: (mask (R,), blocks kept)."""
    blocks = np.isfinite(Y).reshape(-1, size).all(axis=1)
    return np.repeat(blocks, size), int(blocks.sum())


def _dropped_note(kept: int, total: int, what: str) -> str:
    if kept == total:
        return ""
    return (f"{total - kept} of {total} {what} have a run without a finite value and are left out "
            f"(the estimator stays valid with the {kept} complete ones)")


def sobol_indices(design: ContinuousDesign, Y, seed: int, conf: float = 0.95,
                  resamples: int = 1000) -> tuple[pd.DataFrame, str]:
    """Sobol' first-order and total indices with bootstrap CIs (see the module docstring)."""
    from SALib.analyze import sobol

    spec = design.design
    size = (2 * spec.d + 2) if spec.second_order else (spec.d + 2)
    keep, kept = _complete_blocks(np.asarray(Y, dtype=float), size)
    note = _dropped_note(kept, len(keep) // size, "Saltelli base rows")
    if kept < 2:
        return pd.DataFrame(), note or "fewer than 2 complete Saltelli base rows: no indices"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = sobol.analyze(spec.problem(), np.asarray(Y, dtype=float)[keep], calc_second_order=spec.second_order,
                               num_resamples=resamples, conf_level=conf, seed=max(1, int(seed) + 1))
    table = pd.DataFrame({"factor": list(spec.keys), "S1": result["S1"], "S1_conf": result["S1_conf"],
                          "ST": result["ST"], "ST_conf": result["ST_conf"]})
    table["S1_low"], table["S1_high"] = table["S1"] - table["S1_conf"], table["S1"] + table["S1_conf"]
    table["ST_low"], table["ST_high"] = table["ST"] - table["ST_conf"], table["ST"] + table["ST_conf"]
    if spec.second_order:
        for j, key in enumerate(spec.keys):
            s2 = np.asarray(result["S2"])
            table[f"S2_{key}"] = [s2[min(i, j), max(i, j)] if i != j else np.nan for i in range(spec.d)]
    table["n_base"] = kept
    table = table.sort_values("ST", ascending=False, kind="stable").reset_index(drop=True)
    table.insert(1, "rank", np.arange(1, len(table) + 1))
    columns = ["factor", "rank", "ST", "ST_low", "ST_high", "S1", "S1_low", "S1_high", "ST_conf", "S1_conf"]
    return table[columns + [c for c in table.columns if c not in columns]], note


def morris_indices(design: ContinuousDesign, X, Y, seed: int, conf: float = 0.95,
                   resamples: int = 1000) -> tuple[pd.DataFrame, str]:
    """Morris elementary-effect statistics (see the module docstring)."""
    from SALib.analyze import morris

    spec = design.design
    size = spec.d + 1
    keep, kept = _complete_blocks(np.asarray(Y, dtype=float), size)
    note = _dropped_note(kept, len(keep) // size, "Morris trajectories")
    if kept < 2:
        return pd.DataFrame(), note or "fewer than 2 complete trajectories: no indices"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = morris.analyze(spec.problem(), np.asarray(X, dtype=float)[keep], np.asarray(Y, dtype=float)[keep],
                                num_resamples=resamples, conf_level=conf, num_levels=spec.levels,
                                seed=np.random.default_rng(int(seed)))
    table = pd.DataFrame({"factor": list(spec.keys), "mu": result["mu"], "mu_star": result["mu_star"],
                          "mu_star_conf": result["mu_star_conf"], "sigma": result["sigma"]})
    table["mu_star_low"] = table["mu_star"] - table["mu_star_conf"]
    table["mu_star_high"] = table["mu_star"] + table["mu_star_conf"]
    table["n_trajectories"] = kept
    table = table.sort_values("mu_star", ascending=False, kind="stable").reset_index(drop=True)
    table.insert(1, "rank", np.arange(1, len(table) + 1))
    return table, note


def _fisher(r: float, n: int, controlled: int, z: float) -> tuple[float, float, float]:
    """(low, high, p) of a (partial) correlation r from n points with ``controlled`` variables removed."""
    dof = n - 2 - controlled
    if not math.isfinite(r) or dof < 2:
        return math.nan, math.nan, math.nan
    r = float(np.clip(r, -0.999999999, 0.999999999))
    half = z / math.sqrt(max(n - 3 - controlled, 1))
    t = r * math.sqrt(dof / (1.0 - r * r))
    p = float(2.0 * stats.t.sf(abs(t), dof))
    return math.tanh(math.atanh(r) - half), math.tanh(math.atanh(r) + half), p


def correlations(X, Y, names, conf: float = 0.95) -> pd.DataFrame:
    """Spearman and PRCC per factor with Fisher-z CIs and p-values (see the module docstring)."""
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    ok = np.isfinite(Y) & np.isfinite(X).all(axis=1)
    X, Y = X[ok], Y[ok]
    n, d = X.shape
    z = float(stats.norm.ppf(0.5 + conf / 2))
    ranks = np.column_stack([stats.rankdata(X[:, j]) for j in range(d)]) if n else X
    ry = stats.rankdata(Y) if n else Y
    rows = []
    for j, name in enumerate(names):
        rho = _corr(ranks[:, j], ry) if n > 2 else math.nan
        others = np.column_stack([np.ones(n), np.delete(ranks, j, axis=1)])
        prcc = _corr(_residual(ranks[:, j], others), _residual(ry, others)) if n > d + 2 else math.nan
        lo, hi, p = _fisher(rho, n, 0, z)
        plo, phi, pp = _fisher(prcc, n, d - 1, z)
        rows.append({"factor": name, "n": n, "spearman": rho, "spearman_low": lo, "spearman_high": hi,
                     "spearman_p": p, "prcc": prcc, "prcc_low": plo, "prcc_high": phi, "prcc_p": pp})
    return pd.DataFrame(rows)


def _residual(y: np.ndarray, design: np.ndarray) -> np.ndarray:
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    return y - design @ coef


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    if np.ptp(a) == 0 or np.ptp(b) == 0:
        return math.nan
    return float(np.corrcoef(a, b)[0, 1])


def smoother(x, y, grid: int = 60, bins: int = 80):
    """(grid x, fitted) of a GCV smoothing spline through the point means, or None (see the docstring)."""
    from scipy.interpolate import make_smoothing_spline

    frame = pd.DataFrame({"x": np.asarray(x, dtype=float), "y": np.asarray(y, dtype=float)})
    frame = frame[np.isfinite(frame["x"]) & np.isfinite(frame["y"])]
    if frame["x"].nunique() > bins:   # many distinct x: means over quantile bins, weighted by their counts
        frame = frame.assign(x=frame.groupby(pd.qcut(frame["x"], bins, duplicates="drop"), observed=True)["x"]
                             .transform("mean"))
    grouped = frame.groupby("x", sort=True)["y"]
    means, counts = grouped.mean(), grouped.count()
    if len(means) < 5:
        return None
    xs = means.index.to_numpy(dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        spline = make_smoothing_spline(xs, means.to_numpy(dtype=float), w=counts.to_numpy(dtype=float))
    at = np.linspace(xs[0], xs[-1], grid)
    return at, spline(at)


MAX_FIT_POINTS = 2000   # the boosted trees of partial_dependence are fitted to at most this many points


def subsample(n: int, most: int, seed: int) -> np.ndarray:
    """See the module docstring."""
    if n <= most:
        return np.arange(n)
    return np.sort(np.random.default_rng(int(seed)).choice(n, size=most, replace=False))


def partial_dependence(X, Y, names, seed: int, grid: int = 30,
                       most: int = MAX_FIT_POINTS) -> tuple[pd.DataFrame, float]:
    """Partial dependence of a boosted-trees fit on each factor and its cross-validated R^2 (see the module
    docstring)."""
    from sklearn.ensemble import GradientBoostingRegressor
    from sklearn.inspection import partial_dependence as sk_partial_dependence
    from sklearn.model_selection import KFold, cross_val_score

    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    ok = np.isfinite(Y) & np.isfinite(X).all(axis=1)
    X, Y = X[ok], Y[ok]
    if len(Y) < 20 or np.ptp(Y) == 0:
        return pd.DataFrame(columns=["factor", "value", "average"]), math.nan
    chosen = subsample(len(Y), most, seed)
    X, Y = X[chosen], Y[chosen]
    model = GradientBoostingRegressor(n_estimators=100, learning_rate=0.1, max_depth=3, subsample=0.8,
                                      random_state=int(seed))
    folds = KFold(n_splits=3, shuffle=True, random_state=int(seed))
    r2 = float(np.mean(cross_val_score(model, X, Y, cv=folds, scoring="r2")))
    model.fit(X, Y)
    frames = []
    for j, name in enumerate(names):
        result = sk_partial_dependence(model, X, [j], grid_resolution=grid, kind="average")
        frames.append(pd.DataFrame({"factor": name, "value": result["grid_values"][0],
                                    "average": result["average"][0]}))
    return pd.concat(frames, ignore_index=True), r2


def noise_share(runs: pd.DataFrame, keys, metric: str) -> float:
    """Run-to-run variance left in the point means over the variance of the point means."""
    means = point_means(runs, keys, metric)
    replicated = means[means["n"] >= 2]
    if len(replicated) < 2 or len(means) < 3:
        return math.nan
    total = float(means["mean"].var(ddof=1))
    noise = float(np.mean(replicated["var"] / replicated["n"]))
    return noise / total if total > 0 else math.nan
