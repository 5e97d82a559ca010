"""npe from a tracks file: the training runs are the calibration's own data model, measured through the
[observation] block exactly as the tracks were (npe refused the block before); the estimator stores how its
statistics are measured and ``flocksweep posterior`` checks a measured table against it (or measures the
tracks itself), refuses an estimator that failed its coverage check unless --force, and the predictive
viewer page is written beside the data."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.estimator_folder import seal
from flocksweep.analysis.calibration.npe import NPEStream, estimator_identity, training_design
from flocksweep.analysis.calibration.simulator import summary_simulator
from flocksweep.cli import main
from flocksweep.observables.tracks import tracks_frame
from flocksweep.simcore import load_preset, simulate
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.seeds import Tag, generator, seeds_for
from paths import ROOT

PRESET = ROOT / "configs/models/holland.toml"
SEEDS = (41, 42, 43)

CALIBRATION = f'''
name = "npe_tracks"
seed = 4
[model]
preset = "{PRESET}"
set = {{ "init.radius" = 6.0 }}
[run]
n = 10
duration = 3.0
warmup = 1.0
group_radius = 20.0
[observation]
interval = 0.2
velocity_interval = 0.4
detection_probability = 0.9
position_sd = 0.05
[parameters.separation]
key = "steering.separation_weight"
prior = {{ dist = "uniform", low = 6, high = 18 }}
[targets]
stats = ["polarization", "nn_distance", "speed_mean"]
from_tracks = "tracks.parquet"
[targets.tracks]
warmup = 1.0
[method]
kind = "npe"
simulations = 20
heldout = 10
draws = 200
flow = {{ width = 8, layers = 1, max_epochs = 5, patience = 2 }}
'''


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    folder = tmp_path_factory.mktemp("npe_tracks")
    preset = load_preset(PRESET, ["init.n=10", "init.radius=6.0", "run.duration=3.0"])
    runs = [simulate(preset.model, preset.init, seed, 3.0, preset.run.dt, 12) for seed in SEEDS]
    frame = pd.concat([tracks_frame(obs, f"flock{k}") for k, obs in enumerate(runs)], ignore_index=True)
    frame.drop(columns=["vx", "vy", "vz", "pattern"]).to_parquet(folder / "tracks.parquet", index=False)
    (folder / "tracks.json").write_text('{"units": {"length": "bl"}}')
    (folder / "cal.toml").write_text(CALIBRATION)
    assert main(["calibrate", str(folder / "cal.toml"), "--out", str(folder / "out"), "--no-progress"]) == 0
    return folder


@pytest.mark.slow
def test_npe_trains_on_runs_measured_through_the_observation_block(fitted):
    config = load_calibration(fitted / "cal.toml")
    report = json.loads((fitted / "out" / "convergence.json").read_text())
    assert report["npe"]["replicates"] == 3                     # three flocks: each simulation the mean of 3 runs
    assert report["accounting"]["simulations"]["training"] == 20 * 3
    # every training row is the calibration's own simulator (the observation block applied) at its seeds
    (stored,) = (fitted / "out" / "training").glob("*.npz")
    with np.load(stored) as data:
        index, rows = data["index"], data["rows"]
    theta = training_design(config)
    simulator = summary_simulator(config, n_sim=3)
    for i in (0, 7, 25):
        seeds = seeds_for(generator(config.seed, Tag.NPE, int(NPEStream.RUNS), i), 3)
        expected = simulator.simulate(theta[i], seeds).mean(axis=0)
        assert np.array_equal(rows[np.flatnonzero(index == i)[0]], expected)
    identity = json.loads((fitted / "out" / "estimator" / "identity.json").read_text())
    assert identity["simulator"]["observation"]["position_sd"] == 0.05
    assert identity["measurement"] == estimator_identity(config)["measurement"]
    assert identity["measurement"]["interval"] == 0.2 and identity["measurement"]["velocity_interval"] == 0.4
    assert (fitted / "out" / "viewer_predictive.html").is_file()       # the measured flock beside a run
    assert (fitted / "out" / "estimator" / "coverage.json").is_file()


@pytest.mark.slow
def test_posterior_checks_how_a_table_was_measured_and_the_estimator_coverage(fitted, capsys):
    estimator = fitted / "out" / "estimator"
    coverage = json.loads((estimator / "coverage.json").read_text())
    # the tiny estimator's own verdict may go either way on 10 held-out sets: first as a good one's
    (estimator / "coverage.json").write_text(json.dumps({**coverage, "passed": True, "messages": ["coverage: ok"]}))
    seal(estimator, ["coverage.json"])          # (the folder is sealed: a verdict edited by hand is resealed)
    # the tracks measured as the estimator needs (its interval, velocities, group radius): one row per flock
    assert main(["posterior", str(estimator), "--tracks", str(fitted / "tracks.parquet"), "--draws", "100",
                 "--out", str(fitted / "post.csv")]) == 0
    printed = capsys.readouterr().out
    assert "coverage:" in printed and "measurement checked" in printed
    table = pd.read_csv(fitted / "post.csv")
    # trained on 3 flocks at a time (each simulation the mean of 3 runs): ONE posterior given all three
    assert list(table["flock"]) == ["flock0+flock1+flock2"]
    # the same tracks measured by `flocksweep measure` otherwise: refused, naming the setting
    assert main(["measure", str(fitted / "tracks.parquet"), "--group-radius", "20", "--out", str(fitted / "m"),
                 "--no-figures", "--no-progress"]) == 0     # velocities over one interval (0.2 s)
    with pytest.raises(ConfigError, match=r"velocities differenced over 0.2 s; the estimator's are differenced over "
                                          r"0.4 s \(measurement.velocity_interval\)"):
        main_or_raise(["posterior", str(estimator), "--targets", str(fitted / "m" / "runs.parquet")])
    assert main(["measure", str(fitted / "tracks.parquet"), "--group-radius", "20", "--interval", "0.4",
                 "--out", str(fitted / "m4"), "--no-figures", "--no-progress"]) == 0
    with pytest.raises(ConfigError, match=r"measured every 0.4 s; the estimator's statistics are measured every "
                                          r"0.2 s \(measurement.interval\)"):
        main_or_raise(["posterior", str(estimator), "--targets", str(fitted / "m4" / "runs.parquet")])
    # measured as the estimator's were: accepted
    assert main(["measure", str(fitted / "tracks.parquet"), "--group-radius", "20", "--interval", "0.2",
                 "--velocity-interval", "0.4", "--warmup", "1.0", "--out", str(fitted / "m2"), "--no-figures",
                 "--no-progress"]) == 0
    assert main(["posterior", str(estimator), "--targets", str(fitted / "m2" / "runs.parquet"), "--draws", "100"]) == 0
    # an estimator that failed its coverage check: refused, or with --force every row marked
    (estimator / "coverage.json").write_text(json.dumps({**coverage, "passed": False, "messages": [
        "coverage FAILED: ...", "separation: 90% intervals cover 40.0% of 10 held-out truths"]}))
    seal(estimator, ["coverage.json"])
    with pytest.raises(ConfigError, match="FAILED its held-out coverage check.*--force"):
        main_or_raise(["posterior", str(estimator), "--tracks", str(fitted / "tracks.parquet")])
    assert main(["posterior", str(estimator), "--tracks", str(fitted / "tracks.parquet"), "--force", "--draws", "100",
                 "--out", str(fitted / "forced.csv")]) == 0
    assert not pd.read_csv(fitted / "forced.csv")["credible"].any()


def main_or_raise(argv):
    """Run a command's handler directly, so its ConfigError reaches the test (main turns it into status 2)."""
    from flocksweep.cli import build_parser
    from flocksweep.commands import load

    args = build_parser(argv[0]).parse_args(argv)
    return load(args.command).handler(args)
