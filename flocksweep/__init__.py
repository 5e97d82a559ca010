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

The same names stay importable from their layers (``from flocksweep.simcore import simulate``, ``from
flocksweep.sweeps import run_sweep, load_results``, ``from flocksweep.analysis import calibrate, report``); this
table only forwards to them. ``flocksweep`` is the one top-level import name of the distribution: the
repository's layer folders (``simcore/``, ``observables/``, ``sweeps/``, ``analysis/``) are installed as its
subpackages (pyproject.toml's package-dir), and this ``__init__`` and :mod:`flocksweep.lazy` import only the
standard library, so every layer may sit below them.
"""
from __future__ import annotations

from .lazy import public_names

__all__ = ["Calibration", "Results", "Sweep", "__version__", "calibrate", "load_calibration_results",
           "load_preset", "load_results", "report", "run_calibration", "run_sweep", "simulate",
           "simulate_batch", "simulate_preset", "summary_simulator"]

# name -> (package of the layer that owns it, attribute); each resolves through that package's own table
_HOMES = {name: ("flocksweep.simcore", name) for name in ("load_preset", "simulate", "simulate_batch",
                                                          "simulate_preset")}
_HOMES.update({name: ("flocksweep.sweeps", name) for name in ("Sweep", "Results", "run_sweep", "load_results")})
_HOMES.update({name: ("flocksweep.analysis", name) for name in ("Calibration", "calibrate", "load_calibration_results",
                                                                "report", "run_calibration", "summary_simulator")})


def version() -> str:
    """This package's version, from its installed metadata (pyproject.toml's ``version``: one source)."""
    from importlib.metadata import PackageNotFoundError, version as installed

    try:
        return installed("flocksweep")
    except PackageNotFoundError:
        return "0+unknown (not installed: pip install -e .)"


_forward, __dir__ = public_names(__name__, globals(), _HOMES)


def __getattr__(name: str):
    if name == "__version__":
        return version()
    return _forward(name)
