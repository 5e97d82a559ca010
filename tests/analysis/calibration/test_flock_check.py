"""Predictive checks that look at the flock (analysis.calibration.flock_check): every flock statistic of
the predictive runs is reported, and one that disagrees with the observed flock is flagged even when it is
not a target (observed one group, predicted 2-4)."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration import run_calibration
from flocksweep.analysis.calibration.calibration_report import verdict_lines
from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.flock_check import FLOCK_STATS, flock_check, flock_columns, flock_messages
from flocksweep.analysis.calibration.run import summary_simulator
from paths import ROOT
from flocksweep.simcore import ConfigError
from flocksweep.sweeps.seeds import common_seeds

HOLLAND = str(ROOT / "configs/models/holland.toml")


def tiny(flock=None, **targets) -> dict:
    table = {"stats": ["cohesion", "polarization"], "mean": [0.8, 0.7], "sd": [0.1, 0.1], **targets}
    if flock is not None:
        table["flock"] = flock
    return {"name": "tiny", "seed": 4, "model": {"preset": HOLLAND},
            "run": {"n": 10, "duration": 2.0, "record_interval": 0.5, "warmup": 0.5},
            "parameters": {"range": {"key": "perception.range", "prior": {"dist": "uniform", "low": 5, "high": 40}}},
            "targets": table, "method": {"kind": "emcee", "n_sim": 6, "walkers": 4, "steps": 3}}


def test_flock_columns_are_the_non_targets_in_the_targets_summary():
    config = calibration_from_dict(tiny(), ROOT)
    columns = flock_columns(config)
    assert "polarization_mean" not in columns and "cohesion_mean" not in columns   # the targets
    assert "n_groups_mean" in columns and "fragmented" in columns and len(columns) == len(FLOCK_STATS) - 2
    final = calibration_from_dict(tiny(summary="final"), ROOT)
    assert "n_groups_final" in flock_columns(final) and not any(c.endswith("_mean") for c in flock_columns(final))


@pytest.mark.parametrize("flock, key, words", [
    ({"n_grups": 1}, "targets.flock.n_grups", "did you mean 'n_groups'"),
    ({"n_groups": True}, "targets.flock.n_groups", "finite number"),
    ({"n_groups": float("nan")}, "targets.flock.n_groups", "finite number"),
    ({"polarization": 0.9}, "targets.flock.polarization", "a target already"),
    ([1], "targets.flock", "expected a table"),
])
def test_the_flock_table_is_validated(flock, key, words):
    with pytest.raises(ConfigError) as err:
        calibration_from_dict(tiny(flock), ROOT)
    assert err.value.key == key and words in str(err.value)


def test_a_non_target_that_disagrees_is_flagged_and_the_agreeing_or_unknown_ones_are_not():
    config = calibration_from_dict(tiny({"n_groups": 1, "nn_distance": 2.0}), ROOT)
    rng = np.random.default_rng(0)
    targets = rng.normal([0.8, 0.7], 0.05, (100, 2))     # the targets reproduced
    columns = flock_columns(config)
    flock = rng.normal(1.0, 0.2, (100, len(columns)))
    flock[:, columns.index("n_groups_mean")] = rng.integers(2, 5, 100)   # the fitted flocks split in 2-4 groups
    flock[:, columns.index("nn_distance_mean")] = rng.normal(2.0, 0.3, 100)
    table = flock_check(config, targets, flock)
    assert list(table.index[:2]) == ["cohesion_mean", "polarization_mean"] and table["target"].sum() == 2
    assert list(table.index[2:]) == list(columns)
    assert table.index[table["disagrees"]].tolist() == ["n_groups_mean"]
    row = table.loc["n_groups_mean"]
    assert row["observed"] == 1 and row["p"] == 0 and 2 <= row["pred_q2.5"] <= row["pred_q97.5"] <= 4
    assert table.loc["nn_distance_mean", "p"] > 0.3
    unknown = table.drop(["cohesion_mean", "polarization_mean", "n_groups_mean", "nn_distance_mean"])
    assert unknown["observed"].isna().all() and unknown["p"].isna().all() and not unknown["disagrees"].any()
    assert unknown["pred_mean"].notna().all()                # every flock statistic reported all the same
    messages = flock_messages(table)
    assert len(messages) == 1 and messages[0].startswith("flock check: n_groups_mean is 1 in the observed flock")
    # a target in its tail is the predictive check's to say, not the flock check's
    table.loc["cohesion_mean", "disagrees"] = True
    assert len(flock_messages(table)) == 1


def test_the_flag_is_bonferroni_bounded_by_the_number_of_known_statistics():
    rng = np.random.default_rng(1)
    targets = rng.normal([0.8, 0.7], 0.05, (100, 2))
    alone = calibration_from_dict(tiny({"nn_distance": 1.5}), ROOT)
    columns = flock_columns(alone)
    flock = rng.normal(1.0, 0.2, (100, len(columns)))
    flock[:, columns.index("nn_distance_mean")] = np.arange(100.0)     # observed 1.5: p = 2 x 2/100 = 0.04
    flock[:, columns.index("n_groups_mean")] = 1.0
    assert flock_check(alone, targets, flock).loc["nn_distance_mean", "disagrees"]          # 0.04 < 0.05 / 1
    both = calibration_from_dict(tiny({"nn_distance": 1.5, "n_groups": 1}), ROOT)
    table = flock_check(both, targets, flock)
    assert table.loc["nn_distance_mean", "p"] == pytest.approx(0.04)
    assert not table["disagrees"].any()                                                   # 0.04 > 0.05 / 2


def test_the_flock_columns_leave_the_target_columns_bit_identical():
    config = calibration_from_dict(tiny(), ROOT)
    seeds = common_seeds(5, 3)
    bare = summary_simulator(config, n_sim=3).simulate(np.array([20.0]), seeds)
    wide = summary_simulator(config, n_sim=3, extra_columns=flock_columns(config)).simulate(np.array([20.0]), seeds)
    assert wide.shape == (3, 2 + len(flock_columns(config)))
    np.testing.assert_array_equal(wide[:, :2], bare)
    assert np.isfinite(wide).all()


@pytest.mark.slow
def test_calibrate_reports_the_whole_flock_and_flags_the_disagreeing_non_target(tmp_path):
    # ten boids at ranges 5-40 over 2 s never form ten groups: a flock observed as ten singletons is not
    # what any posterior draw produces, though it is no target
    config = calibration_from_dict(tiny({"n_groups": 10}), ROOT)
    run = run_calibration(config, tmp_path / "cal", progress=False, predictive_draws=12)
    table = pd.read_csv(tmp_path / "cal" / "flock_check.csv", index_col=0)
    assert set(flock_columns(config)) <= set(table.index)
    assert table.loc["n_groups_mean", "disagrees"] and table.loc["n_groups_mean", "pred_q97.5"] < 10
    assert table["n_pred"].eq(12).all()
    lines = verdict_lines(config, run)
    assert any(line.startswith("flock check: n_groups_mean is 10") for line in lines)
    assert "The flock in the predictive runs" in (tmp_path / "cal" / "report.md").read_text()
    assert json.loads((tmp_path / "cal" / "convergence.json").read_text())["accounting"]["simulations"]["predictive"] == 12
