"""``flocksweep calibrate``: from a calibration TOML to a posterior with its diagnostics, on disk.

Python API (importable from :mod:`analysis.calibration`):

* ``calibrate(config, out_dir=None, resume=False, progress=True, predictive_draws=100, executor="serial",
  workers=None, scheduler=None) -> arviz.InferenceData``: runs the configured method, writes its outputs
  and returns the InferenceData also written as ``posterior.nc``;
* ``run_calibration(...)`` (same arguments) -> :class:`CalibrationRun`: everything the run produced
  (InferenceData, posterior table, verdicts, predictive check, confirmation, refinement rounds), what
  the command line prints from;
* ``load_calibration_results(out_dir) -> InferenceData`` reads ``posterior.nc`` back
  (:mod:`~analysis.calibration.inference`).

``out_dir`` (default ``results/calibration/<name>/``) is an :class:`sweeps.store.OutputFolder`: locked
while it runs (a second calibration writing there gets ``StoreLocked``), every file written atomically,
the provenance stamp in ``convergence.json`` / ``optimum.json``. Simulations run on a
:class:`sweeps.executors.Executor` (``serial``: this process, each evaluation's replicates in one
threaded compiled call; ``local``: a process pool evaluating proposals in parallel; ``dask``); the
results do not depend on it.

* ``posterior.nc``: ArviZ InferenceData (posterior with parameter names, walkers as chains; sample
  stats with the log likelihood and acceptance; posterior predictive of the target statistics; observed
  data; prior draws; :mod:`~analysis.calibration.inference`);
* ``chain.h5``: the emcee chain (HDF5 backend; ``resume`` continues it exactly, and so does the same
  command run again without it: an existing chain is always continued, never replaced). It records everything
  that defines the chain (:func:`chain_meta`: seed, walkers, moves, likelihood, re-evaluation, n_sim, the
  parameters and their priors, the targets, the model and the metric settings); ``resume`` with any of
  them changed is refused with the list of differences (``ChainMismatch``, a ConfigError at
  ``--resume``), never silently continued;
* ``posterior.csv``: mean, sd, median, 95% and 90% intervals, emcee's integrated autocorrelation time and
  effective sample size, acceptance, and ArviZ's R-hat, bulk and tail ESS and MCSE per parameter;
* ``convergence.json``: plain verdicts (chain length >= 50 tau, acceptance in [0.2, 0.5], R-hat <= 1.01,
  bulk and tail ESS >= 400), the warnings for parameters the targets do not constrain, and the
  provenance stamp;
* ``predictive.csv``: the posterior predictive check (each target against its distribution under
  posterior draws, with its two-sided tail probability);
* ``trace.png``, ``rank.png``, ``corner.png`` (the ``corner`` package: quantiles, contours, truth lines
  when ``targets.truth`` is given), ``predictive.png``;
* ``report.html`` / ``report.md``: the calibration report (:mod:`~analysis.calibration.calibration_report`);
* ``viewer_posterior_median.html``: an interactive 3-D page of one run at the posterior median;
* ``viewer_predictive.html`` (targets from tracks): the measured flock and the predictive run nearest the
  posterior median, re-simulated and checked, as two runs of one page (:mod:`~analysis.calibration.viewer_page`).

The simulator runs ``n_sim`` replicates per evaluation in one batched compiled call, with fresh seeds
at every evaluation. When the targets are given as mean and sd (or a covariance), that observation
uncertainty is added to every simulated summary as Gaussian noise drawn from the same evaluation's
generator, so the fitted Gaussian's covariance is the simulator's plus the observation's. Targets
given as samples (a CSV of observed datasets) are used as they are.

Method ``optimize`` (``scipy.optimize``, common random numbers during the search, the optimum
re-checked with fresh seeds) writes ``optimum.json`` (theta, objective with the common seeds and
re-checked, its standard error, evaluations), ``posterior.nc`` (no posterior: the optimum and the
re-check runs) and ``predictive.csv``/``.png`` at the optimum instead of a chain.

Method ``emulator`` fits a surrogate (Gaussian process or RBF) of the statistics' mean and variance to an
existing sweep's results (:mod:`~analysis.calibration.training`, :mod:`~analysis.calibration.surrogates`,
:mod:`~analysis.calibration.emulated`), samples the emulated posterior with
emcee (``chain.h5``, resumable) and writes the same posterior outputs; the posterior predictive check
uses REAL simulations at posterior draws. With ``confirm = C`` it then runs C real replicates at the
posterior median: ``confirm.csv`` (emulated against real mean, z per statistic) and
``confirm_predictive.csv`` (targets against the real runs), summarised in ``convergence.json``. With
``refine = { rounds = R, runs_per_round = M }`` (:mod:`~analysis.calibration.refine`) each round's chain
goes to ``rounds/chain_round<r>.h5`` (recomputed on every invocation: the sweep holds the state), new
sweep points are added until the confirmation passes, the final round's chain is copied to ``chain.h5``
and ``refine.csv`` lists the rounds. The refinement's sweep runs use the ``local`` executor when the
calibration runs ``serial`` (a sweep's runs are single-threaded).
"""
from __future__ import annotations

import functools
import hashlib
import json
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from flocksweep.analysis.reports.labels import parameter_label
from flocksweep.simcore import MODEL_VERSION
from flocksweep.simcore.schema import to_dict
from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.files import atomic_path, json_ready
from flocksweep.sweeps.progress import Phases, bar
from flocksweep.sweeps.seeds import Tag, generator
from flocksweep.sweeps.store import OutputFolder

from .accounting import Accounting
from .bsl import run_bsl, simulate_keyed
from .calibration_report import calibration_report, verdict_lines
from .chainfile import stored_steps
from .feasibility import check_chain_size, check_simulation_count
from .flock_check import flock_check, flock_columns
from .config import CalibrationConfig
from .diagnostics import (arviz_verdicts, convergence, default_burn, posterior_summary, predictive_check,
                          prior_constraint_warnings)
from .emulated import confirm, observation_covariance, posterior_median, run_emulator_mcmc
from .inference import (POSTERIOR_FILE, arviz_diagnostics, chain_inference_data, draws_inference_data,
                        load_calibration_results, optimum_inference_data, write_inference_data)
from .npe import run_npe
from .optimize import max_evaluations, run_optimize
from .plots import corner_figure, predictive_figure, rank_figure, sbc_figure, trace_figure
from .refine import P_LIMIT, Z_LIMIT, confirmation_passed, refine_emulator
from .simulator import SummarySimulator, summary_simulator
from .surrogates import build_surrogate, prior_outside_box
from .training import training_set
from .viewer_page import posterior_median_page, predictive_page

__all__ = ["CalibrationRun", "calibrate", "run_calibration", "load_calibration_results", "summary_simulator",
           "simulate_fn", "seeded_fn", "posterior_predictive", "SummarySimulator"]


@dataclass
class CalibrationRun:
    """What one calibration produced (see the module docstring); ``idata`` is also ``posterior.nc``."""

    out: Path
    idata: object                                  # arviz.InferenceData
    report: dict                                   # convergence.json (or optimum.json for optimize)
    summary: pd.DataFrame | None = None            # posterior.csv
    convergence: dict | None = None
    warnings: list | None = None
    predictive: pd.DataFrame | None = None         # predictive.csv
    flock: pd.DataFrame | None = None              # flock_check.csv: every flock statistic of the predictive runs
    confirm: dict | None = None                    # emulator: the confirmation at the posterior median
    refine: pd.DataFrame | None = None             # emulator: refine.csv
    optimum: dict | None = None                    # optimize: optimum.json
    paths: dict | None = None                      # the report's files

    def verdicts(self, config) -> list[str]:
        """The report's verdicts as plain sentences (what the command line prints)."""
        return verdict_lines(config, self)


def simulate_fn(config: CalibrationConfig, simulator: SummarySimulator):
    """theta, rng -> (n_sim, k) summaries, with the observation noise of mean/sd targets added."""
    cov = observation_covariance(config)

    def fn(theta, rng):
        sims = simulator(np.asarray(theta, dtype=float), rng)
        if cov is not None:   # the targets' noise, on the target columns (the first k; extra ones stay bare)
            sims = sims.copy()
            sims[:, :len(cov)] += rng.multivariate_normal(np.zeros(len(cov)), cov, size=len(sims))
        return sims
    return fn


def seeded_fn(config: CalibrationConfig, simulator: SummarySimulator):
    """theta, seeds -> (n_sim, k): a deterministic function of the seeds (observation noise included,
    drawn from a generator seeded by the same seeds), as common random numbers need."""
    cov = observation_covariance(config)

    def fn(theta, seeds):
        sims = simulator.simulate(np.asarray(theta, dtype=float), seeds)
        if cov is not None:
            rng = generator(*seeds)
            sims = sims + rng.multivariate_normal(np.zeros(len(cov)), cov, size=len(sims))
        return sims
    return fn


def _digest(data) -> str:
    return hashlib.sha256(json.dumps(json_ready(data), sort_keys=True).encode()).hexdigest()[:16]


def chain_meta(config: CalibrationConfig) -> dict:
    """What defines a BSL chain besides the driver's own settings, as HDF5 attributes (compared on resume)."""
    targets = config.targets
    m = config.metrics
    return {"chain_n_sim": int(config.method.n_sim),
            "chain_parameters": ", ".join(f"{p.name}={p.key}" for p in config.parameters),
            "chain_prior": repr(config.prior),
            "chain_metrics": f"warmup={m.warmup!r}, group_radius={m.group_radius!r}, "
                             f"fragmentation_cohesion={m.fragmentation_cohesion!r}",
            "chain_targets": _digest({"summary": targets.summary, "columns": list(targets.columns),
                                      "observed": targets.observed, "cov": targets.cov}),
            "chain_model": _digest({"preset": config.preset.to_dict(), "version": MODEL_VERSION})}


def resume_hint(config_path, out_dir) -> str:
    """One line on what an interrupted calibration saved and how to resume it."""
    chain = Path(out_dir) / "chain.h5"
    steps = stored_steps(chain)
    if not steps:
        return "no chain step was saved yet: run the same command again"
    return (f"saved: {steps} chain steps in {chain}; resume with: flocksweep calibrate {config_path} "
            f"--out {out_dir} --resume")


def calibrate(config: CalibrationConfig, out_dir=None, resume: bool = False, progress: bool = True,
              predictive_draws: int = 100, executor: str = "serial", workers: int | None = None,
              scheduler: str | None = None):
    """Run a calibration and return its posterior (``flocksweep calibrate``; docs/calibration.md).

    Parameters
    ----------
    config : CalibrationConfig
        The calibration, e.g. ``Calibration.from_toml(path, ["method.steps=500"])``.
    out_dir : str or pathlib.Path, optional
        Where its outputs go (default ``results/calibration/<name>``): posterior.nc, posterior.csv,
        convergence.json, figures, report.html.
    resume : bool, default False
        Continue the stored chain up to ``method.steps`` (an existing chain without it is an error).
    progress : bool, default True
        Show a progress bar.
    predictive_draws : int, default 100
        Posterior draws simulated for the posterior predictive check.
    executor : {"serial", "local", "dask"}, default "serial"
        Where the simulations run (:class:`sweeps.executors.Executor`); results do not depend on it.
    workers : int, optional
        Worker processes for ``local``/``dask``.
    scheduler : str, optional
        Dask scheduler address.

    Returns
    -------
    arviz.InferenceData
        As written to ``posterior.nc``: ``posterior`` (one variable per free parameter, walkers as
        chains), ``sample_stats``, ``posterior_predictive``, ``observed_data``, ``prior``. Everything
        else the run produced: :func:`run_calibration`.
    """
    return run_calibration(config, out_dir, resume, progress, predictive_draws, executor, workers, scheduler).idata


def run_calibration(config: CalibrationConfig, out_dir=None, resume: bool = False, progress: bool = True,
                    predictive_draws: int = 100, executor: str = "serial", workers: int | None = None,
                    scheduler: str | None = None, yes: bool = False) -> CalibrationRun:
    """Run ``config``'s method and write its outputs; the :class:`CalibrationRun` (see the module docstring).
    A chain too large to hold is refused, one of more than ``MAX_SIMULATIONS`` simulations needs ``yes``
    (:func:`~analysis.calibration.feasibility.check_chain_size`), before anything is written."""
    settings = config.method
    if settings.kind == "npe":
        check_simulation_count("method.npe.simulations", settings.simulations * settings.rounds + settings.heldout, yes)
    elif settings.kind in ("emcee", "emulator"):     # the methods that run a chain (optimize does not)
        dim = len(config.names)
        check_chain_size(settings.walkers or max(16, 2 * dim), settings.steps,
                         settings.n_sim if settings.kind == "emcee" else 0, dim, yes)
    default = Path("results") / "calibration" / (config.folder_name or config.name)
    folder = OutputFolder(Path(out_dir) if out_dir else default)
    # the same command, run again after any interrupt, continues the stored chain (checked to have
    # been made with the same settings, else ChainMismatch)
    resume = resume or (config.method.kind not in ("optimize", "npe") and folder.path("chain.h5").exists())
    phases = Phases("calibrate", _phase_count(config), progress)
    with Executor(executor, workers, scheduler) as pool, folder.lock():   # a scheduler is reached before any write
        if config.method.kind == "optimize":
            outcome = _optimize(config, folder, pool, phases)
        elif config.method.kind == "npe":
            outcome = _npe(config, folder, phases, predictive_draws, pool, (executor, workers, scheduler))
        elif config.method.kind == "emulator":
            outcome = _emulator(config, folder, resume, phases, predictive_draws, pool,
                                (executor, workers, scheduler))
        else:
            outcome = _emcee(config, folder, resume, phases, predictive_draws, pool)
        phases.start("the report (figures and tables)")
        outcome.paths = calibration_report(config, outcome, folder)
    phases.done(f": {folder.root}")
    return outcome


def _phase_count(config: CalibrationConfig) -> int:
    """The phases of a calibration's progress lines (the last is the report)."""
    settings = config.method
    if settings.kind == "optimize":
        return 3                                   # search, re-check, report
    if settings.kind == "npe":
        return 2 * settings.rounds + 3             # per round sweep and flow; coverage, predictive, report
    if settings.kind == "emulator":                # (fit and chain) or refinement rounds, predictive, confirm, report
        return (1 if settings.refine.rounds else 2) + 1 + bool(settings.confirm and not settings.refine.rounds) + 1
    return 3                                       # chain, predictive, report


def _optimize(config: CalibrationConfig, folder: OutputFolder, pool: Executor, phases: Phases) -> CalibrationRun:
    started = time.time()
    cost = Accounting()
    settings = config.method
    most = max_evaluations(settings.algorithm, settings.maxiter, settings.popsize, config.dim)
    count = f"up to {most:,} evaluations" if most else f"evaluations (at most {settings.maxiter} iterations)"
    phases.start(f"searching ({settings.algorithm}): {count} of {settings.n_sim} simulations each, then a "
                 f"re-check with {settings.recheck} fresh ones")
    with bar(most, f"{config.name}: search", "evaluation", phases.enabled) as search:
        result = run_optimize(seeded_fn(config, summary_simulator(config)), config.targets.observed, config.prior,
                              seed=config.seed, n_sim=settings.n_sim, algorithm=settings.algorithm,
                              maxiter=settings.maxiter, popsize=settings.popsize, recheck=settings.recheck,
                              likelihood=settings.likelihood, objective=settings.objective, executor=pool,
                              tick=search.update)
    phases.start(f"re-checked the optimum with {result.recheck_simulations} fresh simulations; writing the "
                 "predictive check")
    check = predictive_check(config.targets.observed, result.recheck_summaries, config.targets.columns)
    folder.write_csv("predictive.csv", check)
    predictive_figure(check, result.recheck_summaries, config.targets.observed, config.targets.columns,
                      folder.path("predictive.png"))
    optimum = {"name": config.name, "method": "optimize", "settings": to_dict(settings), "seed": config.seed,
               "theta": dict(zip(config.names, map(float, result.theta))),
               "objective_common_seeds": float(result.objective_crn),
               "objective_recheck": float(result.objective_recheck), "recheck_se": float(result.recheck_se),
               "optimizer_evaluations": int(result.nfev), "success": bool(result.success),
               "message": str(result.message), "wall_s": time.time() - started, "executor": pool.description,
               **folder.provenance()}
    cost.add("search", result.search_simulations, result.search_evaluations)
    cost.add("recheck", result.recheck_simulations, len(result.recheck_batches))
    optimum["accounting"] = cost.block(optimizer_evaluations=int(result.nfev))
    folder.write_json("optimum.json", optimum)
    idata = optimum_inference_data(config, result.theta, result.recheck_summaries)
    write_inference_data(idata, folder.path(POSTERIOR_FILE))
    return CalibrationRun(out=folder.root, idata=idata, report=json_ready(optimum), predictive=check,
                          optimum=json_ready(optimum), warnings=[])


def _posterior_draws(chain: np.ndarray, burn: int, count: int, rng: np.random.Generator):
    """(draws (P, d), their (walker, step) (P, 2)) picked without replacement after the burn-in."""
    flat = chain[burn:].reshape(-1, chain.shape[-1])
    picked = rng.choice(len(flat), size=min(count, len(flat)), replace=False)
    walkers = chain.shape[1]
    return flat[picked], np.column_stack([picked % walkers, burn + picked // walkers])


def predictive_runs(config: CalibrationConfig, draws: np.ndarray, pool: Executor | None = None, tick=None):
    """((P, k), (P, f)): one simulated run per posterior draw, its target statistics (observation noise
    included) and its flock statistics (:func:`~analysis.calibration.flock_check.flock_columns`, bare);
    draw i uses the seed key (config.seed, Tag.PREDICTIVE, i); ``tick()`` after each (a progress bar's
    ``update``)."""
    simulator = summary_simulator(config, n_sim=1, extra_columns=flock_columns(config))
    fn = functools.partial(simulate_keyed, simulate_fn(config, simulator))
    tasks = [(theta, (config.seed, Tag.PREDICTIVE, i)) for i, theta in enumerate(draws)]
    rows = np.vstack((pool or Executor("serial")).map(fn, tasks, tick))
    k = len(config.targets.columns)
    return rows[:, :k], rows[:, k:]


def posterior_predictive(config: CalibrationConfig, draws: np.ndarray, pool: Executor | None = None,
                         tick=None) -> np.ndarray:
    """(P, k): the target statistics of :func:`predictive_runs`."""
    return predictive_runs(config, draws, pool, tick)[0]


def _predictive(config: CalibrationConfig, draws: np.ndarray, pool: Executor, phases: Phases):
    """The posterior predictive runs (:func:`predictive_runs`) as a phase of ``phases``, with a bar of
    simulations."""
    phases.start(f"the posterior predictive check: {len(draws)} simulations at posterior draws")
    with bar(len(draws), f"{config.name}: predictive", "sim", phases.enabled) as shown:
        return predictive_runs(config, draws, pool, shown.update)


def _emcee(config: CalibrationConfig, folder: OutputFolder, resume: bool, phases: Phases, predictive_draws: int,
           pool: Executor) -> CalibrationRun:
    settings = config.method
    started = time.time()
    cost = Accounting()
    resumed_from = stored_steps(folder.path("chain.h5")) if resume else 0
    phases.start(f"the chain: {settings.walkers} walkers x {settings.steps} steps, {settings.n_sim} simulations "
                 f"per evaluation" + (f" (resuming after step {resumed_from})" if resumed_from else ""))
    with _ProgressBar(settings.steps, config.name, phases.enabled) as bar:
        result = run_bsl(simulate_fn(config, summary_simulator(config)), config.targets.observed, config.prior,
                         walkers=settings.walkers, steps=settings.steps, seed=config.seed,
                         path=folder.path("chain.h5"), resume=resume, likelihood=settings.likelihood,
                         reevaluate_every=settings.reevaluate_every, moves=settings.moves, progress=bar.callback,
                         executor=pool, meta=chain_meta(config), until_converged=settings.until_converged,
                         check_every=settings.check_every, count=cost.add)
    return write_posterior(config, result, folder, pool, predictive_draws, started,
                           extra={"executor": pool.description}, cost=cost,
                           cost_extra={"resumed_from": resumed_from} if resumed_from else {}, phases=phases)


def _npe(config: CalibrationConfig, folder: OutputFolder, phases: Phases, predictive_draws: int, pool: Executor,
         sweep_executor: tuple) -> CalibrationRun:
    """Neural posterior estimation (analysis.calibration.npe): the training sweep runs on the sweep
    machinery (``local`` when the calibration runs ``serial``), the coverage check gates the verdict."""
    started = time.time()
    cost = Accounting()
    executor, workers, scheduler = sweep_executor
    result = run_npe(config, folder, "local" if executor == "serial" else executor, workers, scheduler, phases,
                     cost)
    draws, check = result.draws, result.coverage
    chains = 4
    summary = posterior_summary(draws[:len(draws) // chains * chains].reshape(-1, chains, config.dim), config.names,
                                np.full(chains, np.nan), burn=0)
    picked = generator(config.seed, Tag.PREDICTIVE).choice(len(draws), size=min(predictive_draws, len(draws)),
                                                           replace=False)
    predictive, flock = _predictive(config, draws[picked], pool, phases)
    cost.add("predictive", len(predictive))
    predictive_table = predictive_check(config.targets.observed, predictive, config.targets.columns)
    flock_table = flock_check(config, predictive, flock)
    idata = draws_inference_data(config, draws, chains=chains, predictive=predictive)
    write_inference_data(idata, folder.path(POSTERIOR_FILE))
    summary = summary.drop(columns=["tau", "ess", "acceptance"]).join(arviz_diagnostics(idata))
    folder.write_csv("posterior.csv", summary)
    folder.write_csv("predictive.csv", predictive_table)
    folder.write_csv("flock_check.csv", flock_table)
    folder.write_csv("coverage.csv", check["table"], index=False)
    rank_figure(idata, folder.path("rank.png"))
    sbc_figure(check["ranks"], check["draws"], 20, config.names, folder.path("coverage_ranks.png"))
    truth = config.targets.truth
    corner_figure(draws, config.names, folder.path("corner.png"),
                  truths=[truth[n] for n in config.names] if truth else None,
                  labels=[f"{name}: {parameter_label(key)}" for name, key in zip(config.names, config.keys)])
    predictive_figure(predictive_table, predictive, config.targets.observed, config.targets.columns,
                      folder.path("predictive.png"))
    posterior_median_page(config, summary, folder.root)
    _, page_warnings = predictive_page(config, summary, draws[picked], predictive, flock, folder.root)
    warnings = prior_constraint_warnings(summary, config.prior) + page_warnings
    if result.info["leakage"] > 0.1:
        warnings.append(f"{result.info['leakage']:.0%} of the estimator's draws at the targets fell outside the prior "
                        "(redrawn): the targets may lie outside what the simulations cover")
    verdict = {"converged": check["passed"], "coverage_ok": check["passed"], "messages": check["messages"]}
    report = json_ready({"name": config.name, "method": "npe", "settings": to_dict(config.method), "seed": config.seed,
                         "convergence": verdict, "warnings": warnings, "npe": result.info, "draws": len(draws),
                         "executor": pool.description, "wall_s": time.time() - started,
                         "accounting": cost.block(training_runs_reused=result.info["training_simulations"]
                                                  + config.method.heldout - cost.simulations["training"]
                                                  - cost.simulations["heldout"]),
                         **folder.provenance()})
    folder.write_json("convergence.json", report)
    return CalibrationRun(out=folder.root, idata=idata, report=report, summary=summary, convergence=verdict,
                          warnings=warnings, predictive=predictive_table, flock=flock_table)


def _emulator_mcmc(config: CalibrationConfig, surrogate, path, resume: bool, progress: bool, label: str):
    settings = config.method
    with _ProgressBar(settings.steps, label, progress) as bar:
        return run_emulator_mcmc(surrogate, config.targets.observed, observation_covariance(config), config.prior,
                                 walkers=settings.walkers, steps=settings.steps, seed=config.seed, path=path,
                                 resume=resume, progress=bar.callback, moves=settings.moves)


def _emulator_info(config: CalibrationConfig, training, fit_s: float) -> dict:
    return {"training_points": int(len(training.points)), "training_runs": int(training.count.sum()),
            "training_box": {n: [float(lo), float(hi)] for n, lo, hi in
                             zip(config.names, training.lower, training.upper)},
            "fixed_factors": training.fixed, "notes": list(training.notes), "fit_s": fit_s,
            "results": str(config.method.results)}


def _refined_rounds(config: CalibrationConfig, folder: OutputFolder, progress: bool, sweep_executor: tuple):
    """The refinement's rounds (analysis.calibration.refine), each chain in rounds/chain_round<r>.h5; the
    last one copied to chain.h5."""
    fits = {}

    def fit_round(r: int):
        started = time.time()
        training = training_set(config.method.results, config)
        surrogate = build_surrogate(training, config.method.surrogate)
        fits[r] = time.time() - started
        path = folder.path("rounds") / f"chain_round{r}.h5"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.unlink(missing_ok=True)   # recomputed from the sweep as it is now: the sweep holds the state
        result = _emulator_mcmc(config, surrogate, path, False, progress, f"{config.name} (emulator, round {r})")
        return training, surrogate, result, default_burn(result.chain)

    executor, workers, scheduler = sweep_executor
    log = (lambda message: tqdm.write(message, file=sys.stderr)) if progress else (lambda message: None)
    refinement = refine_emulator(config, fit_round, pool_kind="local" if executor == "serial" else executor,
                                 workers=workers, scheduler=scheduler, progress=progress, log=log)
    last = len(refinement.rounds) - 1
    with atomic_path(folder.path("chain.h5")) as tmp:
        shutil.copyfile(folder.path("rounds") / f"chain_round{last}.h5", tmp)
    refinement.result.path = str(folder.path("chain.h5"))
    return refinement, fits[last]


def _emulator(config: CalibrationConfig, folder: OutputFolder, resume: bool, phases: Phases,
              predictive_draws: int, pool: Executor, sweep_executor: tuple) -> CalibrationRun:
    settings = config.method
    started = time.time()
    cost = Accounting()
    progress = phases.enabled
    if settings.refine.rounds:
        phases.start(f"refinement: up to {settings.refine.rounds} rounds of fit, chain and confirmation")
        refinement, fit_s = _refined_rounds(config, folder, progress, sweep_executor)
        training, surrogate, result, check = (refinement.training, refinement.surrogate, refinement.result,
                                              refinement.confirm)
        folder.write_csv("refine.csv", refinement.rounds, index=False)
    else:
        refinement = None
        phases.start(f"fitting the emulator ({settings.surrogate}) on the sweep in {settings.results}")
        training = training_set(settings.results, config)
        surrogate = build_surrogate(training, settings.surrogate)
        fit_s = time.time() - started
        phases.start(f"the chain on the emulator: {settings.walkers} walkers x {settings.steps} steps")
        result = _emulator_mcmc(config, surrogate, folder.path("chain.h5"), resume, progress,
                                f"{config.name} (emulator)")
    outcome = write_posterior(config, result, folder, pool, predictive_draws, started,
                              extra={"executor": pool.description, "emulator": _emulator_info(config, training, fit_s)},
                              warnings=prior_outside_box(config.prior, surrogate), cost=cost, phases=phases)
    if settings.confirm and refinement is None:
        phases.start(f"confirming at the posterior median: {settings.confirm} real simulations")
        theta = posterior_median(result.chain, outcome.report["burn"])
        check = confirm(config, summary_simulator(config), surrogate, theta, count=settings.confirm, seed=config.seed)
        cost.add("confirmation", len(check["summaries"]))
    if settings.confirm:
        _write_confirmation(folder, outcome, check, settings.confirm)
    if refinement is not None:
        rounds = refinement.rounds
        outcome.refine = rounds
        outcome.report["refine"] = {"rounds_run": int(len(rounds)), "rounds_allowed": settings.refine.rounds,
                                    "runs_per_round": settings.refine.runs_per_round,
                                    "runs_added": int(rounds["runs_added"].sum()),
                                    "passed": bool(rounds["passed"].iloc[-1]), "results": str(settings.results)}
        cost.add("confirmation", int(rounds["confirm_runs"].sum()))
        cost.add("refinement", int(rounds["runs_added"].sum()))
    outcome.report["accounting"] = json_ready(cost.block(
        training_runs_reused=int(training.count.sum()) - cost.simulations["refinement"]))
    outcome.report["wall_s"] = time.time() - started
    folder.write_json("convergence.json", outcome.report)
    return outcome


def _write_confirmation(folder: OutputFolder, outcome: CalibrationRun, check: dict, count: int) -> None:
    folder.write_csv("confirm.csv", check["comparison"])
    folder.write_csv("confirm_predictive.csv", check["predictive"])
    outcome.confirm = check
    outcome.report["confirm"] = {"theta": check["theta"], "count": count,
                                 "max_abs_z": float(np.nanmax(np.abs(check["comparison"]["z"]))),
                                 "passed": confirmation_passed(check), "messages": confirm_messages(check)}


def confirm_messages(check: dict, z_limit: float = Z_LIMIT, p_limit: float = P_LIMIT) -> list[str]:
    """Plain sentences on the real simulations at the posterior median."""
    messages = []
    for stat, row in check["comparison"].iterrows():
        if abs(row["z"]) > z_limit:
            messages.append(f"{stat}: the real mean {row['real_mean']:.4g} differs from the emulator's "
                            f"{row['emulated_mean']:.4g} by {row['z']:.1f} standard errors: the surrogate is "
                            f"inaccurate here; refine the sweep near the posterior")
    for stat, row in check["predictive"].iterrows():
        if row["p"] < p_limit:
            messages.append(f"{stat}: the target lies in the tail of real simulations at the posterior median "
                            f"(p = {row['p']:.3g})")
    if not messages:
        messages.append(f"confirmed: real simulations at the posterior median agree with the emulator "
                        f"(|z| <= {z_limit:g}) and with the targets (p >= {p_limit:g})")
    return messages


def write_posterior(config: CalibrationConfig, result, folder: OutputFolder, pool: Executor | None,
                    predictive_draws: int, started: float, extra: dict | None = None,
                    warnings: list | None = None, cost: Accounting | None = None,
                    cost_extra: dict | None = None, phases: Phases | None = None) -> CalibrationRun:
    """From a chain (a ChainResult) to posterior.nc, posterior.csv, convergence.json, predictive.csv and
    the figures (``phases``: the calibration's progress lines, the predictive check one of them)."""
    summary = posterior_summary(result.chain, config.names, result.acceptance_fraction)
    burn = int(summary.attrs.get("burn", 0))
    verdict = convergence(result.chain, result.acceptance_fraction, burn=burn,
                          moves=getattr(config.method, "moves", "stretch"))
    warnings = list(warnings or []) + prior_constraint_warnings(summary, config.prior)
    draws, source = _posterior_draws(result.chain, burn, predictive_draws, generator(config.seed, Tag.PREDICTIVE))
    predictive, flock = _predictive(config, draws, pool, phases or Phases("calibrate", 1, False))
    if cost is not None:
        cost.add("predictive", len(predictive))
    check = predictive_check(config.targets.observed, predictive, config.targets.columns)
    flock_table = flock_check(config, predictive, flock)
    idata = chain_inference_data(config, result, burn, predictive=predictive, predictive_source=source)
    write_inference_data(idata, folder.path(POSTERIOR_FILE))
    diagnostics = arviz_diagnostics(idata)
    summary = summary.join(diagnostics)
    ensemble = arviz_verdicts(diagnostics)
    verdict = {**verdict, **{k: v for k, v in ensemble.items() if k != "messages"},
               "converged": bool(verdict["converged"] and ensemble["rhat_ok"] and ensemble["ess_ok"]),
               "messages": verdict["messages"] + ensemble["messages"]}
    folder.write_csv("posterior.csv", summary)
    folder.write_csv("predictive.csv", check)
    folder.write_csv("flock_check.csv", flock_table)
    trace_figure(result.chain, config.names, folder.path("trace.png"), burn=burn)
    rank_figure(idata, folder.path("rank.png"))
    truth = config.targets.truth
    corner_figure(result.chain[burn:].reshape(-1, config.dim), config.names, folder.path("corner.png"),
                  truths=[truth[n] for n in config.names] if truth else None,
                  labels=[f"{name}: {parameter_label(key)}" for name, key in zip(config.names, config.keys)])
    predictive_figure(check, predictive, config.targets.observed, config.targets.columns,
                      folder.path("predictive.png"))
    posterior_median_page(config, summary, folder.root)  # viewer page of a run at the posterior median
    warnings += predictive_page(config, summary, draws, predictive, flock, folder.root)[1]   # tracks beside a run
    report = json_ready({"name": config.name, "method": config.method.kind, "settings": to_dict(config.method),
                         "seed": config.seed, "convergence": verdict, "warnings": warnings,
                         "wall_s": time.time() - started, "steps": int(result.chain.shape[0]),
                         "walkers": int(result.chain.shape[1]), "burn": burn, **(extra or {}),
                         **({"accounting": cost.block(**(cost_extra or {}))} if cost is not None else {}),
                         **folder.provenance()})
    folder.write_json("convergence.json", report)
    return CalibrationRun(out=folder.root, idata=idata, report=report, summary=summary, convergence=verdict,
                          warnings=warnings, predictive=check, flock=flock_table)


class _ProgressBar:
    """tqdm of MCMC steps with the acceptance and tau estimate; does nothing when disabled."""

    def __init__(self, total: int, name: str, enabled: bool):
        self.bar = tqdm(total=total, desc=name, unit="step", mininterval=0.5) if enabled else None
        self.done = 0

    @property
    def callback(self):
        """The progress callback for the MCMC driver, or None when disabled (no tau is computed then)."""
        return self.update if self.bar is not None else None

    def update(self, step, acceptance, tau):
        self.bar.update(step - self.done)
        self.done = step
        self.bar.set_postfix(acceptance=f"{acceptance:.2f}", tau=f"{tau:.1f}", refresh=False)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
