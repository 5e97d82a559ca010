"""``flocksweep calibrate``: from a calibration TOML to a posterior with its diagnostics, on disk.

``calibrate(config, out_dir, resume=False, progress=True, executor="serial", workers=None,
scheduler=None) -> dict`` runs the configured method and writes into ``out_dir`` (default
``results/calibration/<name>/``), an :class:`sweeps.store.OutputFolder`: locked while it runs (a
second calibration writing there gets ``StoreLocked``), every file written atomically, the provenance
stamp in ``convergence.json`` / ``optimum.json``. Simulations run on a :class:`sweeps.executors.Executor`
(``serial``: this process, each evaluation's replicates in one threaded compiled call; ``local``: a
process pool evaluating proposals in parallel; ``dask``); the results do not depend on it.

* ``chain.h5``: the emcee chain (HDF5 backend; ``resume`` continues it exactly);
* ``posterior.csv``: mean, sd, median, 95% and 90% intervals, integrated autocorrelation time, effective
  sample size and acceptance per parameter;
* ``convergence.json``: plain verdicts (chain length >= 50 tau, acceptance in [0.2, 0.5]), the
  warnings for parameters the targets do not constrain, and the provenance stamp;
* ``predictive.csv``: the posterior predictive check (each target against its distribution under
  posterior draws, with its two-sided tail probability);
* ``trace.png``, ``corner.png``, ``predictive.png``;
* ``viewer_posterior_median.html``: an interactive 3-D page of one run at the posterior median.

The simulator runs ``n_sim`` replicates per evaluation in one batched compiled call, with fresh seeds
at every evaluation. When the targets are given as mean and sd (or a covariance), that observation
uncertainty is added to every simulated summary as Gaussian noise drawn from the same evaluation's
generator, so the fitted Gaussian's covariance is the simulator's plus the observation's. Targets
given as samples (a CSV of observed datasets) are used as they are.

Method ``optimize`` (``scipy.optimize``, common random numbers during the search, the optimum
re-checked with fresh seeds) writes ``optimum.json`` (theta, objective with the common seeds and
re-checked, its standard error, evaluations) and ``predictive.csv``/``.png`` at the optimum instead of
a chain.

Method ``emulator`` fits a surrogate (Gaussian process or RBF) of the statistics' mean and variance to an
existing sweep's results (:mod:`~analysis.calibration.training`, :mod:`~analysis.calibration.surrogates`,
:mod:`~analysis.calibration.emulated`), samples the emulated posterior with
emcee (``chain.h5``, resumable) and writes the same posterior outputs; the posterior predictive check
uses REAL simulations at posterior draws. With ``confirm = C`` it then runs C real replicates at the
posterior median: ``confirm.csv`` (emulated against real mean, z per statistic) and
``confirm_predictive.csv`` (targets against the real runs), summarised in ``convergence.json``.
"""
from __future__ import annotations

import functools
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from simcore.schema import ConfigError, to_dict
from sweeps.executors import Executor
from sweeps.files import json_ready
from sweeps.seeds import Tag, generator
from sweeps.store import OutputFolder

from .bsl import run_bsl, simulate_keyed
from .config import CalibrationConfig
from .diagnostics import convergence, posterior_summary, predictive_check, prior_constraint_warnings
from .emulated import confirm, observation_covariance, posterior_median, run_emulator_mcmc
from .optimize import run_optimize
from .plots import corner_figure, predictive_figure, trace_figure
from .simulator import SummarySimulator
from .surrogates import build_surrogate, prior_outside_box
from .training import training_set
from .viewer_page import posterior_median_page


def summary_simulator(config: CalibrationConfig, n_sim: int | None = None) -> SummarySimulator:
    n_sim = config.method.n_sim if n_sim is None else n_sim
    m = config.metrics
    return SummarySimulator(config.preset_data, config.keys, config.targets.columns, n_sim, m.warmup,
                            m.group_radius, m.fragmentation_cohesion, config.observation)


def simulate_fn(config: CalibrationConfig, simulator: SummarySimulator):
    """theta, rng -> (n_sim, k) summaries, with the observation noise of mean/sd targets added."""
    cov = observation_covariance(config)

    def fn(theta, rng):
        sims = simulator(np.asarray(theta, dtype=float), rng)
        if cov is not None:
            sims = sims + rng.multivariate_normal(np.zeros(len(cov)), cov, size=len(sims))
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


def calibrate(config: CalibrationConfig, out_dir=None, resume: bool = False, progress: bool = True,
              predictive_draws: int = 100, executor: str = "serial", workers: int | None = None,
              scheduler: str | None = None) -> dict:
    """Run ``config``'s method, write its outputs into ``out_dir``; see the module docstring."""
    folder = OutputFolder(Path(out_dir) if out_dir else Path("results") / "calibration" / config.name)
    chain_path = folder.path("chain.h5")
    if config.method.kind != "optimize" and chain_path.exists() and not resume:
        raise ConfigError("--resume", f"{chain_path} exists: pass --resume to continue it, or remove it")
    with folder.lock(), Executor(executor, workers, scheduler) as pool:
        if config.method.kind == "optimize":
            return _optimize(config, folder, pool)
        if config.method.kind == "emulator":
            return _emulator(config, folder, resume, progress, predictive_draws, pool)
        return _emcee(config, folder, resume, progress, predictive_draws, pool)


def _optimize(config: CalibrationConfig, folder: OutputFolder, pool: Executor) -> dict:
    started = time.time()
    settings = config.method
    result = run_optimize(seeded_fn(config, summary_simulator(config)), config.targets.observed, config.prior,
                          seed=config.seed, n_sim=settings.n_sim, algorithm=settings.algorithm,
                          maxiter=settings.maxiter, popsize=settings.popsize, recheck=settings.recheck,
                          likelihood=settings.likelihood, objective=settings.objective, executor=pool)
    check = predictive_check(config.targets.observed, result.recheck_summaries, config.targets.columns)
    folder.write_csv("predictive.csv", check)
    predictive_figure(check, result.recheck_summaries, config.targets.observed, config.targets.columns,
                      folder.path("predictive.png"))
    optimum = {"name": config.name, "method": "optimize", "settings": to_dict(settings), "seed": config.seed,
               "theta": dict(zip(config.names, map(float, result.theta))),
               "objective_common_seeds": float(result.objective_crn),
               "objective_recheck": float(result.objective_recheck), "recheck_se": float(result.recheck_se),
               "evaluations": int(result.nfev), "success": bool(result.success), "message": str(result.message),
               "wall_s": time.time() - started, "executor": pool.description, **folder.provenance()}
    folder.write_json("optimum.json", optimum)
    return {"out": folder.root, "optimum": json_ready(optimum), "predictive": check}


def _posterior_draws(chain: np.ndarray, burn: int, count: int, rng: np.random.Generator) -> np.ndarray:
    flat = chain[burn:].reshape(-1, chain.shape[-1])
    return flat[rng.choice(len(flat), size=min(count, len(flat)), replace=False)]


def posterior_predictive(config: CalibrationConfig, draws: np.ndarray, pool: Executor | None = None) -> np.ndarray:
    """(P, k): one simulated dataset (observation noise included) per posterior draw; draw i uses the
    seed key (config.seed, Tag.PREDICTIVE, i)."""
    fn = functools.partial(simulate_keyed, simulate_fn(config, summary_simulator(config, n_sim=1)))
    tasks = [(theta, (config.seed, Tag.PREDICTIVE, i)) for i, theta in enumerate(draws)]
    return np.vstack(pool.map(fn, tasks) if pool is not None else [fn(task) for task in tasks])


def _emcee(config: CalibrationConfig, folder: OutputFolder, resume: bool, progress: bool, predictive_draws: int,
           pool: Executor) -> dict:
    settings = config.method
    started = time.time()
    with _ProgressBar(settings.steps, config.name, progress) as bar:
        result = run_bsl(simulate_fn(config, summary_simulator(config)), config.targets.observed, config.prior,
                         walkers=settings.walkers, steps=settings.steps, seed=config.seed,
                         path=folder.path("chain.h5"), resume=resume, likelihood=settings.likelihood,
                         reevaluate_every=settings.reevaluate_every, moves=settings.moves, progress=bar.callback,
                         executor=pool)
    return write_posterior(config, result, folder, pool, predictive_draws, started,
                           extra={"executor": pool.description})


def _emulator(config: CalibrationConfig, folder: OutputFolder, resume: bool, progress: bool,
              predictive_draws: int, pool: Executor) -> dict:
    settings = config.method
    started = time.time()
    training = training_set(settings.results, config)
    surrogate = build_surrogate(training, settings.surrogate)
    fitted = time.time()
    with _ProgressBar(settings.steps, f"{config.name} (emulator)", progress) as bar:
        result = run_emulator_mcmc(surrogate, config.targets.observed, observation_covariance(config), config.prior,
                                   walkers=settings.walkers, steps=settings.steps, seed=config.seed,
                                   path=folder.path("chain.h5"), resume=resume, progress=bar.callback,
                                   moves=settings.moves)
    emulator_info = {"training_points": int(len(training.points)), "training_runs": int(training.count.sum()),
                     "training_box": {n: [float(lo), float(hi)] for n, lo, hi in
                                      zip(config.names, training.lower, training.upper)},
                     "fixed_factors": training.fixed, "notes": list(training.notes),
                     "fit_s": fitted - started, "results": str(settings.results)}
    posterior = write_posterior(config, result, folder, pool, predictive_draws, started,
                                extra={"executor": pool.description, "emulator": emulator_info},
                                warnings=prior_outside_box(config.prior, surrogate))
    if settings.confirm:
        theta = posterior_median(result.chain, posterior["report"]["burn"])
        check = confirm(config, summary_simulator(config), surrogate, theta, count=settings.confirm,
                        seed=config.seed)
        folder.write_csv("confirm.csv", check["comparison"])
        folder.write_csv("confirm_predictive.csv", check["predictive"])
        posterior["confirm"] = check
        posterior["report"]["confirm"] = {"theta": check["theta"], "count": settings.confirm,
                                          "max_abs_z": float(np.nanmax(np.abs(check["comparison"]["z"]))),
                                          "messages": confirm_messages(check)}
        posterior["report"]["wall_s"] = time.time() - started
        folder.write_json("convergence.json", posterior["report"])
    return posterior


def confirm_messages(check: dict, z_limit: float = 3.0, p_limit: float = 0.01) -> list[str]:
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
                    warnings: list | None = None) -> dict:
    """From a chain (a ChainResult) to posterior.csv, convergence.json, predictive.csv and the figures."""
    summary = posterior_summary(result.chain, config.names, result.acceptance_fraction)
    burn = int(summary.attrs.get("burn", 0))
    verdict = convergence(result.chain, result.acceptance_fraction, burn=burn)
    warnings = list(warnings or []) + prior_constraint_warnings(summary, config.prior)
    draws = _posterior_draws(result.chain, burn, predictive_draws, generator(config.seed, Tag.PREDICTIVE))
    predictive = posterior_predictive(config, draws, pool)
    check = predictive_check(config.targets.observed, predictive, config.targets.columns)
    folder.write_csv("posterior.csv", summary)
    folder.write_csv("predictive.csv", check)
    trace_figure(result.chain, config.names, folder.path("trace.png"), burn=burn)
    corner_figure(result.chain[burn:].reshape(-1, config.dim), config.names, folder.path("corner.png"))
    predictive_figure(check, predictive, config.targets.observed, config.targets.columns,
                      folder.path("predictive.png"))
    posterior_median_page(config, summary, folder.root)  # viewer page of a run at the posterior median
    report = json_ready({"name": config.name, "method": config.method.kind, "settings": to_dict(config.method),
                         "seed": config.seed, "convergence": verdict, "warnings": warnings,
                         "wall_s": time.time() - started, "steps": int(result.chain.shape[0]),
                         "walkers": int(result.chain.shape[1]), "burn": burn, **(extra or {}),
                         **folder.provenance()})
    folder.write_json("convergence.json", report)
    return {"out": folder.root, "summary": summary, "convergence": verdict, "warnings": warnings,
            "predictive": check, "report": report}


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
