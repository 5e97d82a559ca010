"""BSL-MCMC (analysis.calibration.bsl) on a toy Gaussian simulator with a known posterior.

Toy model: summaries = theta + N(0, SD^2) per component, N_SIM replicates per evaluation, M observed
datasets, prior Uniform(-10, 10) per parameter (wide). The exact posterior is then approximately
N(mean of the observed rows, SD^2 / M) per component.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from flocksweep.analysis.calibration.bsl import run_bsl
from flocksweep.analysis.calibration.mcmc import ChainResult
from flocksweep.analysis.calibration.priors import JointPrior, Uniform

SD = 1.0
N_SIM = 20
M = 4
TRUTH = np.array([1.0, -2.0])


def toy_simulator(calls=None):
    def simulate(theta, rng):
        if calls is not None:
            calls.append(np.array(theta, copy=True))
        return theta[None, :] + SD * rng.standard_normal((N_SIM, theta.size))
    return simulate


def wide_prior(d=2):
    return JointPrior(["a", "b"][:d], [Uniform(-10.0, 10.0)] * d)


def observed_rows():
    rng = np.random.default_rng(20240611)
    return TRUTH + SD * rng.standard_normal((M, TRUTH.size))


def run(steps=50, seed=3, walkers=12, **kw):
    return run_bsl(toy_simulator(), observed_rows(), wide_prior(), walkers=walkers, steps=steps, seed=seed, **kw)


def same(r1: ChainResult, r2: ChainResult) -> bool:
    return (np.array_equal(r1.chain, r2.chain) and np.array_equal(r1.log_prob, r2.log_prob)
            and np.array_equal(r1.acceptance_fraction, r2.acceptance_fraction))


@pytest.mark.slow
def test_posterior_matches_conjugate_normal():
    obs = observed_rows()
    res = run_bsl(toy_simulator(), obs, wide_prior(), walkers=32, steps=400, seed=11)
    assert res.chain.shape == (400, 32, 2) and res.log_prob.shape == (400, 32)
    assert res.names == ("a", "b")
    post = res.chain[150:].reshape(-1, 2)
    exact_mean, exact_sd = obs.mean(axis=0), SD / math.sqrt(M)
    # tolerance: 0.15 = 0.3 posterior sd (Monte Carlo error of ~8000 correlated draws is ~0.04)
    np.testing.assert_allclose(post.mean(axis=0), exact_mean, atol=0.15)
    # BSL with n=20 replicates slightly inflates the posterior; allow 0.7x - 1.5x of the exact sd
    assert np.all(post.std(axis=0) > 0.7 * exact_sd) and np.all(post.std(axis=0) < 1.5 * exact_sd)
    assert np.all((res.acceptance_fraction > 0) & (res.acceptance_fraction < 1))


@pytest.mark.slow
def test_same_seed_bit_identical_different_seed_differs():
    a, b, c = run(seed=5), run(seed=5), run(seed=6)
    assert same(a, b)
    assert not np.array_equal(a.chain, c.chain)


@pytest.mark.slow
@pytest.mark.parametrize("reevaluate_every", [0, 25, 7])
def test_resume_equals_uninterrupted_run(tmp_path, reevaluate_every):
    whole = run(steps=100, path=tmp_path / "whole.h5", reevaluate_every=reevaluate_every)
    part = tmp_path / "part.h5"
    first = run(steps=50, path=part, reevaluate_every=reevaluate_every)
    assert first.chain.shape[0] == 50
    resumed = run(steps=100, path=part, resume=True, reevaluate_every=reevaluate_every)
    assert same(whole, resumed)
    # the file-backed run equals the in-memory run
    assert same(whole, run(steps=100, reevaluate_every=reevaluate_every))
    # a finished file is returned as is
    assert same(whole, run(steps=100, path=part, resume=True, reevaluate_every=reevaluate_every))


def test_existing_file_without_resume_and_mismatched_resume_are_errors(tmp_path):
    p = tmp_path / "c.h5"
    run(steps=5, path=p)
    with pytest.raises(FileExistsError):
        run(steps=10, path=p)
    with pytest.raises(ValueError, match="bsl_seed"):
        run(steps=10, path=p, resume=True, seed=4)
    with pytest.raises(ValueError, match="resume=True needs a path"):
        run(steps=10, resume=True)


@pytest.mark.slow
def test_reevaluation_changes_current_log_prob_and_converges():
    k = 10
    plain = run(steps=200, walkers=16)
    re = run(steps=200, walkers=16, reevaluate_every=k)
    same_pos = np.all(plain.chain[1:] == plain.chain[:-1], axis=2)
    # without re-evaluation an unmoved walker keeps its log_prob exactly
    assert np.array_equal(plain.log_prob[1:][same_pos], plain.log_prob[:-1][same_pos])
    # with it, rows right after a re-evaluation (rows index t with t % k == 0, i.e. chain row t-1 -> t)
    # show new values for walkers that stayed put
    stay = np.all(re.chain[1:] == re.chain[:-1], axis=2)      # stay[j]: row j -> row j+1
    rows = np.arange(stay.shape[0])
    at_reeval = ((rows + 1) % k == 0)[:, None] & stay          # row j+1 was computed after re-eval at t=j+1
    assert at_reeval.sum() > 0
    changed = re.log_prob[1:][at_reeval] != re.log_prob[:-1][at_reeval]
    assert changed.all()
    not_reeval = (~((rows + 1) % k == 0))[:, None] & stay
    assert np.array_equal(re.log_prob[1:][not_reeval], re.log_prob[:-1][not_reeval])
    post = re.chain[80:].reshape(-1, 2)
    np.testing.assert_allclose(post.mean(axis=0), observed_rows().mean(axis=0), atol=0.25)


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_points_outside_prior_are_never_simulated():
    calls = []
    prior = JointPrior(["a", "b"], [Uniform(0.5, 1.5), Uniform(-2.5, -1.5)])  # truth near the middle,
    res = run_bsl(toy_simulator(calls), observed_rows(), prior, walkers=12, steps=60, seed=2)
    thetas = np.array(calls)
    lo, hi = np.array([0.5, -2.5]), np.array([1.5, -1.5])
    assert np.all((thetas >= lo) & (thetas <= hi))
    assert len(calls) < 12 * 61          # some proposals fell outside and were not simulated
    assert np.all((res.chain >= lo) & (res.chain <= hi))


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_nan_rows_dropped_or_minus_inf():
    obs = observed_rows()

    def sim(theta, rng):
        out = theta[None, :] + SD * rng.standard_normal((N_SIM, theta.size))
        if theta[0] > 1.5:
            out[:] = np.nan                 # region where the statistics are undefined: -inf
        else:
            out[:3] = np.nan                 # a few failed replicates: dropped, 17 >= k + 2 remain
        return out

    res = run_bsl(sim, obs, wide_prior(), walkers=12, steps=60, seed=1)
    assert np.all(res.chain[..., 0] <= 1.5)
    assert np.all(np.isfinite(res.log_prob[-1]))


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_progress_callback_and_validation():
    seen = []
    run(steps=20, progress=lambda s, a, tau: seen.append((s, a, tau)), progress_every=5)
    assert [s for s, _, _ in seen] == list(range(1, 21))              # every step: a bar moves with each
    assert all(0.0 <= a <= 1.0 for _, a, _ in seen)
    assert all(math.isnan(t) or t > 0 for _, _, t in seen)
    assert all(math.isnan(t) for s, _, t in seen if s < 5)            # tau: first estimated at step 5,
    taus = {s: t for s, _, t in seen}                                  # then kept until the next estimate
    assert all(taus[s] == taus[s - s % 5] or (math.isnan(taus[s]) and math.isnan(taus[s - s % 5]))
               for s in range(5, 21))
    with pytest.raises(ValueError, match="walkers"):
        run(walkers=3)
    with pytest.raises(ValueError, match="likelihood"):
        run(likelihood="nope")


@pytest.mark.slow
def test_de_moves_are_seeded_resumable_and_recover_the_posterior(tmp_path):
    """moves="de": the posterior is still found, the chain is a function of the seed, a resume continues
    it exactly, and a resume with other moves is refused."""
    full = run(steps=300, moves="de")
    assert same(full, run(steps=300, moves="de"))
    assert not np.array_equal(full.chain, run(steps=300).chain)          # really another proposal
    flat = full.chain[100:].reshape(-1, 2)
    centre, scale = observed_rows().mean(axis=0), SD / math.sqrt(M)
    np.testing.assert_allclose(flat.mean(axis=0), centre, atol=0.5 * scale)
    assert np.all((flat.std(axis=0) > 0.6 * scale) & (flat.std(axis=0) < 1.6 * scale))
    path = tmp_path / "de.h5"
    run(steps=120, moves="de", path=path)
    assert same(run(steps=300, moves="de", path=path, resume=True), full)
    with pytest.raises(ValueError, match="moves"):
        run(steps=310, path=path, resume=True)
    with pytest.raises(ValueError, match="moves"):
        run(steps=10, moves="gibbs")



def gaussian_chain(steps, path=None, resume=False, **kw):
    """run_chain on an exact standard normal log density: a cheap chain for the stopping rule."""
    from flocksweep.analysis.calibration.mcmc import run_chain

    prior = wide_prior()

    def initial(rng, walkers):
        coords = rng.normal(size=(walkers, 2))
        return coords, -0.5 * np.sum(coords ** 2, axis=1)

    return run_chain(lambda c: -0.5 * np.sum(np.atleast_2d(c) ** 2, axis=1), prior, walkers=8, steps=steps, seed=8,
                     initial=initial, path=path, resume=resume, moves="de", **kw)


@pytest.mark.slow
def test_until_converged_stops_at_the_first_check_where_the_verdicts_hold_and_is_resumable(tmp_path):
    from flocksweep.analysis.calibration.diagnostics import sampled_enough

    capped = gaussian_chain(5000, until_converged=True, check_every=20)
    stopped = capped.chain.shape[0]
    assert 100 <= stopped < 5000 and stopped % 20 == 0
    # the verdicts (50 tau, R-hat, ESS) hold at the stopping row and at no earlier check: judged on the prefixes
    assert sampled_enough(capped.chain)
    assert not any(sampled_enough(capped.chain[:t]) for t in range(20, stopped, 20))
    # the same rows as a fixed-length chain of that many steps (stopping changes the length, nothing else)
    assert same(capped, gaussian_chain(stopped))
    # resumed from a shorter file it stops at the same row with the same chain; a stopped file runs nothing
    part = tmp_path / "part.h5"
    gaussian_chain(stopped // 2 - 3, path=part)
    assert same(capped, gaussian_chain(5000, path=part, resume=True, until_converged=True, check_every=20))
    assert same(capped, gaussian_chain(9000, path=part, resume=True, until_converged=True, check_every=20))
    # a cap below the converged length is the length
    assert gaussian_chain(stopped - 20, until_converged=True, check_every=20).chain.shape[0] == stopped - 20
    with pytest.raises(ValueError, match="check_every"):
        gaussian_chain(50, until_converged=True, check_every=1)


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_bsl_passes_the_stopping_rule_to_the_driver():
    # tau cannot be judged on 8 rows: the rule never holds, the cap stands; check_every is validated
    assert run(steps=8, seed=8, until_converged=True, check_every=4).chain.shape[0] == 8
    with pytest.raises(ValueError, match="check_every"):
        run(steps=8, seed=8, until_converged=True, check_every=0)
