"""The ``optimize`` method: a point estimate by ``scipy.optimize`` with common random numbers during the
search, re-checked with fresh seeds (:mod:`analysis.calibration.optimize`); its report is ``optimum.json``."""
from __future__ import annotations

from ..settings import OptimizeSettings
from .base import CalibrationMethod, Job


class Optimize(CalibrationMethod):
    kind = "optimize"
    settings = OptimizeSettings
    report_file = "optimum.json"
    what = ("differential evolution or Nelder-Mead on the synthetic log posterior or a standardised distance, "
            "common random numbers during the search, re-checked with fresh seeds")
    cost = "`popsize x d x maxiter x n_sim` runs"
    use_when = "you want a point estimate fast"

    def phase_count(self, config) -> int:
        return 3                                   # the search, the re-check, the flock at the optimum

    def run(self, job: Job):
        import time

        from flocksweep.simcore.schema import to_dict
        from flocksweep.sweeps.files import json_ready
        from flocksweep.sweeps.progress import bar

        from ..data_model import seeded_fn
        from ..diagnostics import predictive_check
        from ..inference import POSTERIOR_FILE, optimum_inference_data, write_inference_data
        from ..optimize import max_evaluations, run_optimize
        from ..outcome import CalibrationRun
        from ..plots import predictive_figure
        from ..simulator import summary_simulator

        config, folder, settings = job.config, job.folder, job.config.method
        started = time.time()
        most = max_evaluations(settings.algorithm, settings.maxiter, settings.popsize, config.dim)
        count = f"up to {most:,} evaluations" if most else f"evaluations (at most {settings.maxiter} iterations)"
        job.phases.start(f"searching ({settings.algorithm}): {count} of {settings.n_sim} simulations each, then a "
                         f"re-check with {settings.recheck} fresh ones")
        with bar(most, f"{config.name}: search", "evaluation", job.progress) as search:
            result = run_optimize(seeded_fn(config, summary_simulator(config)), config.targets.observed,
                                  config.prior, seed=config.seed, n_sim=settings.n_sim, algorithm=settings.algorithm,
                                  maxiter=settings.maxiter, popsize=settings.popsize, recheck=settings.recheck,
                                  likelihood=settings.likelihood, objective=settings.objective, executor=job.pool,
                                  tick=search.update, transform=config.transforms.apply)
        job.phases.start(f"re-checked the optimum with {result.recheck_simulations} fresh simulations; writing the "
                         "predictive check")
        check = predictive_check(config.targets.observed, result.recheck_summaries, config.targets.columns)
        folder.write_csv("predictive.csv", check)
        predictive_figure(check, result.recheck_summaries, config.targets.observed, config.targets.columns,
                          folder.path("predictive.png"))
        job.cost.add("search", result.search_simulations, result.search_evaluations)
        job.cost.add("recheck", result.recheck_simulations, len(result.recheck_batches))
        job.cost_extra["optimizer_evaluations"] = int(result.nfev)
        optimum = json_ready({"name": config.name, "method": self.kind, "settings": to_dict(settings),
                              "seed": config.seed, "theta": dict(zip(config.names, map(float, result.theta))),
                              "objective_common_seeds": float(result.objective_crn),
                              "objective_recheck": float(result.objective_recheck),
                              "recheck_se": float(result.recheck_se), "optimizer_evaluations": int(result.nfev),
                              "success": bool(result.success), "message": str(result.message),
                              "wall_s": time.time() - started, "executor": job.pool.description,
                              "transforms": config.transforms.record(),
                              "predictive_runs": int(len(result.recheck_summaries)),
                              **folder.provenance()})
        idata = optimum_inference_data(config, result.theta, result.recheck_summaries)
        write_inference_data(idata, folder.path(POSTERIOR_FILE))
        flock_table, warnings = _flock_at_optimum(job, result.theta)
        optimum["warnings"] = warnings
        return CalibrationRun(out=folder.root, idata=idata, report=optimum, predictive=check, optimum=optimum,
                              warnings=warnings, flock=flock_table)

    def report_blocks(self, config, outcome, folder) -> list:
        from ..calibration_report import optimum_blocks

        return optimum_blocks(outcome)


def _flock_at_optimum(job: Job, theta):
    """``job.predictive_draws`` runs at the optimum (the predictive seeds): the flock check against the observed
    flock and the viewer pages (a run at the optimum; the measured flock beside one); (table, warnings)."""
    import numpy as np
    import pandas as pd

    from ..flock_check import flock_check
    from ..posterior_outputs import pages, predictive_phase

    config = job.config
    draws = np.repeat(np.asarray(theta, dtype=float)[None, :], max(1, job.predictive_draws), axis=0)
    predictive, flock = predictive_phase(config, draws, job.pool, job.phases)
    job.cost.add("predictive", len(predictive))
    table = flock_check(config, predictive, flock)
    job.folder.write_csv("flock_check.csv", table)
    summary = pd.DataFrame({"median": np.asarray(theta, dtype=float)}, index=pd.Index(config.names, name="parameter"))
    warnings = []
    pages(config, summary, draws, predictive, flock, job.folder, warnings)
    return table, warnings
