"""``flocksweep compare``: which of several models explains the targets: classifier, model probabilities, confusion.

The options and the handler; the work is :mod:`flocksweep.analysis.calibration.compare_command`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "which of several models explains the targets: classifier, model probabilities, confusion"
DESCRIPTION = ("Model comparison: simulate every model of a comparison file from its priors (as sweeps), train a "
               "classifier on the statistics, and give the targets' posterior model probabilities with the "
               "classifier's confusion matrix on held-out simulations. Finished runs are kept: re-running resumes.")


def arguments(p) -> None:
    p.add_argument("config", help="comparison TOML, e.g. configs/compare/perception.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the comparison file (e.g. simulations=500)")
    p.add_argument("--out", type=Path, help="output directory (default results/calibration/<name>)")
    p.add_argument("--executor", choices=("local", "dask"), default="local", help="where the simulations run")
    p.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    p.add_argument("--scheduler", help="dask scheduler address (with --executor dask)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--yes", action="store_true",
                   help="go ahead with more than 20,000,000 simulations in all (refused otherwise, before anything runs)")


def handler(args) -> int:
    from flocksweep.analysis.calibration.compare_command import run

    return run(args)


COMMAND = Command("compare", HELP, DESCRIPTION, arguments, handler)
