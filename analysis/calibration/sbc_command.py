"""``flocksweep sbc``: simulation-based calibration (Talts et al. 2018) of a calibration file's emcee posterior,
as a command module of the CLI (``DESCRIPTION``, ``add_arguments(parser)``, ``run(args)``; see
``flocksweep/cli.py``, ``DELEGATED``). The work itself is :func:`analysis.calibration.sbc.run_sbc`.
"""
from __future__ import annotations

from pathlib import Path

from simcore.schema import ConfigError
from sweeps.failures import check_count, check_out, check_workers

DESCRIPTION = ("Talts et al. (2018): draw parameters from the prior, simulate a dataset at each, fit it with the "
               "file's emcee settings and test the ranks of the truths for uniformity. Finished datasets are "
               "kept: re-running resumes.")


def add_arguments(p) -> None:
    """The command's arguments on its sub-parser ``p``."""
    p.add_argument("config", help="calibration TOML with method.kind = \"emcee\", e.g. configs/calibration/sbc_range.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the calibration file")
    p.add_argument("--datasets", type=int, default=50, help="synthetic datasets L (default 50)")
    p.add_argument("--draws", type=int, default=49, help="posterior draws per dataset S (default 49)")
    p.add_argument("--workers", type=int, default=1, help="datasets fitted at once in worker processes")
    p.add_argument("--steps", type=int, help="chain length per dataset (default: method.steps)")
    p.add_argument("--walkers", type=int, help="walkers per dataset (default: method.walkers)")
    p.add_argument("--out", type=Path, help="output directory (default results/calibration/<name>/sbc)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args) -> int:
    """Run the SBC check the arguments describe; prints the rank table and the verdict."""
    from .config import load_calibration
    from .sbc import run_sbc

    for flag, value in (("--datasets", args.datasets), ("--draws", args.draws), ("--steps", args.steps)):
        check_count(flag, value, 1)
    check_workers(args.workers, "local")
    check_count("--walkers", args.walkers, 2)
    check_out("--out", args.out)
    config = load_calibration(args.config, args.overrides)
    if config.method.kind != "emcee":
        raise ConfigError("method.kind", f"got {config.method.kind!r}; SBC checks the emcee (BSL) posterior")
    out = args.out or Path("results") / "calibration" / config.name / "sbc"
    args.on_interrupt = lambda: (f"saved: {len(list((out / 'datasets').glob('*.json')))} datasets in {out}; "
                                 "run the same command again to resume")
    result = run_sbc(config, datasets=args.datasets, draws=args.draws, out_dir=args.out,
                     progress=not args.no_progress, steps=args.steps, walkers=args.walkers, workers=args.workers)
    print(result["table"].round(4).to_string())
    print(f"  {result['verdict']}")
    print(f"  wrote {result['out']}")
    return 0
