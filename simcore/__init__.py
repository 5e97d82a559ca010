"""simcore: a deterministic, compiled 3-D flocking simulator (specified in docs/model.md).

Public API::

    from flocksweep.simcore import load_preset, simulate, simulate_preset, simulate_batch
    preset = load_preset("configs/models/holland.toml", ["perception.field_deg=180"])
    obs = simulate_preset(preset, seed=1)           # Observations: times, pos, vel, visible, ...

Importing this package compiles nothing and imports nothing heavy (the public names load their modules
on first use); the kernels compile (or load from numba's cache) on first call. The one thing an import does is drop this package's cached kernels when its sources changed
(numba alone would miss edits to inlined helpers; see ``simcore/_cache.py``).
"""
import sys as _sys
import types as _types
from pathlib import Path as _Path

from flocksweep.lazy import public_names as _public_names

from ._cache import refresh as _refresh_cache

_refresh_cache(_Path(__file__).parent, __name__)

# name -> module that defines it; loaded on first use, so ``import flocksweep.simcore.schema`` (the command
# line's help, version and status) does not import numba
_HOMES = {**{name: "params" for name in ("InitParams", "ModelParams", "Preset", "RunSettings", "load_preset",
                                         "preset_from_dict")},
          "ConfigError": "schema",
          **{name: "simulate" for name in ("MODEL_VERSION", "Observations", "advance", "placeholder_observations",
                                           "simulate", "simulate_batch", "simulate_preset")},
          "State": "state", "initial_state": "state"}
__all__ = sorted(_HOMES)
__getattr__, __dir__ = _public_names(__name__, globals(), _HOMES)


class _Package(_types.ModuleType):
    """``simcore.simulate`` stays the function when the submodule of that name is imported (the import
    system sets the submodule as the package's attribute); the module is ``sys.modules["flocksweep.simcore.simulate"]``."""

    def __setattr__(self, name, value):
        if name == "simulate" and isinstance(value, _types.ModuleType):
            value = value.simulate
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package
