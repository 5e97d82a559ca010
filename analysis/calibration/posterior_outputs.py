"""The outputs every posterior shares, whichever method sampled it: ``posterior.nc``, ``posterior.csv``,
``predictive.csv``, ``flock_check.csv``, the figures, the viewer pages and ``convergence.json``.

Contract
--------
Both take the calibration's :class:`~analysis.calibration.methods.base.Job` (config, output folder, pool,
phases, accounting, the number of predictive draws), count the predictive simulations in its accounting
and return the :class:`~analysis.calibration.outcome.CalibrationRun` whose ``report`` the calibration
completes (accounting, wall time) and writes as ``convergence.json``.

``write_posterior(job, result, extra=None, warnings=None) -> CalibrationRun``: from a chain (a
:class:`~analysis.calibration.mcmc.ChainResult`: emcee, the emulator): the summary after the default
burn-in, the chain verdicts with ArviZ's, ``job.predictive_draws`` posterior draws picked without
replacement (``[seed, Tag.PREDICTIVE]``) and simulated
(:func:`~analysis.calibration.data_model.predictive_runs`), the trace, rank and corner plots, the viewer
pages; ``extra`` merged into the report.

``write_draws(job, draws (S, d), verdict, report_extra, warnings=(), chains=4) -> (CalibrationRun,
picked)``: the same from independent draws (npe, a user's method): the draws split into ``chains``
pseudo-chains for ArviZ's R-hat and ESS, ``job.predictive_draws`` of them picked (``[seed,
Tag.PREDICTIVE]``; their indices returned) and simulated, ``verdict`` (a dict with ``converged`` and
``messages``) as the ``convergence`` entry, ``report_extra`` merged into the report.

``predictive_phase(config, draws, pool, phases)``: :func:`~analysis.calibration.data_model.predictive_runs`
as a numbered phase with a bar of simulations. ``ProgressBar(total, name, enabled)``: a tqdm bar of MCMC
steps with the acceptance and tau estimate, whose ``callback`` is None when disabled.
"""
from __future__ import annotations

import numpy as np
from tqdm import tqdm

from flocksweep.analysis.reports.labels import parameter_label
from flocksweep.simcore.schema import to_dict
from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.files import json_ready
from flocksweep.sweeps.progress import Phases, bar
from flocksweep.sweeps.seeds import Tag, generator
from flocksweep.sweeps.store import OutputFolder

from .data_model import predictive_runs
from .diagnostics import (arviz_verdicts, convergence, posterior_summary, predictive_check,
                          prior_constraint_warnings)
from .flock_check import flock_check
from .inference import POSTERIOR_FILE, arviz_diagnostics, chain_inference_data, draws_inference_data, write_inference_data
from .outcome import CalibrationRun
from .plots import corner_figure, predictive_figure, rank_figure, trace_figure
from .viewer_page import posterior_median_page, predictive_page


def posterior_draws(chain: np.ndarray, burn: int, count: int, rng: np.random.Generator):
    """(draws (P, d), their (walker, step) (P, 2)) picked without replacement after the burn-in."""
    flat = chain[burn:].reshape(-1, chain.shape[-1])
    picked = rng.choice(len(flat), size=min(count, len(flat)), replace=False)
    walkers = chain.shape[1]
    return flat[picked], np.column_stack([picked % walkers, burn + picked // walkers])


def predictive_phase(config, draws: np.ndarray, pool: Executor, phases: Phases):
    """The posterior predictive runs as a phase of ``phases``, with a bar of simulations."""
    phases.start(f"the posterior predictive check: {len(draws)} simulations at posterior draws")
    with bar(len(draws), f"{config.name}: predictive", "sim", phases.enabled) as shown:
        return predictive_runs(config, draws, pool, shown.update)


def drawn(warnings: list, name: str, draw, *args, **kwargs):
    """``draw(*args, **kwargs)``; a figure or page that cannot be drawn is a warning naming it (the
    calibration's numbers are written already), never a lost calibration. Returns what ``draw`` returned,
    or None."""
    try:
        return draw(*args, **kwargs)
    except Exception as err:  # noqa: BLE001 - any drawing failure
        warnings.append(f"{name} was not drawn ({type(err).__name__}: {err}); the tables and posterior.nc are "
                        "complete")
        return None


def _corner(config, samples, folder: OutputFolder) -> None:
    truth = config.targets.truth
    corner_figure(samples, config.names, folder.path("corner.png"),
                  truths=[truth[n] for n in config.names] if truth else None,
                  labels=[f"{name}: {parameter_label(key)}" for name, key in zip(config.names, config.keys)])


def pages(config, summary, draws, predictive, flock, folder, warnings: list) -> None:
    """The viewer pages: a run at the posterior median, and the measured flock beside a predictive run."""
    drawn(warnings, "viewer_posterior_median.html", posterior_median_page, config, summary, folder.root)
    shown = drawn(warnings, "viewer_predictive.html", predictive_page, config, summary, draws, predictive, flock,
                  folder.root)
    if shown is not None:
        warnings += shown[1]


def write_posterior(job, result, extra: dict | None = None, warnings: list | None = None) -> CalibrationRun:
    """From a chain to the posterior's outputs (see the module docstring)."""
    config, folder = job.config, job.folder
    summary = posterior_summary(result.chain, config.names, result.acceptance_fraction)
    burn = int(summary.attrs.get("burn", 0))
    verdict = convergence(result.chain, result.acceptance_fraction, burn=burn,
                          moves=getattr(config.method, "moves", "stretch"))
    warnings = list(warnings or []) + prior_constraint_warnings(summary, config.prior)
    draws, source = posterior_draws(result.chain, burn, job.predictive_draws, generator(config.seed, Tag.PREDICTIVE))
    predictive, flock = predictive_phase(config, draws, job.pool, job.phases)
    job.cost.add("predictive", len(predictive))
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
    drawn(warnings, "trace.png", trace_figure, result.chain, config.names, folder.path("trace.png"), burn=burn)
    drawn(warnings, "rank.png", rank_figure, idata, folder.path("rank.png"))
    drawn(warnings, "corner.png", _corner, config, result.chain[burn:].reshape(-1, config.dim), folder)
    drawn(warnings, "predictive.png", predictive_figure, check, predictive, config.targets.observed,
          config.targets.columns, folder.path("predictive.png"))
    pages(config, summary, draws, predictive, flock, folder, warnings)
    report = json_ready({"name": config.name, "method": config.method.kind, "settings": to_dict(config.method),
                         "seed": config.seed, "convergence": verdict, "warnings": warnings,
                         "transforms": job.transforms_record, "predictive_runs": int(len(predictive)),
                         "steps": int(result.chain.shape[0]), "walkers": int(result.chain.shape[1]), "burn": burn,
                         "executor": job.pool.description, **(extra or {}), **folder.provenance()})
    return CalibrationRun(out=folder.root, idata=idata, report=report, summary=summary, convergence=verdict,
                          warnings=warnings, predictive=check, flock=flock_table)


def write_draws(job, draws: np.ndarray, verdict: dict, report_extra: dict, warnings=(), chains: int = 4):
    """From independent posterior draws to the posterior's outputs (see the module docstring); returns
    (the CalibrationRun, the indices of the draws simulated for the predictive check)."""
    config, folder = job.config, job.folder
    summary = posterior_summary(draws[:len(draws) // chains * chains].reshape(-1, chains, config.dim), config.names,
                                np.full(chains, np.nan), burn=0)
    picked = generator(config.seed, Tag.PREDICTIVE).choice(len(draws), size=min(job.predictive_draws, len(draws)),
                                                           replace=False)
    predictive, flock = predictive_phase(config, draws[picked], job.pool, job.phases)
    job.cost.add("predictive", len(predictive))
    predictive_table = predictive_check(config.targets.observed, predictive, config.targets.columns)
    flock_table = flock_check(config, predictive, flock)
    idata = draws_inference_data(config, draws, chains=chains, predictive=predictive)
    write_inference_data(idata, folder.path(POSTERIOR_FILE))
    summary = summary.drop(columns=["tau", "ess", "acceptance"]).join(arviz_diagnostics(idata))
    folder.write_csv("posterior.csv", summary)
    folder.write_csv("predictive.csv", predictive_table)
    folder.write_csv("flock_check.csv", flock_table)
    drawn_warnings = []
    drawn(drawn_warnings, "rank.png", rank_figure, idata, folder.path("rank.png"))
    drawn(drawn_warnings, "corner.png", _corner, config, draws, folder)
    drawn(drawn_warnings, "predictive.png", predictive_figure, predictive_table, predictive, config.targets.observed,
          config.targets.columns, folder.path("predictive.png"))
    pages(config, summary, draws[picked], predictive, flock, folder, drawn_warnings)
    warnings = prior_constraint_warnings(summary, config.prior) + drawn_warnings + list(warnings)
    report = json_ready({"name": config.name, "method": config.method.kind, "settings": to_dict(config.method),
                         "seed": config.seed, "convergence": verdict, "warnings": warnings,
                         "transforms": job.transforms_record, "predictive_runs": int(len(predictive)),
                         **report_extra,
                         "draws": len(draws), "executor": job.pool.description, **folder.provenance()})
    outcome = CalibrationRun(out=folder.root, idata=idata, report=report, summary=summary, convergence=verdict,
                             warnings=warnings, predictive=predictive_table, flock=flock_table)
    return outcome, picked


class ProgressBar:
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
