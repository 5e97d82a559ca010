"""Calibration core: one-parameter priors, the joint prior and the Gaussian synthetic likelihood.

Fixed seeds throughout; every tolerance is stated next to its assertion."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from flocksweep.analysis.calibration.likelihood import standardized_distance, synthetic_loglik
from flocksweep.analysis.calibration.priors import (JointPrior, LogUniform, Normal, TruncatedNormal, Uniform,
                                         prior_from_dict)
from flocksweep.simcore.schema import ConfigError

PRIORS = {
    "uniform": (Uniform(-1.0, 3.0), stats.uniform(loc=-1.0, scale=4.0)),
    "loguniform": (LogUniform(0.1, 20.0), stats.loguniform(0.1, 20.0)),
    "normal": (Normal(2.0, 0.5), stats.norm(loc=2.0, scale=0.5)),
    "truncnormal": (TruncatedNormal(1.0, 2.0, 0.0, 2.5),
                    stats.truncnorm((0.0 - 1.0) / 2.0, (2.5 - 1.0) / 2.0, loc=1.0, scale=2.0)),
}


# ---------------------------------------------------------------- one-parameter priors

@pytest.mark.parametrize("name", PRIORS)
def test_logpdf_integrates_to_one_and_matches_scipy(name):
    prior, ref = PRIORS[name]
    low, high = prior.bounds
    m, sd = prior.moments
    a, b = (m - 12 * sd, m + 12 * sd) if np.isinf(low) else (low, high)   # normal: +-12 sd holds 1 - 4e-33
    total, _ = integrate.quad(lambda x: math.exp(prior.logpdf(x)), a, b, limit=200)
    assert total == pytest.approx(1.0, abs=1e-7)
    x = np.linspace(max(low, -5.0), min(high, 8.0), 41)
    np.testing.assert_allclose(prior.logpdf(x), ref.logpdf(x), rtol=1e-10, atol=1e-12)
    u = np.linspace(0.01, 0.99, 25)
    np.testing.assert_allclose(prior.ppf(u), ref.ppf(u), rtol=1e-9, atol=1e-12)
    assert prior.moments == pytest.approx((ref.mean(), ref.std()), rel=1e-9)


@pytest.mark.parametrize("name", PRIORS)
def test_samples_have_right_mean_and_sd(name):
    prior, _ = PRIORS[name]
    rng = np.random.default_rng(20240611)
    n = 100_000
    x = prior.sample(rng, n)
    assert x.shape == (n,)
    mean, sd = prior.moments
    # mean within 5 standard errors sd/sqrt(n)
    assert abs(x.mean() - mean) < 5 * sd / math.sqrt(n)
    # variance within 5 standard errors sqrt((mu4 - sigma^4)/n), mu4 estimated from the sample
    mu4 = np.mean((x - mean) ** 4)
    assert abs(x.var(ddof=1) - sd ** 2) < 5 * math.sqrt((mu4 - sd ** 4) / n)
    lo, hi = prior.bounds
    assert np.all((x >= lo) & (x <= hi))


def test_sampling_is_reproducible_and_needs_a_generator():
    p = TruncatedNormal(0.0, 1.0, -1.0, 1.0)
    np.testing.assert_array_equal(p.sample(np.random.default_rng(3), 5), p.sample(np.random.default_rng(3), 5))
    with pytest.raises(TypeError):
        p.sample(3, 5)


@pytest.mark.parametrize("name", ["uniform", "loguniform", "truncnormal"])
def test_out_of_support_logpdf_is_minus_inf(name):
    prior, _ = PRIORS[name]
    low, high = prior.bounds
    out = prior.logpdf(np.array([low - 1e-9, high + 1e-9, low - 10.0, high + 10.0]))
    assert np.all(out == -np.inf)
    assert np.all(np.isfinite(prior.logpdf(np.array([low, high]))))
    assert np.isnan(prior.ppf(1.5))


@pytest.mark.parametrize("ctor, args, key", [
    (Uniform, (1.0, 1.0), "prior.high"),
    (Uniform, (0.0, math.inf), "prior.high"),
    (LogUniform, (0.0, 1.0), "prior.low"),
    (LogUniform, (2.0, 1.0), "prior.high"),
    (Normal, (0.0, 0.0), "prior.sd"),
    (Normal, (math.nan, 1.0), "prior.mean"),
    (Normal, ("1", 1.0), "prior.mean"),
    (TruncatedNormal, (0.0, -1.0, 0.0, 1.0), "prior.sd"),
    (TruncatedNormal, (0.0, 1.0, 1.0, 0.0), "prior.high"),
])
def test_bad_parameters_raise_config_error_with_key(ctor, args, key):
    with pytest.raises(ConfigError) as err:
        ctor(*args)
    assert err.value.key == key


def test_prior_from_dict_builds_each_family_and_names_bad_keys():
    assert prior_from_dict({"dist": "uniform", "low": 0, "high": 1}) == Uniform(0.0, 1.0)
    assert prior_from_dict({"dist": "loguniform", "low": 1, "high": 10}, "p.s") == LogUniform(1.0, 10.0)
    assert prior_from_dict({"dist": "normal", "mean": 1, "sd": 2}) == Normal(1.0, 2.0)
    assert prior_from_dict({"dist": "truncnormal", "mean": 0, "sd": 1, "low": -1, "high": 2}) == \
        TruncatedNormal(0.0, 1.0, -1.0, 2.0)

    with pytest.raises(ConfigError) as err:
        prior_from_dict({"dist": "uniform", "low": 0, "hihg": 1}, "calibration.prior.speed")
    assert err.value.key == "calibration.prior.speed.hihg"
    assert "did you mean 'high'" in str(err.value)

    with pytest.raises(ConfigError) as err:
        prior_from_dict({"dist": "truncnorm", "mean": 0, "sd": 1}, "p.x")
    assert err.value.key == "p.x.dist" and "did you mean 'truncnormal'" in str(err.value)

    with pytest.raises(ConfigError) as err:
        prior_from_dict({"dist": "normal", "mean": 0}, "p.x")
    assert err.value.key == "p.x.sd"

    with pytest.raises(ConfigError) as err:
        prior_from_dict({"dist": "normal", "mean": 0, "sd": -1}, "p.x")
    assert err.value.key == "p.x.sd" and "-1" in str(err.value)

    with pytest.raises(ConfigError) as err:
        prior_from_dict({"low": 0, "high": 1}, "p.x")
    assert err.value.key == "p.x.dist"


# ---------------------------------------------------------------- joint prior

def test_joint_prior_logpdf_sample_and_bounds():
    jp = JointPrior(["a", "b", "c"], [Uniform(0.0, 2.0), Normal(1.0, 1.0), LogUniform(1.0, 100.0)])
    theta = np.array([[1.0, 0.5, 10.0], [3.0, 0.5, 10.0]])
    expected0 = -math.log(2.0) + stats.norm.logpdf(0.5, 1.0, 1.0) + stats.loguniform.logpdf(10.0, 1.0, 100.0)
    lp = jp.logpdf(theta)
    assert lp.shape == (2,)
    assert lp[0] == pytest.approx(expected0, rel=1e-12)
    assert lp[1] == -np.inf
    assert jp.logpdf(theta[0]) == pytest.approx(expected0, rel=1e-12)
    s = jp.sample(np.random.default_rng(7), 1000)
    assert s.shape == (1000, 3)
    assert np.all(np.isfinite(jp.logpdf(s)))
    assert jp.names == ("a", "b", "c")
    assert jp.bounds == ((0.0, 2.0), (-math.inf, math.inf), (1.0, 100.0))
    assert jp.ppf(np.full((4, 3), 0.5)).shape == (4, 3)
    with pytest.raises(ValueError):
        jp.logpdf(np.zeros(2))


def test_joint_prior_explicit_bounds():
    jp = JointPrior(["a", "b"], [Normal(0.5, 1.0), Uniform(0.0, 1.0)], explicit_bounds={"a": (0.0, 2.0),
                                                                                           "b": (0.0, 1.0)})
    assert jp.bounds == ((0.0, 2.0), (0.0, 1.0))
    assert jp.logpdf([-0.1, 0.5]) == -np.inf
    total, _ = integrate.quad(lambda x: math.exp(jp.marginals[0].logpdf(x)), 0.0, 2.0)
    assert total == pytest.approx(1.0, abs=1e-8)    # truncated normal is renormalised

    cases = [
        ([Normal(3.0, 1.0)], (0.0, 2.0)),                   # normal mean outside the bounds
        ([TruncatedNormal(0.5, 1.0, -1.0, 1.0)], (0.0, 2.0)),  # truncation range not inside
        ([Uniform(0.0, 3.0)], (0.0, 2.0)),
        ([LogUniform(0.1, 2.0)], (0.5, 2.0)),
    ]
    for priors, bounds in cases:
        with pytest.raises(ConfigError) as err:
            JointPrior(["x"], priors, explicit_bounds={"x": bounds})
        assert err.value.key == "prior.x" and "prior outside bounds" in str(err.value)

    with pytest.raises(ConfigError) as err:
        JointPrior(["x"], [Uniform(0, 1)], explicit_bounds={"y": (0, 1)})
    assert err.value.key == "bounds.y"
    with pytest.raises(ConfigError) as err:
        JointPrior(["x"], [Uniform(0, 1)], explicit_bounds={"x": (1, 0)})
    assert err.value.key == "bounds.x"
    with pytest.raises(ConfigError) as err:
        JointPrior(["x", "x"], [Uniform(0, 1), Uniform(0, 1)])
    assert err.value.key == "prior.names"
    with pytest.raises(ConfigError):
        JointPrior(["x", "y"], [Uniform(0, 1)])


# ---------------------------------------------------------------- synthetic likelihood

SIGMA = np.array([[1.0, 0.3, 0.0],
                  [0.3, 0.5, -0.1],
                  [0.0, -0.1, 2.0]])


def mu(theta: float) -> np.ndarray:
    return np.array([theta, 2.0 * theta + 1.0, theta ** 2])


def simulate(theta: float, n: int, rng: np.random.Generator) -> np.ndarray:
    return rng.multivariate_normal(mu(theta), SIGMA, n)


def test_gaussian_converges_to_true_logpdf():
    rng = np.random.default_rng(11)
    theta = 0.7
    y = np.array([0.2, 2.9, 1.5])
    n = 200_000
    got = synthetic_loglik(y, simulate(theta, n, rng))
    true = stats.multivariate_normal.logpdf(y, mu(theta), SIGMA)
    # error ~ O(sqrt((k + maha)/n)) ~ 0.006 here; allow 0.05
    assert got == pytest.approx(true, abs=0.05)

    ys = np.array([y, y + 0.1, y - 0.2])
    got_m = synthetic_loglik(ys, simulate(theta, n, rng))
    true_m = stats.multivariate_normal.logpdf(ys, mu(theta), SIGMA).sum()
    assert got_m == pytest.approx(true_m, abs=0.15)


def test_gaussian_equals_plugin_formula_exactly():
    rng = np.random.default_rng(12)
    sim = simulate(0.0, 30, rng)
    y = np.array([0.1, 0.9, 0.2])
    ref = stats.multivariate_normal.logpdf(y, sim.mean(axis=0), np.cov(sim, rowvar=False, ddof=1))
    assert synthetic_loglik(y, sim) == pytest.approx(ref, rel=1e-10)
    # full shrinkage equals the diagonal-covariance Gaussian
    diag = np.diag(np.var(sim, axis=0, ddof=1))
    ref_d = stats.multivariate_normal.logpdf(y, sim.mean(axis=0), diag)
    assert synthetic_loglik(y, sim, shrinkage=1.0) == pytest.approx(ref_d, rel=1e-10)


@pytest.mark.slow
def test_unbiased_estimator_is_unbiased_for_the_density():
    rng = np.random.default_rng(13)
    theta, n, reps = 0.5, 10, 20_000    # n = k + 7, small on purpose: the plug-in is biased here
    y = np.array([0.9, 1.8, 0.5])
    true = stats.multivariate_normal.pdf(y, mu(theta), SIGMA)
    est = np.array([math.exp(synthetic_loglik(y, simulate(theta, n, rng), method="unbiased"))
                    for _ in range(reps)])
    se = est.std(ddof=1) / math.sqrt(reps)
    # unbiased: mean of the estimates within 4 standard errors of the true density
    assert abs(est.mean() - true) < 4 * se
    assert se < 0.05 * true                                 # the check has power


def test_maximiser_over_theta_grid_is_near_truth():
    theta0 = 1.0
    obs_rng = np.random.default_rng(14)
    observed = obs_rng.multivariate_normal(mu(theta0), SIGMA, 20)   # 20 observed datasets
    grid = np.round(np.arange(0.0, 2.0001, 0.05), 10)
    for method in ("gaussian", "unbiased"):
        ll = [synthetic_loglik(observed, simulate(t, 500, np.random.default_rng(99)), method=method)
              for t in grid]
        best = grid[int(np.argmax(ll))]
        # MLE sd is ~0.05 with 20 datasets; allow 0.2
        assert abs(best - theta0) <= 0.2, (method, best)
    d = [standardized_distance(observed, simulate(t, 500, np.random.default_rng(99))) for t in grid]
    assert abs(grid[int(np.argmin(d))] - theta0) <= 0.2


def test_standardized_distance_matches_diagonal_formula():
    rng = np.random.default_rng(15)
    sim = simulate(0.3, 50, rng)
    y = np.array([[0.0, 1.0, 0.0], [1.0, 2.0, 0.5]])
    z = (y - sim.mean(axis=0)) / sim.std(axis=0, ddof=1)
    assert standardized_distance(y, sim) == pytest.approx(np.sum(z ** 2), rel=1e-12)


def test_too_few_replicates_raise_with_the_minimum():
    rng = np.random.default_rng(16)
    y = np.zeros(3)
    with pytest.raises(ValueError, match="at least 5"):
        synthetic_loglik(y, simulate(0.0, 4, rng))               # gaussian needs n >= k + 2 = 5
    assert np.isfinite(synthetic_loglik(y, simulate(0.0, 5, rng)))
    with pytest.raises(ValueError, match="at least 7"):
        synthetic_loglik(y, simulate(0.0, 6, rng), method="unbiased")   # needs n > k + 3
    assert isinstance(synthetic_loglik(y, simulate(0.0, 7, rng), method="unbiased"), float)
    with pytest.raises(ValueError):
        synthetic_loglik(np.zeros(2), simulate(0.0, 10, rng))    # wrong k
    with pytest.raises(ValueError):
        synthetic_loglik(np.array([np.nan, 0, 0]), simulate(0.0, 10, rng))


def test_bad_method_and_shrinkage_are_config_errors():
    sim = simulate(0.0, 20, np.random.default_rng(17))
    with pytest.raises(ConfigError) as err:
        synthetic_loglik(np.zeros(3), sim, method="gauss")
    assert err.value.key == "likelihood.method"
    for bad in (-0.1, 1.5, "0.5"):
        with pytest.raises(ConfigError) as err:
            synthetic_loglik(np.zeros(3), sim, shrinkage=bad)
        assert err.value.key == "likelihood.shrinkage"
    with pytest.raises(ConfigError):
        synthetic_loglik(np.zeros(3), sim, method="unbiased", shrinkage=0.5)


def test_constant_column_is_dropped_when_matched_and_minus_inf_otherwise():
    rng = np.random.default_rng(18)
    sim2 = simulate(0.0, 40, rng)[:, :2]
    sim = np.column_stack([sim2, np.full(40, 3.0)])       # third statistic is deterministic
    y2 = np.array([0.2, 0.8])
    for method in ("gaussian", "unbiased"):
        matched = synthetic_loglik(np.append(y2, 3.0), sim, method=method)
        assert matched == pytest.approx(synthetic_loglik(y2, sim2, method=method), rel=1e-12)
        assert synthetic_loglik(np.append(y2, 3.1), sim, method=method) == -np.inf
    assert standardized_distance(np.append(y2, 3.0), sim) == pytest.approx(standardized_distance(y2, sim2))
    assert standardized_distance(np.append(y2, 3.1), sim) == np.inf
    # all columns constant and matched: log-likelihood 0 (point mass)
    assert synthetic_loglik(np.array([1.0, 0.0]), np.tile([1.0, 0.0], (5, 1))) == 0.0


def test_singular_covariance_needs_shrinkage():
    rng = np.random.default_rng(19)
    x = rng.normal(size=50)
    sim = np.column_stack([x, 2.0 * x])
    with pytest.raises(ValueError, match="shrinkage"):
        synthetic_loglik(np.array([0.0, 0.0]), sim)
    assert np.isfinite(synthetic_loglik(np.array([0.0, 0.0]), sim, shrinkage=0.1))
