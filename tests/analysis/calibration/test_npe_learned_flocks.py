"""npe's learned summaries given several observed flocks (analysis.calibration.learned_inputs, learned_summary;
docs/calibration.md "Learned summaries (npe)", "Several flocks"): a training row of f runs (their mean
statistics, each one's raw inputs), the embedding pooled over the flocks whatever their order, training
deterministic (the same file trains a bit-identical estimator), an end-to-end calibration from messy tracks of two flocks with
`flocksweep posterior --tracks` (one posterior given both; another number of flocks refused), and
`aggregate = "mean"` over tracked flocks refused."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.learned_inputs import LearnedSimulator, SummarySettings, layout
from flocksweep.cli import main
from flocksweep.observables.tracks import tracks_frame
from flocksweep.simcore import load_preset, simulate
from flocksweep.simcore.schema import ConfigError
from npe_tiny import learned_calibration
from paths import ROOT

PRESET = ROOT / "configs/models/holland.toml"
SUMMARY = SummarySettings(kind="learned", features=("speed", "turn_rate"), series=("polarization",),
                          series_length=3, width=8, size=3)


def test_split_gives_each_flock_its_individuals_and_series():
    plan = layout(SUMMARY, 4)                       # a flock: 4 x 3 individual numbers, 3 x 1 series
    rows = np.arange(2 * (2 + 3 * plan.length), dtype=float).reshape(2, -1)
    stats, individuals, series = plan.split(rows, 2, flocks=3)
    assert stats.shape == (2, 2) and individuals.shape == (2, 3, 4, 3) and series.shape == (2, 3, 3, 1)
    one = rows[1, 2 + plan.length:2 + 2 * plan.length]          # flock 1 of row 1, as one flock's row
    alone = plan.split(np.concatenate([[0.0, 0.0], one])[None, :], 2)
    np.testing.assert_array_equal(alone[1][0], individuals[1, 1])
    np.testing.assert_array_equal(alone[2][0], series[1, 1])
    with pytest.raises(ValueError, match="3 x 15 raw inputs"):
        plan.split(rows[:, :-1], 2, flocks=3)


def test_a_training_row_is_the_runs_mean_statistics_then_each_runs_raw_inputs():
    preset = load_preset(PRESET, ["init.n=6"])
    plan = layout(SUMMARY, 6)

    def simulator(runs):
        return LearnedSimulator(preset.to_dict(), ["steering.separation_weight"], ["polarization_mean", "nn_distance_mean"],
                                runs, 0.0, plan=plan)

    rng = np.random.default_rng(3)
    runs = rng.normal(size=(3, 2 + plan.length))
    three = simulator(3)
    assert three.row_width == 2 + 3 * plan.length and three.run_width == 2 + plan.length
    row = three.pool(runs)
    np.testing.assert_array_equal(row[:2], runs[:, :2].mean(axis=0))
    np.testing.assert_array_equal(row[2:], runs[:, 2:].ravel())
    one = simulator(1)
    assert one.row_width == 2 + plan.length and np.array_equal(one.pool(runs[:1]), runs[0])   # as before, bit for bit
    assert three.identity()["n_sim"] == 3 and one.identity()["n_sim"] == 1


def _raw_rows(rng, n_rows: int, plan):
    f = len(plan.features)
    individuals = np.zeros((n_rows, plan.max_individuals, f + 1))
    for i, count in enumerate(rng.integers(2, plan.max_individuals + 1, n_rows)):
        individuals[i, :count, :f] = rng.normal(size=(count, f))
        individuals[i, :count, f] = 1.0
    series = rng.normal(size=(n_rows, plan.series_length, len(plan.series)))
    return np.concatenate([individuals.reshape(n_rows, -1), series.reshape(n_rows, -1)], axis=1)


@pytest.mark.slow   # compiles an embedding in JAX: seconds, out of the quick loop (CI runs it)
def test_the_pooled_embedding_ignores_the_order_of_the_flocks_and_each_flock_counts():
    pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    import jax

    from flocksweep.analysis.calibration.learned_summary import LearnedEstimator, Standardise, _new_embedding
    from flocksweep.analysis.calibration.npe_flow import FlowSettings

    rng = np.random.default_rng(0)
    plan = layout(SUMMARY, 6)
    raw = _raw_rows(rng, 12, plan).reshape(4, 3, plan.length)        # 4 rows of 3 flocks
    _, individuals, series = plan.split(raw.reshape(4, -1), 0, flocks=3)
    estimator = LearnedEstimator(None, FlowSettings(), np.zeros(1), np.ones(1), np.zeros(1), np.ones(1),
                                 embedding=_new_embedding(SUMMARY, plan, jax.random.key(1)), summary=SUMMARY,
                                 plan=plan, raw_scale=Standardise.fit(individuals.reshape(12, 6, 3),
                                                                      series.reshape(12, 3, 1)), flocks=3)
    stats = rng.normal(size=(4, 1))
    base = estimator._condition(np.concatenate([stats, raw.reshape(4, -1)], axis=1))
    assert base.shape == (4, 1 + SUMMARY.size) and estimator.k == 1 + 3 * plan.length
    for order in ([2, 0, 1], [1, 2, 0]):
        again = estimator._condition(np.concatenate([stats, raw[:, order].reshape(4, -1)], axis=1))
        np.testing.assert_allclose(again, base, rtol=1e-5, atol=1e-6)
    twice = raw.copy()
    twice[:, 2] = twice[:, 0]                                       # flock 2 replaced by a copy of flock 0
    assert not np.allclose(estimator._condition(np.concatenate([stats, twice.reshape(4, -1)], axis=1)), base)
    with pytest.raises(ValueError, match="3 x"):
        estimator._condition(np.concatenate([stats, raw[:, :2].reshape(4, -1)], axis=1))


# ----------------------------------------------------------------------------------------------------------
# end to end: two tracked flocks with missed detections -> calibrate -> posterior --tracks

CALIBRATION = learned_calibration("npe_learned_flocks")


def _tracks(folder, seeds_and_names, reverse=False):
    preset = load_preset(PRESET, ["init.n=8", "init.radius=6.0", "run.duration=3.0"])
    rng = np.random.default_rng(7)
    frames = []
    for seed, name in seeds_and_names:
        frame = tracks_frame(simulate(preset.model, preset.init, seed, 3.0, preset.run.dt, 12), name)
        frames.append(frame[rng.random(len(frame)) > 0.1])           # a tenth of the detections missing
    frame = pd.concat(frames[::-1] if reverse else frames, ignore_index=True)   # the file's flock order
    folder.mkdir(exist_ok=True)
    frame.drop(columns=["vx", "vy", "vz", "pattern"]).to_parquet(folder / "tracks.parquet", index=False)
    (folder / "tracks.json").write_text('{"units": {"length": "bl"}}')
    return folder / "tracks.parquet"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    folder = tmp_path_factory.mktemp("npe_learned_flocks")
    _tracks(folder, [(41, "flock0"), (42, "flock1")])
    (folder / "cal.toml").write_text(CALIBRATION)
    assert main(["calibrate", str(folder / "cal.toml"), "--out", str(folder / "out"), "--no-progress"]) == 0
    return folder


def test_aggregate_mean_over_tracked_flocks_is_refused_with_a_learned_summary(tmp_path):
    _tracks(tmp_path, [(41, "flock0"), (42, "flock1")])
    (tmp_path / "cal.toml").write_text(CALIBRATION.replace('from_tracks = "tracks.parquet"',
                                                           'from_tracks = "tracks.parquet"\naggregate = "mean"'))
    from flocksweep.analysis.calibration.npe import estimator_identity
    with pytest.raises(ConfigError, match='targets.aggregate.*"samples"'):
        estimator_identity(load_calibration(tmp_path / "cal.toml"))


@pytest.mark.slow
def test_a_learned_summary_of_two_tracked_flocks_and_its_posterior_from_tracks(fitted, tmp_path):
    from flocksweep.analysis.calibration.learned_inputs import observed_raw
    from flocksweep.analysis.calibration.npe import estimator_identity

    config = load_calibration(fitted / "cal.toml")
    out = fitted / "out"
    identity = json.loads((out / "estimator" / "identity.json").read_text())
    assert identity == json.loads(json.dumps(estimator_identity(config)))
    assert identity["replicates"] == 2 and identity["simulator"]["n_sim"] == 2
    assert json.loads((out / "estimator" / "flow.json").read_text())["flocks"] == 2
    report = json.loads((out / "convergence.json").read_text())
    assert report["npe"]["replicates"] == 2 and "coverage" in report["npe"]
    assert "of each of the 2 observed flocks, their summaries pooled" in (out / "report.html").read_text()
    from flocksweep.commands.calibrate import after_calibrate
    hint = after_calibrate(type("Result", (), {"out": out, "paths": {"html": out / "report.html"}})(), config)
    assert any("--tracks TRACKS" in step and "another 2 flocks in one file" in step for step in hint)
    length = 8 * 5 + 4 * 2                    # 8 x (4 features + mask) individual slots, 4 x 2 series bins
    (stored,) = (out / "training").glob("*.npz")
    with np.load(stored) as data:
        assert data["rows"].shape[1] == 1 + 2 * length          # the mean statistic, then each run's raw inputs
    observed = observed_raw(config)
    assert observed.shape == (2 * length,) and not np.array_equal(observed[:length], observed[length:])
    # the stored estimator gives ONE posterior given both flocks of the tracks, measured as its training runs were
    force = [] if json.loads((out / "estimator" / "coverage.json").read_text())["passed"] else ["--force"]
    assert main(["posterior", str(out / "estimator"), "--tracks", str(fitted / "tracks.parquet"), "--draws", "200",
                 "--out", str(tmp_path / "post.csv"), *force]) == 0
    table = pd.read_csv(tmp_path / "post.csv")
    assert list(table["flock"]) == ["flock0+flock1"] and 6 <= table["separation_q5"][0] <= table["separation_q95"][0] <= 18
    # the same two flocks, in the file the other way round: the same posterior (to float rounding)
    _tracks(tmp_path / "swapped", [(41, "flock0"), (42, "flock1")], reverse=True)
    assert main(["posterior", str(out / "estimator"), "--tracks", str(tmp_path / "swapped" / "tracks.parquet"),
                 "--draws", "200", "--out", str(tmp_path / "swapped.csv"), *force]) == 0
    swapped = pd.read_csv(tmp_path / "swapped.csv")
    assert list(swapped["flock"]) == ["flock1+flock0"]
    for column in ("separation_mean", "separation_q5", "separation_q95"):
        assert swapped[column][0] == pytest.approx(table[column][0], rel=1e-3)
    # another number of flocks is refused, naming how many the estimator takes
    from test_npe_tracks import main_or_raise
    one = _tracks(tmp_path / "one", [(41, "flock0")])
    with pytest.raises(ConfigError, match="1 flock\\(s\\) given.*exactly 2 flocks"):
        main_or_raise(["posterior", str(out / "estimator"), "--tracks", str(one), *force])


@pytest.mark.slow
def test_sbc_of_a_learned_summary_estimator_of_two_flocks(fitted, tmp_path):
    # through `flocksweep sbc` (the method registry), reusing the calibration's trained estimator
    from flocksweep.analysis.calibration import methods
    from flocksweep.analysis.calibration.data_model import simulate_fn
    from flocksweep.analysis.calibration.sbc import draw_observed
    from flocksweep.analysis.calibration.sbc_npe import NpeData
    from flocksweep.analysis.calibration.simulator import summary_simulator

    estimator = fitted / "out" / "estimator"
    out = tmp_path / "sbc"
    assert main(["sbc", str(fitted / "cal.toml"), "--set", f"method.estimator={estimator}", "--datasets", "4",
                 "--draws", "9", "--out", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["datasets"] == 4 and summary["simulations"]["observed"] == 8        # two flocks per dataset
    ranks = pd.read_csv(out / "ranks.csv", index_col=0)
    assert ranks["rank_separation"].between(0, 9).all()
    # a dataset's statistics are the statistics-only SBC's (the same runs, the same noise), two flocks of them
    config = load_calibration(fitted / "cal.toml")
    record = json.loads((out / "datasets" / "000002.json").read_text())
    plain = draw_observed(NpeData(config.prior, simulate_fn(config, summary_simulator(config, n_sim=2)), config.seed),
                          record["theta"], 2)
    np.testing.assert_array_equal(np.asarray(record["observed"]), plain)
    assert np.asarray(record["draws"]).shape == (9, 1)
    # the same study in reverse order, another folder: identical records
    import dataclasses
    reused = dataclasses.replace(config, method=dataclasses.replace(config.method, estimator=estimator))
    methods.run_sbc(reused, datasets=4, draws=9, out_dir=tmp_path / "again", progress=False, order=[3, 2, 1, 0])

    def records(folder):
        return {p.name: {k: v for k, v in json.loads(p.read_text()).items() if k != "wall_s"}
                for p in sorted((folder / "datasets").glob("*.json"))}
    assert records(out) == records(tmp_path / "again")


@pytest.mark.slow
def test_the_same_file_trains_a_bit_identical_estimator_of_two_flocks(fitted, tmp_path):
    # the stored training runs are found (no simulation); the flow and the embedding are trained again
    import shutil

    shutil.copytree(fitted / "out" / "training", tmp_path / "out" / "training")
    assert main(["calibrate", str(fitted / "cal.toml"), "--out", str(tmp_path / "out"), "--no-progress"]) == 0
    again = json.loads((tmp_path / "out" / "convergence.json").read_text())["npe"]
    assert not again["reused"] and again["runs_found"] == 2 * 34          # 24 + 10 simulations of two runs each
    for name in ("flow.eqx", "embedding.eqx", "flow.json", "identity.json", "coverage.json"):
        assert (tmp_path / "out" / "estimator" / name).read_bytes() == (fitted / "out" / "estimator" / name).read_bytes()
    assert (tmp_path / "out" / "posterior.csv").read_bytes() == (fitted / "out" / "posterior.csv").read_bytes()
