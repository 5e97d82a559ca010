"""flocksweep: the top layer. The ``flocksweep`` command (:mod:`flocksweep.cli`) and one public face
for the Python API of every layer below.

Python API (each name loads its home module on first use, so ``import flocksweep`` loads nothing)::

    import flocksweep as fs
    preset = fs.load_preset("configs/models/holland.toml", ["perception.field_deg=180"])
    obs = fs.simulate_preset(preset, seed=1)                         # simcore
    result = fs.run_sweep(fs.Sweep.from_toml("configs/sweeps/smoke.toml"), "results/smoke")  # sweeps
    runs = fs.load_results("results/smoke").runs
    fs.report("results/smoke")                                       # analysis.reports
    idata = fs.calibrate(fs.Calibration.from_toml("configs/calibration/recover_holland.toml"))

``fs.__version__`` (and ``flocksweep --version``) is the installed package's version, read from its
metadata: pyproject.toml's ``version`` is the one place it is written.

The same names stay importable from their layers (``from simcore import simulate``, ``from sweeps import
run_sweep, load_results``, ``from analysis import calibrate, report``); this table only forwards to them.
"""
from __future__ import annotations

__all__ = ["Calibration", "Results", "Sweep", "__version__", "calibrate", "load_calibration_results",
           "load_preset", "load_results", "report", "run_calibration", "run_sweep", "simulate",
           "simulate_batch", "simulate_preset", "summary_simulator"]

# name -> (package of the layer that owns it, attribute); each resolves through that package's own table
_HOMES = {name: ("simcore", name) for name in ("load_preset", "simulate", "simulate_batch", "simulate_preset")}
_HOMES.update({name: ("sweeps", name) for name in ("Sweep", "Results", "run_sweep", "load_results")})
_HOMES.update({name: ("analysis", name) for name in ("Calibration", "calibrate", "load_calibration_results",
                                                     "report", "run_calibration", "summary_simulator")})


def version() -> str:
    """This package's version, from its installed metadata (pyproject.toml's ``version``: one source)."""
    from importlib.metadata import PackageNotFoundError, version as installed

    try:
        return installed("flocksweep")
    except PackageNotFoundError:
        return "0+unknown (not installed: pip install -e .)"


def __getattr__(name: str):
    if name == "__version__":
        return version()
    if name in _HOMES:
        import importlib

        package, attribute = _HOMES[name]
        return getattr(importlib.import_module(package), attribute)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
