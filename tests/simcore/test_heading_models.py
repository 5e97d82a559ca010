"""The constant-speed heading models ``couzin2002`` and ``vicsek``, in 2-D and 3-D: kernels against the
numpy twins (tests/reference_headings.py) step by step, the noise laws, determinism (repeat, batch vs
alone, thread counts) and their configuration.

Step by step: a random state is advanced K single steps by the kernel and by the twin from the same input
state (key 5, step 0: ``advance`` counts steps from 0); both continue from the kernel's state, so rounding
cannot accumulate. Every state array agrees to 1e-12 and the perceived counts exactly. Each case checks
that it exercised what it claims (repulsion, both zones, the turn limit, the blind cone, the box).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

import reference_headings as ref
from conftest import state_from, unit_vectors
from paths import ROOT
from flocksweep.simcore import InitParams, advance, simulate, simulate_batch
from flocksweep.simcore.couzin_params import Couzin
from flocksweep.simcore.params import ModelParams, Perception, World, model_dict
from flocksweep.simcore.schema import ConfigError
from flocksweep.simcore.state import State
from flocksweep.simcore.vicsek_params import Vicsek

FIELDS = ref.STATE_KEYS
N_STEPS = 5
KEY = 5


def couzin_model(dimensions=3, boundary="open", box_size=7.0, search="auto", order="synchronous", **keys):
    return ModelParams(name="c", dynamics="couzin2002", perception=Perception(kind="sphere", search=search),
                       world=World(boundary=boundary, box_size=box_size, dimensions=dimensions, update_order=order),
                       couzin=Couzin(**keys))


def vicsek_model(dimensions=2, box_size=5.0, search="auto", **keys):
    return ModelParams(name="v", dynamics="vicsek", perception=Perception(kind="sphere", search=search),
                       world=World(boundary="periodic_box", box_size=box_size, dimensions=dimensions),
                       vicsek=Vicsek(**keys))


def random_state(seed, n, dimensions, radius=3.0, box=None, speed=1.0):
    """Uniform in a ball (disc in 2-D) or in the periodic box, random headings (in the plane in 2-D)."""
    rng = np.random.default_rng(seed)
    if box is None:
        pos = unit_vectors(rng, n) * (radius * rng.random(n) ** (1.0 / 3.0))[:, None]
    else:
        pos = rng.uniform(-box / 2, box / 2, (n, 3))
    fwd = unit_vectors(rng, n)
    if dimensions == 2:
        pos[:, 2] = 0.0
        fwd[:, 2] = 0.0
        fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
        s = state_from(pos, fwd, speed)
        return State(pos=s.pos, vel=s.vel, fwd=s.fwd, up=np.tile([0.0, 0.0, 1.0], (n, 1)),
                     side=np.stack([fwd[:, 1], -fwd[:, 0], np.zeros(n)], axis=1), acc=s.acc, pattern=s.pattern)
    return state_from(pos, fwd, speed)


def run_steps(model, state, twin_step, dt):
    states = []
    for _ in range(N_STEPS):
        twin = twin_step(state, model, dt, KEY, 0)
        obs = advance(model, state, 1, dt, key=KEY)
        for name in FIELDS:
            np.testing.assert_allclose(getattr(obs.final, name), twin[name], rtol=1e-12, atol=1e-12, err_msg=name)
        states.append(state)
        state = obs.final
    return states


def zone_counts(model, state):
    """Per boid: (repulsion, orientation, attraction, blind) neighbour counts (the twin's zones)."""
    c, out = model.couzin, []
    for i in range(state.n):
        counts = [0, 0, 0, 0]
        for j, d in ref.neighbours(i, state.pos, c.outer_radius, ref.box_of(model)):
            dist = np.linalg.norm(d)
            if float(state.fwd[i] @ d) < -math.cos(math.radians(c.blind_deg / 2)) * dist:
                counts[3] += 1
            else:
                counts[0 if dist < c.repulsion_radius else 1 if dist < c.repulsion_radius + c.orientation_width
                       else 2] += 1
        out.append(counts)
    return np.array(out)


COUZIN_CASES = [
    ("3d-open", dict(), 1),
    ("3d-open-grid", dict(search="grid", blind_deg=120.0), 2),
    ("3d-box", dict(boundary="periodic_box", box_size=8.0), 3),
    ("2d-open", dict(dimensions=2), 4),
    ("2d-box-grid", dict(dimensions=2, boundary="periodic_box", box_size=12.0, search="grid"), 5),
]


@pytest.mark.parametrize("keys, seed", [c[1:] for c in COUZIN_CASES], ids=[c[0] for c in COUZIN_CASES])
def test_couzin_kernel_matches_twin(keys, seed):
    dims = keys.get("dimensions", 3)
    zones = dict(repulsion_radius=0.8, orientation_width=1.0, attraction_width=2.0, turning_rate_deg=400.0,
                 noise_sd=0.3, speed=2.0)
    model = couzin_model(**keys, **{k: v for k, v in zones.items() if k not in keys})
    box = keys.get("box_size") if keys.get("boundary") == "periodic_box" else None
    n = 60 if dims == 3 else 30
    state = random_state(seed, n, dims, radius=3.0 if dims == 3 else 2.5, box=box)
    states = run_steps(model, state, ref.couzin_step, 0.1)
    counts = np.concatenate([zone_counts(model, s) for s in states])
    assert (counts[:, 0] > 0).sum() >= 10                                    # repulsion decided
    assert ((counts[:, 0] == 0) & (counts[:, 1] > 0) & (counts[:, 2] > 0)).sum() >= 10  # both zones averaged
    assert counts[:, 3].sum() >= 10                                          # the blind cone hid some
    turns = np.concatenate([np.arccos(np.clip(np.sum(a.fwd * b.fwd, axis=1), -1, 1))
                            for a, b in zip(states[:-1], states[1:])])
    limit = math.radians(400.0) * 0.1
    assert np.isclose(turns, limit, atol=1e-9).sum() >= 5 and (turns < limit - 1e-3).sum() >= 3
    if dims == 2:
        assert all(np.all(s.pos[:, 2] == 0.0) and np.all(s.fwd[:, 2] == 0.0) for s in states)


VICSEK_CASES = [
    ("2d", dict(dimensions=2), 1),
    ("2d-grid", dict(dimensions=2, search="grid", box_size=6.0), 2),
    ("3d", dict(dimensions=3, box_size=3.5), 3),
    ("3d-grid-noiseless", dict(dimensions=3, box_size=4.0, search="grid", noise=0.0), 4),
]


@pytest.mark.parametrize("keys, seed", [c[1:] for c in VICSEK_CASES], ids=[c[0] for c in VICSEK_CASES])
def test_vicsek_kernel_matches_twin(keys, seed):
    keys = {"noise": 1.5, "speed": 0.3, **keys}
    model = vicsek_model(**keys)
    box, dims = model.world.box_size, model.world.dimensions
    state = random_state(seed, 40, dims, box=box, speed=0.3)
    states = run_steps(model, state, ref.vicsek_step, 1.0)
    crossed = sum(np.any(np.abs(a.pos - b.pos) > box / 2) for a, b in zip(states[:-1], states[1:]))
    assert crossed >= 1                                                      # the box wrapped someone
    seen = [len(ref.neighbours(i, s.pos, 1.0, box)) for s in states for i in range(s.n)]
    assert max(seen) >= 2 and min(seen) == 0


# ----------------------------------------------------------------------------------- the noise laws
def lone_turns(model, dims, steps=4000):
    """Angles between successive headings of one boid alone (no neighbour: only the noise turns it)."""
    state = random_state(0, 1, dims, speed=model.couzin.speed if model.dynamics == "couzin2002" else 1.0)
    obs = advance(model, state, steps, 0.1 if model.dynamics == "couzin2002" else 1.0, key=9)
    f = obs.vel / np.linalg.norm(obs.vel, axis=2, keepdims=True)
    f = f[1:, 0]   # record 0 is the given state (its speed may differ)
    if dims == 2:
        angle = np.arctan2(f[:, 1], f[:, 0])
        return (np.diff(angle) + np.pi) % (2 * np.pi) - np.pi
    return np.arccos(np.clip(np.sum(f[:-1] * f[1:], axis=1), -1.0, 1.0))


def test_couzin_noise_is_a_wrapped_gaussian():
    """A lone boid turning freely: in 2-D the turn is N(0, sigma); in 3-D its size is Rayleigh(sigma) (the
    length of a 2-D Gaussian tangent step). KS tests on 4,000 steps (fixed key), p > 0.01."""
    sd = 0.2
    planar = lone_turns(couzin_model(dimensions=2, noise_sd=sd, turning_rate_deg=1e6), 2)
    assert stats.kstest(planar, stats.norm(scale=sd).cdf).pvalue > 0.01
    spatial = lone_turns(couzin_model(dimensions=3, noise_sd=sd, turning_rate_deg=1e6), 3)
    assert stats.kstest(spatial, stats.rayleigh(scale=sd).cdf).pvalue > 0.01
    assert stats.kstest(spatial, stats.rayleigh(scale=1.2 * sd).cdf).pvalue < 1e-6   # the test can tell


def test_vicsek_noise_is_uniform_on_the_arc_and_the_cap():
    """A lone boid: in 2-D the turn is uniform in [-eta/2, eta/2]; in 3-D the cosine of the turn is uniform
    in [1 - eta/pi, 1] (uniform on the cap of solid angle 2 eta). KS tests, p > 0.01."""
    eta = 2.0
    planar = lone_turns(vicsek_model(dimensions=2, noise=eta, box_size=50.0), 2)
    assert stats.kstest(planar, stats.uniform(loc=-eta / 2, scale=eta).cdf).pvalue > 0.01
    spatial = np.cos(lone_turns(vicsek_model(dimensions=3, noise=eta, box_size=50.0), 3))
    assert stats.kstest(spatial, stats.uniform(loc=1 - eta / math.pi, scale=eta / math.pi).cdf).pvalue > 0.01
    assert stats.kstest(spatial, stats.uniform(loc=1 - 1.1 * eta / math.pi, scale=1.1 * eta / math.pi).cdf
                        ).pvalue < 1e-6


# ----------------------------------------------------------------------------------- determinism
@pytest.mark.parametrize("dynamics, dims", [("couzin2002", 3), ("couzin2002", 2), ("vicsek", 2), ("vicsek", 3)])
def test_repeat_batch_and_threads_are_bit_identical(dynamics, dims):
    if dynamics == "couzin2002":
        model, init, dt = couzin_model(dimensions=dims), InitParams(n=40, radius=4.0, speed=3.0), 0.1
    else:
        model, init, dt = vicsek_model(dimensions=dims), InitParams(n=40, radius=2.5, region="cube"), 1.0
    alone = [simulate(model, init, seed, 20 * dt, dt, 4) for seed in (1, 2, 3)]
    batch = simulate_batch(model, init, [3, 1, 2], 20 * dt, dt, 4)
    threaded = simulate(model, init, 2, 20 * dt, dt, 4, threads=2)
    for x, y in [(alone[2], batch[0]), (alone[0], batch[1]), (alone[1], batch[2]), (alone[1], threaded)]:
        for name in ("pos", "vel", "visible"):
            np.testing.assert_array_equal(getattr(x, name), getattr(y, name))
    assert not np.array_equal(alone[0].pos, alone[1].pos)
    speed = np.linalg.norm(alone[0].vel[1:], axis=2)
    np.testing.assert_allclose(speed, model.couzin.speed if dynamics == "couzin2002" else model.vicsek.speed,
                               rtol=1e-12)
    if dims == 2:
        assert np.all(alone[0].pos[:, :, 2] == 0.0) and np.all(alone[0].vel[:, :, 2] == 0.0)


# ----------------------------------------------------------------------------------- configuration
@pytest.mark.parametrize("table, keys, key", [
    (Couzin, dict(repulsion_radius=0.0), "couzin.repulsion_radius"),
    (Couzin, dict(orientation_width=-1.0), "couzin.orientation_width"),
    (Couzin, dict(blind_deg=360.0), "couzin.blind_deg"),
    (Couzin, dict(turning_rate_deg=0.0), "couzin.turning_rate_deg"),
    (Couzin, dict(noise_sd=float("nan")), "couzin.noise_sd"),
    (Vicsek, dict(noise=7.0), "vicsek.noise"),
    (Vicsek, dict(radius=-1.0), "vicsek.radius"),
])
def test_bad_keys_are_named(table, keys, key):
    with pytest.raises(ConfigError) as err:
        table(**keys)
    assert err.value.key == key


def test_model_level_checks():
    ModelParams(world=World(dimensions=2))   # every built-in dynamics runs in 2-D (tests/simcore/test_planar.py)
    with pytest.raises(ConfigError, match="world.dimensions"):
        World(dimensions=4)
    with pytest.raises(ConfigError, match="perception.kind"):
        ModelParams(dynamics="vicsek")
    from flocksweep.simcore.params import Leadership
    with pytest.raises(ConfigError, match="leadership.x"):
        ModelParams(dynamics="couzin2002", perception=Perception(kind="sphere"), leadership=Leadership(x=0.5))
    with pytest.raises(ValueError, match="z = "):
        advance(couzin_model(dimensions=2), random_state(1, 5, 3), 1, 0.1)


def test_canonical_form_and_sphere():
    model = couzin_model(dimensions=2, orientation_width=3.0)
    canon = model_dict(model)
    assert canon["perception"] == {"kind": "sphere"} and canon["world"]["dimensions"] == 2
    assert canon["couzin"]["orientation_width"] == 3.0 and "vicsek" not in canon and "vehicle" not in canon
    assert model.sphere_radius == model.perception_range == 1.0 + 3.0 + 14.0
    assert "dimensions" not in model_dict(couzin_model())["world"]
    plain = model_dict(ModelParams())
    assert "couzin" not in plain and "vicsek" not in plain and "dimensions" not in plain["world"]
    assert vicsek_model(radius=1.5).sphere_radius == 1.5


@pytest.mark.parametrize("preset, key", [("vicsek.toml", "noise.kappa=10"), ("couzin2002_swarm.toml", "cruise.speed=3"),
                                         ("couzin2002_torus.toml", "noise.speed_sd=0.1")])
def test_the_shared_noise_and_cruise_are_refused_where_the_model_has_its_own(preset, key):
    from flocksweep.simcore import load_preset
    from flocksweep.simcore.schema import ConfigError

    with pytest.raises(ConfigError, match=key.split(".")[0]):
        load_preset(ROOT / "configs" / "models" / preset, [key])
