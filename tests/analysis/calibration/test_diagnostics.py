"""Tests for analysis.calibration.diagnostics and analysis.calibration.plots on synthetic chains."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from flocksweep.analysis.calibration import diagnostics as dg
from flocksweep.analysis.calibration import plots
from flocksweep.analysis.calibration.priors import JointPrior, Normal, Uniform


def ar1_chain(rng, steps, walkers, phis, mu=0.0, sigma=1.0):
    """AR(1) chains with stationary mean ``mu``, sd ``sigma``; tau = (1 + phi) / (1 - phi)."""
    phis = np.asarray(phis, dtype=float)
    d = phis.size
    innov = sigma * np.sqrt(1 - phis ** 2)
    out = np.empty((steps, walkers, d))
    x = rng.normal(0.0, sigma, size=(walkers, d))
    noise = rng.normal(size=(steps, walkers, d)) * innov
    for t in range(steps):
        x = phis * x + noise[t]
        out[t] = x
    return out + mu


def true_tau(phi):
    return (1 + phi) / (1 - phi)


def test_tau_matches_ar1_truth():
    rng = np.random.default_rng(1)
    phis = [0.0, 0.5, 0.9]
    chain = ar1_chain(rng, 5000, 32, phis)
    tau = dg.integrated_times(chain)
    for phi, t in zip(phis, tau):
        assert abs(t - true_tau(phi)) / true_tau(phi) < 0.25
    s = dg.posterior_summary(chain, ["a", "b", "c"], np.full(32, 0.3), burn=100)
    for name, phi in zip("abc", phis):
        assert abs(s.loc[name, "tau"] - true_tau(phi)) / true_tau(phi) < 0.25
        expected_ess = 4900 * 32 / true_tau(phi)
        assert abs(s.loc[name, "ess"] - expected_ess) / expected_ess < 0.35


def test_tau_nan_safe_for_constant_parameter():
    rng = np.random.default_rng(2)
    chain = ar1_chain(rng, 500, 8, [0.5, 0.5])
    chain[:, :, 1] = 3.0
    tau = dg.integrated_times(chain)
    assert np.isfinite(tau[0]) and np.isnan(tau[1])
    s = dg.posterior_summary(chain, ["x", "const"], 0.3)
    assert np.isnan(s.loc["const", "ess"]) and s.loc["const", "mean"] == 3.0


def test_iid_gaussian_summary_matches_truth():
    rng = np.random.default_rng(3)
    mu, sigma = np.array([1.0, -2.0]), np.array([0.5, 3.0])
    steps, walkers = 2000, 20
    chain = mu + sigma * rng.normal(size=(steps, walkers, 2))
    acc = rng.uniform(0.25, 0.35, size=walkers)
    s = dg.posterior_summary(chain, ["m", "n"], acc)
    burn = s.attrs["burn"]
    assert 0 < burn <= 10            # tau ~ 1 for iid draws
    n = (steps - burn) * walkers
    for j, name in enumerate(["m", "n"]):
        row = s.loc[name]
        assert abs(row["mean"] - mu[j]) < 4 * sigma[j] / np.sqrt(n)
        assert abs(row["sd"] / sigma[j] - 1) < 4 / np.sqrt(2 * n)
        assert abs(row["median"] - mu[j]) < 5 * sigma[j] / np.sqrt(n)
        for label, q in dg.QUANTILES:
            z = stats.norm.ppf(q)
            se = np.sqrt(q * (1 - q)) / (stats.norm.pdf(z) * np.sqrt(n)) * sigma[j]
            assert abs(row[label] - (mu[j] + z * sigma[j])) < 4 * se
        assert abs(row["tau"] - 1) < 0.25
        assert row["ess"] == pytest.approx(n / row["tau"])
        assert row["acceptance"] == pytest.approx(acc.mean())
    assert list(s.columns) == ["mean", "sd", "median", "q2.5", "q97.5", "q5", "q95", "tau", "ess",
                               "acceptance"]


def test_burn_default_capped_and_thin(monkeypatch):
    rng = np.random.default_rng(4)
    chain = ar1_chain(rng, 60, 16, [0.5])
    monkeypatch.setattr(dg, "integrated_times", lambda c: np.array([7.2]))
    assert dg.posterior_summary(chain, ["a"], 0.3).attrs["burn"] == 15      # ceil(2 x 7.2)
    monkeypatch.setattr(dg, "integrated_times", lambda c: np.array([39.0]))
    s = dg.posterior_summary(chain, ["a"], 0.3)
    assert s.attrs["burn"] == 30                                             # capped at half of 60
    monkeypatch.setattr(dg, "integrated_times", lambda c: np.array([np.nan]))
    assert dg.posterior_summary(chain, ["a"], 0.3).attrs["burn"] == 0
    monkeypatch.undo()
    s2 = dg.posterior_summary(chain, ["a"], 0.3, burn=10, thin=5)
    assert s2.attrs["burn"] == 10 and s2.attrs["thin"] == 5
    with pytest.raises(ValueError):
        dg.posterior_summary(chain, ["a"], 0.3, thin=0)
    with pytest.raises(ValueError):
        dg.posterior_summary(chain, ["a", "b"], 0.3)


def test_convergence_verdicts():
    rng = np.random.default_rng(5)
    long = ar1_chain(rng, 2000, 16, [0.9, 0.5])   # tau ~ 19: 2000 / 19 ~ 105
    short = long[:400]                             # 400 / 19 ~ 21
    c = dg.convergence(long, np.full(16, 0.3))
    assert c["long_enough"] and c["acceptance_ok"] and c["converged"]
    assert 14 < c["max_tau"] < 24 and len(c["tau"]) == 2
    c = dg.convergence(short, 0.3)
    assert not c["long_enough"] and not c["converged"]
    assert "too short" in c["messages"][0] and f"at least {c['steps_needed']} steps" in c["messages"][0]
    assert c["steps_needed"] == c["burn"] + int(np.ceil(50 * c["max_tau"]))
    assert dg.convergence(long, 0.3, burn=0)["burn"] == 0
    with pytest.raises(ValueError, match="burn"):
        dg.convergence(long, 0.3, burn=2000)
    c = dg.convergence(long, np.full(16, 0.1))
    assert c["long_enough"] and not c["acceptance_ok"] and not c["converged"]
    assert any("below 0.2" in m for m in c["messages"])
    assert any("smaller stretch scale" in m for m in c["messages"])                 # the stretch move's advice
    de = dg.convergence(long, np.full(16, 0.1), moves="de")["messages"]
    assert any("below 0.2" in m and "n_sim" in m for m in de) and not any("stretch" in m for m in de)
    assert not dg.convergence(long, 0.7)["acceptance_ok"]


def test_convergence_judges_tau_after_the_burn_in():
    """Walkers starting far out (drawn from a wide prior) contract in a few dozen steps; that transient
    must not be mistaken for slow mixing."""
    rng = np.random.default_rng(8)
    chain = ar1_chain(rng, 1500, 16, [0.8, 0.8])           # tau = 9
    decay = 0.9 ** np.arange(1500)[:, None, None]
    chain = chain + 40.0 * rng.normal(size=(1, 16, 2)) * decay    # start ~40 sd away, contract with tau 10
    whole = dg.integrated_times(chain).max()
    c = dg.convergence(chain, 0.3)
    assert whole > 1.5 * c["max_tau"]                       # the transient inflates the whole-chain estimate
    assert 6 < c["max_tau"] < 13 and c["burn"] > 0 and c["long_enough"]


def test_prior_constraint_warnings():
    rng = np.random.default_rng(6)
    prior = JointPrior(["wide", "narrow", "trunc"],
                       [Uniform(0.0, 1.0), Normal(0.0, 2.0), Normal(0.0, 1.0)],
                       explicit_bounds={"trunc": (-0.5, 0.5)})
    n = 4000
    draws = prior.sample(rng, n)
    draws[:, 1] = rng.normal(0.3, 0.1, size=n)          # posterior sd 0.1 vs prior 2: constrained
    chain = draws.reshape(200, 20, 3)
    s = dg.posterior_summary(chain, prior.names, 0.3, burn=0)
    warns = dg.prior_constraint_warnings(s, prior)
    # "trunc" equals its truncated prior: its sd is ~0.28, far below the parent sd 1; must still warn
    assert len(warns) == 2
    assert warns[0].startswith("wide:") and "do not constrain" in warns[0]
    assert warns[1].startswith("trunc:")
    assert not any(w.startswith("narrow") for w in warns)


def test_predictive_check_tail_probabilities():
    rng = np.random.default_rng(7)
    pred = rng.normal(size=(4000, 3))
    observed = np.array([[0.0, 3.5, -0.1], [0.0, 3.5, 0.1]])   # mean over rows: (0, 3.5, 0)
    df = dg.predictive_check(observed, pred, ["centre", "tail", "rows"])
    assert df.loc["centre", "p"] > 0.9 and df.loc["rows", "p"] > 0.9
    assert df.loc["tail", "p"] < 0.01
    assert df.loc["tail", "observed"] == pytest.approx(3.5)
    assert abs(df.loc["centre", "pred_mean"]) < 0.1 and abs(df.loc["centre", "pred_sd"] - 1) < 0.05
    assert abs(df.loc["centre", "pred_q97.5"] - 1.96) < 0.15
    df1 = dg.predictive_check(np.array([0.0, 3.5, 0.0]), pred, ["a", "b", "c"])
    assert np.allclose(df1["p"].to_numpy(), df["p"].to_numpy())


def _sbc(rng, L, S, shift=0.0, scale=1.0):
    theta = rng.normal(size=(L, 2))
    post = [rng.normal(shift, scale, size=(S, 2)) for _ in range(L)]
    return theta, post


def test_sbc_uniform_for_exact_posterior_and_fails_for_biased():
    rng = np.random.default_rng(8)
    S, bins, L = 99, 20, 1000
    theta, post = _sbc(rng, L, S)
    ranks = dg.sbc_ranks(theta, post)
    assert ranks.shape == (L, 2) and ranks.min() >= 0 and ranks.max() <= S
    res = dg.sbc_uniformity(ranks, S, bins)
    assert (res["p"] > 0.01).all() and (res["dof"] == bins - 1).all()
    theta, post = _sbc(rng, L, S, shift=0.5)
    assert (dg.sbc_uniformity(dg.sbc_ranks(theta, post), S, bins)["p"] < 1e-6).all()
    theta, post = _sbc(rng, L, S, scale=0.6)         # overconfident posterior: U-shaped ranks
    assert (dg.sbc_uniformity(dg.sbc_ranks(theta, post), S, bins)["p"] < 1e-6).all()


def test_sbc_ranks_validation_and_ties():
    ranks = dg.sbc_ranks(np.array([[1.0]]), [np.array([[0.0], [1.0], [1.0], [2.0]])],
                         rng=np.random.default_rng(0))
    assert ranks[0, 0] in (1, 2, 3)
    with pytest.raises(ValueError):
        dg.sbc_ranks(np.zeros((2, 1)), [np.zeros((3, 1)), np.zeros((4, 1))])
    with pytest.raises(ValueError):
        dg.sbc_uniformity(np.array([[5]]), 4, 5)


@pytest.mark.slow
def test_figures_write_png(tmp_path):
    rng = np.random.default_rng(9)
    names = ["alpha", "beta", "gamma"]
    chain = ar1_chain(rng, 300, 12, [0.5, 0.7, 0.2])
    out = plots.trace_figure(chain, names, tmp_path / "trace.png", burn=50)
    assert out.exists() and out.stat().st_size > 0
    samples = chain[50:].reshape(-1, 3)
    out = plots.corner_figure(samples, names, tmp_path / "sub" / "corner.png", truths=[0.0, 0.0, 0.0])
    assert out.exists() and out.stat().st_size > 0
    out = plots.corner_figure(samples[:200], names, tmp_path / "corner_scatter.svg")
    assert out.exists() and out.stat().st_size > 0
    pred = rng.normal(size=(500, 3))
    obs = np.array([0.0, 2.5, -1.0])
    check = dg.predictive_check(obs, pred, names)
    out = plots.predictive_figure(check, pred, obs, names, tmp_path / "ppc.png")
    assert out.exists() and out.stat().st_size > 0
    theta, post = _sbc(rng, 100, 19)
    ranks = dg.sbc_ranks(theta, post)
    out = plots.sbc_figure(ranks, 19, 10, ["p", "q"], tmp_path / "sbc.png")
    assert out.exists() and out.stat().st_size > 0


@pytest.mark.slow
def test_import_does_not_pull_matplotlib():
    import subprocess
    import sys

    code = ("import sys, analysis.calibration.diagnostics, analysis.calibration.plots; "
            "print('matplotlib' in sys.modules)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip() == "False"
