"""Obstacle, predator and prey metrics (observables.encounters, docs/metrics.md) on hand-built
observations with values worked out by hand, against the numpy twins of tests/reference_metrics.py,
and in the run row (only when the run has obstacles, a predator or prey)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import reference_metrics as ref
from flocksweep.observables.encounters import (PREDATOR_SCALARS, PREDATOR_SERIES, encounter_columns,
                                             obstacle_metrics, predator_metrics, prey_metrics, remerge_time)
from flocksweep.observables.metrics import METRIC_NAMES
from flocksweep.observables.summary import (ENCOUNTER_FAMILIES, MetricSettings, encounter_settings, every_nth,
                                          measure_run, summary_columns)
from flocksweep.simcore.obstacle_spec import Obstacle
from flocksweep.simcore.schema import ConfigError
from flocksweep.simcore.simulate import Observations

SPHERE = Obstacle(kind="sphere", centre=(0.0, 0.0, 0.0), radius=2.0)
GROUND = Obstacle(kind="plane", centre=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0))


def observations(pos, predator=None, prey=None, interval: float = 1.0) -> Observations:
    pos = np.asarray(pos, dtype=np.float64)
    n_records, n = pos.shape[:2]
    vel = np.zeros_like(pos)
    vel[..., 0] = 1.0
    blank = np.zeros((n_records, n), np.int32)
    return Observations(times=np.arange(n_records) * interval, pos=pos, vel=vel, visible=blank, binocular=blank,
                        leader=blank.astype(bool), triggers=np.zeros((0, 2), np.int64),
                        pattern=np.zeros(n, np.uint32), final=None, dt=interval, record_every=1,
                        predator=None if predator is None else np.asarray(predator, dtype=np.float64),
                        prey=None if prey is None else np.asarray(prey, dtype=np.float64))


def settings(warmup: float = 0.0, group_radius: float = 3.0, obstacles=(), **keys) -> MetricSettings:
    """Resolved settings without a model: body radius 0.5, open world."""
    return MetricSettings(warmup=warmup, group_radius=group_radius, escape_duration=1.0, obstacles=tuple(obstacles),
                          body_radius=0.5, **keys)


# ------------------------------------------------------------------------------------------ obstacles

def passing_flock() -> np.ndarray:
    """Four boids flying along x at 2 units/s past a sphere of radius 2 at the origin (x = 0 at t = 5),
    at heights y = 0 (straight through), 2.3 (grazes: overlaps only at x = 0), 3 (clears by 0.5) and
    2.5 (touches at x = 0: clearance 0, no overlap)."""
    x = -10.0 + 2.0 * np.arange(11)
    heights = np.array([0.0, 2.3, 3.0, 2.5])
    pos = np.zeros((11, 4, 3))
    pos[:, :, 0] = x[:, None]
    pos[:, :, 1] = heights[None, :]
    return pos


def test_a_flock_passing_a_sphere_collides_as_worked_out_by_hand():
    pos = passing_flock()
    series, scalars = obstacle_metrics(pos, np.arange(11.0), (SPHERE,), 0.5, warmup=0.0)
    # boid 0 overlaps while |x| < 2.5 (x = -2, 0, 2: t = 4, 5, 6); boid 1 while x^2 < 2.5^2 - 2.3^2 (t = 5)
    expected = np.zeros(11)
    expected[[4, 5, 6]] = [1, 2, 1]
    np.testing.assert_array_equal(series["collisions"], expected)
    np.testing.assert_array_equal(series["collision_fraction"], expected / 4)
    assert series["clearance"][5] == -2.5                       # boid 0 at the centre: 0 - 2 - 0.5
    assert series["clearance"][0] == pytest.approx(math.hypot(10.0, 0.0) - 2.5)
    assert scalars == {"collided_boids": 2.0, "collision_events": 2.0, "clearance_min": -2.5}
    # the touching boid (clearance exactly 0 at t = 5) is not a collision
    touching, _ = obstacle_metrics(pos[:, 3:], np.arange(11.0), (SPHERE,), 0.5, warmup=0.0)
    assert touching["clearance"][5] == 0.0 and touching["collisions"].sum() == 0


def test_obstacle_scalars_count_only_records_from_the_warmup():
    pos = passing_flock()
    _, from_5 = obstacle_metrics(pos, np.arange(11.0), (SPHERE,), 0.5, warmup=4.5)
    assert from_5 == {"collided_boids": 2.0, "collision_events": 2.0, "clearance_min": -2.5}  # boid 0 counts at t = 5
    _, from_6 = obstacle_metrics(pos, np.arange(11.0), (SPHERE,), 0.5, warmup=5.5)
    assert from_6 == {"collided_boids": 1.0, "collision_events": 1.0, "clearance_min": -0.5}  # x = 2: 2 - 2.5


def test_a_boid_dipping_into_the_ground_twice_is_two_collision_events_of_one_boid():
    pos = np.zeros((5, 2, 3))
    pos[:, 0, 2] = [1.0, 0.2, 1.0, 0.2, 0.2]     # under the body radius at t = 1, 3, 4
    pos[:, 1, 2] = 5.0
    series, scalars = obstacle_metrics(pos, np.arange(5.0), (GROUND,), 0.5, warmup=0.0)
    np.testing.assert_array_equal(series["collisions"], [0, 1, 0, 1, 1])
    assert scalars["collided_boids"] == 1.0 and scalars["collision_events"] == 2.0
    assert scalars["clearance_min"] == pytest.approx(0.2 - 0.5)


def test_obstacle_metrics_match_the_numpy_twin_for_every_kind():
    rng = np.random.default_rng(13)
    obstacles = (SPHERE, GROUND.__class__(kind="plane", centre=(0, 0, -3), normal=(0.2, 0.1, 1.0)),
                 Obstacle(kind="box", centre=(4, 1, 0), half_extents=(1, 2, 0.5)),
                 Obstacle(kind="cylinder", centre=(-3, 2, 1), axis=(1, 1, 0), radius=1.0, length=3.0))
    pos = rng.uniform(-6, 6, size=(7, 30, 3))
    times = np.arange(7.0)
    got_series, got = obstacle_metrics(pos, times, obstacles, 0.5, warmup=2.0)
    want_series, want = ref.obstacle_metrics(pos, times, obstacles, 0.5, warmup=2.0)
    assert got["collided_boids"] > 0 and got["collision_events"] >= got["collided_boids"]
    for name, values in want_series.items():
        np.testing.assert_allclose(got_series[name], values, rtol=0, atol=1e-9, err_msg=name)
    assert got.keys() == want.keys()
    for name in want:
        assert got[name] == pytest.approx(want[name], abs=1e-9), name


# ------------------------------------------------------------------------------------------- predator

LATTICE = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
# the lattice split in two squares of side 2, 20 apart along x
SPLIT = np.column_stack([np.where(LATTICE[:, 0] < 0, -10.0, 10.0), 2 * LATTICE[:, 1], 2 * LATTICE[:, 2]])
FAR = np.array([100.0, 0.0, 0.0])


def predator_pass():
    """A 2 x 2 x 2 lattice (spacing 1) until t = 4; the predator at its centre at t = 5, 6, 7 splits it
    into two squares (spacing 2) 20 apart; the predator is gone at t = 8 (still split); the lattice is
    whole again at t = 9, 10."""
    pos = np.array([SPLIT if 5 <= t <= 8 else LATTICE for t in range(11)])
    predator = np.array([np.zeros(3) if 5 <= t <= 7 else FAR for t in range(11)])
    return pos, predator


def test_a_predator_through_a_ball_of_boids_expands_and_splits_it_as_worked_out_by_hand():
    pos, predator = predator_pass()
    run = measure_run(observations(pos, predator=predator), settings())
    np.testing.assert_array_equal(run.series["predator_near"], [0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 0])
    assert run.series["predator_distance"][5] == pytest.approx(math.sqrt(102.0))   # corner (+-10, +-1, +-1)
    assert run.series["predator_distance"][0] == pytest.approx(math.sqrt(99.5 ** 2 + 0.5))
    assert run.series["flock_gyration_radius"][0] == pytest.approx(math.sqrt(0.75))
    assert run.series["flock_gyration_radius"][6] == pytest.approx(math.sqrt(102.0))
    row = run.row
    assert row["flash_nn_ratio"] == pytest.approx(2.0)                    # NND 1 before, 2 while near
    assert row["flash_gyration_ratio"] == pytest.approx(math.sqrt(102.0 / 0.75))
    assert (row["groups_before_predator"], row["groups_near_predator"], row["groups_near_predator_max"]) == (1, 2, 2)
    assert row["remerge_time"] == 1.0                                      # leaves at t = 8, whole at t = 9
    assert row["predator_captures"] == 0.0
    assert row["predator_distance_min"] == pytest.approx(math.sqrt(102.0))
    assert row["predator_near_mean"] == pytest.approx(3 / 11)


def test_flash_expansion_is_measured_against_the_records_before_the_predator_first_came():
    pos, predator = predator_pass()
    pos[9:] = SPLIT                        # never whole again: no re-merge
    row = measure_run(observations(pos, predator=predator), settings(warmup=2.0)).row
    assert math.isnan(row["remerge_time"])
    assert row["groups_before_predator"] == 1.0 and row["flash_nn_ratio"] == pytest.approx(2.0)
    # a predator that is near from the start has no "before": the ratios are nan
    predator[:] = 0.0
    row = measure_run(observations(pos, predator=predator), settings()).row
    assert math.isnan(row["flash_nn_ratio"]) and math.isnan(row["groups_before_predator"])
    assert math.isnan(row["remerge_time"])          # it never leaves


def test_remerge_time_counts_from_the_first_departure():
    times = np.arange(8.0)
    near = np.array([0, 1, 1, 0, 1, 0, 0, 0], bool)
    assert remerge_time(times, near, np.array([1, 2, 3, 3, 2, 2, 1, 1])) == 3.0   # left at t = 3, whole at t = 6
    assert remerge_time(times, near, np.array([1, 2, 3, 1, 2, 2, 1, 1])) == 0.0   # whole as it leaves
    assert math.isnan(remerge_time(times, np.zeros(8, bool), np.ones(8)))


def test_captures_count_distinct_boids_within_the_capture_radius():
    boids = np.array([[0.0, 0, 0], [5.0, 0, 0], [10.0, 0, 0]])
    pos = np.repeat(boids[None], 4, axis=0)
    predator = np.array([[0, 0.5, 0], [5, 0.5, 0], [20, 0, 0], [0, 0.5, 0]])   # boid 0 twice, boid 1 once
    run = measure_run(observations(pos, predator=predator), settings(capture_radius=0.6))
    np.testing.assert_array_equal(run.series["predator_in_capture"], [1, 1, 0, 1])
    assert run.row["predator_captures"] == 2.0
    assert measure_run(observations(pos, predator=predator), settings(capture_radius=0.4)).row["predator_captures"] == 0


def test_a_predator_that_appears_later_is_measured_only_while_present():
    """The simulator records the predator as NaN until it appears: its nearest approach is over the
    records where it is present, and no record before counts as near or as a capture."""
    boids = np.array([[0.0, 0, 0], [5.0, 0, 0], [10.0, 0, 0]])
    pos = np.repeat(boids[None], 4, axis=0)
    predator = np.array([[np.nan] * 3, [np.nan] * 3, [5, 3, 0], [5, 2, 0]])
    run = measure_run(observations(pos, predator=predator), settings(capture_radius=0.6, predator_near=100.0))
    assert run.row["predator_distance_min"] == 2.0
    np.testing.assert_array_equal(run.series["predator_near"], [0, 0, 1, 1])
    assert run.row["predator_captures"] == 0
    never = measure_run(observations(pos, predator=np.full((4, 3), np.nan)), settings())
    assert math.isnan(never.row["predator_distance_min"])


def test_predator_metrics_match_the_numpy_twin_in_an_open_world_and_a_periodic_box():
    rng = np.random.default_rng(7)
    n_records, n = 9, 12
    pos = rng.normal(0, 3, size=(n_records, n, 3)) + np.linspace(0, 4, n_records)[:, None, None]
    predator = rng.normal(0, 6, size=(n_records, 3))
    times = np.arange(n_records) * 0.5
    for box in (None, 20.0):
        obs = observations(pos if box is None else pos % box, predator=predator, interval=0.5)
        s = dataclasses.replace(settings(warmup=1.0, capture_radius=2.5, predator_near=5.0), box=box)
        run = measure_run(obs, s)
        want_series, want = ref.predator_metrics(obs.pos, predator, times, 2.5, 5.0, 3.0, 1.0, box)
        for name in PREDATOR_SERIES:
            np.testing.assert_allclose(run.series[name], want_series[name], rtol=1e-12, atol=1e-12, err_msg=name)
        for name in PREDATOR_SCALARS:
            assert run.row[name] == pytest.approx(want[name], rel=1e-12, nan_ok=True), (box, name)
        assert 0 < run.series["predator_near"].sum() < n_records   # both windows are exercised


# ----------------------------------------------------------------------------------------------- prey

def test_a_flock_flying_to_the_prey_reaches_it_when_worked_out_by_hand():
    t = np.arange(11.0)
    pos = np.zeros((11, 2, 3))
    pos[:, 0, 0] = 2 * t          # the front boid
    pos[:, 1, 0] = 2 * t - 4      # 4 behind: the centre is at 2t - 2
    prey = np.tile([20.0, 0.0, 0.0], (11, 1))
    series, scalars = prey_metrics(pos, prey, t, reach=5.0)
    np.testing.assert_allclose(series["prey_distance"], np.abs(22 - 2 * t))
    np.testing.assert_array_equal(series["prey_within_fraction"], [0] * 8 + [0.5, 0.5, 1.0])
    assert scalars == {"prey_reach_time": 9.0, "prey_first_reach_time": 8.0}   # |22 - 2t| <= 5; |20 - 2t| <= 5
    _, never = prey_metrics(pos, prey, t, reach=0.5)
    assert math.isnan(never["prey_reach_time"]) and never["prey_first_reach_time"] == 10.0


def test_prey_metrics_match_the_numpy_twin():
    rng = np.random.default_rng(3)
    pos = rng.normal(0, 4, size=(10, 15, 3))
    prey = rng.normal(0, 3, size=(10, 3))
    times = np.arange(10.0)
    for box in (None, 12.0):
        p = pos if box is None else pos % box
        got_series, got = prey_metrics(p, prey, times, 4.0, box)
        want_series, want = ref.prey_metrics(p, prey, times, 4.0, box)
        for name in want_series:
            np.testing.assert_allclose(got_series[name], want_series[name], rtol=1e-12, atol=1e-12)
        assert got == pytest.approx(want, nan_ok=True)


# ------------------------------------------------------------------------------------------ in the row

def test_the_row_has_a_family_only_when_the_run_has_it_and_in_the_declared_order():
    pos, predator = predator_pass()
    plain = measure_run(observations(pos), settings())
    assert tuple(plain.row) == summary_columns(leadership=False)
    assert tuple(plain.series) == METRIC_NAMES
    full = measure_run(observations(pos, predator=predator, prey=predator), settings(obstacles=(SPHERE,)))
    assert tuple(full.row) == summary_columns(leadership=False, encounters=ENCOUNTER_FAMILIES)
    assert tuple(full.row)[len(plain.row):] == encounter_columns()
    assert {"collisions", "predator_near", "prey_distance"} <= set(full.series)
    # the shared columns are untouched by the extra families
    assert {k: full.row[k] for k in plain.row} == pytest.approx(plain.row, nan_ok=True)


def test_every_nth_keeps_every_nth_agent_position():
    pos, predator = predator_pass()
    obs = every_nth(observations(pos, predator=predator, prey=predator * 2), 2)
    np.testing.assert_array_equal(obs.predator, predator[::2])
    np.testing.assert_array_equal(obs.prey, 2 * predator[::2])
    assert obs.pos.shape[0] == obs.predator.shape[0] == 6


def test_agent_positions_of_the_wrong_shape_are_an_error_naming_the_field():
    pos, predator = predator_pass()
    with pytest.raises(ValueError, match=r"observations.predator: expected shape \(11, 3\)"):
        measure_run(observations(pos, predator=predator[:5]), settings())


def test_encounter_settings_are_validated_and_only_non_defaults_are_identity():
    for key in ("capture_radius", "predator_near", "prey_reach"):
        with pytest.raises(ConfigError, match=f"{key}: got -1"):
            MetricSettings(**{key: -1.0})
        with pytest.raises(ConfigError, match=f"{key}: got nan"):
            MetricSettings(**{key: float("nan")})
    assert encounter_settings(MetricSettings()) == {}
    assert encounter_settings(MetricSettings(prey_reach=2.0)) == {"prey_reach": 2.0}
