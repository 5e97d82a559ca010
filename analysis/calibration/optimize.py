"""Point calibration by optimisation with common random numbers (CRN), then a fresh-seed re-check.

Contract
--------
``run_optimize(simulate_seeds_fn, observed, prior, *, seed, n_sim, algorithm="differential_evolution",
objective="loglik", maxiter=100, popsize=15, recheck=200, likelihood="gaussian", executor=None, tick=None)
-> OptimizeResult`` (``tick()`` after each evaluation of the search, for a progress bar; at most
``max_evaluations(algorithm, maxiter, popsize, dim)`` of them, None when not known beforehand)

* ``simulate_seeds_fn(theta, seeds) -> (len(seeds), k)`` summary table at ``theta`` (shape (d,)), one
  row per seed (e.g. :meth:`~analysis.calibration.simulator.SummarySimulator.simulate`). It is only
  ever called with exactly ``n_sim`` seeds (SummarySimulator insists on that).
* Search objective (minimised), evaluated with COMMON RANDOM NUMBERS: the same seeds
  ``common_seeds(seed, n_sim)`` at every theta, so it is a deterministic (and, for a smooth simulator,
  smooth) function of theta:
    - ``objective="loglik"``:   ``-(prior.logpdf(theta) + synthetic_loglik(observed, sims, likelihood))``
      (a negative log synthetic posterior);
    - ``objective="distance"``: ``standardized_distance(observed, sims)`` (the prior only restricts the
      support).
  Where ``prior.logpdf(theta)`` is not finite (outside the support) the value is ``+inf`` and
  ``simulate_seeds_fn`` is NOT called. Rows with any non-finite value (the simulator's NaN rows) are
  dropped; with fewer rows left than the estimator needs (k + 2 for ``"gaussian"``, k + 4 for
  ``"unbiased"``, 2 for ``"distance"``) the value is ``+inf``. :func:`crn_objective` builds this
  function on its own (for inspection and tests).
* ``algorithm="differential_evolution"``: :func:`scipy.optimize.differential_evolution` over
  ``prior.bounds`` (all must be finite, else ValueError), seeded with ``seed``, ``maxiter``,
  ``popsize``, ``polish=False``, ``updating="deferred"``: each generation's trial population is
  evaluated as one block through ``executor.map`` (a :class:`sweeps.executors.Executor`; None: this
  process), so the result is the same for any executor and number of workers.
  ``algorithm="nelder_mead"`` (or ``"nelder-mead"``): :func:`scipy.optimize.minimize` with
  ``method="Nelder-Mead"`` started at ``prior.mean``, initial simplex ``mean + 0.5 * sd`` along each axis (clipped into the bounds),
  ``options={"maxiter": maxiter}``. A trial point outside the bounds is evaluated at its projection
  onto the bounds plus a penalty ``1e3 * (1 + |f|) * sum(((theta - clipped) / scale)^2)``
  (scale = prior sd); the reported optimum is the projection, so it always lies inside the bounds.
* Re-check with FRESH seeds: ``seeds_for(generator(seed, Tag.RECHECK), R)`` (:mod:`sweeps.seeds`) where
  ``R`` is ``recheck`` rounded up to a multiple of ``n_sim``; they are simulated at the optimum in
  ``B = R / n_sim`` batches of ``n_sim`` (consecutive seeds), mapped through ``executor`` too. The
  objective of each batch is the same estimator as the CRN search value (same n, so the same estimator bias), and
  ``objective_recheck`` is their mean with the normal-approximation standard error
  ``recheck_se = sd(batch values, ddof=1) / sqrt(B)`` (nan when ``B < 2`` or any batch is infinite).
  ``objective_crn`` is the search value at the optimum (common seeds). The CRN value is selected by
  the optimiser and therefore optimistic; ``objective_recheck - objective_crn`` far above a few
  ``recheck_se`` (see :attr:`OptimizeResult.crn_gap_z`) means the optimum fits the common seeds'
  noise rather than the data.
* :class:`OptimizeResult`: ``theta`` (d,), ``names`` (the prior's names when it has them),
  ``objective_crn``, ``objective_recheck``, ``recheck_se``, ``nfev`` (search evaluations as counted
  by scipy), ``success``, ``message``, ``summaries_at_optimum`` (k,) column means of the finite
  re-check rows, ``recheck_summaries`` (R, k) all re-check rows, ``recheck_batches`` (B,) batch
  objective values, plus ``algorithm``, ``objective``, ``likelihood``, ``seed``, ``n_sim``, and the
  simulations run, counted in this process: ``search_evaluations`` (objective evaluations that
  simulated: inside the prior's support, the final one at the optimum included; scipy's ``nfev`` also
  counts those outside), ``search_simulations`` (their rows) and ``recheck_simulations``.

Everything is a deterministic function of the arguments: the same call gives an identical result.
"""
from __future__ import annotations

import dataclasses
import functools
import inspect
import math
from typing import Callable

import numpy as np
from scipy import optimize as _opt

from flocksweep.sweeps.seeds import Tag, common_seeds, generator, seeds_for

from .checks import integer
from .likelihood import METHODS, min_replicates, standardized_distance, synthetic_loglik

ALGORITHMS = ("differential_evolution", "nelder_mead")
OBJECTIVES = ("loglik", "distance")
PENALTY = 1e3


@dataclasses.dataclass
class OptimizeResult:
    theta: np.ndarray                   # (d,)
    objective_crn: float                # search objective at theta with the common seeds
    objective_recheck: float            # mean over fresh-seed batches at theta
    recheck_se: float                   # normal-approximation standard error of objective_recheck
    nfev: int
    success: bool
    message: str
    summaries_at_optimum: np.ndarray    # (k,) mean of the finite re-check rows
    recheck_summaries: np.ndarray       # (R, k)
    recheck_batches: np.ndarray         # (B,)
    names: tuple[str, ...] | None = None
    algorithm: str = "differential_evolution"
    objective: str = "loglik"
    likelihood: str = "gaussian"
    seed: int | None = None
    n_sim: int | None = None
    search_evaluations: int = 0         # objective evaluations that simulated (inside the support)
    search_simulations: int = 0         # their runs: search_evaluations x n_sim
    recheck_simulations: int = 0        # the fresh-seed re-check's runs

    @property
    def crn_gap_z(self) -> float:
        """(objective_recheck - objective_crn) / recheck_se; large positive = overfit to the CRN seeds."""
        if not (math.isfinite(self.recheck_se) and self.recheck_se > 0):
            return math.nan
        return (self.objective_recheck - self.objective_crn) / self.recheck_se


def _min_rows(k: int, objective: str, likelihood: str) -> int:
    return 2 if objective == "distance" else min_replicates(k, likelihood)


def _batch_value(observed, sims, objective: str, likelihood: str, log_prior: float) -> float:
    """Objective from one simulated table (NaN rows dropped); +inf when too few rows remain."""
    sims = np.asarray(sims, dtype=float)
    if sims.ndim != 2:
        raise ValueError(f"simulate_seeds_fn must return shape (n, k), got {sims.shape}")
    sims = sims[np.isfinite(sims).all(axis=1)]
    if sims.shape[0] < _min_rows(sims.shape[1], objective, likelihood):
        return math.inf
    if objective == "distance":
        return float(standardized_distance(observed, sims))
    ll = synthetic_loglik(observed, sims, likelihood)
    return -(log_prior + ll) if math.isfinite(ll) else math.inf


class _Objective:
    """theta -> objective value with a fixed list of seeds (see module docstring)."""

    def __init__(self, simulate_seeds_fn, observed, prior, seeds, objective: str, likelihood: str,
                 transform: Callable | None = None):
        self.simulate_seeds_fn = simulate_seeds_fn
        self.transform = transform
        self.observed = np.asarray(observed, dtype=float)
        self.prior = prior
        self.seeds = list(seeds)
        self.objective = objective
        self.likelihood = likelihood
        self.simulated = 0      # evaluations that simulated, counted where they are requested (this process)

    def count_inside(self, thetas) -> None:
        self.simulated += sum(math.isfinite(self.log_prior(t)) for t in thetas)

    def log_prior(self, theta) -> float:
        return float(self.prior.logpdf(np.asarray(theta, dtype=float)))

    def evaluate(self, theta, seeds) -> float:
        theta = np.asarray(theta, dtype=float)
        lp = self.log_prior(theta)
        if not math.isfinite(lp):
            return math.inf
        sims = self.simulate_seeds_fn(theta.copy(), list(seeds))
        if self.transform is not None:
            sims = self.transform(sims)
        return _batch_value(self.observed, sims, self.objective, self.likelihood, lp)

    def __call__(self, theta) -> float:
        return self.evaluate(theta, self.seeds)


def _simulate_batch(simulate_seeds_fn, theta, seeds):
    return simulate_seeds_fn(np.array(theta, dtype=float), list(seeds))


def _check_choices(objective: str, likelihood: str) -> None:
    if objective not in OBJECTIVES:
        raise ValueError(f"objective: unknown {objective!r}; allowed: {', '.join(OBJECTIVES)}")
    if likelihood not in METHODS:
        raise ValueError(f"likelihood: unknown method {likelihood!r}; allowed: {', '.join(METHODS)}")


def crn_objective(simulate_seeds_fn: Callable, observed, prior, *, seed: int, n_sim: int,
                  objective: str = "loglik", likelihood: str = "gaussian") -> Callable:
    """The deterministic search objective ``theta -> float`` using ``common_seeds(seed, n_sim)``."""
    _check_choices(objective, likelihood)
    seed = integer(seed, "seed", 0)
    n_sim = integer(n_sim, "n_sim", 1)
    return _Objective(simulate_seeds_fn, observed, prior, common_seeds(seed, n_sim), objective, likelihood)


def _de_kwargs(seed: int) -> dict:
    params = inspect.signature(_opt.differential_evolution).parameters
    return {"rng": seed} if "rng" in params else {"seed": seed}


def _run_de(func, bounds, seed, maxiter, popsize, executor=None, tick=None):
    if not all(math.isfinite(lo) and math.isfinite(hi) for lo, hi in bounds):
        raise ValueError(f"differential_evolution needs finite prior bounds, got {bounds}; "
                         "use bounded priors (or explicit bounds) or algorithm='nelder_mead'")
    tick = tick or (lambda: None)

    def evaluated(theta):
        value = func(theta)
        tick()
        return value

    def block_map(_wrapped, thetas):   # scipy's wrapper only forwards to func; evaluate func itself
        thetas = [np.asarray(t, dtype=float) for t in thetas]
        func.count_inside(thetas)
        return executor.map(func, thetas, tick) if executor is not None else [evaluated(t) for t in thetas]

    res = _opt.differential_evolution(func, bounds, maxiter=maxiter, popsize=popsize, polish=False,
                                      updating="deferred", workers=block_map, **_de_kwargs(seed))
    return np.asarray(res.x, dtype=float), int(res.nfev), bool(res.success), str(res.message)


def _run_nm(func, prior, bounds, maxiter, tick=None):
    lo = np.array([b[0] for b in bounds], dtype=float)
    hi = np.array([b[1] for b in bounds], dtype=float)
    x0 = np.clip(np.asarray(prior.mean, dtype=float), lo, hi)
    sd = np.asarray(prior.sd, dtype=float)
    scale = np.where(np.isfinite(sd) & (sd > 0), sd, 1.0)
    d = x0.size
    simplex = np.tile(x0, (d + 1, 1))
    for j in range(d):
        step = 0.5 * scale[j]
        trial = x0[j] + step
        simplex[j + 1, j] = trial if trial <= hi[j] else x0[j] - step
    simplex = np.clip(simplex, lo, hi)

    def penalised(theta):
        theta = np.asarray(theta, dtype=float)
        clipped = np.clip(theta, lo, hi)
        func.count_inside([clipped])
        value = func(clipped)
        if tick is not None:
            tick()
        excess = float(np.sum(((theta - clipped) / scale) ** 2))
        if excess == 0.0 or not math.isfinite(value):
            return value
        return value + PENALTY * (1.0 + abs(value)) * excess

    res = _opt.minimize(penalised, x0, method="Nelder-Mead",
                        options={"maxiter": maxiter, "initial_simplex": simplex})
    return np.clip(np.asarray(res.x, dtype=float), lo, hi), int(res.nfev), bool(res.success), str(res.message)


def max_evaluations(algorithm: str, maxiter: int, popsize: int, dim: int) -> int | None:
    """At most how many evaluations the search makes (differential evolution: (maxiter + 1) generations of
    popsize x dim members, at least 5 as scipy makes them), or None when it is not known beforehand
    (Nelder-Mead)."""
    return (maxiter + 1) * max(5, popsize * dim) if algorithm in ("differential_evolution", "de") else None


def run_optimize(simulate_seeds_fn: Callable, observed, prior, *, seed: int, n_sim: int,
                 algorithm: str = "differential_evolution", objective: str = "loglik", maxiter: int = 100,
                 popsize: int = 15, recheck: int = 200, likelihood: str = "gaussian",
                 executor=None, tick: Callable[[], object] | None = None, transform: Callable | None = None
                 ) -> OptimizeResult:
    """Minimise the CRN objective, then re-check the optimum with fresh seeds (module docstring);
    ``tick()`` is called after each evaluation of the search (a progress bar's ``update``); ``transform``
    ((n, k) -> (n, k), e.g. :meth:`analysis.calibration.transforms.Transforms.apply`) is applied to the
    observed and simulated statistics inside the objective only (the re-check rows are returned as
    simulated)."""
    _check_choices(objective, likelihood)
    algo = algorithm.lower().replace("-", "_") if isinstance(algorithm, str) else algorithm
    algo = {"differential_evolution": "differential_evolution", "de": "differential_evolution",
            "nelder_mead": "nelder_mead", "neldermead": "nelder_mead"}.get(algo)
    if algo is None:
        raise ValueError(f"algorithm: unknown {algorithm!r}; allowed: {', '.join(ALGORITHMS)}")
    seed = integer(seed, "seed", 0)
    n_sim = integer(n_sim, "n_sim", 1)
    maxiter = integer(maxiter, "maxiter", 1)
    popsize = integer(popsize, "popsize", 1)
    recheck = integer(recheck, "recheck", 1)

    transform = transform or (lambda x: np.asarray(x, dtype=float))
    func = _Objective(simulate_seeds_fn, transform(np.atleast_2d(observed)), prior, common_seeds(seed, n_sim),
                      objective, likelihood, transform)
    bounds = [(float(lo), float(hi)) for lo, hi in prior.bounds]
    if algo == "differential_evolution":
        theta, nfev, success, message = _run_de(func, bounds, seed, maxiter, popsize, executor, tick)
    else:
        theta, nfev, success, message = _run_nm(func, prior, bounds, maxiter, tick)
    func.count_inside([theta])
    objective_crn = float(func(theta))

    n_batches = -(-recheck // n_sim)
    fresh = seeds_for(generator(seed, Tag.RECHECK), n_batches * n_sim)
    lp = func.log_prior(theta)
    batches = [fresh[b * n_sim:(b + 1) * n_sim] for b in range(n_batches)]
    task = functools.partial(_simulate_batch, simulate_seeds_fn, theta.copy())
    tables = executor.map(task, batches) if executor is not None else [task(b) for b in batches]
    tables = [np.asarray(t, dtype=float) for t in tables]
    values = [_batch_value(func.observed, transform(sims), objective, likelihood, lp) if math.isfinite(lp)
              else math.inf for sims in tables]
    values = np.asarray(values, dtype=float)
    rows = np.concatenate(tables, axis=0)
    finite_rows = rows[np.isfinite(rows).all(axis=1)]
    means = finite_rows.mean(axis=0) if finite_rows.shape[0] else np.full(rows.shape[1], np.nan)
    objective_recheck = float(values.mean())
    if n_batches >= 2 and np.all(np.isfinite(values)):
        recheck_se = float(values.std(ddof=1) / math.sqrt(n_batches))
    else:
        recheck_se = math.nan

    names = getattr(prior, "names", None)
    return OptimizeResult(theta=theta, objective_crn=objective_crn, objective_recheck=objective_recheck,
                          recheck_se=recheck_se, nfev=nfev, success=success, message=message,
                          summaries_at_optimum=means, recheck_summaries=rows, recheck_batches=values,
                          names=tuple(names) if names is not None else None, algorithm=algo,
                          objective=objective, likelihood=likelihood, seed=seed, n_sim=n_sim,
                          search_evaluations=func.simulated, search_simulations=func.simulated * n_sim,
                          recheck_simulations=int(rows.shape[0]))
