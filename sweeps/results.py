"""Loading a sweep's results directory into pandas, for reports, calibration and users.

``load_results(path, timeseries=False) -> Results`` with

* ``runs``: DataFrame, one row per run (``runs.parquet``; built from the parts if the sweep was
  interrupted before consolidating), in design order;
* ``factors``: the swept factor columns, in design order (an axis' name column, e.g. ``mode``, or its
  key, e.g. ``perception.field_deg``; zipped keys and the keys of a ``[sample]`` or ``[design]`` block
  are factors too), only those with more than one level;
* ``metrics``: the summary metric columns (``<metric>_mean``, ``<metric>_final``,
  ``time_to_fragmentation``, ``fragmented``);
* ``manifest``: the provenance stamp (dict), ``design``: ``design.parquet``, ``sweep``: the sweep file's
  parsed effective configuration (dict);
* ``timeseries``: DataFrame (run_id, t, metrics...) when requested, else None.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.observables.summary import ENCOUNTER_FAMILIES, summary_columns
from simcore.params import canonical_key

from .store import ResultsStore


@dataclass
class Results:
    path: Path
    runs: pd.DataFrame
    factors: list[str]
    metrics: list[str]
    manifest: dict
    design: pd.DataFrame
    sweep: dict
    timeseries: pd.DataFrame | None = None

    @property
    def name(self) -> str:
        return self.manifest.get("sweep", self.path.name)

    @property
    def ok(self) -> pd.DataFrame:
        return self.runs[self.runs["status"] == "ok"]

    def levels(self, factor: str) -> list:
        return sorted(self.runs[factor].dropna().unique(), key=_level_key)


def _level_key(value):
    numeric = isinstance(value, (int, float, np.number)) and not isinstance(value, (bool, np.bool_))
    return (0, float(value), "") if numeric else (1, 0.0, str(value))


def swept_columns(design: pd.DataFrame, sweep: dict) -> list[str]:
    """Factor columns in design order: for each axis its name column (and its keys when they are the
    only columns), then the keys of the sampled block ([sample] or [design])."""
    columns = []
    for axis in sweep.get("axes", []):
        keys = [axis["key"]] if "key" in axis else list(axis.get("keys", []))
        keys = [canonical_key(k) for k in keys]
        name = axis.get("name", keys[0] if len(keys) == 1 else "+".join(keys))
        columns.append(name if name in design.columns else keys[0])
    for block in ("sample", "design"):
        columns += [canonical_key(key) for key in sweep.get(block, {}).get("bounds", {})]
    return [c for c in columns if c in design.columns and design[c].nunique() > 1]


def metric_columns(runs: pd.DataFrame) -> list[str]:
    """The summary columns (analysis.observables.summary.summary_columns) the runs table holds."""
    known = set(summary_columns(leadership=True, encounters=ENCOUNTER_FAMILIES, migration=True))
    return [c for c in runs.columns if c in known]


def load_results(path, timeseries: bool = False) -> Results:
    path = Path(path)
    store = ResultsStore(path)
    design = store.design()
    if design is None:
        raise FileNotFoundError(f"{path}: not a sweep results directory (design.parquet missing)")
    runs = store.runs()
    if "index" in runs:
        runs = runs.sort_values("index", kind="stable").reset_index(drop=True)
    sweep = store.read_json("sweep.effective.json", {})
    factors = swept_columns(design, sweep)
    return Results(path=path, runs=runs, factors=factors, metrics=metric_columns(runs),
                   manifest=store.manifest(), design=design, sweep=sweep,
                   timeseries=store.timeseries() if timeseries else None)
