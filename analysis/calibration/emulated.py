"""The emulator method's posterior: the emulated likelihood, its emcee chain and the confirmation with real
simulations at the posterior's centre.

Shapes: d free parameters, k statistics, m observed datasets, n points evaluated at once.

Contract
--------
``emulated_loglik(theta (d,), observed (m, k) or (k,), surrogate, obs_cov (k, k) or None) -> float``
    ``sum_i log N(observed_i; mu(theta), D C D + obs_cov + diag(mean_var(theta)))`` with ``D`` the
    diagonal of emulated per-replicate sds and ``C`` the pooled correlation. ``obs_cov`` is the
    targets' covariance (mean with sd or cov; the same observation noise run.py adds to simulated
    summaries) or None (samples targets). ``-inf`` outside the training box (bounds included): the
    emulator must not extrapolate, so the posterior is the prior truncated to the box times this
    likelihood. :func:`~.surrogates.prior_outside_box` lists the parameters whose prior reaches beyond the box.
    ``emulated_logliks(thetas (n, d), ...) -> (n,)`` is the same for many points at once.

``run_emulator_mcmc(surrogate, observed, obs_cov, prior, *, walkers, steps, seed, path=None,
resume=False, progress=None, progress_every=None, moves="stretch") -> ChainResult``
    The one emcee driver (:func:`~analysis.calibration.mcmc.run_chain`: seeds, moves, HDF5 file,
    exact resume, progress) on log posterior = ``prior.logpdf + emulated_loglik`` (no randomness of its
    own). Initial walkers: ``prior.sample(generator(seed, Tag.WALKERS), walkers)``; walkers outside the
    box (or with a -inf log posterior) are replaced, in walker order, by the next acceptable draws of
    the same generator, drawn ``max(64, 4 x walkers)`` at a time, for at most 1000 rounds (then
    RuntimeError with the share accepted: the prior has too little mass in the box). The chain file
    records ``emulator_seed``, ``emulator_fingerprint`` (surrogate, training data, targets, prior) and
    ``emulator_moves``, which a resume must match.

``confirm(config, simulator, surrogate, theta, *, count, seed, stream=()) -> dict``
    ``count`` (>= 2) fresh replicates at theta with ``SummarySimulator.simulate(theta,
    seeds_for(rng, count))``, ``rng = generator(seed, Tag.CONFIRM, *stream)`` (:mod:`sweeps.seeds`;
    ``stream`` = (round,) for the refinement's later rounds). Returns
    ``theta`` (name -> value), ``comparison`` (DataFrame indexed by stat column: emulated_mean,
    emulated_mean_sd, emulated_sd, real_mean, real_sd, n_real, se, z with ``se = sqrt(real_sd^2 /
    n_real + emulated_mean_sd^2)`` and ``z = (real_mean - emulated_mean) / se``, sd_ratio = real_sd /
    emulated_sd), ``predictive`` (:func:`~.diagnostics.predictive_check` of the observed targets
    against the real summaries, with the targets' observation noise added from the same rng when
    mean/sd targets are given), ``summaries`` (count, k) (raw, non-finite rows kept) and ``seeds``.
    It writes no file.

Helpers: ``posterior_median(chain, burn=0) -> (d,)`` (the centre to confirm at);
``observation_covariance(config) -> (k, k) | None`` (the ``obs_cov`` argument for a config).
"""
from __future__ import annotations

import hashlib
import math
from typing import Callable

import numpy as np
import pandas as pd

from flocksweep.sweeps.seeds import Tag, generator, seeds_for

from .checks import integer
from .diagnostics import predictive_check
from .mcmc import ChainResult, run_chain
from .surrogates import EmulatorPrediction, Surrogate, _as_points, _rows, single_threaded_blas

MAX_INITIAL_ROUNDS = 1000
_LOG_2PI = math.log(2.0 * math.pi)


def _observed_rows(observed, k: int) -> np.ndarray:
    return _rows(observed, k, "observed")


def _obs_cov_matrix(obs_cov, k: int) -> np.ndarray:
    if obs_cov is None:
        return np.zeros((k, k))
    obs_cov = np.asarray(obs_cov, dtype=float)
    if obs_cov.shape != (k, k):
        raise ValueError(f"obs_cov must be ({k}, {k}) or None, got {obs_cov.shape}")
    return obs_cov


def _gaussian_logpdf_rows(observed: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(n,) sum over the m observed rows (m, k) of log N(row; mean_i (k,), cov_i (k, k)); -inf where
    cov_i is not positive definite."""
    n, k = mean.shape
    m = observed.shape[0]
    try:
        factors = np.linalg.cholesky(cov)                                   # (n, k, k)
    except np.linalg.LinAlgError:
        return np.array([_gaussian_logpdf_rows(observed, mean[i:i + 1], cov[i:i + 1])[0] if _is_pd(cov[i])
                         else -np.inf for i in range(n)])
    residuals = observed[None, :, :] - mean[:, None, :]                     # (n, m, k)
    z = np.linalg.solve(factors, np.swapaxes(residuals, 1, 2))              # (n, k, m)
    log_det = 2.0 * np.sum(np.log(np.diagonal(factors, axis1=1, axis2=2)), axis=1)
    return -0.5 * np.sum(z * z, axis=(1, 2)) - 0.5 * m * log_det - 0.5 * m * k * _LOG_2PI


def _is_pd(matrix: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        return False
    return True


def emulated_logliks(thetas, observed, surrogate: Surrogate, obs_cov=None) -> np.ndarray:
    """(n,) :func:`emulated_loglik` at each row of ``thetas`` (n, d)."""
    thetas = _as_points(thetas, surrogate.d)
    observed = _observed_rows(observed, surrogate.k)
    extra = _obs_cov_matrix(obs_cov, surrogate.k)
    out = np.full(len(thetas), -np.inf)
    inside = surrogate.inside(thetas) & np.isfinite(thetas).all(axis=1)
    if not inside.any():
        return out
    prediction = surrogate.predict(thetas[inside])
    sd = np.sqrt(prediction.var)
    cov = sd[:, :, None] * surrogate.correlation[None] * sd[:, None, :] + extra[None]
    cov = cov + np.einsum("nk,kl->nkl", prediction.mean_var, np.eye(surrogate.k))
    values = _gaussian_logpdf_rows(observed, prediction.mean, cov)
    out[inside] = np.where(np.isfinite(values), values, -np.inf)
    return out


def emulated_loglik(theta, observed, surrogate: Surrogate, obs_cov=None) -> float:
    """Gaussian log likelihood of ``observed`` under the emulator at ``theta`` (d,); -inf outside the
    training box (see the module docstring)."""
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (surrogate.d,):
        raise ValueError(f"theta must have shape ({surrogate.d},), got {theta.shape}")
    return float(emulated_logliks(theta[None, :], observed, surrogate, obs_cov)[0])


# ----------------------------------------------------------------------------------------------- MCMC

class _EmulatedPosterior:
    """Vectorised log posterior: prior log density + emulated log likelihood, -inf where either is."""

    def __init__(self, surrogate, observed, obs_cov, prior):
        self.surrogate, self.observed, self.obs_cov, self.prior = surrogate, observed, obs_cov, prior

    def __call__(self, thetas) -> np.ndarray:
        thetas = np.asarray(thetas, dtype=float)
        log_prior = np.atleast_1d(np.asarray(self.prior.logpdf(thetas), dtype=float))
        out = np.full(len(thetas), -np.inf)
        finite = np.isfinite(log_prior)
        if finite.any():
            out[finite] = log_prior[finite] + emulated_logliks(thetas[finite], self.observed, self.surrogate,
                                                               self.obs_cov)
        return np.where(np.isnan(out), -np.inf, out)


def _initial_walkers(logpost: _EmulatedPosterior, rng: np.random.Generator, walkers: int):
    """Draws from the prior inside the box: (coords (walkers, d), log_prob (walkers,))."""
    prior = logpost.prior
    d = int(prior.dim)
    coords = np.asarray(prior.sample(rng, walkers), dtype=float).reshape(walkers, d)
    log_prob = logpost(coords)
    drawn, accepted = walkers, int(np.isfinite(log_prob).sum())
    batch = max(64, 4 * walkers)
    for _ in range(MAX_INITIAL_ROUNDS):
        bad = np.flatnonzero(~np.isfinite(log_prob))
        if bad.size == 0:
            return coords, log_prob
        fresh = np.asarray(prior.sample(rng, batch), dtype=float).reshape(batch, d)
        fresh_lp = logpost(fresh)
        good = np.flatnonzero(np.isfinite(fresh_lp))[:bad.size]
        drawn, accepted = drawn + batch, accepted + int(np.isfinite(fresh_lp).sum())
        coords[bad[:good.size]] = fresh[good]
        log_prob[bad[:good.size]] = fresh_lp[good]
    raise RuntimeError(f"could not place {int((~np.isfinite(log_prob)).sum())} initial walkers inside the "
                       f"training box: only {accepted} of {drawn} prior draws had a finite emulated log "
                       "posterior; narrow the prior to the swept range")


def _fingerprint(surrogate: Surrogate, observed, obs_cov, prior) -> str:
    digest = hashlib.sha256(surrogate.fingerprint.encode())
    digest.update(np.ascontiguousarray(observed, dtype=float).tobytes())
    digest.update(_obs_cov_matrix(obs_cov, surrogate.k).tobytes())
    digest.update(repr(prior).encode())
    return digest.hexdigest()[:32]


def run_emulator_mcmc(surrogate: Surrogate, observed, obs_cov, prior, *, walkers: int, steps: int, seed: int,
                      path=None, resume: bool = False, progress: Callable | None = None,
                      progress_every: int | None = None, moves: str = "stretch") -> ChainResult:
    """emcee on the emulated posterior; see the module docstring for the full contract."""
    seed = integer(seed, "seed", 0)
    d = int(prior.dim)
    if d != surrogate.d:
        raise ValueError(f"the prior has {d} parameters, the surrogate {surrogate.d}")
    observed = _observed_rows(observed, surrogate.k)
    logpost = _EmulatedPosterior(surrogate, observed, obs_cov, prior)
    meta = {"emulator_seed": seed, "emulator_fingerprint": _fingerprint(surrogate, observed, obs_cov, prior),
            "emulator_moves": moves}
    with single_threaded_blas():
        return run_chain(logpost, prior, walkers=walkers, steps=steps, seed=seed,
                         initial=lambda rng, count: _initial_walkers(logpost, rng, count), path=path, resume=resume,
                         meta=meta, meta_defaults={"emulator_moves": "stretch"},
                         needs="the same seed, surrogate, training data, targets, prior and moves", moves=moves,
                         progress=progress, progress_every=progress_every)


def posterior_median(chain: np.ndarray, burn: int = 0) -> np.ndarray:
    """(d,) median over walkers and the rows after ``burn`` of a chain (steps, walkers, d)."""
    chain = np.asarray(chain, dtype=float)
    return np.median(chain[burn:].reshape(-1, chain.shape[-1]), axis=0)


# ---------------------------------------------------------------------------------------- confirmation

def observation_covariance(config) -> np.ndarray | None:
    """The targets' (k, k) covariance for mean/sd (or cov) targets, None for samples targets."""
    return None if config.targets.samples_path is not None else np.asarray(config.targets.cov, dtype=float)


def _comparison_table(columns, prediction: EmulatorPrediction, finite: np.ndarray):
    n_real = len(finite)
    real_mean = finite.mean(axis=0) if n_real else np.full(len(columns), np.nan)
    real_sd = finite.std(axis=0, ddof=1) if n_real > 1 else np.full(len(columns), np.nan)
    emulated_mean, emulated_mean_sd = prediction.mean[0], np.sqrt(prediction.mean_var[0])
    emulated_sd = np.sqrt(prediction.var[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        se = np.sqrt(real_sd ** 2 / max(n_real, 1) + emulated_mean_sd ** 2)
        z = (real_mean - emulated_mean) / se
        ratio = real_sd / emulated_sd
    return pd.DataFrame({"emulated_mean": emulated_mean, "emulated_mean_sd": emulated_mean_sd,
                         "emulated_sd": emulated_sd, "real_mean": real_mean, "real_sd": real_sd,
                         "n_real": n_real, "se": se, "z": z, "sd_ratio": ratio},
                        index=pd.Index(list(columns), name="statistic"))


def confirm(config, simulator, surrogate: Surrogate, theta, *, count: int, seed: int, stream: tuple = ()) -> dict:
    """Real simulations at ``theta`` against the emulator and the targets; see the module docstring."""
    count, seed = integer(count, "count", 2), integer(seed, "seed", 0)
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (surrogate.d,):
        raise ValueError(f"theta must have shape ({surrogate.d},), got {theta.shape}")
    rng = generator(seed, Tag.CONFIRM, *stream)
    seeds = seeds_for(rng, count)
    summaries = simulator.with_replicates(count).simulate(theta, seeds)
    finite = summaries[np.isfinite(summaries).all(axis=1)]
    comparison = _comparison_table(config.targets.columns, surrogate.predict(theta), finite)
    cov = observation_covariance(config)
    noisy = finite if cov is None else finite + rng.multivariate_normal(np.zeros(len(cov)), cov, size=len(finite))
    predictive = predictive_check(config.targets.observed, noisy, config.targets.columns)
    return {"theta": dict(zip(config.names, map(float, theta))), "comparison": comparison,
            "predictive": predictive, "summaries": summaries, "seeds": seeds}
