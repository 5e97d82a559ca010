"""The observables of collective motion as calibration statistics (docs/metrics.md "Observables of
collective motion"): named in ``targets.stats``, measured alike on simulated runs seen through an
[observation] block and on measured tracks (the same numbers, bit for bit, from the calibration's
simulator, its targets and ``flocksweep measure``), with the settings of [run] acting on both."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.run import summary_simulator
from flocksweep.cli import main
from flocksweep.observables.summary import summarize_run
from flocksweep.observables.tracks import tracks_frame
from flocksweep.simcore import load_preset, simulate
from flocksweep.simcore.schema import ConfigError
from paths import ROOT

PRESET = ROOT / "configs/models/holland.toml"
SEEDS = (31, 32, 33, 34)
THETA = np.array([12.0])     # holland's separation weight: the tracks are runs at it
STATS = ["polarization", "nn_ahead_fraction", "knn_bearing_deg", "corr_length", "front_spacing_ratio",
         "turn_rate_q50", "heading_autocorr_time", "speed_q90", "polarized_fraction"]
COLUMNS = ("polarization_mean", "nn_ahead_fraction_mean", "knn_bearing_deg_mean", "corr_length_mean",
           "front_spacing_ratio_mean", "turn_rate_q50", "heading_autocorr_time", "speed_q90", "polarized_fraction")


def text(targets: str, run_extra: str = "k_nearest = 3\nstate_high = 0.6", observation: bool = True) -> str:
    block = "[observation]\ninterval = 0.2\nvelocity_interval = 0.4\n" if observation else ""
    return f'''
name = "motion_targets"
seed = 3

[model]
preset = "{PRESET}"
set = {{ "init.radius" = 6.0 }}

[run]
n = 10
duration = 3.0
warmup = 1.0
{run_extra}

{block}
[parameters.separation]
key = "steering.separation_weight"
prior = {{ dist = "uniform", low = 6, high = 18 }}

[targets]
summary = "mean"
{targets}

[method]
kind = "emcee"
n_sim = 12
walkers = 4
steps = 2
'''


@pytest.fixture(scope="module")
def tracks(tmp_path_factory):
    """Four runs as one track file of four flocks, in body lengths, positions only."""
    preset = load_preset(PRESET, ["init.n=10", "init.radius=6.0", "run.duration=3.0"])
    runs = [simulate(preset.model, preset.init, seed, 3.0, preset.run.dt, 12) for seed in SEEDS]
    folder = tmp_path_factory.mktemp("motion_tracks")
    frame = pd.concat([tracks_frame(obs, f"flock{k}") for k, obs in enumerate(runs)], ignore_index=True)
    path = folder / "tracks.parquet"
    frame.drop(columns=["vx", "vy", "vz", "pattern"]).to_parquet(path, index=False)
    (folder / "tracks.json").write_text('{"units": {"length": "bl"}}')
    return path


def write(folder, content: str):
    path = folder / "calib.toml"
    path.write_text(content)
    return path


def test_motion_statistics_are_measured_alike_on_observed_runs_and_on_tracks(tracks, tmp_path):
    targets = (f"stats = {STATS!r}\nfrom_tracks = \"{tracks}\"\n[targets.tracks]\nwarmup = 1.0").replace("'", '"')
    config = load_calibration(write(tmp_path, text(targets)))
    assert config.targets.columns == COLUMNS
    assert (config.metrics.k_nearest, config.metrics.state_high) == (3, 0.6)
    # the calibration's simulator at the tracks' parameters and seeds, through the same observation block
    rows = summary_simulator(config, n_sim=len(SEEDS)).simulate(THETA, list(SEEDS))
    assert np.isfinite(rows).all() and np.array_equal(rows, config.targets.observed)
    assert all(len(np.unique(rows[:, c])) > 1 for c in range(len(COLUMNS)) if COLUMNS[c] != "polarized_fraction")
    # another k is another statistic
    other = load_calibration(write(tmp_path, text(targets, run_extra="k_nearest = 5\nstate_high = 0.6")))
    assert not np.array_equal(other.targets.observed[:, 2], config.targets.observed[:, 2])
    assert np.array_equal(other.targets.observed[:, :2], config.targets.observed[:, :2])


def test_measure_gives_the_statistics_of_the_tracks_targets(tracks, tmp_path):
    targets = (f"stats = {STATS!r}\nfrom_tracks = \"{tracks}\"\n[targets.tracks]\nwarmup = 1.0").replace("'", '"')
    config = load_calibration(write(tmp_path, text(targets)))
    out = tmp_path / "measured"
    assert main(["measure", str(tracks), "--group-radius", "20", "--interval", "0.2", "--velocity-interval", "0.4",
                 "--warmup", "1.0", "--k-nearest", "3", "--state-high", "0.6", "--out", str(out), "--no-figures",
                 "--no-progress"]) == 0
    measured = pd.read_parquet(out / "runs.parquet").set_index("flock")
    for k, flock in enumerate(config.targets.flocks):
        assert np.array_equal(measured.loc[flock, list(COLUMNS)].to_numpy(float), config.targets.observed[k])
    assert main(["measure", str(tracks), "--group-radius", "20", "--k-nearest", "0", "--out", str(out)]) == 2


def test_simulated_targets_take_them_and_refuse_them_when_switched_off(tmp_path):
    typed = 'stats = ["polarization", "knn_ahead_fraction", "speed_autocorr_time"]\nmean = [0.9, 0.4, 0.5]\n' \
            'sd = [0.05, 0.05, 0.1]'
    config = load_calibration(write(tmp_path, text(typed, run_extra="record_interval = 0.25\nk_nearest = 2",
                                                   observation=False)))
    assert config.targets.columns == ("polarization_mean", "knn_ahead_fraction_mean", "speed_autocorr_time")
    simulator = summary_simulator(config, n_sim=2)
    preset = simulator.preset(THETA)
    run = simulate(preset.model, preset.init, 5, preset.run.duration, preset.run.dt, preset.run.record_every)
    alone = summarize_run(run, config.metrics.resolve(preset.model))
    assert np.array_equal(simulator.simulate(THETA, [5, 6])[0], [alone[c] for c in config.targets.columns])
    assert config.metrics.resolve(preset.model).k_nearest == 2
    with pytest.raises(ConfigError, match=r"targets.stats: 'knn_ahead_fraction' is computed only with "
                                          r"run.pairwise_metrics = true"):
        load_calibration(write(tmp_path, text(typed, run_extra="pairwise_metrics = false", observation=False)))
    with pytest.raises(ConfigError, match=r"run.k_nearest: got 0; expected a whole number >= 1"):
        load_calibration(write(tmp_path, text(typed, run_extra="k_nearest = 0", observation=False)))
