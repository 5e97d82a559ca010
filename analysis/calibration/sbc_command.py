"""``flocksweep sbc``: simulation-based calibration (Talts et al. 2018) of a calibration file's method (emcee's
BSL posterior, npe's amortised estimator: the methods whose object has ``sbc = True``), the command's work,
``run(args)``, for its declaration in ``flocksweep/commands/sbc.py``. The work itself is
:func:`analysis.calibration.methods.run_sbc`, which runs the method object's ``run_sbc``.
"""
from __future__ import annotations

from pathlib import Path

from flocksweep.sweeps.failures import check_count, check_out, check_workers
from flocksweep.sweeps.progress import next_steps


def run(args) -> int:
    """Run the SBC check the arguments describe; prints the rank table and the verdict."""
    from .config import load_calibration
    from .methods import check_sbc, run_sbc

    for flag, value in (("--datasets", args.datasets), ("--draws", args.draws), ("--steps", args.steps)):
        check_count(flag, value, 1)
    check_workers(args.workers, "local")
    check_count("--walkers", args.walkers, 2)
    check_out("--out", args.out)
    config = load_calibration(args.config, args.overrides)
    check_sbc(config)
    out = args.out or Path("results") / "calibration" / config.name / "sbc"
    args.on_interrupt = lambda: (f"saved: {len(list((out / 'datasets').glob('*.json')))} datasets in {out}; "
                                 "run the same command again to resume")
    result = run_sbc(config, datasets=args.datasets, draws=args.draws, out_dir=args.out,
                     progress=not args.no_progress, steps=args.steps, walkers=args.walkers, workers=args.workers)
    print(result["table"].round(4).to_string())
    print(f"  {result['verdict']}")
    print(f"  wrote {result['out']}")
    next_steps(f"open {Path(result['out']) / 'rank_histogram.png'} and {Path(result['out']) / 'ecdf_diff.png'}   "
               "(flat ranks, a curve inside its band: the posterior is calibrated; docs/calibration/sbc.md)")
    return 0
