"""The generic test kinds of claims, on a results table: which runs a test uses, and its statistic.

``leaf_data(test, runs, factors) -> LeafData`` picks the runs of a leaf test (``trend``, ``compare``,
``sign``; :class:`sweeps.claims.Test`): the rows meeting its conditions, the metric (a column or an
expression, non-finite values dropped and counted), and per value

* ``x``: trend: the factor's value; compare: 1.0 in the group claimed higher, 0.0 in the lower one
  (rows in neither group are left out); sign: none;
* ``point``: the design point it belongs to (an integer code of its ``factors`` values), which the power
  analysis uses to separate the spread between design points from the spread between replicates;
* ``cell``: the levels of the other factors (a code of the factors that do not determine ``x``), which
  the power analysis keeps the same at every level of a trend or in both groups of a comparison.

A ``paired`` comparison matches each run of the higher group with the run of the lower group that has
the same replicate and the same value of every factor that does not separate the groups, and becomes a
one-sample test of the differences (higher minus lower; ``x`` none). Unmatched runs are dropped.

``leaf_result(test, data) -> LeafResult``: the two-sided test (:mod:`.statistics`), the observed
direction (+1 as the metric rises along the factor / in the higher group / above ``value``) and the
estimate in the metric's units: a trend's change of the mean over the factor's range (least-squares
line), a comparison's difference of means (higher minus lower), a sign test's distance from ``value``
of its :func:`location` (mean for t, median for sign, Hodges-Lehmann pseudo-median for wilcoxon, the
share for 0/1 data). A ``zero`` sign test is a check, not a test: it counts runs farther than ``tolerance`` from
``value`` (p NaN).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from . import statistics as S


@dataclass
class LeafData:
    y: np.ndarray                # metric values used (finite)
    x: np.ndarray | None         # trend: factor values; compare: 1.0 higher group / 0.0 lower; else None
    point: np.ndarray            # design point code per value
    rows: pd.Index               # the runs' index in the table (a paired test: both runs of each pair)
    n_missing: int               # rows meeting the conditions whose metric was not finite
    note: str = ""               # what was dropped or matched (paired tests)
    cell: np.ndarray | None = None  # code of the other factors' levels per value (None: the point)

    @property
    def n(self) -> int:
        return int(self.y.size)


@dataclass
class LeafResult:
    method: str
    statistic: float
    p: float
    sign: int                    # direction of the data: +1 up, -1 down, 0 none
    estimate: float              # metric units (module docstring)
    n: int
    detail: str


def _points(frame: pd.DataFrame, factors) -> np.ndarray:
    columns = [c for c in factors if c in frame.columns]
    if not columns or frame.empty:
        return np.zeros(len(frame), dtype=int)
    return frame.groupby(columns, sort=True, dropna=False).ngroup().to_numpy()


def _separating(frame: pd.DataFrame, higher: np.ndarray, factors) -> list[str]:
    """Factors whose values never occur in both groups (they tell the groups apart)."""
    out = []
    for column in factors:
        if column in frame.columns:
            a = set(frame.loc[higher, column].astype(str))
            b = set(frame.loc[~higher, column].astype(str))
            if not a & b:
                out.append(column)
    return out


def _determining(frame: pd.DataFrame, target: np.ndarray, factors) -> list[str]:
    """Factors each of whose values goes with one value of ``target`` only (``target`` itself, its
    aliases, the columns that define a comparison's groups)."""
    out = []
    for column in factors:
        if column in frame.columns:
            pairs = pd.DataFrame({"c": frame[column].astype(str).to_numpy(), "t": target})
            if pairs.groupby("c")["t"].nunique().max() <= 1:
                out.append(column)
    return out


def _paired(frame: pd.DataFrame, y: np.ndarray, higher: np.ndarray, factors) -> LeafData:
    separating = _separating(frame, higher, factors)
    keys = [c for c in factors if c in frame.columns and c not in separating]
    keys += ["replicate"] if "replicate" in frame.columns else []
    table = frame[keys].astype(str).assign(_y=y, _higher=higher, _row=frame.index)
    table = table[np.isfinite(table["_y"])]
    high, low = table[table["_higher"]], table[~table["_higher"]]
    merged = high.merge(low, on=keys, suffixes=("", "_low")) if keys else pd.DataFrame()
    if keys and (merged.duplicated(keys).any()):
        merged = merged.drop_duplicates(keys)
    d = (merged["_y"] - merged["_y_low"]).to_numpy(dtype=float) if len(merged) else np.zeros(0)
    points = _points(merged, [k for k in keys if k != "replicate"]) if len(merged) else np.zeros(0, dtype=int)
    note = (f"{len(merged)} pairs matched on {', '.join(keys) or 'nothing'} "
            f"({len(high) - len(merged)} higher and {len(low) - len(merged)} lower runs unmatched)")
    rows = pd.Index(list(merged["_row"]) + list(merged["_row_low"])) if len(merged) else pd.Index([])
    return LeafData(d, None, points, rows, 0, note)


def leaf_data(test, runs: pd.DataFrame, factors) -> LeafData:
    """The values a leaf test uses (see the module docstring)."""
    frame = runs[test.select(runs)]
    y = test.metric.evaluate(frame) if len(frame) else np.zeros(0)
    x = None
    if test.kind == "compare":
        lower, higher = test.lower.evaluate(frame), test.higher.evaluate(frame)
        keep = lower | higher
        frame, y, higher = frame[keep], y[keep], higher[keep]
        if test.paired:
            return _paired(frame, y, higher, factors)
        x = higher.astype(float)
    elif test.kind == "trend":
        x = frame[test.factor].to_numpy(dtype=float)
    finite = np.isfinite(y)
    if x is not None:
        finite &= np.isfinite(x)
    points = _points(frame, factors)
    cells = points
    if x is not None and len(frame):
        others = [c for c in factors if c not in _determining(frame, x, factors)]
        cells = _points(frame, others)
    return LeafData(y[finite], None if x is None else x[finite], points[finite], frame.index[finite],
                    int((~finite).sum()), cell=cells[finite])


def location(values: np.ndarray, method: str) -> float:
    """Where a one-sample test puts a sample: the mean (t), the median (sign), the Hodges-Lehmann
    pseudo-median, the median of all pairwise means (wilcoxon); 0/1 data: the mean (the share)."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return float("nan")
    if method == "t" or np.isin(values, (0.0, 1.0)).all():
        return float(values.mean())
    if method == "sign":
        return float(np.median(values))
    if values.size > 2000:   # 2000 evenly spaced order statistics keep the pairs in memory
        values = np.sort(values)[np.linspace(0, values.size - 1, 2000).astype(int)]
    upper = np.triu_indices(values.size)
    return float(np.median((values[upper[0]] + values[upper[1]]) / 2.0))


def _slope_change(x: np.ndarray, y: np.ndarray) -> float:
    """Change of the least-squares line over the range of x."""
    spread = x - x.mean()
    denominator = spread @ spread
    return float((spread @ (y - y.mean())) / denominator * (x.max() - x.min())) if denominator > 0 else float("nan")


def run_rows(test, data: LeafData, Y: np.ndarray):
    """(statistic, p, sign) of ``test``'s method on each row of Y (k, n): the data's values or simulated
    ones, at ``data``'s x."""
    if test.kind == "trend":
        return S.spearman(data.x, Y)
    if test.kind == "compare" and not test.paired:
        return S.TWO_GROUP[test.method](Y, data.x > 0.5)
    return S.ONE_SAMPLE[test.method](Y - (0.0 if test.kind == "compare" else test.value))


def leaf_result(test, data: LeafData) -> LeafResult:
    n = data.n
    y = data.y
    if test.kind == "sign" and test.direction == "zero":
        off = int((np.abs(y - test.value) > test.tolerance).sum())
        worst = float(np.max(np.abs(y - test.value))) if n else float("nan")
        return LeafResult("check", float(off), float("nan"), 0, worst, n,
                          f"{off} of {n} runs farther than {test.tolerance:g} from {test.value:g} "
                          f"(largest distance {worst:.3g})")
    if n == 0:
        return LeafResult(test.method, float("nan"), float("nan"), 0, float("nan"), 0, "no runs")
    statistic, p, sign = (float(v[0]) for v in run_rows(test, data, y[None, :]))
    name = S.STATISTIC_NAMES[test.method]
    if test.kind == "trend":
        estimate = _slope_change(data.x, y)
        detail = (f"{name} = {statistic:+.3f}; the mean changes by {estimate:+.3g} from {test.factor} = "
                  f"{data.x.min():g} to {data.x.max():g}")
    elif test.kind == "compare" and not test.paired:
        hi, lo = y[data.x > 0.5], y[data.x < 0.5]
        estimate = float(hi.mean() - lo.mean()) if hi.size and lo.size else float("nan")
        detail = (f"{name} = {statistic:.4g}; mean {_mean(lo):.3g} (lower group, n = {lo.size}) vs "
                  f"{_mean(hi):.3g} (higher group, n = {hi.size}), difference {estimate:+.3g}")
    else:
        reference = 0.0 if test.kind == "compare" else test.value
        estimate = location(y, test.method) - reference
        what = "paired difference higher - lower" if test.kind == "compare" else f"distance from {reference:g}"
        where = {"t": "mean", "sign": "median", "wilcoxon": "pseudo-median"}[test.method]
        if np.isin(y, (0.0, 1.0)).all():
            where = "share"
        detail = f"{name} = {statistic:.4g}; {where} {what} {estimate:+.3g} (mean {float(y.mean()) - reference:+.3g})"
        if data.note:
            detail += f"; {data.note}"
    return LeafResult(test.method, statistic, p, int(sign), estimate, n, detail)


def _mean(values: np.ndarray) -> float:
    return float(values.mean()) if values.size else float("nan")
