"""`flocksweep report`: the report renders on real sweep results with every figure and table, the
Holland findings reach a verdict from data, and the verdict logic follows the data on synthetic tables;
`run --until-ci` adds replicates only where the confidence interval is too wide."""
from __future__ import annotations

import re
from html import unescape
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.reports.findings import holland_findings
from analysis.reports.report import ReportError, build_report, resolve_metrics
from sweeps.cli import main
from sweeps.config import load_sweep, sweep_from_dict
from sweeps.results import load_results
from sweeps.runner import halfwidths, run_sweep, run_until_ci
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
PNG = b"\x89PNG\r\n\x1a\n"
VERDICTS = {"supported", "not supported", "inconclusive"}


@pytest.fixture(scope="module")
def smoke_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("smoke") / "results"
    config = load_sweep(ROOT / "configs/sweeps/smoke.toml")
    run_sweep(config, (ROOT / "configs/sweeps/smoke.toml").read_text(), out, executor="serial", progress=False)
    return out


@pytest.fixture(scope="module")
def holland_like(tmp_path_factory):
    """A small Holland-like grid: mode x direction x field, 12 boids, 4 s, 2 replicates (32 runs)."""
    data = {"name": "holland_like", "seed": 5, "replicates": 2, "model": {"preset": HOLLAND},
            "run": {"n": 12, "duration": 4.0, "record_interval": 0.5, "warmup": 1.0},
            "axes": [{"name": "mode", "key": "patterns.enabled", "values": [False, True],
                      "labels": ["normal", "pattern"]},
                     {"key": "perception.direction_deg", "values": [20, 90]},
                     {"key": "perception.field_deg", "values": [30, 60, 120, 180]}],
            "report": {"showcase": {"wide": {"mode": "normal", "perception.direction_deg": 90,
                                             "perception.field_deg": 180}}}}
    out = tmp_path_factory.mktemp("holland_like") / "results"
    run_sweep(sweep_from_dict(data, ROOT), "# test sweep\n", out, executor="serial", progress=False)
    return out


@pytest.mark.slow
def test_report_renders_every_figure_and_table(smoke_results, tmp_path):
    result = build_report(smoke_results, tmp_path / "report")
    html = result["paths"]["html"].read_text()
    md = result["paths"]["md"].read_text()
    figures = re.findall(r"\]\((figures/[^)]+\.(?:png|svg))\)", md)
    assert len(figures) >= 8
    for rel in figures:
        path = tmp_path / "report" / rel
        assert path.stat().st_size > 2000, rel
        if rel.endswith(".png"):
            assert path.read_bytes()[:8] == PNG
    assert html.count("data:image/png;base64,") == md.count("![")     # every figure embedded in the HTML
    assert not re.search(r"<img[^>]+src='(?!data:)", html)             # and nothing linked from outside
    for name in ("design", "factor_tests", "main_effects", "adjacent_comparisons", "two_way_tests",
                 "cell_summaries", "findings"):
        table = pd.read_csv(tmp_path / "report" / "tables" / f"{name}.csv")
        assert len(table), name
    tests = pd.read_csv(tmp_path / "report" / "tables" / "factor_tests.csv")
    assert {"H", "p", "epsilon2", "p_holm"} <= set(tests.columns)
    assert set(tests["factor"]) == {"mode", "perception.field_deg"}
    for section in ("Overview", "Which factor matters", "Heatmaps", "Time series", "Replicate adequacy",
                    "Holland & Semwal's findings"):
        assert section in md and section in unescape(html)


@pytest.mark.slow
def test_report_tables_are_reproducible_from_the_results(smoke_results, tmp_path):
    build_report(smoke_results, tmp_path / "a", formats=("md",))
    build_report(smoke_results, tmp_path / "b", formats=("md",))
    for name in ("main_effects", "factor_tests", "cell_summaries"):
        a = pd.read_csv(tmp_path / "a" / "tables" / f"{name}.csv")
        b = pd.read_csv(tmp_path / "b" / "tables" / f"{name}.csv")
        pd.testing.assert_frame_equal(a, b)


@pytest.mark.slow
def test_holland_findings_reach_verdicts_on_a_small_holland_like_sweep(holland_like, tmp_path):
    findings = holland_findings(load_results(holland_like).runs)
    assert [f.key for f in findings] == ["a", "b", "c", "d", "e"]
    for f in findings:
        assert f.verdict in VERDICTS
        assert f.tests and all(np.isfinite(t.p_holm) for t in f.tests)
    result = build_report(holland_like, tmp_path / "report")
    checks = pd.read_csv(tmp_path / "report" / "tables" / "showcase_checks.csv")
    assert checks["identical"].all()            # the showcase run re-simulates bit for bit
    table = result["tables"]["findings"]
    assert set(table["verdict"]) <= VERDICTS


def _synthetic(field_effect: float, seed: int = 0, n_per: int = 20) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for field in (30, 60, 90, 120, 150, 180):
        for direction in (0, 45, 90):
            for mode in ("normal", "pattern"):
                for _ in range(n_per):
                    cohesion = np.clip(0.5 + field_effect * (field - 105) / 150 + rng.normal(0, 0.1), 0, 1)
                    rows.append({"status": "ok", "mode": mode, "perception.field_deg": float(field),
                                 "perception.direction_deg": float(direction), "cohesion_mean": cohesion,
                                 "polarization_mean": cohesion + rng.normal(0, 0.05),
                                 "fragmented": float(cohesion < 0.5),
                                 "speed_mean_mean": 5 - field_effect * field / 100 + rng.normal(0, 0.3),
                                 "aspect_heading_mean": 2 - field_effect * field / 100 + rng.normal(0, 0.3),
                                 "segregation_mean": (0.1 if mode == "pattern" else 0.0) * field_effect
                                 + rng.normal(0, 0.02) * (mode == "pattern")})
    return pd.DataFrame(rows)


def test_verdicts_follow_planted_effects():
    verdicts = {f.key: f.verdict for f in holland_findings(_synthetic(+1.0))}
    assert verdicts == {"a": "supported", "b": "supported", "c": "inconclusive", "d": "supported",
                        "e": "supported"}
    # c: direction has no planted effect at field 60 -> never "supported"


def test_verdicts_turn_when_the_effect_is_reversed_or_absent():
    reversed_ = {f.key: f.verdict for f in holland_findings(_synthetic(-1.0))}
    assert reversed_["a"] == "not supported" and reversed_["b"] == "not supported"
    assert reversed_["d"] == "not supported" and reversed_["e"] == "not supported"
    absent = {f.key: f.verdict for f in holland_findings(_synthetic(0.0, seed=3))}
    assert absent["a"] != "supported" and absent["b"] != "supported" and absent["d"] != "supported"


def test_findings_need_their_factors():
    table = _synthetic(1.0).drop(columns=["perception.direction_deg"])
    assert [f.key for f in holland_findings(table)] == ["a", "b", "d", "e"]
    assert holland_findings(table.drop(columns=["perception.field_deg", "mode"])) == []


def test_metric_names_and_aliases_resolve(smoke_results):
    results = load_results(smoke_results)
    assert resolve_metrics(results, ["alignment", "groups", "cohesion_final"]) == \
        ["polarization_mean", "n_groups_mean", "cohesion_final"]
    with pytest.raises(ReportError, match="unknown metric 'cohesian'"):
        resolve_metrics(results, ["cohesian"])


@pytest.mark.slow
def test_report_cli_end_to_end_and_bad_input(smoke_results, tmp_path, capsys):
    assert main(["report", str(smoke_results), "--out", str(tmp_path / "r"), "--format", "html",
                 "--metrics", "cohesion", "alignment"]) == 0
    out = capsys.readouterr().out
    assert "report.html" in out and "finding (a)" in out
    assert (tmp_path / "r" / "report.html").exists() and not (tmp_path / "r" / "report.md").exists()
    assert main(["report", str(smoke_results), "--by", "perception.feild_deg"]) == 2
    assert "unknown factor" in capsys.readouterr().err
    assert main(["report", str(tmp_path / "nothing")]) == 2


def test_until_ci_adds_replicates_only_where_needed(tmp_path):
    data = {"name": "ci", "seed": 2, "replicates": 2, "model": {"preset": HOLLAND},
            "run": {"n": 10, "duration": 2.0, "record_interval": 0.5, "warmup": 0.5},
            "axes": [{"key": "perception.field_deg", "values": [40, 360]}]}
    config = sweep_from_dict(data, ROOT)
    out = tmp_path / "ci"
    result = run_until_ci(config, "", out, "cohesion_mean", 0.05, 8, log=lambda *_: None,
                          executor="serial", progress=False)
    table = result.table
    assert table["run_id"].is_unique and (table["status"] == "ok").all()
    widths = halfwidths(table, "cohesion_mean")
    per_point = table.groupby("point_index").size()
    for point, width in widths["halfwidth"].items():
        assert width <= 0.05 or per_point[point] == 8      # target met, or capped
    assert per_point.min() >= 2
    # rerunning finds everything done: the store is reused, nothing recomputed
    again = run_until_ci(config, "", out, "cohesion_mean", 0.05, 8, log=lambda *_: None,
                         executor="serial", progress=False)
    assert len(again.plan.todo) == 0 and len(again.table) == len(table)


def _leadership_table(seed: int = 0, reverse: bool = False) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for x in (0.0, 0.5, 1.0, 2.0, 3.0):
        for _ in range(12):
            effect = -x if reverse else x
            rate = 0.0 if x == 0 else max(0.0, 3 * x + rng.normal(0, 0.5))
            rows.append({"status": "ok", "leadership.x": x, "trigger_rate": rate,
                         "leaders_mean": rate / 10, "follow_corr_max": np.nan if x == 0 else 0.5 + rng.normal(0, 0.1),
                         "follow_lag_max": np.nan if x == 0 else 0.3 + abs(rng.normal(0, 0.1)),
                         "follow_corr_before": np.nan if x == 0 else 0.4 + rng.normal(0, 0.1),
                         "n_groups_mean": 1 + max(0.0, 2 * effect) + rng.normal(0, 0.3),
                         "cohesion_mean": float(np.clip(1 - 0.1 * effect + rng.normal(0, 0.03), 0, 1))})
    return pd.DataFrame(rows)


def test_leadership_verdicts_follow_planted_effects():
    from analysis.reports.findings import leadership_findings

    verdicts = {f.key: f.verdict for f in leadership_findings(_leadership_table())}
    assert verdicts == {"a": "supported", "b": "supported", "c": "supported", "d": "supported"}
    reversed_ = {f.key: f.verdict for f in leadership_findings(_leadership_table(reverse=True))}
    assert reversed_["d"] == "not supported"
    table = _leadership_table()
    table.loc[table["leadership.x"] == 0, "trigger_rate"] = 0.2       # a trigger at X = 0
    assert {f.key: f.verdict for f in leadership_findings(table)}["a"] == "not supported"
    assert leadership_findings(table.drop(columns=["trigger_rate"])) == []


@pytest.fixture(scope="module")
def leadership_results(tmp_path_factory):
    """A small leadership sweep on the hartman_benes preset: X x 2 replicates, 20 boids, 6 s."""
    data = {"name": "lead", "seed": 3, "replicates": 2,
            "model": {"preset": str(ROOT / "configs/models/hartman_benes.toml")},
            "run": {"n": 20, "duration": 6.0, "record_interval": 0.1, "warmup": 1.0},
            "axes": [{"key": "leadership.x", "values": [0, 0.5, 2]}]}
    out = tmp_path_factory.mktemp("lead") / "results"
    run_sweep(sweep_from_dict(data, ROOT), "", out, executor="serial", progress=False)
    return out


def test_events_increase_with_x_on_a_small_sweep(leadership_results):
    runs = load_results(leadership_results).runs
    assert (runs["status"] == "ok").all()
    rates = runs.groupby("leadership.x")["trigger_rate"].mean()
    assert rates.loc[0.0] == 0.0
    assert 0.0 < rates.loc[0.5] < rates.loc[2.0]
    assert {"leaders_mean", "follow_corr_max", "follow_corr_before", "heading_change_deg"} <= set(runs.columns)


@pytest.mark.slow
def test_report_has_a_leadership_section_with_verdicts(leadership_results, tmp_path):
    result = build_report(leadership_results, tmp_path / "report", formats=("md",))
    md = result["paths"]["md"].read_text()
    assert "## Change of leadership" in md and "Hartman & Benes' findings, tested" in md
    assert (tmp_path / "report" / "figures" / "leadership_vs_x.png").stat().st_size > 10_000
    findings = result["tables"]["leadership_findings"]
    assert list(findings["finding"].unique()) == ["a", "b", "c", "d"]
    assert set(findings["verdict"]) <= VERDICTS
    assert findings.loc[findings["finding"] == "a", "verdict"].iloc[0] == "supported"
