"""The ``emulator`` method: emcee on a surrogate of the statistics fitted to an existing sweep's results
(:mod:`analysis.calibration.training`, :mod:`~analysis.calibration.surrogates`,
:mod:`~analysis.calibration.emulated`), confirmed with real runs at the posterior median and, with
``refine``, refined by new sweep runs until the confirmation passes (:mod:`analysis.calibration.refine`)."""
from __future__ import annotations

import sys
import time

from ..settings import EmulatorSettings
from .base import Job
from .emcee import ChainMethod


class Emulator(ChainMethod):
    kind = "emulator"
    settings = EmulatorSettings
    uses_transforms = False     # the surrogate emulates the statistics' mean and variance on their own scale
    what = ("a Gaussian-process (or RBF) surrogate of the statistics' mean and variance fitted to an existing "
            "sweep's results, emcee on the surrogate, confirmed with real runs; optionally refines the sweep where "
            "the posterior is until the confirmation passes")
    cost = "the sweep you already ran + a few hundred runs"
    use_when = "you already have a sweep (e.g. the 648-cell grid) over the free parameters"
    sbc = True   # its chain on the surrogate, on many simulated datasets (analysis.calibration.sbc_emulator)

    def resolve(self, settings, where, base, dim: int, k: int):
        import dataclasses

        from flocksweep.simcore.schema import resolve_path

        settings = super().resolve(settings, where, base, dim, k)
        return dataclasses.replace(settings, results=resolve_path(str(settings.results), base, where("results"),
                                                                  "results folder", must_exist=False))

    def check(self, config) -> None:
        from flocksweep.simcore.schema import ConfigError

        if config.observation is not None and config.command is not None:
            raise ConfigError("method.kind", "the emulator measures a sweep's runs through the [observation] block "
                                             "from their trajectories, which a command model's sweep does not keep; "
                                             "use npe, emcee or optimize")

    def check_cost(self, config, yes: bool) -> None:
        from ..feasibility import check_chain_size

        settings = config.method
        check_chain_size(settings.walkers, settings.steps, 0, config.dim, yes)

    def phase_count(self, config) -> int:
        settings = config.method          # (fit and chain) or refinement rounds, predictive, confirmation
        return (1 if settings.refine.rounds else 2) + 1 + bool(settings.confirm and not settings.refine.rounds)

    def run_sbc(self, config, steps=None, walkers=None, out_dir=None, **options) -> dict:
        from pathlib import Path

        from ..sbc import run_sbc
        from ..sbc_emulator import emulator_problem

        out_dir = Path("results") / "calibration" / config.name / "sbc" if out_dir is None else out_dir
        return run_sbc(emulator_problem(config, steps, walkers), out_dir=out_dir, **options)

    def run(self, job: Job):
        from ..emulated import confirm, posterior_median
        from ..posterior_outputs import write_posterior
        from ..simulator import summary_simulator
        from ..surrogates import build_surrogate, prior_outside_box
        from ..training import training_set

        config, folder, settings, phases = job.config, job.folder, job.config.method, job.phases
        started = time.time()
        if settings.refine.rounds:
            phases.start(f"refinement: up to {settings.refine.rounds} rounds of fit, chain and confirmation")
            refinement, fit_s = _refined_rounds(job)
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
            result = _emulator_mcmc(config, surrogate, folder.path("chain.h5"), job.resume, job.progress,
                                    f"{config.name} (emulator)")
        outcome = write_posterior(job, result, extra={"emulator": _emulator_info(config, training, fit_s)},
                                  warnings=prior_outside_box(config.prior, surrogate))
        if settings.confirm and refinement is None:
            phases.start(f"confirming at the posterior median: {settings.confirm} real simulations")
            theta = posterior_median(result.chain, outcome.report["burn"])
            check = confirm(config, summary_simulator(config), surrogate, theta, count=settings.confirm,
                            seed=config.seed)
            job.cost.add("confirmation", len(check["summaries"]))
        if settings.confirm:
            _write_confirmation(folder, outcome, check, settings.confirm)
        if refinement is not None:
            rounds = refinement.rounds
            outcome.refine = rounds
            outcome.report["refine"] = {"rounds_run": int(len(rounds)), "rounds_allowed": settings.refine.rounds,
                                        "runs_per_round": settings.refine.runs_per_round,
                                        "runs_added": int(rounds["runs_added"].sum()),
                                        "passed": bool(rounds["passed"].iloc[-1]), "results": str(settings.results)}
            job.cost.add("confirmation", int(rounds["confirm_runs"].sum()))
            job.cost.add("refinement", int(rounds["runs_added"].sum()))
        job.cost_extra["training_runs_reused"] = int(training.count.sum()) - job.cost.simulations["refinement"]
        return outcome

    def report_blocks(self, config, outcome, folder) -> list:
        from ..calibration_report import chain_blocks, emulator_blocks

        return chain_blocks(outcome, folder) + emulator_blocks(outcome, folder)


def _emulator_mcmc(config, surrogate, path, resume: bool, progress: bool, label: str):
    from ..emulated import observation_covariance, run_emulator_mcmc
    from ..posterior_outputs import ProgressBar

    settings = config.method
    with ProgressBar(settings.steps, label, progress) as bar:
        return run_emulator_mcmc(surrogate, config.targets.observed, observation_covariance(config), config.prior,
                                 walkers=settings.walkers, steps=settings.steps, seed=config.seed, path=path,
                                 resume=resume, progress=bar.callback, moves=settings.moves)


def _emulator_info(config, training, fit_s: float) -> dict:
    return {"training_points": int(len(training.points)), "training_runs": int(training.count.sum()),
            "training_box": {n: [float(lo), float(hi)] for n, lo, hi in
                             zip(config.names, training.lower, training.upper)},
            "fixed_factors": training.fixed, "notes": list(training.notes), "fit_s": fit_s,
            "results": str(config.method.results)}


def _refined_rounds(job: Job):
    """The refinement's rounds (analysis.calibration.refine), each chain in rounds/chain_round<r>.h5; the
    last one copied to chain.h5."""
    import shutil

    from tqdm import tqdm

    from flocksweep.sweeps.files import atomic_path

    from ..diagnostics import default_burn
    from ..refine import refine_emulator
    from ..surrogates import build_surrogate
    from ..training import training_set

    config, folder, progress = job.config, job.folder, job.progress
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

    pool_kind, workers, scheduler = job.sweep_executor
    log = (lambda message: tqdm.write(message, file=sys.stderr)) if progress else (lambda message: None)
    refinement = refine_emulator(config, fit_round, pool_kind=pool_kind, workers=workers, scheduler=scheduler,
                                 progress=progress, log=log)
    last = len(refinement.rounds) - 1
    with atomic_path(folder.path("chain.h5")) as tmp:
        shutil.copyfile(folder.path("rounds") / f"chain_round{last}.h5", tmp)
    refinement.result.path = str(folder.path("chain.h5"))
    return refinement, fits[last]


def _write_confirmation(folder, outcome, check: dict, count: int) -> None:
    import numpy as np

    from ..refine import confirmation_passed

    folder.write_csv("confirm.csv", check["comparison"])
    folder.write_csv("confirm_predictive.csv", check["predictive"])
    outcome.confirm = check
    outcome.report["confirm"] = {"theta": check["theta"], "count": count,
                                 "max_abs_z": float(np.nanmax(np.abs(check["comparison"]["z"]))),
                                 "passed": confirmation_passed(check), "messages": confirm_messages(check)}


def confirm_messages(check: dict, z_limit: float | None = None, p_limit: float | None = None) -> list[str]:
    """Plain sentences on the real simulations at the posterior median."""
    from ..refine import P_LIMIT, Z_LIMIT

    z_limit = Z_LIMIT if z_limit is None else z_limit
    p_limit = P_LIMIT if p_limit is None else p_limit
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
