"""``flocksweep export``: a sweep's results as plain tables for other tools (R, spreadsheets, NetLogo-style
BehaviorSpace users).

    flocksweep export RESULTS (--csv | --parquet) [--with-fixed] [--timeseries] [--out DIR]

``export_results(results_dir, fmt, out_dir=None, with_fixed=False, timeseries=False) -> dict`` writes

* ``runs.csv`` / ``runs.parquet``: :func:`sweeps.results.load_results` ``.runs``, one row per run in design
  order (run_id, index, replicate, seed, the factors, status, error, every summary metric); with
  ``with_fixed`` also one column per fixed setting (dotted preset keys such as ``perception.range``,
  ``analysis.warmup``), so each row says everything the run was;
* with ``timeseries``: ``timeseries.csv`` / ``.parquet``, the metric time series in long format (run_id,
  t, one column per metric) of every ok run, in design order then time, streamed from the lazy dataset
  :data:`CHUNK_RUNS` runs at a time (never the whole sweep in memory); join it to the runs table on
  ``run_id``.

Files go to ``RESULTS/export/`` unless ``out_dir``; each is written atomically (:mod:`sweeps.files`).
The runs table alone (no ``timeseries``) of a folder whose files are all as flocksweep wrote them (their
checksums say so) is written without pandas, byte for byte the same (:mod:`sweeps.quick_export`); every
other export loads the results with :func:`sweeps.results.load_results` (:func:`export_with_pandas`),
verifying and warning as it does.
CSV: comma-separated, a header row, missing values (NaN, a failed run's metrics) as empty fields,
booleans as ``True``/``False``. ``flocksweep export`` (declared in ``flocksweep/commands/export.py``) calls :func:`run`.
"""
from __future__ import annotations

from pathlib import Path

from .files import atomic_path, write_csv, write_parquet
from .quick_export import runs_csv, runs_parquet

CHUNK_RUNS = 1000   # runs whose time series are read, sorted and written together
FORMATS = ("csv", "parquet")

def export_results(results_dir, fmt: str, out_dir=None, with_fixed: bool = False,
                   timeseries: bool = False) -> dict:
    """Write the tables of the module docstring; returns {"runs": (path, rows, columns), "timeseries": ...}."""
    if fmt not in FORMATS:
        raise ValueError(f"fmt: got {fmt!r}; expected one of {FORMATS}")
    out = Path(out_dir) if out_dir is not None else Path(results_dir) / "export"
    if not timeseries:
        written = (runs_csv if fmt == "csv" else runs_parquet)(results_dir, out / f"runs.{fmt}", with_fixed)
        if written is not None:
            return {"runs": written}
    return export_with_pandas(results_dir, fmt, out, with_fixed, timeseries)


def export_with_pandas(results_dir, fmt: str, out: Path, with_fixed: bool, timeseries: bool) -> dict:
    """:func:`export_results` by way of :func:`sweeps.results.load_results` (every export but the quick one)."""
    from .results import load_results   # pandas and pyarrow: loaded when exporting, not for --help

    results = load_results(results_dir, with_fixed=with_fixed, timeseries=timeseries)
    runs = results.runs.drop(columns=["part"], errors="ignore")
    path = out / f"runs.{fmt}"
    if fmt == "csv":
        write_csv(path, runs, index=False)
    else:
        write_parquet(path, runs)
    written = {"runs": (path, len(runs), runs.shape[1])}
    if timeseries:
        written["timeseries"] = _write_series(results, out / f"timeseries.{fmt}", fmt)
    return written


def _series_chunks(results):
    """The ok runs' series as Arrow tables, CHUNK_RUNS runs at a time, sorted by design order and time."""
    import pyarrow as pa
    import pyarrow.dataset as ds

    ok = results.ok
    order = {run_id: k for k, run_id in enumerate(ok["run_id"])}
    ids = list(ok["run_id"])
    for start in range(0, len(ids), CHUNK_RUNS):
        chunk = ids[start:start + CHUNK_RUNS]
        table = results.timeseries.to_table(filter=ds.field("run_id").isin(chunk))
        table = table.drop_columns([c for c in ("part",) if c in table.column_names])
        position = pa.array([order[r] for r in table.column("run_id").to_pylist()], pa.int64())
        table = table.append_column("__order", position).sort_by([("__order", "ascending"), ("t", "ascending")])
        yield table.drop_columns(["__order"])


def _write_series(results, path: Path, fmt: str) -> tuple[Path, int, int]:
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    schema = results.timeseries.schema
    schema = schema.remove(schema.get_field_index("part")) if "part" in schema.names else schema
    rows = 0
    with atomic_path(path) as tmp:
        writer = (pacsv.CSVWriter(tmp, schema, write_options=pacsv.WriteOptions(quoting_style="needed"))
                  if fmt == "csv" else pq.ParquetWriter(tmp, schema))
        try:
            for table in _series_chunks(results):
                writer.write_table(table.select(schema.names).cast(schema))
                rows += table.num_rows
        finally:
            writer.close()
    return path, rows, len(schema.names)



def run(args) -> int:
    """The command: exit status 0, or 2 when ``args.dir`` is not a sweep's results directory."""
    import sys

    from .failures import check_out

    check_out("--out", args.out)
    try:
        written = export_results(args.dir, args.format, args.out, args.with_fixed, args.timeseries)
    except FileNotFoundError as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    for path, rows, columns in written.values():
        print(f"  wrote {path} ({rows:,} rows, {columns} columns)")
    return 0
