"""Viewer pages written by other commands: `flocksweep report` gives each showcase run a page beside the
report, linked from its still in the HTML and the Markdown; calibration writes a page of a run at the
posterior median."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.reports.report import build_report
from flocksweep.analysis.viewer.encode import decode_stream
from flocksweep.analysis.calibration.viewer_page import MEDIAN_PAGE, posterior_median_page
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")


def page_json(path: Path) -> dict:
    return json.loads(re.search(r'id="flock-data">(.*?)</script>', Path(path).read_text(), re.S).group(1))


@pytest.mark.slow
def test_report_links_every_showcase_still_to_its_viewer_page(tmp_path):
    data = {"name": "shows", "seed": 2, "replicates": 2, "model": {"preset": HOLLAND},
            "run": {"n": 10, "duration": 2.0, "record_interval": 0.5, "warmup": 0.5},
            "axes": [{"key": "perception.field_deg", "values": [60, 180]},
                     {"key": "perception.direction_deg", "values": [20, 90]}],
            "report": {"showcase": {"narrow": {"perception.field_deg": 60, "perception.direction_deg": 20},
                                    "wide view": {"perception.field_deg": 180, "perception.direction_deg": 90}}}}
    results = tmp_path / "results"
    run_sweep(sweep_from_dict(data, ROOT), "# test\n", results, executor="serial", progress=False)
    report = tmp_path / "results" / "report"
    (report / "viewer").mkdir(parents=True)
    (report / "viewer" / "stale.html").write_text("old")   # a page an earlier build wrote (and recorded) ...
    (report / "viewer" / "notes.html").write_text("mine")  # ... and a file of the user's
    (report / ".flocksweep-report.json").write_text(json.dumps({"files": ["viewer/stale.html"]}))
    result = build_report(results)
    out = result["out"]
    html, md = result["paths"]["html"].read_text(), result["paths"]["md"].read_text()
    runs = pd.read_parquet(results / "runs.parquet")
    for name, slug in (("narrow", "narrow"), ("wide view", "wide_view")):
        page = out / "viewer" / f"{slug}.html"
        assert page.is_file()
        assert f"href='viewer/{slug}.html'><img" in html  # the still is the link
        assert re.search(rf"\[!\[{name} \(run \w+\)\]\(figures/viewer_{slug}.png\)\]\(viewer/{slug}.html\)", md)
        assert (out / "figures" / f"viewer_{slug}.png").stat().st_size > 2000
        info = page_json(page)["info"]
        row = runs[runs["run_id"] == info["run id"]].iloc[0]
        assert row["replicate"] == 0 and info["reproduced"].startswith("bit for bit")
    assert not (out / "viewer" / "stale.html").exists()
    assert (out / "viewer" / "notes.html").read_text() == "mine"   # never delete what we did not write
    assert "Watch the showcase runs in 3-D" in html


def test_calibration_writes_a_page_at_the_posterior_median(tmp_path):
    config = load_calibration(ROOT / "configs/calibration/recover_holland.toml", ["run.duration=1.0", "run.warmup=0.5"])
    summary = pd.DataFrame({"median": [151.3, 44.6]}, index=pd.Index(["field", "direction"], name="parameter"))
    path = posterior_median_page(config, summary, tmp_path)
    assert path == tmp_path / MEDIAN_PAGE
    data = page_json(path)
    assert data["params"]["perception.field_deg"] == pytest.approx(151.3)
    assert data["params"]["perception.direction_deg"] == pytest.approx(44.6)
    assert data["info"]["median field"] == "151.3" and data["info"]["seed"] == config.seed
    assert data["n"] == 20 and data["frames"] == 61
    # the same run, simulated directly, is what the page shows
    from flocksweep.analysis.calibration.simulator import SummarySimulator
    from flocksweep.simcore import simulate_preset

    preset = SummarySimulator(config.preset_data, config.keys, config.targets.columns, 1,
                              config.warmup).preset(np.array([151.3, 44.6]))
    obs = simulate_preset(preset, config.seed, record_every=1)
    np.testing.assert_allclose(decode_stream(data["pos"]), obs.pos, atol=max(data["encoding"]["position_quantum"]))
