"""The settings a sweep did not vary, as ``{dotted name: value}``: the ``--with-fixed`` columns.

``fixed_settings(model)`` takes the parsed ``model.json`` of a results folder
(:meth:`sweeps.store.ResultsStore.model`) and returns every key of the base preset's canonical
resolved form (:meth:`simcore.Preset.to_dict`, defaults filled in) by its dotted name
(``perception.range``, ``init.n``, ``run.dt``; a list such as ``patterns.set`` as JSON text) that was not
swept, and the analysis settings as ``analysis.<name>``. A stored preset that no longer validates (e.g.
an ``init.from_file`` that moved since) gives its stored keys, without defaults. Imports neither pandas
nor pyarrow (:func:`sweeps.results.load_results` and ``flocksweep export``'s quick path use it).
"""
from __future__ import annotations

import json

from flocksweep.simcore.params import canonical_key, preset_from_dict
from flocksweep.simcore.schema import ConfigError


def flat_settings(table: dict, prefix: str = "") -> dict:
    """A nested settings dict as {dotted name: value}; lists become JSON text (one cell per setting)."""
    out = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flat_settings(value, f"{name}."))
        else:
            out[name] = json.dumps(value) if isinstance(value, (list, tuple)) else value
    return out


def fixed_settings(model: dict) -> dict:
    """{dotted key: value} of every setting the sweep did not vary (see the module docstring)."""
    if not model.get("preset"):
        return {}
    swept = {canonical_key(k) for k in model.get("swept_keys", [])}
    try:
        preset = flat_settings(preset_from_dict(model["preset"]).to_dict())
    except ConfigError:   # e.g. an init.from_file that moved since: the stored keys, without defaults
        preset = flat_settings(model["preset"])
    fixed = {k: v for k, v in preset.items() if k not in swept and not any(k.startswith(f"{s}.") for s in swept)}
    fixed.update(flat_settings(model.get("analysis", {}), "analysis."))
    return fixed
