"""Round trips: a simulated run written as long-format tracks and measured back gives exactly the
simulator's own metrics; measured with a velocity interval it gives exactly what the observation model
makes of the run (one code path for measured and simulated flocks)."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.columns import PERCEPTION_SERIES
from flocksweep.observables.metrics import METRIC_NAMES
from flocksweep.observables.observation import Observation, observe_run
from flocksweep.observables.summary import MetricSettings, measure_run, summarize_run, summary_columns
from flocksweep.observables.tracks import TrackSource, load_tracks, tracks_frame
from flocksweep.simcore import load_preset, simulate_preset
from paths import ROOT



@pytest.fixture(scope="module")
def pattern_run():
    preset = load_preset(ROOT / "configs/models/holland_pattern.toml",
                         ["init.n=14", "run.duration=4.0", "run.record_interval=0.1", "init.radius=6.0"])
    return preset, simulate_preset(preset, 21)


def _write(frame, path):
    if path.suffix == ".parquet":
        frame.to_parquet(path, index=False)
    else:
        frame.to_csv(path, index=False)
    return path


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_exported_tracks_give_exactly_the_simulators_metrics(pattern_run, tmp_path, suffix):
    preset, obs = pattern_run
    settings = MetricSettings(warmup=1.0, group_radius=3.0).resolve(preset.model)   # small: groups split
    series, row = measure_run(obs, settings)
    path = _write(tracks_frame(obs, "sim"), tmp_path / f"tracks{suffix}")
    table = load_tracks(path, TrackSource(units={"length": "bl"}))
    assert table.has_pattern and table.has_velocity and table.dims == 3
    measured = measure_tracks(table, track_settings(settings.group_radius, warmup=1.0), velocity_interval="recorded")
    (got,) = measured.runs.to_dict("records")
    assert got["status"] == "ok" and got["records"] == len(obs.times) and got["interval"] == 0.1
    assert not [i for i in measured.issues if i.level != "note"]    # the simulator's velocities agree
    for column in summary_columns(leadership=False):
        if column.rsplit("_", 1)[0] in PERCEPTION_SERIES:
            assert np.isnan(got[column])
        else:
            assert np.array_equal(got[column], row[column], equal_nan=True), column
    ts = measured.timeseries
    assert np.array_equal(ts["t"].to_numpy(), obs.times)
    for name in METRIC_NAMES:
        if name not in PERCEPTION_SERIES:
            assert np.array_equal(ts[name].to_numpy(), series[name], equal_nan=True), name
    assert series["segregation"][1:].std() > 0 and series["n_groups"].max() > 1   # every metric is exercised


def test_measured_tracks_and_the_observation_model_share_one_code_path(pattern_run, tmp_path):
    preset, obs = pattern_run
    frame = tracks_frame(obs, "sim").drop(columns=["vx", "vy", "vz"])
    table = load_tracks(_write(frame, tmp_path / "tracks.parquet"), TrackSource(units={"length": "bl"}))
    observation = Observation(interval=0.2, velocity_interval=0.4)
    settings = track_settings(7.0, warmup=1.0)
    measured = measure_tracks(table, settings, observation.interval, observation.max_gap, observation.velocity_interval)
    simulated = summarize_run(observe_run(obs, observation, 0), settings)
    (got,) = measured.runs.to_dict("records")
    for column, value in simulated.items():
        assert np.array_equal(got[column], value, equal_nan=True), column
    assert got["records"] == (len(obs.times) - 1) // 2 + 1 - 2       # 0.2 s samples, one trimmed at each end


def test_planar_tracks_match_a_projected_run(pattern_run, tmp_path):
    preset, obs = pattern_run
    frame = tracks_frame(obs, "sim").drop(columns=["z", "vx", "vy", "vz"])
    table = load_tracks(_write(frame, tmp_path / "flat.csv"), TrackSource(units={"length": "bl"}))
    assert table.dims == 2
    observation = Observation(interval=0.1, velocity_interval=0.2, projection="xy")
    settings = track_settings(7.0)
    measured = measure_tracks(table, settings, 0.1, None, 0.2)
    simulated = summarize_run(observe_run(obs, observation, 0), settings)
    (got,) = measured.runs.to_dict("records")
    assert got["dims"] == 2
    for column, value in simulated.items():
        assert np.array_equal(got[column], value, equal_nan=True), column


def test_planar_tracks_with_velocities_match_a_projected_run_with_recorded_velocities(pattern_run, tmp_path):
    preset, obs = pattern_run
    frame = tracks_frame(obs, "sim").drop(columns=["z", "vz"])
    table = load_tracks(_write(frame, tmp_path / "flat.csv"), TrackSource(units={"length": "bl"}))
    assert table.dims == 2 and table.has_velocity
    observation = Observation(interval=0.1, velocity_interval="recorded", projection="xy")
    settings = track_settings(7.0)
    measured = measure_tracks(table, settings, 0.1, None, "recorded")
    simulated = summarize_run(observe_run(obs, observation, 0), settings)
    (got,) = measured.runs.to_dict("records")
    assert got["dims"] == 2 and got["status"] == "ok"
    for column, value in simulated.items():
        assert np.array_equal(got[column], value, equal_nan=True), column
