"""`flocksweep report`: the report renders on real sweep results with every figure and table, declared
claims (Holland & Semwal's, Hartman & Benes') reach verdicts from data with their evidence; `run
--until-ci` adds replicates only where the confidence interval is too wide. (The verdict logic on
synthetic tables is in test_claims_verdicts.py.)"""
from __future__ import annotations

import re
from html import unescape
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.reports.report import ReportError, build_report, resolve_metrics
from flocksweep.cli import main
from flocksweep.sweeps.config import load_sweep, sweep_from_dict
from flocksweep.sweeps.results import load_results
from flocksweep.sweeps.runner import halfwidths, run_sweep, run_until_ci
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
PNG = b"\x89PNG\r\n\x1a\n"
VERDICTS = {"supported", "partly supported", "not supported", "inconclusive"}
CLAIMS = ROOT / "configs/claims"


@pytest.fixture(scope="module")
def smoke_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("smoke") / "results"
    config = load_sweep(ROOT / "configs/sweeps/smoke.toml")
    run_sweep(config, (ROOT / "configs/sweeps/smoke.toml").read_text(), out, executor="serial", progress=False)
    return out


@pytest.fixture(scope="module")
def smoke_report(smoke_results, tmp_path_factory):
    """The smoke sweep's report (html and md), built once for the tests that read it."""
    out = tmp_path_factory.mktemp("smoke_report") / "report"
    build_report(smoke_results, out)
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
                                             "perception.field_deg": 180}}},
            "include_claims": [str(CLAIMS / "holland.toml")]}
    out = tmp_path_factory.mktemp("holland_like") / "results"
    run_sweep(sweep_from_dict(data, ROOT), "# test sweep\n", out, executor="serial", progress=False)
    return out


@pytest.mark.slow
def test_report_renders_every_figure_and_table(smoke_report):
    html = (smoke_report / "report.html").read_text()
    md = (smoke_report / "report.md").read_text()
    figures = re.findall(r"\]\((figures/[^)]+\.(?:png|svg))\)", md)
    assert len(figures) >= 8
    for rel in figures:
        path = smoke_report / rel
        assert path.stat().st_size > 2000, rel
        if rel.endswith(".png"):
            assert path.read_bytes()[:8] == PNG
    assert html.count("data:image/png;base64,") == md.count("![")     # every figure embedded in the HTML
    assert not re.search(r"<img[^>]+src='(?!data:)", html)             # and nothing linked from outside
    for name in ("design", "factor_tests", "main_effects", "adjacent_comparisons", "two_way_tests",
                 "cell_summaries", "claims", "claim_tests"):
        table = pd.read_csv(smoke_report / "tables" / f"{name}.csv")
        assert len(table), name
    tests = pd.read_csv(smoke_report / "tables" / "factor_tests.csv")
    assert {"H", "p", "epsilon2", "p_holm"} <= set(tests.columns)
    assert set(tests["factor"]) == {"mode", "perception.field_deg"}
    for section in ("Overview", "Claims, tested", "Which factor matters", "Heatmaps", "Time series",
                    "Replicate adequacy"):
        assert section in md and section in unescape(html)
    assert_smoke_comment_matches(pd.read_csv(smoke_report / "tables" / "claim_tests.csv"))


def assert_smoke_comment_matches(claim_tests: pd.DataFrame) -> None:
    """smoke.toml's comment on its claim says what its report shows: the verdict, p (Holm) and power."""
    text = (ROOT / "configs/sweeps/smoke.toml").read_text()
    comment = " ".join(line.lstrip("# ").strip() for line in text.splitlines() if line.startswith("#"))
    said = re.search(r'the report says "([a-z ]+)" \(p = ([0-9.]+), power ([0-9.]+)\)', comment)
    assert said, "smoke.toml's comment states the claim's verdict, p and power"
    row = claim_tests.set_index("claim").loc["wider-is-aligned"]
    assert said.group(1) == row["claim_verdict"]
    assert f"{row['p_holm']:.2g}" == f"{float(said.group(2)):.2g}" and f"{row['power']:.2f}" == said.group(3)


@pytest.mark.slow
def test_report_tables_are_reproducible_from_the_results(smoke_results, smoke_report, tmp_path):
    build_report(smoke_results, tmp_path / "again", formats=("md",))     # a second, independent build
    for name in ("main_effects", "factor_tests", "cell_summaries"):
        a = pd.read_csv(smoke_report / "tables" / f"{name}.csv")
        b = pd.read_csv(tmp_path / "again" / "tables" / f"{name}.csv")
        pd.testing.assert_frame_equal(a, b)


@pytest.mark.slow
def test_holland_claims_reach_verdicts_on_a_small_holland_like_sweep(holland_like, tmp_path):
    result = build_report(holland_like, tmp_path / "report")
    checks = pd.read_csv(tmp_path / "report" / "tables" / "showcase_checks.csv")
    assert checks["identical"].all()            # the showcase run re-simulates bit for bit
    claims, tests = result["tables"]["claims"], result["tables"]["claim_tests"]
    assert list(claims["claim"]) == ["a", "b", "c", "d", "e"]
    assert set(claims["verdict"]) <= VERDICTS and set(tests["verdict"]) <= VERDICTS - {"partly supported"}
    assert list(tests["test"]) == ["a.cohesion", "a.alignment", "b.cohesion", "b.disperses", "c.cohesion",
                                   "c.alignment", "d.faster", "d.elongated", "d.leapfrog", "e"]
    assert np.isfinite(tests["p_holm"]).all() and (tests["p_holm"] >= tests["p"]).all()
    # (d) is tested where the paper states it: direction of vision <= 20 (half of the 32 runs)
    assert (tests.loc[tests["claim"] == "d", "n"] == 16).all()
    assert (tests.loc[tests["claim"] == "c", "n"] == 8).all()        # field 60 only
    for claim in "abcde":
        assert (tmp_path / "report" / "figures" / f"claim_{claim}.png").stat().st_size > 5000
    md = result["paths"]["md"].read_text()
    assert "(d) Narrow fields of vision" in md and "Tested where `perception.direction_deg <= 20`" in md


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
    assert "report.html" in out and "claim (wider-is-aligned): " in out
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


@pytest.fixture(scope="module")
def leadership_results(tmp_path_factory):
    """A small leadership sweep on the hartman_benes preset: X x 2 replicates, 20 boids, 6 s."""
    data = {"name": "lead", "seed": 3, "replicates": 2,
            "model": {"preset": str(ROOT / "configs/models/hartman_benes.toml")},
            "run": {"n": 20, "duration": 6.0, "record_interval": 0.1, "warmup": 1.0},
            "axes": [{"key": "leadership.x", "values": [0, 0.5, 2]}],
            "include_claims": [str(CLAIMS / "hartman_benes.toml")]}
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
def test_report_has_a_leadership_section_and_claims(leadership_results, tmp_path):
    result = build_report(leadership_results, tmp_path / "report", formats=("md",))
    md = result["paths"]["md"].read_text()
    assert "## Change of leadership" in md and "## Claims, tested" in md
    assert (tmp_path / "report" / "figures" / "leadership_vs_x.png").stat().st_size > 10_000
    claims = result["tables"]["claims"].set_index("claim")
    assert list(claims.index) == ["a", "b", "c", "d"] and set(claims["verdict"]) <= VERDICTS
    assert claims.loc["a", "verdict"] == "supported"       # X = 0: no trigger, no leader in any run
    assert claims.loc["b", "verdict"] == "supported"       # events rise with X, even on 6 runs per level
