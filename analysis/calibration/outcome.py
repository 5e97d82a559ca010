"""What one calibration produced: :class:`CalibrationRun`, returned by
:func:`analysis.calibration.run.run_calibration` and by every method's ``run``
(:mod:`analysis.calibration.methods`); its ``idata`` is also ``posterior.nc``, its ``report``
``convergence.json`` (``optimum.json`` for optimize)."""
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
