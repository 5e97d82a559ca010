"""The obstacle, predator and prey metric settings of a sweep's [run] table: validated with the key
named, part of a run's identity only when they differ from their defaults (shipped sweeps keep their run
ids), recorded in model.json and rebuilt from it."""
from __future__ import annotations

import pytest

from flocksweep.simcore import ConfigError
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.design import expand, rebuild
from flocksweep.sweeps.runner import model_record
from paths import ROOT
from tiny_sweeps import HOLLAND, run_ids, sweep


@pytest.mark.parametrize("key", ["capture_radius", "predator_near", "prey_reach"])
@pytest.mark.parametrize("bad", [0.0, -1.5, float("inf")])
def test_bad_settings_are_config_errors_naming_the_key(key, bad):
    with pytest.raises(ConfigError, match=rf"run\.{key}: got {bad!r}; must be a finite number > 0"):
        sweep_from_dict(sweep(**{key: bad}), ROOT)
    with pytest.raises(ConfigError, match=rf"run\.{key}"):
        sweep_from_dict(sweep(**{key: "far"}), ROOT)


def test_defaults_keep_the_run_ids_and_other_values_change_them():
    plain = run_ids(sweep())
    assert run_ids(sweep(capture_radius=1.0, predator_near=10.0, prey_reach=5.0)) == plain
    changed = {key: run_ids(sweep(**{key: 2.5})) for key in ("capture_radius", "predator_near", "prey_reach")}
    assert all(ids != plain for ids in changed.values())
    assert len({tuple(ids) for ids in changed.values()}) == 3


def test_settings_are_recorded_in_model_json_and_rebuilt():
    config = sweep_from_dict(sweep(capture_radius=2.5), ROOT)
    record = config.analysis_record()
    assert record["capture_radius"] == 2.5 and "prey_reach" not in record   # defaults are left out
    spec = expand(config)[0]
    _, metrics = rebuild(model_record(config), {})
    assert (metrics.capture_radius, metrics.predator_near, metrics.prey_reach) == (2.5, 10.0, 5.0)
    assert metrics == spec.metrics


CALIBRATION = f"""
name = "cal"
seed = 7

[model]
preset = "{HOLLAND}"

[run]
n = 30
duration = 10.0
warmup = 3.0
{{extra}}
[parameters.field]
key = "perception.field_deg"
prior = {{{{ dist = "uniform", low = 30, high = 360 }}}}

[targets]
summary = "mean"
stats = ["cohesion", "polarization"]
mean = [0.9, 0.8]
sd = [0.05, 0.05]

[method]
kind = "emcee"
n_sim = 10
walkers = 8
steps = 100
"""


def test_a_calibration_file_refuses_them_as_they_are_no_targets(tmp_path):
    from flocksweep.analysis.calibration.config import load_calibration

    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION.format(extra="prey_reach = 2.0\n"))
    with pytest.raises(ConfigError, match="not calibration targets") as info:
        load_calibration(path)
    assert info.value.key == "run.prey_reach"
    path.write_text(CALIBRATION.format(extra="prey_reach = 5.0\n"))   # the default changes nothing
    assert load_calibration(path).metrics.prey_reach == 5.0


def test_a_run_with_a_predator_stores_its_metrics_series_and_track(tmp_path, monkeypatch):
    """The worker's path for a model with a predator (none is shipped on this branch: the simulator's
    observations get a predator circling the flock's start): the row gets the predator columns, the
    series frame the predator series, a kept trajectory the predator's positions."""
    import dataclasses

    import numpy as np

    from flocksweep.observables.summary import every_nth, measure_run
    from flocksweep.simcore import simulate
    from flocksweep.sweeps import worker

    def with_predator(*args, **kwargs):
        obs = simulate(*args, **kwargs)
        angle = obs.times
        return dataclasses.replace(obs, predator=np.stack([6 * np.cos(angle), np.zeros_like(angle),
                                                           6 * np.sin(angle)], axis=1))

    monkeypatch.setattr(worker, "simulate", with_predator)
    spec = expand(sweep_from_dict(sweep(keep="trajectories", trajectory_every=10, predator_near=30.0), ROOT))[0]
    row, series = worker.execute_run(spec, tmp_path)
    assert row["status"] == "ok", row["error"]
    run = spec.preset.run
    obs = with_predator(spec.preset.model, spec.preset.init, spec.seed, run.duration, run.dt, run.record_every)
    expected = measure_run(obs, spec.metrics)
    for column in ("predator_distance_mean", "flash_nn_ratio", "predator_captures", "remerge_time"):
        assert row[column] == pytest.approx(expected.row[column], nan_ok=True), column
    assert "prey_distance_mean" not in row and "collisions_mean" not in row
    np.testing.assert_array_equal(series["predator_distance"], expected.series["predator_distance"])
    with np.load(tmp_path / "trajectories" / f"{spec.run_id}.npz") as saved:
        assert saved["predator"].shape == (saved["pos"].shape[0], 3)


def test_simulate_prints_and_records_the_encounter_summary(tmp_path, monkeypatch, capsys):
    """``flocksweep simulate`` of a run with a predator and prey (given to the simulator's observations
    here; no shipped model has them on this branch): the summary lines and params.json carry them, and
    --plot draws their paths."""
    import dataclasses
    import json

    import numpy as np

    from flocksweep.sweeps import single
    from flocksweep.cli import main

    def with_agents(preset, seed, record_every=None, threads=None):
        obs = real(preset, seed, record_every, threads)
        centre = obs.pos.mean(axis=1)
        return dataclasses.replace(obs, predator=centre + [0.0, 0.5, 0.0], prey=centre + [100.0, 0.0, 0.0])

    real = single.simulate_preset
    monkeypatch.setattr(single, "simulate_preset", with_agents)
    assert main(["simulate", str(HOLLAND), "--n", "8", "--duration", "0.5", "--out", str(tmp_path), "--plot"]) == 0
    printed = capsys.readouterr().out
    assert "predator:" in printed and "prey: the flock's centre reached it at t = nan s" in printed
    summary = json.loads((tmp_path / "params.json").read_text())["summary"]
    assert summary["prey_reach_time"] is None                 # never: nan is stored as null
    assert 0 <= summary["predator_captures"] <= 8 and summary["predator_distance_min"] >= 0
    assert "collided_boids" not in summary                     # holland has no obstacles
    assert (tmp_path / "traces.png").stat().st_size > 10_000
    with np.load(tmp_path / "trajectory.npz") as saved:
        assert saved["predator"].shape == saved["prey"].shape == (saved["pos"].shape[0], 3)


def test_the_simulate_summary_counts_obstacle_collisions_over_the_whole_run():
    import numpy as np

    from flocksweep.simcore.obstacle_spec import Obstacle
    from flocksweep.simcore.simulate import Observations
    from flocksweep.observables.summary import MetricSettings
    from flocksweep.sweeps.single import summarize

    # two boids along x past a sphere of radius 2 at the origin, at heights 0 and 2.3 (body radius 0.5):
    # both overlap at x = 0, the first also at x = +-2; the deepest gap is 0 - 2 - 0.5
    x = np.arange(-10.0, 11.0, 2.0)
    pos = np.zeros((len(x), 2, 3))
    pos[:, :, 0] = x[:, None]
    pos[:, 1, 1] = 2.3
    vel = np.zeros_like(pos)
    vel[..., 0] = 2.0
    blank = np.zeros((len(x), 2), np.int32)
    obs = Observations(times=np.arange(len(x)) * 1.0, pos=pos, vel=vel, visible=blank, binocular=blank,
                       leader=blank.astype(bool), triggers=np.zeros((0, 2), np.int64), pattern=np.zeros(2, np.uint32),
                       final=None, dt=1.0, record_every=1)
    sphere = Obstacle(kind="sphere", centre=(0.0, 0.0, 0.0), radius=2.0)
    settings = MetricSettings(warmup=0.0, group_radius=5.0, escape_duration=1.0, obstacles=(sphere,), body_radius=0.5)
    summary = summarize(obs, settings)
    assert summary["collided_boids"] == 2 and summary["clearance_min"] == -2.5
    assert summary["polarization_final"] == 1.0 and "predator_captures" not in summary
    assert summary["n"] == 2 and summary["time_s"] == 10.0
