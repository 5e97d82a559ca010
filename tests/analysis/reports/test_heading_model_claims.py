"""Claims of the Vicsek (1995) and Couzin et al. (2002) models on tiny sweeps with fixed seeds: each sweep
is run, stored and loaded, and its declared claim judged as `flocksweep report` judges it
(:func:`analysis.reports.claims.evaluate.evaluate`).

* Vicsek: 40 boids at density 4 in 2-D, eta = 0.5 against eta = 5.5, 3 replicates of 300 steps: the
  claim "less noise, more order" is supported, with polarization above 0.9 at eta = 0.5 and below 0.35
  at eta = 5.5 (40 random headings give about 0.14; the tolerances leave room for 3 short runs).
* Couzin (slow): 100 boids in 3-D, orientation zone width 1 against 12, 3 replicates of 60 s: milling
  above 0.6 in the torus, polarization above 0.95 in the parallel group, and the claim "a wider zone of
  orientation gives a more polarised group" supported.
"""
from __future__ import annotations

import pytest

from flocksweep.analysis.reports.claims.evaluate import evaluate
from flocksweep.analysis.reports.claims.load import claims_of
from paths import ROOT
from flocksweep.sweeps import load_results, run_sweep
from flocksweep.sweeps.config import sweep_from_dict


def judged(tmp_path, data):
    run_sweep(sweep_from_dict(data, ROOT), tmp_path / "out", executor="serial", progress=False)
    results = load_results(tmp_path / "out")
    claims, columns, skipped = claims_of(results)
    assert not skipped
    return results, {o.claim.id: o for o in evaluate(claims, results.runs, columns.factors, with_power=False)}


def compare_claim(metric, factor, low, high):
    return {"id": "more", "statement": f"{metric} is higher at {factor} = {high} than at {low}.", "test": "compare",
            "metric": metric, "lower": f"{factor} == {low}", "higher": f"{factor} == {high}", "method": "welch",
            "effect": 0.2}


@pytest.mark.slow
def test_vicsek_less_noise_more_order(tmp_path):
    data = {"name": "tiny_vicsek", "seed": 11, "replicates": 3,
            "model": {"preset": str(ROOT / "configs/models/vicsek.toml"),
                      "set": {"world.box_size": 40 ** 0.5, "init.radius": 40 ** 0.5 / 2}},
            "run": {"n": 40, "duration": 300.0, "record_interval": 10.0, "warmup": 100.0},
            "axes": [{"key": "vicsek.noise", "values": [5.5, 0.5]}],
            "claims": [compare_claim("polarization_mean", "vicsek.noise", 5.5, 0.5)]}
    results, outcomes = judged(tmp_path, data)
    means = results.runs.groupby("vicsek.noise")["polarization_mean"].mean()
    assert means[0.5] > 0.9 and means[5.5] < 0.35
    assert outcomes["more"].outcome.verdict == "supported"


@pytest.mark.slow
def test_couzin_wider_orientation_zone_more_polarised(tmp_path):
    data = {"name": "tiny_couzin", "seed": 12, "replicates": 3,
            "model": {"preset": str(ROOT / "configs/models/couzin2002_torus.toml")},
            "run": {"duration": 60.0, "record_interval": 1.0, "warmup": 30.0},
            "axes": [{"key": "couzin.orientation_width", "values": [1.0, 12.0]}],
            "claims": [compare_claim("polarization_mean", "couzin.orientation_width", 1.0, 12.0)]}
    results, outcomes = judged(tmp_path, data)
    by_width = results.runs.groupby("couzin.orientation_width")[["polarization_mean", "milling_mean"]].mean()
    assert by_width.loc[1.0, "milling_mean"] > 0.6 and by_width.loc[12.0, "polarization_mean"] > 0.95
    assert outcomes["more"].outcome.verdict == "supported"
