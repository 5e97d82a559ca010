"""The ``emcee`` method: Bayesian synthetic likelihood MCMC (:mod:`analysis.calibration.bsl`), its chain in
``chain.h5`` (continued by the same command run again), then the posterior's common outputs
(:func:`analysis.calibration.posterior_outputs.write_posterior`)."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from flocksweep.simcore.schema import ConfigError

from ..settings import ChainSettings, EmceeSettings
from .base import CalibrationMethod, Job


def checked_walkers(settings: ChainSettings, where, dim: int) -> int:
    """The walkers of a chain method: max(16, 2 d) when not given; even and >= 2 d."""
    walkers = max(16, 2 * dim) if settings.walkers is None else settings.walkers
    if walkers < 2 * dim:
        raise ConfigError(where("walkers"), f"got {walkers}; need at least 2 x {dim} parameters = {2 * dim}")
    if walkers % 2:
        raise ConfigError(where("walkers"), f"got {walkers}; must be even")
    return walkers


def _digest(data) -> str:
    from flocksweep.sweeps.files import json_ready

    return hashlib.sha256(json.dumps(json_ready(data), sort_keys=True).encode()).hexdigest()[:16]


def chain_meta(config) -> dict:
    """What defines a BSL chain besides the driver's own settings, as HDF5 attributes (compared on resume)."""
    from flocksweep.simcore import MODEL_VERSION

    targets = config.targets
    m = config.metrics
    return {"chain_n_sim": int(config.method.n_sim),
            "chain_parameters": ", ".join(f"{p.name}={p.key}" for p in config.parameters),
            "chain_prior": repr(config.prior),
            "chain_metrics": f"warmup={m.warmup!r}, group_radius={m.group_radius!r}, "
                             f"fragmentation_cohesion={m.fragmentation_cohesion!r}",
            "chain_targets": _digest({"summary": targets.summary, "columns": list(targets.columns),
                                      "observed": targets.observed, "cov": targets.cov}),
            "chain_model": _digest({"preset": config.preset.to_dict(), "version": MODEL_VERSION}
                                   if config.command is None else {"command": config.command.identity}),
            "chain_transforms": config.transforms.describe()}


class ChainMethod(CalibrationMethod):
    """A method whose posterior is an emcee chain in ``chain.h5`` (emcee, emulator)."""

    def resolve(self, settings, where, base, dim: int, k: int):
        import dataclasses

        return dataclasses.replace(settings, walkers=checked_walkers(settings, where, dim))

    def continues(self, config, folder) -> bool:
        return folder.path("chain.h5").exists()

    def resume_hint(self, command: str, out_dir) -> str:
        from ..chainfile import stored_steps

        chain = Path(out_dir) / "chain.h5"
        steps = stored_steps(chain)
        if not steps:
            return "no chain step was saved yet: run the same command again"
        return (f"saved: {steps} chain steps in {chain}; resume with: flocksweep calibrate {command} "
                f"--out {out_dir} --resume")

    def report_blocks(self, config, outcome, folder) -> list:
        from ..calibration_report import chain_blocks

        return chain_blocks(outcome, folder)


class Emcee(ChainMethod):
    kind = "emcee"
    settings = EmceeSettings
    sbc = True
    what = "Bayesian synthetic likelihood MCMC (Wood 2010; Price et al. 2018)"
    cost = "`walkers x steps x n_sim` runs"
    use_when = "you want the posterior and can afford the simulations"

    def check_cost(self, config, yes: bool) -> None:
        from ..feasibility import check_chain_size

        settings = config.method
        check_chain_size(settings.walkers, settings.steps, settings.n_sim, config.dim, yes)

    def phase_count(self, config) -> int:
        return 2                                   # the chain, the predictive check

    def run(self, job: Job):
        from ..bsl import run_bsl
        from ..chainfile import stored_steps
        from ..data_model import simulate_fn
        from ..posterior_outputs import ProgressBar, write_posterior
        from ..simulator import summary_simulator

        config, settings = job.config, job.config.method
        resumed_from = stored_steps(job.folder.path("chain.h5")) if job.resume else 0
        job.phases.start(f"the chain: {settings.walkers} walkers x {settings.steps} steps, {settings.n_sim} "
                         f"simulations per evaluation" + (f" (resuming after step {resumed_from})" if resumed_from
                                                          else ""))
        with ProgressBar(settings.steps, config.name, job.progress) as bar:
            transforms = config.transforms      # what BSL's Gaussian sees (analysis.calibration.transforms)
            result = run_bsl(transforms.wrap(simulate_fn(config, summary_simulator(config))),
                             transforms.apply(config.targets.observed), config.prior,
                             walkers=settings.walkers, steps=settings.steps, seed=config.seed,
                             path=job.folder.path("chain.h5"), resume=job.resume, likelihood=settings.likelihood,
                             reevaluate_every=settings.reevaluate_every, moves=settings.moves,
                             progress=bar.callback, executor=job.pool, meta=chain_meta(config),
                             until_converged=settings.until_converged, check_every=settings.check_every,
                             count=job.cost.add)
        if resumed_from:
            job.cost_extra["resumed_from"] = resumed_from
        return write_posterior(job, result)

    def run_sbc(self, config, **options) -> dict:
        from ..sbc import run_sbc

        return run_sbc(config, **options)
