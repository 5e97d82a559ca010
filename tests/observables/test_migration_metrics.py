"""Migratory progress and efficiency (observables.migration): analytic cases, the numpy twin, and
when summarize_run adds them (a reynolds87 model with a migratory urge in an open world only)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import reference_metrics as ref
from flocksweep.observables.migration import migration_metrics
from flocksweep.observables.summary import MetricSettings, summarize_run, summary_columns
from flocksweep.simcore import InitParams, simulate
from flocksweep.simcore.params import ModelParams, Perception, World
from flocksweep.simcore.reynolds_params import Reynolds


def straight_flight(direction, speed=2.0, n=5, records=11, dt=0.5):
    """Boids translating rigidly with velocity speed * direction (unit): progress = speed along it."""
    rng = np.random.default_rng(0)
    start = rng.normal(size=(n, 3))
    times = np.arange(records) * dt
    vel = np.broadcast_to(speed * np.asarray(direction), (records, n, 3)).copy()
    pos = start[None] + times[:, None, None] * vel
    return pos, vel, times


def test_rigid_flight_along_and_across():
    g = np.array([0.0, 0.6, 0.8])
    pos, vel, times = straight_flight(g)
    out = migration_metrics(pos, vel, times, g, warmup=1.0)
    assert out["migratory_progress"] == pytest.approx(2.0, rel=1e-12)
    assert out["migratory_efficiency"] == pytest.approx(1.0, rel=1e-12)
    across = migration_metrics(pos, vel, times, (1.0, 0.0, 0.0), warmup=0.0)
    assert abs(across["migratory_progress"]) < 1e-12
    back = migration_metrics(pos, vel, times, -g, warmup=0.0)
    assert back["migratory_efficiency"] == pytest.approx(-1.0, rel=1e-12)


def test_window_too_short_is_nan():
    pos, vel, times = straight_flight((1.0, 0.0, 0.0))
    out = migration_metrics(pos, vel, times, (1.0, 0.0, 0.0), warmup=4.6)  # only the record at 5.0
    assert np.isnan(out["migratory_progress"]) and np.isnan(out["migratory_efficiency"])


def test_matches_twin_on_random_records():
    rng = np.random.default_rng(3)
    for _ in range(20):
        pos = rng.normal(size=(9, 7, 3)) * 5
        vel = rng.normal(size=(9, 7, 3))
        times = np.arange(9) * 0.25
        g = rng.normal(size=3)
        g /= np.linalg.norm(g)
        warmup = float(rng.uniform(0, 1.5))
        ours, twin = migration_metrics(pos, vel, times, g, warmup), ref.migration_metrics(pos, vel, times, g, warmup)
        for key in twin:
            assert ours[key] == pytest.approx(twin[key], rel=1e-12, abs=1e-12)


def reynolds(boundary="open", weight=3.0):
    return ModelParams(name="r", dynamics="reynolds87", perception=Perception(kind="sphere", radius=10.0),
                       world=World(boundary=boundary),
                       reynolds=Reynolds(migration_weight=weight, migration_direction=(0.0, 0.0, 2.0)))


def test_summary_has_them_only_with_a_migratory_urge_in_an_open_world():
    assert MetricSettings().resolve(reynolds()).migration == (0.0, 0.0, 1.0)
    assert MetricSettings().resolve(reynolds(weight=0.0)).migration is None
    assert MetricSettings().resolve(reynolds(boundary="sphere_wrap")).migration is None
    assert MetricSettings().resolve(ModelParams()).migration is None
    assert summary_columns(True, True)[-2:] == ("migratory_progress", "migratory_efficiency")
    assert "migratory_progress" not in summary_columns(True)


def test_summarize_run_of_a_migrating_flock():
    model = reynolds()
    obs = simulate(model, InitParams(n=30, radius=5.0, speed=3.0), 2, 6.0, 1 / 60, 30)
    settings = MetricSettings(warmup=2.0).resolve(model)
    row = summarize_run(obs, settings)
    twin = ref.migration_metrics(obs.pos, obs.vel, obs.times, (0.0, 0.0, 1.0), 2.0)
    assert row["migratory_progress"] == pytest.approx(twin["migratory_progress"], rel=1e-12)
    assert row["migratory_progress"] > 1.0                  # the urge moves the flock along +z
    plain = summarize_run(obs, dataclasses.replace(settings, migration=None))
    assert "migratory_progress" not in plain
