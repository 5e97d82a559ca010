"""Choosing the statistics before any posterior (analysis.calibration.informative): on a toy design with
known signal and noise, the ranking follows the between/within variance ratio (a pure-noise statistic's
ratio is near 1/replicates, its sampling expectation), a near-copy of a chosen statistic is rejected
for its correlation, a statistic that does not move is never chosen, and each gets the measurement sd
convention (2.5 % of its range over the design, one significant figure)."""
from __future__ import annotations

import numpy as np

from flocksweep.analysis.calibration.informative import rank_statistics
from flocksweep.analysis.calibration.training import group_replicates

REPLICATES = 5


def toy_training():
    rng = np.random.default_rng(3)
    x1, x2 = np.meshgrid(np.arange(6.0), np.arange(6.0), indexing="ij")
    points = np.repeat(np.column_stack([x1.ravel(), x2.ravel()]), REPLICATES, axis=0)
    noise = rng.standard_normal((len(points), 4))
    strong = points[:, 0] + 0.1 * noise[:, 0]
    copy = 2.0 * strong + 0.01 * noise[:, 1]
    pure_noise = 0.5 * noise[:, 2]
    moderate = 0.4 * points[:, 1] + 0.2 * noise[:, 3]
    summaries = np.column_stack([pure_noise, copy, moderate, strong, np.full(len(points), 4.0)])
    return group_replicates(points, summaries, ["x1", "x2"], ["pure_noise", "copy", "moderate", "strong", "constant"])


def test_statistics_rank_by_signal_over_replicate_spread():
    table = rank_statistics(toy_training()).set_index("statistic")
    assert table.index[0] in ("strong", "copy") and table.index[-1] in ("pure_noise", "constant")
    assert table.loc["strong", "ratio"] > 100 and 5 < table.loc["moderate", "ratio"] < 100
    assert 0.5 / REPLICATES < table.loc["pure_noise", "ratio"] < 2.0 / REPLICATES   # E = 1 / replicates
    assert table.loc["constant", "ratio"] == 0


def test_the_greedy_choice_skips_copies_and_uninformative_statistics():
    table = rank_statistics(toy_training(), min_ratio=5.0).set_index("statistic")
    assert set(table.index[table["chosen"]]) == {table.index[0], "moderate"}   # strong or its copy, not both
    skipped = "copy" if table.index[0] == "strong" else "strong"
    assert table.loc[skipped, "reason"].startswith("|r| = 1.00 with")
    assert table.loc["pure_noise", "reason"] == "ratio < 5" and not table.loc["constant", "chosen"]
    loose = rank_statistics(toy_training(), min_ratio=5.0, max_correlation=1.0).set_index("statistic")
    assert loose.loc[skipped, "chosen"]
    np.testing.assert_array_equal(rank_statistics(toy_training()).to_numpy(), rank_statistics(toy_training()).to_numpy())


def test_measurement_sd_is_a_share_of_the_range_to_one_significant_figure():
    table = rank_statistics(toy_training()).set_index("statistic")
    span = table.loc["strong", "range"]
    assert 4.5 < span < 5.5 and table.loc["strong", "measurement_sd"] == 0.1     # 0.025 x ~5 = 0.125 -> 0.1
    assert table.loc["constant", "measurement_sd"] == 0.0
    wider = rank_statistics(toy_training(), sd_share=0.1).set_index("statistic")
    assert wider.loc["strong", "measurement_sd"] == 0.5
