"""The compiled analysis kernels and ``simcore.rng.hash4`` against their plain numpy twins
(tests/reference_metrics.py) on random flocks: open and periodic worlds, stopped boids, several groups.

Floating-point results agree to a relative 1e-9 (the twins sum and decompose in another order; the
aspect ratio's major axis comes from an eigenvector there and from an angle formula in the kernel);
the hash is integer arithmetic and agrees exactly."""
from __future__ import annotations

import numpy as np
import pytest

import reference_metrics as ref
from flocksweep.observables import kernels
from flocksweep.observables.leadership import follow_curve, leadership_metrics
from flocksweep.observables.metrics import frame_metrics, milling, segregation
from flocksweep.simcore.rng import hash4, uniform01

RTOL, ATOL = 1e-9, 1e-12
CASES = [(seed, box) for seed in range(6) for box in (None, 30.0)]


def flock(seed: int, n: int = 24, spread: float = 12.0, stopped: int = 2):
    """Positions in a few clumps, velocities around a common heading, ``stopped`` boids at rest, patterns."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-spread, spread, (3, 3))
    pos = centres[rng.integers(0, 3, n)] + rng.normal(0, 2.0, (n, 3))
    vel = np.array([1.0, 0.3, -0.2]) + rng.normal(0, 0.6, (n, 3))
    vel[rng.choice(n, stopped, replace=False)] = 0.0
    pattern = rng.integers(0, 3, n).astype(np.uint32)
    return pos, vel, pattern


def close(a, b) -> bool:
    return bool(np.allclose(a, b, rtol=RTOL, atol=ATOL, equal_nan=True))


@pytest.mark.parametrize("seed, box", CASES)
def test_milling_and_segregation_match_their_twins(seed, box):
    pos, vel, pattern = flock(seed)
    if box is not None:
        pos = pos % box
    assert close(milling(pos, vel, box), ref.milling(pos, vel, box))
    for radius in (2.0, 4.0, 9.0):
        assert close(segregation(pos, pattern, radius, box), ref.segregation(pos, pattern, radius, box))


@pytest.mark.parametrize("seed", range(8))
def test_shape_matches_its_twin_for_any_selection(seed):
    pos, vel, _ = flock(seed)
    rng = np.random.default_rng(100 + seed)
    for mask in (np.ones(len(pos), bool), rng.random(len(pos)) < 0.5, np.arange(len(pos)) < 2):
        got = kernels.shape_frame(np.ascontiguousarray(pos), np.ascontiguousarray(vel), mask)
        assert close(got, ref.shape(pos, vel, mask)), (got, ref.shape(pos, vel, mask))


def test_shape_edge_cases_match_their_twin():
    pos, vel, _ = flock(3, n=6)
    still = np.zeros_like(vel)
    line = np.column_stack([np.arange(6.0), np.zeros(6), np.zeros(6)])
    for points, v in ((pos, still), (line, vel), (line, np.tile([1.0, 0, 0], (6, 1)))):
        for mask in (np.ones(6, bool), np.zeros(6, bool)):
            assert close(kernels.shape_frame(points, v, mask), ref.shape(points, v, mask))


@pytest.mark.parametrize("seed, box", [(s, None) for s in range(4)])
def test_frame_kernel_columns_match_the_twins(seed, box):
    """Open world: the largest group's layout is the positions themselves."""
    records = [flock(seed * 10 + r) for r in range(3)]
    pos = np.stack([p for p, _, _ in records])
    vel = np.stack([v for _, v, _ in records])
    pattern = records[0][2]
    radius = 4.0
    series = frame_metrics(pos, vel, None, None, pattern, radius, box)
    for r in range(len(pos)):
        largest = ref.components(pos[r], radius, box) == 0
        gyration, elongation, aspect, stretched = ref.shape(pos[r], vel[r], largest)
        assert close(series["gyration_radius"][r], gyration)
        assert close(series["elongation"][r], elongation)
        assert close(series["aspect_heading"][r], aspect)
        assert close(series["elongation_heading"][r], stretched)
        assert close(series["cohesion"][r], largest.mean())
        assert close(series["milling"][r], ref.milling(pos[r], vel[r], box))
        assert close(series["segregation"][r], ref.segregation(pos[r], pattern, radius, box))


def run_with_triggers(seed: int, records: int = 40, n: int = 10, events: int = 6):
    """A synthetic run: a drifting flock whose headings wander, and trigger events at random steps."""
    rng = np.random.default_rng(seed)
    dt, every = 0.05, 2
    heading = np.cumsum(rng.normal(0, 0.3, (records, n, 3)), axis=0) + np.array([2.0, 0, 0])
    vel = heading + rng.normal(0, 0.1, (records, n, 3))
    vel[rng.random((records, n)) < 0.03] = 0.0                     # a few stopped records
    pos = np.cumsum(vel * dt * every, axis=0) + rng.normal(0, 1.5, (1, n, 3))
    times = np.arange(records) * dt * every
    steps = np.sort(rng.integers(0, records * every, events))
    triggers = np.column_stack([steps, rng.integers(0, n, events)])
    inputs = {"times": times, "pos": pos, "vel": vel, "leader": np.zeros((records, n), bool),
              "triggers": triggers, "dt": dt, "record_every": every}
    return inputs


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("escape, max_lag", [(0.6, 0.5), (1.0, 2.0)])
def test_follow_correlation_matches_its_twin(seed, escape, max_lag):
    inputs = run_with_triggers(seed)
    radius = 3.0
    curve, before = ref.follow(inputs["times"], inputs["vel"], inputs["pos"], inputs["triggers"], inputs["dt"],
                               inputs["record_every"], radius, escape, None, max_lag)
    got = follow_curve(inputs, radius, escape, None, max_lag)
    assert np.isfinite(curve).any()
    assert close(got["corr"].to_numpy(), curve)
    metrics = leadership_metrics(inputs, radius, escape, None, max_lag)
    assert close(metrics["follow_corr_lag0"], curve[0])
    assert close(metrics["follow_corr_before"], before)


def test_hash4_matches_its_integer_twin_exactly():
    rng = np.random.default_rng(7)
    words = rng.integers(0, 2 ** 63, (500, 4), dtype=np.int64).astype(np.uint64)
    words[:5] = [[0, 0, 0, 0], [2 ** 64 - 1, 0, 1, 2], [1, 2 ** 64 - 1, 3, 2 ** 63], [5, 1, 0, 0], [5, 1, 0, 1]]
    for key, stream, step, index in words:
        expect = ref.hash4(int(key), int(stream), int(step), int(index))
        assert int(hash4(key, stream, step, index)) == expect
        assert uniform01(key, stream, step, index) == ref.uniform01(int(key), int(stream), int(step), int(index))


def passing_flock(seed: int, records: int = 12, n: int = 14):
    """Boids flying roughly +x at their own, wandering speeds, so neighbours pass each other; a few
    stopped records."""
    rng = np.random.default_rng(seed)
    speed = rng.uniform(1.0, 3.0, (1, n)) + rng.normal(0, 0.8, (records, n))
    vel = np.zeros((records, n, 3))
    vel[..., 0] = speed
    vel[..., 1:] = rng.normal(0, 0.4, (records, n, 2))
    vel[rng.random((records, n)) < 0.04] = 0.0
    pos = rng.uniform(-4, 4, (1, n, 3)) + np.cumsum(vel, axis=0) * 0.5
    return pos, vel


@pytest.mark.parametrize("seed, box", [(s, b) for s in range(4) for b in (None, 12.0)])
def test_overtake_rate_matches_its_twin(seed, box):
    pos, vel = passing_flock(seed)
    if box is not None:
        pos = pos % box
    for radius in (2.5, 5.0):
        got = frame_metrics(pos, vel, None, None, None, radius, box, record_interval=0.5)["overtake_rate"]
        want = ref.overtakes(pos, vel, radius, 0.5, box)
        assert close(got, want), (got, want)
    assert np.nansum(want) > 0                     # the case does test swaps
