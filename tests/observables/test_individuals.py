"""Per-individual features and series windows (observables.individuals), the raw inputs of npe's learned
summaries: their record means are the flock series of observables.metrics (one definition), an analytic
circle, missing detections, the order of individuals, and the binning of the window."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.observables.individuals import (INDIVIDUAL_FEATURES, individual_features, individual_frames,
                                                window_series)
from flocksweep.observables.metrics import frame_metrics
from flocksweep.observables.observed import ObservedFlock, present_metrics


def _flock(seed: int, records: int = 6, n: int = 7):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-4, 4, (records, n, 3))
    vel = rng.normal(size=(records, n, 3))
    pos[..., 2] = vel[..., 2] = 0.0
    return pos, vel


def _row_means(values):
    known = np.isfinite(values)
    return np.where(known, values, 0.0).sum(axis=1) / known.sum(axis=1)


@pytest.mark.parametrize("box", [None, 9.0])
def test_record_means_of_the_individual_terms_are_the_flock_series(box):
    pos, vel = _flock(0)
    if box:
        pos = pos - box * np.round(pos / box)
    series = frame_metrics(pos, vel, None, None, None, 3.0, box)
    distance, ahead = individual_frames(pos, vel, np.ones(pos.shape[:2], dtype=bool), box)
    np.testing.assert_allclose(_row_means(distance), series["nn_distance"], rtol=1e-12)
    np.testing.assert_allclose(_row_means(ahead), series["nn_ahead_fraction"], rtol=1e-12)


def test_with_missing_detections_the_terms_are_those_of_the_individuals_present():
    pos, vel = _flock(1)
    present = np.random.default_rng(2).random(pos.shape[:2]) > 0.25
    present[:, :2] = True                                      # at least two present at every record
    flock = ObservedFlock("f", np.arange(pos.shape[1]), np.arange(len(pos)) * 0.5,
                          np.where(present[..., None], pos, np.nan), np.where(present[..., None], vel, np.nan),
                          present, dims=2, interval=0.5)
    series = present_metrics(flock, 3.0)
    distance, ahead = individual_frames(flock.pos, flock.vel, present)
    assert np.isnan(distance[~present]).all() and np.isnan(ahead[~present]).all()
    np.testing.assert_allclose(_row_means(distance), series["nn_distance"], rtol=1e-12)
    np.testing.assert_allclose(_row_means(ahead), series["nn_ahead_fraction"], rtol=1e-12)
    features = individual_features(flock, warmup=0.0, interval=0.5)
    assert features.shape == (pos.shape[1], len(INDIVIDUAL_FEATURES))
    # shuffling the individuals shuffles their rows, nothing else
    order = np.random.default_rng(3).permutation(pos.shape[1])
    shuffled = ObservedFlock("f", np.arange(pos.shape[1]), flock.times, flock.pos[:, order], flock.vel[:, order],
                             present[:, order], dims=2, interval=0.5)
    np.testing.assert_allclose(individual_features(shuffled, 0.0, 0.5), features[order], rtol=1e-12)


def test_individuals_on_circles_turn_at_their_angular_speed():
    # two individuals on concentric circles, 30 degrees/s at speed 2; a third never seen: nan features
    times = np.arange(8) * 0.5
    pos = np.zeros((8, 3, 3))
    vel = np.zeros((8, 3, 3))
    for i, radius in enumerate((2.0 / np.radians(30.0), 2.0 / np.radians(30.0) + 1.0)):
        omega = 2.0 / radius
        phase = omega * times
        pos[:, i, :2] = radius * np.column_stack([np.cos(phase), np.sin(phase)])
        vel[:, i, :2] = 2.0 * np.column_stack([-np.sin(phase), np.cos(phase)])
    present = np.zeros((8, 3), dtype=bool)
    present[:, :2] = True
    flock = ObservedFlock("c", np.arange(3), times, np.where(present[..., None], pos, np.nan),
                          np.where(present[..., None], vel, np.nan), present, dims=2, interval=0.5)
    features = individual_features(flock, warmup=1.0, interval=0.5)
    np.testing.assert_allclose(features[:2, 0], 2.0)                                   # speed
    np.testing.assert_allclose(features[0, 1], 30.0, rtol=1e-9)                        # degrees/s
    np.testing.assert_allclose(features[1, 1], np.degrees(2.0 / (2.0 / np.radians(30.0) + 1.0)), rtol=1e-9)
    assert np.isnan(features[2]).all()


def test_the_window_is_cut_into_bins_of_nearly_equal_records():
    times = np.arange(12) * 1.0
    series = {"a": np.arange(12, dtype=float), "b": np.r_[np.full(5, np.nan), np.ones(7)]}
    binned = window_series(series, ["a", "b"], times, warmup=2.0, length=3)     # 10 records: 4, 3, 3
    np.testing.assert_array_equal(binned[:, 0], [3.5, 7.0, 10.0])
    np.testing.assert_array_equal(binned[:, 1], [1.0, 1.0, 1.0])      # the nan records left out of their bin
    with pytest.raises(ValueError, match="fewer than the 11 bins"):
        window_series(series, ["a"], times, warmup=2.0, length=11)
