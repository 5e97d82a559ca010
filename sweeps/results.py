"""Loading a sweep's results directory into pandas, for reports, calibration and users.

``load_results(path, with_fixed=False, timeseries=False) -> Results`` with

* ``runs``: DataFrame, one row per run (``runs.parquet``; built from the parts if the sweep was
  interrupted before consolidating), in design order; with ``with_fixed`` also one column per fixed
  (not swept) setting: every key of the base preset's canonical resolved form
  (:meth:`simcore.Preset.to_dict`, defaults filled in) by its dotted name (``perception.range``,
  ``init.n``, ``run.dt``; a list such as ``patterns.set`` as JSON text) and the analysis settings as
  ``analysis.<name>`` (``analysis.warmup``, ...). A column the table already has is not replaced;
* ``factors``: the swept factor columns, in design order (an axis' name column, e.g. ``mode``, or its
  key, e.g. ``perception.field_deg``; zipped keys and the keys of a ``[sample]`` or ``[design]`` block
  are factors too), only those with more than one level;
* ``metrics``: the summary metric columns (``<metric>_mean``, ``<metric>_final``,
  ``time_to_fragmentation``, ``fragmented``);
* ``fixed``: the fixed columns added by ``with_fixed`` (empty without it);
* ``manifest``: the provenance stamp (dict), ``design``: ``design.parquet``, ``sweep``: the sweep file's
  parsed effective configuration (dict);
* ``timeseries``: with ``timeseries=True`` a lazy ``pyarrow.dataset.Dataset`` of the series (run_id, t,
  metrics...) of exactly the ok runs of ``runs``, each run once (a run computed again appears in a later
  part; only the part its row comes from is read), nothing loaded until asked
  (``results.timeseries.to_table(filter=...)``, ``.to_batches()``, ``.to_table().to_pandas()``);
  else None. :meth:`Results.series` reads the series of some runs into a DataFrame.

Every part read is verified against the checksum recorded when it was written (:mod:`sweeps.store`): a
changed runs part or ``runs.parquet`` is left out with a warning naming the file (its runs count as
missing until ``flocksweep run`` recomputes them), a changed time series part likewise.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds
import pyarrow.fs

from flocksweep.observables.columns import FAMILIES, summary_columns   # the names only: no kernels, no numba
from flocksweep.simcore.params import canonical_key

from .fixed_settings import fixed_settings, flat_settings  # noqa: F401 - also read from here
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
    timeseries: ds.Dataset | None = None
    fixed: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.manifest.get("sweep", self.path.name)

    @property
    def ok(self) -> pd.DataFrame:
        return self.runs[self.runs["status"] == "ok"]

    def levels(self, factor: str) -> list:
        return sorted(self.runs[factor].dropna().unique(), key=_level_key)

    def series(self, run_ids=None, columns: list[str] | None = None) -> pd.DataFrame:
        """The time series of ``run_ids`` (default: every ok run), ``columns`` of them (default all), as a
        DataFrame sorted by run and time; reads only what is asked from the lazy dataset."""
        dataset = self.timeseries if self.timeseries is not None else series_dataset(ResultsStore(self.path),
                                                                                     self.runs)
        where = None if run_ids is None else ds.field("run_id").isin(list(run_ids))
        frame = dataset.to_table(columns=columns, filter=where).to_pandas()
        keys = [c for c in ("run_id", "t") if c in frame]
        return frame.sort_values(keys, kind="stable").reset_index(drop=True) if keys else frame


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
    """The summary columns (observables.summary.summary_columns) the runs table holds."""
    known = set(summary_columns(leadership=True, encounters=tuple(FAMILIES), migration=True, dcd=True, walls=True))
    return [c for c in runs.columns if c in known]


def series_dataset(store: ResultsStore, runs: pd.DataFrame) -> ds.Dataset:
    """Lazy dataset of the time series of the ok runs of ``runs``, each read from the part its row is in
    (a run computed again also has rows in an earlier part; those are filtered out). Each file is a
    fragment whose ``part`` column is its part number, so the filter reduces to one run id set per file."""
    ok = runs[runs["status"] == "ok"] if len(runs) else runs
    paths, numbers, keep = [], [], None
    for part, group in ok.groupby("part"):
        path = store.root / "timeseries" / f"part-{int(part):06d}.parquet"
        if not path.exists() or not store.series_intact(path):
            continue
        paths.append(str(path))
        numbers.append(int(part))
        mine = (ds.field("part") == int(part)) & ds.field("run_id").isin(list(group["run_id"]))
        keep = mine if keep is None else keep | mine
    if not paths:
        return ds.dataset(pa.table({"run_id": pa.array([], pa.string()), "t": pa.array([], pa.float64()),
                                    "part": pa.array([], pa.int64())}))
    schema = pa.unify_schemas([ds.dataset(p, format="parquet").schema for p in paths] +
                              [pa.schema([("part", pa.int64())])])
    dataset = ds.FileSystemDataset.from_paths(paths, schema=schema, format=ds.ParquetFileFormat(),
                                              filesystem=pyarrow.fs.LocalFileSystem(),
                                              partitions=[ds.field("part") == n for n in numbers])
    return dataset.filter(keep)


def load_results(path: str | Path, with_fixed: bool = False, timeseries: bool = False) -> Results:
    """A sweep's results directory, loaded (see the module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        The results directory of a sweep (the ``--out`` of ``flocksweep run``).
    with_fixed : bool, default False
        Add one column per fixed (not swept) setting to ``runs``, named by its dotted key.
    timeseries : bool, default False
        Open the per-run metric time series as a lazy ``pyarrow.dataset.Dataset`` (``Results.timeseries``).

    Returns
    -------
    Results
        ``runs`` (one row per run), ``factors``, ``metrics``, ``fixed``, ``manifest``, ``design``,
        ``sweep`` and ``timeseries``.

    Raises
    ------
    FileNotFoundError
        When ``path`` is not a sweep results directory.
    """
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
    metrics = metric_columns(runs)
    fixed = []
    if with_fixed:
        settings = {k: v for k, v in fixed_settings(store.model()).items() if k not in runs.columns}
        runs = pd.concat([runs, pd.DataFrame({k: [v] * len(runs) for k, v in settings.items()},
                                             index=runs.index)], axis=1)
        fixed = list(settings)
    return Results(path=path, runs=runs, factors=factors, metrics=metrics, manifest=store.manifest(),
                   design=design, sweep=sweep, fixed=fixed,
                   timeseries=series_dataset(store, runs) if timeseries else None)
