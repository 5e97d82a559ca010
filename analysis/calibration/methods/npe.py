"""The ``npe`` method: neural posterior estimation (:mod:`analysis.calibration.npe`, the flow of
:mod:`analysis.calibration.npe_flow`; the ``sbi`` extra): the estimator trained (or reused), its coverage
checked on held-out simulations (which gates the verdict), then its draws at the targets through the
posterior's common outputs (:func:`analysis.calibration.posterior_outputs.write_draws`) with
``coverage.csv`` and ``coverage_ranks.png``."""
from __future__ import annotations

from ..settings import NpeSettings
from .base import CalibrationMethod, Job


class Npe(CalibrationMethod):
    kind = "npe"
    settings = NpeSettings
    sbc = True
    what = ("neural posterior estimation: a conditional normalising flow q(theta given statistics) trained on "
            "prior draws run through the calibration's own simulator (measured through the `[observation]` block "
            "like the tracks), its coverage checked on held-out simulations; amortised (new targets cost no "
            "simulation)")
    cost = ("`simulations + heldout` runs once (default 1,000 + 200; stored as they finish and found again, not "
            "rerun), then only the predictive check")
    use_when = "simulations are expensive, or many flocks/flights share one model; needs the `sbi` extra"

    def resolve(self, settings, where, base, dim: int, k: int):
        import dataclasses

        from flocksweep.simcore.schema import resolve_path

        if settings.estimator is None:
            return settings
        return dataclasses.replace(settings, estimator=resolve_path(str(settings.estimator), base,
                                                                    where("estimator"), "estimator folder",
                                                                    must_exist=False))

    def check_cost(self, config, yes: bool) -> None:
        from ..feasibility import check_simulation_count

        settings = config.method
        check_simulation_count("method.npe.simulations", settings.simulations * settings.rounds + settings.heldout,
                               yes)

    def phase_count(self, config) -> int:
        return 2 * config.method.rounds + 2        # per round sweep and flow; coverage, predictive

    def resume_hint(self, command: str, out_dir) -> str:
        return (f"the training runs and estimators finished so far are kept in {out_dir}; run the same command "
                f"again to go on: flocksweep calibrate {command} --out {out_dir}")

    def run(self, job: Job):
        from ..npe import run_npe
        from ..plots import sbc_figure
        from ..posterior_outputs import drawn, write_draws

        config, folder = job.config, job.folder
        result = run_npe(config, folder, job.pool, job.executor, job.phases, job.cost)
        draws, check = result.draws, result.coverage
        warnings = []
        if result.info["leakage"] > 0.1:
            warnings.append(f"{result.info['leakage']:.0%} of the estimator's draws at the targets fell outside the "
                            "prior (redrawn): the targets may lie outside what the simulations cover")
        verdict = {"converged": check["passed"], "coverage_ok": check["passed"], "messages": check["messages"]}
        outcome, _ = write_draws(job, draws, verdict, {"npe": result.info}, warnings)
        folder.write_csv("coverage.csv", check["table"], index=False)
        drawn(outcome.warnings, "coverage_ranks.png", sbc_figure, check["ranks"], check["draws"], 20, config.names,
              folder.path("coverage_ranks.png"))
        if result.info["runs_found"]:
            job.cost_extra["training_runs_reused"] = result.info["runs_found"]
        return outcome

    def run_sbc(self, config, steps=None, walkers=None, **options) -> dict:
        from flocksweep.simcore.schema import ConfigError

        from ..sbc_npe import run_npe_sbc

        for flag, value in (("--steps", steps), ("--walkers", walkers)):
            if value is not None:
                raise ConfigError(flag, f"got {value}; npe's SBC runs no chain (the steps and walkers of a chain "
                                        "apply to emcee): leave it out")
        return run_npe_sbc(config, **options)

    def report_blocks(self, config, outcome, folder) -> list:
        from ..calibration_report import npe_blocks

        return npe_blocks(outcome, folder)
