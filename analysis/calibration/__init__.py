"""analysis.calibration: fitting a flocking model's free parameters to observed flock statistics.

Python API (loaded on first use, so ``import flocksweep.analysis.calibration`` stays light):

* ``load_calibration(path, overrides=()) -> CalibrationConfig``: read and validate a calibration TOML;
* ``calibrate(config, out_dir=None, ...) -> arviz.InferenceData``: run it, write its outputs (posterior.nc,
  posterior.csv, convergence.json, figures, report.html) and return the posterior as InferenceData;
* ``run_calibration(config, ...) -> CalibrationRun``: the same with everything the run produced (verdicts,
  tables, the emulator's confirmation and refinement rounds);
* ``load_calibration_results(out_dir) -> arviz.InferenceData``: read a calibration's ``posterior.nc`` back.

Modules: configuration (``config``: calibration files on the one schema engine, typed settings per
method in ``settings``), priors and synthetic likelihoods (``priors``, ``likelihood``), the theta ->
summaries simulator (``simulator``), the one emcee driver (``mcmc``) and the methods on it: BSL
(``bsl``), the emulator (``training``, ``surrogates``, ``emulated``, its sequential design ``refine``),
optimisation (``optimize``), neural posterior estimation (``npe`` on the flow of ``npe_flow``; the
``sbi`` extra) and its amortised command ``flocksweep posterior`` (``posterior_command``); ``flocksweep calibrate`` (``run``), diagnostics, ArviZ output and figures
(``diagnostics``, ``inference``, ``plots``), the calibration report (``calibration_report``),
simulation-based calibration (``sbc``, ``sbc_report``), synthetic targets (``synthetic``) and targets
from measured tracks with the ``[observation]`` block's checks (``tracks_targets``). This layer
sits above ``sweeps`` (its executor, seed registry, output folders and sweep extension) and
``analysis.reports`` (figure plumbing, the report document); see docs/architecture.md.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from flocksweep.lazy import public_names

if TYPE_CHECKING:  # for type checkers and IDEs; at run time the names load on first use (__getattr__)
    from .config import CalibrationConfig, load_calibration
    from .inference import load_calibration_results
    from .outcome import CalibrationRun
    from .run import calibrate, run_calibration

__all__ = ["CalibrationConfig", "CalibrationRun", "calibrate", "load_calibration", "load_calibration_results",
           "run_calibration"]

__getattr__, __dir__ = public_names(__name__, globals(), {
    "CalibrationConfig": "config", "load_calibration": "config", "load_calibration_results": "inference",
    "CalibrationRun": "outcome", "calibrate": "run", "run_calibration": "run"})
