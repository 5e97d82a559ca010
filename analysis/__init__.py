"""analysis: the layer above the sweeps (layer 4): the viewer, the reports and the calibration.

See docs/architecture.md for the layers and what each may import. Importing ``analysis`` loads none of
its subpackages: the names below load theirs on first use (module ``__getattr__``).

Python API::

    from analysis import report, Calibration, calibrate, summary_simulator
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

# No import statements here: the namespace stays below every layer (tests/test_architecture.py); the
# public names resolve through _HOMES on first use.
__all__ = ["Calibration", "CalibrationSimulator", "calibrate", "load_calibration_results", "report",
           "run_calibration", "summary_simulator"]

_HOMES = {"report": ("reports.report", "build_report"), "Calibration": ("calibration.config", "CalibrationConfig"),
          "calibrate": ("calibration.run", "calibrate"), "run_calibration": ("calibration.run", "run_calibration"),
          "load_calibration_results": ("calibration.inference", "load_calibration_results"),
          "summary_simulator": ("calibration.summaries", "summary_simulator"),
          "CalibrationSimulator": ("calibration.summaries", "CalibrationSimulator")}


def __getattr__(name: str):
    if name in _HOMES:
        import importlib

        module, attribute = _HOMES[name]
        return getattr(importlib.import_module(f"{__name__}.{module}"), attribute)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
