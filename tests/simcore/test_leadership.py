"""Hartman-Benes dynamics and the change of leadership (docs/model.md sections 5 and 7).

* the compiled Hartman-Benes step agrees with the slow reference (tests/reference_hb.py) step by step,
  with and without leadership (the reference uses the same counter-based draws);
* X = 0 is exactly "no leadership" for every dynamics;
* the trigger probability is P(X score > g) for g = clip(1/2 + sigma z, 0, 1), for every front gate;
* a leader cannot re-trigger during its escape (+ refractory), and the leader records say who leads;
* the escape profile and the speed a lone leader gains follow the specification;
* events grow with X; batches and repeated runs give the same triggers bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate
from scipy.stats import norm

import reference_hb as ref_hb
from conftest import flock_state, state_from
from flocksweep.simcore import advance, load_preset, preset_from_dict, simulate, simulate_batch
from flocksweep.simcore.layout import pack
from flocksweep.simcore.leadership import decide, profile
from flocksweep.simcore.params import read_toml
from flocksweep.simcore.state import FIELDS
from paths import ROOT

MODELS = ROOT / "configs" / "models"
HB_PRESET = MODELS / "hartman_benes.toml"
RTOL = ATOL = 1e-12
DT = 1 / 30  # the preset's frame
N_BOIDS = 32
N_STEPS = 8
KEY = 0x5EED_1EAD
MODEL_PROFILE = [0.01, 0.05, 0.10, 0.16, 0.27, 0.40, 0.55, 0.72, 0.85, 0.96, 1.00, 0.98, 0.90, 0.80, 0.65,
                 0.51, 0.36, 0.25, 0.18, 0.14, 0.12, 0.10, 0.08, 0.07, 0.06, 0.05, 0.04, 0.03, 0.02, 0.00]


def hb_preset(*overrides):
    return load_preset(HB_PRESET, list(overrides))


def hb_model(*overrides):
    return hb_preset(*overrides).model


def leadership_state(state, model, seed):
    """``state`` with a mix of leadership clocks: never led, leading at every phase of the escape (some
    about to finish within the window), refractory; two leaders escape along a fixed (slow) direction."""
    rng = np.random.default_rng(seed)
    lead = model.leadership
    n = state.n
    clock = np.full(n, np.inf)
    chosen = rng.permutation(n)[: n // 2]
    clock[chosen] = rng.uniform(0.0, lead.duration + lead.refractory + 0.1, len(chosen))
    ending = chosen[:3]
    clock[ending] = lead.duration - rng.uniform(0.5, N_STEPS / 2, 3) * DT  # the escape ends in the window
    escape = np.zeros((n, 3))
    for i in chosen[3:5]:
        clock[i] = rng.uniform(0.1, 0.5) * lead.duration
        d = rng.standard_normal(3)
        escape[i] = d / np.linalg.norm(d)
    return replace(state, clock=clock, escape=escape)


# --------------------------------------------------------------------------------------------------
# 1. kernel == reference, step by step

# (id, preset overrides)
STEP_CASES = [
    ("preset", ()),
    ("falloff0", ("gains.separation_falloff_exponent=0",)),
    ("falloff1.5", ("gains.separation_falloff_exponent=1.5",)),
    ("sequential", ("world.update_order=sequential",)),
    ("sequential-falloff0", ("world.update_order=sequential", "gains.separation_falloff_exponent=0")),
    ("box", ("world.boundary=periodic_box", "world.box_size=9.0", "perception.radius=4.0")),
    ("lead-positive", ("leadership.x=3",)),
    ("lead-weighted-seq-falloff0", ("leadership.x=4", "leadership.front_gate=weighted",
                                    "world.update_order=sequential", "gains.separation_falloff_exponent=0")),
    ("lead-none-refractory-box", ("leadership.x=2", "leadership.front_gate=none", "leadership.duration=0.5",
                                  "leadership.refractory=0.1", "world.boundary=periodic_box",
                                  "world.box_size=9.0", "perception.radius=4.0")),
    ("lead-slow-seq-box", ("leadership.x=3", "leadership.slow_speed=1.5", "leadership.gain=0.5",
                           "leadership.boost=2.0", "world.update_order=sequential",
                           "world.boundary=periodic_box", "world.box_size=9.0", "perception.radius=4.0")),
]


def case_state(model, seed):
    max_speed = model.vehicle.max_speed
    if model.world.boundary == "periodic_box":
        state = flock_state(seed, N_BOIDS, box_size=model.world.box_size, max_speed=max_speed)
    else:
        state = flock_state(seed, N_BOIDS, ball_radius=4.0, max_speed=max_speed)
    state = replace(state, pattern=np.zeros(N_BOIDS, np.uint32))
    return leadership_state(state, model, seed) if model.leadership.x > 0 else state


@pytest.mark.parametrize("seed, overrides", [pytest.param(seed, ov, id=name)
                                             for seed, (name, ov) in enumerate(STEP_CASES)])
@pytest.mark.slow
def test_kernel_matches_reference_step_by_step(seed, overrides):
    model = hb_model(*overrides)
    lead = model.leadership
    state = case_state(model, seed)
    neighbours = triggers = slow_triggers = escaping = over_cap = wrapped = 0
    for k in range(N_STEPS):
        key = KEY + k  # advance() numbers its steps from 0: vary the key so the draws change every step
        obs = advance(model, state, 1, DT, key=key)
        ref = ref_hb.step(state, model, DT, step_index=0, key=key)
        for name in ref_hb.STATE_KEYS:
            np.testing.assert_allclose(getattr(obs.final, name), ref[name], rtol=RTOL, atol=ATOL,
                                       err_msg=f"step {k}: {name}")
        np.testing.assert_array_equal(obs.visible[0], ref["visible"], err_msg=f"step {k}: visible")
        assert obs.triggers.tolist() == [list(t) for t in ref["triggers"]], f"step {k}: triggers"
        np.testing.assert_array_equal(obs.leader[0], state.clock < lead.duration - 0.5 * DT,
                                      err_msg=f"step {k}: leader")

        neighbours += int(ref["visible"].sum())
        triggers += len(ref["triggers"])
        slow_triggers += sum(1 for _, i in ref["triggers"] if np.any(ref["escape"][i] != 0))
        escaping += int(np.sum(state.clock < lead.duration - 0.5 * DT))
        over_cap += int(np.sum(np.linalg.norm(ref["vel"], axis=1) > model.vehicle.max_speed * (1 + 1e-9)))
        wrapped += int(np.sum(np.linalg.norm(obs.final.pos - state.pos, axis=1) > 1.0))
        state = obs.final

    # the comparison was meaningful
    assert neighbours / (N_STEPS * N_BOIDS) >= 5.0, "too few neighbours for a meaningful comparison"
    if lead.x > 0:
        assert triggers >= 3, "no triggers in the comparison window"
        assert escaping > 0 and over_cap > 0, "no escape raised a speed above max_speed"
        if lead.slow_speed is not None:
            assert slow_triggers > 0, "no slow boid triggered"
    else:
        assert triggers == 0 and over_cap == 0
    if model.world.boundary == "periodic_box":
        assert wrapped > 0, "no boid crossed the box"


@pytest.mark.parametrize("overrides", [("leadership.x=3",),
                                       ("leadership.x=3", "leadership.front_gate=none",
                                        "world.update_order=sequential", "leadership.duration=0.4")],
                         ids=["positive-sync", "none-seq-short"])
def test_kernel_matches_reference_over_a_run(overrides):
    """One compiled call of many steps (step counter 0, 1, ... in the draws) against the reference run
    continuing from its own state; records, leader flags and trigger events agree."""
    model = hb_model(*overrides)
    n_steps = 30
    state = leadership_state(replace(flock_state(40, N_BOIDS, ball_radius=4.0, max_speed=5.0),
                                     pattern=np.zeros(N_BOIDS, np.uint32)), model, 40)
    obs = advance(model, state, n_steps, DT, record_every=1, key=KEY)
    current = {name: getattr(state, name) for name in ref_hb.STATE_KEYS}
    events = []
    for k in range(n_steps + 1):
        np.testing.assert_allclose(obs.pos[k], current["pos"], rtol=1e-10, atol=1e-10, err_msg=f"record {k}")
        np.testing.assert_allclose(obs.vel[k], current["vel"], rtol=1e-10, atol=1e-10, err_msg=f"record {k}")
        np.testing.assert_array_equal(obs.leader[k], current["clock"] < model.leadership.duration - 0.5 * DT)
        if k < n_steps:
            out = ref_hb.step(current, model, DT, step_index=k, key=KEY)
            events += out["triggers"]
            current = {name: out[name] for name in ref_hb.STATE_KEYS}
    assert obs.triggers.tolist() == [list(e) for e in events]
    assert len(events) >= 3
    assert len({s for s, _ in events}) >= 2, "triggers all in one step: the step counter is not exercised"


# --------------------------------------------------------------------------------------------------
# 2. X = 0 is exactly the model without leadership

OFF_TABLE = dict(x=0.0, front_gate="none", sigma=0.3, duration=0.5, gain=0.9, boost=2.0, refractory=0.2,
                 slow_speed=2.0)


def observation_arrays(obs) -> dict:
    out = {name: getattr(obs, name) for name in ("times", "pos", "vel", "visible", "binocular", "leader",
                                                  "triggers", "pattern")}
    out.update({f"final.{name}": getattr(obs.final, name) for name in FIELDS})
    return out


def assert_same_observations(a, b):
    xa, xb = observation_arrays(a), observation_arrays(b)
    for name in xa:
        assert xa[name].shape == xb[name].shape, name
        assert np.array_equal(xa[name], xb[name]), f"{name} differs"


@pytest.mark.parametrize("preset_name", ["hartman_benes", "opensteer", "holland"])
def test_x_zero_is_bit_identical_to_no_leadership(preset_name):
    data = read_toml(MODELS / f"{preset_name}.toml")
    absent = {key: value for key, value in data.items() if key != "leadership"}
    variants = [preset_from_dict(dict(absent, leadership=OFF_TABLE))]
    if "leadership" in data:
        variants.append(preset_from_dict(data))
    base = preset_from_dict(absent)
    init = replace(base.init, n=40)
    duration = 60 * base.run.dt
    reference = simulate(base.model, init, 11, duration, base.run.dt)
    for preset in variants:
        assert preset.model.leadership.x == 0.0
        obs = simulate(preset.model, init, 11, duration, base.run.dt)
        assert_same_observations(obs, reference)
        assert not obs.leader.any()
        assert obs.triggers.shape == (0, 2)
        assert np.all(np.isinf(obs.final.clock)) and not obs.final.escape.any()

    # the check has teeth: leadership on changes this very run
    on = preset_from_dict(dict(absent, leadership=dict(OFF_TABLE, x=20.0)))
    obs = simulate(on.model, init, 11, duration, base.run.dt)
    assert len(obs.triggers) > 0
    assert not np.array_equal(obs.pos, reference.pos)


# --------------------------------------------------------------------------------------------------
# 3. trigger probability

N_DRAWS = 20000


def trigger_probability(a: float, sigma: float) -> float:
    """P(a > g), g = clip(1/2 + sigma z, 0, 1): 0 for a <= 0, 1 for a > 1, Phi((a - 1/2)/sigma) between."""
    if a <= 0.0:
        return 0.0
    if a > 1.0:
        return 1.0
    return float(norm.cdf((a - 0.5) / sigma))


def boid_geometry(x, front, speed, e):
    """(k, v) with |k| / e = x, -(k/|k|).(v/|v|) = front, |v| = speed, in a generic orientation."""
    rot, _ = np.linalg.qr(np.array([[0.3, -1.2, 0.5], [0.8, 0.1, -0.7], [0.2, 0.9, 1.1]]))
    k_dir = rot[:, 0]
    perp = rot[:, 1]
    v_dir = -front * k_dir + math.sqrt(max(0.0, 1.0 - front * front)) * perp
    return x * e * k_dir, speed * v_dir


# (id, overrides, eccentricity x, front, speed (None: 3, a flying boid), expected score a / X, slow)
PROBABILITY_CASES = [
    ("positive-front", ("leadership.x=1",), 0.5, 0.6, None, 0.5, False),
    ("positive-front-2", ("leadership.x=1.5",), 0.4, 0.3, None, 0.4, False),
    ("positive-small-X", ("leadership.x=0.25",), 0.8, 0.9, None, 0.8, False),
    ("positive-behind", ("leadership.x=2",), 0.3, -0.5, None, 0.0, False),
    ("weighted-front", ("leadership.x=2", "leadership.front_gate=weighted"), 0.4, 0.5, None, 0.2, False),
    ("weighted-behind", ("leadership.x=5", "leadership.front_gate=weighted"), 0.6, -0.4, None, 0.0, False),
    ("none-behind", ("leadership.x=2", "leadership.front_gate=none"), 0.3, -0.5, None, 0.3, False),
    ("none-front", ("leadership.x=0.8", "leadership.front_gate=none"), 0.7, 0.2, None, 0.7, False),
    ("slow-positive-behind", ("leadership.x=1",), 0.7, -1.0, 0.1, 0.7, True),
    ("slow-weighted-behind", ("leadership.x=1", "leadership.front_gate=weighted"), 0.45, -0.8, 0.2, 0.45, True),
    ("stopped-none", ("leadership.x=1.2", "leadership.front_gate=none"), 0.35, 0.0, 0.0, 0.35, True),
    ("wide-sigma", ("leadership.x=0.5", "leadership.sigma=0.4"), 0.04, 0.7, None, 0.04, False),
    ("clipped-above", ("leadership.x=1.2", "leadership.sigma=0.4"), 0.9, 0.7, None, 0.9, False),
]


@pytest.mark.parametrize("overrides, x, front, speed, score, slow",
                         [pytest.param(*case[1:], id=case[0]) for case in PROBABILITY_CASES])
@pytest.mark.slow
def test_trigger_probability(overrides, x, front, speed, score, slow):
    model = hb_model(*overrides)
    lead = model.leadership
    fp, ip = pack(model, DT)
    e = model.perception.radius
    k, v = boid_geometry(x, front, 3.0 if speed is None else speed, e)
    boid, m = 3, 4
    clock = np.full(5, np.inf)
    expected = trigger_probability(lead.x * score, lead.sigma)

    hits = 0
    for step in range(N_DRAWS):
        fired, was_slow = decide(boid, step, k[0], k[1], k[2], m, v[0], v[1], v[2], clock, fp, ip, np.uint64(KEY))
        ref_fired, ref_slow = ref_hb.decide(boid, step, k, m, v, np.inf, model, KEY, DT)
        assert fired == ref_fired, f"draw {step}: kernel and reference disagree"
        if fired:
            assert was_slow == ref_slow == slow, f"draw {step}: slow flag"
        hits += fired
    rate = hits / N_DRAWS
    if expected in (0.0, 1.0):
        assert rate == expected
    else:
        se = math.sqrt(expected * (1 - expected) / N_DRAWS)
        assert abs(rate - expected) <= 4 * se, f"rate {rate:.4f}, expected {expected:.4f} +- {4 * se:.4f}"


def test_probability_cases_distinguish_the_clip():
    """The clipped case differs from the unclipped normal by many standard errors (the test has teeth)."""
    p_unclipped = norm.cdf((1.2 * 0.9 - 0.5) / 0.4)
    assert (1.0 - p_unclipped) > 10 * math.sqrt(p_unclipped * (1 - p_unclipped) / N_DRAWS)


def test_exact_product_one_triggers_unless_g_is_one():
    """X x = 1 exactly: a trigger needs g < 1, i.e. the raw draw below 1 (P = Phi(1/(2 sigma)))."""
    model = hb_model("leadership.x=2", "leadership.sigma=0.4")
    fp, ip = pack(model, DT)
    k = np.array([2.5, 0.0, 0.0])  # |k| / e = 0.5 exactly
    v = np.array([-3.0, 0.0, 0.0])
    clock = np.full(1, np.inf)
    hits = sum(decide(0, s, *k, 2, *v, clock, fp, ip, np.uint64(KEY))[0] for s in range(N_DRAWS))
    expected = norm.cdf(0.5 / 0.4)
    assert abs(hits / N_DRAWS - expected) <= 4 * math.sqrt(expected * (1 - expected) / N_DRAWS)


@pytest.mark.parametrize("clock_value, m, what", [
    (0.0, 3, "leader at the start of its escape"),
    (2.99, 3, "leader at the end of its escape"),
    (3.3, 3, "refractory"),
    (np.inf, 0, "no neighbours"),
])
def test_cannot_trigger(clock_value, m, what):
    model = hb_model("leadership.x=100", "leadership.front_gate=none", "leadership.refractory=0.5")
    fp, ip = pack(model, DT)
    k, v = boid_geometry(0.6, 0.5, 3.0, model.perception.radius)
    clock = np.full(2, clock_value)
    fired = [decide(1, s, *k, m, *v, clock, fp, ip, np.uint64(KEY))[0] for s in range(2000)]
    assert not any(fired), what
    clock[:] = 3.5  # after escape + refractory: X = 100 fires every time
    assert all(decide(1, s, *k, max(m, 1), *v, clock, fp, ip, np.uint64(KEY))[0] for s in range(2000))


# --------------------------------------------------------------------------------------------------
# 4. no re-trigger during the escape (+ refractory); leader records

def min_gap_steps(seconds: float, dt: float) -> int:
    """Steps that span ``seconds`` (to rounding): ceil(seconds / dt) with a 1e-9 tolerance."""
    return math.ceil(seconds / dt - 1e-9)


@pytest.mark.parametrize("duration, refractory", [(3.0, 0.0), (1.0, 0.0), (1.0, 0.5)])
def test_no_retrigger_during_escape_and_leader_records(duration, refractory):
    preset = hb_preset("leadership.x=50", "leadership.front_gate=none", f"leadership.duration={duration}",
                       f"leadership.refractory={refractory}")
    dt = preset.run.dt
    n = 40
    obs = simulate(preset.model, replace(preset.init, n=n), 3, 20.0, dt, record_every=1)
    steps, boids = obs.triggers[:, 0], obs.triggers[:, 1]
    order = np.lexsort((boids, steps))
    assert np.array_equal(order, np.arange(len(steps))), "triggers not in (step, boid) order"

    blocked = min_gap_steps(duration + refractory, dt)
    gaps = []
    for b in range(n):
        gaps += np.diff(steps[boids == b]).tolist()
    assert len(gaps) > n, "too few re-triggers to test"
    assert min(gaps) >= blocked, f"re-trigger after {min(gaps)} steps; blocked for {blocked}"
    # with X = 50 and no gate a boid re-triggers as soon as it may (up to one step of clock rounding)
    assert min(gaps) <= blocked + 1

    # leader at record r  <=>  its last trigger t < r was less than `duration` seconds before, i.e. within
    # round(duration / dt) steps (records are taken before the step's triggers)
    leader = obs.leader
    assert leader.shape == (obs.pos.shape[0], n)
    escape_steps = round(duration / dt)
    for b in range(n):
        own = steps[boids == b]
        for r in range(leader.shape[0]):
            before = own[own < r]
            if len(before) == 0:
                assert not leader[r, b], f"boid {b} leads at record {r} without a trigger"
                continue
            assert leader[r, b] == (r - before[-1] < escape_steps), f"boid {b}, record {r}"
    assert leader.any() and not leader.all()


def test_escape_lasts_duration_over_dt_steps():
    lengths = {}
    for duration, dt in [(3.0, 1 / 30), (1.5, 1 / 30), (1.0, 1 / 30), (3.0, 0.05), (1.0, 1 / 60)]:
        model = hb_model("leadership.x=1", f"leadership.duration={duration}")
        state = lone_state(speed=1.0, n_far=0)
        state.clock[0] = 0.0
        obs = advance(model, state, round(duration / dt) + 5, dt, record_every=1, key=KEY)
        lengths[(duration, dt)] = (int(obs.leader[:, 0].sum()), round(duration / dt))
    assert all(got == want for got, want in lengths.values()), f"(leader steps, T/dt): {lengths}"


# --------------------------------------------------------------------------------------------------
# 5. the escape profile and the speed a lone leader gains

def test_profile_samples_interpolation_and_support():
    samples = np.array(MODEL_PROFILE)
    grid = np.arange(30) / 29
    np.testing.assert_allclose([profile(u) for u in grid[:-1]], samples[:-1], rtol=0, atol=1e-14)
    assert profile(1.0) == 0.0 and samples[-1] == 0.0
    assert profile(10 / 29) == pytest.approx(1.0, abs=1e-14) and samples.max() == 1.0
    rng = np.random.default_rng(0)
    u = np.concatenate([rng.random(2000), (np.arange(29) + 0.5) / 29])
    np.testing.assert_allclose([profile(x) for x in u], np.interp(u, grid, samples), rtol=0, atol=1e-14)
    fine = np.linspace(0.0, 1.0, 20001)[:-1]
    values = np.array([profile(x) for x in fine])
    assert values.max() <= 1.0 and values.min() >= 0.0
    for outside in (-1e-12, -0.5, 1.0, 1.0 + 1e-12, 2.0, np.inf):
        assert profile(outside) == 0.0
    np.testing.assert_allclose([ref_hb.profile(x) for x in u], np.interp(u, grid, samples), rtol=0, atol=1e-14)


def test_profile_integral_is_the_trapezoid_sum():
    samples = np.array(MODEL_PROFILE)
    trapezoid = (samples.sum() - 0.5 * (samples[0] + samples[-1])) / 29
    knots = list(np.arange(1, 29) / 29)
    value, err = integrate.quad(profile, 0.0, 1.0, points=knots, limit=200, epsabs=1e-13, epsrel=1e-13)
    assert value == pytest.approx(trapezoid, abs=1e-11)


def lone_state(speed, n_far=2, direction=(0.6, -0.48, 0.64)):
    """Boid 0 at the origin heading along ``direction``; ``n_far`` others each 1000 units away from
    everyone (no one perceives anyone)."""
    pos = [[0.0, 0.0, 0.0]] + [[1000.0 * (j + 1), -1000.0 * j, 0.0] for j in range(n_far)]
    heading = np.array(direction) / np.linalg.norm(direction)
    fwd = [heading] + [[0.0, 0.0, 1.0]] * n_far
    speeds = [speed] + [2.0] * n_far
    return state_from(pos, fwd, speeds)


def predicted_speeds(model, v0, n_steps, dt, clock0=0.0):
    """|v| after each step of a lone leader: v' = min(|v| + gain b max(|v|, slow), max_speed (1 + boost b))."""
    lead, max_speed = model.leadership, model.vehicle.max_speed
    slow = ref_hb.slow_speed_of(model)
    clock, speed = clock0, v0
    speeds, caps = [v0], []
    for _ in range(n_steps):
        b = ref_hb.profile(clock / lead.duration)
        cap = max_speed * (1.0 + lead.boost * b)
        speed = min(speed + lead.gain * b * max(speed, slow), cap)
        speeds.append(speed)
        caps.append(cap)
        clock += dt
    return np.array(speeds), np.array(caps)


@pytest.mark.parametrize("gain, v0, escape_dir", [
    (0.2, 1.0, None),                 # preset gain: the raised cap binds at the peak
    (0.01, 1.0, None),                # small gain: the cap never binds, speed = v0 + sum of the increments
    (0.05, 0.1, None),                # slower than slow_speed: increments gain b slow_speed at first
    (0.2, 0.0, (0.0, 0.0, -1.0)),     # stopped, with a fixed (slow) escape direction
])
def test_lone_leader_gains_the_predicted_speed(gain, v0, escape_dir):
    model = hb_model("leadership.x=1", f"leadership.gain={gain}", "gains.separation=0", "gains.cohesion=0",
                     "gains.alignment=0")
    lead, max_speed = model.leadership, model.vehicle.max_speed
    state = lone_state(v0)
    state.clock[0] = 0.0
    if escape_dir is not None:
        state.escape[0] = escape_dir
    n_escape = min_gap_steps(lead.duration, DT)
    n_steps = n_escape + 10
    obs = advance(model, state, n_steps, DT, record_every=1, key=KEY)

    assert obs.triggers.shape == (0, 2) and not obs.visible.any()
    speeds = np.linalg.norm(obs.vel[:, 0], axis=1)
    expected, caps = predicted_speeds(model, v0, n_steps, DT)
    np.testing.assert_allclose(speeds, expected, rtol=1e-12, atol=1e-12)
    assert np.all(speeds[1:] <= caps * (1 + 1e-12)), "speed above the leader's cap"

    direction = np.array(escape_dir) if escape_dir is not None else state.fwd[0]
    np.testing.assert_allclose(obs.vel[1:, 0] / speeds[1:, None], np.broadcast_to(direction, (n_steps, 3)),
                               rtol=0, atol=1e-12)
    # p' = p + dt v with the old velocity
    np.testing.assert_allclose(obs.pos[1:, 0], np.cumsum(obs.vel[:-1, 0] * DT, axis=0), rtol=1e-12, atol=1e-12)
    # leader for the escape, then a follower at max_speed again
    assert obs.leader[0, 0] and not obs.leader[-1, 0]
    assert speeds[-1] <= max_speed * (1 + 1e-12)
    # the other boids are untouched by leadership: constant velocity
    np.testing.assert_array_equal(obs.vel[:, 1:], np.broadcast_to(state.vel[1:], obs.vel[:, 1:].shape))

    if gain == 0.2 and v0 > 0:
        assert np.any(np.isclose(expected[1:], caps, rtol=1e-12)), "the raised cap never bound"
        assert speeds.max() > max_speed * 1.5
    elif gain == 0.01:
        # the cap never bound: the gained speed is the plain sum of the increments
        b = np.array([ref_hb.profile(k * DT / lead.duration) for k in range(n_steps)])
        increments = gain * b * np.maximum(expected[:-1], ref_hb.slow_speed_of(model))
        assert np.all(expected[1:] < caps)
        assert speeds[-1] - v0 == pytest.approx(increments.sum(), rel=1e-10)


# --------------------------------------------------------------------------------------------------
# 6. events grow with X

def test_events_increase_with_x():
    preset = hb_preset()
    init = replace(preset.init, n=50)
    means = []
    for x in (0.0, 0.25, 1.0, 3.0):
        model = replace(preset.model, leadership=replace(preset.model.leadership, x=x))
        counts = [len(simulate(model, init, seed, 10.0, preset.run.dt, record_every=30).triggers)
                  for seed in (1, 2, 3)]
        means.append(np.mean(counts))
    assert means[0] == 0
    assert all(a < b for a, b in zip(means, means[1:])), f"mean triggers {means}"


# --------------------------------------------------------------------------------------------------
# 7. batches and determinism with leadership

@pytest.mark.parametrize("overrides", [("leadership.x=2",),
                                       ("leadership.x=2", "world.update_order=sequential",
                                        "leadership.front_gate=weighted")], ids=["sync", "seq-weighted"])
def test_batch_equals_separate_runs_with_leadership(overrides):
    preset = hb_preset(*overrides)
    init = replace(preset.init, n=30)
    seeds = [4, 5, 6, 7]
    batch = simulate_batch(preset.model, init, seeds, 4.0, preset.run.dt, record_every=5)
    for seed, got in zip(seeds, batch):
        alone = simulate(preset.model, init, seed, 4.0, preset.run.dt, record_every=5)
        assert_same_observations(got, alone)
        assert len(got.triggers) > 0


def test_same_seed_same_triggers_different_seeds_differ():
    preset = hb_preset("leadership.x=2")
    init = replace(preset.init, n=30)
    first = simulate(preset.model, init, 8, 4.0, preset.run.dt)
    again = simulate(preset.model, init, 8, 4.0, preset.run.dt)
    other = simulate(preset.model, init, 9, 4.0, preset.run.dt)
    assert_same_observations(first, again)
    assert len(first.triggers) > 0
    assert not np.array_equal(first.pos, other.pos)
    assert first.triggers.tolist() != other.triggers.tolist()
