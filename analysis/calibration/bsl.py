"""Bayesian synthetic likelihood (BSL) MCMC with emcee (Price et al. 2018).

Contract
--------
``run_bsl(simulate_fn, observed, prior, *, walkers, steps, seed, path=None, resume=False,
likelihood="gaussian", reevaluate_every=0, progress=None, progress_every=None, executor=None,
moves="stretch", meta=None, until_converged=False, check_every=50, count=None) -> ChainResult``

* ``simulate_fn(theta, rng) -> (n_sim, k)`` summary table at ``theta`` (shape (d,)), using FRESH seeds
  drawn from the :class:`numpy.random.Generator` ``rng`` it is given (e.g. a
  :class:`~analysis.calibration.simulator.SummarySimulator` instance, whose ``__call__`` does exactly
  that). Nothing inside the MCMC uses fixed seeds: every evaluation gets its own generator.
* Log posterior at theta = ``prior.logpdf(theta) + synthetic_loglik(observed, sims, likelihood)``.
  Where the prior log density is not finite (outside its support) the result is ``-inf`` and
  ``simulate_fn`` is NOT called. Rows of ``sims`` with any non-finite value (the simulator's NaN rows)
  are dropped; if fewer than the method's minimum remain (k + 2 for ``"gaussian"``, k + 4 for
  ``"unbiased"``) the result is ``-inf`` (the parameter makes the statistics undefined too often).
  A singular covariance (ValueError from :func:`synthetic_loglik`) is a configuration error and
  propagates.
* The chain is run by the one emcee driver, :func:`~analysis.calibration.mcmc.run_chain` (seeds of the
  initial walkers and of the moves, ``moves``, the HDF5 file and its resume checks, progress). Randomness
  is a deterministic function of ``seed`` only (:mod:`sweeps.seeds`):
    - initial walkers: ``prior.sample(generator(seed, Tag.WALKERS), walkers)``; walkers whose initial
      log posterior is -inf (e.g. all-NaN summaries) are redrawn from the same generator (evaluation
      ``(phase 0, step = attempt, i = walker)``), at most 100 rounds, else RuntimeError;
    - each log-posterior evaluation: ``generator(seed, Tag.EVALUATION, phase, step, i)`` where ``phase``
      is 0 for the initial walkers (step 0), 1 for the proposals made while computing chain row
      ``step - 1`` (step = 1..steps) and 2 for re-evaluations at step ``step``; ``i`` is the call's
      position within that step. emcee's stretch move evaluates the proposals of the two half-ensembles
      in walker order, so ``i`` is the walker index (so do the DE moves of ``moves="de"``, which also
      split the ensemble in two). No counter has to be stored.
  The same arguments therefore give a bit-identical chain.
* Parallelism: emcee is run vectorised, so each half-ensemble's proposals (``walkers / 2`` points)
  arrive at once and their simulations are mapped through ``executor`` (a
  :class:`sweeps.executors.Executor`, or None for this process), one task per point. A task is
  ``(theta, seed key)``, so the chain is bit-identical whatever the executor and workers.
* Storage and exact resume as in :func:`~analysis.calibration.mcmc.run_chain`; the file records
  ``bsl_seed``, ``bsl_likelihood``, ``bsl_reevaluate_every`` and ``bsl_moves`` (and the caller's ``meta``:
  what else defines the chain, e.g. the simulator's settings and the targets), which a resume must
  match. The simulation seeds follow from (seed, phase, step, i) and re-evaluations happen at fixed step
  numbers, so a resumed chain recomputes them identically. emcee writes one step per HDF5 open/close;
  an interruption in the middle of that write can leave the file unusable (the step is not journaled).
* ``reevaluate_every = r > 0``: before computing row ``t`` for every ``t`` with ``t % r == 0`` (t > 0),
  the log posterior of every walker's current point is re-simulated with fresh seeds (phase 2) and
  replaces the current log-probability emcee compares proposals against, so a lucky overestimate of
  the noisy synthetic likelihood cannot keep a walker stuck. Rows already written keep the value they
  had; a walker that rejects its next proposal shows the re-evaluated value in the next row. This is
  the "noisy" (not pseudo-marginal exact) variant of BSL; 0 (default) never re-evaluates.
* ``count(phase, simulations, evaluations)`` (optional) is called in this process after each evaluation
  that simulated (points outside the prior's support are not), with ``phase`` ``"initial"``,
  ``"search"`` or ``"reevaluation"``, the rows ``simulate_fn`` returned and 1
  (:class:`~analysis.calibration.accounting.Accounting.add`).
* ``until_converged`` / ``check_every``: ``steps`` becomes a cap and the chain stops at the first
  multiple of ``check_every`` rows where it is long enough (:func:`~analysis.calibration.mcmc.run_chain`).
* ``progress(step, acceptance_fraction_mean, tau_estimate)`` is called after every row; ``tau_estimate``
  is the mean over parameters of emcee's integrated autocorrelation time of the second half of the rows
  so far (the first half taken as burn-in; no length check), estimated again every ``progress_every``
  rows (default ``max(1, steps // 10)``) and at the last, nan before the first estimate or when it
  cannot be computed (fewer than 2 rows).
* The result is a :class:`~analysis.calibration.mcmc.ChainResult`: ``chain`` (steps, walkers, d),
  ``log_prob`` (steps, walkers), ``acceptance_fraction`` (walkers,), ``names`` (the prior's parameter
  names when it has them), ``path`` (or None), ``seed``.
"""
from __future__ import annotations

import functools
import math
import os
from typing import Callable

import numpy as np

from flocksweep.sweeps.seeds import Tag, generator

from .checks import integer
from .likelihood import METHODS, min_replicates, synthetic_loglik
from .mcmc import ChainResult, run_chain

PHASE_INITIAL, PHASE_PROPOSAL, PHASE_REEVALUATE = 0, 1, 2
PHASE_NAMES = {PHASE_INITIAL: "initial", PHASE_PROPOSAL: "search", PHASE_REEVALUATE: "reevaluation"}
MAX_INITIAL_ATTEMPTS = 100


def simulate_keyed(simulate_fn, task):
    """One evaluation's simulations: ``task = (theta, key)``; the generator is ``generator(*key)``, so
    the result depends on the task only (not on the process or the order it runs in)."""
    theta, key = task
    return np.asarray(simulate_fn(np.array(theta, dtype=float), generator(*key)), dtype=float)


class _LogPosterior:
    """Vectorised log posterior with a deterministic per-evaluation generator (see module docstring).

    Called by emcee with a (n, d) block of points (a half-ensemble of proposals); evaluation ``i`` of
    the current (phase, step) gets the seed key ``(seed, Tag.EVALUATION, phase, step, i)``. The points
    inside the prior's support are simulated through ``executor.map`` (one task each, in order)."""

    def __init__(self, simulate_fn, observed, prior, seed: int, likelihood: str, executor=None, count=None):
        self.simulate_fn = simulate_fn
        self.count = count
        self.observed = observed
        self.prior = prior
        self.seed = seed
        self.likelihood = likelihood
        self.executor = executor
        self.phase = PHASE_INITIAL
        self.step = 0
        self.index = 0

    def begin(self, phase: int, step: int) -> None:
        self.phase, self.step, self.index = phase, step, 0

    def _map(self, tasks) -> list:
        fn = functools.partial(simulate_keyed, self.simulate_fn)
        if self.executor is None:
            return [fn(task) for task in tasks]
        return self.executor.map(fn, tasks)

    def _loglik(self, sims: np.ndarray) -> float:
        if sims.ndim != 2:
            raise ValueError(f"simulate_fn must return shape (n_sim, k), got {sims.shape}")
        sims = sims[np.isfinite(sims).all(axis=1)]
        if sims.shape[0] < min_replicates(sims.shape[1], self.likelihood):
            return -math.inf
        ll = synthetic_loglik(self.observed, sims, self.likelihood)
        return ll if math.isfinite(ll) else -math.inf

    def _evaluate(self, coords: np.ndarray, indices) -> np.ndarray:
        out = np.full(len(coords), -math.inf)
        log_prior = np.array([float(self.prior.logpdf(theta)) for theta in coords])
        inside = np.flatnonzero(np.isfinite(log_prior))
        tasks = [(coords[j].copy(), (self.seed, Tag.EVALUATION, self.phase, self.step, int(indices[j])))
                 for j in inside]
        for j, sims in zip(inside, self._map(tasks)):
            if self.count is not None:
                self.count(PHASE_NAMES[self.phase], int(np.shape(sims)[0]), 1)
            out[j] = log_prior[j] + self._loglik(sims)
        return out

    def __call__(self, coords) -> np.ndarray:
        coords = np.atleast_2d(np.asarray(coords, dtype=float))
        first = self.index
        self.index += len(coords)
        return self._evaluate(coords, range(first, first + len(coords)))

    def evaluate_all(self, coords, phase: int, step: int) -> np.ndarray:
        self.begin(phase, step)
        return self(coords)

    def evaluate_at(self, thetas, phase: int, step: int, indices) -> np.ndarray:
        """Points ``thetas`` (n, d) evaluated as calls number ``indices`` (n,) of (phase, step)."""
        self.phase, self.step = phase, step
        return self._evaluate(np.atleast_2d(np.asarray(thetas, dtype=float)), list(indices))

    def initial(self, rng: np.random.Generator, walkers: int):
        """Initial walkers from the prior, redrawing those with a -inf log posterior (module docstring)."""
        ndim = int(self.prior.dim)
        coords = np.asarray(self.prior.sample(rng, walkers), dtype=float).reshape(walkers, ndim)
        log_prob = self.evaluate_all(coords, PHASE_INITIAL, 0)
        for attempt in range(1, MAX_INITIAL_ATTEMPTS + 1):
            bad = np.flatnonzero(~np.isfinite(log_prob))
            if bad.size == 0:
                return coords, log_prob
            fresh = np.asarray(self.prior.sample(rng, bad.size), dtype=float).reshape(bad.size, ndim)
            coords[bad] = fresh
            log_prob[bad] = self.evaluate_at(fresh, PHASE_INITIAL, attempt, bad)
        if not np.all(np.isfinite(log_prob)):
            raise RuntimeError(f"{int(np.sum(~np.isfinite(log_prob)))} initial walkers still have a "
                               f"-inf log posterior after {MAX_INITIAL_ATTEMPTS} redraws from the prior")
        return coords, log_prob


def run_bsl(simulate_fn: Callable, observed, prior, *, walkers: int, steps: int, seed: int,
            path: str | os.PathLike | None = None, resume: bool = False, likelihood: str = "gaussian",
            reevaluate_every: int = 0, progress: Callable | None = None,
            progress_every: int | None = None, executor=None, moves: str = "stretch",
            meta: dict | None = None, until_converged: bool = False, check_every: int = 50,
            count: Callable | None = None) -> ChainResult:
    """Run BSL-MCMC; see the module docstring for the full contract."""
    if likelihood not in METHODS:
        raise ValueError(f"likelihood: unknown method {likelihood!r}; allowed: {', '.join(METHODS)}")
    seed = integer(seed, "seed", 0)
    reevaluate_every = integer(reevaluate_every, "reevaluate_every", 0)
    logpost = _LogPosterior(simulate_fn, np.asarray(observed, dtype=float), prior, seed, likelihood, executor, count)
    meta = {**(meta or {}), "bsl_seed": seed, "bsl_likelihood": likelihood,
            "bsl_reevaluate_every": reevaluate_every, "bsl_moves": moves}
    return run_chain(logpost, prior, walkers=walkers, steps=steps, seed=seed, initial=logpost.initial,
                     path=path, resume=resume, meta=meta, meta_defaults={"bsl_moves": "stretch"},  # files before moves
                     needs="the settings the chain was started with",
                     moves=moves,
                     progress=progress, progress_every=progress_every,
                     before_step=lambda t: logpost.begin(PHASE_PROPOSAL, t), refresh_every=reevaluate_every,
                     refresh=lambda coords, t: logpost.evaluate_all(coords, PHASE_REEVALUATE, t),
                     until_converged=until_converged, check_every=check_every)
