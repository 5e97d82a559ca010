"""Verdicts that speak, for every method (analysis.calibration.verdicts): posterior mass against a prior bound is
named, a fit whose predictive flocks split while the observed flock is one group fails whatever the tail
probabilities, and every fit ends with one line: credible, or not credible and why (report and
convergence.json)."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.run import run_calibration
from flocksweep.analysis.calibration.verdicts import bound_verdicts, credibility, group_verdict
from paths import ROOT

HOLLAND = str(ROOT / "configs" / "models" / "holland.toml")


def config_with(bounds, names=("field", "speed")):
    return SimpleNamespace(names=names, prior=SimpleNamespace(bounds=bounds))


def test_mass_against_a_prior_bound_is_named_with_the_share_and_the_bound():
    rng = np.random.default_rng(1)
    config = config_with([(30.0, 300.0), (0.0, 4.0)])
    field = np.where(rng.random(2000) < 0.38, rng.uniform(295, 300, 2000), rng.uniform(150, 250, 2000))
    speed = rng.uniform(1.0, 3.0, 2000)
    found = bound_verdicts(config, np.column_stack([field, speed]))
    assert [(f["parameter"], f["bound"], f["value"]) for f in found] == [("field", "upper", 300.0)]
    assert found[0]["share"] == pytest.approx(0.38, abs=0.03)
    assert "field: 38% of draws lie within 2% of the upper bound 300: widen the prior" in found[0]["message"]
    # a flat posterior puts 2% in each band: not flagged; an optimum in the band is
    flat = np.column_stack([rng.uniform(30, 300, 4000), rng.uniform(0, 4, 4000)])
    assert bound_verdicts(config, flat) == []
    assert [f["bound"] for f in bound_verdicts(config, [[100.0, 3.95]])] == ["upper"]


def flock_table(observed_fragmented, predictive_fragmented, n_groups=None):
    rows = {"polarization_mean": [0.9, True, 0.88], "fragmented": [observed_fragmented, False, predictive_fragmented]}
    if n_groups is not None:
        rows["n_groups_mean"] = [n_groups, False, 1.4]
    return pd.DataFrame([{"observed": o, "target": t, "pred_mean": m, "pred_sd": 0.1, "pred_q2.5": 0, "pred_q97.5": 1,
                          "p": 0.5, "disagrees": False, "n_pred": 100} for o, t, m in rows.values()], index=list(rows))


def test_a_fit_whose_flocks_split_fails_when_the_observed_flock_is_one_group():
    failing = group_verdict(None, flock_table(0.0, 0.78))
    assert not failing["passed"] and failing["observed_one_group"] and failing["predictive_fragmented"] == 0.78
    assert "78% of the predictive flocks split" in failing["message"]
    assert group_verdict(None, flock_table(0.0, 0.08))["passed"]                  # at most 10% allowed
    assert group_verdict(None, flock_table(1.0, 0.78))["passed"]                  # the observed flock split too
    assert group_verdict(None, flock_table(np.nan, 0.78, n_groups=1.0))["observed_one_group"]   # from n_groups
    assert group_verdict(None, flock_table(np.nan, 0.78)) is None                 # group structure not known


def outcome(**report):
    table = pd.DataFrame({"observed": [0.9], "pred_mean": [0.9], "p": [0.4]}, index=["polarization_mean"])
    return SimpleNamespace(report={"convergence": {"converged": True}, **report}, predictive=table, flock=None,
                           optimum=None)


def test_one_line_says_credible_or_not_and_every_reason():
    assert credibility(None, outcome()) == {"credible": True, "verdict": "credible: converged, every target and known "
                                            "flock statistic within its predictive spread", "reasons": []}
    bad = outcome(convergence={"converged": False, "coverage_ok": False},
                  group_structure={"passed": False, "predictive_fragmented": 0.78},
                  bounds=[{"message": "speed: 40% of draws lie within 2% of the upper bound 4: widen the prior, or "
                                      "the model cannot reach the data"}])
    bad.predictive.loc["polarization_mean", "p"] = 0.001
    verdict = credibility(None, bad)
    assert not verdict["credible"]
    assert verdict["verdict"].startswith("NOT credible: the estimator failed its held-out coverage check; "
                                         "polarization_mean lies in the tail")
    assert "78% of the predictive flocks split while the observed flock is one group" in verdict["verdict"]
    assert "upper bound 4" in verdict["verdict"]


def test_a_fit_of_a_scattering_flock_to_one_group_says_so_in_the_report_and_convergence_json(tmp_path):
    # range 1-3 body lengths: the boids hardly see each other, the flock splits at once; the observed one did not
    data = {"name": "scatter", "seed": 5, "model": {"preset": HOLLAND, "set": {"init.radius": 12.0}},
            "run": {"n": 8, "duration": 1.5, "record_interval": 0.5, "warmup": 0.5, "group_radius": 3.0},
            "parameters": {"range": {"key": "perception.range", "prior": {"dist": "uniform", "low": 1, "high": 3}}},
            "targets": {"stats": ["polarization"], "mean": [0.9], "sd": [0.05], "flock": {"fragmented": 0}},
            "method": {"kind": "emcee", "n_sim": 4, "walkers": 4, "steps": 2}}
    result = run_calibration(calibration_from_dict(data, ROOT), tmp_path / "out", progress=False, predictive_draws=10)
    report = json.loads((tmp_path / "out" / "convergence.json").read_text())
    assert report["group_structure"]["observed_one_group"] and not report["group_structure"]["passed"]
    assert not report["credible"] and report["verdict"].startswith("NOT credible")
    assert "of the predictive flocks split while the observed flock is one group" in report["verdict"]
    assert result.verdicts(calibration_from_dict(data, ROOT))[0] == report["verdict"]
    assert report["verdict"] in (tmp_path / "out" / "report.md").read_text()
    accounting = json.loads((tmp_path / "out" / "accounting.json").read_text())
    assert accounting["status"] == "done"
    assert accounting["accounting"]["simulations"]["predictive"] == report["predictive_runs"] == 8   # 4 walkers x 2
