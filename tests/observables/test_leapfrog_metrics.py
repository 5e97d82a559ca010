"""The leapfrog metrics, on hand-worked cases: ``overtake_rate`` (overtakes along the group's heading per
boid per second between consecutive records) and ``elongation_heading`` (RMS extent along the heading
over the largest RMS extent across it). Definitions in docs/metrics.md; the numpy twins are compared in
test_twins.py."""
from __future__ import annotations

import math

import numpy as np
import pytest

from flocksweep.observables.metrics import (aspect_heading, elongation_heading, frame_metrics, group_shape,
                                          overtake_rate)
from flocksweep.observables.summary import MetricSettings, summarize_run, summary_columns
from flocksweep.simcore import load_preset, simulate_preset
from paths import ROOT

PLUS_X = np.array([1.0, 0.0, 0.0])


def records(*frames):
    return np.array(frames, dtype=np.float64)


def test_a_single_overtake_counts_once_per_boid_per_second():
    # A (boid 0) starts 1 behind B along the heading +x and ends 0.5 ahead of it; both stay linked
    pos = records([[0.0, 0, 0], [1.0, 0, 0]], [[2.0, 0.2, 0], [1.5, 0, 0]])
    vel = records([[4.0, 0, 0], [1.0, 0, 0]], [[4.0, 0, 0], [1.0, 0, 0]])
    rate = overtake_rate(pos, vel, group_radius=3.0, record_interval=0.5)
    assert math.isnan(rate[0])                       # no record before the first
    assert rate[1] == 1 / 2 / 0.5                    # one swap, 2 boids, half a second
    # a third boid far away counts in the per-boid denominator only
    far = np.array([[50.0, 0, 0]])
    rate3 = overtake_rate(np.concatenate([pos, np.stack([far, far])], axis=1),
                          np.concatenate([vel, np.tile(PLUS_X, (2, 1, 1))], axis=1), 3.0, 0.5)
    assert rate3[1] == 1 / 3 / 0.5


def test_a_rigid_translation_has_no_overtakes():
    rng = np.random.default_rng(11)
    start = rng.uniform(-3, 3, (15, 3))
    velocity = np.array([1.5, -0.4, 0.7])
    times = np.arange(8) * 0.25
    pos = start[None] + times[:, None, None] * velocity
    vel = np.broadcast_to(velocity, pos.shape).copy()
    rate = overtake_rate(pos, vel, 4.0, 0.25)
    assert math.isnan(rate[0]) and (rate[1:] == 0).all()
    # the same flock wrapped into a periodic box on its way: still none
    box = 9.0
    wrapped = pos + np.array([4.0, 0, 0])
    wrapped = wrapped - box * np.floor(wrapped / box + 0.5)
    assert (overtake_rate(wrapped, vel, 4.0, 0.25, box)[1:] == 0).all()


def test_a_pass_between_boids_that_were_not_linked_is_not_an_overtake():
    # A closes in from far behind and passes B: linked only at the second record
    pos = records([[-10.0, 0, 0], [1.0, 0, 0]], [[2.0, 0, 0], [1.5, 0, 0]])
    vel = np.tile(PLUS_X, (2, 2, 1))
    assert overtake_rate(pos, vel, 3.0, 1.0)[1] == 0.0
    # ... and a pair side by side that drifts apart across the heading never swaps order along it
    pos = records([[0.0, 0, 0], [0.5, 1, 0]], [[1.0, 0, 0], [1.5, 2, 0]])
    assert overtake_rate(pos, vel, 3.0, 1.0)[1] == 0.0


def test_an_overtake_across_the_periodic_boundary():
    box = 20.0
    # B sits just across the +x face (x = -9.5 is 1 ahead of A at 9.5 by minimum image); A then passes it
    pos = records([[9.5, 0, 0], [-9.5, 0, 0]], [[-9.0, 0, 0], [-9.2, 0, 0]])
    vel = np.tile(PLUS_X, (2, 2, 1))
    assert overtake_rate(pos, vel, 3.0, 1.0, box)[1] == 0.5
    assert overtake_rate(pos, vel, 3.0, 1.0)[1] == 0.0    # in open space they are 19 apart: no link


def test_overtakes_need_the_record_spacing_and_a_heading():
    pos = records([[0.0, 0, 0], [1.0, 0, 0]], [[2.0, 0, 0], [1.5, 0, 0]])
    vel = np.tile(PLUS_X, (2, 2, 1))
    assert np.isnan(frame_metrics(pos, vel, None, None, None, 3.0)["overtake_rate"]).all()
    assert overtake_rate(pos, np.zeros_like(vel), 3.0, 1.0)[1] == 0.0      # nobody moves: no heading, no swap
    with pytest.raises(ValueError, match="record_interval"):
        frame_metrics(pos, vel, None, None, None, 3.0, record_interval=0.0)
    with pytest.raises(ValueError, match="consecutive records"):
        overtake_rate(pos[0], vel[0], 3.0, 1.0)


def test_elongation_heading_of_exact_point_sets():
    # G = diag(3, 1/3, 1/12): the RMS extents along x, y, z are sqrt(3), sqrt(1/3), sqrt(1/12)
    star = np.array([[3.0, 0, 0], [-3, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 0.5], [0, 0, -0.5]])
    for heading, expected in (((1, 0, 0), 3.0), ((0, 1, 0), 1 / 3), ((0, 0, 1), 1 / 6)):
        vel = np.tile(heading, (6, 1)).astype(float) * np.linspace(1, 2, 6)[:, None]
        assert math.isclose(float(elongation_heading(star, vel)), expected, rel_tol=1e-12)


def test_one_straggler_moves_elongation_heading_far_less_than_the_aspect():
    # 100 boids in single file (x = 0..99, y = +-1) and one straggler 6 to the side: the range across
    # the heading grows from 2 to 7, the second moment across it only by about 36 / 101
    line = np.column_stack([np.arange(100.0), np.tile([1.0, -1.0], 50), np.zeros(100)])
    vel = np.tile(PLUS_X, (101, 1))
    with_straggler = np.vstack([line, [[49.5, 6.0, 0.0]]])
    before = group_shape(line, vel[:100])
    after = group_shape(with_straggler, vel)
    assert math.isclose(before["aspect_heading"] / after["aspect_heading"], 3.5, rel_tol=0.02)
    assert before["elongation_heading"] / after["elongation_heading"] < 1.2


def test_elongation_heading_nan_rules():
    two = np.array([[0.0, 0, 0], [1, 0, 0]])
    assert math.isnan(float(elongation_heading(two, np.tile(PLUS_X, (2, 1)))))       # fewer than 3 boids
    file = np.outer(np.arange(5.0), [1, 0, 0])
    assert math.isnan(float(elongation_heading(file, np.tile(PLUS_X, (5, 1)))))      # nothing across
    triangle = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert math.isnan(float(elongation_heading(triangle, np.zeros((3, 3)))))         # no heading
    assert math.isfinite(float(aspect_heading(triangle, np.tile(PLUS_X, (3, 1)))))


def test_leapfrog_metrics_are_summary_columns_of_a_real_run():
    preset = load_preset(ROOT / "configs/models/holland.toml",
                         ["init.n=30", "run.duration=6", "perception.field_deg=60", "perception.direction_deg=0"])
    obs = simulate_preset(preset, seed=4)
    row = summarize_run(obs, MetricSettings(warmup=1.0).resolve(preset.model))
    columns = summary_columns(leadership=False)
    for name in ("overtake_rate_mean", "overtake_rate_final", "elongation_heading_mean", "elongation_heading_final"):
        assert name in columns and name in row
    assert row["overtake_rate_mean"] >= 0 and math.isfinite(row["overtake_rate_mean"])
    # every swap is a pair of boids: at most N (N - 1) / 2 per record interval, per boid per second
    assert row["overtake_rate_mean"] <= (30 - 1) / 2 / preset.run.record_interval
