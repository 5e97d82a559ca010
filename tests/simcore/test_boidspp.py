"""The Boids++ kernel (simcore.boidspp) agrees with its numpy twin (tests/reference_boidspp.py) and is
deterministic.

Each twin case advances a random flock-like state K steps with the kernel (``advance``) and with the
twin from the same input; positions, velocities, frames, accelerations, agents and capture steps must
agree to 1e-9 (the twin's obstacle ray casts are iterative, so hits agree to ~1e-12, not bit for bit).
Each case checks that it exercised what it claims: neighbours within the separation radius, kicks,
boids whose forward ray is blocked, fleeing and non-fleeing boids, a prey target reached.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import reference_boidspp as twin
from conftest import flock_state
from flocksweep.simcore import advance, simulate, simulate_batch
from flocksweep.simcore.boidspp_params import BoidsPP
from flocksweep.simcore.obstacle_spec import Obstacle
from flocksweep.simcore.params import InitParams, ModelParams, Perception, Vehicle, World, model_dict
from flocksweep.simcore.schema import ConfigError, build

TOL = 1e-9
N = 24
K = 6
DT = 1 / 60
KEY = 0x1234_5678_9ABC_DEF0


def model_of(boidspp=None, boundary="open", order="synchronous", obstacles=(), radius=3.5, box_size=7.0,
             sphere_radius=4.0, max_speed=9.0):
    return ModelParams(name="t", dynamics="boidspp", perception=Perception(kind="sphere", radius=radius),
                       vehicle=Vehicle(max_speed=max_speed),
                       world=World(boundary=boundary, box_size=box_size, sphere_radius=sphere_radius,
                                   update_order=order, obstacles=obstacles),
                       boidspp=build(BoidsPP, boidspp or {}, "boidspp"))


SPHERES = (Obstacle(kind="sphere", centre=(3.0, 0.0, 0.0), radius=1.5),
           Obstacle(kind="sphere", centre=(-2.0, 3.0, 1.0), radius=1.0),
           Obstacle(kind="sphere", centre=(0.0, -4.0, -2.0), radius=2.0))

CASES = [
    ("rules-sync", {}, {}),
    ("rules-literal-sync", {"separation": {"form": "velocity_over_distance", "radius": 2.5}}, {}),
    ("rules-seq", {"alignment": {"blend": 0.3}, "cohesion": {"blend": 0.1}}, {"order": "sequential"}),
    ("rules-box-sync", {"separation": {"radius": 1.5}}, {"boundary": "periodic_box", "radius": 3.0}),
    ("rules-flock-seq", {"alignment": {"scope": "flock"}, "cohesion": {"scope": "flock", "blend": 0.2}},
     {"order": "sequential"}),
    ("rules-flock-box-seq", {"cohesion": {"scope": "flock"}}, {"boundary": "periodic_box", "order": "sequential"}),
    ("rules-flock-align-sync", {"alignment": {"scope": "flock"}, "separation": {"form": "velocity_over_distance"}},
     {}),
    ("random-force-wrap", {"random_force": {"every": 2, "magnitude": 3.0}, "min_speed": 0.5},
     {"boundary": "sphere_wrap"}),
    pytest.param("obstacles-sync", {"avoid": {"rays": 32, "lookahead": 4.0, "weight": 80.0}}, {"obstacles": SPHERES},
                 marks=pytest.mark.slow),
    pytest.param("obstacles-seq-literal", {"avoid": {"rays": 16, "lookahead": 3.0},
                                           "separation": {"form": "velocity_over_distance"}},
                 {"obstacles": SPHERES, "order": "sequential"}, marks=pytest.mark.slow),
    ("prey", {"prey": {"enabled": True, "speed": 30.0, "target_radius": 0.5, "arrive_radius": 0.4,
                       "weight": 20.0}}, {}),
    ("predator", {"predator": {"enabled": True, "start_s": 2 * DT, "leave_s": 4 * DT, "start_distance": 1.0,
                               "avoid_radius": 3.0, "capture_radius": 2.0, "flee_blend": 0.7}}, {}),
    ("predator-nearest", {"predator": {"enabled": True, "target": "nearest", "start_distance": 2.0, "speed": 40.0,
                                       "avoid_radius": 2.0, "capture_radius": 1.5}}, {}),
    ("predator-prey-box-seq", {"predator": {"enabled": True, "start_distance": 0.5, "avoid_radius": 2.0},
                               "prey": {"enabled": True, "target_radius": 2.0}},
     {"boundary": "periodic_box", "order": "sequential", "radius": 3.0}),
]


def state_for(model, seed):
    if model.world.boundary == "periodic_box":
        return flock_state(seed, N, box_size=model.world.box_size)
    return flock_state(seed, N, ball_radius=4.0)


@pytest.mark.parametrize("case, table, world", CASES,
                         ids=[c.values[0] if hasattr(c, "values") else c[0] for c in CASES])
def test_kernel_agrees_with_the_twin(case, table, world):
    model = model_of(table, **world)
    state = state_for(model, seed=11)
    got = advance(model, state, K, DT, record_every=1, key=KEY)
    ref, agents, capture = twin.run(state, model, DT, K, KEY)
    for name in twin.STATE_KEYS:
        np.testing.assert_allclose(getattr(got.final, name), ref[name], rtol=TOL, atol=TOL, err_msg=name)
    if model.boidspp.predator.enabled:
        np.testing.assert_allclose(got.predator[-1], agents.pred, rtol=TOL, atol=TOL)
    else:
        assert got.predator is None
    if model.boidspp.prey.enabled:
        np.testing.assert_allclose(got.prey[-1], agents.prey, rtol=TOL, atol=TOL)
    else:
        assert got.prey is None
    if model.boidspp.predator.capture_radius is not None:
        expected = sorted((int(s), i) for i, s in enumerate(capture) if s >= 0)
        assert [tuple(row) for row in got.captures.tolist()] == expected
        assert expected, "the predator should capture someone"
    assert_exercised(case, model, state, got, agents)


def assert_exercised(case, model, state, got, agents):
    pos = state.pos
    dist = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    np.fill_diagonal(dist, np.inf)
    if case.startswith("rules") and model.world.boundary != "periodic_box":
        assert (dist < model.boidspp.separation.radius).any(axis=1).sum() >= 4
    if case.startswith("random"):
        assert not np.allclose(got.vel[1], advance(model_of({"min_speed": 0.5}, boundary="sphere_wrap"), state, 1,
                                                   DT, key=KEY).vel[1])
    if case.startswith("obstacles"):
        blocked = sum(twin.avoidance(i, {k: getattr(state, k) for k in twin.STATE_KEYS}, model) is not None
                      for i in range(N))
        assert blocked >= 2, "some boids must see an obstacle ahead"
    if case == "prey":
        assert agents.drawn > 2, "the prey must reach a target"
    if case.startswith("predator"):
        start = got.predator[0] if not math.isnan(got.predator[0, 0]) else got.predator[2]
        at_start = got.pos[2 if case == "predator" else 0]
        near = np.linalg.norm(at_start - start, axis=1) < model.boidspp.predator.avoid_radius
        assert 0 < near.sum() < N, "some boids must flee and some not"
    if case == "predator":
        assert np.isnan(got.predator[:2]).all() and not np.isnan(got.predator[2:]).any()
    if case == "predator-nearest":  # it heads for the boid nearest to it, not for the flock's centre
        step = got.predator[1] - got.predator[0]
        gaps = got.pos[0] - got.predator[0]
        nearest = gaps[np.argmin(np.linalg.norm(gaps, axis=1))]
        np.testing.assert_allclose(step / np.linalg.norm(step), nearest / np.linalg.norm(nearest), atol=1e-12)


def test_fleeing_boids_skip_the_rules():
    """A boid within avoid_radius moves as the flee blend alone says, whatever its neighbours."""
    table = {"predator": {"enabled": True, "start_distance": 0.0, "avoid_radius": 100.0, "flee_blend": 1.0},
             "alignment": {"blend": 1.0}, "cohesion": {"blend": 1.0}}
    model = model_of(table)
    state = flock_state(3, N, ball_radius=4.0)
    got = advance(model, state, 1, DT, key=KEY)
    away = state.pos - got.predator[0]
    expected = 9.0 * away / np.linalg.norm(away, axis=1, keepdims=True)
    np.testing.assert_allclose(got.final.vel, expected, rtol=1e-12, atol=1e-12)


def run(model, seeds, n=40, duration=0.5):
    init = InitParams(n=n, radius=5.0, speed=4.0)
    return [simulate(model, init, seed, duration, DT, record_every=5) for seed in seeds], \
        simulate_batch(model, init, seeds, duration, DT, record_every=5)


FULL = {"random_force": {"magnitude": 2.0, "every": 3}, "prey": {"enabled": True},
        "predator": {"enabled": True, "start_distance": 5.0, "start_s": 0.1, "leave_s": 0.3, "capture_radius": 1.0}}


def test_repeat_and_batch_are_bit_identical():
    model = model_of(FULL, obstacles=SPHERES, radius=5.0)
    alone, batch = run(model, [1, 2, 3])
    again, _ = run(model, [1, 2, 3])
    for a, b, c in zip(alone, batch, again):
        for name in ("pos", "vel", "visible", "predator", "prey", "captures"):
            assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
            assert np.array_equal(getattr(a, name), getattr(c, name), equal_nan=True), name
    assert not np.array_equal(alone[0].pos, alone[1].pos)


def test_random_kicks_are_counter_based():
    """The kick of boid i at step s depends on (key, s, i) only: a batch of different seeds around the
    same seed changes nothing, and a flock of identical boids still gets different kicks per boid."""
    model = model_of({"random_force": {"magnitude": 3.0, "every": 1}, "alignment": {"blend": 0.0},
                      "cohesion": {"blend": 0.0}, "separation": {"blend": 0.0}})
    _, batch_a = run(model, [7, 8])
    _, batch_b = run(model, [9, 7])
    assert np.array_equal(batch_a[0].pos, batch_b[1].pos)
    state = flock_state(5, 4, ball_radius=50.0)
    same = type(state)(pos=state.pos, vel=np.tile([3.0, 0.0, 0.0], (4, 1)), fwd=np.tile([1.0, 0.0, 0.0], (4, 1)),
                       up=np.tile([0.0, 1.0, 0.0], (4, 1)), side=np.tile([0.0, 0.0, 1.0], (4, 1)),
                       acc=np.zeros((4, 3)), pattern=state.pattern[:4])
    kicked = advance(model, same, 1, DT, key=KEY).final.vel
    assert len({tuple(v) for v in kicked.round(12)}) == 4
    np.testing.assert_allclose(np.linalg.norm(kicked - [3.0, 0.0, 0.0], axis=1), 3.0, rtol=1e-12)


def test_other_models_keep_their_identity_and_boidspp_identity_ignores_unused_keys():
    plain = ModelParams()
    assert "boidspp" not in model_dict(plain)
    assert model_dict(plain) == model_dict(ModelParams(boidspp=build(BoidsPP, {"min_speed": 1.0}, "boidspp")))
    base = model_of()
    unused = model_of({"predator": {"speed": 3.0}, "prey": {"speed": 1.0}, "random_force": {"every": 5}})
    assert model_dict(base) == model_dict(unused)
    assert model_dict(base) != model_dict(model_of({"random_force": {"magnitude": 1.0}}))
    assert "steering" not in model_dict(base) and "gains" not in model_dict(base)


@pytest.mark.parametrize("table, extra, key", [
    ({"separation": {"form": "velocity"}}, {}, "boidspp.separation.form"),
    ({"alignment": {"blend": 1.5}}, {}, "boidspp.alignment.blend"),
    ({"random_force": {"every": 0}}, {}, "boidspp.random_force.every"),
    ({"predator": {"start_s": 5.0, "leave_s": 2.0}}, {}, "boidspp.predator.leave_s"),
    ({"prey": {"target_centre": [0.0, 1.0]}}, {}, "boidspp.prey.target_centre"),
    ({"min_speed": 20.0}, {}, "boidspp.min_speed"),
    ({}, {"leadership": {"x": 1.0}}, "leadership.x"),
])
def test_bad_tables_name_the_key(table, extra, key):
    data = {"dynamics": "boidspp", "perception": {"kind": "sphere"}, "boidspp": table}
    data.update(extra)
    with pytest.raises(ConfigError) as err:
        build(ModelParams, data)
    assert err.value.key == key


def lone_boid(x=0.0, speed=5.0):
    from flocksweep.simcore.state import State, frame_from_forward

    fwd = np.array([[1.0, 0.0, 0.0]])
    up, side = frame_from_forward(fwd)
    return State(pos=np.array([[x, 0.3, 0.0]]), vel=fwd * speed, fwd=fwd, up=up, side=side, acc=np.zeros((1, 3)),
                 pattern=np.zeros(1, np.uint32))


def test_a_boid_heading_for_a_sphere_goes_round_it_only_with_avoidance():
    from flocksweep.simcore.obstacle_spec import pack_obstacles
    from flocksweep.simcore.obstacles import clearances

    ball = (Obstacle(kind="sphere", centre=(12.0, 0.0, 0.0), radius=2.0),)
    table, kinds = pack_obstacles(ball)
    clearance = {}
    for weight in (60.0, 0.0):
        model = model_of({"avoid": {"weight": weight}, "min_speed": 5.0}, obstacles=ball, max_speed=5.0)
        obs = advance(model, lone_boid(), 240, DT, key=KEY)
        clearance[weight] = clearances(table, kinds, obs.pos[:, 0]).min()
        assert obs.pos[-1, 0, 0] > 14.0  # it got past the sphere either way
    assert clearance[60.0] > 0.5 and clearance[0.0] < 0.0


def test_the_flock_follows_the_prey_and_the_predator_closes_in():
    """The prey seek pulls the flock's centre toward the prey; a hunting predator closes the gap to the
    flock's centre at least at its speed less the speed cap (the flock's centre moves at most that fast)."""
    model = model_of({"prey": {"enabled": True, "weight": 20.0, "target_radius": 20.0},
                      "predator": {"enabled": True, "start_distance": 30.0, "speed": 12.0, "avoid_radius": 0.0},
                      "alignment": {"blend": 0.1}, "cohesion": {"blend": 0.02}, "separation": {"blend": 0.1},
                      "min_speed": 2.0}, radius=5.0)
    obs = simulate(model, InitParams(n=10, radius=3.0, speed=4.0), 5, 4.0, DT, record_every=60)
    prey_gap = np.linalg.norm(obs.pos.mean(axis=1) - obs.prey, axis=1)
    pred_gap = np.linalg.norm(obs.pos.mean(axis=1) - obs.predator, axis=1)
    assert prey_gap[-1] < 0.3 * prey_gap[0]
    blind = model_of({"prey": {"enabled": True, "weight": 0.0, "target_radius": 20.0}, "min_speed": 2.0,
                      "alignment": {"blend": 0.1}, "cohesion": {"blend": 0.02}, "separation": {"blend": 0.1}},
                     radius=5.0)
    ignored = simulate(blind, InitParams(n=10, radius=3.0, speed=4.0), 5, 4.0, DT, record_every=60)
    assert np.linalg.norm(ignored.pos.mean(axis=1) - ignored.prey, axis=1)[-1] > 0.3 * prey_gap[0]
    assert pred_gap[0] == pytest.approx(30.0, abs=1e-9)
    assert pred_gap[2] <= 30.0 - 2.0 * (12.0 - 9.0) + 1e-9
