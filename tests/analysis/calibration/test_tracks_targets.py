"""Targets straight from measured tracks and the [observation] block of calibration files
(analysis.calibration.tracks_targets, config, simulator)."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.flock_check import flock_columns, observed_flock

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.emulated import observation_covariance
from flocksweep.analysis.calibration.run import summary_simulator
from flocksweep.analysis.calibration.simulator import SummarySimulator
from flocksweep.observables.observation import observe_run
from flocksweep.observables.summary import MetricSettings, summarize_run
from flocksweep.observables.tracks import tracks_frame
from flocksweep.simcore import load_preset, simulate
from flocksweep.simcore.schema import ConfigError
from flocksweep.cli import main
from paths import ROOT

PRESET = ROOT / "configs/models/holland.toml"
SEEDS = (31, 32, 33, 34, 35)
THETA = (12.0, 8.0)


def calibration_text(tracks: str, observation: str = "interval = 0.2\nvelocity_interval = 0.4", run_extra: str = "",
                     targets_extra: str = "", method: str = 'kind = "emcee"\nn_sim = 6\nwalkers = 4\nsteps = 2',
                     parameters: str = "") -> str:
    return f'''
name = "tracks_test"
seed = 3

[model]
preset = "{PRESET}"
set = {{ "init.radius" = 6.0 }}

[run]
n = 10
duration = 3.0
warmup = 1.0
{run_extra}

[observation]
{observation}

[parameters.separation]
key = "steering.separation_weight"
prior = {{ dist = "uniform", low = 6, high = 18 }}

[parameters.alignment]
key = "steering.alignment_weight"
prior = {{ dist = "uniform", low = 3, high = 14 }}
{parameters}

[targets]
summary = "mean"
stats = ["polarization", "nn_distance", "speed_mean"]
from_tracks = "{tracks}"
{targets_extra}

[method]
{method}
'''


@pytest.fixture(scope="module")
def runs():
    preset = load_preset(PRESET, ["init.n=10", "init.radius=6.0", "run.duration=3.0"])
    return [simulate(preset.model, preset.init, seed, 3.0, preset.run.dt, 12) for seed in SEEDS]


@pytest.fixture()
def tracks(runs, tmp_path):
    """The runs as one track file of five flocks, in body lengths, positions only."""
    frame = pd.concat([tracks_frame(obs, f"flock{k}") for k, obs in enumerate(runs)], ignore_index=True)
    path = tmp_path / "tracks.parquet"
    frame.drop(columns=["vx", "vy", "vz", "pattern"]).to_parquet(path, index=False)
    (tmp_path / "tracks.json").write_text('{"units": {"length": "bl"}}')
    return path


def write_config(tmp_path, text: str):
    path = tmp_path / "calib.toml"
    path.write_text(text)
    return path


def test_each_flock_is_one_sample_measured_as_the_simulator_measures_a_run(tracks, tmp_path):
    # the tracks' warm-up set to the runs' 1 s: they start where the simulations start
    text = calibration_text(tracks.name, targets_extra="[targets.tracks]\nwarmup = 1.0")
    config = load_calibration(write_config(tmp_path, text))
    targets = config.targets
    assert targets.observed.shape == (5, 3) and targets.flocks == tuple(f"flock{k}" for k in range(5))
    assert targets.samples_path == tracks and observation_covariance(config) is None
    assert config.metrics.group_radius == 20.0                 # "auto" fixed to the perception range
    # the same seeds through the calibration's simulator (same observation block, no noise) give the same rows
    rows = summary_simulator(config, n_sim=5).simulate(np.array(THETA), list(SEEDS))
    assert np.array_equal(rows, targets.observed)
    # the flocks' other statistics (the flock check's observed values) are those runs' too, averaged
    extra = flock_columns(config)
    wide = summary_simulator(config, n_sim=5, extra_columns=extra).simulate(np.array(THETA), list(SEEDS))
    known = observed_flock(config)
    assert {"n_groups_mean", "gyration_radius_mean", "fragmented"} <= set(known)   # nn_distance is a target here
    for j, column in enumerate(extra):
        if column in known:
            assert known[column] == pytest.approx(wide[:, 3 + j].mean(), rel=1e-9, abs=1e-12), column
    default = load_calibration(write_config(tmp_path, calibration_text(tracks.name)))   # warm-up 0: all records
    assert not np.array_equal(default.targets.observed, targets.observed)


def test_aggregate_mean_gives_the_mean_and_the_covariance_of_the_mean(tracks, tmp_path):
    config = load_calibration(write_config(tmp_path, calibration_text(tracks.name, targets_extra='aggregate = "mean"')))
    per_flock = config.targets.per_flock
    assert np.allclose(config.targets.observed[0], per_flock.mean(axis=0))
    assert np.allclose(config.targets.cov, np.cov(per_flock, rowvar=False) / 5)
    assert config.targets.samples_path is None and observation_covariance(config) is not None


def test_a_measurement_sd_is_added_to_the_replicate_covariance(tracks, tmp_path, capsys):
    text = calibration_text(tracks.name, targets_extra="sd = [0.05, 0.5, 0.1]")
    config = load_calibration(write_config(tmp_path, text))
    assert config.targets.observed.shape == (5, 3) and config.targets.samples_path is None
    assert np.array_equal(observation_covariance(config), np.diag([0.05, 0.5, 0.1]) ** 2)
    plain = load_calibration(write_config(tmp_path, calibration_text(tracks.name)))
    assert np.array_equal(config.targets.observed, plain.targets.observed)
    # the simulator adds that noise: with common seeds the difference is one draw of N(0, diag(sd^2))
    noisy = summary_simulator(config, n_sim=5)
    assert noisy.simulate(np.array(THETA), list(SEEDS)).shape == (5, 3)
    for bad, message in (("sd = [0.05, 0.5]", "expected 3 numbers > 0"), ("sd = [0.05, 0.5, -1]", "expected 3"),
                         ('sd = [0.05, 0.5, 0.1]\naggregate = "mean"', 'only with aggregate = "samples"')):
        with pytest.raises(ConfigError, match=message) as caught:
            load_calibration(write_config(tmp_path, calibration_text(tracks.name, targets_extra=bad)))
        assert caught.value.key == "targets.sd"
    # flocksweep targets --set: the override reaches the measured targets
    path = write_config(tmp_path, calibration_text(tracks.name))
    assert main(["targets", str(path), "--from-tracks", "--set", "targets.sd=[0.05, 0.5, 0.1]"]) == 0
    assert "sd = [0.05, 0.5, 0.1]" in capsys.readouterr().out
    assert main(["targets", str(path), "--from-tracks"]) == 0
    default = capsys.readouterr().out
    assert main(["targets", str(path), "--from-tracks", "--set", "observation.velocity_interval=0.6"]) == 0
    changed = capsys.readouterr().out
    assert "velocities over 0.6" in changed or changed.splitlines()[3:] != default.splitlines()[3:]


@pytest.mark.parametrize("change, key, message", [
    (dict(observation=""), "observation.interval", "missing"),
    (dict(targets_extra="mean = [0.9, 5, 2]"), "targets.mean", "not with from_tracks"),
    (dict(run_extra="record_interval = 0.5"), "run.record_interval", "remove run.record_interval"),
    (dict(observation="interval = 0.21"), "observation.interval", "whole multiple of the run's dt"),
    (dict(observation='interval = 0.2\nprojection = "xz"'), "observation.projection", "3-D tracks"),
    (dict(targets_extra='aggregate = "mean"\n[targets.tracks]\nbody_length = 0.3'), "targets.tracks.body_length",
     "already in body lengths"),
    (dict(parameters='[parameters.range]\nkey = "perception.range"\nprior = { dist = "uniform", low = 10, high = 30 }'),
     "run.group_radius", "measured tracks need one fixed radius"),
])
def test_bad_blocks_are_config_errors_naming_the_key(tracks, tmp_path, change, key, message):
    with pytest.raises(ConfigError, match=message) as caught:
        load_calibration(write_config(tmp_path, calibration_text(tracks.name, **change)))
    assert caught.value.key == key


def test_tracks_in_metres_need_a_body_length_and_two_d_tracks_a_projection(tracks, tmp_path):
    (tmp_path / "tracks.json").write_text('{"units": {"length": "m"}}')
    with pytest.raises(ConfigError, match="give the body length") as caught:
        load_calibration(write_config(tmp_path, calibration_text(tracks.name)))
    assert caught.value.key == "targets.tracks.body_length"
    config = load_calibration(write_config(tmp_path, calibration_text(tracks.name, targets_extra="[targets.tracks]\n"
                                                                      "body_length = 2.0")))
    assert config.targets.observed.shape == (5, 3)            # positions halved: nn_distance in body lengths
    (tmp_path / "tracks.json").write_text('{"units": {"length": "bl"}}')
    flat = pd.read_parquet(tracks).drop(columns=["z"])
    flat.to_parquet(tracks)
    with pytest.raises(ConfigError, match="2-D tracks") as caught:
        load_calibration(write_config(tmp_path, calibration_text(tracks.name)))
    assert caught.value.key == "observation.projection"


def test_observation_blocks_need_an_open_world_and_observable_statistics(tracks, tmp_path):
    text = calibration_text(tracks.name).replace('set = { "init.radius" = 6.0 }',
                                                 'set = { "init.radius" = 6.0, "world.boundary" = "sphere_wrap" }')
    with pytest.raises(ConfigError, match="open world"):
        load_calibration(write_config(tmp_path, text))
    for hidden in ("visible_mean", "visible_sd"):
        text = calibration_text(tracks.name).replace('"speed_mean"]', f'"{hidden}"]')
        with pytest.raises(ConfigError, match=f"'{hidden}' cannot be measured by an observer"):
            load_calibration(write_config(tmp_path, text))


def test_bad_tracks_are_config_errors_naming_row_and_column(tracks, tmp_path):
    frame = pd.read_parquet(tracks)
    frame = pd.concat([frame, frame.iloc[[7]]], ignore_index=True)
    frame.to_parquet(tracks)
    with pytest.raises(ConfigError, match=r"(?s)targets.from_tracks: .*duplicate: flock 'flock0', rows 8, 801:") as caught:
        load_calibration(write_config(tmp_path, calibration_text(tracks.name)))
    assert caught.value.key == "targets.from_tracks"


def test_the_simulator_without_observation_is_unchanged_and_with_it_deterministic(runs):
    preset = load_preset(PRESET, ["init.n=10", "init.radius=6.0", "run.duration=3.0", "run.record_interval=0.5"])
    data = preset.to_dict()
    columns = ("polarization_mean", "nn_distance_mean")
    bare = SummarySimulator(data, ["steering.separation_weight"], columns, 2, 1.0).simulate([12.0], [5, 6])
    settings = MetricSettings(warmup=1.0).resolve(preset.model)
    for row, seed in zip(bare, (5, 6)):
        alone = summarize_run(simulate(preset.model, preset.init, seed, 3.0, preset.run.dt, 30), settings)
        assert np.array_equal(row, [alone[c] for c in columns])
    from flocksweep.observables.observation import Observation
    observation = Observation(interval=0.1, velocity_interval=0.2, detection_probability=0.9, position_sd=0.1)
    seen = SummarySimulator(data, ["steering.separation_weight"], columns, 2, 1.0, observation=observation)
    first = seen.simulate([12.0], [5, 6])
    assert np.array_equal(first, seen.simulate([12.0], [5, 6]))
    assert np.array_equal(first[1], seen.with_replicates(3).simulate([12.0], [9, 6, 7])[1])  # batch-independent
    obs = simulate(preset.model, preset.init, 6, 3.0, preset.run.dt, 6)
    alone = summarize_run(observe_run(obs, observation, 6), settings)
    assert np.array_equal(first[1], [alone[c] for c in columns])
    assert not np.array_equal(first, bare)


def test_targets_command_prints_every_flock_and_the_block(tracks, tmp_path, capsys):
    path = write_config(tmp_path, calibration_text(tracks.name))
    assert main(["targets", str(path), "--from-tracks"]) == 0
    out = capsys.readouterr().out
    assert out.count("# flock") == 6 and "[targets]" in out and f'from_tracks = "{tracks}"' in out
    assert "# mean = [" in out and "# cov = [[" in out
    # a typed-targets file can be pointed at tracks from the command line
    typed = calibration_text("unused.csv").replace('from_tracks = "unused.csv"', "mean = [0.9, 5, 2]\nsd = [0.1, 1, 1]")
    path = write_config(tmp_path, typed)
    assert main(["targets", str(path), "--from-tracks", str(tracks)]) == 0
    assert "flock4" in capsys.readouterr().out
    assert main(["targets", str(path), "--from-tracks"]) == 2
    assert "no targets.from_tracks" in capsys.readouterr().err


@pytest.mark.slow
def test_a_calibration_from_tracks_runs_end_to_end_through_the_cli(tracks, tmp_path, capsys):
    path = write_config(tmp_path, calibration_text(tracks.name))
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress"]) == 0
    posterior = pd.read_csv(out / "posterior.csv")
    assert list(posterior["parameter"]) == ["separation", "alignment"]
    predictive = pd.read_csv(out / "predictive.csv")
    assert len(predictive) == 3 and (out / "chain.h5").exists()
    # the tracks it was fitted to are recorded: file (not the machine's path), units and scales with their source
    record = json.loads((out / "convergence.json").read_text())["tracks"]
    assert record["file"] == tracks.name and record["dims"] in (2, 3) and record["flocks"]
    assert record["scales"]["length unit"]["from"] and "analysis length unit" in record["scales"]
    assert set(record["checks"]) == {"warnings", "errors"}
    report = (out / "report.md").read_text()
    assert "## The tracks" in report and "Every unit and scale used" in report


DCD_STATS = '["polarization", "dcd_corr_mean", "dcd_delay_mean", "dcd_leader_delay"]'


def test_directional_correlation_delays_are_statistics_measured_alike_on_runs_and_tracks(tracks, tmp_path):
    text = calibration_text(tracks.name, run_extra="dcd_max_delay = 0.6",
                            targets_extra="[targets.tracks]\nwarmup = 1.0").replace(
        'stats = ["polarization", "nn_distance", "speed_mean"]', f"stats = {DCD_STATS}")
    config = load_calibration(write_config(tmp_path, text))
    assert config.targets.columns == ("polarization_mean", "dcd_corr_mean", "dcd_delay_mean", "dcd_leader_delay")
    assert config.metrics.dcd and config.metrics.dcd_max_delay == 0.6
    rows = summary_simulator(config, n_sim=5).simulate(np.array(THETA), list(SEEDS))
    assert np.array_equal(rows, config.targets.observed) and np.isfinite(rows).all()
    assert len(np.unique(rows[:, 3])) > 1                       # the flocks differ: not a constant
    # flocksweep measure on the same track file, measured as the [observation] block says, gives them too
    out = tmp_path / "measured"
    assert main(["measure", str(tracks), "--group-radius", "20", "--interval", "0.2", "--velocity-interval", "0.4",
                 "--warmup", "1.0", "--dcd-max-delay", "0.6", "--out", str(out), "--no-figures",
                 "--no-progress"]) == 0
    measured = pd.read_parquet(out / "runs.parquet").set_index("flock")
    for k, flock in enumerate(config.targets.flocks):
        assert np.array_equal(measured.loc[flock, list(config.targets.columns)].to_numpy(float), rows[k])
    # a longer largest delay is another statistic
    longer = load_calibration(write_config(tmp_path, text.replace("dcd_max_delay = 0.6", "dcd_max_delay = 1.0")))
    assert not np.array_equal(longer.targets.observed, config.targets.observed)


def test_a_simulated_target_may_name_a_directional_correlation_delay(tmp_path):
    text = calibration_text("unused").replace("[observation]\ninterval = 0.2\nvelocity_interval = 0.4", "")
    text = text.replace('stats = ["polarization", "nn_distance", "speed_mean"]\nfrom_tracks = "unused"',
                        'stats = ["polarization", "dcd_corr_mean"]\nmean = [0.9, 0.8]\nsd = [0.05, 0.1]')
    config = load_calibration(write_config(tmp_path, text.replace("warmup = 1.0", "warmup = 1.0\nrecord_interval = 0.2")))
    assert config.targets.columns == ("polarization_mean", "dcd_corr_mean") and config.metrics.dcd
    simulator = summary_simulator(config, n_sim=2)
    preset = simulator.preset(np.array(THETA))
    run = simulate(preset.model, preset.init, 5, preset.run.duration, preset.run.dt, preset.run.record_every)
    alone = summarize_run(run, config.metrics.resolve(preset.model))
    assert np.array_equal(simulator.simulate(np.array(THETA), [5, 6])[0], [alone["polarization_mean"],
                                                                          alone["dcd_corr_mean"]])
    with pytest.raises(ConfigError, match=r"targets.stats: unknown metric 'dcd_corr'.*did you mean"):
        load_calibration(write_config(tmp_path, text.replace('"dcd_corr_mean"]', '"dcd_corr"]')))
