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
    p.add_argument("--targets", type=Path,
                   help="CSV or Parquet: one row per observed flock, a column per statistic of the estimator (e.g. the "
                        "runs.parquet of flocksweep measure, checked against how the estimator's statistics are "
                        "measured)")
    p.add_argument("--tracks", type=Path,
                   help="instead of --targets: a track file, measured here as the estimator's statistics are "
                        "(interval, velocities, group radius; read as its sidecar JSON says)")
    p.add_argument("--force", action="store_true",
                   help="give the posteriors of an estimator that failed its coverage check, each row marked "
                        "credible = false")
    p.add_argument("--draws", type=int, default=4000, help="posterior draws per flock (default 4000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the draws (default 0)")
    p.add_argument("--out", type=Path, help="write the table here (CSV; default: print it)")


def handler(args) -> int:
    from flocksweep.analysis.calibration.posterior_command import run

    return run(args)


COMMAND = Command("posterior", HELP, DESCRIPTION, arguments, handler)
