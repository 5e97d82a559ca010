"""A sweep written back as a TOML file: what a sweep built in Python stores as ``sweep.toml``.

``sweep_toml(config) -> str`` writes the sweep's tables as given (``config.source``, the dict it was
built from, with ``--set`` overrides and ``replicates`` applied) so that
``SweepConfig.from_toml`` of the text gives the same sweep: the same design and run ids. Two things
change so the file runs from any folder: ``model.preset`` becomes the absolute path of the preset that
was read, and ``include_claims`` are written out as ``[[claims]]`` tables (as in
``sweep.effective.json``). Values TOML cannot hold (``None``, objects) raise
:class:`~simcore.schema.ConfigError` naming the dotted key. The writer is ``tomli_w``.
"""
from __future__ import annotations

import math
from pathlib import PurePath

import numpy as np
import tomli_w

from simcore.schema import ConfigError

from .claims import with_claims

HEADER = "# The sweep as run, written by flocksweep (sweeps/sweep_toml.py); reads back as the same sweep.\n"


def toml_value(value, key: str):
    """``value`` as a type TOML holds (numpy scalars and arrays, tuples and paths converted)."""
    if isinstance(value, dict):
        return {str(k): toml_value(v, f"{key}.{k}" if key else str(k)) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [toml_value(v, f"{key}[{i}]") for i, v in enumerate(list(value))]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return value   # TOML has nan and inf; the schema decides whether they are allowed
    if value is None or not isinstance(value, (bool, int, float, str)):
        raise ConfigError(key, f"got {value!r}; a sweep file holds only numbers, booleans, strings, lists "
                               "and tables")
    return value


def sweep_toml(config) -> str:
    """TOML text of the sweep ``config`` (a :class:`sweeps.config.SweepConfig`); see the module docstring."""
    data = with_claims({**config.source, "replicates": config.replicates}, config.claims)
    data["model"] = {**data.get("model", {}), "preset": str(config.preset_path)}
    return HEADER + tomli_w.dumps(toml_value(data, ""))
