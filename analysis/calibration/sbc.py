"""Simulation-based calibration (SBC; Talts et al. 2018, arXiv:1804.06788) of the BSL posterior.

SBC checks the whole inference pipeline (simulator, synthetic likelihood, MCMC, burn-in, thinning): if
``theta ~ prior``, ``y ~ p(y | theta)`` and ``theta_1..theta_S`` are draws of the posterior computed
from ``y``, then the rank of ``theta`` among the ``theta_s`` (the number of draws below it, 0..S) is
uniformly distributed on 0..S for every parameter. Non-uniform ranks mean miscalibration: a U shape an
overconfident posterior, a hump an overdispersed one, a slope a biased one.

Contract
--------
``run_sbc(config, datasets=50, draws=49, out_dir=None, progress=True, *, steps=None, walkers=None,
bins=None, workers=1, order=None, resume=True, alpha=0.05) -> dict`` (BSL's; the check of any calibration
by its own method is :func:`analysis.calibration.methods.run_sbc`, which runs this one for emcee, this one
on :func:`analysis.calibration.sbc_emulator.emulator_problem` for the emulator (its chain on the
surrogate in place of BSL's) and :func:`analysis.calibration.sbc_npe.run_npe_sbc` for npe)

* ``config`` is a :class:`~analysis.calibration.config.CalibrationConfig` with method ``emcee`` (or an
  :class:`SBCProblem`, e.g. a cheap toy model in tests). ``steps`` / ``walkers`` override the config's.
* For dataset ``j = 0..datasets-1``, every random number comes from ``(config.seed, j)`` only, through
  ``seed_sequence((seed, Tag.SBC, j, stream))`` (:mod:`sweeps.seeds`, streams :class:`~sweeps.seeds.SBCStream`):
    - stream 0: ``theta_j = prior.sample(rng, 1)[0]``, shape (d,);
    - stream 1: the observed data ``y_j``, shape (m, k) (m = rows of the config's targets, 1 for
      mean/sd targets), from the SAME data model the likelihood assumes: the summary simulator plus,
      for mean/sd (or cov) targets, Gaussian observation noise with the targets' covariance
      (:func:`analysis.calibration.data_model.simulate_fn` on a one-replicate-per-row simulator);
    - stream 2: the integer ``seed`` given to :func:`~analysis.calibration.bsl.run_bsl` (observed=y_j,
      the config's walkers, steps, n_sim, likelihood, reevaluate_every);
    - stream 3: which thinned posterior draws are kept; stream 4: tie-breaking in the ranks.
  A dataset's result therefore does not depend on the order datasets are processed in, on other
  datasets, on the number of worker processes or on being resumed.
* Posterior draws (:func:`posterior_draws`): burn-in is the first HALF of the chain; the integrated
  autocorrelation time ``tau`` (largest over parameters, estimated on the kept half) sets the thinning
  ``thin = ceil(tau)``; ``draws`` = S of the thinned rows x walkers are picked without replacement.
  When fewer than S thinned draws exist the thinning is reduced until S exist and the dataset is
  flagged ``short`` (its draws are autocorrelated; too many short datasets mean the chains are too
  short for SBC).
* Storage in ``out_dir`` (default ``results/calibration/<name>/sbc``, an :class:`sweeps.store.OutputFolder`,
  locked while it runs): ``settings.json`` (everything
  the results depend on; a resume with other settings is refused, except a larger ``datasets``),
  ``datasets/<j:06d>.json`` per dataset, written atomically when that dataset is done (theta, y,
  ranks, posterior draws, tau, thinning, acceptance, wall time, the simulations it ran by phase:
  :mod:`~analysis.calibration.accounting`), so an interrupted run resumes where it
  stopped (``resume=False`` refuses an existing folder with results). When all datasets are done:
  ``ranks.csv`` (one row per dataset), ``uniformity.csv`` and ``uniformity.md`` (chi-square test per
  parameter from :func:`~analysis.calibration.diagnostics.sbc_uniformity`, plus the ECDF band test),
  ``rank_histogram.png`` (:func:`~analysis.calibration.plots.sbc_figure`), ``ecdf_diff.png`` (ECDF
  of the fractional ranks minus the uniform CDF with a simultaneous band) and ``summary.json``.
* Two uniformity tests per parameter: the chi-square test of the binned rank histogram
  (:func:`~analysis.calibration.diagnostics.sbc_uniformity`, ``bins`` default
  :func:`~analysis.calibration.sbc_report.default_bins`)
  and the ECDF test (Saeilynoja et al. 2022), whose p-value is the probability, under uniform ranks, of
  a rank ECDF whose most extreme point-wise binomial tail probability is as small as the observed one
  (more powerful against U and hump shapes than a coarse histogram). Verdict: no significant
  miscalibration when every p-value is at least ``alpha / (2 d)`` (Bonferroni over both tests and the
  d parameters).
* ``workers > 1`` runs datasets on a local :class:`sweeps.executors.Executor` of that many processes
  (the problem travels to them with cloudpickle). As with any spawn pool, a script calling it needs the
  ``if __name__ == "__main__":`` guard. Results are the same as with 1.
* :func:`analysis.calibration.sbc_report.write_report` rebuilds the tables and figures from the
  stored datasets alone (run_sbc calls it at the end).
* Return value: ``{"out", "table" (DataFrame, index parameter: chi2, dof, p, n, bins, ecdf_p),
  "ranks" (DataFrame), "calibrated" (bool), "verdict" (sentence), "paths" (name -> Path), "wall_s"}``.

Array shapes: theta (d,), y (m, k), posterior draws (S, d), ranks (L, d) for L datasets; ranks are
integers in 0..S. Nothing runs at import.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import sys
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from tqdm import tqdm

from flocksweep.simcore.rng import seed_sequence
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps import seeds
from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.files import json_ready
from flocksweep.sweeps.progress import Phases
from flocksweep.sweeps.seeds import SBCStream, Tag
from flocksweep.sweeps.store import OutputFolder

from .accounting import Accounting
from .bsl import run_bsl
from .checks import integer
from .diagnostics import integrated_times, sbc_ranks
from .data_model import simulate_fn
from .simulator import summary_simulator
from .sbc_report import dataset_path, write_report


@dataclasses.dataclass(frozen=True)
class SBCProblem:
    """Everything SBC needs: prior, the likelihood's simulator, the data model and the BSL settings.

    ``simulate_fn(theta, rng) -> (n_sim, k)`` is what the synthetic likelihood fits (as in run_bsl);
    ``observe_fn(theta, rng) -> (m, k)`` draws one observed dataset from the generative model. For a
    calibrated posterior both must describe the same model. ``meta`` (JSON-ready) identifies the
    problem in ``settings.json``. ``posterior_fn(y, seed) -> ChainResult``, when given, is the chain of
    another method on dataset ``y`` in place of BSL's (the emulator's chain on its surrogate:
    :mod:`analysis.calibration.sbc_emulator`); ``simulate_fn`` is then unused."""

    prior: object
    simulate_fn: Callable
    observe_fn: Callable
    names: tuple[str, ...]
    columns: tuple[str, ...]
    seed: int
    walkers: int
    steps: int
    likelihood: str = "gaussian"
    reevaluate_every: int = 0
    moves: str = "stretch"
    meta: dict = dataclasses.field(default_factory=dict, compare=False)
    posterior_fn: Callable | None = dataclasses.field(default=None, compare=False)

    @property
    def dim(self) -> int:
        return len(self.names)


# ------------------------------------------------------------------------------------------ the problem

def problem_from_config(config, steps: int | None = None, walkers: int | None = None) -> SBCProblem:
    """The SBC problem of an emcee calibration config (optionally with other steps / walkers)."""
    if not all(hasattr(config.method, key) for key in ("walkers", "steps", "n_sim", "likelihood")):
        raise ConfigError("method.kind", f"got {config.method.kind!r}; this is the problem of a BSL chain (walkers, "
                                         "steps, n_sim); methods.run_sbc runs each method's own SBC")
    settings = config.method
    rows = int(np.asarray(config.targets.observed).shape[0])
    observer = summary_simulator(config, n_sim=rows)
    meta = {"name": config.name, "n_sim": int(settings.n_sim), "observed_rows": rows,
            "config": json_ready(config.source), "preset_sha256": _digest(config.preset_data)}
    return SBCProblem(prior=config.prior, simulate_fn=simulate_fn(config, summary_simulator(config)),
                      observe_fn=simulate_fn(config, observer), names=tuple(config.names),
                      columns=tuple(config.targets.columns), seed=int(config.seed),
                      walkers=int(walkers if walkers is not None else settings.walkers),
                      steps=int(steps if steps is not None else settings.steps),
                      likelihood=settings.likelihood, reevaluate_every=int(settings.reevaluate_every),
                      moves=settings.moves, meta=meta)


def _as_problem(source, steps=None, walkers=None) -> SBCProblem:
    if isinstance(source, SBCProblem):
        changes = {k: int(v) for k, v in (("steps", steps), ("walkers", walkers)) if v is not None}
        return dataclasses.replace(source, **changes) if changes else source
    return problem_from_config(source, steps=steps, walkers=walkers)


# ---------------------------------------------------------------------------------------------- seeds

def stream(seed: int, j: int, which: int) -> np.random.SeedSequence:
    """The seed sequence of stream ``which`` of dataset ``j`` (see the module docstring)."""
    return seed_sequence((seed, Tag.SBC, j, which))


def generator(seed: int, j: int, which: int) -> np.random.Generator:
    """The generator of stream ``which`` of dataset ``j``: ``Generator(PCG64(stream(seed, j, which)))``."""
    return seeds.generator(seed, Tag.SBC, j, which)


def bsl_seed(seed: int, j: int) -> int:
    """The integer seed of dataset ``j``'s BSL run, in [0, 2**63)."""
    word = stream(seed, j, SBCStream.BSL).generate_state(1, np.uint64)[0]
    return int(word >> np.uint64(1))


# ------------------------------------------------------------------------------------------ one dataset

def draw_theta(problem: SBCProblem, j: int) -> np.ndarray:
    """theta_j ~ prior, shape (d,)."""
    return np.asarray(problem.prior.sample(generator(problem.seed, j, SBCStream.THETA), 1), dtype=float)[0]


def draw_observed(problem: SBCProblem, theta, j: int) -> np.ndarray:
    """y_j ~ p(y | theta_j), shape (m, k)."""
    y = np.asarray(problem.observe_fn(np.asarray(theta, dtype=float), generator(problem.seed, j,
                                                                                SBCStream.OBSERVED)), dtype=float)
    return y[None, :] if y.ndim == 1 else y


def thinning(chain: np.ndarray, draws: int) -> dict:
    """Burn-in (half the chain), tau of the kept half (max over parameters) and the thinning that
    leaves at least ``draws`` draws: ``ceil(tau)``, reduced (``short``) when that leaves too few."""
    steps, walkers, _ = chain.shape
    burn = steps // 2
    kept = steps - burn
    tau = integrated_times(chain[burn:]) if kept >= 2 else np.full(chain.shape[2], np.nan)
    finite = tau[np.isfinite(tau)]
    tau_max = float(finite.max()) if finite.size else math.nan
    thin = max(1, math.ceil(tau_max)) if math.isfinite(tau_max) else 1
    rows_needed = math.ceil(draws / walkers)
    if kept < rows_needed:
        raise ValueError(f"{kept} steps after burn-in x {walkers} walkers cannot give {draws} draws; "
                         f"run at least {2 * rows_needed} steps")
    short = math.ceil(kept / thin) < rows_needed
    if short:
        thin = max(1, kept // rows_needed)
    return {"burn": burn, "tau": [float(t) for t in tau], "tau_max": tau_max, "thin": thin, "short": short,
            "pool": int(math.ceil(kept / thin) * walkers)}


def posterior_draws(chain, draws: int, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """``draws`` roughly independent posterior draws (S, d) from an emcee chain (steps, walkers, d),
    with the burn-in / thinning record of :func:`thinning`."""
    chain = np.asarray(chain, dtype=float)
    info = thinning(chain, draws)
    pool = chain[info["burn"]::info["thin"]].reshape(-1, chain.shape[2])
    pick = np.sort(rng.choice(len(pool), size=draws, replace=False))
    return pool[pick], info


def sbc_dataset(problem: SBCProblem, j: int, draws: int) -> dict:
    """Run SBC dataset ``j``: theta, y, BSL posterior, ranks. A JSON-ready record."""
    started = time.time()
    cost = Accounting()
    theta = draw_theta(problem, j)
    y = draw_observed(problem, theta, j)
    cost.add("observed", len(y))
    if problem.posterior_fn is not None:   # another method's chain (it simulates nothing)
        result = problem.posterior_fn(y, bsl_seed(problem.seed, j))
    else:
        result = run_bsl(problem.simulate_fn, y, problem.prior, walkers=problem.walkers, steps=problem.steps,
                         seed=bsl_seed(problem.seed, j), likelihood=problem.likelihood,
                         reevaluate_every=problem.reevaluate_every, moves=problem.moves, count=cost.add)
    sample, info = posterior_draws(result.chain, draws, generator(problem.seed, j, SBCStream.SELECT))
    ranks = sbc_ranks(theta[None, :], [sample], rng=generator(problem.seed, j, SBCStream.TIES))[0]
    return {"dataset": int(j), "theta": theta.tolist(), "observed": y.tolist(), "ranks": ranks.tolist(),
            "draws": sample.tolist(), "post_mean": sample.mean(axis=0).tolist(),
            "post_sd": sample.std(axis=0, ddof=1).tolist(), "acceptance": float(result.acceptance_fraction.mean()),
            "steps": int(result.chain.shape[0]), "walkers": int(result.chain.shape[1]), "bsl_seed":
            bsl_seed(problem.seed, j), **info, "wall_s": time.time() - started,
            "simulations": cost.block()["simulations"]}


# -------------------------------------------------------------------------------------------- storage

def settings_record(problem: SBCProblem, draws: int) -> dict:
    """What the per-dataset results depend on (compared on resume)."""
    moves = {} if problem.moves == "stretch" else {"moves": problem.moves}   # records before moves: stretch
    return json_ready({**moves, "method": "sbc", "seed": problem.seed, "draws": int(draws),
                       "names": list(problem.names), "columns": list(problem.columns), "walkers": problem.walkers,
                       "steps": problem.steps, "likelihood": problem.likelihood,
                       "reevaluate_every": problem.reevaluate_every, "burn": "first half of the chain",
                       "thin": "ceil(max tau of the kept half)", "problem": problem.meta})


def _check_settings(folder: OutputFolder, settings: dict) -> dict | None:
    """The stored settings; ConfigError when they differ from ``settings``."""
    stored = folder.read_json("settings.json")
    if stored is not None and stored != settings:
        diff = sorted(k for k in set(stored) | set(settings) if stored.get(k) != settings.get(k))
        raise ConfigError("--out", f"{folder.path('settings.json')} was written with other settings "
                                   f"({', '.join(diff)} differ); use another folder or remove it")
    return stored


def _prepare_out(folder: OutputFolder, settings: dict, resume: bool) -> None:
    stored = _check_settings(folder, settings)
    if stored is not None:
        if not resume and any(folder.path("datasets").glob("*.json")):
            raise FileExistsError(f"{folder.root} holds SBC results; pass resume=True to continue, or remove it")
    folder.write_json("settings.json", settings)


# -------------------------------------------------------------------------------------------- running

def _bar(total: int, done: int, name: str, enabled: bool):
    if not enabled:
        return None
    return tqdm(total=total, initial=done, desc=f"SBC {name}", unit="dataset", smoothing=0.1, file=sys.stderr,
                mininterval=0.5)


def _tick(bar, record: dict) -> None:
    if bar is not None:
        bar.update(1)
        bar.set_postfix(tau=f"{record['tau_max']:.1f}", acc=f"{record['acceptance']:.2f}",
                        s=f"{record['wall_s']:.0f}", refresh=False)


def _run_missing(problem: SBCProblem, todo: list[int], draws: int, folder: OutputFolder, workers: int, bar) -> None:
    """Fit the datasets ``todo``, saving each record as soon as it is done (in finishing order)."""
    task = functools.partial(sbc_dataset, problem, draws=draws)
    with Executor("local" if workers > 1 else "serial", workers) as pool:
        for outcome in pool.as_completed(task, todo):
            if outcome.error is not None:
                raise outcome.error   # finished datasets are saved; the executor stops the rest
            folder.write_json(str(dataset_path(folder.root, outcome.item).relative_to(folder.root)), outcome.value)
            _tick(bar, outcome.value)


def run_sbc(config, datasets: int = 50, draws: int = 49, out_dir=None, progress: bool = True, *,
            steps: int | None = None, walkers: int | None = None, bins: int | None = None,
            workers: int = 1, order: Sequence[int] | None = None, resume: bool = True,
            alpha: float = 0.05) -> dict:
    """Simulation-based calibration of the config's BSL posterior; see the module docstring."""
    problem = _as_problem(config, steps, walkers)
    datasets, draws = integer(datasets, "datasets", 1), integer(draws, "draws", 1)
    workers = integer(workers, "workers", 1)
    if out_dir is None:
        if isinstance(config, SBCProblem):
            raise ValueError("out_dir is required when config is an SBCProblem")
        out_dir = Path("results") / "calibration" / config.name / "sbc"
    folder = OutputFolder(out_dir)
    order = list(range(datasets)) if order is None else [int(j) for j in order]
    if sorted(order) != list(range(datasets)):
        raise ValueError(f"order must be a permutation of 0..{datasets - 1}")
    _check_settings(folder, settings_record(problem, draws))   # before the lock: refused without a write
    with folder.lock():
        _prepare_out(folder, settings_record(problem, draws), resume)
        todo = [j for j in order if not dataset_path(folder.root, j).exists()]
        started = time.time()
        phases = Phases("sbc", 2, progress)
        phases.start(f"fitting {len(todo)} of {datasets} datasets ({problem.walkers} walkers x {problem.steps} "
                     f"steps each; {datasets - len(todo)} stored)")
        bar = _bar(datasets, datasets - len(todo), problem.meta.get("name", "problem"), progress)
        try:
            _run_missing(problem, todo, draws, folder, workers, bar)
        finally:
            if bar is not None:
                bar.close()
        phases.start("the rank statistics, figures and report")
        result = write_report(folder.root, problem.names, datasets, draws, bins=bins, alpha=alpha,
                              seed=problem.seed, columns=problem.columns)
        phases.done(f": {folder.root}")
    result["wall_s"] = time.time() - started
    return result


def _digest(data) -> str:
    """sha256 of a JSON-ready structure (sorted keys): detects a changed model preset on resume."""
    return hashlib.sha256(json.dumps(json_ready(data), sort_keys=True).encode()).hexdigest()
