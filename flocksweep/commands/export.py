"""``flocksweep export``: a sweep's runs (and time series) as CSV or Parquet.

The options and the handler; the work is :mod:`flocksweep.sweeps.export`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "a sweep's runs (and time series) as CSV or Parquet"
DESCRIPTION = ("Write a sweep's runs table (one row per run; with --with-fixed every fixed setting as a column) "
               "and optionally its metric time series (long format) as CSV or Parquet, for R, spreadsheets "
               "and other tools.")


def arguments(p) -> None:
    p.add_argument("dir", type=Path, help="results directory of a sweep (the --out of flocksweep run)")
    kind = p.add_mutually_exclusive_group(required=True)
    kind.add_argument("--csv", dest="format", action="store_const", const="csv", help="write CSV files")
    kind.add_argument("--parquet", dest="format", action="store_const", const="parquet", help="write Parquet files")
    p.add_argument("--with-fixed", action="store_true",
                   help="add every fixed (not swept) setting as a column of the runs table (dotted preset keys, "
                        "analysis.<setting>)")
    p.add_argument("--timeseries", action="store_true",
                   help="also write the metric time series of every ok run (long format: run_id, t, metrics)")
    p.add_argument("--out", type=Path, help="output folder (default RESULTS/export)")


def handler(args) -> int:
    from flocksweep.sweeps.export import run
    from flocksweep.sweeps.progress import next_steps

    code = run(args)
    if code == 0:
        runs = (args.out or Path(args.dir) / "export") / f"runs.{args.format}"
        read = f'pandas.read_csv("{runs}")' if args.format == "csv" else f'pandas.read_parquet("{runs}")'
        r_read = f'read.csv("{runs}")' if args.format == "csv" else f'arrow::read_parquet("{runs}")'
        next_steps(f"{read} in Python, {r_read} in R   (one row per run)",
                   f"flocksweep report {args.dir}   (statistics and figures, made for you)")
    return code


COMMAND = Command("export", HELP, DESCRIPTION, arguments, handler)
