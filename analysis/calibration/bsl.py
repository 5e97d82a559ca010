"""Bayesian synthetic likelihood (BSL) MCMC with emcee (Price et al. 2018).

Contract
--------
``run_bsl(simulate_fn, observed, prior, *, walkers, steps, seed, path=None, resume=False,
likelihood="gaussian", reevaluate_every=0, progress=None, progress_every=None, evaluator=None) -> BSLResult``

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
* Randomness is a deterministic function of ``seed`` only:
    - initial walkers: ``prior.sample(Generator(PCG64(SeedSequence([seed, 0]))), walkers)``; walkers
      whose initial log posterior is -inf (e.g. all-NaN summaries) are redrawn from the same generator
      (evaluation ``(phase 0, step = attempt, i = walker)``), at most 100 rounds, else RuntimeError;
    - emcee's move randomness: a ``RandomState(MT19937(SeedSequence([seed, 1])))`` state passed in
      the initial :class:`emcee.State`;
    - each log-posterior evaluation: ``Generator(PCG64(SeedSequence([seed, 2, phase, step, i])))``
      where ``phase`` is 0 for the initial walkers (step 0), 1 for the proposals made while computing
      chain row ``step - 1`` (step = 1..steps) and 2 for re-evaluations at step ``step``; ``i`` is the
      call's position within that step. emcee's stretch move evaluates the proposals of the two
      half-ensembles in walker order, so ``i`` is the walker index (so do the DE moves of
  ``moves="de"``, which also split the ensemble in two). No counter has to be stored.
  The same arguments therefore give a bit-identical chain.
* Parallelism: emcee is run vectorised, so each half-ensemble's proposals (``walkers / 2`` points)
  arrive at once and their simulations are mapped through ``evaluator`` (an
  :class:`~analysis.calibration.parallel.Evaluator`, or None for this process), one task per point.
  A task is ``(theta, seed key)``, so the chain is bit-identical whatever the executor and workers.
* Storage: with ``path`` the chain goes to ``emcee.backends.HDFBackend(path, name="mcmc")`` (after
  every step emcee writes the chain row, the log-probabilities, the acceptance counts and its random
  state into the file). Without ``resume`` an existing file is an error (remove it yourself, or pass
  ``resume=True``); the file also records ``bsl_seed``, ``bsl_likelihood``, ``bsl_reevaluate_every``,
  which a resume must match (ValueError otherwise).
* Exact resume: ``resume=True`` continues from the stored iteration up to ``steps`` rows in total and
  gives bit for bit the chain of an uninterrupted run. The state needed is exactly what emcee stores:
  the last row (coordinates and log-probabilities), the accepted counts and the move random state
  (MT19937 state in the group attributes). The simulation seeds follow from (seed, phase, step, i) and
  re-evaluations happen at fixed step numbers, so they are recomputed identically. A file whose stored
  iteration is 0 starts from the (seeded) initial walkers; with ``resume=True`` and no file the run
  starts fresh. If the file already holds ``>= steps`` rows nothing is run and the stored rows are
  returned. emcee writes one step per HDF5 open/close; an interruption in the middle of that write
  can leave the file unusable (the step is not journaled).
* ``reevaluate_every = r > 0``: before computing row ``t`` for every ``t`` with ``t % r == 0`` (t > 0),
  the log posterior of every walker's current point is re-simulated with fresh seeds (phase 2) and
  replaces the current log-probability emcee compares proposals against, so a lucky overestimate of
  the noisy synthetic likelihood cannot keep a walker stuck. Rows already written keep the value they
  had; a walker that rejects its next proposal shows the re-evaluated value in the next row. This is
  the "noisy" (not pseudo-marginal exact) variant of BSL; 0 (default) never re-evaluates.
* ``progress(step, acceptance_fraction_mean, tau_estimate)`` is called after every ``progress_every``
  rows (default ``max(1, steps // 10)``) and after the last one; ``tau_estimate`` is the mean over
  parameters of emcee's integrated autocorrelation time of the second half of the rows so far (the
  first half taken as burn-in; no length check), nan
  when it cannot be computed (fewer than 2 rows).
* :class:`BSLResult`: ``chain`` (steps, walkers, d), ``log_prob`` (steps, walkers),
  ``acceptance_fraction`` (walkers,), ``names`` (the prior's parameter names when it has them),
  ``path`` (or None), ``seed``.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import os
from typing import Callable

import numpy as np

from .chainfile import MOVES, emcee_moves, ensemble_sampler, open_chain, progress_tau  # noqa: F401 (MOVES)
from .likelihood import METHODS, synthetic_loglik

_TAG_INIT, _TAG_MOVES, _TAG_EVAL = 0, 1, 2
PHASE_INITIAL, PHASE_PROPOSAL, PHASE_REEVALUATE = 0, 1, 2
MAX_INITIAL_ATTEMPTS = 100


@dataclasses.dataclass
class BSLResult:
    chain: np.ndarray               # (steps, walkers, d)
    log_prob: np.ndarray            # (steps, walkers)
    acceptance_fraction: np.ndarray  # (walkers,)
    names: tuple[str, ...] | None = None
    path: str | None = None
    seed: int | None = None


def min_replicates(k: int, likelihood: str) -> int:
    """Fewest finite simulated rows :func:`synthetic_loglik` accepts for ``k`` statistics."""
    return k + 2 if likelihood == "gaussian" else k + 4


def simulate_keyed(simulate_fn, task):
    """One evaluation's simulations: ``task = (theta, key)``; the generator is PCG64(SeedSequence(key)),
    so the result depends on the task only (not on the process or the order it runs in)."""
    theta, key = task
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(list(key))))
    return np.asarray(simulate_fn(np.array(theta, dtype=float), rng), dtype=float)


class _LogPosterior:
    """Vectorised log posterior with a deterministic per-evaluation generator (see module docstring).

    Called by emcee with a (n, d) block of points (a half-ensemble of proposals); evaluation ``i`` of
    the current (phase, step) gets the seed key ``(seed, 2, phase, step, i)``. The points inside the
    prior's support are simulated through ``evaluator.map`` (one task each, in order)."""

    def __init__(self, simulate_fn, observed, prior, seed: int, likelihood: str, evaluator=None):
        self.simulate_fn = simulate_fn
        self.observed = observed
        self.prior = prior
        self.seed = seed
        self.likelihood = likelihood
        self.evaluator = evaluator
        self.phase = PHASE_INITIAL
        self.step = 0
        self.index = 0

    def begin(self, phase: int, step: int) -> None:
        self.phase, self.step, self.index = phase, step, 0

    def _map(self, tasks) -> list:
        fn = functools.partial(simulate_keyed, self.simulate_fn)
        if self.evaluator is None:
            return [fn(task) for task in tasks]
        return self.evaluator.map(fn, tasks)

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
        tasks = [(coords[j].copy(), (self.seed, _TAG_EVAL, self.phase, self.step, int(indices[j])))
                 for j in inside]
        for j, sims in zip(inside, self._map(tasks)):
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


def _int(value, name: str, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name}: got {value!r}; must be an integer >= {minimum}")
    return int(value)


def run_bsl(simulate_fn: Callable, observed, prior, *, walkers: int, steps: int, seed: int,
            path: str | os.PathLike | None = None, resume: bool = False, likelihood: str = "gaussian",
            reevaluate_every: int = 0, progress: Callable | None = None,
            progress_every: int | None = None, evaluator=None, moves: str = "stretch") -> BSLResult:
    """Run BSL-MCMC; see the module docstring for the full contract."""
    import emcee

    if likelihood not in METHODS:
        raise ValueError(f"likelihood: unknown method {likelihood!r}; allowed: {', '.join(METHODS)}")
    steps = _int(steps, "steps", 1)
    seed = _int(seed, "seed", 0)
    reevaluate_every = _int(reevaluate_every, "reevaluate_every", 0)
    ndim = int(prior.dim)
    walkers = _int(walkers, "walkers", max(2, 2 * ndim))
    progress_every = max(1, steps // 10) if progress_every is None else _int(progress_every,
                                                                               "progress_every", 1)
    observed = np.asarray(observed, dtype=float)
    if resume and path is None:
        raise ValueError("resume=True needs a path")

    emcee_moves(moves)   # validates
    meta = {"bsl_seed": seed, "bsl_likelihood": likelihood, "bsl_reevaluate_every": reevaluate_every,
            "bsl_moves": moves}
    backend = None
    if path is not None:
        path = os.fspath(path)
        backend = open_chain(path, resume, meta, defaults={"bsl_moves": "stretch"},   # files before moves
                             needs="the same seed, likelihood, reevaluate_every and moves")

    logpost = _LogPosterior(simulate_fn, observed, prior, seed, likelihood, evaluator)
    sampler = ensemble_sampler(logpost, walkers, ndim, backend, meta, moves)

    start = int(sampler.backend.iteration)
    if start == 0:
        init_rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, _TAG_INIT])))
        coords = np.asarray(prior.sample(init_rng, walkers), dtype=float).reshape(walkers, ndim)
        move_rs = np.random.RandomState(np.random.MT19937(np.random.SeedSequence([seed, _TAG_MOVES])))
        log_prob = logpost.evaluate_all(coords, PHASE_INITIAL, 0)
        for attempt in range(1, MAX_INITIAL_ATTEMPTS + 1):
            bad = np.flatnonzero(~np.isfinite(log_prob))
            if bad.size == 0:
                break
            fresh = np.asarray(prior.sample(init_rng, bad.size), dtype=float).reshape(bad.size, ndim)
            coords[bad] = fresh
            log_prob[bad] = logpost.evaluate_at(fresh, PHASE_INITIAL, attempt, bad)
        else:
            if not np.all(np.isfinite(log_prob)):
                raise RuntimeError(f"{int(np.sum(~np.isfinite(log_prob)))} initial walkers still have a "
                                   f"-inf log posterior after {MAX_INITIAL_ATTEMPTS} redraws from the prior")
        state = emcee.State(coords, log_prob=log_prob, random_state=move_rs.get_state())
        check_initial = True
    else:
        state = sampler.backend.get_last_sample()   # coords, log_prob, emcee's random state
        check_initial = False

    t = start
    while t < steps:
        if reevaluate_every and t > 0 and t % reevaluate_every == 0:
            state = emcee.State(state.coords, log_prob=logpost.evaluate_all(state.coords, PHASE_REEVALUATE, t),
                                random_state=state.random_state)
        stop = steps
        if reevaluate_every:
            stop = min(steps, (t // reevaluate_every + 1) * reevaluate_every)
        gen = sampler.sample(state, iterations=stop - t, skip_initial_state_check=not check_initial)
        check_initial = False
        for _ in range(stop - t):
            logpost.begin(PHASE_PROPOSAL, t + 1)
            state = next(gen)
            t += 1
            if progress is not None and (t % progress_every == 0 or t == steps):
                acc = float(np.mean(sampler.backend.accepted / float(t)))
                progress(t, acc, progress_tau(sampler.backend.get_chain()[t // 2:]))
        gen.close()

    b = sampler.backend
    n = int(b.iteration)
    names = getattr(prior, "names", None)
    return BSLResult(chain=np.asarray(b.get_chain()), log_prob=np.asarray(b.get_log_prob()),
                     acceptance_fraction=np.asarray(b.accepted, dtype=float) / float(n),
                     names=tuple(names) if names is not None else None, path=path, seed=seed)
