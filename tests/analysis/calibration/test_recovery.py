"""Parameter recovery on a cheap configuration: targets simulated at a known field of vision are fitted
by BSL-MCMC; the truth must lie inside the 90% posterior interval and the posterior must be much
narrower than the prior. Plus the `flocksweep targets` tool that makes such synthetic targets."""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.run import run_calibration
from flocksweep.analysis.calibration.synthetic import synthetic_observation, truth_vector
from flocksweep.simcore import ConfigError
from flocksweep.cli import main
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
TRUTH_FIELD = 150.0
PRIOR = (60.0, 300.0)


def cheap(mean, **method) -> dict:
    return {"name": "recover_field", "seed": 2, "model": {"preset": HOLLAND},
            "run": {"n": 12, "duration": 3.0, "record_interval": 0.5, "warmup": 1.0},
            "parameters": {"field": {"key": "perception.field_deg",
                                     "prior": {"dist": "uniform", "low": PRIOR[0], "high": PRIOR[1]}}},
            "targets": {"stats": ["visible_mean", "binocular_share"], "mean": list(mean), "sd": [0.1, 0.02]},
            "method": {"kind": "emcee", "n_sim": 12, "walkers": 8, "steps": 120, "reevaluate_every": 30,
                       **method}}


@pytest.fixture(scope="module")
def observed():
    config = calibration_from_dict(cheap([0.5, 1.0]), ROOT)
    row = synthetic_observation(config, {"field": TRUTH_FIELD}, seed=5)
    assert row.shape == (1, 2) and np.isfinite(row).all()
    return row[0]


@pytest.mark.slow
def test_field_of_vision_is_recovered(observed, tmp_path):
    config = calibration_from_dict(cheap(observed), ROOT)
    result = run_calibration(config, tmp_path / "out", progress=False, predictive_draws=20)
    row = result.summary.loc["field"]
    assert row["q5"] <= TRUTH_FIELD <= row["q95"], row.to_dict()
    prior_sd = (PRIOR[1] - PRIOR[0]) / np.sqrt(12.0)
    assert row["sd"] < 0.4 * prior_sd, (row["sd"], prior_sd)
    assert not result.warnings       # the targets do constrain the field
    assert (result.predictive["p"] > 0.01).all()


def test_synthetic_observation_is_deterministic_and_validated(observed):
    config = calibration_from_dict(cheap(observed), ROOT)
    again = synthetic_observation(config, [TRUTH_FIELD], seed=5)
    np.testing.assert_array_equal(again[0], observed)
    other = synthetic_observation(config, [TRUTH_FIELD], seed=6)
    assert not np.array_equal(other[0], observed)
    with pytest.raises(ConfigError, match="unknown parameter"):
        truth_vector(config, {"field": 100, "range": 3})
    with pytest.raises(ConfigError, match="missing"):
        truth_vector(config, {})
    with pytest.raises(ConfigError, match="outside the prior"):
        truth_vector(config, {"field": 400})


def test_targets_cli_prints_a_block_that_loads(observed, tmp_path, capsys):
    path = tmp_path / "cal.toml"
    data = cheap(observed)
    lines = ['name = "cli"', "[model]", f'preset = "{HOLLAND}"', "[run]", "n = 12", "duration = 3.0",
             "record_interval = 0.5", "warmup = 1.0", "[parameters.field]", 'key = "perception.field_deg"',
             'prior = { dist = "uniform", low = 60, high = 300 }', "[method]", 'kind = "emcee"', "n_sim = 12"]
    body = "\n".join(lines) + "\n"
    path.write_text(body + '[targets]\nstats = ["visible_mean", "binocular_share"]\nmean = [0.5, 1.0]\n'
                           'sd = [0.1, 0.02]\n')
    assert main(["targets", str(path), "--truth", "field=150", "--seed", "5"]) == 0
    block = capsys.readouterr().out
    parsed = tomllib.loads(block)["targets"]
    np.testing.assert_allclose(parsed["mean"], observed, rtol=1e-5)
    assert parsed["sd"] == data["targets"]["sd"] and parsed["truth"] == {"field": 150}
    assert {"n_groups", "nn_distance", "fragmented", "speed_mean"} <= set(parsed["flock"])   # the same run's flock
    assert parsed["flock"]["fragmented"] in (0, 1) and parsed["flock"]["n_groups"] >= 1
    path.write_text(body + block)                       # the printed block is a valid [targets] table
    assert main(["targets", str(path), "--truth", "field=150", "--replicates", "3", "--sd", "0.1,0.2"]) == 0
    assert "means of 3 runs" in capsys.readouterr().out
    assert main(["targets", str(path), "--truth", "fov=150"]) == 2
    assert "--truth" in capsys.readouterr().err
