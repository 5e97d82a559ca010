"""``flocksweep sbc``: simulation-based calibration check of a calibration's posterior.

The options and the handler; the work is :mod:`flocksweep.analysis.calibration.sbc_command`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "simulation-based calibration check of a calibration's posterior"
DESCRIPTION = ("Talts et al. (2018): draw parameters from the prior, simulate a dataset at each, fit it with the "
               "file's method (emcee: a BSL chain per dataset; emulator: its chain on the surrogate per dataset; npe: "
               "the amortised estimator, trained once) and "
               "test the ranks of the truths for uniformity. Finished datasets are kept: re-running resumes.")


def arguments(p) -> None:
    """The command's arguments on its sub-parser ``p``."""
    p.add_argument("config", help="calibration TOML with method.kind = \"emcee\", \"emulator\" or \"npe\", e.g. "
                                     "configs/calibration/sbc_range.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the calibration file")
    p.add_argument("--datasets", type=int, default=50, help="synthetic datasets L (default 50)")
    p.add_argument("--draws", type=int, default=49, help="posterior draws per dataset S (default 49)")
    p.add_argument("--workers", type=int, default=1, help="datasets fitted (emcee) or simulated (npe) at once in worker processes")
    p.add_argument("--steps", type=int, help="chain length per dataset (emcee, emulator; default: method.steps)")
    p.add_argument("--walkers", type=int, help="walkers per dataset (emcee, emulator; default: method.walkers)")
    p.add_argument("--out", type=Path, help="output directory (default results/calibration/<name>/sbc)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def handler(args) -> int:
    from flocksweep.analysis.calibration.sbc_command import run

    return run(args)


COMMAND = Command("sbc", HELP, DESCRIPTION, arguments, handler)
