"""``flocksweep calibrate``: fit model parameters to target flock statistics."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.failures import check_out, check_workers

HELP = "fit model parameters to target flock statistics"
DESCRIPTION = ("Fit the free parameters of a calibration TOML with its method (--method picks another the file has "
               "settings for; the methods are listed under --method); writes the posterior or optimum, diagnostics, "
               "figures, the verdicts and the cost.")


def arguments(p) -> None:
    from flocksweep.analysis.calibration.methods import kinds   # the registered methods (light: no engine)

    p.add_argument("config", help="calibration TOML, e.g. configs/calibration/recover_holland.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the calibration file, e.g. --set method.steps=500 (a flat [method] "
                        "table) or --set method.emcee.steps=500 (a [method.emcee] table)")
    p.add_argument("--method", metavar="|".join(kinds()),
                   help="run this method with its [method.<name>] settings instead of the file's method.kind "
                        f"(registered: {', '.join(kinds())}); its outputs go to "
                        "results/calibration/<name>-<method> unless --out is given")
    p.add_argument("--out", type=Path, help="output directory (default results/calibration/<name>)")
    p.add_argument("--resume", action="store_true", help="continue the stored chain up to method.steps (the same "
                                                         "command without it does too)")
    p.add_argument("--yes", action="store_true", help="go ahead with a chain of more than 20,000,000 simulations")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--executor", choices=("serial", "local", "dask"), default="serial",
                   help="where simulations run: serial = this process, each evaluation's replicates on all "
                        "cores in one threaded compiled call (default); local = a "
                        "process pool evaluating walkers' proposals in parallel; dask = a cluster")
    p.add_argument("--workers", type=int, help="worker processes for local/dask (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDR", help="dask scheduler address; without it a LocalCluster starts")


def handler(args) -> int:
    from flocksweep.analysis.calibration.accounting import lines as cost_lines
    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.run import output_folder, resume_hint, run_calibration
    from flocksweep.sweeps.progress import next_steps

    check_workers(args.workers, args.executor)
    check_out("--out", args.out)
    if args.scheduler is not None and args.executor != "dask":
        raise ConfigError("--scheduler", "only used with --executor dask")
    config = load_calibration(args.config, args.overrides, args.method)
    command = f"{args.config} --method {args.method}" if args.method else args.config
    args.on_interrupt = lambda: stop_early_hint(lambda c, out: resume_hint(c, out, config), command,
                                                output_folder(config, args.out),
                                                _steps_key(args.config, config.method.kind))
    result = run_calibration(config, args.out, resume=args.resume, progress=not args.no_progress,
                             executor=args.executor, workers=args.workers, scheduler=args.scheduler,
                             yes=args.yes)
    if result.optimum:
        opt = result.optimum
        print("optimum: " + ", ".join(f"{k} = {v:.4g}" for k, v in opt["theta"].items()))
        se = float("nan") if opt["recheck_se"] is None else opt["recheck_se"]   # null: one batch
        print(f"  objective {opt['objective_common_seeds']:.4g} with the search's common seeds, "
              f"{opt['objective_recheck']:.4g} +- {se:.2g} re-checked with fresh seeds")
    elif result.summary is not None:
        print(result.summary.round(4).to_string())
    for message in result.verdicts(config):   # convergence, warnings, confirmation (failed too), truth
        print(f"  {message}")
    for line in cost_lines(result.report.get("accounting")):
        print(f"  {line}")
    print(f"  wrote {result.out} (report: {result.paths['html']})")
    next_steps(*after_calibrate(result, config))
    return 0


def after_calibrate(result, config) -> list[str]:
    """Open the report, the predictive page when there is one, and reuse a trained estimator."""
    out = Path(result.out)
    steps = [f"open {result.paths['html']} in a browser (verdicts first, then the posterior and its checks)"]
    predictive = out / "viewer_predictive.html"
    if predictive.exists():
        steps.append(f"open {predictive} in a browser (the measured flock beside a posterior predictive run)")
    if (out / "estimator").is_dir():
        summary = getattr(getattr(config, "method", None), "summary", None)
        given = "--tracks TRACKS" if getattr(summary, "learned", False) else "--targets FLOCKS.csv"
        flocks = len(config.targets.observed) if getattr(summary, "learned", False) else 1
        other = f"another {flocks} flocks in one file: one posterior given all of them" if flocks > 1 else "other flocks"
        steps.append(f"flocksweep posterior {out / 'estimator'} {given}   (the same estimator on {other}, no new "
                     "simulation)")
    return steps


def stop_early_hint(resume_hint, command: str, out: Path, steps_key: str = "method.steps") -> str:
    """What an interrupted calibration saved, how to resume it, and how to stop here with a report
    (docs/calibration.md, "Stopping early")."""
    from flocksweep.analysis.calibration.chainfile import stored_steps

    hint = resume_hint(command, out)
    steps = stored_steps(Path(out) / "chain.h5")
    if steps:
        hint += (f"\n  or stop here and still get a report from the {steps} saved steps: flocksweep calibrate "
                 f"{command} --out {out} --resume --set {steps_key}={steps}")
    return hint


def _steps_key(config_path, kind: str) -> str:
    """The --set key of the chain's length: method.<kind>.steps in a file with [method.<kind>] tables."""
    import tomllib

    try:
        method = tomllib.loads(Path(config_path).read_text()).get("method", {})
    except (OSError, UnicodeError, ValueError):
        method = {}
    return f"method.{kind}.steps" if isinstance(method.get(kind), dict) else "method.steps"


COMMAND = Command("calibrate", HELP, DESCRIPTION, arguments, handler)
