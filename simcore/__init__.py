"""simcore: a deterministic, compiled 3-D flocking simulator (specified in docs/model.md).

Public API::

    from simcore import load_preset, simulate, simulate_preset, simulate_batch
    preset = load_preset("configs/models/holland.toml", ["perception.field_deg=180"])
    obs = simulate_preset(preset, seed=1)           # Observations: times, pos, vel, visible, ...

Importing this package compiles nothing; the kernels compile (or load from numba's cache) on first
call. The one thing an import does is drop this package's cached kernels when its sources changed
(numba alone would miss edits to inlined helpers; see ``simcore/_cache.py``).
"""
from pathlib import Path as _Path

from ._cache import refresh as _refresh_cache

_refresh_cache(_Path(__file__).parent)
from .params import InitParams, ModelParams, Preset, RunSettings, load_preset, preset_from_dict
from .schema import ConfigError
from .simulate import MODEL_VERSION, Observations, advance, simulate, simulate_batch, simulate_preset
from .state import State, initial_state

__all__ = ["ConfigError", "InitParams", "MODEL_VERSION", "ModelParams", "Observations", "Preset",
           "RunSettings", "State", "advance", "initial_state", "load_preset", "preset_from_dict",
           "simulate", "simulate_batch", "simulate_preset"]
