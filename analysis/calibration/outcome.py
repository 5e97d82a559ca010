"""What one calibration produced: :class:`CalibrationRun`, returned by
:func:`analysis.calibration.run.run_calibration` and by every method's ``run``
(:mod:`analysis.calibration.methods`); its ``idata`` is also ``posterior.nc``, its ``report``
``convergence.json`` (``optimum.json`` for optimize). :class:`NoPosterior`: what a method raises when it
cannot give a posterior (a verdict, not a crash)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd


@dataclass
class CalibrationRun:
    """What one calibration produced (see the module docstring)."""

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
        from .calibration_report import verdict_lines

        return verdict_lines(config, self)


class NoPosterior(RuntimeError):
    """A method could not give a posterior (e.g. npe's estimator puts no mass inside the prior at the observed
    statistics): a verdict, not a crash. ``reason`` says why in plain words; ``report`` holds what the method
    learnt before (merged into ``convergence.json``). The calibration writes its accounting, the verdict "not
    credible" with the reason and a report of the verdicts, and returns without a posterior."""

    def __init__(self, reason: str, report: dict | None = None):
        super().__init__(reason)
        self.reason = reason
        self.report = dict(report or {})
