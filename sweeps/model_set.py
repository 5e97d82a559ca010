"""How ``[model] set`` and ``--set model.<key>`` change a preset: one key at a time, merged into its table.

* ``flat_changes(table) -> {dotted key: value}``: a ``set`` table with nested tables turned into dotted
  keys, so ``set = { perception = { range = 30 } }`` (or ``set.perception.range = 30``, or ``--set
  model.set.perception.range=30``) changes ``perception.range`` and keeps the preset's other
  ``[perception]`` keys, exactly as ``set = { "perception.range" = 30 }`` does. A whole table is never
  replaced this way (lists, like ``patterns.set``, are values).
* ``model_overrides(overrides) -> list[str]``: ``--set`` items with ``model.<preset key>=v`` (a key whose
  first part is a preset table or ``n``) spelled ``model.set.<preset key>=v``; other items as given.
  Used by sweep and calibration files alike (their ``[model]`` is the same table).
"""
from __future__ import annotations

import dataclasses

from flocksweep.simcore.params import KEY_ALIASES, ModelParams

PRESET_TABLES = frozenset({f.name for f in dataclasses.fields(ModelParams)} | {"init", "run"} | set(KEY_ALIASES))


def model_overrides(overrides) -> list[str]:
    """``--set`` items with ``model.<preset key>=v`` spelled ``model.set.<preset key>=v`` (other items as
    given): both change one key of the preset."""
    out = []
    for item in overrides or ():
        key = item.split("=", 1)[0].strip()
        parts = key.split(".")
        if len(parts) >= 2 and parts[0] == "model" and parts[1] in PRESET_TABLES and "=" in item:
            item = "model.set." + ".".join(parts[1:]) + "=" + item.split("=", 1)[1]
        out.append(item)
    return out


def flat_changes(table: dict, prefix: str = "") -> dict:
    """``model.set`` as {dotted key: value}: nested tables become dotted keys (so they merge)."""
    out = {}
    for key, value in table.items():
        dotted = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict) and value:
            out.update(flat_changes(value, dotted))
        else:
            out[dotted] = value
    return out
