"""2-D motion (``world.dimensions = 2``) of opensteer, hartman_benes, reynolds87 and boidspp (docs/model.md
section 15).

* the kernels agree with their numpy twins (tests/reference*.py, whose moves zero a 2-D force's z and keep
  the planar frame) step by step from states in the plane, for every perception kind of opensteer
  (sphere, opensteer, binocular with occlusion, topological with a blind angle) and for the other dynamics;
  both continue from the kernel's state (as tests/simcore/test_kernel_vs_reference.py does in 3-D);
* z stays exactly 0 (positions, velocities, headings, side, acceleration; up = +z) over long runs with
  noise and cruise on, for every enabled dynamics x perception kind;
* the 2-D angular noise is a wrapped normal turn (its numpy twin; free boids' polarization decays as
  exp(-sd^2 t / 2), the mean cosine of a wrapped normal, not as the 3-D exp(-sd^2 t));
* runs are bit-identical alone, batched and threaded;
* a 2-D flock is not a 3-D one seen from above (its boids perceive more neighbours);
* what a 2-D run cannot have is refused, naming the key.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numba
import numpy as np
import pytest

import reference
import reference_boidspp as ref_bpp
import reference_hb as ref_hb
import reference_noise as ref_noise
import reference_reynolds as ref_rey
from conftest import flock_state
from paths import ROOT
from flocksweep.simcore import advance, load_preset, simulate, simulate_batch
from flocksweep.simcore.boidspp_params import BoidsPP
from flocksweep.simcore.layout import F, pack
from flocksweep.simcore.noise import drive
from flocksweep.simcore.obstacle_spec import Obstacle
from flocksweep.simcore.params import ModelParams, Patterns, Perception, World
from flocksweep.simcore.reynolds_params import Reynolds
from flocksweep.simcore.schema import ConfigError, build
from flocksweep.simcore.state import State, planar_frame

MODELS = ROOT / "configs" / "models"
FIELDS = ("pos", "vel", "fwd", "up", "side", "acc")
N_BOIDS = 32
N_STEPS = 6
DT = 1 / 60
KEY = 0x2D2D_0BAD_5EED_0001
TOL = 1e-12


def in_plane(state):
    """A flock state put in the plane z = 0: z dropped from positions, headings (renormalised, speeds kept)
    and accelerations, the planar frame (up = +z, side = f x up)."""
    pos, acc = state.pos.copy(), state.acc.copy()
    pos[:, 2] = acc[:, 2] = 0.0
    fwd = state.fwd.copy()
    fwd[:, 2] = 0.0
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    speed = np.linalg.norm(state.vel, axis=1, keepdims=True)
    up, side = planar_frame(fwd)
    return replace(state, pos=pos, vel=fwd * speed, fwd=fwd, up=up, side=side, acc=acc)


def planar_flock(seed, box=None):
    state = flock_state(seed, N_BOIDS, box_size=box) if box else flock_state(seed, N_BOIDS, ball_radius=4.0)
    return in_plane(state)


def assert_in_plane(state):
    for name in ("pos", "vel", "fwd", "side", "acc"):
        assert np.all(getattr(state, name)[:, 2] == 0.0), name
    assert np.all(state.up == [0.0, 0.0, 1.0])


def opensteer_model(kind, boundary="open", order="synchronous", patterns=None, **perception):
    return ModelParams(perception=Perception(kind=kind, **perception),
                       world=World(boundary=boundary, sphere_radius=4.0, box_size=7.0, update_order=order,
                                   dimensions=2),
                       patterns=Patterns() if patterns is None else Patterns(enabled=True,
                                                                             separation_weight=patterns))


# ------------------------------------------------------------------------------------------------------
# 1. kernel == numpy twin, step by step, in the plane

OPENSTEER_CASES = [
    ("sphere-open-sync", dict(kind="sphere", radius=3.5)),
    ("opensteer-box-seq", dict(kind="opensteer", boundary="periodic_box", order="sequential")),
    ("binocular-occl-default-sync", dict(kind="binocular")),
    ("binocular-occl-200-wrap-seq-similarity", dict(kind="binocular", direction_deg=45.0, field_deg=200.0,
                                                    range=6.0, boundary="sphere_wrap", order="sequential",
                                                    patterns="similarity")),
    ("binocular-noocc-90-sync", dict(kind="binocular", occlusion=False, direction_deg=30.0, field_deg=90.0,
                                     range=6.0)),
    ("topological-blind-seq-grid", dict(kind="topological", neighbours=5, blind_deg=90.0, order="sequential",
                                        search="grid", max_distance=5.0)),
]


@pytest.mark.parametrize("seed, kwargs", [pytest.param(seed, kw, id=name)
                                          for seed, (name, kw) in enumerate(OPENSTEER_CASES)])
def test_opensteer_kernel_matches_the_twin_in_the_plane(seed, kwargs):
    model = opensteer_model(**kwargs)
    box = model.world.box_size if model.world.boundary == "periodic_box" else None
    state = planar_flock(seed, box)   # with Holland's Table 1 patterns, used in pattern mode
    neighbours = hidden = 0
    for k in range(N_STEPS):
        obs, ref = reference.kernel_step_agrees(model, state, DT, k, TOL)
        assert_in_plane(obs.final)
        neighbours += int(ref["visible"].sum())
        if model.perception.kind == "binocular" and model.perception.occlusion:
            hidden += sum(len(reference.perceive(i, state.pos, state.fwd, state.side, model, box)["hidden"])
                          for i in range(N_BOIDS))
        state = obs.final
    assert neighbours / (N_STEPS * N_BOIDS) >= 3.0, "too few neighbours for a meaningful comparison"
    if model.perception.kind == "binocular" and model.perception.occlusion:
        assert hidden > 0, "occlusion never hid a boid in the plane"


def hb_model(*overrides):
    return load_preset(MODELS / "hartman_benes.toml", ["world.dimensions=2", *overrides]).model


@pytest.mark.parametrize("overrides", [(), ("world.update_order=sequential", "gains.separation_falloff_exponent=0"),
                                       ("leadership.x=3", "leadership.slow_speed=1.5"),
                                       ("world.boundary=periodic_box", "world.box_size=9.0",
                                        "perception.radius=4.0")],
                         ids=["preset", "seq-falloff0", "leadership", "box"])
def test_hartman_benes_kernel_matches_the_twin_in_the_plane(overrides):
    model = hb_model(*overrides)
    box = model.world.box_size if model.world.boundary == "periodic_box" else None
    state = planar_flock(3, box)
    triggers = 0
    for k in range(N_STEPS):
        obs = advance(model, state, 1, DT, key=KEY + k)
        ref = ref_hb.step(state, model, DT, step_index=0, key=KEY + k)
        for name in ref_hb.STATE_KEYS:
            np.testing.assert_allclose(getattr(obs.final, name), ref[name], rtol=TOL, atol=TOL,
                                       err_msg=f"step {k}: {name}")
        np.testing.assert_array_equal(obs.visible[0], ref["visible"])
        assert obs.triggers.tolist() == [list(t) for t in ref["triggers"]]
        assert_in_plane(obs.final)
        assert np.all(obs.final.escape[:, 2] == 0.0)
        triggers += len(ref["triggers"])
        state = obs.final
    if model.leadership.x > 0:
        assert triggers > 0, "no leadership trigger in the window"


def reynolds_model(**keys):
    world = dict(boundary="open", sphere_radius=4.0, box_size=7.0, update_order="synchronous", dimensions=2)
    world.update({k: keys.pop(k) for k in list(keys) if k in ("boundary", "update_order")})
    return ModelParams(name="r", dynamics="reynolds87", perception=Perception(kind="sphere", radius=3.5),
                       world=World(**world), reynolds=Reynolds(**keys))


@pytest.mark.parametrize("keys", [dict(max_accel=12.0),
                                  dict(max_accel=4.0, allocation="priority_magnitude", update_order="sequential"),
                                  dict(max_accel=12.0, allocation="weighted_sum", boundary="periodic_box"),
                                  dict(max_accel=12.0, migration_weight=5.0, migration_direction=(1.0, 2.0, 0.0),
                                       migration_who="front")],
                         ids=["priority", "magnitude-seq", "weighted-box", "migration-front"])
def test_reynolds87_kernel_matches_the_twin_in_the_plane(keys):
    model = reynolds_model(**keys)
    box = model.world.box_size if model.world.boundary == "periodic_box" else None
    state = planar_flock(5, box)
    for k in range(N_STEPS):
        twin = ref_rey.step(state, model, DT)
        obs = advance(model, state, 1, DT)
        for name in FIELDS:
            np.testing.assert_allclose(getattr(obs.final, name), twin[name], rtol=TOL, atol=TOL,
                                       err_msg=f"step {k}: {name}")
        np.testing.assert_array_equal(obs.visible[0], twin["visible"])
        assert_in_plane(obs.final)
        state = obs.final


def boidspp_model(table, **world):
    return ModelParams(name="t", dynamics="boidspp", perception=Perception(kind="sphere", radius=3.5),
                       world=World(sphere_radius=4.0, box_size=7.0, dimensions=2, **world),
                       boidspp=build(BoidsPP, table, "boidspp"))


@pytest.mark.parametrize("table, world", [
    ({"random_force": {"every": 2, "magnitude": 3.0}, "min_speed": 0.5}, {"boundary": "sphere_wrap"}),
    ({"alignment": {"scope": "flock"}, "cohesion": {"scope": "flock", "blend": 0.2}}, {"update_order": "sequential"}),
    ({"predator": {"enabled": True, "start_s": 2 * DT, "start_distance": 1.0, "avoid_radius": 3.0,
                   "capture_radius": 2.0, "flee_blend": 0.7}}, {}),
    ({"predator": {"enabled": True, "start_distance": 0.5, "avoid_radius": 2.0},
      "prey": {"enabled": True, "target_radius": 2.0, "speed": 30.0, "arrive_radius": 0.4}},
     {"boundary": "periodic_box", "update_order": "sequential"}),
], ids=["random-force-wrap", "flock-seq", "predator", "predator-prey-box-seq"])
def test_boidspp_kernel_matches_the_twin_in_the_plane(table, world):
    model = boidspp_model(table, **world)
    state = planar_flock(11)
    got = advance(model, state, N_STEPS, DT, record_every=1, key=KEY)
    ref, agents, capture = ref_bpp.run(state, model, DT, N_STEPS, KEY)
    for name in ref_bpp.STATE_KEYS:
        np.testing.assert_allclose(getattr(got.final, name), ref[name], rtol=1e-9, atol=1e-9, err_msg=name)
    assert_in_plane(got.final)
    if model.boidspp.predator.enabled:
        np.testing.assert_allclose(got.predator[-1], agents.pred, rtol=1e-9, atol=1e-9)
        assert got.predator[-1, 2] == 0.0
    if model.boidspp.predator.capture_radius is not None:
        assert (capture >= 0).any(), "the predator should capture someone"
    if model.boidspp.prey.enabled:
        np.testing.assert_allclose(got.prey[-1], agents.prey, rtol=1e-9, atol=1e-9)
        assert got.prey[-1, 2] == 0.0 and agents.drawn > 2, "the prey should reach a target"


# ------------------------------------------------------------------------------------------------------
# 2. z stays exactly 0 over long runs, noise and cruise on

NOISY = {"noise.angular_sd_deg": 30.0, "noise.speed_sd": 0.5, "cruise.speed": 3.0, "cruise.tau": 0.5}
LONG_RUNS = [
    ("holland.toml", {}),
    ("holland.toml", {"perception.occlusion": False, "perception.direction_deg": 60.0}),
    ("opensteer.toml", {}),
    ("topological.toml", {}),
    ("hartman_benes.toml", {"leadership.x": 3.0}),
    ("reynolds87.toml", {}),
    ("boidspp.toml", {"boidspp.random_force.magnitude": 2.0}),
    ("boidspp_predator.toml", {}),
]


def preset_2d(name, changes, n=40, duration=30.0, noisy=True):
    """A shipped preset in 2-D (without its obstacles) with ``changes`` and, when ``noisy``, noise and cruise."""
    preset = load_preset(MODELS / name, ["world.dimensions=2", "world.obstacles=[]", f"init.n={n}",
                                         f"run.duration={duration}"])
    return preset.replace({**(NOISY if noisy else {}), **changes})


@pytest.mark.slow
@pytest.mark.parametrize("name, changes", LONG_RUNS,
                         ids=[f"{n[:-5]}-{i}" for i, (n, _) in enumerate(LONG_RUNS)])
def test_z_stays_exactly_zero_over_a_long_run(name, changes):
    preset = preset_2d(name, changes)
    obs = simulate(preset.model, preset.init, 4, preset.run.duration, preset.run.dt, preset.run.record_every)
    assert np.all(obs.pos[..., 2] == 0.0) and np.all(obs.vel[..., 2] == 0.0)
    assert_in_plane(obs.final)
    assert np.all(np.isfinite(obs.pos)) and np.ptp(obs.pos[..., 0]) > 0 and np.ptp(obs.pos[..., 1]) > 0
    for agent in (obs.predator, obs.prey):
        if agent is not None:
            assert np.all(agent[~np.isnan(agent[:, 0]), 2] == 0.0)


# ------------------------------------------------------------------------------------------------------
# 3. the 2-D angular noise

@numba.njit(cache=True)
def _drive(v, f, u, fp):
    return drive(v[0], v[1], v[2], f[0], f[1], f[2], u[0], u[1], u[2], fp)


@pytest.mark.parametrize("keys", [{"noise.kappa": 30.0}, {"noise.angular_sd_deg": 20.0, "noise.speed_sd": 0.5},
                                  {"cruise.speed": 4.0, "noise.kappa": 2.0}])
def test_planar_drive_matches_the_twin(keys):
    model = load_preset(MODELS / "opensteer.toml").replace({"world.dimensions": 2, **keys}).model
    fp, _ = pack(model, DT)
    kappa = model.noise.kappa_per_step(DT)
    assert fp[F.NOISE_KAPPA] == 0.0 and fp[F.PLANAR_TURN_SD] == pytest.approx(1.0 / math.sqrt(kappa), rel=1e-15)
    rng = np.random.default_rng(4)
    for _ in range(50):
        v = np.append(rng.standard_normal(2) * 3, 0.0)
        angle = rng.uniform(0, 2 * np.pi)
        f = np.array([math.cos(angle), math.sin(angle), 0.0])
        u = np.array([*rng.random(2), rng.standard_normal()])
        expected = ref_noise.drive(v, f, *u, 0.0, fp[F.SPEED_KICK], model.cruise.speed, fp[F.CRUISE_DECAY],
                                   fp[F.PLANAR_TURN_SD])
        got = _drive(v, f, u, fp)
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-12) and got[2] == 0.0
    three_d = load_preset(MODELS / "opensteer.toml").replace(keys).model
    assert pack(three_d, DT)[0][F.PLANAR_TURN_SD] == 0.0


@pytest.mark.slow
def test_planar_polarization_decays_as_a_wrapped_normal():
    """2 000 free boids (no rule acts) from one heading, angular sd 30 degrees per sqrt(s): after t the mean
    of f . x is exp(-sd^2 t / 2) (the mean cosine of a wrapped normal of variance sd^2 t), within 5
    standard errors; the 3-D decay exp(-sd^2 t) is far outside that."""
    n, sd_deg = 2000, 30.0
    model = load_preset(MODELS / "opensteer.toml").replace({
        "steering.separation_weight": 0.0, "steering.alignment_weight": 0.0, "steering.cohesion_weight": 0.0,
        "vehicle.max_speed": 100.0, "world.boundary": "open", "perception.search": "all_pairs",
        "world.dimensions": 2, "noise.angular_sd_deg": sd_deg}).model
    pos = np.zeros((n, 3))
    pos[:, 1] = 1000.0 * np.arange(n)
    fwd = np.tile([1.0, 0.0, 0.0], (n, 1))
    up, side = planar_frame(fwd)
    state = State(pos=pos, vel=2.0 * fwd, fwd=fwd, up=up, side=side, acc=np.zeros((n, 3)),
                  pattern=np.zeros(n, np.uint32))
    obs = advance(model, state, 120, DT, record_every=40, key=KEY)
    sd2 = math.radians(sd_deg) ** 2
    for r in range(1, 4):
        t = r * 40 * DT
        cos = obs.vel[r, :, 0] / np.linalg.norm(obs.vel[r], axis=1)
        assert abs(cos.mean() - math.exp(-sd2 * t / 2)) <= 5 * cos.std() / math.sqrt(n), t
        assert abs(cos.mean() - math.exp(-sd2 * t)) > 10 * cos.std() / math.sqrt(n), t
    assert np.all(obs.vel[..., 2] == 0.0)


# ------------------------------------------------------------------------------------------------------
# 4. determinism, and a 2-D flock is its own

@pytest.mark.slow   # compiles the batched and threaded loops of two presets (a minute on a busy machine)
@pytest.mark.parametrize("name", ["holland.toml", "hartman_benes.toml"])
def test_planar_runs_are_bit_identical_alone_batched_and_threaded(name):
    preset = preset_2d(name, {}, n=60, duration=3.0)
    m, i, r = preset.model, preset.init, preset.run
    alone = simulate(m, i, 7, r.duration, r.dt, r.record_every, threads=1)
    threaded = simulate(m, i, 7, r.duration, r.dt, r.record_every, threads=2)
    batch = simulate_batch(m, i, [6, 7], r.duration, r.dt, r.record_every)
    for other in (threaded, batch[1]):
        np.testing.assert_array_equal(other.pos, alone.pos)
        np.testing.assert_array_equal(other.vel, alone.vel)
    assert not np.array_equal(batch[0].pos, alone.pos)


@pytest.mark.slow
def test_a_planar_flock_is_not_a_spatial_flock_seen_from_above():
    """Holland's preset (N = 100, 40 s, seeds 2 and 5, second half): a 2-D run is not the 3-D run of the same
    seed seen from above (the plane x-z, orthogonal to OpenSteer's up y), and its boids perceive at least
    1.3 times as many neighbours (measured: 23.0 against 15.3 and 22.7 against 14.4): the same perception
    range holds more of a flock packed in a plane. (The mean nearest-neighbour distance is no test: seen
    from above it came out 4.64 against 4.68 in 2-D for seed 2 and 3.77 against 6.79 for seed 5.)"""
    flat = preset_2d("holland.toml", {}, n=100, duration=40.0, noisy=False)
    spatial = load_preset(MODELS / "holland.toml", ["init.n=100", "run.duration=40"])
    for seed in (2, 5):
        a, b = (simulate(p.model, p.init, seed, p.run.duration, p.run.dt, p.run.record_every) for p in (flat, spatial))
        assert not np.allclose(a.pos[..., :2], b.pos[..., [0, 2]], atol=1.0)
        half = len(a.visible) // 2
        assert a.visible[half:].mean() > 1.3 * b.visible[half:].mean(), seed


# ------------------------------------------------------------------------------------------------------
# 5. what a 2-D run cannot have

def test_what_lies_out_of_the_plane_is_refused_by_name():
    sphere = Obstacle(kind="sphere", centre=(3.0, 0.0, 0.0), radius=1.0)
    with pytest.raises(ConfigError) as err:
        ModelParams(dynamics="reynolds87", perception=Perception(kind="sphere"),
                    world=World(dimensions=2, obstacles=(sphere,)))
    assert err.value.key == "world.obstacles"
    with pytest.raises(ConfigError) as err:
        reynolds_model(migration_weight=1.0, migration_direction=(0.0, 0.0, 1.0))
    assert err.value.key == "reynolds.migration_direction"
    reynolds_model(migration_weight=0.0, migration_direction=(0.0, 0.0, 1.0))   # unused: no refusal
    with pytest.raises(ConfigError) as err:
        boidspp_model({"prey": {"enabled": True, "target_centre": [0.0, 0.0, 5.0]}})
    assert err.value.key == "boidspp.prey.target_centre"
    with pytest.raises(ConfigError, match="3-D only") as err:
        load_preset(ROOT / "examples" / "couzin_like.toml", ["world.dimensions=2"])   # a plug-in dynamics
    assert err.value.key == "world.dimensions"


def test_planar_start_has_patterns_only_in_pattern_mode():
    flat = load_preset(MODELS / "holland_pattern.toml", ["world.dimensions=2", "init.n=50"])
    from flocksweep.simcore.rng import run_streams
    from flocksweep.simcore.state import initial_state
    state = initial_state(flat.init, flat.model.patterns, run_streams(3)[0], 2)
    assert_in_plane(state)
    assert len(set(state.pattern.tolist())) > 1
    plain = initial_state(flat.init, Patterns(), run_streams(3)[0], 2)
    np.testing.assert_array_equal(plain.pos, state.pos)       # the patterns are drawn last
    assert not plain.pattern.any()
