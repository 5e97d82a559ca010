"""The reynolds87 dynamics: kernel against the numpy twin (tests/reference_reynolds.py) step by step,
hand-worked allocations, determinism (repeat, batch vs alone) and its configuration.

Step by step: a random flock-like state (or a flock flying into an obstacle) is advanced K single steps by
the kernel and by the twin from the same input state; both continue from the kernel's state, so rounding
cannot accumulate. Without obstacles every state array agrees to 1e-12. With obstacles the twin's
avoidance directions (bisection ray casts, silhouettes by scanning and refining support functions,
finite-difference normals) agree with the kernel's to about 1e-7 (observed: 2e-7 of the request, box and
cylinder), so the tolerances are about ten times what is observed: realised acceleration 2e-5 (units/s^2,
requests of 16), velocities 5e-7, frame vectors 2e-7, positions 1e-8. Each case checks that it
exercised what it claims (budget crossings, obstacles ahead, front boids, boids inside an obstacle).
"""
from __future__ import annotations

import numpy as np
import pytest

import reference_reynolds as ref
from conftest import flock_state, state_from, unit_vectors
from flocksweep.simcore import InitParams, advance, simulate, simulate_batch
from flocksweep.simcore.obstacle_spec import Obstacle
from flocksweep.simcore.params import ModelParams, Perception, World, model_dict
from flocksweep.simcore.reynolds87 import ALLOC_PRIORITY, ALLOC_PRIORITY_MAGNITUDE, ALLOC_WEIGHTED_SUM, allocate
from flocksweep.simcore.reynolds_params import Reynolds
from flocksweep.simcore.schema import ConfigError

FIELDS = ("pos", "vel", "fwd", "up", "side", "acc")
N_STEPS = 6
QUICK = {("priority", "sphere"), ("priority", "plane"), ("weighted_sum", "box")}  # other obstacle cases: slow
OBSTACLE_TOLERANCE = {"pos": 1e-8, "vel": 5e-7, "fwd": 2e-7, "up": 2e-7, "side": 2e-7, "acc": 2e-5}
DT = 1 / 60

OBSTACLES = {
    "sphere": Obstacle(kind="sphere", centre=(7.0, 0.3, -0.2), radius=2.5),
    "plane": Obstacle(kind="plane", centre=(6.0, 0.0, 0.0), normal=(-1.0, 0.2, 0.1)),
    "box": Obstacle(kind="box", centre=(7.0, 0.4, 0.0), half_extents=(1.5, 2.0, 2.5)),
    "cylinder": Obstacle(kind="cylinder", centre=(7.0, 0.0, 0.5), axis=(0.2, 1.0, 0.1), radius=2.0, length=9.0),
}


def reynolds_model(radius=3.5, boundary="open", order="synchronous", obstacles=(), search="auto", **keys):
    world = World(boundary=boundary, sphere_radius=4.0, box_size=7.0, update_order=order, obstacles=obstacles)
    return ModelParams(name="r", dynamics="reynolds87", perception=Perception(kind="sphere", radius=radius,
                                                                              search=search),
                       world=world, reynolds=Reynolds(**keys))


def heading_state(seed, n=24):
    """A flock about the origin flying roughly along +x, toward the obstacles above; one boid stopped."""
    rng = np.random.default_rng(seed)
    pos = unit_vectors(rng, n) * (3.0 * rng.random(n) ** (1 / 3))[:, None]
    fwd = np.array([1.0, 0.0, 0.0]) + 0.35 * rng.standard_normal((n, 3))
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    speed = rng.uniform(2.0, 6.0, n)
    speed[0] = 0.0
    pos[1] = OBSTACLES["sphere"].centre + np.array([-2.6, 0.0, 0.0])  # touching the sphere: the inside case
    return state_from(pos, fwd, speed, rng.normal(scale=3.0, size=(n, 3)))


CASES = [
    ("open-sync-priority", dict(), 1),
    ("open-seq-magnitude", dict(order="sequential", allocation="priority_magnitude"), 2),
    ("box-sync-weighted", dict(boundary="periodic_box", allocation="weighted_sum", radius=3.0), 3),
    ("wrap-seq-priority-grid", dict(boundary="sphere_wrap", order="sequential", search="grid", radius=2.0), 4),
    ("open-sync-falloff1-tight", dict(falloff_exponent=1.0, max_accel=4.0), 5),
    ("open-sync-falloff1.5", dict(falloff_exponent=1.5), 8),
    ("box-seq-falloff0", dict(falloff_exponent=0.0, boundary="periodic_box", order="sequential", radius=3.0), 9),
    ("migration-all", dict(migration_weight=5.0, migration_direction=(1.0, 2.0, -0.5)), 6),
    ("migration-front-seq", dict(migration_weight=5.0, migration_direction=(0.0, 0.0, 3.0), migration_who="front",
                                 order="sequential"), 7),
]


def run_steps(model, state, obstacles=False):
    """Advance K steps with both; returns per-step (kernel, twin) pairs and the twin's accelerations."""
    tolerance = OBSTACLE_TOLERANCE if obstacles else dict.fromkeys(FIELDS, 1e-12)
    accels = []
    for _ in range(N_STEPS):
        twin = ref.step(state, model, DT)
        obs = advance(model, state, 1, DT)
        new = obs.final
        for name in FIELDS:
            np.testing.assert_allclose(getattr(new, name), twin[name], rtol=1e-12, atol=tolerance[name],
                                       err_msg=name)
        np.testing.assert_array_equal(obs.visible[0], twin["visible"])
        accels.append(twin["accel"])
        state = new
    return np.array(accels)


@pytest.mark.parametrize("keys, seed", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_kernel_matches_twin(keys, seed):
    keys = dict(keys)
    max_accel = keys.setdefault("max_accel", 12.0)
    model = reynolds_model(**keys)
    box = 7.0 if keys.get("boundary") == "periodic_box" else None
    state = flock_state(seed, 24, ball_radius=3.0, box_size=box, max_speed=6.0)
    accels = run_steps(model, state)
    sizes = np.linalg.norm(accels, axis=2)
    assert np.isclose(sizes, max_accel, rtol=1e-12).sum() >= 5      # the budget was reached
    if max_accel > 4.0:
        assert (sizes < max_accel * (1 - 1e-9)).sum() >= 5          # and not reached


OBSTACLE_CASES = [pytest.param(kind, allocation, order, id=f"{allocation}-{order}-{kind}",
                               marks=() if (allocation, kind) in QUICK else pytest.mark.slow)
                  for allocation, order in [("priority", "synchronous"), ("weighted_sum", "synchronous"),
                                            ("priority_magnitude", "sequential")]
                  for kind in OBSTACLES]


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
@pytest.mark.parametrize("kind, allocation, order", OBSTACLE_CASES)
def test_kernel_matches_twin_with_obstacles(kind, allocation, order):
    model = reynolds_model(radius=3.0, obstacles=(OBSTACLES[kind],), allocation=allocation, lookahead=8.0,
                           order=order)
    state = heading_state(11)
    ahead = [np.any(ref.avoidance(model.world.obstacles, state.pos[i], state.fwd[i], state.up[i], 0.5, 8.0, 1.0))
             for i in range(state.n)]
    assert sum(ahead) >= 6, "too few boids see the obstacle ahead"
    run_steps(model, state, obstacles=True)


def test_front_boids_are_those_with_nobody_ahead():
    """Migration toward +z for front boids only: exactly the boids with no neighbour ahead get it."""
    model = reynolds_model(migration_weight=5.0, migration_direction=(0.0, 0.0, 1.0), migration_who="front",
                           separation_weight=0.0, alignment_weight=0.0, cohesion_weight=0.0, max_accel=100.0)
    state = flock_state(3, 24, ball_radius=3.0, max_speed=6.0)
    twin = ref.step(state, model, DT)
    front = np.isclose(twin["accel"][:, 2], 5.0)
    assert 1 <= front.sum() < state.n - 3
    for i in range(state.n):
        d = state.pos - state.pos[i]
        near = (np.einsum("ij,ij->i", d, d) < 3.5 ** 2) & (np.arange(state.n) != i)
        assert front[i] == (not np.any(d[near] @ state.fwd[i] > 0.0))


# ----------------------------------------------------------------------------------- hand-worked allocation
def allocated(reqs, limit, mode):
    a = np.zeros(3)
    used, full = 0.0, False
    for r in reqs:
        *a, used, full = allocate(a[0], a[1], a[2], used, full, r[0], r[1], r[2], limit, mode)
    a = np.array(a)
    if mode == ALLOC_WEIGHTED_SUM and np.linalg.norm(a) > limit:
        a *= limit / np.linalg.norm(a)
    return a


MODES = {"priority": ALLOC_PRIORITY, "priority_magnitude": ALLOC_PRIORITY_MAGNITUDE,
         "weighted_sum": ALLOC_WEIGHTED_SUM}
HAND = [  # requests, max_accel, mode, expected
    ([(3, 0, 0), (0, 4, 0), (0, 0, 1)], 10.0, "priority", (3, 4, 1)),                       # budget not reached
    ([(6, 0, 0), (0, 16, 0), (5, 5, 5)], 10.0, "priority", (6, 8, 0)),                      # s = 1/2 fills it
    ([(6, 0, 0), (0, 16, 0), (5, 5, 5)], 10.0, "priority_magnitude", (6, 4, 0)),            # s = 4/16
    ([(6, 0, 0), (0, 16, 0), (5, 5, 5)], 10.0, "weighted_sum", np.array([11, 21, 5]) * 10 / np.sqrt(587)),
    ([(20, 0, 0), (0, 1, 0)], 10.0, "priority", (10, 0, 0)),                                # first one alone
    ([(8, 0, 0), (-8, 0, 0), (0, 3, 0)], 10.0, "priority", (0, 3, 0)),                      # cancelling
    ([(8, 0, 0), (-8, 0, 0), (0, 3, 0)], 10.0, "priority_magnitude", (6, 0, 0)),
    ([(6, 0, 0), (0, 8, 0), (1, 0, 0)], 10.0, "priority", (6, 8, 0)),                       # exactly full
    ([(0, 0, 0), (3, 0, 0)], 2.0, "priority_magnitude", (2, 0, 0)),                         # zero skipped
]


@pytest.mark.parametrize("reqs, limit, mode, expected", HAND)
def test_hand_worked_allocation(reqs, limit, mode, expected):
    reqs = [np.array(r, dtype=float) for r in reqs]
    np.testing.assert_allclose(allocated(reqs, limit, MODES[mode]), expected, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(ref.allocate(reqs, limit, mode), expected, rtol=1e-12, atol=1e-12)


def test_crossing_scale_fills_the_budget_exactly_for_random_requests():
    rng = np.random.default_rng(5)
    for _ in range(500):
        reqs = [rng.normal(scale=rng.uniform(0.1, 8.0), size=3) for _ in range(5)]
        a = allocated(reqs, 10.0, ALLOC_PRIORITY)
        total = np.sum(reqs, axis=0)
        partial = np.cumsum(reqs, axis=0)
        if np.all(np.linalg.norm(partial, axis=1) <= 10.0):
            np.testing.assert_allclose(a, total, rtol=1e-13, atol=1e-13)
        else:
            assert abs(np.linalg.norm(a) - 10.0) < 1e-12
        np.testing.assert_allclose(a, ref.allocate(reqs, 10.0, "priority"), rtol=1e-10, atol=1e-10)


# ----------------------------------------------------------------------------------- determinism
def course_model(**keys):
    obstacles = tuple(OBSTACLES.values())
    return reynolds_model(radius=6.0, obstacles=obstacles, migration_weight=4.0, migration_who="front", **keys)


@pytest.mark.parametrize("order", ["synchronous", "sequential"])
def test_repeat_and_batch_are_bit_identical(order):
    model = course_model(order=order)
    init = InitParams(n=30, radius=5.0, speed=4.0)
    alone = [simulate(model, init, seed, 1.0, DT, 6) for seed in (1, 2, 3)]
    again = simulate(model, init, 2, 1.0, DT, 6)
    batch = simulate_batch(model, init, [3, 1, 2], 1.0, DT, 6)
    for x, y in [(alone[1], again), (alone[2], batch[0]), (alone[0], batch[1]), (alone[1], batch[2])]:
        for name in ("pos", "vel", "visible"):
            np.testing.assert_array_equal(getattr(x, name), getattr(y, name))
        np.testing.assert_array_equal(x.final.up, y.final.up)
    assert not np.array_equal(alone[0].pos, alone[1].pos)


def test_speed_stays_within_limits_and_final_record_perceives():
    model = course_model(min_speed=2.5, max_speed=5.0)
    obs = simulate(model, InitParams(n=30, radius=5.0, speed=0.0), 4, 1.0, DT, 6)
    speed = np.linalg.norm(obs.vel[1:], axis=2)
    assert speed.min() >= 2.5 * (1 - 1e-12) and speed.max() <= 5.0 * (1 + 1e-12)
    assert obs.visible[-1].sum() > 0 and not obs.leader.any() and len(obs.triggers) == 0


# ----------------------------------------------------------------------------------- configuration
@pytest.mark.parametrize("keys, key", [
    (dict(min_speed=7.0), "reynolds.min_speed"),
    (dict(allocation="priority_sum"), "reynolds.allocation"),
    (dict(migration_direction=(0.0, 0.0, 0.0)), "reynolds.migration_direction"),
    (dict(migration_direction=(1.0, 0.0)), "reynolds.migration_direction"),
    (dict(migration_who="leaders"), "reynolds.migration_who"),
    (dict(max_accel=0.0), "reynolds.max_accel"),
    (dict(falloff_exponent=-1.0), "reynolds.falloff_exponent"),
    (dict(lookahead=float("inf")), "reynolds.lookahead"),
])
def test_bad_reynolds_keys_are_named(keys, key):
    with pytest.raises(ConfigError) as err:
        Reynolds(**keys)
    assert err.value.key == key


def test_model_level_checks():
    with pytest.raises(ConfigError, match="perception.kind"):
        ModelParams(dynamics="reynolds87")
    from flocksweep.simcore.params import Leadership, Patterns
    with pytest.raises(ConfigError, match="leadership.x"):
        ModelParams(dynamics="reynolds87", perception=Perception(kind="sphere"), leadership=Leadership(x=0.5))
    with pytest.raises(ConfigError, match="patterns.enabled"):
        ModelParams(dynamics="reynolds87", perception=Perception(kind="sphere"), patterns=Patterns(enabled=True))


def test_canonical_form():
    plain = model_dict(reynolds_model())
    assert "migration_direction" not in plain["reynolds"] and "steering" not in plain and "vehicle" not in plain
    migrating = model_dict(reynolds_model(migration_weight=2.0, migration_direction=(0.0, 3.0, 4.0)))
    assert migrating["reynolds"]["migration_direction"] == [0.0, 0.6, 0.8]
    assert migrating["reynolds"]["migration_who"] == "all"
    assert "reynolds" not in model_dict(ModelParams())
    again = Reynolds(**{**migrating["reynolds"], "migration_direction": tuple(migrating["reynolds"]
                                                                              ["migration_direction"])})
    assert again.migration_direction == (0.0, 0.6, 0.8)
