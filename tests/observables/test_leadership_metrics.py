"""Leadership metrics (analysis/leadership.py): hand-made cases with known answers, then real runs of the
hartman_benes preset."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from flocksweep.observables.leadership import (LEADERSHIP_METRIC_NAMES, follow_curve, leadership_input,
                                             leadership_metrics)
from flocksweep.observables.summary import observation_leadership
from flocksweep.simcore import load_preset, simulate_preset
from paths import ROOT

PRESET = ROOT / "configs" / "models" / "hartman_benes.toml"
FOLLOW = ("follow_corr_lag0", "follow_corr_max", "follow_lag_max", "follow_corr_before")


def random_units(rng, shape):
    v = rng.standard_normal(shape + (3,))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def run(n_rec, n, dt=0.1, record_every=1, pos=None, vel=None, leader=None, triggers=()):
    """Explicit observation arrays: records every dt x record_every from t = 0; boids parked in a tight
    cluster (all within 1 unit) unless ``pos`` is given, flying along +x unless ``vel`` is given."""
    if pos is None:
        offsets = np.random.default_rng(0).uniform(-0.3, 0.3, (n, 3))
        pos = np.broadcast_to(offsets, (n_rec, n, 3)).copy()
    if vel is None:
        vel = np.zeros((n_rec, n, 3))
        vel[..., 0] = 1.0
    return dict(times=np.arange(n_rec) * dt * record_every, pos=pos, vel=vel,
                leader=np.zeros((n_rec, n), bool) if leader is None else np.asarray(leader, bool),
                triggers=np.array(triggers, dtype=np.int64).reshape(-1, 2), dt=dt, record_every=record_every)


# ---------------------------------------------------------------------------------------------------
# hand-made arrays


def test_no_triggers_gives_zero_rate_and_nan_follow_metrics():
    m = leadership_metrics(run(50, 8), group_radius=2.0, escape_duration=3.0)
    assert tuple(m) == LEADERSHIP_METRIC_NAMES
    assert m["trigger_rate"] == 0.0
    assert m["leader_time_fraction"] == 0.0 and m["leaders_mean"] == 0.0
    for name in FOLLOW + ("heading_change_deg", "escape_gain"):
        assert math.isnan(m[name]), name
    curve = follow_curve(run(50, 8), 2.0, 3.0, max_lag=1.0)
    assert len(curve) == 11 and curve["corr"].isna().all() and (curve["pairs"] == 0).all()


def test_trigger_rate_counts_events_per_boid_per_minute():
    # 6 events, 3 boids, a 120 s run (records every 1 s, t = 0..120) -> 6 / 3 / 2 = 1 per boid per minute
    obs = run(121, 3, dt=0.5, record_every=2, triggers=[(0, 0), (10, 1), (50, 2), (100, 0), (200, 1), (239, 2)])
    assert leadership_metrics(obs, 2.0, 3.0)["trigger_rate"] == pytest.approx(1.0, rel=1e-12)
    obs["triggers"] = obs["triggers"][:3]
    assert leadership_metrics(obs, 2.0, 3.0)["trigger_rate"] == pytest.approx(0.5, rel=1e-12)


def test_leader_fraction_and_mean_on_a_hand_made_leader_array():
    leader = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 1]]
    m = leadership_metrics(run(5, 3, leader=leader), 2.0, 3.0)
    assert m["leader_time_fraction"] == pytest.approx(3 / 5)
    assert m["leaders_mean"] == pytest.approx(6 / 5)


def delayed_copy_flock(seed, n_rec, n, delay, copy=True):
    """Boid 0 flies iid random headings at random speeds; with ``copy`` every other boid flies boid 0's
    velocity of ``delay`` records earlier (random before that), otherwise its own random headings."""
    rng = np.random.default_rng(seed)
    vel = random_units(rng, (n_rec, n)) * rng.uniform(0.5, 2.0, (n_rec, n, 1))
    if copy:
        vel[delay:, 1:] = vel[:-delay, :1]
    return vel


@pytest.mark.parametrize("delay", [1, 4, 9])
def test_followers_copying_the_leader_with_a_delay_peak_at_that_lag(delay):
    # records every 0.1 s (dt 0.05, 2 steps); 29 events of boid 0, 40 records apart
    n_rec, n = 1200, 6
    vel = delayed_copy_flock(7, n_rec, n, delay)
    obs = run(n_rec, n, dt=0.05, record_every=2, vel=vel, triggers=[(2 * r, 0) for r in range(20, 1160, 40)])
    m = leadership_metrics(obs, group_radius=2.0, escape_duration=3.0, max_lag=2.0)
    assert m["follow_lag_max"] == pytest.approx(delay * 0.1, abs=1e-12)
    assert m["follow_corr_max"] == pytest.approx(1.0, abs=1e-12)
    assert abs(m["follow_corr_lag0"]) < 0.1
    curve = follow_curve(obs, 2.0, 3.0, max_lag=2.0)
    assert np.allclose(curve["lag"], np.arange(21) * 0.1)
    assert int(curve["corr"].idxmax()) == delay
    assert curve["corr"].iloc[0] == m["follow_corr_lag0"]
    assert (curve["pairs"] == 29 * (n - 1)).all() and (curve["events"] == 29).all()
    # every other lag pairs unrelated headings: about 0 (sd ~ 0.02 with 29 events of ~25 records)
    others = np.delete(curve["corr"].to_numpy(), delay)
    assert np.abs(others).max() < 0.15


def test_independent_headings_give_near_zero_correlation():
    n_rec, n = 1200, 6
    vel = delayed_copy_flock(8, n_rec, n, 4, copy=False)
    obs = run(n_rec, n, dt=0.05, record_every=2, vel=vel, triggers=[(2 * r, 0) for r in range(20, 1160, 40)])
    m = leadership_metrics(obs, 2.0, 3.0)
    assert abs(m["follow_corr_lag0"]) < 0.1
    assert abs(m["follow_corr_max"]) < 0.1
    assert abs(m["follow_corr_before"]) < 0.1


def test_following_that_starts_at_the_trigger_shows_against_the_baseline():
    # one event at record 200: before it the 29 followers fly at random, from then on they copy the leader
    # 3 records late -> the lag-0.3 s correlation is 1 after the trigger, the baseline before it about 0
    n_rec, n, r0, delay = 300, 30, 200, 3
    rng = np.random.default_rng(11)
    vel = random_units(rng, (n_rec, n)) * 1.5
    vel[r0 + delay:, 1:] = vel[r0:n_rec - delay, :1]
    m = leadership_metrics(run(n_rec, n, vel=vel, triggers=[(r0, 0)]), 2.0, 3.0)
    assert m["follow_lag_max"] == pytest.approx(0.3)
    assert m["follow_corr_max"] == pytest.approx(1.0, abs=1e-12)
    assert abs(m["follow_corr_before"]) < 0.1


def test_events_without_followers_are_skipped():
    # boid 0 is a stray 50 units away from the others: its events have no follower
    n_rec, n = 100, 4
    pos = np.zeros((n_rec, n, 3))
    pos[:, 1:, 1] = [0.0, 0.5, 1.0]
    pos[:, 0, 0] = 50.0
    stray = run(n_rec, n, pos=pos, triggers=[(10, 0), (50, 0)])
    m = leadership_metrics(stray, 2.0, 3.0)
    assert m["trigger_rate"] > 0
    for name in FOLLOW:
        assert math.isnan(m[name]), name
    # a larger group radius joins it to the flock, and the (aligned) followers correlate perfectly
    m = leadership_metrics(stray, 60.0, 3.0)
    assert m["follow_corr_lag0"] == pytest.approx(1.0) and m["follow_corr_before"] == pytest.approx(1.0)


def test_groups_use_the_minimum_image_in_a_periodic_box():
    n_rec = 60
    pos = np.zeros((n_rec, 2, 3))
    pos[:, 0, 0], pos[:, 1, 0] = -49.6, 49.6   # 0.8 apart across the boundary of a box of side 100
    obs = run(n_rec, 2, pos=pos, triggers=[(5, 0)])
    assert math.isnan(leadership_metrics(obs, 2.0, 3.0)["follow_corr_lag0"])
    assert leadership_metrics(obs, 2.0, 3.0, box=100.0)["follow_corr_lag0"] == pytest.approx(1.0)


def test_a_group_turning_a_right_angle_and_the_escape_gain():
    # 5 boids fly +x until record 20, then +y; the event at record 10 ends its 3 s window at record 40
    n_rec, n = 60, 5
    vel = np.zeros((n_rec, n, 3))
    vel[:20, :, 0] = 1.0
    vel[20:, :, 1] = 1.0
    vel[:, 0] *= np.interp(np.arange(n_rec), [0, 10, 25, 40, 59], [1.2, 1.0, 2.5, 1.5, 1.0])[:, None]
    obs = run(n_rec, n, vel=vel, triggers=[(10, 0), (45, 2)])   # the second event's window runs past the end
    m = leadership_metrics(obs, 2.0, 3.0)
    assert m["heading_change_deg"] == pytest.approx(90.0, abs=1e-9)
    assert m["escape_gain"] == pytest.approx(2.5)
    # an event whose window stays on one heading does not turn
    straight = run(n_rec, n, vel=vel, triggers=[(20, 1)])
    assert leadership_metrics(straight, 2.0, 3.0)["heading_change_deg"] == pytest.approx(0.0, abs=1e-6)
    # no event fits
    late = run(n_rec, n, vel=vel, triggers=[(45, 2)])
    assert math.isnan(leadership_metrics(late, 2.0, 3.0)["heading_change_deg"])
    assert math.isnan(leadership_metrics(late, 2.0, 3.0)["escape_gain"])


def test_inputs_are_checked():
    obs = run(10, 3)
    with pytest.raises(ValueError, match="missing"):
        leadership_input({k: v for k, v in obs.items() if k != "triggers"})
    with pytest.raises(ValueError, match="evenly spaced"):
        leadership_input({**obs, "record_every": 3})
    with pytest.raises(ValueError, match="triggers"):
        leadership_input({**obs, "triggers": [(0, 3)]})
    with pytest.raises(ValueError, match="escape_duration"):
        leadership_metrics(obs, 2.0, 0.0)


# ---------------------------------------------------------------------------------------------------
# real runs of the hartman_benes preset (30 s, 100 boids, records every 0.1 s = 3 steps)


@pytest.fixture(scope="module")
def runs():
    out = {}
    for x in (0.0, 0.5, 1.0, 2.0):
        preset = load_preset(PRESET, [f"leadership.x={x}", "run.record_interval=0.1"])
        out[x] = preset, simulate_preset(preset, seed=1)
    return out


def test_preset_without_leadership_has_no_events(runs):
    preset, obs = runs[0.0]
    m = observation_leadership(obs, preset.model)
    assert obs.triggers.shape == (0, 2)
    assert m["trigger_rate"] == 0.0 and m["leaders_mean"] == 0.0 and m["leader_time_fraction"] == 0.0
    assert all(math.isnan(m[name]) for name in FOLLOW)


def test_preset_with_leadership_has_events_and_finite_follow_metrics(runs):
    preset, obs = runs[1.0]
    m = observation_leadership(obs, preset.model)
    assert m["trigger_rate"] > 0
    assert m["trigger_rate"] == pytest.approx(len(obs.triggers) / obs.n / 0.5)
    for name in FOLLOW + ("heading_change_deg", "escape_gain"):
        assert np.isfinite(m[name]), name
    assert -1.0 <= m["follow_corr_lag0"] <= m["follow_corr_max"] <= 1.0
    assert 0.0 <= m["follow_lag_max"] <= 2.0
    # the escape speeds the leader up (its cap doubles at the profile's peak)
    assert m["escape_gain"] > 1.0
    # explicit arrays give the same numbers as the Observations
    arrays = {k: getattr(obs, k) for k in ("times", "pos", "vel", "leader", "triggers", "dt", "record_every")}
    assert leadership_metrics(arrays, 5.0, 3.0) == m


def test_trigger_rate_grows_with_x_up_to_one_escape_per_boid_per_escape(runs):
    # Expectation from the preset: a boid triggers when X x_i > g with g ~ N(1/2, 1/6) clipped to [0, 1],
    # so a larger X passes the test for more front-edge boids: more events. A boid cannot trigger again
    # while it leads (3 s, refractory 0), so no rate exceeds 60 / 3 = 20 per boid per minute
    # (measured, seed 1: 8.66 at X = 0.5, 14.42 at X = 1, 15.72 at X = 2).
    rates = {x: observation_leadership(obs, preset.model)["trigger_rate"] for x, (preset, obs) in runs.items()}
    assert rates[2.0] > rates[0.5] > 0
    assert all(rate <= 20.0 for rate in rates.values())
