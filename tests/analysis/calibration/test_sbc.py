"""Simulation-based calibration (analysis.calibration.sbc): uniform ranks for a correct posterior on a cheap
Gaussian toy model, a detected miscalibration for a wrong one, resume without redoing finished datasets,
results independent of the processing order and of worker processes, and the shipped cheap config."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flocksweep.analysis.calibration import sbc, sbc_report
from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.priors import JointPrior, Uniform
from flocksweep.sweeps.seeds import SBCStream
from paths import ROOT

SBC_CONFIG = ROOT / "configs/calibration/sbc_range.toml"


class GaussianRows:
    """theta, rng -> (rows, 1) draws of N(theta, sd^2): the toy simulator and data model."""

    def __init__(self, rows: int, sd: float):
        self.rows, self.sd, self.calls = rows, sd, 0

    def __call__(self, theta, rng):
        self.calls += 1
        return np.asarray(theta, dtype=float)[None, :] + self.sd * rng.normal(size=(self.rows, 1))


def toy(likelihood_sd: float = 1.0, seed: int = 3, steps: int = 50) -> sbc.SBCProblem:
    """y ~ N(mu, 1), mu ~ U(-3, 3); the likelihood assumes sd ``likelihood_sd`` (1: the correct model)."""
    return sbc.SBCProblem(prior=JointPrior(["mu"], [Uniform(-3.0, 3.0)]),
                          simulate_fn=GaussianRows(10, likelihood_sd), observe_fn=GaussianRows(1, 1.0),
                          names=("mu",), columns=("y",), seed=seed, walkers=8, steps=steps,
                          meta={"name": "toy", "likelihood_sd": likelihood_sd})


def records(out: Path) -> dict:
    """Per-dataset records without their wall time (the only field allowed to differ between runs)."""
    out_records = {}
    for path in sorted((out / "datasets").glob("*.json")):
        record = json.loads(path.read_text())
        record.pop("wall_s")
        out_records[path.name] = record
    return out_records


@pytest.mark.slow
def test_correct_posterior_gives_uniform_ranks_and_writes_the_report(tmp_path):
    result = sbc.run_sbc(toy(), datasets=50, draws=19, out_dir=tmp_path, progress=False)
    table = result["table"]
    assert table.loc["mu", "p"] > 0.01 and table.loc["mu", "ecdf_p"] > 0.01
    assert result["calibrated"] and "no significant miscalibration" in result["verdict"]
    assert table.loc["mu", "n"] == 50 and table.loc["mu", "bins"] == 10
    ranks = pd.read_csv(tmp_path / "ranks.csv", index_col=0)
    assert len(ranks) == 50 and ranks["rank_mu"].between(0, 19).all() and not ranks["short"].any()
    for name in ("rank_histogram.png", "ecdf_diff.png"):
        assert (tmp_path / name).stat().st_size > 1000
    assert "| mu |" in (tmp_path / "uniformity.md").read_text()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["calibrated"] and summary["datasets"] == 50


@pytest.mark.slow
def test_overconfident_posterior_is_detected(tmp_path):
    """The likelihood assumes a third of the real observation noise: the posterior is too narrow and the
    ranks pile up at 0 and S."""
    result = sbc.run_sbc(toy(likelihood_sd=1 / 3), datasets=30, draws=19, bins=10, out_dir=tmp_path,
                         progress=False)
    assert result["table"].loc["mu", "p"] < 0.01 and result["table"].loc["mu", "ecdf_p"] < 0.01
    assert not result["calibrated"] and "significant miscalibration for mu" in result["verdict"]
    ranks = result["ranks"]["rank_mu"]
    assert ((ranks == 0) | (ranks == 19)).mean() > 0.3


@pytest.mark.slow
def test_resume_skips_finished_datasets_and_gives_the_same_results(tmp_path):
    full = tmp_path / "full"
    sbc.run_sbc(toy(), datasets=6, draws=9, out_dir=full, progress=False)
    part = tmp_path / "part"
    sbc.run_sbc(toy(), datasets=4, draws=9, out_dir=part, progress=False)   # "interrupted" after 4
    (part / "datasets" / "000001.json").unlink()                              # ... and one lost
    problem = toy()
    sbc.run_sbc(problem, datasets=6, draws=9, out_dir=part, progress=False)
    assert problem.observe_fn.calls == 3                                      # datasets 1, 4, 5 only
    assert records(part) == records(full)
    columns = lambda df: df.drop(columns="wall_s")                            # noqa: E731
    pd.testing.assert_frame_equal(columns(pd.read_csv(part / "ranks.csv")), columns(pd.read_csv(full / "ranks.csv")))


@pytest.mark.slow
def test_results_do_not_depend_on_the_processing_order(tmp_path):
    sbc.run_sbc(toy(), datasets=5, draws=9, out_dir=tmp_path / "a", progress=False)
    sbc.run_sbc(toy(), datasets=5, draws=9, out_dir=tmp_path / "b", progress=False, order=[3, 0, 4, 2, 1])
    assert records(tmp_path / "a") == records(tmp_path / "b")
    with pytest.raises(ValueError, match="permutation"):
        sbc.run_sbc(toy(), datasets=5, draws=9, out_dir=tmp_path / "c", progress=False, order=[0, 1])


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_other_settings_or_no_resume_are_refused(tmp_path):
    sbc.run_sbc(toy(), datasets=2, draws=9, out_dir=tmp_path, progress=False)
    with pytest.raises(ValueError, match="seed"):
        sbc.run_sbc(toy(seed=4), datasets=2, draws=9, out_dir=tmp_path, progress=False)
    with pytest.raises(ValueError, match="draws"):
        sbc.run_sbc(toy(), datasets=2, draws=19, out_dir=tmp_path, progress=False)
    with pytest.raises(FileExistsError, match="resume"):
        sbc.run_sbc(toy(), datasets=2, draws=9, out_dir=tmp_path, progress=False, resume=False)


def test_dataset_randomness_comes_from_seed_and_index_only():
    problem = toy()
    theta = sbc.draw_theta(problem, 7)
    assert np.array_equal(theta, sbc.draw_theta(toy(), 7)) and not np.array_equal(theta, sbc.draw_theta(problem, 8))
    assert np.array_equal(sbc.draw_observed(problem, theta, 7), sbc.draw_observed(toy(), theta, 7))
    assert sbc.bsl_seed(3, 7) == sbc.bsl_seed(3, 7) != sbc.bsl_seed(3, 8)
    assert 0 <= sbc.bsl_seed(3, 7) < 2 ** 63


def test_posterior_draws_burn_half_thin_by_tau_and_flag_short_chains():
    rng = np.random.default_rng(0)
    steps, walkers = 400, 8
    chain = np.zeros((steps, walkers, 1))
    for t in range(1, steps):                          # AR(1) walkers, tau = (1 + 0.8) / (1 - 0.8) = 9
        chain[t] = 0.8 * chain[t - 1] + 0.6 * rng.normal(size=(walkers, 1))
    draws, info = sbc.posterior_draws(chain, 49, np.random.default_rng(1))
    assert draws.shape == (49, 1) and info["burn"] == 200 and not info["short"]
    assert 5 <= info["tau_max"] <= 15 and info["thin"] == int(np.ceil(info["tau_max"]))
    kept = chain[200::info["thin"]].reshape(-1)
    assert np.isin(draws[:, 0], kept).all() and len(np.unique(draws)) == 49
    walk = np.cumsum(rng.normal(size=(40, walkers, 1)), axis=0)       # random walk: strongly autocorrelated
    _, info = sbc.posterior_draws(walk, 120, np.random.default_rng(1))  # 20 kept rows, 15 needed for 120 draws
    assert info["tau_max"] > 1 and info["short"] and info["thin"] == 1
    with pytest.raises(ValueError, match="cannot give"):
        sbc.posterior_draws(chain[:10], 49, np.random.default_rng(1))


def test_too_few_datasets_are_not_judged():
    table = pd.DataFrame({"chi2": [0.0], "dof": [0], "p": [np.nan], "n": [2], "bins": [1], "ecdf_p": [0.9]},
                         index=pd.Index(["mu"], name="parameter"))
    calibrated, sentence = sbc_report.verdict(table, 0.05)
    assert not calibrated and sentence.startswith("cannot judge")


def test_default_bins_divide_the_rank_values():
    assert sbc_report.default_bins(49, 50) == 10 and sbc_report.default_bins(49, 100) == 10 \
        and sbc_report.default_bins(19, 60) == 10
    assert sbc_report.default_bins(99, 100) == 20 and sbc_report.default_bins(19, 20) == 4


@pytest.mark.slow
def test_worker_processes_give_the_same_results(tmp_path):
    sbc.run_sbc(toy(), datasets=3, draws=9, out_dir=tmp_path / "one", progress=False)
    sbc.run_sbc(toy(), datasets=3, draws=9, out_dir=tmp_path / "two", progress=False, workers=2)
    assert records(tmp_path / "one") == records(tmp_path / "two")


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_shipped_config_data_model_matches_the_likelihood_and_runs(tmp_path):
    from flocksweep.analysis.calibration.run import simulate_fn
    from flocksweep.analysis.calibration.simulator import SummarySimulator

    config = load_calibration(SBC_CONFIG, ["method.n_sim=4"])
    assert config.dim == 1 and config.method.kind == "emcee" and config.targets.cov is not None
    problem = sbc.problem_from_config(config, steps=6, walkers=4)
    assert (problem.steps, problem.walkers, problem.seed) == (6, 4, config.seed)
    theta = sbc.draw_theta(problem, 0)
    low, high = config.prior.bounds[0]
    assert low <= theta[0] <= high
    one = SummarySimulator(config.preset_data, config.keys, config.targets.columns, 1, config.warmup)
    expected = simulate_fn(config, one)(theta, sbc.generator(config.seed, 0, SBCStream.OBSERVED))
    assert np.array_equal(sbc.draw_observed(problem, theta, 0), expected) and expected.shape == (1, 2)
    result = sbc.run_sbc(config, datasets=2, draws=3, out_dir=tmp_path, progress=False, steps=6, walkers=4)
    assert result["ranks"]["rank_range"].between(0, 3).all()
    assert (tmp_path / "rank_histogram.png").exists() and (tmp_path / "uniformity.csv").exists()
    settings = json.loads((tmp_path / "settings.json").read_text())
    assert settings["problem"]["name"] == "sbc_range" and settings["steps"] == 6


@pytest.mark.slow
def test_sbc_cli_runs_resumes_and_refuses_other_methods(tmp_path, capsys):
    from flocksweep.cli import main

    args = ["sbc", str(SBC_CONFIG), "--datasets", "2", "--draws", "4", "--steps", "24", "--walkers", "4",
            "--out", str(tmp_path / "sbc"), "--no-progress"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "range" in out and "wrote" in out
    assert len(list((tmp_path / "sbc" / "datasets").glob("*.json"))) == 2
    ranks = pd.read_csv(tmp_path / "sbc" / "ranks.csv")
    assert main(args) == 0                                          # resumes: nothing redone, same ranks
    pd.testing.assert_frame_equal(ranks, pd.read_csv(tmp_path / "sbc" / "ranks.csv"))
    capsys.readouterr()
    assert main(["sbc", str(SBC_CONFIG), "--set", 'method.kind="optimize"', "--out", str(tmp_path / "x")]) == 2
    assert "config error: method." in capsys.readouterr().err
    assert main(["sbc", str(SBC_CONFIG), "--datasets", "0", "--out", str(tmp_path / "y")]) == 2


def test_sbc_counts_the_simulations_of_every_dataset(tmp_path):
    problem = toy(steps=20)
    sbc.run_sbc(problem, datasets=3, draws=9, out_dir=tmp_path, progress=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    sims = summary["simulations"]
    # the independent count: the toy simulator's calls, 10 rows each, and one observed row per dataset
    assert sims["total"] == problem.simulate_fn.calls * 10 + problem.observe_fn.calls == sum(
        count for phase, count in sims.items() if phase != "total")
    assert sims["observed"] == 3 and sims["initial"] >= 3 * 8 * 10 and summary["datasets_without_count"] == 0
    per_dataset = json.loads((tmp_path / "datasets" / "000000.json").read_text())["simulations"]
    assert per_dataset["observed"] == 1 and per_dataset["total"] < sims["total"]
