"""Metrics of flocks in the plane z = 0 (2-D runs, ``world.dimensions = 2``): milling is the angular
momentum about +z, groups and spacing are the same formulas, and a 2-D run's summary row has them.

Planted flocks: a rigid ring rotating in the plane mills at exactly 1 (up to rounding) with polarization 0;
the same ring translating mills at 0; two rings far apart are two groups. Then a 2-D Couzin torus (the
preset's values in the plane, 100 s, means over the last 50 s) is measured through ``summarize_run`` as a
sweep worker does.
"""
from __future__ import annotations

import numpy as np

from flocksweep.observables.metrics import frame_metrics
from flocksweep.observables.summary import MetricSettings, summarize_run
from flocksweep.simcore import load_preset, simulate_preset
from paths import ROOT


def ring(n=24, radius=5.0, centre=(0.0, 0.0), speed=2.0, rotating=True):
    angle = 2 * np.pi * np.arange(n) / n
    pos = np.stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle), np.zeros(n)], axis=1)
    if rotating:
        vel = speed * np.stack([-np.sin(angle), np.cos(angle), np.zeros(n)], axis=1)
    else:
        vel = np.tile([speed, 0.0, 0.0], (n, 1))
    return pos, vel


def test_planted_planar_mill_translation_and_two_groups():
    pos, vel = ring()
    m = frame_metrics(pos[None], vel[None], None, None, None, group_radius=2.0)
    assert abs(m["milling"][0] - 1.0) < 1e-12 and m["polarization"][0] < 1e-12 and m["n_groups"][0] == 1
    pos, vel = ring(rotating=False)
    m = frame_metrics(pos[None], vel[None], None, None, None, group_radius=2.0)
    assert m["milling"][0] < 1e-12 and abs(m["polarization"][0] - 1.0) < 1e-12
    a, b = ring(centre=(-20.0, 0.0)), ring(centre=(20.0, 0.0), rotating=False)
    m = frame_metrics(np.concatenate([a[0], b[0]])[None], np.concatenate([a[1], b[1]])[None], None, None, None,
                      group_radius=2.0)
    assert m["n_groups"][0] == 2 and abs(m["nn_distance"][0] - 2 * 5.0 * np.sin(np.pi / 24)) < 1e-12


def test_a_planar_couzin_torus_reports_milling_and_groups():
    preset = load_preset(ROOT / "configs/models/couzin2002_torus.toml", ["world.dimensions=2", "run.duration=100"])
    obs = simulate_preset(preset, 3)
    assert np.all(obs.pos[:, :, 2] == 0.0)
    row = summarize_run(obs, MetricSettings(warmup=50.0).resolve(preset.model))
    assert row["milling_mean"] > 0.6 and row["polarization_mean"] < 0.3
    assert row["n_groups_final"] == 1 and 0.5 < row["nn_distance_mean"] < 2.0
    assert MetricSettings().resolve(preset.model).group_radius == 1.0 + 1.0 + 14.0   # the zones' outer edge
