"""The directional correlation delays in a sweep's rows: off by default (shipped sweeps keep their run ids
and columns), switched on by ``[run] dcd_metrics = true`` with ``dcd_max_delay``, part of a run's identity
only when on, recorded in model.json and rebuilt from it; on, a row gains the dcd_* columns and keeps
every other column bit for bit."""
from __future__ import annotations

import math

import pytest

from flocksweep.observables.directional_correlation import DCD_METRIC_NAMES
from flocksweep.simcore import ConfigError
from flocksweep.sweeps.config import load_sweep, sweep_from_dict
from flocksweep.sweeps.design import expand, rebuild
from flocksweep.sweeps.runner import model_record
from flocksweep.sweeps.worker import execute_run
from paths import ROOT
from tiny_sweeps import run_ids, sweep


def test_off_by_default_and_part_of_the_run_id_only_when_on():
    plain = run_ids(sweep())
    assert run_ids(sweep(dcd_metrics=False)) == plain
    on = run_ids(sweep(dcd_metrics=True))
    longer = run_ids(sweep(dcd_metrics=True, dcd_max_delay=1.0))
    assert on != plain and longer != on and longer != plain
    config = sweep_from_dict(sweep(), ROOT)
    assert not config.metrics.dcd and "dcd_max_delay" not in config.analysis_record()


def test_settings_are_checked_recorded_in_model_json_and_rebuilt():
    config = sweep_from_dict(sweep(dcd_metrics=True, dcd_max_delay=1.5), ROOT)
    assert config.analysis_record()["dcd_max_delay"] == 1.5
    _, metrics = rebuild(model_record(config), {})
    assert metrics.dcd and metrics.dcd_max_delay == 1.5 and metrics == expand(config)[0].metrics
    with pytest.raises(ConfigError, match=r"run\.dcd_max_delay: .*only with dcd_metrics = true"):
        sweep_from_dict(sweep(dcd_max_delay=1.0), ROOT)
    with pytest.raises(ConfigError, match=r"run\.dcd_max_delay: got -1.0; must be a finite number >= 0"):
        sweep_from_dict(sweep(dcd_metrics=True, dcd_max_delay=-1.0), ROOT)
    with pytest.raises(ConfigError, match=r"claims.*dcd_metrics = true"):
        sweep_from_dict({**sweep(), "claims": [{"id": "c", "statement": "s", "test": "trend", "metric": "dcd_edges",
                                                "factor": "n", "direction": "increasing"}]}, ROOT)


def test_a_shipped_sweep_row_keeps_its_columns_and_gains_the_delays():
    plain = load_sweep(ROOT / "configs" / "sweeps" / "smoke.toml")
    on = load_sweep(ROOT / "configs" / "sweeps" / "smoke.toml", ["run.dcd_metrics=true"])
    spec, spec_on = expand(plain)[0], expand(on)[0]
    row, _ = execute_run(spec)
    row_on, _ = execute_run(spec_on)
    assert not set(DCD_METRIC_NAMES) & set(row) and set(DCD_METRIC_NAMES) <= set(row_on)
    for column, value in row.items():
        if column in ("run_id", "sim_s", "wall_s"):
            continue
        assert row_on[column] == value or (math.isnan(value) and math.isnan(row_on[column])), column
    assert 0.0 < row_on["dcd_corr_mean"] <= 1.0
