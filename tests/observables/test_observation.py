"""The observation model (observables.observation): validation, determinism, and the statistics
moving by the amounts it predicts under position noise, missed detections and jittered time stamps."""
from __future__ import annotations

import math

import numpy as np
import pytest

from flocksweep.observables.measured import track_settings
from flocksweep.observables.metrics import frame_metrics
from flocksweep.observables.observation import Observation, detect, observe_run, predicted_velocity_sd
from flocksweep.observables.resample import resample
from flocksweep.observables.summary import measure_run, summarize_run
from flocksweep.observables.tracks import RawFlock
from flocksweep.simcore import load_preset, simulate
from flocksweep.simcore.schema import ConfigError
from flocksweep.simcore.simulate import Observations
from paths import ROOT

HOLLAND = ROOT / "configs/models/holland.toml"


def straight_run(n: int = 50, n_records: int = 401, interval: float = 0.1, speed: float = 10.0) -> Observations:
    """A flock flying straight along x at ``speed`` on a 5 x 10 lattice (no simulator)."""
    times = np.arange(n_records) * interval
    lattice = np.array([[2.0 * (i % 5), 2.0 * (i // 5), 0.0] for i in range(n)])
    pos = lattice[None] + times[:, None, None] * np.array([speed, 0.0, 0.0])
    vel = np.broadcast_to([speed, 0.0, 0.0], pos.shape).copy()
    blank = np.zeros((n_records, n), np.int32)
    return Observations(times=times, pos=pos, vel=vel, visible=blank, binocular=blank, leader=blank.astype(bool),
                        triggers=np.zeros((0, 2), np.int64), pattern=np.zeros(n, np.uint32), final=None,
                        dt=interval, record_every=1)


def test_observation_block_is_validated_with_key_names():
    with pytest.raises(ConfigError, match="interval: got -1"):
        Observation(interval=-1)
    with pytest.raises(ConfigError, match="velocity_interval: .*whole multiple"):
        Observation(interval=0.2, velocity_interval=0.3)
    with pytest.raises(ConfigError, match="detection_probability: got 0"):
        Observation(interval=0.2, detection_probability=0.0)
    with pytest.raises(ConfigError, match="position_sd"):
        Observation(interval=0.2, position_sd=-0.1)
    with pytest.raises(ConfigError, match="max_gap: got 0.1; must be at least the interval 0.2"):
        Observation(interval=0.2, max_gap=0.1)
    with pytest.raises(ConfigError, match="interval: got 0.21; must be a whole multiple of the run's dt"):
        Observation(interval=0.21).record_every(1 / 60)
    assert Observation(interval=0.2).record_every(1 / 60) == 12


def test_same_seed_same_observed_flock_and_independent_of_other_runs():
    run = straight_run(n=10, n_records=60)
    observation = Observation(interval=0.1, velocity_interval=0.2, detection_probability=0.8, position_sd=0.3)
    a, b = observe_run(run, observation, 5), observe_run(run, observation, 5)
    assert np.array_equal(a.pos, b.pos, equal_nan=True) and np.array_equal(a.present, b.present)
    c = observe_run(run, observation, np.random.SeedSequence(5))
    assert np.array_equal(a.pos, c.pos, equal_nan=True)
    d = observe_run(run, observation, 6)
    assert not np.array_equal(a.present, d.present)
    # detections and noise are separate streams: switching the noise off keeps the same detections
    quiet = observe_run(run, Observation(interval=0.1, velocity_interval=0.2, detection_probability=0.8), 5)
    assert np.array_equal(a.present, quiet.present)


def test_projection_zeroes_the_dropped_axis_and_marks_two_dimensions():
    obs = simulate(load_preset(HOLLAND).model, load_preset(HOLLAND, ["init.n=8"]).init, 1, 1.0, 1 / 60, 6)
    flock = observe_run(obs, Observation(interval=0.1, projection="xz", position_sd=0.1), 2)
    assert flock.dims == 2
    assert np.all(flock.pos[..., 1] == 0.0) and np.all(flock.vel[..., 1] == 0.0)
    assert np.std(flock.pos[..., 0] - obs.pos[::1][:len(flock.times), :, 0]) > 0.05


def test_missed_detections_leave_n_p_squared_or_bridged_n_p2_3_minus_2p_individuals():
    run = straight_run(n=50, n_records=400)
    p = 0.8
    # forward differences: present at a record when detected there and at the next sample
    flock = observe_run(run, Observation(interval=0.1, detection_probability=p, max_gap=0.15), 1)
    assert abs(flock.tracked.mean() - 50 * p ** 2) < 0.25
    # centred over two intervals: detected at the previous, this and the next sample
    flock = observe_run(run, Observation(interval=0.1, velocity_interval=0.2, detection_probability=p, max_gap=0.15), 1)
    assert abs(flock.tracked.mean() - 50 * p ** 3) < 0.25
    # one missed sample bridged (default max_gap 2.5 intervals): p^2 (3 - 2p)
    flock = observe_run(run, Observation(interval=0.1, detection_probability=p), 1)
    assert abs(flock.tracked[1:-1].mean() - 50 * p ** 2 * (3 - 2 * p)) < 0.25


@pytest.mark.parametrize("projection, dims", [("none", 3), ("xy", 2)])
def test_position_noise_lowers_polarization_and_raises_speed_as_predicted(projection, dims):
    n, speed = 50, 10.0
    observation = Observation(interval=0.1, velocity_interval=0.1, position_sd=0.05, projection=projection)
    rho2 = (predicted_velocity_sd(observation) / speed) ** 2              # (sigma sqrt 2 / D)^2 / s^2 = 0.005
    assert math.isclose(rho2, 0.005)
    flock = observe_run(straight_run(n=n, speed=speed), observation, 9)
    row = measure_run(flock, track_settings(3.0)).row
    # |mean unit heading| = 1 - (d - 1)/2 rho^2 (1 - 1/N); |v| = s (1 + (d - 1)/2 rho^2); cv = rho
    assert abs(row["polarization_mean"] - (1 - (dims - 1) / 2 * rho2 * (1 - 1 / n))) < 3e-4
    assert abs(row["speed_mean_mean"] / speed - (1 + (dims - 1) / 2 * rho2)) < 3e-4
    assert abs(row["speed_cv_mean"] - math.sqrt(rho2)) < 2e-3
    clean = measure_run(observe_run(straight_run(n=n, speed=speed), Observation(interval=0.1), 9),
                        track_settings(3.0)).row
    assert clean["polarization_mean"] == 1.0 and clean["speed_mean_mean"] == pytest.approx(speed, rel=1e-12)


def _sample_at(obs, steps_per_sample: int, rng, jitter: int, p: float, sd: float) -> RawFlock:
    """A tracker built here, not by the observation module: every steps_per_sample steps, each sample taken
    jitter steps early or late at random and stamped with its true time, detected with probability p, with
    Gaussian noise of sd on each coordinate."""
    nominal = np.arange(jitter, len(obs.times) - jitter, steps_per_sample)
    steps = nominal[:, None] + rng.integers(-jitter, jitter + 1, size=(len(nominal), obs.n))
    birds = np.broadcast_to(np.arange(obs.n), steps.shape)
    keep = rng.random(steps.shape) < p
    pos = obs.pos[steps, birds] + rng.normal(0.0, sd, steps.shape + (3,))
    order = np.lexsort((steps[keep], birds[keep]))
    return RawFlock(name="measured", ids=np.arange(obs.n), t=obs.times[steps[keep]][order],
                    ind=birds[keep][order].astype(np.int64), pos=pos[keep][order], pattern=np.zeros(obs.n, np.int64))


def _flock_run(duration: float = 10.0, n: int = 20):
    preset = load_preset(HOLLAND, [f"init.n={n}", "init.radius=8.0"])
    return simulate(preset.model, preset.init, 11, duration, preset.run.dt, 1)


@pytest.mark.slow
def test_noisy_gappy_tracks_measure_as_the_observation_model_predicts():
    obs = _flock_run()
    columns = ("polarization_mean", "nn_distance_mean", "speed_mean_mean", "speed_cv_mean", "gyration_radius_mean",
               "tracked_mean")
    observation = Observation(interval=0.2, velocity_interval=0.4, detection_probability=0.9, position_sd=0.2)
    settings = track_settings(20.0, warmup=3.0)
    draws = 30
    rng = np.random.default_rng(2026)
    measured = np.array([[measure_run(resample(_sample_at(obs, 12, rng, 0, 0.9, 0.2), 0.2, None, 0.4), settings).row[c]
                          for c in columns] for _ in range(draws)])
    predicted = np.array([[summarize_run(observe_run(obs, observation, seed), settings)[c] for c in columns]
                          for seed in range(draws)])
    clean = summarize_run(observe_run(obs, Observation(interval=0.2, velocity_interval=0.4), 0), settings)
    se = np.sqrt(measured.var(axis=0, ddof=1) / draws + predicted.var(axis=0, ddof=1) / draws)
    gap = measured.mean(axis=0) - predicted.mean(axis=0)
    assert np.all(np.abs(gap) < 4 * se + 1e-9), dict(zip(columns, gap / se))
    # and the shifts themselves are real: noise lowers polarization, raises speed and its spread
    shift = predicted.mean(axis=0) - np.array([clean[c] for c in columns])
    assert shift[0] < -0.01 and shift[2] > 0.02 and shift[3] > 0.02


def test_jittered_time_stamps_move_positions_by_at_most_the_interpolation_bound():
    obs = _flock_run(duration=6.0, n=12)
    rng = np.random.default_rng(7)
    flock = resample(_sample_at(obs, 12, rng, 2, 1.0, 0.0), 0.2, max_gap=0.5, velocity_interval=0.2)
    # records at the nominal times 2/60 + 0.2 k (up to the phase estimate's error, well below a step)
    assert abs(flock.t_start - 2 / 60) < 0.1 / 60 and np.allclose(np.diff(flock.times), 0.2)
    grid = flock.times + flock.t_start
    # the true positions there, from the run's every-step records (error <= A dt^2 / 8, negligible)
    steps = grid / obs.dt
    low = np.floor(steps).astype(int)
    w = (steps - low)[:, None, None]
    truth = obs.pos[low] * (1 - w) + obs.pos[low + 1] * w
    # linear interpolation between samples g apart misses a path with |acceleration| <= A by <= A g^2 / 8
    accel = np.linalg.norm(np.diff(obs.vel, axis=0), axis=2).max() / obs.dt
    g = 0.2 + 4 / 60
    bound = accel * (g * g + obs.dt * obs.dt) / 8
    inner = slice(1, len(grid) - 1)
    assert flock.present[inner].all()                 # only the ends can miss a jittered sample
    error = np.linalg.norm(flock.pos[inner] - truth[inner], axis=2).max()
    assert 0 < error <= bound
    a = frame_metrics(flock.pos[inner], flock.vel[inner], None, None, None, 20.0)
    b = frame_metrics(truth[inner], flock.vel[inner], None, None, None, 20.0)
    # each distance moves by at most 2 x the position error, so do the nearest neighbours and the size
    assert np.all(np.abs(a["nn_distance"] - b["nn_distance"]) <= 2 * error + 1e-12)
    assert np.all(np.abs(a["gyration_radius"] - b["gyration_radius"]) <= 2 * error + 1e-12)


def test_detect_keeps_every_sample_of_a_perfect_tracker():
    run = straight_run(n=6, n_records=30)
    raw = detect(run, Observation(interval=0.2), 0)
    assert len(raw.t) == 6 * 15 and np.array_equal(raw.pos[raw.ind == 2], run.pos[::2, 2])
    with pytest.raises(ValueError, match="not a whole multiple"):
        detect(run, Observation(interval=0.15), 0)
