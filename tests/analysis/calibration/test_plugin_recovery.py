"""A plug-in dynamics is calibrated like a built-in one: targets simulated from the example plug-in
(examples/couzin_like.py) at a known cruise speed are fitted by BSL-MCMC on a small budget; the truth lies
inside the 90% posterior interval, which is much narrower than the prior."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.run import run_calibration
from flocksweep.analysis.calibration.synthetic import synthetic_observation
from paths import ROOT

PRESET = str(ROOT / "examples" / "couzin_like.toml")
TRUTH = 3.5
PRIOR = (1.5, 6.0)


def calibration(mean) -> dict:
    return {"name": "recover_cruise", "seed": 4, "model": {"preset": PRESET},
            "run": {"n": 12, "duration": 3.0, "record_interval": 0.5, "warmup": 1.0},
            "parameters": {"cruise": {"key": "plugin.cruise_speed",
                                      "prior": {"dist": "uniform", "low": PRIOR[0], "high": PRIOR[1]}}},
            "targets": {"stats": ["speed_mean", "nn_distance"], "mean": list(mean), "sd": [0.1, 0.1]},
            "method": {"kind": "emcee", "n_sim": 8, "walkers": 8, "steps": 100, "reevaluate_every": 25}}


@pytest.mark.slow
def test_the_cruise_speed_of_the_example_plugin_is_recovered(tmp_path):
    observed = synthetic_observation(calibration_from_dict(calibration([1.0, 1.0]), ROOT), {"cruise": TRUTH},
                                     seed=9)[0]
    assert np.isfinite(observed).all()
    result = run_calibration(calibration_from_dict(calibration(observed), ROOT), tmp_path / "out", progress=False,
                             predictive_draws=10)
    row = result.summary.loc["cruise"]
    assert row["q5"] <= TRUTH <= row["q95"], row.to_dict()
    assert row["sd"] < 0.2 * (PRIOR[1] - PRIOR[0]) / np.sqrt(12.0), row.to_dict()
