"""Intrinsic noise and cruise speed (docs/model.md section 3.5, simcore.noise).

The draws and the drive against their numpy twin (tests/reference_noise.py); the von Mises-Fisher turn's
mean cosine coth(kappa) - 1/kappa; the analytic cases in whole runs of non-interacting boids (every rule's
weight 0): the polarization decays as (coth(kappa) - 1/kappa)^k after k steps, the speed relaxes to v0 as
e^(-t/tau), the stationary speed under speed noise is normal with sd sigma sqrt(tau/2) and without cruise
the speed is a random walk of variance sigma^2 t; determinism across batches, threads and processes.
Statistical checks use fixed seeds and allow Z = 5 standard errors (stated per test), so each passes or
fails the same way every time.
"""
from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from scipy import stats

import reference_noise as twin
from conftest import state_from
from paths import ROOT
from flocksweep.simcore import advance, load_preset, simulate, simulate_batch
from flocksweep.simcore.layout import F, I, pack
from flocksweep.simcore.noise import drive, store_draws, turn_in_plane, vmf_turn
from flocksweep.simcore.rng import run_streams
from flocksweep.simcore.schema import ConfigError

Z = 5.0
DT = 1 / 60
KEY = int(run_streams(11)[1])
MODELS = ROOT / "configs" / "models"


@numba.njit(cache=True)
def _turns(d, u, kappa):
    out = np.empty((u.shape[0], 3))
    for k in range(u.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = vmf_turn(d[k, 0], d[k, 1], d[k, 2], u[k, 0], u[k, 1], kappa)
    return out


@numba.njit(cache=True)
def _draws(key, step, n):
    row = np.zeros((n, 4))
    for i in range(n):
        store_draws(row, i, 1, key, step)
    return row


@numba.njit(cache=True)
def _drive(v, f, u, fp):
    return drive(v[0], v[1], v[2], f[0], f[1], f[2], u[0], u[1], u[2], fp)


def unit(rng, n):
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# --- the draws and the drive against the numpy twin ------------------------------------------------------

@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_draws_are_the_twins_counter_based_values():
    row = _draws(np.uint64(KEY), 17, 40)
    assert np.all(row[:, 0] == 0.0)
    for i in (0, 1, 7, 39):
        assert tuple(row[i, 1:]) == pytest.approx(twin.draws(KEY, 17, i), abs=0, rel=1e-15)
    assert not np.array_equal(row, _draws(np.uint64(KEY), 18, 40))


@pytest.mark.parametrize("kappa", [1e-3, 0.7, 20.0, 5e4])
def test_vmf_turn_matches_the_twin(kappa):
    rng = np.random.default_rng(3)
    d, u = unit(rng, 300), rng.random((300, 2))
    d[0] = (0, 0, 1.0)
    d[1] = (0, 0, -1.0)   # both branches of the basis, at its poles
    out = _turns(d, u, kappa)
    expected = np.array([twin.vmf_turn(d[k], u[k, 0], u[k, 1], kappa) for k in range(len(d))])
    assert np.allclose(out, expected, rtol=0, atol=1e-10)
    assert np.allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize("kappa", [0.5, 4.0, 300.0])
def test_vmf_mean_cosine_and_uniform_azimuth(kappa):
    """200 000 turns of random headings: E[w] = coth(kappa) - 1/kappa within 5 standard errors, and the
    mean turned heading has no component across d (within 5 standard errors of sd(sin)/sqrt(n))."""
    n = 200_000
    rng = np.random.default_rng(5)
    d = unit(rng, n)
    out = _turns(d, rng.random((n, 2)), kappa)
    w = np.einsum("ij,ij->i", out, d)
    assert abs(w.mean() - twin.mean_cosine(kappa)) < Z * w.std() / math.sqrt(n)
    across = out - w[:, None] * d
    # project on a fixed direction perpendicular to each d: the first basis vector of the twin's choice
    e = np.cross(d, [0.0, 0.0, 1.0])
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    c = np.einsum("ij,ij->i", across, e)
    assert abs(c.mean()) < Z * c.std() / math.sqrt(n) + 1e-12


def test_turn_in_plane_is_a_rotation_by_sd_z():
    fx, fy = turn_in_plane(1.0, 0.0, 0.5, 0.2)
    assert (fx, fy) == pytest.approx((math.cos(0.1), math.sin(0.1)), abs=1e-15)
    fx, fy = turn_in_plane(0.6, 0.8, -3.0, 2.0)   # a wrapped angle of -6 rad turns as -6 + 2 pi
    assert fx * fx + fy * fy == pytest.approx(1.0, abs=1e-15)
    assert math.atan2(fy, fx) == pytest.approx(math.atan2(0.8, 0.6) - 6.0 + 2 * math.pi, abs=1e-12)


@pytest.mark.parametrize("keys", [
    {"noise.kappa": 30.0},
    {"noise.angular_sd_deg": 20.0, "noise.speed_sd": 0.5},
    {"cruise.speed": 4.0, "cruise.tau": 0.3, "noise.speed_sd": 1.5, "noise.kappa": 2.0},
    {"cruise.speed": 4.0},
])
def test_drive_matches_the_twin(keys):
    model = load_preset(MODELS / "opensteer.toml").replace(keys).model
    fp, ip = pack(model, DT)
    assert ip[I.DRIVE] == 1
    rng = np.random.default_rng(8)
    for _ in range(50):
        v, f, u = rng.standard_normal(3) * 3, unit(rng, 1)[0], (*rng.random(2), rng.standard_normal())
        v0 = model.cruise.speed
        expected = twin.drive(v, f, *u, fp[F.NOISE_KAPPA], fp[F.SPEED_KICK], v0, fp[F.CRUISE_DECAY])
        assert np.allclose(_drive(v, f, np.array(u), fp), expected, rtol=1e-12, atol=1e-12)
    stopped = twin.drive(np.zeros(3), [0.0, 1.0, 0.0], 0.5, 0.5, 0.0, fp[F.NOISE_KAPPA], fp[F.SPEED_KICK],
                         model.cruise.speed, fp[F.CRUISE_DECAY])   # a stopped boid turns about its heading f
    assert np.allclose(_drive(np.zeros(3), np.array([0.0, 1.0, 0.0]), np.array([0.5, 0.5, 0.0]), fp), stopped,
                       rtol=1e-12, atol=1e-12)


def test_packed_constants():
    base = load_preset(MODELS / "opensteer.toml")
    fp, ip = pack(base.model, DT)
    assert ip[I.DRIVE] == 0 and fp[F.NOISE_KAPPA] == 0.0 and fp[F.SPEED_KICK] == 0.0 and fp[F.CRUISE_DECAY] == 1.0
    fp, _ = pack(base.replace({"noise.angular_sd_deg": 10.0}).model, 0.02)
    assert fp[F.NOISE_KAPPA] == pytest.approx(1.0 / (math.radians(10.0) ** 2 * 0.02), rel=1e-14)
    fp, _ = pack(base.replace({"noise.speed_sd": 2.0}).model, 0.04)
    assert fp[F.SPEED_KICK] == pytest.approx(2.0 * 0.2, rel=1e-14)
    fp, _ = pack(base.replace({"noise.speed_sd": 2.0, "cruise.speed": 3.0, "cruise.tau": 0.5}).model, 0.04)
    assert fp[F.CRUISE_DECAY] == pytest.approx(math.exp(-0.08), rel=1e-14)
    assert fp[F.SPEED_KICK] == pytest.approx(2.0 * math.sqrt(0.25 * (1 - math.exp(-0.16))), rel=1e-13)


@pytest.mark.parametrize("changes, key", [
    ({"noise.kappa": 0.0}, "noise.kappa"),
    ({"noise.kappa": 3.0, "noise.angular_sd_deg": 4.0}, "noise.angular_sd_deg"),
    ({"noise.speed_sd": -1.0}, "noise.speed_sd"),
    ({"cruise.speed": -2.0}, "cruise.speed"),
    ({"cruise.tau": 0.0}, "cruise.tau"),
    ({"noise.kapa": 3.0}, "noise.kapa"),
])
def test_bad_values_name_their_key(changes, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_preset(MODELS / "opensteer.toml").replace(changes)


def test_off_leaves_the_run_identity_alone():
    preset = load_preset(MODELS / "holland.toml")
    assert "noise" not in preset.to_dict() and "cruise" not in preset.to_dict()
    on = preset.replace({"noise.kappa": 5.0, "cruise.speed": 3.0}).to_dict()
    assert on["noise"]["kappa"] == 5.0 and on["cruise"]["speed"] == 3.0


# --- analytic cases in whole runs ------------------------------------------------------------------------

# non-interacting boids: every rule's weight (or gain) 0, under each dynamics' preset perception
FREE = {
    "opensteer": ("opensteer.toml", {"steering.separation_weight": 0.0, "steering.alignment_weight": 0.0,
                                     "steering.cohesion_weight": 0.0, "vehicle.max_speed": 100.0,
                                     "world.boundary": "open"}),
    "hartman_benes": ("hartman_benes.toml", {"gains.separation": 0.0, "gains.cohesion": 0.0,
                                             "gains.alignment": 0.0, "vehicle.max_speed": 100.0,
                                             "world.boundary": "open"}),
    "reynolds87": ("reynolds87.toml", {"reynolds.separation_weight": 0.0, "reynolds.alignment_weight": 0.0,
                                       "reynolds.cohesion_weight": 0.0, "reynolds.migration_weight": 0.0,
                                       "reynolds.min_speed": 0.0, "reynolds.max_speed": 100.0}),
}


def free_model(dynamics, changes):
    name, free = FREE[dynamics]
    return load_preset(MODELS / name).replace({**free, **changes, "perception.search": "all_pairs"}).model


def aligned(n, speed, spacing=1000.0):
    """n boids on a line far apart (no one perceives another), all heading along +x at ``speed``."""
    pos = np.zeros((n, 3))
    pos[:, 1] = spacing * np.arange(n)
    return state_from(pos, np.tile([1.0, 0.0, 0.0], (n, 1)), speed)


@pytest.mark.slow
@pytest.mark.parametrize("dynamics", list(FREE))
def test_speed_relaxes_to_v0_with_time_constant_tau(dynamics):
    """No noise: s(k dt) = v0 + (s0 - v0) e^(-k dt / tau) to 1e-12, from above and below."""
    tau, v0 = 0.4, 5.0
    model = free_model(dynamics, {"cruise.speed": v0, "cruise.tau": tau})
    state = aligned(2, 1.0)
    state.vel[1] *= 9.0
    dt = 1 / 30 if dynamics == "hartman_benes" else DT
    obs = advance(model, state, 60, dt)
    speed = np.linalg.norm(obs.vel, axis=2)
    t = obs.times[:, None]
    expected = v0 + (np.array([1.0, 9.0]) - v0) * np.exp(-t / tau)
    assert np.allclose(speed, expected, rtol=1e-12, atol=0)
    assert np.allclose(obs.vel[-1, :, 1:], 0.0)    # along the heading only


@pytest.mark.slow
@pytest.mark.parametrize("dynamics", ["opensteer", "hartman_benes"])
def test_polarization_decays_as_mean_cosine_per_step(dynamics):
    """2 000 free boids from one heading: after k steps the mean of f . x is A^k, A = coth(kappa) - 1/kappa,
    within 5 standard errors; the polarization |mean f| with it (its finite-n bias is < 1/sqrt(n))."""
    n, kappa = 2000, 40.0
    model = free_model(dynamics, {"noise.kappa": kappa})
    dt = 1 / 30 if dynamics == "hartman_benes" else DT
    obs = advance(model, aligned(n, 2.0), 90, dt, record_every=30, key=KEY)
    a = twin.mean_cosine(kappa)
    for r, k in enumerate((0, 30, 60, 90)):
        heading = obs.vel[r] / np.linalg.norm(obs.vel[r], axis=1, keepdims=True)
        cos = heading[:, 0]
        assert abs(cos.mean() - a ** k) <= Z * cos.std() / math.sqrt(n) + 1e-12, k
        assert abs(np.linalg.norm(heading.mean(axis=0)) - a ** k) < 0.03
    assert np.allclose(np.linalg.norm(obs.vel, axis=2), 2.0, rtol=1e-12)   # the turn keeps the speed


@pytest.mark.slow
def test_stationary_speed_under_noise_is_normal_with_sd_sigma_sqrt_tau_over_2():
    """Ornstein-Uhlenbeck: 2 000 free boids from v0, after 10 tau the speed is N(v0, sigma^2 tau / 2):
    mean within 5 standard errors, sd within 5 standard errors of an sd (sd / sqrt(2 n)), and a KS test
    against that normal at p > 1e-4 (fixed seed: deterministic)."""
    n, v0, tau, sigma = 2000, 5.0, 0.5, 2.0
    model = free_model("opensteer", {"cruise.speed": v0, "cruise.tau": tau, "noise.speed_sd": sigma})
    obs = advance(model, aligned(n, v0), 300, DT, record_every=300, key=KEY)
    speed = np.linalg.norm(obs.vel[-1], axis=1)
    sd = sigma * math.sqrt(tau / 2)
    assert abs(speed.mean() - v0) < Z * sd / math.sqrt(n)
    assert abs(speed.std() - sd) < Z * sd / math.sqrt(2 * n)
    assert stats.kstest(speed, "norm", args=(v0, sd)).pvalue > 1e-4
    assert np.allclose(obs.vel[-1, :, 1:], 0.0)   # no angular noise: the headings stay


@pytest.mark.slow
def test_speed_without_cruise_is_a_random_walk():
    """No cruise: after t the speed's variance is sigma^2 t (start 20, sd 1.4: never near the 0 floor)."""
    n, sigma, steps = 2000, 1.0, 120
    model = free_model("opensteer", {"noise.speed_sd": sigma})
    obs = advance(model, aligned(n, 20.0), steps, DT, record_every=steps, key=KEY)
    speed = np.linalg.norm(obs.vel[-1], axis=1)
    sd = sigma * math.sqrt(steps * DT)
    assert abs(speed.mean() - 20.0) < Z * sd / math.sqrt(n)
    assert abs(speed.std() - sd) < Z * sd / math.sqrt(2 * n)


# --- determinism -----------------------------------------------------------------------------------------

NOISY = {"noise.kappa": 50.0, "noise.speed_sd": 0.5, "cruise.speed": 4.0, "cruise.tau": 0.5}


def same(a, b):
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("pos", "vel", "visible")) and \
        np.array_equal(a.final.fwd, b.final.fwd)


@pytest.mark.slow
@pytest.mark.parametrize("preset", ["opensteer.toml", "hartman_benes.toml", "reynolds87.toml", "boidspp.toml"])
def test_noisy_runs_are_deterministic_across_batches_and_threads(preset):
    p = load_preset(MODELS / preset, ["init.n=30", "run.duration=2"]).replace(NOISY)
    m, i, r = p.model, p.init, p.run
    alone = simulate(m, i, 7, r.duration, r.dt, 6)
    batch = simulate_batch(m, i, [3, 7, 9], r.duration, r.dt, 6)
    assert same(alone, batch[1])
    assert same(alone, simulate(m, i, 7, r.duration, r.dt, 6, threads=2))
    quiet = simulate(p.replace({"noise": {}}).model, i, 7, r.duration, r.dt, 6)
    assert not np.array_equal(alone.pos, quiet.pos)   # the noise acts
    assert not same(batch[0], batch[2])
