"""Invariants of the OpenSteer dynamics that must hold at every step (docs/model.md sections 0-3).

Speed cap, force truncation, an orthonormal right-handed body frame, the two world boundaries (sphere wrap
and periodic box with minimum-image neighbours), a stopped boid keeping its heading, and sane
visible/binocular counts.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import flock_state, make_model, state_from
from flocksweep.simcore import InitParams, advance, simulate
from flocksweep.simcore.opensteer_params import Steering
from flocksweep.simcore.params import Vehicle
from flocksweep.simcore.probe import perceived, steering

DT = 1 / 60
KINDS = ("sphere", "opensteer", "binocular")
# perception keys per kind giving lively flocks of 30 in a ball of radius 5-6 (binocular: overlapping eyes)
PERCEPTION = {"sphere": dict(radius=3.0), "opensteer": {}, "binocular": dict(direction_deg=30.0)}
ABSURD = Steering(separation_weight=1e6, alignment_weight=1e6, cohesion_weight=1e6)
# cohesion and alignment far beyond max_force but weak separation: boids speed up and hit the cap
CAP_SEEKING = Steering(separation_weight=1e3, alignment_weight=1e6, cohesion_weight=1e6)


def speeds(obs):
    return np.linalg.norm(obs.vel, axis=-1)


@pytest.mark.parametrize("kind", KINDS)
def test_speed_never_exceeds_max_speed(kind):
    vehicle = Vehicle(max_speed=4.0)
    model = make_model(kind, steering=CAP_SEEKING, vehicle=vehicle, **PERCEPTION[kind])
    obs = simulate(model, InitParams(n=30, radius=6.0, speed=3.0), seed=11, duration=2.0, dt=DT)
    speed = speeds(obs)
    assert speed.max() <= vehicle.max_speed * (1 + 1e-12)
    at_cap = speed >= vehicle.max_speed * (1 - 1e-9)
    assert at_cap.sum() >= 100, "the speed cap was rarely reached, so hardly tested"


@pytest.mark.parametrize("kind", KINDS)
def test_truncated_force_bounds_the_velocity_change(kind):
    """|v(t+dt) - v(t)| <= max_force / mass * dt under absurd steering weights (smoothing only shrinks it)."""
    vehicle = Vehicle(max_speed=9.0, max_force=10.0, mass=2.0)
    model = make_model(kind, steering=ABSURD, vehicle=vehicle, **PERCEPTION[kind])
    obs = simulate(model, InitParams(n=30, radius=6.0, speed=2.7), seed=12, duration=1.5, dt=DT)
    change = np.linalg.norm(np.diff(obs.vel, axis=0), axis=-1)
    bound = vehicle.max_force / vehicle.mass * DT
    assert change.max() <= bound * (1 + 1e-9)
    assert change.max() >= 0.5 * bound, "the force limit was never approached"


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("order", ("synchronous", "sequential"))
def test_frame_stays_orthonormal_and_right_handed(kind, order):
    model = make_model(kind, order=order, **PERCEPTION[kind])
    state = flock_state(13, 30, ball_radius=5.0)
    for _ in range(8):
        state = advance(model, state, 15, DT).final
        f, u, s = state.fwd, state.up, state.side
        for v in (f, u, s):
            np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-9)
        for a, b in ((f, u), (f, s), (u, s)):
            np.testing.assert_allclose(np.einsum("ij,ij->i", a, b), 0.0, atol=1e-9)
        np.testing.assert_allclose(s, np.cross(f, u), atol=1e-9)
        moving = np.linalg.norm(state.vel, axis=1) > 0
        np.testing.assert_allclose(f[moving], state.vel[moving] / np.linalg.norm(state.vel[moving], axis=1,
                                                                                     keepdims=True), atol=1e-9)


def test_sphere_wrap_keeps_boids_inside_and_wraps():
    radius = 6.0
    model = make_model("opensteer", boundary="sphere_wrap", sphere_radius=radius)
    obs = simulate(model, InitParams(n=30, radius=radius, speed=6.0), seed=14, duration=3.0, dt=DT)
    assert np.linalg.norm(obs.pos, axis=-1).max() <= radius * (1 + 1e-12)
    jumps = np.linalg.norm(np.diff(obs.pos, axis=0), axis=-1)
    assert (jumps > radius).sum() >= 5, "boids should have wrapped through the centre"
    # the wrap moves the position only, the velocity is kept: no jump in velocity beyond the force bound
    assert np.linalg.norm(np.diff(obs.vel, axis=0), axis=-1).max() <= 27.0 * DT * (1 + 1e-9)


def test_sphere_wrap_distances_do_not_wrap():
    """Two boids just inside opposite poles of the world sphere are far apart (no wrapped neighbours)."""
    model = make_model("sphere", radius=2.0, boundary="sphere_wrap", sphere_radius=5.0)
    state = state_from([[-4.9, 0, 0], [4.9, 0, 0]], [[1.0, 0, 0], [1.0, 0, 0]], 1.0)
    assert perceived(model, state, 0)["idx"].size == 0


def test_periodic_positions_stay_in_box_and_wrap():
    box = 6.0
    model = make_model("opensteer", boundary="periodic_box", box_size=box)
    obs = simulate(model, InitParams(n=30, radius=3.0, speed=6.0), seed=15, duration=3.0, dt=DT)
    pos = obs.pos[1:]  # the initial draw is not the kernel's output
    assert pos.min() >= -box / 2 and pos.max() < box / 2
    jumps = np.abs(np.diff(obs.pos, axis=0))
    assert (jumps > box / 2).sum() >= 5, "boids should have crossed the box faces"


@pytest.mark.parametrize("kind", ("sphere", "opensteer"))
def test_periodic_neighbours_use_minimum_image(kind):
    box = 20.0
    keys = dict(radius=2.0) if kind == "sphere" else {}
    near_faces = [[-box / 2 + 0.5, 0, 0], [box / 2 - 0.5, 0, 0]]
    state = state_from(near_faces, [[0, 0, 1.0], [0, 0, 1.0]], 1.0)

    periodic = make_model(kind, boundary="periodic_box", box_size=box, **keys)
    seen_by_0, seen_by_1 = perceived(periodic, state, 0), perceived(periodic, state, 1)
    assert seen_by_0["idx"].tolist() == [1] and seen_by_1["idx"].tolist() == [0]
    np.testing.assert_allclose(seen_by_0["offset"], [[-1.0, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(seen_by_1["offset"], [[1.0, 0, 0]], atol=1e-12)
    assert seen_by_0["mask"].tolist() == [7]

    open_world = make_model(kind, **keys)
    assert perceived(open_world, state, 0)["idx"].size == 0


def test_periodic_cohesion_pulls_across_the_face():
    box = 20.0
    model = make_model("sphere", radius=2.0, boundary="periodic_box", box_size=box,
                       steering=Steering(separation_weight=0.0, alignment_weight=0.0, cohesion_weight=1.0))
    state = state_from([[-box / 2 + 0.5, 0, 0], [box / 2 - 0.5, 0, 0]], [[0, 0, 1.0], [0, 0, 1.0]], 1.0)
    np.testing.assert_allclose(steering(model, state, 0), [-1.0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(steering(model, state, 1), [1.0, 0, 0], atol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_stopped_isolated_boid_keeps_its_heading(kind):
    fwd = np.array([[0.36, 0.48, 0.8], [1.0, 0, 0]])
    state = state_from([[0.0, 0, 0], [500.0, 0, 0]], fwd, 0.0)
    final = advance(make_model(kind), state, 120, DT).final
    np.testing.assert_array_equal(final.fwd, state.fwd)
    np.testing.assert_array_equal(final.vel, 0.0)
    np.testing.assert_array_equal(final.pos, state.pos)


def test_stopped_boid_starts_along_its_heading():
    """At speed 0 the cone clamp has cosine 1: a sideways force turns into a push along the heading."""
    heading = np.array([0.0, 0.0, 1.0])
    state = state_from([[0.0, 0, 0], [1.0, 0, 0]], [heading, heading], [0.0, 5.0])
    model = make_model("sphere", radius=3.0)
    force = steering(model, state, 0)
    assert abs(force @ heading) < 1e-9 * np.linalg.norm(force), "the raw force should be sideways"
    final = advance(model, state, 1, DT).final
    assert np.linalg.norm(final.vel[0]) > 0
    np.testing.assert_allclose(final.fwd[0], heading, atol=1e-12)
    np.testing.assert_allclose(final.vel[0] / np.linalg.norm(final.vel[0]), heading, atol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_visible_and_binocular_counts_are_consistent(kind):
    n = 30
    model = make_model(kind, order="sequential" if kind == "sphere" else "synchronous", **PERCEPTION[kind])
    obs = simulate(model, InitParams(n=n, radius=5.0), seed=16, duration=1.0, dt=DT, record_every=6)
    assert obs.visible.min() >= 0 and obs.visible.max() <= n - 1
    assert (obs.binocular >= 0).all() and (obs.binocular <= obs.visible).all()
    assert obs.visible.mean() > 3
    if kind == "binocular":
        assert obs.binocular.sum() > 0
        assert (obs.binocular < obs.visible).any()
    else:
        assert not obs.binocular.any()
