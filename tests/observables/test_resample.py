"""Resampling raw samples onto records (observables.resample) and metrics over the individuals
present (observables.observed)."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.observables.metrics import METRIC_NAMES, frame_metrics
from flocksweep.observables.observed import ObservedFlock, present_metrics
from flocksweep.observables.resample import MAX_RECORD_VALUES, check_size, record_grid, resample, velocity_steps
from flocksweep.observables.summary import MetricSettings, measure_run
from flocksweep.observables.tracks import RawFlock


def raw_from(times_per_id, position, name="A", vel=None) -> RawFlock:
    """RawFlock of individuals sampled at the given times, positions position(i, t) (3,)."""
    t, ind, pos = [], [], []
    for i, times in enumerate(times_per_id):
        for time in times:
            t.append(time)
            ind.append(i)
            pos.append(position(i, time))
    pos = np.array(pos, dtype=float)
    return RawFlock(name=name, ids=np.arange(len(times_per_id)), t=np.array(t, dtype=float),
                    ind=np.array(ind, dtype=np.int64), pos=pos, vel=None if vel is None else vel(pos))


def curve(i, t):
    return np.array([3.0 * t + i, np.sin(t) + 2.0 * i, t * t])


def test_grid_snaps_to_sample_times_so_regular_data_keep_their_values():
    times = np.arange(31) * 0.1                       # 0.30000000000000004 and friends
    grid = record_grid(times, 0.1)
    assert np.array_equal(grid, times)
    raw = raw_from([times] * 3, curve)
    flock = resample(raw, 0.1, velocity_interval=0.1)
    # forward difference (m = 1): the last sample only ends a difference
    assert np.array_equal(flock.times, times[:-1])
    assert np.array_equal(flock.pos[:, 1], raw.pos[raw.ind == 1][:-1])


def test_linear_interpolation_inside_max_gap_and_missing_beyond():
    times = [np.array([0.0, 0.2, 0.6, 0.8, 1.6, 1.8])]
    raw = raw_from(times, lambda i, t: np.array([t, 2 * t, 0.0]))
    flock = resample(raw, 0.2, max_gap=0.5, velocity_interval=0.2)
    # grid 0 .. 1.8; 0.4 bridged (gap 0.4 <= 0.5), 1.0 .. 1.4 not (gap 0.8)
    x = flock.pos[:, 0, 0]
    expected = np.array([0.0, 0.2, 0.4, 0.6, 0.8, np.nan, np.nan, np.nan, 1.6])
    assert np.allclose(x, expected, equal_nan=True)
    assert list(flock.present[:, 0]) == [True, True, True, True, False, False, False, False, True]


def test_velocity_by_differences_is_exact_for_straight_motion_and_centred_for_even_steps():
    times = [np.arange(21) * 0.1] * 2
    raw = raw_from(times, lambda i, t: np.array([5.0 * t, -t, 2.0 + i]))
    for m, (ahead, behind) in ((1, (1, 0)), (2, (1, 1)), (3, (2, 1)), (4, (2, 2))):
        flock = resample(raw, 0.1, velocity_interval=0.1 * m)
        assert len(flock.times) == 21 - m
        assert np.isclose(flock.times[0], 0.1 * behind)
        assert np.allclose(flock.vel, [5.0, -1.0, 0.0])
    # a curved path: the centred difference over 0.2 s at t is (p(t + 0.1) - p(t - 0.1)) / 0.2
    raw = raw_from([np.arange(21) * 0.1], curve)
    flock = resample(raw, 0.1, velocity_interval=0.2)
    t = flock.times[4]
    assert np.allclose(flock.vel[4, 0], (curve(0, t + 0.1) - curve(0, t - 0.1)) / 0.2)


def test_recorded_velocities_are_resampled_like_positions():
    times = [np.array([0.0, 0.1, 0.3, 0.4])]
    raw = raw_from(times, curve, vel=lambda pos: pos * 2.0)
    flock = resample(raw, 0.1, velocity_interval="recorded")
    assert len(flock.times) == 5 and flock.present.all()
    assert np.allclose(flock.vel[2, 0], (curve(0, 0.1) + curve(0, 0.3)))     # 2 x the midpoint of the two


def test_bad_velocity_intervals_are_rejected():
    assert velocity_steps(None, 0.2) == 1 and velocity_steps("recorded", 0.2) is None
    with pytest.raises(ValueError, match="whole multiple"):
        velocity_steps(0.3, 0.2)
    raw = raw_from([np.arange(3) * 0.1], curve)
    with pytest.raises(ValueError, match="too few"):
        resample(raw, 0.1, velocity_interval=0.4)
    with pytest.raises(ValueError, match="no velocities"):
        resample(raw, 0.1, velocity_interval="recorded")


def _random_flock(seed: int, n_records: int = 12, n: int = 9, pattern=None, p: float = 0.7) -> ObservedFlock:
    rng = np.random.default_rng(seed)
    pos = rng.normal(scale=4.0, size=(n_records, n, 3))
    vel = rng.normal(size=(n_records, n, 3)) + [2.0, 0, 0]
    present = rng.random((n_records, n)) < p
    present[3] = True
    present[5] = False
    pos[~present] = np.nan
    return ObservedFlock(name="r", ids=np.arange(n), times=np.arange(n_records) * 0.5, pos=pos, vel=vel,
                         present=present, pattern=pattern)


@pytest.mark.parametrize("with_pattern", [False, True])
def test_present_metrics_are_frame_metrics_of_the_individuals_present_record_by_record(with_pattern):
    pattern = np.array([0, 1, 1, 2, 0, 0, 1, 2, 2]) if with_pattern else None
    flock = _random_flock(3, pattern=pattern)
    series = present_metrics(flock, 5.0)
    for r in range(len(flock.times)):
        members = flock.present[r]
        if not members.any():
            assert all(np.isnan(series[name][r]) for name in METRIC_NAMES)
            continue
        alone = frame_metrics(flock.pos[r, members], flock.vel[r, members], None, None,
                              None if pattern is None else pattern[members], 5.0)
        for name in METRIC_NAMES:
            assert np.array_equal(series[name][r], alone[name], equal_nan=True), (r, name)


def test_everyone_present_is_exactly_frame_metrics_and_measure_run_adds_tracked():
    rng = np.random.default_rng(4)
    pos, vel = rng.normal(scale=4.0, size=(12, 9, 3)), rng.normal(size=(12, 9, 3)) + [2.0, 0, 0]
    flock = ObservedFlock(name="r", ids=np.arange(9), times=np.arange(12) * 0.5, pos=pos, vel=vel,
                          present=np.ones((12, 9), dtype=bool))
    whole = frame_metrics(flock.pos, flock.vel, None, None, None, 5.0)
    series = present_metrics(flock, 5.0)
    for name in METRIC_NAMES:
        assert np.array_equal(series[name], whole[name], equal_nan=True)
    settings = MetricSettings(warmup=1.0, group_radius=5.0, escape_duration=np.nan)
    run = measure_run(flock, settings)
    assert np.array_equal(run.series["tracked"], np.full(len(flock.times), 9.0))
    assert run.row["tracked_mean"] == 9.0
    with pytest.raises(ValueError, match="leadership"):
        measure_run(flock, MetricSettings(group_radius=5.0, leadership=True, escape_duration=1.0))


def test_grid_follows_the_phase_of_jittered_sampling_and_starts_at_the_first_sample_otherwise():
    rng = np.random.default_rng(2)
    nominal = 10.05 + np.arange(40) * 0.2
    jittered = np.sort(np.concatenate([nominal + rng.choice([-0.01, 0.0, 0.01], 40) for _ in range(5)]))
    grid = record_grid(jittered, 0.2)
    assert np.abs(grid - nominal[:len(grid)]).max() < 0.003 and len(grid) >= 39
    dense = np.arange(50) * 0.1 + 3.0                  # samples twice as dense as the grid: no common phase
    assert np.array_equal(record_grid(dense, 0.2)[:3], dense[[0, 2, 4]])


def test_max_gap_below_the_interval_is_refused():
    raw = raw_from([np.arange(5) * 0.1], curve)
    with pytest.raises(ValueError, match="max_gap: got 0.05; must be at least the sampling interval"):
        resample(raw, 0.1, max_gap=0.05)


def test_the_record_count_is_checked_before_the_grid_is_allocated():
    t = np.array([0.0, 1.0, 2.0])
    assert check_size(t, 2, 0.5) == len(record_grid(t, 0.5)) == 5
    with pytest.raises(ValueError, match=r"2e\+09 records x 2 individuals = 4e\+09 positions, over the limit of "
                                         r"20,000,000 .*at least 2e-07 s"):
        check_size(t, 2, 1e-9)
    largest = 2.0 * 2 / MAX_RECORD_VALUES   # at the stated smallest interval the flock fits
    assert check_size(t, 2, largest * 1.01) <= MAX_RECORD_VALUES // 2
