"""MCMC diagnostics for calibration runs: posterior summaries, convergence verdicts, prior-constraint
warnings, posterior predictive checks and simulation-based calibration (SBC).

Chains are arrays of shape ``(steps, walkers, d)`` as produced by ``emcee.EnsembleSampler.get_chain()``;
``acceptance`` is the per-walker acceptance fraction (shape ``(walkers,)``) or a single number.

Functions:

``integrated_times(chain)``
    integrated autocorrelation time of each parameter (``emcee.autocorr.integrated_time`` with
    ``tol=0``), ``nan`` where it cannot be estimated (constant or non-finite parameter).
``posterior_summary(chain, names, acceptance, burn=None, thin=1)``
    one row per parameter (index ``parameter``): ``mean, sd, median, q2.5, q97.5, q5, q95, tau, ess,
    acceptance``. ``burn`` defaults to ``2 x`` the largest tau of the whole chain, capped at half the
    chain. Moments/quantiles use ``chain[burn::thin]`` pooled over walkers; ``tau`` is estimated on
    ``chain[burn:]`` (unthinned, in steps) and ``ess = steps_after_burn * walkers / tau``.
``convergence(chain, acceptance, burn=None)``
    plain verdicts ``long_enough`` (the steps after burn-in >= 50 x the largest tau estimated on them),
    ``acceptance_ok`` (mean in [0.2, 0.5]), ``converged`` (both), the numbers and ``messages`` (plain
    sentences). ``burn`` defaults as in ``posterior_summary``. The autocorrelation time is estimated
    after the burn-in because the walkers' initial contraction from the prior would otherwise dominate
    the estimate (a chain that mixes well after 70 steps would look as if tau were twice its value).
``long_enough(chain)``
    the chain-length verdict of ``convergence`` alone (False for fewer than 4 rows).
``sampled_enough(chain)``
    the verdicts a longer chain can change, as ``convergence.json`` computes them: ``long_enough`` and,
    on the rows after the default burn-in with walkers as chains, ArviZ's largest R-hat <= 1.01 and
    smallest bulk and tail ESS >= 400 (:func:`chain_ess_rhat`): the rule a chain run
    ``until_converged`` stops by. Acceptance is left out (more steps do not change it).
``chain_ess_rhat(chain, names=None)``
    ArviZ's ``r_hat``, ``ess_bulk``, ``ess_tail`` per parameter of a chain (steps, walkers, d), walkers
    as chains (the numbers ``arviz.summary`` gives for the posterior.nc of that chain).
``arviz_verdicts(diagnostics)``
    from ArviZ's per-parameter ``r_hat, ess_bulk, ess_tail`` (:func:`~.inference.arviz_diagnostics`):
    ``rhat_max``, ``ess_bulk_min``, ``ess_tail_min``, ``rhat_ok`` (max R-hat <= 1.01) and ``ess_ok``
    (bulk and tail ESS >= 400 everywhere; Vehtari et al. 2021) with plain ``messages``.
``prior_constraint_warnings(summary, prior)``
    a sentence for each parameter whose posterior sd exceeds 0.8 x its prior marginal's sd.
``predictive_check(observed, predictive, names)``
    per statistic: ``observed, pred_mean, pred_sd, pred_q2.5, pred_q97.5, p`` with the two-sided tail
    probability ``p = 2 min(P(pred <= obs), P(pred >= obs))`` (capped at 1).
``sbc_ranks(prior_draws, posterior_samples, rng=None)`` / ``sbc_uniformity(ranks, S, bins)``
    SBC ranks (Talts et al. 2018) and a chi-square uniformity test per parameter.
"""
from __future__ import annotations

import math
import warnings
from typing import Sequence

import numpy as np
import pandas as pd
from emcee.autocorr import integrated_time
from scipy import stats

TAU_FACTOR = 50            # chain length should be at least this many autocorrelation times
BURN_FACTOR = 2            # default burn-in in autocorrelation times
ACCEPTANCE_RANGE = (0.2, 0.5)
PRIOR_SD_RATIO = 0.8       # posterior sd above this fraction of the prior sd: "not constrained"
RHAT_MAX = 1.01            # Vehtari et al. (2021): rank-normalised split R-hat below 1.01
ESS_MIN = 400              # and bulk and tail effective sample sizes of at least 400
QUANTILES = (("q2.5", 0.025), ("q97.5", 0.975), ("q5", 0.05), ("q95", 0.95))


def _chain(chain) -> np.ndarray:
    chain = np.asarray(chain, dtype=float)
    if chain.ndim != 3:
        raise ValueError(f"chain must have shape (steps, walkers, d), got shape {chain.shape}")
    if chain.shape[0] < 2 or chain.shape[1] < 1 or chain.shape[2] < 1:
        raise ValueError(f"chain needs at least 2 steps, 1 walker and 1 parameter, got shape {chain.shape}")
    return chain


def _names(names: Sequence[str] | None, d: int) -> list[str]:
    if names is None:
        return [f"theta{j}" for j in range(d)]
    names = [str(n) for n in names]
    if len(names) != d:
        raise ValueError(f"got {len(names)} names for {d} parameters")
    return names


def _mean_acceptance(acceptance) -> float:
    a = np.asarray(acceptance, dtype=float).ravel()
    a = a[np.isfinite(a)]
    return float(a.mean()) if a.size else math.nan


def integrated_times(chain) -> np.ndarray:
    """Integrated autocorrelation time per parameter, shape (d,); ``nan`` where it cannot be estimated."""
    chain = _chain(chain)
    out = np.full(chain.shape[2], np.nan)
    for j in range(chain.shape[2]):
        x = chain[:, :, j:j + 1]
        if not np.all(np.isfinite(x)) or np.ptp(x, axis=0).max() == 0.0:
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                tau = float(np.asarray(integrated_time(x, tol=0)).ravel()[0])
        except Exception:   # emcee raises for degenerate input; report "unknown"
            continue
        if math.isfinite(tau) and tau > 0:
            out[j] = tau
    return out


def _max_tau(tau: np.ndarray) -> float:
    finite = tau[np.isfinite(tau)]
    return float(finite.max()) if finite.size else math.nan


def default_burn(chain) -> int:
    """``2 x`` the largest autocorrelation time (rounded up), at most half the chain; 0 if unknown."""
    chain = _chain(chain)
    max_tau = _max_tau(integrated_times(chain))
    if not math.isfinite(max_tau):
        return 0
    return int(min(math.ceil(BURN_FACTOR * max_tau), chain.shape[0] // 2))


def posterior_summary(chain, names: Sequence[str] | None, acceptance, burn: int | None = None,
                      thin: int = 1) -> pd.DataFrame:
    """Per-parameter posterior summary (see the module docstring)."""
    chain = _chain(chain)
    steps, walkers, d = chain.shape
    names = _names(names, d)
    if isinstance(thin, bool) or int(thin) != thin or thin < 1:
        raise ValueError(f"thin must be a positive integer, got {thin!r}")
    thin = int(thin)
    if burn is None:
        burn = default_burn(chain)
    if isinstance(burn, bool) or int(burn) != burn or not 0 <= burn < steps:
        raise ValueError(f"burn must be an integer in [0, {steps - 1}], got {burn!r}")
    burn = int(burn)
    kept = chain[burn:]
    n_after = kept.shape[0]
    tau = integrated_times(kept) if n_after >= 2 else np.full(d, np.nan)
    flat = kept[::thin].reshape(-1, d)
    acc = _mean_acceptance(acceptance)
    rows = []
    for j, name in enumerate(names):
        x = flat[:, j]
        x = x[np.isfinite(x)]
        row = {"parameter": name}
        if x.size:
            row["mean"] = float(x.mean())
            row["sd"] = float(x.std(ddof=1)) if x.size > 1 else math.nan
            row["median"] = float(np.median(x))
            for label, q in QUANTILES:
                row[label] = float(np.quantile(x, q))
        else:
            row.update({k: math.nan for k in ("mean", "sd", "median", *(q[0] for q in QUANTILES))})
        row["tau"] = float(tau[j])
        row["ess"] = float(n_after * walkers / tau[j]) if math.isfinite(tau[j]) else math.nan
        row["acceptance"] = acc
        rows.append(row)
    df = pd.DataFrame(rows).set_index("parameter")
    df.attrs.update(burn=burn, thin=thin, steps=steps, walkers=walkers)
    return df


def convergence(chain, acceptance, burn: int | None = None, moves: str = "stretch") -> dict:
    """Plain convergence verdicts for an ensemble chain (see the module docstring); ``moves`` (the
    chain's proposal, "stretch" or "de") decides the advice on a low acceptance."""
    chain = _chain(chain)
    steps, walkers, _ = chain.shape
    burn = default_burn(chain) if burn is None else int(burn)
    if not 0 <= burn < steps - 1:
        raise ValueError(f"burn must be an integer in [0, {steps - 2}], got {burn!r}")
    kept = steps - burn
    tau = integrated_times(chain[burn:])
    max_tau = _max_tau(tau)
    acc = _mean_acceptance(acceptance)
    messages = []
    after = f"after {burn} burn-in steps, " if burn else ""
    if math.isfinite(max_tau):
        ratio = kept / max_tau
        needed = burn + int(math.ceil(TAU_FACTOR * max_tau))
        long_enough = steps >= needed
        if long_enough:
            messages.append(f"{after}the chain's {kept} steps are {ratio:.0f} x the largest autocorrelation "
                            f"time {max_tau:.1f}: long enough (at least {TAU_FACTOR} x needed)")
        else:
            messages.append(f"{after}the chain's {kept} steps are {ratio:.0f} x the largest autocorrelation "
                            f"time {max_tau:.1f}: too short, run at least {needed} steps in all")
    else:
        ratio, needed, long_enough = math.nan, None, False
        messages.append(f"the autocorrelation time could not be estimated from {kept} steps "
                        f"(constant or non-finite chain): cannot judge the chain length")
    lo, hi = ACCEPTANCE_RANGE
    acceptance_ok = bool(math.isfinite(acc) and lo <= acc <= hi)
    if not math.isfinite(acc):
        messages.append("acceptance fraction unknown: cannot judge the step size")
    elif acc < lo:
        advice = ("try a smaller stretch scale or better starting points" if moves == "stretch" else
                  "with differential-evolution moves the step follows the walkers' spread: try more "
                  "replicates per evaluation (n_sim) or reevaluate_every, so a noisy likelihood rejects "
                  "less, or better starting points")
        messages.append(f"mean acceptance fraction {acc:.2f} is below {lo}: proposals are too bold, "
                        f"walkers rarely move ({advice})")
    elif acc > hi:
        messages.append(f"mean acceptance fraction {acc:.2f} is above {hi}: proposals are too timid, "
                        f"walkers move in tiny steps")
    else:
        messages.append(f"mean acceptance fraction {acc:.2f} is within [{lo}, {hi}]: fine")
    return {
        "converged": bool(long_enough and acceptance_ok),
        "long_enough": bool(long_enough),
        "acceptance_ok": acceptance_ok,
        "steps": int(steps),
        "burn": int(burn),
        "walkers": int(walkers),
        "tau": [float(t) for t in tau],
        "max_tau": max_tau,
        "length_over_tau": ratio,
        "steps_needed": needed,
        "acceptance": acc,
        "messages": messages,
    }


def long_enough(chain) -> bool:
    """``convergence(chain, nan)["long_enough"]``: at least 50 x the largest tau after the default burn-in."""
    chain = np.asarray(chain, dtype=float)
    if chain.ndim != 3 or chain.shape[0] < 4:
        return False
    return bool(convergence(chain, math.nan)["long_enough"])


def chain_ess_rhat(chain, names: Sequence[str] | None = None) -> pd.DataFrame:
    """ArviZ's R-hat and bulk/tail ESS per parameter, walkers as chains (see the module docstring)."""
    import arviz as az   # heavy: loaded when a verdict needs it

    chain = _chain(chain)
    names = _names(names, chain.shape[2])
    data = az.convert_to_dataset({n: np.swapaxes(chain[:, :, j], 0, 1) for j, n in enumerate(names)})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rhat, bulk, tail = az.rhat(data), az.ess(data, method="bulk"), az.ess(data, method="tail")
    return pd.DataFrame({"r_hat": [float(rhat[n]) for n in names], "ess_bulk": [float(bulk[n]) for n in names],
                         "ess_tail": [float(tail[n]) for n in names]}, index=pd.Index(names, name="parameter"))


def sampled_enough(chain) -> bool:
    """long_enough, R-hat and ESS verdicts all hold (see the module docstring)."""
    if not long_enough(chain):
        return False
    chain = np.asarray(chain, dtype=float)
    verdicts = arviz_verdicts(chain_ess_rhat(chain[default_burn(chain):]))
    return bool(verdicts["rhat_ok"] and verdicts["ess_ok"])


def arviz_verdicts(diagnostics: pd.DataFrame) -> dict:
    """R-hat and ESS verdicts from ArviZ's diagnostics table (see the module docstring)."""
    rhat = float(diagnostics["r_hat"].max())
    bulk, tail = float(diagnostics["ess_bulk"].min()), float(diagnostics["ess_tail"].min())
    rhat_ok = bool(math.isfinite(rhat) and rhat <= RHAT_MAX)
    ess_ok = bool(math.isfinite(bulk) and math.isfinite(tail) and min(bulk, tail) >= ESS_MIN)
    messages = [f"largest R-hat {rhat:.3f} (ArviZ, walkers as chains) is " +
                ("at most 1.01: the walkers agree" if rhat_ok else "above 1.01: the walkers have not yet sampled "
                                                                    "the same distribution; run longer"),
                f"smallest bulk / tail ESS {bulk:.0f} / {tail:.0f} is " +
                (f"at least {ESS_MIN}: enough for the means and the 90% intervals" if ess_ok else
                 f"below {ESS_MIN}: the means or the interval ends are uncertain; run longer")]
    return {"rhat_max": rhat, "ess_bulk_min": bulk, "ess_tail_min": tail, "rhat_ok": rhat_ok, "ess_ok": ess_ok,
            "messages": messages}


def prior_constraint_warnings(summary: pd.DataFrame, prior) -> list[str]:
    """Warnings for parameters whose posterior sd is above 0.8 x the prior marginal's sd."""
    out = []
    for name, marginal in zip(prior.names, prior.marginals):
        if name not in summary.index:
            continue
        post_sd = float(summary.loc[name, "sd"])
        prior_sd = float(marginal.moments[1])
        if not (math.isfinite(post_sd) and math.isfinite(prior_sd) and prior_sd > 0):
            continue
        ratio = post_sd / prior_sd
        if ratio > PRIOR_SD_RATIO:
            out.append(f"{name}: posterior sd {post_sd:.3g} is {ratio:.0%} of the prior sd {prior_sd:.3g}; "
                       f"the targets do not constrain {name}, its posterior mostly reflects the prior")
    return out


def predictive_check(observed, predictive, names: Sequence[str] | None = None) -> pd.DataFrame:
    """Posterior predictive check per summary statistic (see the module docstring)."""
    obs = np.asarray(observed, dtype=float)
    if obs.ndim == 1:
        obs = obs[None, :]
    pred = np.asarray(predictive, dtype=float)
    if obs.ndim != 2 or pred.ndim != 2 or obs.shape[1] != pred.shape[1]:
        raise ValueError(f"observed must be (m, k) or (k,) and predictive (S, k) with the same k, "
                         f"got {np.shape(observed)} and {np.shape(predictive)}")
    k = pred.shape[1]
    names = _names(names, k)
    rows = []
    for j, name in enumerate(names):
        o = obs[:, j][np.isfinite(obs[:, j])]
        p = pred[:, j][np.isfinite(pred[:, j])]
        row = {"statistic": name, "observed": float(o.mean()) if o.size else math.nan, "n_pred": int(p.size)}
        if p.size and o.size:
            x = row["observed"]
            tail = 2.0 * min(np.mean(p <= x), np.mean(p >= x))
            row.update(pred_mean=float(p.mean()), pred_sd=float(p.std(ddof=1)) if p.size > 1 else math.nan,
                       **{"pred_q2.5": float(np.quantile(p, 0.025)),
                          "pred_q97.5": float(np.quantile(p, 0.975))},
                       p=float(min(1.0, tail)))
        else:
            row.update({"pred_mean": math.nan, "pred_sd": math.nan, "pred_q2.5": math.nan,
                        "pred_q97.5": math.nan, "p": math.nan})
        rows.append(row)
    cols = ["observed", "pred_mean", "pred_sd", "pred_q2.5", "pred_q97.5", "p", "n_pred"]
    return pd.DataFrame(rows).set_index("statistic")[cols]


def sbc_ranks(prior_draws, posterior_samples, rng: np.random.Generator | None = None) -> np.ndarray:
    """SBC rank of each prior draw among its posterior samples: number of samples below it, in 0..S.

    ``prior_draws`` (L, d); ``posterior_samples`` a list of L arrays (S, d), all with the same S (thin
    them to near-independence first). Ties are broken uniformly at random with ``rng``."""
    theta = np.asarray(prior_draws, dtype=float)
    if theta.ndim == 1:
        theta = theta[:, None]
    if theta.ndim != 2:
        raise ValueError(f"prior_draws must have shape (L, d), got {np.shape(prior_draws)}")
    L, d = theta.shape
    if len(posterior_samples) != L:
        raise ValueError(f"got {len(posterior_samples)} posterior sample sets for {L} prior draws")
    rng = np.random.default_rng(0) if rng is None else rng
    ranks = np.zeros((L, d), dtype=int)
    size = None
    for i, s in enumerate(posterior_samples):
        s = np.asarray(s, dtype=float)
        if s.ndim == 1:
            s = s[:, None]
        if s.ndim != 2 or s.shape[1] != d:
            raise ValueError(f"posterior sample set {i} must have shape (S, {d}), got {s.shape}")
        if size is None:
            size = s.shape[0]
        elif s.shape[0] != size:
            raise ValueError(f"all posterior sample sets need the same size S; set {i} has {s.shape[0]}, "
                             f"set 0 has {size}")
        below = (s < theta[i]).sum(axis=0)
        ties = (s == theta[i]).sum(axis=0)
        extra = np.array([rng.integers(0, t + 1) if t else 0 for t in ties])
        ranks[i] = below + extra
    return ranks


def ecdf_counts(ranks: np.ndarray, S: int) -> np.ndarray:
    """(..., S) counts of ranks <= m for m = 0..S-1; ``ranks`` (..., L)."""
    below = ranks[..., None] <= np.arange(S)
    return below.sum(axis=-2)


def _bin_probs(S: int, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Bin index of each rank 0..S and the probability of each bin under uniform ranks."""
    values = np.arange(S + 1)
    index = (values * bins) // (S + 1)
    probs = np.bincount(index, minlength=bins) / (S + 1)
    return index, probs


def _check_sbc(ranks, S, bins) -> tuple[np.ndarray, int, int]:
    ranks = np.asarray(ranks)
    if ranks.ndim == 1:
        ranks = ranks[:, None]
    S, bins = int(S), int(bins)
    if S < 1 or not 1 <= bins <= S + 1:
        raise ValueError(f"need S >= 1 and 1 <= bins <= S + 1, got S={S}, bins={bins}")
    if ranks.ndim != 2 or ranks.size == 0 or ranks.min() < 0 or ranks.max() > S:
        raise ValueError(f"ranks must be an (L, d) array of integers in 0..{S}")
    return ranks.astype(int), S, bins


def sbc_histogram(ranks, S: int, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Counts per bin, shape (bins, d), and expected counts per bin under uniformity, shape (bins,)."""
    ranks, S, bins = _check_sbc(ranks, S, bins)
    index, probs = _bin_probs(S, bins)
    counts = np.stack([np.bincount(index[ranks[:, j]], minlength=bins) for j in range(ranks.shape[1])],
                      axis=1)
    return counts, probs * ranks.shape[0]


def sbc_uniformity(ranks, S: int, bins: int, names: Sequence[str] | None = None) -> pd.DataFrame:
    """Chi-square test of uniform SBC ranks per parameter: columns ``chi2, dof, p, n, bins``.

    Ranks take ``S + 1`` values; bins are as even as possible (choose ``bins`` dividing ``S + 1``)."""
    ranks, S, bins = _check_sbc(ranks, S, bins)
    counts, expected = sbc_histogram(ranks, S, bins)
    names = _names(names, ranks.shape[1])
    rows = []
    for j, name in enumerate(names):
        chi2 = float(((counts[:, j] - expected) ** 2 / expected).sum())
        dof = bins - 1
        p = float(stats.chi2.sf(chi2, dof)) if dof > 0 else math.nan
        rows.append({"parameter": name, "chi2": chi2, "dof": dof, "p": p, "n": int(ranks.shape[0]),
                     "bins": bins})
    return pd.DataFrame(rows).set_index("parameter")
