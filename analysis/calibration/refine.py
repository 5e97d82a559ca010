"""The emulator's sequential design: after each fit, new sweep points where the posterior mass and the
emulator's uncertainty are, added to the sweep through the sweep machinery, then a refit, until the
confirmation at the posterior median passes AND the emulator's own uncertainty is a small share of the
likelihood's, or the rounds run out (``refine = { rounds, runs_per_round, max_emulator_share }``).

Shapes: d free parameters, k statistics, C candidate points, m points chosen.

Contract
--------
``select_points(surrogate, chain, burn, count, obs_cov, replicates, candidates=1000) -> (m, d)``
    Candidates: posterior draws (``chain[burn:]`` flattened, evenly thinned to at most ``candidates``,
    duplicates dropped), so they follow the posterior mass. For a GP surrogate, per statistic j the
    GP's latent covariance S_j over the candidates and the likelihood variance L_j(c) (emulated
    run-to-run variance + the targets' variance + the emulator's variance at c); the objective is the
    posterior-averaged emulator variance in likelihood units, ``U = mean_c sum_j S_j(c, c) / L_j(c)``.
    Greedy batch: the next point x* is the candidate whose run (the mean of ``replicates`` runs, noise
    var_j(x*) / replicates) would reduce U most, ``sum_c sum_j S_j(c, x*)^2 / (S_j(x*, x*) + noise_j(x*))
    / L_j(c)``; S_j is then conditioned on x* (a rank-one update, as if x* were observed) and the next is
    chosen, ``count`` times (no candidate twice). Surrogates without a covariance (RBF): the candidates
    farthest from each other and the posterior median, greedily (space filling inside the posterior).
    Deterministic: no random numbers.

``emulator_share(surrogate, chain, burn, obs_cov, candidates=1000) -> float``
    How much the emulator's own uncertainty widens the likelihood over the posterior mass: over the same
    posterior draws as ``select_points``, the mean of ``max_j mean_var_j(c) / (var_j(c) + obs_j)``,
    the GP's variance of statistic j's mean against the exact synthetic likelihood's variance there
    (run-to-run variance + the targets' variance; samples targets: run-to-run only). The emulated
    likelihood's variance is the exact one times at most ``1 + share`` per statistic, so the emulated
    posterior's sd exceeds the exact one by about ``sqrt(1 + share)`` at most (share 0.1: 5 %) where
    the emulator is unbiased within its variance (which the confirmation checks).

``refine_emulator(config, fit_round, *, pool_kind, workers, scheduler, progress, log) -> Refinement``
    Runs the rounds: ``fit_round(r) -> (training, surrogate, chain result, burn)`` fits and samples
    round r (the caller's MCMC, into its own chain file); :func:`~.emulated.confirm` at the posterior
    median with round r's seeds (``generator(seed, Tag.CONFIRM)`` for round 0, ``(seed, Tag.CONFIRM, r)``
    after) and ``emulator_share``; the rounds stop when the confirmation passes and the share is at most
    ``refine.max_emulator_share`` (both), or after ``refine.rounds`` rounds of new runs; otherwise
    ``select_points`` picks ``max(1, runs_per_round //
    replicates)`` points, :func:`sweeps.extend.add_points` runs them into the sweep's own results
    (``method.results``: same store, same run identities; the sweep keeps them, so a later calibration
    on it starts from the refined design), and the next round refits on the grown training set.
    ``Refinement``: the last round's ``training``, ``surrogate``, ``result``, ``burn``, ``confirm``
    (its check) and ``rounds`` (a DataFrame, one row per round: training points and runs, runs added,
    the confirmation's runs,
    posterior mean, sd and 90% interval per parameter, the confirmation's max |z| and min p, passed,
    emulator_share, wall seconds).

``confirmation_passed(check, z_limit=3, p_limit=0.01) -> bool``: every |z| <= z_limit (real against
emulated mean at the posterior median) and every predictive p >= p_limit (targets against the real runs).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pandas as pd

from flocksweep.sweeps.extend import add_points

from .emulated import confirm, posterior_median
from .simulator import summary_simulator
from .surrogates import GPSurrogate, Surrogate, single_threaded_blas

Z_LIMIT = 3.0
P_LIMIT = 0.01


@dataclass
class Refinement:
    training: object
    surrogate: Surrogate
    result: object
    burn: int
    confirm: dict
    rounds: pd.DataFrame


def confirmation_passed(check: dict, z_limit: float = Z_LIMIT, p_limit: float = P_LIMIT) -> bool:
    """Real runs at the posterior median agree with the emulator and with the targets."""
    z = np.abs(check["comparison"]["z"].to_numpy(dtype=float))
    p = check["predictive"]["p"].to_numpy(dtype=float)
    return bool(np.all(np.isfinite(z)) and np.all(z <= z_limit) and np.all(np.nan_to_num(p, nan=0.0) >= p_limit))


def _candidates(chain: np.ndarray, burn: int, count: int) -> np.ndarray:
    flat = np.asarray(chain, dtype=float)[burn:].reshape(-1, chain.shape[-1])
    step = max(1, len(flat) // count)
    return np.unique(flat[::step][:count], axis=0)


def _likelihood_variance(surrogate: Surrogate, candidates: np.ndarray, obs_cov) -> np.ndarray:
    prediction = surrogate.predict(candidates)
    extra = np.zeros(surrogate.k) if obs_cov is None else np.diag(np.asarray(obs_cov, dtype=float))
    return prediction.var + prediction.mean_var + extra[None, :]


def _greedy_variance_reduction(surrogate: GPSurrogate, candidates: np.ndarray, count: int, weights: np.ndarray,
                               noise: np.ndarray) -> list[int]:
    unit = surrogate.to_unit(candidates)
    covariances = [model.output.scale ** 2 * model.covariance(unit) for model in surrogate.mean_models]
    chosen: list[int] = []
    for _ in range(min(count, len(candidates))):
        gain = np.zeros(len(candidates))
        for j, cov in enumerate(covariances):
            gain += (cov ** 2 * weights[:, j:j + 1]).sum(axis=0) / (np.diag(cov) + noise[:, j])
        gain[chosen] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        for j, cov in enumerate(covariances):
            column = cov[:, best].copy()
            cov -= np.outer(column, column) / (column[best] + noise[best, j])
    return chosen


def _farthest_points(surrogate: Surrogate, candidates: np.ndarray, count: int, centre: np.ndarray) -> list[int]:
    unit = surrogate.to_unit(candidates)
    distance = np.linalg.norm(unit - surrogate.to_unit(centre[None, :]), axis=1)
    chosen: list[int] = []
    for _ in range(min(count, len(candidates))):
        best = int(np.argmax(distance))
        chosen.append(best)
        distance = np.minimum(distance, np.linalg.norm(unit - unit[best], axis=1))
        distance[chosen] = -np.inf
    return chosen


def emulator_share(surrogate: Surrogate, chain, burn: int, obs_cov, candidates: int = 1000) -> float:
    """The emulator's variance as a share of the exact likelihood's over the posterior (module docstring)."""
    pool = _candidates(chain, burn, candidates)
    with single_threaded_blas():
        prediction = surrogate.predict(pool)
    extra = np.zeros(surrogate.k) if obs_cov is None else np.diag(np.asarray(obs_cov, dtype=float))
    share = prediction.mean_var / (prediction.var + extra[None, :])
    return float(np.mean(np.max(share, axis=1)))


def select_points(surrogate: Surrogate, chain, burn: int, count: int, obs_cov, replicates: int,
                  candidates: int = 1000) -> np.ndarray:
    """The next design points (see the module docstring)."""
    pool = _candidates(chain, burn, candidates)
    with single_threaded_blas():
        if isinstance(surrogate, GPSurrogate):
            weights = 1.0 / _likelihood_variance(surrogate, pool, obs_cov)
            noise = surrogate.predict(pool).var / max(int(replicates), 1)
            chosen = _greedy_variance_reduction(surrogate, pool, count, weights, noise)
        else:
            chosen = _farthest_points(surrogate, pool, count, posterior_median(chain, burn))
    return pool[chosen]


def _round_row(r: int, training, result, burn: int, names, check: dict, share: float, added: int,
               started: float) -> dict:
    flat = result.chain[burn:].reshape(-1, result.chain.shape[-1])
    row = {"round": r, "training_points": int(len(training.points)), "training_runs": int(training.count.sum()),
           "runs_added": added, "confirm_runs": int(len(check["summaries"]))}
    for j, name in enumerate(names):
        row.update({f"{name}_mean": float(flat[:, j].mean()), f"{name}_sd": float(flat[:, j].std(ddof=1)),
                    f"{name}_q5": float(np.quantile(flat[:, j], 0.05)),
                    f"{name}_q95": float(np.quantile(flat[:, j], 0.95))})
    z = np.abs(check["comparison"]["z"].to_numpy(dtype=float))
    row.update(confirm_max_abs_z=float(np.nanmax(z)) if np.isfinite(z).any() else math.nan,
               confirm_min_p=float(np.nanmin(check["predictive"]["p"])), passed=confirmation_passed(check),
               emulator_share=share, wall_s=time.time() - started)
    return row


def _as_sweep_points(theta_rows: np.ndarray, config, training) -> list[dict]:
    """Sweep points {swept key: value}: the free parameters (integer keys rounded) and the sweep's other
    swept keys at the calibration's values (a point gives every swept key)."""
    integer = summary_simulator(config, n_sim=1).integer_keys
    points = []
    for theta in theta_rows:
        point = {str(key): value for key, value in training.fixed.items()}
        point.update({key: int(round(v)) if is_int else float(v) for key, v, is_int in zip(config.keys, theta, integer)})
        points.append(point)
    return points


def refine_emulator(config, fit_round: Callable, *, pool_kind: str = "local",
                    workers: int | None = None, scheduler: str | None = None, progress: bool = True,
                    log: Callable = print) -> Refinement:
    """The rounds of fit, confirmation and new sweep points (see the module docstring)."""
    settings = config.method
    rounds, r = [], 0
    while True:
        started = time.time()
        training, surrogate, result, burn = fit_round(r)
        theta = posterior_median(result.chain, burn)
        check = confirm(config, summary_simulator(config), surrogate, theta, count=settings.confirm,
                        seed=config.seed, stream=(r,) if r else ())
        share = emulator_share(surrogate, result.chain, burn, _obs_cov(config))
        settled = confirmation_passed(check) and share <= settings.refine.max_emulator_share
        added = 0
        last = settled or r >= settings.refine.rounds
        if not last:
            replicates = int(np.median(training.count))
            picks = select_points(surrogate, result.chain, burn, max(1, settings.refine.runs_per_round // replicates),
                                  _obs_cov(config), replicates)
            _, specs = add_points(settings.results, _as_sweep_points(picks, config, training),
                                        executor=pool_kind, workers=workers, scheduler=scheduler, progress=progress)
            added = len(specs)
        rounds.append(_round_row(r, training, result, burn, config.names, check, share, added, started))
        log(_round_message(rounds[-1], config.names, last, settings.refine.max_emulator_share))
        if last:
            return Refinement(training=training, surrogate=surrogate, result=result, burn=burn, confirm=check,
                              rounds=pd.DataFrame(rounds))
        r += 1


def _obs_cov(config):
    return None if config.targets.samples_path is not None else np.asarray(config.targets.cov, dtype=float)


def _round_message(row: dict, names, last: bool, max_share: float) -> str:
    posterior = ", ".join(f"{n} {row[f'{n}_mean']:.4g} +- {row[f'{n}_sd']:.2g}" for n in names)
    verdict = "passed" if row["passed"] else "failed"
    then = "" if last else f"; {row['runs_added']} runs added to the sweep"
    return (f"refine round {row['round']}: {row['training_points']} training points; posterior {posterior}; "
            f"confirmation {verdict} (max |z| {row['confirm_max_abs_z']:.2f}, min p {row['confirm_min_p']:.3g}); "
            f"emulator share {row['emulator_share']:.3g} (limit {max_share:g}){then}")
