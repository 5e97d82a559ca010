"""``flocksweep posterior``: one posterior per observed flock from a trained npe estimator (no simulation).

The options and the handler; the work is :mod:`flocksweep.analysis.calibration.posterior_command`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "one posterior per observed flock from a trained npe estimator (no simulation)"
DESCRIPTION = ("Amortised inference: the estimator a `flocksweep calibrate` run of method npe trained (its "
               "estimator/ folder) gives the posterior of every row of a table of observed flocks (one row "
               "per flock or flight, a column per statistic) in seconds, without simulating.")


def arguments(p) -> None:
    p.add_argument("estimator", type=Path, help="a trained estimator folder, e.g. results/calibration/NAME/estimator")
    p.add_argument("--targets", type=Path, required=True,
                   help="CSV or Parquet: one row per observed flock, a column per statistic of the estimator")
    p.add_argument("--draws", type=int, default=4000, help="posterior draws per flock (default 4000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the draws (default 0)")
    p.add_argument("--out", type=Path, help="write the table here (CSV; default: print it)")


def handler(args) -> int:
    from flocksweep.analysis.calibration.posterior_command import run

    return run(args)


COMMAND = Command("posterior", HELP, DESCRIPTION, arguments, handler)
