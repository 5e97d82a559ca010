"""``flocksweep compile``: compile the simulation and metric kernels now, into numba's cache.

The options and the handler; the work is :mod:`flocksweep.sweeps.compile_command`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "compile the simulation and metric kernels now, into numba's cache"
DESCRIPTION = ("Compile every kernel the models need (default: every preset of configs/models) into numba's "
               "on-disk cache, several model families at once, so that processes starting together (a sweep's "
               "workers, a test run split over workers, cluster jobs on one file system) load them instead of "
               "each compiling its own. Kernels already cached are loaded, not compiled again.")


def arguments(parser) -> None:
    """``flocksweep compile``'s arguments."""
    parser.add_argument("models", nargs="*", type=Path, help="model preset TOMLs (default: every shipped preset)")
    parser.add_argument("--jobs", type=int, help="processes compiling at once (default: all cores)")


def handler(args) -> int:
    from flocksweep.sweeps.compile_command import run
    from flocksweep.sweeps.progress import next_steps

    code = run(args)
    if code == 0:
        first = args.models[0] if args.models else "configs/models/holland.toml"
        next_steps(f"flocksweep simulate {first}   (a run of a compiled model starts at once now)",
                   "flocksweep run configs/sweeps/smoke.toml   (a first sweep)")
    return code


COMMAND = Command("compile", HELP, DESCRIPTION, arguments, handler)
