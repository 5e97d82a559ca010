"""``flocksweep compare FILE``: which of several models best explains the targets
(:mod:`analysis.calibration.compare`), the command's work, ``run(args)``,
for its declaration in ``flocksweep/commands/compare.py``.
"""
from __future__ import annotations


from flocksweep.sweeps.failures import check_out, check_workers
from flocksweep.sweeps.progress import next_steps


def run(args) -> int:
    from .compare import load_comparison, run_comparison

    check_out("--out", args.out)
    if args.workers is not None:
        check_workers(args.workers, args.executor)
    comparison = load_comparison(args.config, args.overrides, yes=args.yes)
    result = run_comparison(comparison, args.out, args.executor, args.workers, args.scheduler,
                            progress=not args.no_progress)
    for line in result["messages"]:
        print(line)
    print(f"wrote {result['folder']} (report: {result['folder'] / 'report.md'})")
    next_steps(f"open {result['folder'] / 'report.md'}   (which model, how sure, and the confusion matrix)",
               "flocksweep calibrate CALIBRATION.toml   (the chosen model's own calibration file, named in "
               f"{args.config})")
    return 0
