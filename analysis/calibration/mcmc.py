"""The one emcee driver, used by BSL (:mod:`.bsl`), the emulator (:mod:`.emulated`) and, through BSL, SBC.

Contract
--------
``run_chain(log_prob, prior, *, walkers, steps, seed, initial, path=None, resume=False, meta=None,
meta_defaults=None, needs="the same settings", moves="stretch", progress=None, progress_every=None,
before_step=None, refresh_every=0, refresh=None, until_converged=False, check_every=CHECK_EVERY) -> ChainResult``

* ``log_prob(coords (n, d)) -> (n,)`` is called vectorised (emcee's ``vectorize=True``: each
  half-ensemble's proposals arrive at once); ``prior`` gives the dimension ``prior.dim`` and the names.
* Seeds (:mod:`sweeps.seeds`): the initial walkers are ``initial(generator(seed, Tag.WALKERS), walkers)
  -> (coords (walkers, d), log_prob (walkers,))`` (the caller draws them from the prior and replaces the
  unusable ones); emcee's move random state is ``RandomState(MT19937(seed_sequence((seed, Tag.MOVES))))``.
  Nothing else here is random, so the same arguments give a bit-identical chain.
* ``moves``: ``"stretch"`` (Goodman & Weare's stretch move, emcee's default) or ``"de"`` (differential
  evolution 90% with step ``DE_SCALE x 2.38 / sqrt(2 d)``, DE snooker 10%; ter Braak & Vrugt 2008),
  which mixes faster for a few parameters and a small ensemble; the shortened step keeps the
  acceptance up under a noisy synthetic likelihood.
* Storage: with ``path`` the chain goes to :class:`~analysis.calibration.chainfile.ChainFile` (emcee's
  HDF5 backend, group ``mcmc``; after every step the row, the log-probabilities, the acceptance counts
  and the random state, committed whole and not cut by SIGINT/SIGTERM; a failed write is
  ``WriteFailed``). Without ``resume`` an existing file is FileExistsError. The file records ``meta``
  plus ``walkers`` and ``ndim``; a resume needs every one stored with the same value (strings compared
  as strings, other values in the type of this run's value; a key missing from an older file takes its
  ``meta_defaults`` value, else it counts as different), else :class:`ChainMismatch` (a ConfigError
  at ``--resume``) listing every difference and ``needs``. A file that cannot be read as a chain, or
  whose rows changed since they were written (:func:`~analysis.calibration.chainfile.check_chain`: row
  checksums), is moved to ``quarantine/`` beside it with one warning and the chain starts again (the same
  seed gives the same chain). A run that fails before its first step is stored removes the file it
  created, and only then: a failed write never deletes a file that may hold steps.
* Exact resume: ``resume=True`` continues from the stored iteration up to ``steps`` rows and gives bit
  for bit the chain of an uninterrupted run (the state is what emcee stores: the last row, the accepted
  counts, the move random state). A file holding ``>= steps`` rows runs nothing; with no file (or an
  empty one) the run starts fresh.
* ``before_step(t)`` is called before row ``t`` (1-based) is computed; ``refresh(coords, t) -> (walkers,)``
  replaces the walkers' current log-probabilities before row ``t`` for every ``t`` that is a positive
  multiple of ``refresh_every`` (0: never) - BSL's re-evaluation of the noisy likelihood.
* ``until_converged``: ``steps`` is then a cap; after every row ``t`` that is a multiple of
  ``check_every`` (and before the first new row of a resume at such a row) the chain so far is judged by
  the project's convergence verdicts that more steps can change
  (:func:`~analysis.calibration.diagnostics.sampled_enough`: the rows after the default burn-in are at
  least 50 x the largest integrated autocorrelation time estimated on them, and ArviZ's R-hat <= 1.01 and
  bulk and tail ESS >= 400 with walkers as chains) and the run stops at the first row where they hold. Stopping depends only on the rows, which are
  bit-identical for the same arguments, so a resumed or repeated run stops at the same row.
* ``progress(step, acceptance_fraction_mean, tau_estimate)`` after every row, so a bar moves with each
  step; ``tau_estimate`` is :func:`progress_tau` of the second half of the rows so far, computed again
  every ``progress_every`` rows (default ``max(1, steps // 10)``) and at the last (the latest estimate
  in between; nan before the first).
* :class:`ChainResult`: ``chain`` (steps, walkers, d), ``log_prob`` (steps, walkers),
  ``acceptance_fraction`` (walkers,), ``names`` (the prior's), ``path`` (or None), ``seed``.

``progress_tau(chain) -> float``: the mean over parameters of the integrated autocorrelation times of
``chain`` (steps, walkers, d) (:func:`~analysis.calibration.diagnostics.integrated_times`, no length
check: an estimate for a progress display); nan when it cannot be computed (fewer than 2 rows, a
constant parameter).
"""
from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable

import emcee
import numpy as np

from pathlib import Path

from flocksweep.simcore.rng import seed_sequence
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.files import write_failed
from flocksweep.sweeps.quarantine import quarantine
from flocksweep.sweeps.seeds import Tag, generator

from .chainfile import ChainFile, DamagedChain, check_chain, differences, stored_attrs
from .checks import integer
from .diagnostics import integrated_times, sampled_enough

GROUP = "mcmc"
MOVES = ("stretch", "de")
DE_SCALE = 0.7   # differential-evolution step: this fraction of ter Braak's 2.38 / sqrt(2 d)
CHECK_EVERY = 50   # until_converged: the chain-length rule is checked after every this many rows


class ChainMismatch(ConfigError):
    """A stored chain was made with other settings than this resume's."""


@dataclasses.dataclass
class ChainResult:
    chain: np.ndarray                # (steps, walkers, d)
    log_prob: np.ndarray             # (steps, walkers)
    acceptance_fraction: np.ndarray  # (walkers,)
    names: tuple[str, ...] | None = None
    path: str | None = None
    seed: int | None = None


def emcee_moves(moves: str, ndim: int = 1):
    """emcee's proposal for ``moves`` (see the module docstring); None is emcee's default stretch move."""
    if moves == "stretch":
        return None
    if moves == "de":
        gamma0 = DE_SCALE * 2.38 / math.sqrt(2 * max(1, ndim))
        return [(emcee.moves.DEMove(gamma0=gamma0), 0.9), (emcee.moves.DESnookerMove(), 0.1)]
    raise ValueError(f"moves: unknown {moves!r}; allowed: {', '.join(MOVES)}")


def open_chain(path, resume: bool, meta: dict, defaults: dict | None = None, needs: str = "the same settings"):
    """The chain file at ``path``, checked against ``meta`` when it already holds a chain."""
    path = os.fspath(path)
    if os.path.exists(path) and not resume:
        raise FileExistsError(f"{path} exists; remove it to start afresh or pass resume=True")
    backend = ChainFile(path, name=GROUP)
    try:
        check_chain(path) if os.path.exists(path) else 0
        attrs = stored_attrs(path) if os.path.exists(path) else {}
        initialized = bool(attrs) and backend.initialized
    except DamagedChain as err:
        reason = str(err).replace(f"{path} ", "", 1).replace(f"{path}: ", "", 1)
        quarantine(Path(path).parent, Path(path), f"{reason}; the chain starts again from its first step "
                                                  "(same seed: same chain)")
        return ChainFile(path, name=GROUP)
    if initialized:
        attrs.setdefault("walkers", attrs.get("nwalkers"))
        found = differences(attrs, meta, defaults)
        if found:
            raise ChainMismatch("--resume", f"{path} holds a chain made with other settings ({'; '.join(found)}); "
                                            f"resume needs {needs}: restore them, or start a new chain in another "
                                            "folder (--out) or after removing the file")
    return backend


def progress_tau(chain: np.ndarray) -> float:
    if chain.shape[0] < 2:
        return math.nan
    tau = integrated_times(chain)
    return float(np.mean(tau)) if np.all(np.isfinite(tau)) else math.nan


def _sampler(log_prob, walkers: int, ndim: int, backend, meta: dict, moves: str):
    sampler = emcee.EnsembleSampler(walkers, ndim, log_prob, backend=backend, vectorize=True,
                                    moves=emcee_moves(moves, ndim))
    sampler.log_prob_fn = log_prob   # emcee's wrapper prints a traceback for any exception, Ctrl-C included
    if backend is not None:
        try:
            with backend.open("a") as f:
                for key, value in meta.items():
                    f[GROUP].attrs[key] = value
        except OSError as err:
            raise write_failed(backend.filename, err) from None
    return sampler


def run_chain(log_prob: Callable, prior, *, walkers: int, steps: int, seed: int, initial: Callable,
              path=None, resume: bool = False, meta: dict | None = None, meta_defaults: dict | None = None,
              needs: str = "the same settings", moves: str = "stretch", progress: Callable | None = None,
              progress_every: int | None = None, before_step: Callable | None = None, refresh_every: int = 0,
              refresh: Callable | None = None, until_converged: bool = False,
              check_every: int = CHECK_EVERY) -> ChainResult:
    """Run (or resume) an emcee chain; see the module docstring for the full contract."""
    emcee_moves(moves)   # validates
    steps = integer(steps, "steps", 1)
    check_every = integer(check_every, "check_every", 2) if until_converged else 0
    seed = integer(seed, "seed", 0)
    refresh_every = integer(refresh_every, "refresh_every", 0)
    ndim = int(prior.dim)
    walkers = integer(walkers, "walkers", max(2, 2 * ndim))
    every = max(1, steps // 10) if progress_every is None else integer(progress_every, "progress_every", 1)
    if resume and path is None:
        raise ValueError("resume=True needs a path")
    meta = {**(meta or {}), "walkers": walkers, "ndim": ndim}
    backend = None
    created = False
    if path is not None:
        path = os.fspath(path)
        created = not os.path.exists(path)
        backend = open_chain(path, resume, meta, meta_defaults, needs)
    try:
        return _run(log_prob, prior, backend, meta, moves, walkers, ndim, steps, seed, initial, every, progress,
                    before_step, refresh_every, refresh, path, check_every)
    except BaseException:
        if created and backend is not None and _empty(path):
            os.unlink(path)   # nothing of ours is in it yet: a rerun starts cleanly
        raise


def _empty(path) -> bool:
    """True only for a chain file that can be read and holds no step: one that cannot be read (a full
    disk cut its write) may hold steps, so it is kept (the next run sets it aside if it is damaged)."""
    try:
        return os.path.exists(path) and int(stored_attrs(path).get("iteration", 0)) == 0
    except ValueError:
        return False


def _run(log_prob, prior, backend, meta, moves, walkers, ndim, steps, seed, initial, every, progress, before_step,
         refresh_every, refresh, path, check_every=0) -> ChainResult:
    sampler = _sampler(log_prob, walkers, ndim, backend, meta, moves)
    start = int(sampler.backend.iteration)
    if start == 0:
        coords, values = initial(generator(seed, Tag.WALKERS), walkers)
        move_rs = np.random.RandomState(np.random.MT19937(seed_sequence((seed, Tag.MOVES))))
        state = emcee.State(coords, log_prob=values, random_state=move_rs.get_state())
    else:
        state = sampler.backend.get_last_sample()   # coords, log_prob, emcee's random state
    t = start
    check_initial = start == 0
    tau = float("nan")

    def converged() -> bool:
        return bool(check_every and t > 0 and t % check_every == 0 and sampled_enough(sampler.backend.get_chain()))

    done = converged()
    while t < steps and not done:
        if refresh_every and t > 0 and t % refresh_every == 0:
            state = emcee.State(state.coords, log_prob=refresh(state.coords, t), random_state=state.random_state)
        stop = min(steps, (t // refresh_every + 1) * refresh_every) if refresh_every else steps
        rows = sampler.sample(state, iterations=stop - t, skip_initial_state_check=not check_initial)
        check_initial = False
        for _ in range(stop - t):
            if before_step is not None:
                before_step(t + 1)
            state = next(rows)
            t += 1
            done = converged()
            if progress is not None:
                if t % every == 0 or t == steps or done:
                    tau = progress_tau(sampler.backend.get_chain()[t // 2:])
                progress(t, float(np.mean(sampler.backend.accepted / float(t))), tau)
            if done:
                break
        rows.close()
    stored = sampler.backend
    names = getattr(prior, "names", None)
    return ChainResult(chain=np.asarray(stored.get_chain()), log_prob=np.asarray(stored.get_log_prob()),
                       acceptance_fraction=np.asarray(stored.accepted, dtype=float) / float(stored.iteration),
                       names=tuple(names) if names is not None else None, path=path, seed=seed)
