"""The npe method (analysis.calibration.npe, npe_flow, posterior_command): a toy simulator with an
analytic posterior, determinism of training, the coverage check catching a mis-specified estimator, and
the amortised path (a stored estimator reused: no simulation counted; many flocks at once)."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats

pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")

from flocksweep.analysis.calibration.config import load_calibration  # noqa: E402
from flocksweep.analysis.calibration.npe import coverage_check, estimator_identity  # noqa: E402
from flocksweep.analysis.calibration.npe_flow import (MEMBER_SEED_STEP, Ensemble, FlowSettings, load_estimator,  # noqa: E402
                                           train_ensemble, train_flow)
from flocksweep.cli import main  # noqa: E402
from npe_tiny import CALIBRATION  # noqa: E402
from flocksweep.simcore.schema import ConfigError  # noqa: E402

REPLICATES = 4          # x = mean of 4 unit-variance draws around theta: posterior N(x, 1/4) (flat prior)
# batches of 200 at a learning rate of 3e-3: a quarter of the steps of batches of 50 at 1e-3 (measured at
# x = 1: mean 0.966, sd 0.488; coverage of the 200 held-out truths 0.425 and 0.870 against the exact 0.46
# and 0.88; with batches of 50 at 1e-3: 0.970, 0.484, 0.420 and 0.865)
SMALL = FlowSettings(width=32, layers=2, max_epochs=400, patience=40, learning_rate=3e-3, batch_size=200)


def toy(n: int, seed: int):
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-5, 5, (n, 1))
    return theta, theta + rng.normal(0, 1, (n, 1)) / np.sqrt(REPLICATES)


@pytest.fixture(scope="module")
def trained():
    theta, x = toy(2000, 0)
    return train_flow(theta, x, SMALL, seed=3)


@pytest.mark.slow
def test_gaussian_mean_posterior_recovered(trained):
    # analytic posterior at x = 1: N(1, 0.5^2) (the prior's edges at -5, 5 are 12 sd away)
    draws = trained.sample([1.0], 4000, seed=1)
    assert abs(draws.mean() - 1.0) < 0.1
    assert 0.42 < draws.std() < 0.58


@pytest.mark.slow
def test_a_support_holding_little_of_the_posterior_is_filled_by_wider_batches(trained):
    # theta > 2.2 holds 0.8 % of N(1, 0.5^2) (the flow's lighter tail less): under 41 of the 5,100 draws
    # of the row-wise redraws, so the wide batches (64 x 100 at a time) find the rest; theta > 4.5 (7 sd)
    # holds none of them
    draws = trained.sample([1.0], 100, seed=2, support=lambda t: t[:, 0] > 2.2)
    assert draws.shape == (100, 1) and (draws[:, 0] > 2.2).all()
    assert trained.last_leakage > 0.9
    with pytest.raises(ValueError, match="almost no mass"):
        trained.sample([1.0], 100, seed=2, support=lambda t: t[:, 0] > 4.5)


@pytest.mark.slow
def test_training_is_deterministic_given_the_seed_and_the_stored_estimator_rebuilds(tmp_path):
    theta, x = toy(300, 0)
    quick = FlowSettings(width=16, layers=2, max_epochs=15, patience=15)
    trained = train_flow(theta, x, quick, seed=3)
    again = train_flow(theta, x, quick, seed=3)
    assert again.losses == trained.losses
    assert np.array_equal(again.sample([0.5], 200, seed=2), trained.sample([0.5], 200, seed=2))
    other = train_flow(theta, x, quick, seed=4)
    assert not np.array_equal(other.sample([0.5], 200, seed=2), trained.sample([0.5], 200, seed=2))
    trained.save(tmp_path / "est")
    loaded = load_estimator(tmp_path / "est")
    assert np.array_equal(loaded.sample_many([[0.5], [2.0]], 100, seed=5), trained.sample_many([[0.5], [2.0]], 100, seed=5))


@pytest.mark.slow
def test_an_ensemble_is_the_mixture_of_its_members_and_rebuilds_from_its_folder(tmp_path):
    theta, x = toy(300, 0)
    quick = FlowSettings(width=16, layers=2, max_epochs=15, patience=15)
    single = train_ensemble(theta, x, quick, seed=3, members=1)
    assert not isinstance(single, Ensemble)               # one member: the flow itself
    ensemble = train_ensemble(theta, x, quick, seed=3, members=2)
    assert ensemble.members[0].losses == single.losses    # member i is train_flow(..., seed + i)
    assert ensemble.members[1].losses != single.losses
    # the mixture's 200 draws are the members' 100 draws each (seed + i x MEMBER_SEED_STEP), shuffled
    draws = ensemble.sample([0.5], 200, seed=5)
    parts = np.concatenate([m.sample([0.5], 100, seed=5 + MEMBER_SEED_STEP * i) for i, m in enumerate(ensemble.members)])
    assert np.array_equal(np.sort(draws, axis=0), np.sort(parts, axis=0))
    assert not np.array_equal(draws, parts)
    grid = np.linspace(-1, 2, 7)[:, None]
    mean_density = np.mean([np.exp(m.log_prob(grid, [0.5])) for m in ensemble.members], axis=0)
    assert np.allclose(np.exp(ensemble.log_prob(grid, [0.5])), mean_density, rtol=1e-6)
    ensemble.save(tmp_path / "est")
    loaded = load_estimator(tmp_path / "est")
    assert isinstance(loaded, Ensemble) and len(loaded.members) == 2
    assert np.array_equal(loaded.sample([0.5], 200, seed=5), draws)


class Shrunk:
    """A deliberately mis-specified estimator: the trained one's draws squeezed to a third of their spread
    (over-confident), as a flow trained on too few simulations or the wrong noise model can be."""

    def __init__(self, estimator):
        self.estimator = estimator

    def sample_many(self, x, count, seed, support=None, short="raise"):
        draws = self.estimator.sample_many(x, count, seed, support, short)
        centre = draws.mean(axis=1, keepdims=True)
        return centre + (draws - centre) / 3


@pytest.mark.slow
def test_coverage_check_passes_the_trained_estimator_and_catches_a_misspecified_one(trained):
    theta, x = toy(200, 99)   # held out: not in the training set
    good = coverage_check(trained, theta, x, draws=199, seed=1, support=None, tolerance=0.05, names=["mu"])
    assert good["passed"], good["messages"]
    for level in (0.5, 0.9):   # the exact posterior N(x, 1/4) covers 46 % and 88 % of these 200 truths
        exact = np.mean(np.abs(theta - x) <= stats.norm.ppf((1 + level) / 2) / np.sqrt(REPLICATES))
        found = good["table"].query("level == @level")["coverage"].iloc[0]
        assert abs(found - exact) <= 0.06, (level, found, exact)
    bad = coverage_check(Shrunk(trained), theta, x, draws=199, seed=1, support=None, tolerance=0.05, names=["mu"])
    assert not bad["passed"]
    assert "coverage FAILED" in bad["messages"][0]
    ninety = bad["table"].query("level == 0.9")["coverage"].iloc[0]
    assert ninety < 0.6   # a third of the width covers about 2 x Phi(1.645 / 3) - 1 = 42 %


def test_npe_settings_are_validated_before_anything_runs(tmp_path):
    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION.replace("simulations = 60", "simulations = 5"))
    with pytest.raises(ConfigError, match="method.simulations"):
        load_calibration(path)
    path.write_text(CALIBRATION.replace("width = 16", "widht = 16"))
    with pytest.raises(ConfigError, match="width"):
        load_calibration(path)
    path.write_text(CALIBRATION.replace("draws = 400", "draws = 400\nensemble = 0"))
    with pytest.raises(ConfigError, match="ensemble"):
        load_calibration(path)


def test_the_estimator_identity_ignores_the_observed_values_but_not_their_sd(tmp_path):
    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION)
    base = estimator_identity(load_calibration(path))
    assert estimator_identity(load_calibration(path, ["targets.mean=[4.0, 0.3]"])) == base
    assert estimator_identity(load_calibration(path, ["targets.sd=[0.2, 0.02]"])) != base
    assert estimator_identity(load_calibration(path, ["method.ensemble=3"])) != base
    assert estimator_identity(load_calibration(path, ["method.ensemble=1"])) == base   # the default


@pytest.mark.slow
def test_calibrate_trains_once_then_reuses_the_estimator_and_posterior_serves_many_flocks(tmp_path, capsys):
    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION)
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress"]) == 0
    first = json.loads((out / "convergence.json").read_text())
    assert first["accounting"]["simulations"]["training"] == 60
    assert first["accounting"]["simulations"]["heldout"] == 20
    assert not first["npe"]["reused"] and "training_runs_reused" not in first["accounting"]
    for name in ("posterior.nc", "posterior.csv", "corner.png", "coverage.csv", "coverage_ranks.png", "report.html"):
        assert (out / name).is_file(), name
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress",
                 "--set", "targets.mean=[4.0, 0.25]"]) == 0
    second = json.loads((out / "convergence.json").read_text())
    assert second["npe"]["reused"]
    assert "training" not in second["accounting"]["simulations"]
    assert "heldout" not in second["accounting"]["simulations"]
    assert second["accounting"]["training_runs_reused"] == 20     # the held-out runs it needs, found stored
    flocks = pd.DataFrame({"flight": ["a", "b", "c"], "visible_mean_mean": [2.5, 3.0, 4.0],
                           "binocular_share_mean": [0.15, 0.2, 0.25]})
    flocks.to_csv(tmp_path / "flocks.csv", index=False)
    capsys.readouterr()
    assert main(["posterior", str(out / "estimator"), "--targets", str(tmp_path / "flocks.csv"),
                 "--out", str(tmp_path / "post.csv")]) == 0
    said = capsys.readouterr().out.splitlines()
    assert said[-2:] == ["next:", f'  pandas.read_csv("{tmp_path / "post.csv"}")   (one posterior per row: mean, sd, '
                                  'median, 5% and 95% quantiles)']
    table = pd.read_csv(tmp_path / "post.csv")
    assert list(table["flight"]) == ["a", "b", "c"]
    assert ((table["field_q5"] >= 60) & (table["field_q95"] <= 300)).all()
    # a damaged estimator of its own is set aside and trained again (its training runs found stored) ...
    import shutil

    shutil.copytree(out / "estimator", tmp_path / "kept")
    member = next(p for p in sorted((out / "estimator").rglob("*")) if p.is_file() and p.name != "manifest.json")
    member.write_bytes(member.read_bytes() + b"\0")
    capsys.readouterr()
    assert main(["calibrate", str(path), "--out", str(out), "--no-progress"]) == 0
    third = json.loads((out / "convergence.json").read_text())
    assert not third["npe"]["reused"] and "training" not in third["accounting"]["simulations"]
    assert any((out / "quarantine").iterdir()) and "cannot be trusted" in capsys.readouterr().err
    # ... and one named by method.estimator is refused, naming the key, before anything is trained
    kept = next(p for p in sorted((tmp_path / "kept").rglob("*")) if p.is_file() and p.name != "manifest.json")
    kept.write_bytes(kept.read_bytes() + b"\0")
    assert main(["calibrate", str(path), "--out", str(tmp_path / "elsewhere"), "--no-progress",
                 "--set", f"method.estimator={tmp_path / 'kept'}"]) == 2
    assert "method.estimator" in capsys.readouterr().err
