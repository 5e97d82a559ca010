"""A report of a sweep of an external simulator (configs/external/vicsek.toml, runs shortened to 4 s): the
statistics, figures and its claim as for any sweep, and no re-simulated showcase (a command's runs cannot
be re-simulated: their output was measured and not kept)."""
from __future__ import annotations

import pandas as pd
import pytest

from flocksweep.analysis.reports.report import build_report
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT


@pytest.mark.slow
def test_report_of_an_external_simulator_sweep(tmp_path):
    config = load_sweep(ROOT / "configs" / "external" / "vicsek.toml", ["model.parameters.duration.default=4.0"])
    run_sweep(config, None, tmp_path / "results", executor="serial", progress=False)
    result = build_report(tmp_path / "results", tmp_path / "report")
    md = result["paths"]["md"].read_text()
    for section in ("Overview", "Claims, tested", "Which factor matters", "Heatmaps", "Time series"):
        assert section in md
    assert "Showcase runs" not in md and "Watch the showcase runs" not in md
    tests = pd.read_csv(tmp_path / "report" / "tables" / "factor_tests.csv")
    assert set(tests["factor"]) == {"noise", "radius"}
    claims = pd.read_csv(tmp_path / "report" / "tables" / "claims.csv").set_index("claim")
    assert claims.loc["noise-disorders", "verdict"] == "supported"
