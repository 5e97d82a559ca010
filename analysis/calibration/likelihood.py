"""Synthetic likelihood of observed summary statistics (Wood 2010; Price et al. 2018).

At a parameter vector the caller simulates ``n`` replicates and computes ``k`` summary statistics for
each (``simulated``, shape (n, k)). :func:`synthetic_loglik` fits a Gaussian to them and evaluates the
observed statistics (``observed``, shape (k,) or (m, k)) under it; for m observed datasets the
per-dataset log-likelihoods are summed (independent datasets).

Methods
-------
``"gaussian"``  plug-in estimate: sample mean and covariance (ddof=1), log N(y; mu_hat, Sigma_hat).
                Needs n >= k + 2 (so the covariance has n - 1 > k degrees of freedom).
``"unbiased"``  log of the unbiased estimator of the Gaussian density N(y; mu, Sigma) of Ghurye & Olkin
                (1969), as used by Price et al. (2018). With M = (n-1) Sigma_hat and
                q = (y - mu_hat)' M^{-1} (y - mu_hat) / (1 - 1/n) it is
                (2 pi)^{-k/2} c(k, n-2) / (c(k, n-1) (1-1/n)^{k/2}) |M|^{-1/2} (1 - q)^{(n-k-3)/2}
                for q < 1 and 0 otherwise (log: -inf), where
                c(k, v) = 2^{-kv/2} pi^{-k(k-1)/4} / prod_{i=1..k} Gamma((v-i+1)/2).
                The *density* estimate is unbiased; its log is not. Needs n >= k + 4 (n > k + 3).
                For m observed datasets the logs are summed (the product of independent unbiased
                estimates from one simulation set is not exactly unbiased for the product).

Shrinkage (``"gaussian"`` only): ``shrinkage=lam`` in [0, 1] uses (1 - lam) Sigma_hat + lam diag(Sigma_hat),
shrinking correlations toward zero; useful when n is small relative to k.

Degenerate cases (decision)
---------------------------
* A *constant* summary column (sample sd <= 1e-12 * |column mean|, i.e. exactly constant up to rounding)
  is a deterministic statistic: if the observed value equals the constant (relative tolerance 1e-9; exact
  when the constant is 0) the column carries no information and is dropped from the Gaussian; if it
  differs, the observed data are impossible under the fit and the result is ``-inf``. No floor variance
  is invented (a floor would make the value depend on an arbitrary scale). The minimum-n check uses the
  full k.
* A singular covariance among the remaining columns (e.g. one column a multiple of another) raises
  ValueError suggesting ``shrinkage``.
* n below the minimum raises ValueError stating the minimum; non-finite input raises ValueError.

:func:`standardized_distance` is sum_j ((y_j - mean_j) / sd_j)^2 over columns (and observed rows) with the
simulated sd (ddof=1): a cheap objective for optimisation. Constant columns follow the same rule
(0 when matched, ``inf`` otherwise).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import linalg, special

from flocksweep.simcore.schema import ConfigError

METHODS = ("gaussian", "unbiased")
CONSTANT_RTOL = 1e-12
MATCH_RTOL = 1e-9
_LOG_2PI = math.log(2.0 * math.pi)


def min_replicates(k: int, method: str) -> int:
    """Fewest simulated replicates the ``method`` estimator accepts for ``k`` statistics."""
    return k + 2 if method == "gaussian" else k + 4


def _arrays(observed, simulated) -> tuple[np.ndarray, np.ndarray]:
    obs = np.asarray(observed, dtype=float)
    sim = np.asarray(simulated, dtype=float)
    if sim.ndim != 2:
        raise ValueError(f"simulated must have shape (n, k), got shape {sim.shape}")
    k = sim.shape[1]
    if obs.ndim == 1:
        obs = obs[None, :]
    if obs.ndim != 2 or obs.shape[1] != k:
        raise ValueError(f"observed must have shape ({k},) or (m, {k}) to match simulated {sim.shape}, "
                         f"got shape {np.shape(observed)}")
    if k == 0 or obs.shape[0] == 0:
        raise ValueError("need at least one summary statistic and one observed dataset")
    if not (np.all(np.isfinite(obs)) and np.all(np.isfinite(sim))):
        raise ValueError("observed and simulated summaries must be finite (found nan or inf)")
    return obs, sim


def _constant_columns(obs, mean, sd) -> tuple[np.ndarray, bool]:
    """(mask of constant columns, whether every observed row matches them)."""
    const = sd <= CONSTANT_RTOL * np.abs(mean)
    if not const.any():
        return const, True
    diff = np.abs(obs[:, const] - mean[const])
    matched = bool(np.all(diff <= MATCH_RTOL * np.abs(mean[const])))
    return const, matched


def _log_c(k: int, v: float) -> float:
    i = np.arange(1, k + 1)
    return (-0.5 * k * v * math.log(2.0) - 0.25 * k * (k - 1) * math.log(math.pi)
            - float(np.sum(special.gammaln(0.5 * (v - i + 1)))))


def synthetic_loglik(observed, simulated, method: str = "gaussian", shrinkage: float | None = None) -> float:
    """Gaussian synthetic log-likelihood of ``observed`` (k,) or (m, k) given ``simulated`` (n, k).

    See the module docstring for the methods, the minimum n and the degenerate-case rules."""
    if method not in METHODS:
        raise ConfigError("likelihood.method", f"unknown method {method!r}; allowed: {', '.join(METHODS)}")
    if shrinkage is not None:
        if isinstance(shrinkage, bool) or not isinstance(shrinkage, (int, float)) \
                or not 0.0 <= float(shrinkage) <= 1.0:
            raise ConfigError("likelihood.shrinkage", f"must be a number in [0, 1] or None, got {shrinkage!r}")
        if method == "unbiased":
            raise ConfigError("likelihood.shrinkage", "shrinkage is only allowed with method='gaussian' "
                                                      "(the unbiased estimator needs the raw covariance)")
    obs, sim = _arrays(observed, simulated)
    n, k = sim.shape
    need = min_replicates(k, method)
    if n < need:
        rule = "n >= k + 2" if method == "gaussian" else "n > k + 3"
        raise ValueError(f"method={method!r} needs at least {need} simulated replicates for k={k} "
                         f"summary statistics ({rule}), got n={n}")

    mean = sim.mean(axis=0)
    sd = sim.std(axis=0, ddof=1)
    const, matched = _constant_columns(obs, mean, sd)
    if not matched:
        return -math.inf
    keep = ~const
    if not keep.any():
        return 0.0
    sim, obs, mean = sim[:, keep], obs[:, keep], mean[keep]
    k = sim.shape[1]
    centred = sim - mean
    cov = centred.T @ centred / (n - 1)
    if shrinkage:
        lam = float(shrinkage)
        cov = (1.0 - lam) * cov + lam * np.diag(np.diag(cov))
    try:
        chol = linalg.cholesky(cov, lower=True)
    except linalg.LinAlgError:
        raise ValueError("simulated summaries have a singular covariance (linearly dependent columns); "
                         "drop redundant statistics or pass shrinkage in (0, 1]") from None
    logdet = 2.0 * float(np.sum(np.log(np.diag(chol))))
    resid = linalg.solve_triangular(chol, (obs - mean).T, lower=True)   # (k, m)
    maha = np.sum(resid * resid, axis=0)                                # (m,) under Sigma_hat

    if method == "gaussian":
        return float(np.sum(-0.5 * (k * _LOG_2PI + logdet + maha)))

    # unbiased (Ghurye & Olkin): M = (n-1) Sigma_hat, q = d' M^{-1} d / (1 - 1/n)
    shrink = 1.0 - 1.0 / n
    q = maha / ((n - 1) * shrink)
    if np.any(q >= 1.0):
        return -math.inf
    logdet_m = logdet + k * math.log(n - 1)
    const_term = (-0.5 * k * _LOG_2PI + _log_c(k, n - 2) - _log_c(k, n - 1) - 0.5 * k * math.log(shrink))
    per_obs = const_term - 0.5 * logdet_m + 0.5 * (n - k - 3) * np.log1p(-q)
    return float(np.sum(per_obs))


def standardized_distance(observed, simulated) -> float:
    """sum over observed rows and columns of ((observed - sim mean) / sim sd)^2, sd with ddof=1.

    Diagonal only (correlations ignored). Constant columns: 0 when matched, ``inf`` otherwise.
    Needs n >= 2 replicates."""
    obs, sim = _arrays(observed, simulated)
    if sim.shape[0] < 2:
        raise ValueError(f"standardized_distance needs at least 2 simulated replicates, got n={sim.shape[0]}")
    mean = sim.mean(axis=0)
    sd = sim.std(axis=0, ddof=1)
    const, matched = _constant_columns(obs, mean, sd)
    if not matched:
        return math.inf
    z = (obs[:, ~const] - mean[~const]) / sd[~const]
    return float(np.sum(z * z))
