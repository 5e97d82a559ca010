"""sweeps: config-driven parameter sweeps of the simulator and their results folders (layer 3).

Python API (loaded on first use, so ``import flocksweep.sweeps`` loads nothing)::

    from flocksweep.sweeps import Sweep, run_sweep, load_results
    sweep = Sweep.from_toml("configs/sweeps/smoke.toml")          # or Sweep.from_dict({...})
    result = run_sweep(sweep, "results/smoke", executor="local")  # resumable, one row per run
    runs = load_results("results/smoke", with_fixed=True).runs    # pandas, fixed settings as columns

* :class:`Sweep` (= :class:`sweeps.config.SweepConfig`): a validated sweep, ``Sweep.from_toml(path)``,
  ``Sweep.from_dict(data)``, ``sweep.to_toml()``;
* :func:`run_sweep`: run or resume it into a results folder (:mod:`sweeps.api`);
* :func:`load_results`: a results folder as :class:`Results` (pandas runs table, lazy pyarrow time
  series; :mod:`sweeps.results`);
* :class:`ResultsStore`: the folder's files, :class:`SweepResult`: what a run of a sweep returns;
* :class:`RunsLost` (runs left missing by dead workers) and :class:`UnguardedScript` (a script that
  starts workers outside ``if __name__ == "__main__":``): what ``run_sweep`` raises rather than go on
  silently.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from flocksweep.lazy import public_names

if TYPE_CHECKING:  # for type checkers and IDEs; at run time the names load on first use (__getattr__)
    from .api import RunsLost, run_sweep
    from .main_guard import UnguardedScript
    from .config import SweepConfig, SweepConfig as Sweep
    from .results import Results, load_results
    from .runner import SweepResult
    from .store import ResultsStore

__all__ = ["Results", "ResultsStore", "RunsLost", "Sweep", "SweepConfig", "SweepResult", "UnguardedScript", "load_results",
           "run_sweep"]

__getattr__, __dir__ = public_names(__name__, globals(), {
    "run_sweep": "api", "RunsLost": "api", "UnguardedScript": "main_guard", "Sweep": ("config", "SweepConfig"),
    "SweepConfig": "config", "Results": "results", "load_results": "results", "SweepResult": "runner",
    "ResultsStore": "store"})
