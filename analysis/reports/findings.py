"""The papers' claims as testable hypotheses, judged from a sweep's results table: Holland & Semwal's
vision findings (``holland_findings``) and Hartman & Benes' leadership findings (``leadership_findings``).

``holland_findings(runs, alpha=0.05) -> list[Finding]`` evaluates every claim whose factors are in the
table (ok runs only; NaN metric values dropped per test). Each finding states the hypothesis, the test,
its statistics, and a verdict: ``supported``, ``not supported`` or ``inconclusive``. p-values are
Holm-adjusted across all the tests of all findings (one family). The verdict comes from the data only:

(a) wider field of vision -> more cohesive, more aligned: Spearman rho of field vs ``cohesion_mean``
    and vs ``polarization_mean``; supported when both are positive and significant, not supported when
    either is significantly negative, else inconclusive.
(b) below a field of 90 degrees cohesion breaks down and the flock disperses: runs with field < 90 vs
    field >= 90, one-sided Mann-Whitney for lower ``cohesion_mean``, and the share of runs below 90 that
    fragment (``fragmented``: cohesion fell below the fragmentation threshold after warmup); supported
    when cohesion is significantly lower and most (> 50%) of the runs below 90 fragment; not supported
    when cohesion is not significantly lower; inconclusive when lower but most runs hold together.
(c) at field 60, a more lateral direction of vision improves cohesion and alignment (samples 1 and 2):
    Spearman rho of direction vs ``cohesion_mean`` and ``polarization_mean`` within field = 60; verdict
    as (a).
(d) narrow fields give faster, elongated flocks (leapfrog): Spearman rho of field vs ``speed_mean_mean``
    and vs ``aspect_heading_mean`` (extent along the heading over width of the largest group); supported
    when both are negative and significant, not supported when either is significantly positive, else
    inconclusive.
(e) in pattern mode boids of a pattern segregate (Table 1 set, sample 4): one-sided Wilcoxon
    signed-rank test of ``segregation_mean`` > 0 over the pattern-mode runs (0 means random mixing);
    supported when significant, not supported when significantly < 0 or the median is <= 0 with p >= alpha,
    inconclusive otherwise (e.g. too few runs).

Leadership (``leadership_findings``; factor ``leadership.x``, with the leadership metrics of
``analysis/leadership.py``):

(a) X = 0 is the base model: no trigger and no leader in any run at X = 0 (supported, else not supported;
    bit-identity with the model without leadership is proven by the test suite, not by a sweep);
(b) events rise with X: Spearman rho of X vs ``trigger_rate`` > 0 and significant;
(c) leaders are followed: over runs with X > 0, one-sided Wilcoxon tests that the follow correlation
    (``follow_corr_max``) is > 0 and that it rises above the same correlation before the trigger
    (``follow_corr_max - follow_corr_before`` > 0); the lag of the maximum is reported alongside;
(d) high X fragments the flock: Spearman rho of X vs ``n_groups_mean`` > 0 and vs ``cohesion_mean`` < 0,
    both significant.
Verdicts as for (a) of Holland's: supported when all tests go the claimed way significantly, not
supported when any goes significantly the other way, else inconclusive.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import stats

from .stats import holm

FIELD = "perception.field_deg"
DIRECTION = "perception.direction_deg"
MODE_COLUMNS = ("mode", "patterns.enabled")


@dataclass
class Test:
    name: str
    statistic: float
    p: float
    n: int
    direction: float  # sign of the effect (+1, -1, 0)
    detail: str
    p_holm: float = float("nan")


@dataclass
class Finding:
    key: str
    claim: str
    hypothesis: str
    tests: list[Test] = field(default_factory=list)
    verdict: str = "inconclusive"
    summary: str = ""
    facts: dict = field(default_factory=dict)


def _trend(runs: pd.DataFrame, factor: str, metric: str, label: str) -> Test:
    data = runs[[factor, metric]].dropna()
    if len(data) < 3 or data[factor].nunique() < 2 or data[metric].nunique() < 2:
        return Test(label, float("nan"), float("nan"), len(data), 0.0, "too few distinct values")
    rho, p = stats.spearmanr(data[factor], data[metric])
    return Test(label, float(rho), float(p), len(data), float(np.sign(rho)), f"Spearman rho = {rho:+.3f}")


def _pattern_runs(runs: pd.DataFrame) -> pd.DataFrame | None:
    if "patterns.enabled" in runs:
        return runs[runs["patterns.enabled"].astype(bool)]
    if "mode" in runs:
        return runs[runs["mode"] == "pattern"]
    return None


def _judge_pair(tests: list[Test], alpha: float, want: float) -> str:
    significant = [t for t in tests if t.p_holm < alpha]
    if any(t.direction == -want for t in significant):
        return "not supported"
    if len(significant) == len(tests) and all(t.direction == want for t in tests):
        return "supported"
    return "inconclusive"


def _finding_a(runs):
    f = Finding("a", "Wider field of vision gives more cohesive, more aligned flocks.",
                "cohesion and polarization increase with field of vision (Spearman rho > 0)")
    f.tests = [_trend(runs, FIELD, "cohesion_mean", "field vs cohesion"),
               _trend(runs, FIELD, "polarization_mean", "field vs polarization")]
    return f, lambda alpha: _judge_pair(f.tests, alpha, +1.0)


def _finding_b(runs):
    f = Finding("b", "Below a field of vision of 90 degrees flock cohesion breaks down and the flock disperses.",
                "cohesion is lower for field < 90 than for field >= 90, and most runs below 90 fragment")
    data = runs[[FIELD, "cohesion_mean", "fragmented"]].dropna(subset=[FIELD, "cohesion_mean"])
    below, above = data[data[FIELD] < 90], data[data[FIELD] >= 90]
    if len(below) and len(above):
        u, p = stats.mannwhitneyu(below["cohesion_mean"], above["cohesion_mean"], alternative="less")
        diff = below["cohesion_mean"].mean() - above["cohesion_mean"].mean()
        f.tests = [Test("cohesion below 90 < at or above 90", float(u), float(p), len(data), float(np.sign(diff)),
                        f"median cohesion {below['cohesion_mean'].median():.3f} vs "
                        f"{above['cohesion_mean'].median():.3f} (one-sided Mann-Whitney U = {u:.0f})")]
    share = float(below["fragmented"].mean()) if len(below) else float("nan")
    share_above = float(above["fragmented"].mean()) if len(above) else float("nan")
    f.facts = {"fragmented_share_below_90": share, "fragmented_share_at_or_above_90": share_above}

    def judge(alpha):
        if not f.tests or not f.tests[0].p_holm < alpha:
            return "not supported" if f.tests else "inconclusive"
        return "supported" if share > 0.5 else "inconclusive"
    return f, judge


def _finding_c(runs):
    f = Finding("c", "With a field of 60 degrees, a more lateral direction of vision improves cohesion and "
                "alignment (samples 1 and 2).",
                "within field = 60, cohesion and polarization increase with direction of vision")
    subset = runs[np.isclose(runs[FIELD].astype(float), 60.0)]
    f.tests = [_trend(subset, DIRECTION, "cohesion_mean", "direction vs cohesion (field 60)"),
               _trend(subset, DIRECTION, "polarization_mean", "direction vs polarization (field 60)")]
    f.facts = {"runs_at_field_60": int(len(subset))}
    return f, lambda alpha: _judge_pair(f.tests, alpha, +1.0)


def _finding_d(runs):
    f = Finding("d", "Narrow fields of vision give faster, elongated flocks (the leapfrog effect).",
                "speed and the largest group's length-over-width along its heading decrease with field")
    f.tests = [_trend(runs, FIELD, "speed_mean_mean", "field vs speed"),
               _trend(runs, FIELD, "aspect_heading_mean", "field vs aspect along heading")]
    return f, lambda alpha: _judge_pair(f.tests, alpha, -1.0)


def _finding_e(runs):
    f = Finding("e", "In pattern mode, boids of a pattern segregate (Table 1 pattern set, sample 4).",
                "segregation (same-pattern share among neighbours minus random mixing) > 0 in pattern mode")
    pattern = _pattern_runs(runs)
    values = pattern["segregation_mean"].dropna() if pattern is not None else pd.Series(dtype=float)
    if len(values) >= 5 and values.nunique() > 1:
        w, p = stats.wilcoxon(values, alternative="greater")
        med = float(values.median())
        f.tests = [Test("segregation > 0 (pattern mode)", float(w), float(p), len(values),
                        float(np.sign(med)), f"median segregation {med:+.3f} (one-sided Wilcoxon W = {w:.0f})")]
    f.facts = {"pattern_runs": int(len(values)), "median_segregation": float(values.median()) if len(values) else float("nan")}

    def judge(alpha):
        if not f.tests:
            return "inconclusive"
        t = f.tests[0]
        if t.p_holm < alpha and t.direction > 0:
            return "supported"
        return "not supported" if t.direction <= 0 else "inconclusive"
    return f, judge


def applicable(runs: pd.DataFrame) -> list:
    builders = []
    has = set(runs.columns)
    if FIELD in has and runs[FIELD].nunique() > 1:
        builders += [_finding_a, _finding_b, _finding_d]
    if FIELD in has and DIRECTION in has and runs[DIRECTION].nunique() > 1 and np.isclose(runs[FIELD], 60).any():
        builders.append(_finding_c)
    if any(c in has for c in MODE_COLUMNS) and "segregation_mean" in has:
        pattern = _pattern_runs(runs)
        if pattern is not None and len(pattern):
            builders.append(_finding_e)
    return sorted(builders, key=lambda b: b.__name__)


def _evaluate(built: list, alpha: float) -> list[Finding]:
    """Holm-adjust every test of the built findings as one family, then judge each finding."""
    tests = [t for f, _ in built for t in f.tests]
    adjusted = holm(np.array([t.p for t in tests], dtype=float)) if tests else []
    for t, p in zip(tests, adjusted):
        t.p_holm = float(p)
    findings = []
    for f, judge in built:
        f.verdict = judge(alpha)
        parts = [t.detail + (f", p = {t.p_holm:.2g} (Holm)" if np.isfinite(t.p_holm) else "") + f", n = {t.n}"
                 for t in f.tests]
        f.summary = "; ".join(parts) if parts else "no test possible with these data"
        findings.append(f)
    return findings


def holland_findings(runs: pd.DataFrame, alpha: float = 0.05) -> list[Finding]:
    """Evaluate the claims whose factors are present (see module docstring)."""
    ok = runs[runs["status"] == "ok"] if "status" in runs else runs
    return _evaluate([builder(ok) for builder in applicable(ok)], alpha)


# -- Hartman & Benes: change of leadership ------------------------------------------------------------

LEAD = "leadership.x"


def _lead_a(runs):
    f = Finding("a", "With leadership X = 0 the model is the base model (no boid ever leads).",
                "no trigger event and no leader in any run at X = 0")
    base = runs[np.isclose(runs[LEAD].astype(float), 0.0)]
    with_events = int((base["trigger_rate"].fillna(0) > 0).sum() + (base["leaders_mean"].fillna(0) > 0).sum())
    f.tests = [Test("runs at X = 0 with a trigger or a leader", float(with_events), float("nan"), len(base),
                    0.0, f"{with_events} of {len(base)} runs at X = 0 had a trigger or a leader")]
    f.facts = {"runs_at_x0": int(len(base))}

    def judge(alpha):
        if not len(base):
            return "inconclusive"
        return "supported" if with_events == 0 else "not supported"
    return f, judge


def _lead_b(runs):
    f = Finding("b", "Trigger events (boids shooting off) become more frequent as X grows.",
                "the trigger rate (events per boid per minute) increases with X (Spearman rho > 0)")
    f.tests = [_trend(runs, LEAD, "trigger_rate", "X vs trigger rate")]
    return f, lambda alpha: _judge_pair(f.tests, alpha, +1.0)


def _one_sided_positive(values: pd.Series, label: str, what: str) -> Test:
    values = values.dropna()
    if len(values) < 5 or values.nunique() < 2:
        return Test(label, float("nan"), float("nan"), len(values), 0.0, "too few runs")
    w, p = stats.wilcoxon(values, alternative="greater")
    med = float(values.median())
    return Test(label, float(w), float(p), len(values), float(np.sign(med)),
                f"median {what} {med:+.3g} (one-sided Wilcoxon W = {w:.0f})")


def _lead_c(runs):
    f = Finding("c", "Leaders are followed: after a boid shoots off, its group turns after it.",
                "after a trigger, the heading correlation between the leader and its group (at its best lag "
                "0..2 s, after Nagy et al. 2010) is positive and higher than in the escape-long window before")
    led = runs[runs[LEAD].astype(float) > 0]
    rise = led["follow_corr_max"] - led["follow_corr_before"] if "follow_corr_before" in led else led["follow_corr_max"] * np.nan
    f.tests = [_one_sided_positive(led["follow_corr_max"], "follow correlation > 0", "follow correlation"),
               _one_sided_positive(rise, "follow correlation after > before", "rise of the correlation")]
    f.facts = {"median_follow_corr_max": float(led["follow_corr_max"].median()),
               "median_follow_lag_max_s": float(led["follow_lag_max"].median())}
    return f, lambda alpha: _judge_pair(f.tests, alpha, +1.0)


def _lead_d(runs):
    f = Finding("d", "High X breaks the flock into parts.",
                "the number of groups rises and cohesion falls with X (Spearman)")
    f.tests = [_trend(runs, LEAD, "n_groups_mean", "X vs number of groups"),
               _trend(runs, LEAD, "cohesion_mean", "X vs cohesion")]
    f.tests[1].direction = -f.tests[1].direction  # falling cohesion counts as support

    def judge(alpha):
        return _judge_pair(f.tests, alpha, +1.0)
    return f, judge


def leadership_findings(runs: pd.DataFrame, alpha: float = 0.05) -> list[Finding]:
    """Hartman & Benes' claims, when ``leadership.x`` is a factor with leadership metrics in the table."""
    ok = runs[runs["status"] == "ok"] if "status" in runs else runs
    needed = {LEAD, "trigger_rate", "leaders_mean", "follow_corr_max", "follow_corr_before", "follow_lag_max",
              "n_groups_mean", "cohesion_mean"}
    if not needed <= set(ok.columns) or ok[LEAD].nunique() < 2:
        return []
    return _evaluate([b(ok) for b in (_lead_a, _lead_b, _lead_c, _lead_d)], alpha)


def findings_table(findings: list[Finding]) -> pd.DataFrame:
    rows = []
    for f in findings:
        for t in f.tests or [Test("(none)", float("nan"), float("nan"), 0, 0.0, "")]:
            rows.append({"finding": f.key, "claim": f.claim, "verdict": f.verdict, "test": t.name,
                         "statistic": t.statistic, "n": t.n, "p": t.p, "p_holm": t.p_holm, "detail": t.detail,
                         **{f"fact_{k}": v for k, v in f.facts.items()}})
    return pd.DataFrame(rows)
