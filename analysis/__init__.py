"""analysis: the layer above the sweeps (layer 4): the viewer, the reports and the calibration.

See docs/architecture.md for the layers and what each may import. Importing ``analysis`` loads none of
its subpackages: the names below load theirs on first use (module ``__getattr__``).

Python API::

    from flocksweep.analysis import report, Calibration, calibrate, summary_simulator
    report("results/smoke")                                         # HTML/Markdown report, tables
    cal = Calibration.from_toml("configs/calibration/recover_holland.toml", ["method.steps=200"])
    idata = calibrate(cal, out_dir="results/calibration/recover")   # ArviZ InferenceData
    sim = summary_simulator(cal, threads=1)                         # for pyABC, sbi, ELFI ...

* :func:`report` (= :func:`analysis.reports.report.build_report`): a sweep's statistics, figures and claims;
* :class:`Calibration` (= :class:`analysis.calibration.config.CalibrationConfig`), ``Calibration.from_toml``;
* :func:`calibrate` (:func:`analysis.calibration.run.calibrate`), :func:`run_calibration` (everything a
  calibration produced) and :func:`load_calibration_results`;
* :func:`summary_simulator` (:mod:`analysis.calibration.summaries`): a calibration's exact simulator and
  observation noise model, for other inference libraries and their worker processes.
"""
from __future__ import annotations

# Only the namespace's name helper is imported here: importing flocksweep.analysis loads none of its
# subpackages (tests/test_architecture.py); the public names load their homes on first use.
from flocksweep.lazy import public_names

__all__ = ["Calibration", "CalibrationSimulator", "calibrate", "load_calibration_results", "report",
           "run_calibration", "summary_simulator"]

__getattr__, __dir__ = public_names(__name__, globals(), {
    "report": ("reports.report", "build_report"), "Calibration": ("calibration.config", "CalibrationConfig"),
    "calibrate": "calibration.run", "run_calibration": "calibration.run",
    "load_calibration_results": "calibration.inference", "summary_simulator": "calibration.summaries",
    "CalibrationSimulator": "calibration.summaries"})
