"""The compiled kernel agrees with the slow reference (tests/reference.py), step by step.

For each configuration (perception kind and its parameters, update order, pattern mode, boundary, dt) a
random flock-like state is advanced K single steps by the kernel and by the reference from the same input
state; every state array must agree to 1e-12 and the visible/binocular counts exactly. Both continue from
the kernel's state, so rounding differences cannot accumulate. On every input state the kernel's
perception of every boid (simcore.probe.perceived) is compared with reference.perceive.

Each case also checks that it exercised what it claims to: enough neighbours, occlusion actually hiding
boids, the low-speed cone clamp acting, boids actually wrapping around the world.
"""
from __future__ import annotations

import numpy as np
import pytest

import reference
from conftest import flock_state, make_model
from flocksweep.simcore import advance
from flocksweep.simcore.probe import perceived

RULE_BITS = {"separation": 1, "alignment": 2, "cohesion": 4}
RTOL = ATOL = 1e-12
N_BOIDS = 32
N_STEPS = 8
WRAP_RADIUS = 4.0  # sphere_wrap world radius, equal to the flock's ball so boids cross it within K steps
BOX = 7.0          # periodic box side, of the order of the perception radii so minimum image matters

# (id, model keyword arguments, dt)
CASES = [
    ("sphere-open-sync", dict(kind="sphere", radius=3.5), 1 / 60),
    ("sphere-open-seq", dict(kind="sphere", radius=3.5, order="sequential"), 1 / 60),
    ("sphere-box-sync", dict(kind="sphere", radius=3.0, boundary="periodic_box"), 1 / 60),
    ("sphere-wrap-seq-uniform", dict(kind="sphere", radius=3.5, boundary="sphere_wrap", order="sequential",
                                     patterns="uniform"), 1 / 30),
    ("opensteer-open-sync", dict(kind="opensteer"), 1 / 60),
    ("opensteer-open-seq", dict(kind="opensteer", order="sequential"), 0.05),
    ("opensteer-wrap-sync", dict(kind="opensteer", boundary="sphere_wrap"), 1 / 60),
    ("opensteer-box-seq", dict(kind="opensteer", boundary="periodic_box", order="sequential"), 1 / 60),
    ("opensteer-open-sync-similarity", dict(kind="opensteer", patterns="similarity"), 1 / 60),
    ("opensteer-box-sync-dissimilarity", dict(kind="opensteer", boundary="periodic_box",
                                              patterns="dissimilarity"), 1 / 30),
    ("binocular-occl-default-sync", dict(kind="binocular"), 1 / 60),
    ("binocular-occl-360-wrap-sync", dict(kind="binocular", direction_deg=0.0, field_deg=360.0, range=8.0,
                                          boundary="sphere_wrap"), 1 / 60),
    ("binocular-occl-200-seq", dict(kind="binocular", direction_deg=90.0, field_deg=200.0, range=6.0,
                                    order="sequential"), 1 / 60),
    ("binocular-occl-270-box-sync", dict(kind="binocular", direction_deg=30.0, field_deg=270.0, range=5.0,
                                         body_radius=0.8, boundary="periodic_box"), 0.05),
    ("binocular-occl-180-sync-similarity", dict(kind="binocular", direction_deg=45.0, field_deg=180.0,
                                                range=7.0, patterns="similarity"), 1 / 60),
    ("binocular-occl-150-wrap-seq-dissimilarity", dict(kind="binocular", direction_deg=60.0,
                                                       eye_position_deg=20.0, field_deg=150.0, range=8.0,
                                                       boundary="sphere_wrap", order="sequential",
                                                       patterns="dissimilarity"), 1 / 60),
    ("binocular-noocc-default-sync", dict(kind="binocular", occlusion=False), 1 / 60),
    ("binocular-noocc-200-box-seq-uniform", dict(kind="binocular", occlusion=False, direction_deg=45.0,
                                                 field_deg=200.0, range=4.0, boundary="periodic_box",
                                                 order="sequential", patterns="uniform"), 1 / 60),
    ("topological-open-sync", dict(kind="topological"), 1 / 60),
    ("topological-blind-radius-seq-similarity", dict(kind="topological", neighbours=5, max_distance=3.0,
                                                     blind_deg=90.0, order="sequential", patterns="similarity"),
     1 / 60),
    ("topological-box-sync-grid", dict(kind="topological", neighbours=4, boundary="periodic_box",
                                       search="grid"), 1 / 60),
    ("topological-wrap-seq-grid", dict(kind="topological", neighbours=9, blind_deg=120.0, boundary="sphere_wrap",
                                       order="sequential", search="grid"), 1 / 30),
    ("sphere-box-seq-grid", dict(kind="sphere", radius=2.0, boundary="periodic_box", order="sequential",
                                 search="grid"), 1 / 60),
    ("opensteer-open-sync-grid", dict(kind="opensteer", search="grid"), 1 / 60),
    ("binocular-occl-360-wrap-seq-grid", dict(kind="binocular", direction_deg=0.0, field_deg=360.0, range=2.5,
                                              boundary="sphere_wrap", order="sequential", search="grid"), 1 / 60),
]


def build_model(kwargs):
    kwargs = dict(kwargs)
    boundary = kwargs.get("boundary", "open")
    if boundary == "sphere_wrap":
        kwargs["sphere_radius"] = WRAP_RADIUS
    if boundary == "periodic_box":
        kwargs["box_size"] = BOX
    return make_model(**kwargs)


def build_state(model, seed):
    if model.world.boundary == "periodic_box":
        return flock_state(seed, N_BOIDS, box_size=BOX)
    return flock_state(seed, N_BOIDS, ball_radius=WRAP_RADIUS)


def reference_box(model):
    return model.world.box_size if model.world.boundary == "periodic_box" else None


def compare_perception(model, state):
    """probe.perceived == reference.perceive for every boid; returns the reference results."""
    box = reference_box(model)
    results = []
    for i in range(state.n):
        ref = reference.perceive(i, state.pos, state.fwd, state.side, model, box)
        got = perceived(model, state, i)
        assert got["idx"].tolist() == ref["visible"], f"boid {i}: neighbour set"
        for j, off in zip(got["idx"], got["offset"]):
            np.testing.assert_allclose(off, reference.offset(state.pos[i], state.pos[j], box), rtol=RTOL,
                                       atol=ATOL)
        for j, mask in zip(got["idx"], got["mask"]):
            expected = sum(bit for rule, bit in RULE_BITS.items() if j in ref[rule])
            assert mask == expected, f"boid {i}, neighbour {j}: rule mask"
        if model.perception.kind == "binocular":
            assert got["label"].tolist() == [ref["labels"][j] for j in ref["visible"]], f"boid {i}: eye labels"
        else:
            assert not got["label"].any()
        results.append(ref)
    return results


def clamped_boids(model, state, sets):
    """How many boids get their steering force turned by the low-speed cone clamp (synchronous view)."""
    slow = 0.2 * model.vehicle.max_speed
    count = 0
    for i in range(state.n):
        speed = np.linalg.norm(state.vel[i])
        force = reference.steering_force(i, sets[i], state.pos, state.fwd, state.pattern, model,
                                         reference_box(model))
        magnitude = np.linalg.norm(force)
        if speed <= slow and magnitude > 0:
            cosine = 1.0 - 2.0 * (speed / slow) ** 20
            count += int(force @ state.fwd[i] / magnitude < cosine)
    return count


def wrapped_boids(before, after):
    """Boids that jumped across the world boundary in one step (a jump far longer than max_speed * dt)."""
    jump = np.linalg.norm(after.pos - before.pos, axis=1)
    return int(np.sum(jump > 1.0))


@pytest.mark.parametrize("seed, kwargs, dt",
                         [pytest.param(seed, kw, dt, id=name) for seed, (name, kw, dt) in enumerate(CASES)])
@pytest.mark.slow
def test_kernel_matches_reference_step_by_step(seed, kwargs, dt):
    model = build_model(kwargs)
    state = build_state(model, seed)
    neighbours = hidden = clamped = wrapped = 0
    for k in range(N_STEPS):
        sets = compare_perception(model, state)
        neighbours += sum(len(s["visible"]) for s in sets)
        hidden += sum(len(s["hidden"]) for s in sets)
        if model.world.update_order == "synchronous":
            clamped += clamped_boids(model, state, sets)

        obs, ref = reference.kernel_step_agrees(model, state, dt, k, RTOL)
        wrapped += wrapped_boids(state, obs.final)
        state = obs.final

    # the comparison was meaningful
    assert neighbours / (N_STEPS * N_BOIDS) >= 3.0, "too few neighbours for a meaningful comparison"
    if model.perception.kind == "binocular" and model.perception.occlusion:
        assert hidden > 0, "occlusion never hid a boid"
    if model.perception.search == "grid":
        assert perceived(model, build_state(model, seed), 0)["grid"], "the grid was not used"
    if model.world.update_order == "synchronous":
        assert clamped > 0, "the low-speed cone clamp never acted"
    if model.world.boundary != "open":
        assert wrapped > 0, "no boid crossed the world boundary"


def test_update_orders_give_different_steps():
    """The two update orders really differ on a flock state (so both reference branches are exercised)."""
    state = flock_state(5, N_BOIDS)
    sync = advance(make_model("opensteer"), state, 1, 1 / 60).final
    seq = advance(make_model("opensteer", order="sequential"), state, 1, 1 / 60).final
    assert not np.allclose(sync.pos, seq.pos, rtol=0, atol=1e-9)
    # boid 0 moves first in the sequential order, so it sees exactly what the synchronous order sees
    np.testing.assert_array_equal(sync.pos[0], seq.pos[0])


def test_pattern_separation_options_give_different_steps():
    """The three separation_weight options change the dynamics (the pattern cases test distinct code)."""
    state = flock_state(6, N_BOIDS)
    finals = [advance(make_model("opensteer", patterns=w), state, 1, 1 / 60).final.acc
              for w in ("similarity", "dissimilarity", "uniform")]
    assert not np.allclose(finals[0], finals[1])
    assert not np.allclose(finals[0], finals[2])
    assert not np.allclose(finals[1], finals[2])
