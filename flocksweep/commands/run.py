"""``flocksweep run``: run (or resume) a sweep from a sweep TOML or --model with --axis."""
from __future__ import annotations

import os
import sys
from contextlib import nullcontext
from pathlib import Path

from flocksweep.command import Command
from flocksweep.simcore.schema import ConfigError, suggest
from flocksweep.sweeps.failures import INCOMPLETE, check_workers

HELP = "run (or resume) a sweep from a sweep TOML or --model with --axis"
DESCRIPTION = ("Run a parameter sweep. Finished runs are skipped (resume); results go to results/<sweep name>/ "
               "unless --out is given. --model MODEL.toml --axis KEY=VALUES ... instead of a file builds the sweep a"
               " file would and stores it, resolved, as RESULTS/sweep.toml (rerun that file to reproduce it).")


def arguments(p) -> None:
    p.add_argument("sweep", nargs="?", help="sweep TOML, e.g. configs/sweeps/holland648.toml")
    p.add_argument("--model", help="instead of a sweep file: a model preset TOML, e.g. configs/models/holland.toml")
    p.add_argument("--axis", action="append", default=[], metavar="KEY=VALUES",
                   help="with --model, one axis of the grid (repeatable): KEY=V1,V2,... or "
                        "KEY=linspace(START,STOP,NUM) or KEY=range(START,STOP,STEP), e.g. "
                        "--axis perception.field_deg=30,90,180 --axis init.n=20,50")
    p.add_argument("--name", help="with --model: the sweep's name (default <model>_<axis keys>)")
    p.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    p.add_argument("--executor", choices=("serial", "local", "dask", "cluster"), default="local",
                   help="local process pool (default), serial in this process, dask, or cluster: batch jobs "
                        "on a SLURM/PBS/SGE/LSF cluster as the sweep's [cluster] table (or --set "
                        "cluster.KEY=VALUE) declares them (docs/sweeps.md, On a cluster)")
    p.add_argument("--scheduler", metavar="ADDR", help="dask scheduler address; without it a LocalCluster starts")
    p.add_argument("--replicates", type=int, help="override the sweep's replicates")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the sweep (file or command line; repeatable): run.duration=10, "
                        "seed=3, model.<preset key>=VALUE (a fixed model setting, e.g. "
                        "model.perception.range=20; = model.set.<preset key>)")
    p.add_argument("--out", type=Path, help="results directory (default results/<sweep name>)")
    p.add_argument("--dry-run", action="store_true", help="print runs, done and estimated cost; run nothing")
    p.add_argument("--force", action="store_true", help="recompute every run, finished or not")
    p.add_argument("--retry-failed", action="store_true", help="rerun the runs recorded as failed")
    p.add_argument("--batch-size", type=int, help="runs per task (default: automatic)")
    p.add_argument("--until-ci", metavar="METRIC=HALFWIDTH",
                   help="add replicates to the cells whose 95%% CI half-width of METRIC (e.g. cohesion_mean) "
                        "exceeds HALFWIDTH, until all meet it")
    p.add_argument("--until-claims", action="store_true",
                   help="add replicates to the design points of the sweep's undecided claims (tests that are "
                        "inconclusive for lack of power) until every claim is decided or the cap is reached")
    p.add_argument("--max-replicates", type=int, default=30,
                   help="cap of replicates per design point for --until-ci and --until-claims (default 30)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--yes", action="store_true", help=f"run a design of more than {100_000:,} runs")


def handler(args) -> int:
    with _early_pool(args) as pool:
        return _run(args, pool)

def _early_pool(args):
    """A plain run on a local pool of several processes: the pool, started before anything else is
    imported or read, so its workers import the simulator meanwhile (about a second saved on every sweep);
    otherwise, or with flags the checks will refuse, nothing (the sweep starts its own executor when it
    has runs to compute). Nor for a sweep whose results table is already there (without ``--force`` or
    ``--retry-failed``): run again, it most likely has nothing to compute, and workers importing for
    nothing would slow its answer down by about half a second."""
    if (args.executor != "local" or args.scheduler is not None or args.dry_run or args.until_ci
            or args.until_claims):
        return nullcontext()
    folder = _results_folder(args)
    if not (args.force or args.retry_failed) and folder is not None and (folder / "runs.parquet").exists():
        return nullcontext()
    try:
        check_workers(args.workers, args.executor)
    except ConfigError:
        return nullcontext()   # refused, with its message, by check_run_args
    workers = args.workers or os.cpu_count() or 1
    if workers < 2:
        return nullcontext()
    from flocksweep.sweeps.executors import Executor

    return Executor("local", workers, preload=("flocksweep.sweeps.worker:prepare",))

def _results_folder(args) -> Path | None:
    """Where the run will store its results, told before the sweep is read: ``--out``, or the sweep
    file's name under ``results/`` (None when that cannot be told this early)."""
    if args.out is not None:
        return Path(args.out)
    if args.sweep is None or any(o.split("=", 1)[0].strip() == "name" for o in args.overrides or ()):
        return None
    import tomllib

    try:
        name = tomllib.loads(Path(args.sweep).read_text()).get("name")
    except (OSError, UnicodeError, ValueError):
        return None
    return Path("results") / name if isinstance(name, str) and name else None

def _run(args, pool) -> int:
    from flocksweep.command_line import check_run_args, sweep_from_args
    from flocksweep.sweeps.progress import next_steps
    from flocksweep.sweeps.runner import resume_hint, run_sweep

    check_run_args(args)
    until = parse_until_ci(args.until_ci) if args.until_ci else None
    config, args.sweep_text = sweep_from_args(args.sweep, args.model, args.axis, args.replicates, args.name,
                                              args.overrides)
    out = args.out or Path("results") / config.name
    args.on_interrupt = lambda: resume_hint(args.sweep or out / "sweep.toml", out)
    if args.until_ci and args.until_claims:
        raise ConfigError("--until-claims", "give either --until-ci or --until-claims, not both")
    if until:
        return run_until_ci_command(args, config, out, *until)
    if args.until_claims:
        return run_until_claims_command(args, config, out)
    result = run_sweep(config, args.sweep_text, out, args.executor, args.workers,
                       args.scheduler, args.force, args.retry_failed, args.dry_run, not args.no_progress,
                       args.batch_size, yes=args.yes, pool=pool)
    plan = result.plan
    if pool is not None and not plan.todo:
        pool.close(wait=False)   # never used: its workers need not finish importing
    if args.dry_run:
        est = result.estimate
        print(f"{config.name}: {len(plan.specs)} runs; {len(plan.done)} done, {len(plan.failed)} failed "
              f"(kept; --retry-failed reruns them), {len(plan.todo)} to run")
        workers = 1 if args.executor == "serial" else (args.workers or os.cpu_count())
        if args.executor == "cluster":
            workers = config.cluster.workers
        if est.get("command"):
            print(f"  estimated wall time: unknown: the runs are an external command's, and a dry run executes "
                  f"nothing (each run may take up to model.timeout_s = {config.command.timeout_s:g} s; on "
                  f"{workers} worker(s))")
            print(f"  results directory: {out}")
            return 0
        if est.get("pilot_failed"):
            print(f"  estimated wall time: unknown: a pilot run failed ({est['pilot_failed']}); the runs will "
                  "be recorded as failed the same way")
            print(f"  results directory: {out}")
            return 0
        print(f"  estimated wall time: about {est['total_s']:.0f} s = start-up {est['startup_s']:.1f} s + simulation "
              f"{est['seconds']:.1f} s + per-run overhead {est['per_run_s'] * 1000:.1f} ms x {len(plan.todo)} runs, "
              f"on {workers} worker(s) ({est['boid_steps']:,} boid-steps; measured here: short pilot runs)")
        if args.executor == "cluster":
            _print_job_script(config.cluster)
        if est["compile_s"]:
            print(f"  first compile: {est['compile_s']:.0f} s, done now by this dry run (numba's cache had no run loop "
                  "for these models); the run will load them")
        print(f"  results directory: {out}")
        next_steps(f"flocksweep {_without_dry_run(args)}   (runs it)")
        return 0
    table = result.table
    ok = int((table["status"] == "ok").sum())
    failed = int((table["status"] == "failed").sum())
    print(f"{config.name}: {len(plan.specs)} runs, {ok} ok, {failed} failed; computed {len(plan.todo)} "
          f"now, {len(plan.done)} already done; {result.wall_s:.1f} s")
    print(f"  table: {out / 'runs.parquet'}")
    if failed:
        print(f"  failures: flocksweep status {out}")
    code = report_lost(args, result)
    if ok:
        next_steps(*after_sweep(config, out, table))
    return code


def after_sweep(config, out: Path, table) -> list[str]:
    """What to do with a sweep's results: its report, and one of its runs in the 3-D viewer (its first
    ``[report.showcase]`` entry, else its first finished run)."""
    showcase = list((config.report or {}).get("showcase", {}))
    if showcase:
        view = f"--showcase {showcase[0]}"
    else:
        view = f"--run {table.loc[table['status'] == 'ok', 'run_id'].iloc[0]}"
    return [f"flocksweep report {out}   (statistics, figures and claims: {out / 'report' / 'report.html'})",
            f"flocksweep view {out} {view}   (one run in 3-D, in a page of {out / 'viewer'})"]


def _without_dry_run(args) -> str:
    """This run's command line without --dry-run (its sweep, model, axes, overrides and folder)."""
    import shlex

    words = ["run", args.sweep] if args.sweep else ["run", "--model", args.model]
    words += [f"--axis={axis}" for axis in args.axis] + [f"--set={item}" for item in args.overrides]
    for flag in ("replicates", "name", "out", "workers"):
        if getattr(args, flag) is not None:
            words += [f"--{flag}", str(getattr(args, flag))]
    return " ".join(shlex.quote(str(word)) for word in words)

def _print_job_script(settings) -> None:
    """A dry run on a cluster: the batch script each job would run (nothing is submitted)."""
    from flocksweep.sweeps.cluster import job_script

    print(f"  {settings.describe()}; each job runs (nothing submitted by a dry run):")
    for line in job_script(settings).strip().splitlines():
        print(f"    {line}")


def report_lost(args, result) -> int:
    """Say which runs were left missing because their workers died; exit status 5 if any."""
    for path in result.quarantined:
        print(f"  moved aside (damaged or unverified): {path}")
    if not result.lost:
        return 0
    causes = "; ".join(result.lost_reasons) or "killed, out of memory or crashed"
    print(f"flocksweep: {len(result.lost)} runs were left missing: their worker processes died on every attempt "
          f"({causes}); run the same command again to compute them", file=sys.stderr)
    return INCOMPLETE

def parse_until_ci(text: str) -> tuple[str, float]:
    from flocksweep.observables.summary import ENCOUNTER_FAMILIES, summary_columns

    metric, _, value = text.partition("=")
    metric = metric.strip()
    try:
        target = float(value)
    except ValueError:
        target = float("nan")
    if not metric or not (0 < target < float("inf")):
        raise ConfigError("--until-ci", f"got {text!r}; expected METRIC=HALFWIDTH with a finite HALFWIDTH > 0, "
                                        "e.g. cohesion_mean=0.05")
    columns = summary_columns(leadership=True, migration=True, encounters=ENCOUNTER_FAMILIES, dcd=True, walls=True)
    column = metric if metric in columns else f"{metric}_mean"
    if column not in columns:
        raise ConfigError("--until-ci", f"unknown metric {metric!r}{suggest(metric, columns)}; expected a summary "
                                        "column such as cohesion_mean or polarization_final")
    return column, target

def run_until_ci_command(args, config, out, metric: str, target: float) -> int:
    from flocksweep.sweeps.runner import ci_rule

    _check_rounds(args, config, "--until-ci")
    print(f"{config.name}: adding replicates until the 95% CI half-width of {metric} <= {target:g} "
          f"(at most {args.max_replicates} per cell)")
    return _run_rounds(args, config, out, ci_rule(metric, target), "")

def run_until_claims_command(args, config, out) -> int:
    from flocksweep.analysis.reports.claims.until import claims_rule
    from flocksweep.sweeps.claims import sweep_columns

    if not config.claims:
        raise ConfigError("--until-claims", f"{args.sweep or 'the sweep'} declares no claims ([[claims]] or include_claims)")
    _check_rounds(args, config, "--until-claims")
    print(f"{config.name}: adding replicates where a claim is undecided (at most {args.max_replicates} per cell); "
          f"claims {', '.join(c.id for c in config.claims)}")
    factors = sweep_columns(config.axes, config.sample or config.design, config.metrics.leadership,
                            config.metrics.dcd).factors
    return _run_rounds(args, config, out, claims_rule(config.claims, factors),
                       f"; `flocksweep report {out}` shows the claims' evidence")

def _check_rounds(args, config, flag: str) -> None:
    if args.max_replicates < config.replicates:
        raise ConfigError("--max-replicates", f"got {args.max_replicates}; must be >= replicates ({config.replicates})")
    if args.dry_run:
        raise ConfigError(flag, "cannot be combined with --dry-run (the rounds depend on the results)")

def _run_rounds(args, config, out, rule, note: str) -> int:
    """:func:`sweeps.runner.run_until` with ``rule`` and the run's flags; prints the table's line (and
    ``note``) and returns the exit status."""
    from flocksweep.sweeps.progress import next_steps
    from flocksweep.sweeps.runner import run_until

    result = run_until(config, args.sweep_text, out, rule, args.max_replicates, executor=args.executor,
                       workers=args.workers, scheduler=args.scheduler, force=args.force,
                       retry_failed=args.retry_failed, progress=not args.no_progress, batch_size=args.batch_size,
                       yes=args.yes)
    table = result.table
    ok = int((table['status'] == 'ok').sum())
    print(f"{config.name}: {len(table)} runs in {out / 'runs.parquet'} ({ok} ok){note}")
    code = report_lost(args, result)
    if ok:
        next_steps(*after_sweep(config, out, table))
    return code


COMMAND = Command("run", HELP, DESCRIPTION, arguments, handler)
