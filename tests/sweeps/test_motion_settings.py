"""The settings of the observables of collective motion in a sweep's [run] table (k_nearest,
pairwise_metrics, state_high, state_low): validated with the key named, part of a run's identity only
when they differ from their defaults (shipped sweeps keep their run ids), recorded in model.json and
rebuilt from it; a run's row holds the new columns after the older ones, which keep their values."""
from __future__ import annotations

import math

import numpy as np
import pytest

from flocksweep.observables.columns import MOTION_METRIC_NAMES, PAIRWISE_SERIES
from flocksweep.simcore import ConfigError
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.design import expand, rebuild
from flocksweep.sweeps.runner import model_record
from flocksweep.sweeps.worker import execute_run
from paths import ROOT
from tiny_sweeps import run_ids, sweep

@pytest.mark.parametrize("key, bad, message", [
    ("k_nearest", 0, "got 0; expected a whole number >= 1"),
    ("k_nearest", 2.5, "got 2.5"),
    ("pairwise_metrics", "no", "got 'no'"),
    ("state_high", 1.2, r"got 1.2; allowed range \[0.0, 1.0\]"),
    ("state_low", 0.9, "above state_high"),
])
def test_bad_settings_are_config_errors_naming_the_key(key, bad, message):
    with pytest.raises(ConfigError, match=rf"run\.{key}: .*{message}"):
        sweep_from_dict(sweep(**{key: bad}), ROOT)


def test_defaults_keep_the_run_ids_and_other_values_change_them():
    plain = run_ids(sweep())
    assert run_ids(sweep(k_nearest=6, pairwise_metrics=True, state_high=0.65, state_low=0.35)) == plain
    changed = [run_ids(sweep(**change)) for change in ({"k_nearest": 3}, {"pairwise_metrics": False},
                                                        {"state_high": 0.7}, {"state_low": 0.3})]
    assert all(ids != plain for ids in changed) and len({tuple(ids) for ids in changed}) == 4


def test_settings_are_recorded_in_model_json_and_rebuilt():
    config = sweep_from_dict(sweep(k_nearest=3, pairwise_metrics=False), ROOT)
    record = config.analysis_record()
    assert record["k_nearest"] == 3 and record["pairwise_metrics"] is False and "state_high" not in record
    assert "k_nearest" not in sweep_from_dict(sweep(), ROOT).analysis_record()      # defaults are left out
    spec = expand(config)[0]
    _, metrics = rebuild(model_record(config), {})
    assert (metrics.k_nearest, metrics.pairwise_metrics, metrics.state_high) == (3, False, 0.65)
    assert metrics == spec.metrics


def test_a_runs_row_gains_the_new_columns_and_keeps_the_old_ones():
    plain = expand(sweep_from_dict(sweep(record_interval=0.25), ROOT))[0]
    off = expand(sweep_from_dict(sweep(record_interval=0.25, pairwise_metrics=False, k_nearest=2), ROOT))[0]
    (row, series), (row_off, _) = execute_run(plain), execute_run(off)
    assert row["status"] == row_off["status"] == "ok" and set(PAIRWISE_SERIES) <= set(series.columns)
    assert all(name in row and name in row_off for name in MOTION_METRIC_NAMES)
    assert all(math.isnan(row_off[f"{name}_mean"]) and np.isfinite(row[f"{name}_mean"]) for name in PAIRWISE_SERIES)
    older = [c for c in row if c.endswith(("_mean", "_final")) and not c.startswith(
        ("nn_ahead", "nn_bearing", "nn_anisotropy", "knn_", "corr_length", "edge_spacing", "front_spacing"))]
    assert older and all(np.array_equal(row[c], row_off[c], equal_nan=True) for c in older)
