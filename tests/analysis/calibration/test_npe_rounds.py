"""Sequential rounds of npe (analysis.calibration.npe_rounds): the truncation region of a known posterior,
the truncated prior's draws (inside the region, uniform there, deterministic given the generator), a toy
simulator with an analytic Gaussian posterior recovered in two rounds, and a calibration of two rounds
interrupted after round 1 re-using that round's runs and estimator."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from flocksweep.analysis.calibration.npe import support_of
from flocksweep.analysis.calibration.npe_rounds import QUANTILE, truncated_prior_draws, truncation_region
from flocksweep.analysis.calibration.priors import JointPrior, Uniform
from npe_tiny import CALIBRATION
from flocksweep.simcore.schema import ConfigError


class Gaussian:
    """A stand-in estimator whose posterior is N(x, sd^2) in one parameter: numpy sampling and density."""

    def __init__(self, sd):
        self.sd = sd

    def sample(self, x, count, seed, support=None):
        draws = np.random.default_rng(seed).normal(x[0], self.sd, (count, 1))
        return draws if support is None else draws[support(draws)]

    def log_prob(self, theta, x):
        return stats.norm.logpdf(np.asarray(theta)[:, 0], x[0], self.sd)


PRIOR = JointPrior(["mu"], [Uniform(-50, 50)])


def test_the_region_holds_all_but_the_quantile_of_the_posterior_mass():
    region = truncation_region(Gaussian(0.5), [1.0], support_of(PRIOR), seed=4, draws=200_000)
    # log N >= its 1e-4 quantile <=> |mu - 1| <= 0.5 z, z^2 the (1 - 1e-4) quantile of chi2(1)
    half = 0.5 * np.sqrt(stats.chi2.ppf(1 - QUANTILE, 1))
    grid = np.linspace(-5, 7, 1201)[:, None]
    inside = region.contains(grid)
    assert abs(grid[inside].min() - (1 - half)) < 0.05 and abs(grid[inside].max() - (1 + half)) < 0.05
    assert not region.contains([[60.0]])[0]        # outside the prior's bounds: never inside


def test_truncated_prior_draws_lie_in_the_region_uniformly_and_repeat_given_the_generator():
    region = truncation_region(Gaussian(0.5), [1.0], support_of(PRIOR), seed=4)
    theta, mass = truncated_prior_draws(PRIOR, region, 2000, np.random.default_rng(7))
    assert theta.shape == (2000, 1) and region.contains(theta).all()
    low, high = theta.min(), theta.max()
    assert stats.kstest(theta[:, 0], stats.uniform(low, high - low).cdf).pvalue > 0.01
    assert abs(mass - (high - low) / 100) < 0.005        # the region's share of the prior's 100 units
    again, _ = truncated_prior_draws(PRIOR, region, 2000, np.random.default_rng(7))
    assert np.array_equal(again, theta)
    other, _ = truncated_prior_draws(PRIOR, region, 2000, np.random.default_rng(8))
    assert not np.array_equal(other, theta)


def test_a_region_too_small_to_sample_is_a_config_error_naming_rounds():
    region = truncation_region(Gaussian(1e-6), [1.0], support_of(PRIOR), seed=4)
    with pytest.raises(ConfigError, match="method.rounds"):
        truncated_prior_draws(PRIOR, region, 10, np.random.default_rng(0))


@pytest.mark.slow
def test_a_gaussian_mean_posterior_is_recovered_in_two_truncated_rounds():
    pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    from flocksweep.analysis.calibration.npe_flow import FlowSettings, train_flow

    # x = theta + N(0, 0.5^2) under a flat prior on [-5, 5]: the posterior at x = 1 is N(1, 0.5^2)
    prior, rng = JointPrior(["mu"], [Uniform(-5, 5)]), np.random.default_rng(0)
    # batches of 200 at a learning rate of 2e-3: a quarter of the steps of batches of 50 at 1e-3 (the
    # same flow; the posterior as close: measured mean 0.989 and sd 0.513 at 1e-3 and 50: 1.000, 0.501)
    small = FlowSettings(width=32, layers=2, max_epochs=400, patience=40, learning_rate=2e-3, batch_size=200)
    theta1 = prior.sample(rng, 1000)
    x1 = theta1 + rng.normal(0, 0.5, theta1.shape)
    region = truncation_region(train_flow(theta1, x1, small, seed=3), [1.0], support_of(prior), seed=5)
    theta2, mass = truncated_prior_draws(prior, region, 1000, np.random.default_rng(6))
    x2 = theta2 + rng.normal(0, 0.5, theta2.shape)
    assert mass < 0.95                                       # round 2 is drawn from a truncated prior
    two = train_flow(np.concatenate([theta1, theta2]), np.concatenate([x1, x2]), small, seed=4)
    draws = two.sample([1.0], 4000, seed=1, support=region.contains)
    assert abs(draws.mean() - 1.0) < 0.1                     # measured 0.989 (round 1 alone: 1.018)
    assert 0.42 < draws.std() < 0.58                         # measured 0.513 (round 1 alone: 0.574)


def _calibration_text() -> str:
    return CALIBRATION + "rounds = 2\n"


def _round2_files(out) -> list:
    """Round 2's stored runs: the .json and .npz of the design labelled round 2 in the training folder."""
    (found,) = [p for p in (out / "training").glob("*.json") if json.loads(p.read_text())["label"].startswith("round 2")]
    return [found, found.with_suffix(".npz")]


def _round2_design(out) -> np.ndarray:
    """Round 2's statistics in design order (its design is a function of the seed and round 1)."""
    with np.load(_round2_files(out)[1]) as data:
        return data["rows"][np.argsort(data["index"])]


@pytest.mark.slow
def test_two_rounds_resume_after_round_one_reusing_its_runs_and_estimator(tmp_path):
    pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    from flocksweep.cli import main

    path = tmp_path / "cal.toml"
    path.write_text(_calibration_text())
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress"]) == 0
    first = json.loads((out / "convergence.json").read_text())
    assert first["accounting"]["simulations"]["training"] == 120     # 2 rounds of 60
    assert first["accounting"]["simulations"]["heldout"] == 20       # drawn in the last round only
    assert [r["round"] for r in first["npe"]["rounds"]] == [1, 2]
    design, posterior = _round2_design(out), pd.read_csv(out / "posterior.csv")
    # interrupted after round 1: its runs and estimator are stored, round 2 and the final estimator are not
    for stored in _round2_files(out):
        stored.unlink()
    shutil.rmtree(out / "estimator")
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress"]) == 0
    second = json.loads((out / "convergence.json").read_text())
    assert second["accounting"]["simulations"]["training"] == 60     # round 2's only: round 1's runs found
    assert second["npe"]["rounds"][0]["estimator_reused"] and not second["npe"]["rounds"][1]["estimator_reused"]
    assert np.array_equal(_round2_design(out), design)              # the round-2 design, given the seed
    pd.testing.assert_frame_equal(pd.read_csv(out / "posterior.csv"), posterior)
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress"]) == 0
    third = json.loads((out / "convergence.json").read_text())
    assert "training" not in third["accounting"]["simulations"] and third["npe"]["reused"]
    flocks = tmp_path / "flocks.csv"
    pd.DataFrame({"visible_mean_mean": [3.0], "binocular_share_mean": [0.2]}).to_csv(flocks, index=False)
    assert main(["posterior", str(out / "estimator"), "--targets", str(flocks)]) == 2   # one flock's estimator


def test_rounds_are_validated_and_one_round_keeps_the_estimator_identity(tmp_path):
    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.npe import estimator_identity

    path = tmp_path / "cal.toml"
    path.write_text(_calibration_text().replace("rounds = 2", "rounds = 1"))
    one = estimator_identity(load_calibration(path))
    assert "rounds" not in one and "observed" not in one                 # rounds = 1: today's identity
    two = estimator_identity(load_calibration(path, ["method.rounds=2"]))
    assert two["rounds"] == 2 and two["observed"] == [3.0, 0.2]          # truncated to these targets
    assert estimator_identity(load_calibration(path, ["method.rounds=2", "targets.mean=[4.0, 0.3]"])) != two
    with pytest.raises(ConfigError, match="rounds"):
        load_calibration(path, ["method.rounds=0"])
    with pytest.raises(ConfigError, match="estimator"):
        load_calibration(path, ["method.rounds=2", "method.estimator=elsewhere"])


def test_a_larger_truncation_leaves_that_share_of_the_posterior_mass_outside_the_region():
    # the region {log q >= its `quantile` quantile} of N(1, 0.5^2) is |mu - 1| <= 0.5 z, z^2 the chi2(1)
    # quantile of 1 - quantile: 1e-2 gives a narrower region than the default 1e-4
    for quantile in (QUANTILE, 1e-2):
        region = truncation_region(Gaussian(0.5), [1.0], support_of(PRIOR), seed=4, quantile=quantile,
                                   draws=200_000)
        half = 0.5 * np.sqrt(stats.chi2.ppf(1 - quantile, 1))
        grid = np.linspace(-5, 7, 1201)[:, None]
        inside = grid[region.contains(grid)]
        assert abs(inside.min() - (1 - half)) < 0.05 and abs(inside.max() - (1 + half)) < 0.05


def test_truncation_is_validated_and_named_in_the_identity_of_rounds_only_when_not_the_default(tmp_path):
    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.npe import estimator_identity

    path = tmp_path / "cal.toml"
    path.write_text(_calibration_text())
    default = estimator_identity(load_calibration(path))
    assert "truncation" not in default             # sequential estimators stored before keep their identity
    changed = estimator_identity(load_calibration(path, ["method.truncation=1e-3"]))
    assert changed["truncation"] == 1e-3 and changed != default
    one_round = tmp_path / "one.toml"
    one_round.write_text(_calibration_text().replace("rounds = 2", "rounds = 1"))
    assert "truncation" not in estimator_identity(load_calibration(one_round, ["method.truncation=1e-3"]))
    for bad in ("0", "0.2", "-1e-4"):
        with pytest.raises(ConfigError, match="truncation"):
            load_calibration(path, [f"method.truncation={bad}"])


class _Stop(Exception):
    pass


@pytest.mark.slow
def test_the_calibration_truncates_each_round_at_its_truncation_setting(tmp_path, monkeypatch):
    pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    from flocksweep.analysis.calibration import npe
    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.run import run_calibration

    def spy(*args, **kwargs):       # round 2's region, from round 1's estimator: the quantile it is given
        region = truncation_region(*args, **kwargs)
        raise _Stop(args[4] if len(args) > 4 else kwargs.get("quantile", QUANTILE), region.threshold)

    monkeypatch.setattr(npe, "truncation_region", spy)
    path = tmp_path / "cal.toml"
    path.write_text(_calibration_text() + "truncation = 0.01\n")
    with pytest.raises(_Stop) as stopped:
        run_calibration(load_calibration(path), tmp_path / "out", progress=False)
    quantile, threshold = stopped.value.args
    assert quantile == 0.01 and np.isfinite(threshold)
