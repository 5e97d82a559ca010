"""``flocksweep compare FILE``: which of several models best explains the targets
(:mod:`analysis.calibration.compare`), as a command module of the CLI (``DESCRIPTION``,
``add_arguments(parser)``, ``run(args)``; see ``flocksweep/cli.py``, ``DELEGATED``).
"""
from __future__ import annotations

from pathlib import Path

from sweeps.failures import check_out, check_workers

DESCRIPTION = ("Model comparison: simulate every model of a comparison file from its priors (as sweeps), train a "
               "classifier on the statistics, and give the targets' posterior model probabilities with the "
               "classifier's confusion matrix on held-out simulations. Finished runs are kept: re-running resumes.")


def add_arguments(p) -> None:
    p.add_argument("config", help="comparison TOML, e.g. configs/compare/perception.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the comparison file (e.g. simulations=500)")
    p.add_argument("--out", type=Path, help="output directory (default results/calibration/<name>)")
    p.add_argument("--executor", choices=("local", "dask"), default="local", help="where the simulations run")
    p.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    p.add_argument("--scheduler", help="dask scheduler address (with --executor dask)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args) -> int:
    from .compare import load_comparison, run_comparison

    check_out("--out", args.out)
    if args.workers is not None:
        check_workers(args.workers, args.executor)
    comparison = load_comparison(args.config, args.overrides)
    result = run_comparison(comparison, args.out, args.executor, args.workers, args.scheduler,
                            progress=not args.no_progress)
    for line in result["messages"]:
        print(line)
    print(f"wrote {result['folder']} (report: {result['folder'] / 'report.md'})")
    return 0
