"""``targets.truth`` of a calibration file (recovery studies): a value for every free parameter inside its
bounds, refused with the key otherwise; absent, nothing changes."""
from __future__ import annotations

import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.simcore import ConfigError
from paths import ROOT


def data(truth=None) -> dict:
    targets = {"stats": ["polarization"], "mean": [0.9], "sd": [0.05]}
    if truth is not None:
        targets["truth"] = truth
    return {"name": "t", "model": {"preset": str(ROOT / "configs/models/holland.toml")},
            "parameters": {"field": {"key": "perception.field_deg", "prior": {"dist": "uniform", "low": 60, "high": 300}},
                           "range": {"key": "perception.range", "prior": {"dist": "uniform", "low": 5, "high": 40}}},
            "targets": targets, "method": {"kind": "emcee", "n_sim": 8}}


def test_truth_is_read_in_parameter_order():
    config = calibration_from_dict(data({"range": 20, "field": 150}), ROOT)
    assert config.targets.truth == {"field": 150.0, "range": 20.0}
    assert calibration_from_dict(data(), ROOT).targets.truth is None


@pytest.mark.parametrize("truth, key, words", [
    ({"field": 150, "rnage": 20}, "targets.truth.rnage", "did you mean 'range'"),
    ({"field": 150}, "targets.truth", "missing 'range'"),
    ({"field": 400, "range": 20}, "targets.truth.field", "outside the bounds"),
    ({"field": "wide", "range": 20}, "targets.truth.field", "finite number"),
])
def test_bad_truths_are_refused_with_their_key(truth, key, words):
    with pytest.raises(ConfigError, match=words) as err:
        calibration_from_dict(data(truth), ROOT)
    assert err.value.key == key
