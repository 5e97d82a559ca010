"""The observables of collective motion (docs/metrics.md "Observables of collective motion"): their
compiled per-record series and per-run scalars against the plain twins of tests/reference_metrics.py on
random flocks (open and periodic worlds, stopped boids, missing individuals), analytic cases worked by
hand, the settings, and their place in a run's row.

Twins agree to a relative 1e-9 (other summation orders); analytic cases are exact unless a tolerance is
stated (statistical cases: fixed seeds, tolerances of several standard errors)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import reference_metrics as ref
from flocksweep.observables import kernels
from flocksweep.observables.columns import MOTION_METRIC_NAMES, PAIRWISE_SERIES, RUN_COLUMNS, SERIES
from flocksweep.observables.metrics import frame_metrics
from flocksweep.observables.motion import decay_time, motion_metrics, state_fractions
from flocksweep.observables.observed import ObservedFlock, present_metrics
from flocksweep.observables.summary import MetricSettings, measure_run, motion_settings, summary_columns
from flocksweep.simcore.schema import ConfigError

NEW_SERIES = ("nn_ahead_fraction", "nn_bearing_deg", "nn_anisotropy", "knn_ahead_fraction", "knn_bearing_deg",
              "knn_anisotropy", "corr_length", "edge_spacing_ratio", "front_spacing_ratio")
RTOL, ATOL = 1e-9, 1e-12
X = np.array([1.0, 0.0, 0.0])


def close(a, b) -> bool:
    return bool(np.allclose(a, b, rtol=RTOL, atol=ATOL, equal_nan=True))


def flock(seed: int, n: int = 16, records: int = 3, spread: float = 8.0):
    """Records of a clumpy flock around a common heading, one boid stopped."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-spread, spread, (3, 3))
    pos = centres[rng.integers(0, 3, n)] + rng.normal(0, 2.0, (records, n, 3))
    vel = np.array([1.0, 0.3, -0.2]) + rng.normal(0, 0.6, (records, n, 3))
    vel[:, rng.integers(n)] = 0.0
    return pos, vel


def series_of(pos, vel, radius=4.0, box=None, k=4, **kw):
    return frame_metrics(pos, vel, None, None, None, radius, box, k_nearest=k, **kw)


# ------------------------------------------------------------------------------ per-record series: twins

@pytest.mark.parametrize("seed, box", [(seed, box) for seed in range(4) for box in (None, 30.0)])
def test_series_match_their_twins(seed, box):
    pos, vel = flock(seed)
    if box is not None:
        pos = pos % box
    for radius, k in ((3.0, 1), (5.0, 4), (40.0, 30)):
        got = series_of(pos, vel, radius, box, k)
        for r in range(len(pos)):
            want = ref.motion_series(pos[r], vel[r], radius, k, box)
            for name in NEW_SERIES:
                assert close(got[name][r], want[name]), (name, r, radius, k, got[name][r], want[name])


def test_series_are_declared_in_order_and_the_existing_ones_are_untouched():
    assert SERIES[-len(NEW_SERIES):] == NEW_SERIES and set(PAIRWISE_SERIES) <= set(NEW_SERIES)
    pos, vel = flock(7)
    got = series_of(pos, vel)
    assert tuple(got) == SERIES
    kernel_free = {name: got[name] for name in SERIES[:-len(NEW_SERIES)]}
    off = series_of(pos, vel, pairwise=False, k=2)
    for name, values in kernel_free.items():          # neither k nor the switch touches an older series
        assert np.array_equal(values, off[name], equal_nan=True), name


def test_pairwise_switch_leaves_only_the_pairwise_series_nan():
    pos, vel = flock(3)
    on, off = series_of(pos, vel), series_of(pos, vel, pairwise=False)
    for name in NEW_SERIES:
        if name in PAIRWISE_SERIES:
            assert np.isfinite(on[name]).all() and np.isnan(off[name]).all(), name
        else:
            assert np.array_equal(on[name], off[name], equal_nan=True), name


# ------------------------------------------------------------------------ per-record series: by hand

def test_single_file_neighbours_lie_ahead_and_behind():
    """Five boids in a line along their heading x, gaps 1, 2, 3, 4: the first boid's nearest neighbour is
    ahead, every other's behind (the nearer of its two), all on the axis."""
    x = np.array([0.0, 1.0, 3.0, 6.0, 10.0])
    pos = np.column_stack([x, np.zeros(5), np.zeros(5)])
    vel = np.tile(X, (5, 1))
    got = series_of(pos, vel, radius=5.0, k=2)
    assert got["nn_ahead_fraction"] == pytest.approx(0.2) and got["nn_bearing_deg"] == pytest.approx(144.0)
    assert got["nn_anisotropy"] == pytest.approx(1.0)
    # two nearest: 0 -> 1, 2 (ahead, ahead); 1 -> 0, 2 (behind, ahead); 2 -> 1, then 0 and 3 tie at 3: 0
    # (behind, behind); 3 -> 2, 4 (behind, ahead); 4 -> 3, 2 (behind, behind): 4 of 10 ahead
    assert got["knn_ahead_fraction"] == pytest.approx(0.4) and got["knn_bearing_deg"] == pytest.approx(108.0)
    # the spacing behind (gaps 1) against ahead: the front boids 6, 10 have nn 3, 4, the back ones 0, 1 nn 1, 1
    assert got["front_spacing_ratio"] == pytest.approx(3.5)


def test_a_line_abreast_has_every_neighbour_at_the_side():
    pos = np.column_stack([np.zeros(6), np.zeros(6), np.arange(6.0) * 1.5])
    vel = np.tile(2.0 * X, (6, 1))
    got = series_of(pos, vel, radius=2.0, k=3)
    for prefix in ("nn", "knn"):
        assert got[f"{prefix}_ahead_fraction"] == 0.5 and got[f"{prefix}_bearing_deg"] == 90.0
        assert got[f"{prefix}_anisotropy"] == 0.0


@pytest.mark.parametrize("dims, isotropic", [(3, 1 / 3), (2, 1 / 2)])
def test_isotropic_neighbours_give_the_isotropic_anisotropy(dims, isotropic):
    """Uniform positions in a cube (or square) and random headings: cos^2 of the bearing averages 1/3 in
    3-D and 1/2 in 2-D, half the neighbours lie ahead and the mean bearing is 90 degrees (tolerances: about
    four standard errors over 20 records of 200 boids)."""
    rng = np.random.default_rng(5)
    pos = rng.uniform(0, 50, (20, 200, 3))
    vel = rng.normal(0, 1, (20, 200, 3))
    if dims == 2:
        pos[..., 2] = 0.0
        vel[..., 2] = 0.0
    got = series_of(pos, vel, radius=1.0, k=6)
    assert got["knn_anisotropy"].mean() == pytest.approx(isotropic, abs=0.01)
    assert got["knn_ahead_fraction"].mean() == pytest.approx(0.5, abs=0.015)
    assert got["knn_bearing_deg"].mean() == pytest.approx(90.0, abs=1.5)


def test_correlation_length_of_two_counter_moving_clusters_is_the_cluster_size():
    """Two tight clusters 20 apart, one moving faster than the mean, one slower: the fluctuations agree
    inside a cluster and oppose across, so S(r) grows up to the largest distance inside a cluster."""
    rng = np.random.default_rng(2)
    left = rng.uniform(-1, 1, (6, 3)) + [-10.0, 0, 0]
    right = rng.uniform(-1, 1, (6, 3)) + [10.0, 0, 0]
    pos = np.vstack([left, right])
    vel = np.vstack([np.tile([1.2, 0, 0], (6, 1)), np.tile([0.8, 0, 0], (6, 1))])
    inside = max(np.linalg.norm(a - b) for cluster in (left, right) for a in cluster for b in cluster)
    got = series_of(pos, vel, radius=30.0)
    assert got["corr_length"] == pytest.approx(inside, rel=1e-12)
    scaled = series_of(3.0 * pos, vel, radius=90.0)                 # a length: it scales with the flock
    assert scaled["corr_length"] == pytest.approx(3.0 * inside, rel=1e-12)
    assert math.isnan(series_of(pos, np.tile(X, (12, 1)), radius=30.0)["corr_length"])  # no fluctuation
    # independent fluctuations: no positive range worth the name, far below the flock's size (about 30)
    noise = np.tile(X, (12, 1)) + rng.normal(0, 0.1, (12, 3))
    assert series_of(pos, noise, radius=30.0)["corr_length"] < series_of(pos, vel, radius=30.0)["corr_length"]


def test_edge_spacing_ratio_of_a_tight_core_with_sparse_edges():
    core = np.array([[0.5, 0.5, 0], [-0.5, 0.5, 0], [0.5, -0.5, 0], [-0.5, -0.5, 0]])
    edge = np.array([[10.0, 0, 0], [-10.0, 0, 0], [0, 10.0, 0], [0, -10.0, 0]])
    pos = np.vstack([core, edge])
    vel = np.tile(X, (8, 1))
    got = series_of(pos, vel, radius=100.0)
    assert got["edge_spacing_ratio"] == pytest.approx(math.hypot(9.5, 0.5) / 1.0, rel=1e-12)
    assert got["front_spacing_ratio"] == pytest.approx(1.0, rel=1e-12)    # symmetric along x
    assert math.isnan(series_of(pos[:3], vel[:3], radius=100.0)["edge_spacing_ratio"])   # below 4 boids


# ----------------------------------------------------------------------------------- per-run scalars

def test_decay_time_is_exact_for_an_exponential():
    lags = np.arange(1, 8) * 0.5
    assert decay_time(lags, np.exp(-lags / 1.3)) == pytest.approx(1.3, rel=1e-12)     # crossing inside
    assert decay_time(lags, np.exp(-lags / 0.2)) == pytest.approx(0.2, rel=1e-12)     # before the first lag
    assert decay_time(lags, np.exp(-lags / 9.0)) == pytest.approx(9.0, rel=1e-12)     # extrapolated
    with_gap = np.exp(-lags / 1.3)
    with_gap[2] = np.nan                                                               # a lag without pairs
    assert decay_time(lags, with_gap) == pytest.approx(1.3, rel=1e-12)
    assert math.isnan(decay_time(lags, np.ones(7))) and math.isnan(decay_time(lags[:0], lags[:0]))
    assert decay_time([1.0, 2.0], [0.5, -0.5]) == pytest.approx(1.0 + (0.5 - math.exp(-1)) / 1.0)  # linear past 0


def circling(rate_deg: float, n: int = 4, records: int = 21, interval: float = 0.5):
    """n boids turning at a constant rate, each from its own heading, at speed 2."""
    t = np.arange(records) * interval
    angle = np.radians(rate_deg) * t[:, None] + np.linspace(0, 1, n)[None, :]
    vel = 2.0 * np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=-1)
    return t, vel


def test_constant_turning_gives_the_turning_rate_and_the_cosine_decay():
    t, vel = circling(20.0)
    got = motion_metrics(vel, t, 0.5, 0.0, np.ones(len(t)), np.zeros(len(t)))
    for name in ("turn_rate_mean", "turn_rate_q10", "turn_rate_q50", "turn_rate_q90"):
        assert got[name] == pytest.approx(20.0, rel=1e-9)
    # C(tau) = cos(omega tau) at lags of 0.5 s: the 1/e crossing log-interpolated between them
    lags = np.arange(1, 11) * 0.5
    assert got["heading_autocorr_time"] == pytest.approx(decay_time(lags, np.cos(np.radians(20.0) * lags)), rel=1e-9)
    assert got["speed_q10"] == pytest.approx(2.0) and got["speed_q90"] == pytest.approx(2.0)
    assert got["speed_cv_pooled"] == pytest.approx(0, abs=1e-12)
    assert math.isnan(got["speed_autocorr_time"])                    # constant speeds do not fluctuate
    straight = motion_metrics(np.tile(X, (9, 3, 1)), np.arange(9.0), 1.0, 0.0, np.ones(9), np.zeros(9))
    assert math.isnan(straight["heading_autocorr_time"]) and straight["turn_rate_q90"] == 0.0


def test_rotational_diffusion_decorrelates_in_one_over_d():
    """2-D headings diffusing with rate D: C(tau) = exp(-D tau), so the time is 1/D (seed 4, 200 walkers,
    401 records 0.05 s apart; tolerance 5 %, several standard errors)."""
    rng = np.random.default_rng(4)
    d_rot, dt = 2.0, 0.05
    theta = np.cumsum(rng.normal(0, math.sqrt(2 * d_rot * dt), (401, 200)), axis=0)
    vel = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=-1)
    t = np.arange(401) * dt
    got = motion_metrics(vel, t, dt, 0.0, np.zeros(401), np.zeros(401))
    assert got["heading_autocorr_time"] == pytest.approx(1 / d_rot, rel=0.05)


def test_speed_fluctuations_decorrelate_in_their_relaxation_time():
    """Speeds 3 + an Ornstein-Uhlenbeck fluctuation of relaxation time 0.8 s (sampled exactly as AR(1)):
    the speed autocorrelation time is 0.8 s (seed 6, 100 individuals, 2,001 records 0.05 s apart: long
    enough that subtracting each individual's window mean biases it by about 2 x 0.8 / 100 s; tolerance 6 %)."""
    rng = np.random.default_rng(6)
    relax, dt, records = 0.8, 0.05, 2001
    a = math.exp(-dt / relax)
    x = np.empty((records, 100))
    x[0] = rng.normal(0, 0.3, 100)
    for r in range(1, records):
        x[r] = a * x[r - 1] + math.sqrt(1 - a * a) * 0.3 * rng.normal(size=100)
    vel = np.zeros((records, 100, 3))
    vel[..., 0] = 3.0 + x
    got = motion_metrics(vel, np.arange(records) * dt, dt, 0.0, np.zeros(records), np.zeros(records))
    assert got["speed_autocorr_time"] == pytest.approx(relax, rel=0.06)
    assert got["speed_q50"] == pytest.approx(3.0, abs=0.02) and got["speed_cv_pooled"] == pytest.approx(0.1, rel=0.05)


def test_state_fractions_follow_the_thresholds():
    p = np.array([0.1, 0.9, 0.2, 0.5, 0.9, np.nan, 0.3])
    m = np.array([0.1, 0.1, 0.8, 0.5, 0.5, 0.1, 0.2])
    got = state_fractions(p, m)          # swarm, polarized, milling, transition, transition, -, swarm
    assert got == {"swarming_fraction": 2 / 6, "polarized_fraction": 1 / 6, "milling_fraction": 1 / 6}
    wider = state_fractions(p, m, high=0.85, low=0.55)   # swarm, polarized, -, swarm, polarized, -, swarm
    assert wider == {"swarming_fraction": 3 / 6, "polarized_fraction": 2 / 6, "milling_fraction": 0.0}
    assert all(math.isnan(v) for v in state_fractions(p[5:6], m[5:6]).values())


@pytest.mark.parametrize("seed", range(3))
def test_run_scalars_match_their_twin_with_missing_individuals(seed):
    rng = np.random.default_rng(seed)
    records, n = 15, 7
    vel = np.array([1.0, 0.2, 0.0]) + rng.normal(0, 0.4, (records, n, 3))
    vel[rng.random((records, n)) < 0.2] = np.nan           # not seen
    vel[3, 2] = 0.0                                          # stopped
    vel[:, 5] = np.nan                                       # never seen
    t = np.arange(records) * 0.4
    pol, mil = rng.uniform(0, 1, records), rng.uniform(0, 1, records)
    got = motion_metrics(vel, t, 0.4, 1.0, pol, mil)
    want = ref.motion_metrics(vel, t, 0.4, 1.0, pol, mil)
    assert tuple(got) == MOTION_METRIC_NAMES
    for name in MOTION_METRIC_NAMES:
        assert close(got[name], want[name]), (name, got[name], want[name])
    short = motion_metrics(vel[:1], t[:1], 0.4, 0.0, pol[:1], mil[:1])
    assert all(math.isnan(short[name]) for name in MOTION_METRIC_NAMES if "fraction" not in name and "speed_q" not in name
               and name != "speed_cv_pooled")


# ---------------------------------------------------------------------------------------- in the row

def observed(pos, vel, present, interval=0.5):
    times = np.arange(len(pos)) * interval
    return ObservedFlock("f", np.arange(pos.shape[1]), times, np.where(present[..., None], pos, np.nan),
                         np.where(present[..., None], vel, np.nan), present, interval=interval)


def test_missing_detections_are_measured_over_the_individuals_present():
    """A record with an individual missing gives the series of the flock without it, and an individual never
    seen changes nothing at all."""
    pos, vel = flock(11, n=10, records=6)
    present = np.ones((6, 10), bool)
    present[2, 4] = False
    got = present_metrics(observed(pos, vel, present), 5.0, k_nearest=3)
    alone = series_of(np.delete(pos[2], 4, axis=0)[None], np.delete(vel[2], 4, axis=0)[None], 5.0, k=3)
    for name in NEW_SERIES:
        assert close(got[name][2], alone[name][0]), name
    present[:, 9] = False
    settings = MetricSettings(group_radius=5.0, warmup=0.0, escape_duration=math.nan, k_nearest=3)
    row = measure_run(observed(pos, vel, present), settings).row
    fewer = measure_run(observed(pos[:, :9], vel[:, :9], present[:, :9]), settings).row
    assert row.keys() == fewer.keys()
    for name, value in row.items():
        if name != "tracked_mean" and name != "tracked_final":
            assert close(value, fewer[name]), name


def test_row_holds_the_motion_columns_in_order_and_the_settings_act():
    pos, vel = flock(12, n=10, records=8)
    present = np.ones((8, 10), bool)
    plain = MetricSettings(group_radius=5.0, warmup=1.0, escape_duration=math.nan)
    row = measure_run(observed(pos, vel, present), plain).row
    columns = summary_columns(leadership=False)
    assert [c for c in row if c in columns] == list(columns)
    at = columns.index(MOTION_METRIC_NAMES[0])
    assert columns[at:at + len(MOTION_METRIC_NAMES) + 2] == MOTION_METRIC_NAMES + RUN_COLUMNS
    off = measure_run(observed(pos, vel, present), MetricSettings(group_radius=5.0, warmup=1.0,
                      escape_duration=math.nan, pairwise_metrics=False, state_high=0.5, state_low=0.5)).row
    assert all(math.isnan(off[f"{name}_mean"]) for name in PAIRWISE_SERIES)
    assert off["polarized_fraction"] + off["swarming_fraction"] + off["milling_fraction"] <= 1.0
    assert motion_settings(plain) == {}
    assert motion_settings(MetricSettings(k_nearest=3, state_low=0.3)) == {"k_nearest": 3, "state_low": 0.3}


@pytest.mark.parametrize("change, message", [
    ({"k_nearest": 0}, r"k_nearest: got 0; expected a whole number >= 1"),
    ({"k_nearest": 2.5}, r"k_nearest: got 2.5"),
    ({"pairwise_metrics": "yes"}, r"pairwise_metrics: got 'yes'; expected true or false"),
    ({"state_high": 1.5}, r"state_high: got 1.5; allowed range \[0.0, 1.0\]"),
    ({"state_low": 0.7}, r"state_low: got 0.7, above state_high = 0.65"),
])
def test_bad_settings_name_the_key(change, message):
    with pytest.raises(ConfigError, match=message):
        MetricSettings(**change)


def test_focal_kernel_ranks_ties_by_index_and_skips_coincident_boids():
    pos = np.array([[0.0, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [0.0, 0, 0]])   # 3 sits on 0
    vel = np.tile(X, (4, 1))
    out = np.empty(6)
    kernels.focal_neighbours_frame(pos, vel, 0.0, 1, True, np.empty(4), np.empty(4, np.int64), out)
    # 0 and 3: nearest 1 (ahead; 2 is as near, higher index); 1: nearest 0 (behind, before 3); 2: 0 (ahead)
    assert out[0] == pytest.approx(3 / 4) and close(out, ref.focal_neighbours(pos, vel, 1))


@pytest.mark.parametrize("m", [1, 2, 7, 33, 435, 4950])
def test_distance_order_sorts_any_keys(m):
    """The bucket sort behind the correlation length: sorted keys for uniform, clustered (a bucket above 32
    entries) and tied keys."""
    rng = np.random.default_rng(m)
    for key in (rng.random(m), np.r_[rng.random(m // 2) * 1e-3, 5 + rng.random(m - m // 2)],
                rng.integers(0, 4, m).astype(float), np.full(m, 2.5)):
        order = np.empty(m, np.int64)
        kernels.distance_order(key, m, order)
        assert sorted(order) == list(range(m)) and np.all(np.diff(key[order]) >= 0)
