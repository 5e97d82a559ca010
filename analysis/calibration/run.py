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

The driver names no method: it runs ``method_of(config.method.kind)`` (:mod:`analysis.calibration.methods`:
its cost check, its ``run`` on a :class:`~analysis.calibration.methods.base.Job`, its report section), then
completes the method's report with the accounting and the wall time and writes it (``convergence.json``,
or the method's ``report_file``), then the report. ``output_folder(config, out_dir)`` is where it writes;
``resume_hint(command, out_dir, config)`` the method's line on how an interrupted run goes on. The
calibration's data model (``simulate_fn``, ``seeded_fn``, ``predictive_runs``) lives in
:mod:`~analysis.calibration.data_model` and is re-exported here.

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
  that defines the chain (:func:`~analysis.calibration.methods.emcee.chain_meta`: seed, walkers, moves,
  likelihood, re-evaluation, n_sim, the statistics' transforms, the
  parameters and their priors, the targets, the model and the metric settings); ``resume`` with any of
  them changed is refused with the list of differences (``ChainMismatch``, a ConfigError at
  ``--resume``), never silently continued;
* ``posterior.csv``: mean, sd, median, 95% and 90% intervals, emcee's integrated autocorrelation time and
  effective sample size, acceptance, and ArviZ's R-hat, bulk and tail ESS and MCSE per parameter;
* ``convergence.json``: plain verdicts (chain length >= 50 tau, acceptance in [0.2, 0.5], R-hat <= 1.01,
  bulk and tail ESS >= 400), the warnings for parameters the targets do not constrain, the verdicts every
  fit gets (:mod:`~analysis.calibration.verdicts`: ``bounds``, ``group_structure``, and ``credible``,
  ``verdict``, ``reasons``: one line, credible or not and why), the statistics' ``transforms``, the
  ``accounting`` and the provenance stamp;
* ``accounting.json``: written before the method starts and as each phase starts (:class:`Checkpoints`):
  ``status`` (running, done, failed, interrupted), ``phase``, the accounting so far, and after a failure
  the ``error`` and how to go on. A method that can give no posterior raises
  :class:`~analysis.calibration.outcome.NoPosterior`: the report then holds its reason as the verdict;
* ``predictive.csv``: the posterior predictive check (each target against its distribution under
  posterior draws, with its two-sided tail probability);
* ``trace.png``, ``rank.png``, ``corner.png`` (the ``corner`` package: quantiles, contours, truth lines
  when ``targets.truth`` is given), ``predictive.png``;
* ``report.html`` / ``report.md``: the calibration report (:mod:`~analysis.calibration.calibration_report`);
* ``viewer_posterior_median.html``: an interactive 3-D page of one run at the posterior median;
* ``viewer_predictive.html`` (targets from tracks, every method): the measured flock and the predictive run
  nearest the posterior median, re-simulated and checked, as two runs of one page
  (:mod:`~analysis.calibration.viewer_page`).

A command model's calibration runs its simulations in worker processes (``serial`` becomes ``local``): the
command starts processes, which must not be forked beside JAX's threads.

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

import time
from pathlib import Path

from flocksweep.simcore.schema import to_dict
from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.files import json_ready
from flocksweep.sweeps.progress import Phases
from flocksweep.sweeps.store import OutputFolder

from .accounting import Accounting
from .calibration_report import calibration_report
from .config import CalibrationConfig
from .data_model import posterior_predictive, predictive_runs, seeded_fn, simulate_fn
from .inference import load_calibration_results
from .methods import Job, method_of
from .outcome import CalibrationRun, NoPosterior
from .verdicts import bound_verdicts, credibility, group_verdict
from .simulator import SummarySimulator, summary_simulator

ACCOUNTING_FILE = "accounting.json"

__all__ = ["CalibrationRun", "calibrate", "run_calibration", "load_calibration_results", "summary_simulator",
           "simulate_fn", "seeded_fn", "posterior_predictive", "predictive_runs", "SummarySimulator"]


def output_folder(config: CalibrationConfig, out_dir=None) -> Path:
    """Where a calibration's outputs go: ``out_dir``, else ``results/calibration/<folder name>``."""
    return Path(out_dir) if out_dir else Path("results") / "calibration" / (config.folder_name or config.name)


def resume_hint(config_path, out_dir, config: CalibrationConfig | None = None) -> str:
    """One line on what an interrupted calibration saved and how to go on (its method's words)."""
    kind = config.method.kind if config is not None else "emcee"
    return method_of(kind).resume_hint(str(config_path), out_dir)


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
    """Run ``config``'s method (:func:`analysis.calibration.methods.method_of`) and write its outputs; the
    :class:`CalibrationRun` (see the module docstring). A calibration too large to run is refused by its
    method (``check_cost``; ``yes`` goes ahead where it may) before anything is written."""
    method = method_of(config.method.kind)
    method.check_cost(config, yes)
    folder = OutputFolder(output_folder(config, out_dir))
    # the same command, run again after any interrupt, continues what the folder holds (a chain is checked
    # to have been made with the same settings, else ChainMismatch)
    resume = resume or method.continues(config, folder)
    if config.command is not None and executor == "serial":
        # an external command's runs start processes: from worker processes, never from this one once JAX
        # (npe) has started its threads here (a fork beside them can deadlock); the results are the same
        executor = "local"
    cost = Accounting()
    phases = Checkpoints(method.phase_count(config) + 1, progress, folder, cost, config)
    with Executor(executor, workers, scheduler) as pool, folder.lock():   # a scheduler is reached before any write
        job = Job(config=config, folder=folder, pool=pool, phases=phases, cost=cost, resume=resume,
                  predictive_draws=predictive_draws, executor=(executor, workers, scheduler), started=time.time(),
                  transforms_record=config.transforms.record() if method.uses_transforms else None)
        phases.job = job
        phases.save("running")          # the run's accounting exists before anything that can fail
        try:
            outcome = method.run(job)
        except NoPosterior as err:
            outcome = _no_posterior(job, err)
        except BaseException as err:
            phases.save("interrupted" if isinstance(err, KeyboardInterrupt) else "failed", err)
            raise
        outcome.report.update(fit_verdicts(config, outcome))
        if config.targets.tracks_record is not None:   # the tracks' units and scales, with their sources
            outcome.report["tracks"] = config.targets.tracks_record
        outcome.report["accounting"] = json_ready(job.cost.block(**job.cost_extra))
        outcome.report["wall_s"] = time.time() - job.started
        folder.write_json(method.report_file, outcome.report)
        phases.start("the report (figures and tables)")
        blocks = method.report_blocks(config, outcome, folder) if outcome.idata is not None else []
        outcome.paths = calibration_report(config, outcome, folder, blocks)
        phases.save("done")
    phases.done(f": {folder.root}")
    return outcome


def _no_posterior(job: Job, err: NoPosterior) -> CalibrationRun:
    """The outcome of a method that could give no posterior: its reason as the verdict."""
    config = job.config
    report = json_ready({"name": config.name, "method": config.method.kind, "settings": to_dict(config.method),
                         "seed": config.seed, "no_posterior": err.reason, **err.report,
                         "executor": job.pool.description, **job.folder.provenance()})
    return CalibrationRun(out=job.folder.root, idata=None, report=report, warnings=[])


def fit_verdicts(config: CalibrationConfig, outcome: CalibrationRun) -> dict:
    """The verdicts every fit gets (:mod:`analysis.calibration.verdicts`), as entries of its report."""
    out = {}
    draws = posterior_sample(config, outcome)
    if draws is not None:
        out["bounds"] = bound_verdicts(config, draws)
    group = group_verdict(config, outcome.flock)
    if group is not None:
        out["group_structure"] = group
    outcome.report.update(out)
    return {**out, **credibility(config, outcome)}


def posterior_sample(config: CalibrationConfig, outcome: CalibrationRun):
    """(S, d) posterior draws of the outcome (the optimum as one draw), or None."""
    import numpy as np

    if outcome.optimum:
        return np.array([[outcome.optimum["theta"][name] for name in config.names]])
    posterior = getattr(outcome.idata, "posterior", None) if outcome.idata is not None else None
    if posterior is None:
        return None
    return np.column_stack([np.asarray(posterior[name]).ravel() for name in config.names])


class Checkpoints(Phases):
    """The calibration's numbered phases, each start also saving ``accounting.json``: the run's status
    (running, done, failed, interrupted), the phase it is in, its accounting so far, and how to go on."""

    def __init__(self, total: int, enabled: bool, folder: OutputFolder, cost: Accounting, config):
        super().__init__("calibrate", total, enabled)
        self.folder, self.cost, self.config, self.phase, self.job = folder, cost, config, "", None

    def start(self, name: str) -> None:
        super().start(name)
        self.phase = f"[{min(self.count, self.total)}/{self.total}] {name}"
        self.save("running")

    def save(self, status: str, error: BaseException | None = None) -> None:
        extra = self.job.cost_extra if self.job is not None else {}
        record = {"name": self.config.name, "method": self.config.method.kind, "status": status,
                  "phase": self.phase, "accounting": self.cost.block(**extra)}
        if error is not None:
            record["error"] = f"{type(error).__name__}: {error}"
        if status in ("failed", "interrupted"):
            record["resume"] = ("finished work is kept; run the same command again to go on: "
                                + resume_hint(self.config.source_path or "CALIB.toml", self.folder.root, self.config))
        try:
            self.folder.write_json(ACCOUNTING_FILE, json_ready(record))
        except Exception:   # noqa: BLE001 - a failing disk must not hide the error being reported
            if error is None:
                raise
