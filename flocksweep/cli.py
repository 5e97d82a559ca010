"""The ``flocksweep`` command line. Subcommands parse their arguments here and call library code.

    flocksweep simulate MODEL.toml [--set key=value ...] [--seed S] [--n N] [--duration T] [--dt DT]
                        [--record-every STEPS] [--out DIR] [--tracks csv|parquet] [--plot]
                        [--color-by auto|boid|pattern]
    flocksweep run SWEEP.toml | --model MODEL.toml --axis KEY=VALUES ... [--name NAME]
                   [--workers K] [--executor serial|local|dask] [--scheduler ADDR] [--replicates R] [--set key=value ...] [--out DIR] [--dry-run] [--force]
                   [--retry-failed] [--batch-size B] [--no-progress] [--yes]
                   [--until-ci METRIC=HALFWIDTH | --until-claims] [--max-replicates R]
    flocksweep status DIR
    flocksweep compile [MODEL.toml ...] [--jobs K] (sweeps/compile_command.py)
    flocksweep export RESULTS_DIR (--csv | --parquet) [--with-fixed] [--timeseries] [--out DIR] (sweeps/export.py)
    flocksweep report RESULTS_DIR [--metrics NAME ...] [--by FACTOR ...] [--out DIR] [--format html|md|both]
                      [--claims FILE ...] [--seed S]
    flocksweep calibrate CALIB.toml [--method emcee|optimize|emulator|npe] [--set key=value ...] [--out DIR]
                         [--resume] [--no-progress]
                         [--executor serial|local|dask] [--workers K] [--scheduler ADDR]
    flocksweep targets CALIB.toml --truth NAME=VALUE ... [--set key=value ...] [--seed S] [--replicates R] [--sd SD,...]
    flocksweep targets CALIB.toml --from-tracks [TRACKS] [--set key=value ...]
    flocksweep posterior ESTIMATOR --targets FLOCKS.csv [--draws S] [--seed S] [--out FILE.csv]
    flocksweep sbc CALIB.toml [--datasets L] [--draws S] [--workers K] [--out DIR] [--steps N] [--walkers W]
    flocksweep view MODEL.toml | RESULTS_DIR (--run ID | --where "K=V, ..." | --showcase NAME) | TRAJ.npz
                    [--out PAGE.html] [--animate OUT.gif|OUT.mp4] [--color-by MODE] ... (analysis/viewer/command.py)
    flocksweep measure TRACKS --group-radius R [--columns ROLE=NAME ...] [--units ...] [--body-length M]
                       [--interval S] [--velocity-interval S] [--out DIR] ... (analysis/reports/measure_command.py)

Exit status (sweeps/failures.py, docs/errors.md): 0 on success, 2 for bad input (a config error names
the key, the value and what is allowed; nothing is written), 3 when another runner holds the results
directory, 4 when a write fails (the file and errno named; what was saved is kept), 5 when runs were
left missing because their worker processes died, 130 after Ctrl-C and 143 after SIGTERM (finished work
saved, the way to resume printed). Every one of these is a single message on stderr, never a traceback.

This module is the top of the import graph (docs/architecture.md): it may import every layer. Each
command imports what it needs when it runs, and the parser declares only the arguments of the command
named on the command line (``view`` and ``measure`` take theirs from their own modules), so
``flocksweep simulate`` loads neither the calibration, the reports, the viewer nor pandas
(tests/flocksweep/test_cli.py checks it).
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from contextlib import nullcontext
from pathlib import Path

from simcore.schema import ConfigError, suggest

from sweeps.failures import INCOMPLETE, check_count, check_out, check_workers, explain, parse_numbers, show_warnings
from sweeps.interrupts import ignored, signals_as_exceptions
from flocksweep import version


def _add_simulate(sub) -> None:
    p = sub.add_parser("simulate", help="run one simulation from a model preset",
                       description="Run one simulation from a model preset TOML and print a short summary.")
    p.add_argument("model", help="model preset TOML, e.g. configs/models/holland.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a preset key, e.g. --set perception.field_deg=180 (repeatable)")
    p.add_argument("--seed", type=int, default=0, help="run seed (default 0)")
    p.add_argument("--n", type=int, help="number of boids (init.n)")
    p.add_argument("--duration", type=float, help="simulated seconds (run.duration)")
    p.add_argument("--dt", type=float, help="time step in seconds (run.dt)")
    p.add_argument("--record-every", type=int, default=1, metavar="STEPS",
                   help="record positions and velocities every STEPS steps (default 1: every step)")
    p.add_argument("--out", type=Path, help="write trajectory.npz and params.json (and traces.png) here")
    p.add_argument("--tracks", choices=("csv", "parquet"),
                   help="also write the records as long-format tracks (tracks.csv or tracks.parquet, in body "
                        "lengths, with a tracks.json sidecar) into --out, for flocksweep measure")
    p.add_argument("--plot", action="store_true",
                   help="save a PNG of the 3-D traces (into --out, default results/simulate/NAME-seedS/)")
    p.add_argument("--color-by", choices=("auto", "boid", "pattern"), default="auto",
                   help="trace colours: one per boid, or per pattern (auto: pattern in pattern mode)")
    p.add_argument("--init-state", type=Path, metavar="FILE",
                   help="start from the state in FILE (.npz with pos, vel or fwd + speed, optional up, acc, "
                        "pattern; or a trajectory.npz, whose last record is used); sets init.from_file and init.n")


def cmd_simulate(args) -> int:
    import json

    from simcore import load_preset
    from simcore.params import RUN_SHORTHANDS
    from sweeps.single import run_single

    overrides = list(args.overrides)
    if args.init_state is not None:
        from simcore.initfile import boid_count

        overrides.append(f"init.from_file={json.dumps(str(args.init_state))}")
        if args.n is None:
            overrides.append(f"init.n={boid_count(args.init_state)}")
    for short in ("n", "duration", "dt"):  # the [run] shorthands of sweep files
        if getattr(args, short) is not None:
            overrides.append(f"{RUN_SHORTHANDS[short]}={getattr(args, short)!r}")
    from sweeps.budget import check_runs

    preset = load_preset(args.model, overrides)
    check_count("--record-every", args.record_every, 1, preset.run.n_steps)   # at least one record after t = 0
    check_count("--seed", args.seed, 0, 2 ** 63 - 1)
    check_out("--out", args.out)
    check_runs("init.n", preset.init.n, preset.run.n_steps, args.record_every)
    out = args.out
    if out is None and (args.plot or args.tracks):
        out = Path("results") / "simulate" / f"{preset.model.name}-seed{args.seed}"
    summary, written, obs = run_single(preset, args.seed, out, args.record_every, args.tracks)
    if args.plot:
        from analysis.reports.traces import plot_traces, wrap_distance

        title = (f"{preset.model.name}: N={obs.n}, {obs.times[-1]:g} s, seed {args.seed}, "
                 f"final polarization {summary['polarization_final']:.2f}")
        written.append(plot_traces(obs.pos, Path(out) / "traces.png", obs.pattern, args.color_by,
                                   wrap_distance(preset.model), title, preset.model.world.obstacles,
                                   obs.predator, obs.prey))
    compiled = f" (+ {summary['compile_s']:.1f} s compiling its run loop, once)" if summary["compile_s"] else ""
    print(f"{preset.model.name}: N={summary['n']}, {summary['time_s']:g} s simulated in {summary['wall_s']:.2f} s"
          f"{compiled}")
    print(f"  final polarization     {summary['polarization_final']:.3f}")
    print(f"  final mean speed       {summary['speed_mean_final']:.3f}")
    print(f"  mean visible neighbours {summary['visible_mean_final']:.2f}"
          f" (binocular share {summary['binocular_share_final']:.2f})")
    if "collided_boids" in summary:
        print(f"  obstacles: {summary['collided_boids']:g} boids collided, least clearance "
              f"{summary['clearance_min']:.3f}")
    if "predator_captures" in summary:
        print(f"  predator: {summary['predator_captures']:g} boids captured, nearest approach "
              f"{summary['predator_distance_min']:.2f}")
    if "prey_reach_time" in summary:
        print(f"  prey: the flock's centre reached it at t = {summary['prey_reach_time']:g} s (nan: never)")
    for path in written:
        print(f"  wrote {path}")
    return 0


def _add_run(sub) -> None:
    p = sub.add_parser("run", help="run (or resume) a sweep from a sweep TOML or --model with --axis",
                       description="Run a parameter sweep. Finished runs are skipped (resume); results go to "
                                   "results/<sweep name>/ unless --out is given. --model MODEL.toml --axis "
                                   "KEY=VALUES ... instead of a file builds the sweep a file would and stores it, "
                                   "resolved, as RESULTS/sweep.toml (rerun that file to reproduce it).")
    p.add_argument("sweep", nargs="?", help="sweep TOML, e.g. configs/sweeps/holland648.toml")
    p.add_argument("--model", help="instead of a sweep file: a model preset TOML, e.g. configs/models/holland.toml")
    p.add_argument("--axis", action="append", default=[], metavar="KEY=VALUES",
                   help="with --model, one axis of the grid (repeatable): KEY=V1,V2,... or "
                        "KEY=linspace(START,STOP,NUM) or KEY=range(START,STOP,STEP), e.g. "
                        "--axis perception.field_deg=30,90,180 --axis init.n=20,50")
    p.add_argument("--name", help="with --model: the sweep's name (default <model>_<axis keys>)")
    p.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    p.add_argument("--executor", choices=("serial", "local", "dask"), default="local",
                   help="local process pool (default), serial in this process, or dask")
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


def cmd_run(args) -> int:
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
    from sweeps.executors import Executor

    return Executor("local", workers, preload=("sweeps.worker:prepare",))


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
    from sweeps.runner import resume_hint, run_sweep

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
        if est.get("command"):
            print(f"  estimated wall time: unknown: the runs are an external command's, and a dry run executes "
                  f"nothing (each run may take up to model.timeout_s = {config.command.timeout_s:g} s; on "
                  f"{workers} worker(s))")
            print(f"  results directory: {out}")
            return 0
        print(f"  estimated wall time: about {est['total_s']:.0f} s = start-up {est['startup_s']:.1f} s + simulation "
              f"{est['seconds']:.1f} s + per-run overhead {est['per_run_s'] * 1000:.1f} ms x {len(plan.todo)} runs, "
              f"on {workers} worker(s) ({est['boid_steps']:,} boid-steps; measured here: short pilot runs)")
        if est["compile_s"]:
            print(f"  first compile: {est['compile_s']:.0f} s, done now by this dry run (numba's cache had no run loop "
                  "for these models); the run will load them")
        print(f"  results directory: {out}")
        return 0
    table = result.table
    ok = int((table["status"] == "ok").sum())
    failed = int((table["status"] == "failed").sum())
    print(f"{config.name}: {len(plan.specs)} runs, {ok} ok, {failed} failed; computed {len(plan.todo)} "
          f"now, {len(plan.done)} already done; {result.wall_s:.1f} s")
    print(f"  table: {out / 'runs.parquet'}")
    if failed:
        print(f"  failures: flocksweep status {out}")
    return report_lost(args, result)


# the rounds of run --until-ci / --until-claims: each run_until_*_command(args, config, out) checks its
# flags (ConfigError naming the flag), runs the rounds through sweeps.runner.run_until and returns the
# command's exit status; report_lost closes every run with the runs dead workers left missing

def report_lost(args, result) -> int:
    """Say which runs were left missing because their workers died; exit status 5 if any."""
    for path in result.quarantined:
        print(f"  moved aside (unreadable): {path}")
    if not result.lost:
        return 0
    causes = "; ".join(result.lost_reasons) or "killed, out of memory or crashed"
    print(f"flocksweep: {len(result.lost)} runs were left missing: their worker processes died on every attempt "
          f"({causes}); run the same command again to compute them", file=sys.stderr)
    return INCOMPLETE


def parse_until_ci(text: str) -> tuple[str, float]:
    from observables.summary import ENCOUNTER_FAMILIES, summary_columns

    metric, _, value = text.partition("=")
    metric = metric.strip()
    try:
        target = float(value)
    except ValueError:
        target = float("nan")
    if not metric or not (0 < target < float("inf")):
        raise ConfigError("--until-ci", f"got {text!r}; expected METRIC=HALFWIDTH with a finite HALFWIDTH > 0, "
                                        "e.g. cohesion_mean=0.05")
    columns = summary_columns(leadership=True, migration=True, encounters=ENCOUNTER_FAMILIES, dcd=True)
    column = metric if metric in columns else f"{metric}_mean"
    if column not in columns:
        raise ConfigError("--until-ci", f"unknown metric {metric!r}{suggest(metric, columns)}; expected a summary "
                                        "column such as cohesion_mean or polarization_final")
    return column, target


def run_until_ci_command(args, config, out, metric: str, target: float) -> int:
    from sweeps.runner import ci_rule

    _check_rounds(args, config, "--until-ci")
    print(f"{config.name}: adding replicates until the 95% CI half-width of {metric} <= {target:g} "
          f"(at most {args.max_replicates} per cell)")
    return _run_rounds(args, config, out, ci_rule(metric, target), "")


def run_until_claims_command(args, config, out) -> int:
    from analysis.reports.claims.until import claims_rule
    from sweeps.claims import sweep_columns

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
    from sweeps.runner import run_until

    result = run_until(config, args.sweep_text, out, rule, args.max_replicates, executor=args.executor,
                       workers=args.workers, scheduler=args.scheduler, force=args.force,
                       retry_failed=args.retry_failed, progress=not args.no_progress, batch_size=args.batch_size,
                       yes=args.yes)
    table = result.table
    print(f"{config.name}: {len(table)} runs in {out / 'runs.parquet'} "
          f"({int((table['status'] == 'ok').sum())} ok){note}")
    return report_lost(args, result)


def _add_status(sub) -> None:
    p = sub.add_parser("status", help="done / failed / missing runs of a results directory",
                       description="Count the done, failed and missing runs of a results directory, say whether "
                                   "a runner is working there now, when its results were computed, and list "
                                   "the failed runs with their reasons. Reads only; quick (simulates nothing).")
    p.add_argument("dir", type=Path, help="results directory of a sweep")
    p.add_argument("--verify", action="store_true",
                   help="read and verify every file even if none changed since the last full check (status "
                        "otherwise reuses that check's counts while the files' sizes and times are unchanged)")


def cmd_status(args) -> int:
    from sweeps.status import computed, status

    try:
        info = status(args.dir, remember=not args.verify)
    except FileNotFoundError as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    manifest = info["manifest"]
    print(f"{manifest.get('sweep', args.dir)}: {info['runs']} runs: {info['ok']} done, {info['failed']} failed, "
          f"{info['missing']} missing")
    if info["running"]:
        print(f"  a runner is working here now ({info['running']}), started {manifest.get('started')}")
    elif manifest.get("finished"):
        print(f"  results computed {computed(manifest)} (git {manifest.get('git_revision')})")
    elif manifest:
        print(f"  last run started {manifest.get('started')} and did not finish (resume with flocksweep run)")
    if info["checked"] != "full":
        print(f"  files {info['checked']} (--verify reads them all again)")
    for run_id, error in info["failures"][:50]:
        print(f"  failed {run_id}: {error}")
    if len(info["failures"]) > 50:
        print(f"  ... and {len(info['failures']) - 50} more")
    return 0


def _add_report(sub) -> None:
    p = sub.add_parser("report", help="statistics, figures and tested claims from a results directory",
                       description="Write a self-contained HTML report, the same as Markdown with figures, "
                                   "and the tables behind it as CSV (default: RESULTS_DIR/report/).")
    p.add_argument("dir", type=Path, help="results directory of a sweep (with runs.parquet)")
    p.add_argument("--metrics", nargs="+", metavar="NAME",
                   help="metrics (default: cohesion alignment stray_fraction groups elongation speed); "
                        "names like cohesion or columns like cohesion_final")
    p.add_argument("--by", nargs="+", metavar="FACTOR", help="factors to analyse (default: all swept factors)")
    p.add_argument("--out", type=Path, help="output directory (default RESULTS_DIR/report)")
    p.add_argument("--format", choices=("html", "md", "both"), default="both",
                   help="html: report.html (self-contained); md: report.md with its figures as PNG files; "
                        "both (default)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the bootstrap resampling and of the claims' power simulations (default 0)")
    p.add_argument("--claims", nargs="+", type=Path, default=[], metavar="FILE",
                   help="also test the claims of these claims files (or sweep files), e.g. configs/claims/holland.toml")
    p.add_argument("--no-progress", action="store_true", help="no progress lines (each section as it starts) on stderr")


def cmd_report(args) -> int:
    from analysis.reports.report import ReportError, build_report

    formats = ("html", "md") if args.format == "both" else (args.format,)
    check_out("--out", args.out)
    check_count("--seed", args.seed, 0, 2 ** 63 - 1)
    try:
        result = build_report(args.dir, args.out, args.metrics, args.by, formats, args.seed, args.claims,
                              progress=not args.no_progress)
    except (ReportError, FileNotFoundError) as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    for kind, path in result["paths"].items():
        print(f"  wrote {path}")
    print(f"  tables: {result['out'] / 'tables'} ({len(result['tables'])} CSV files); {result['seconds']:.1f} s")
    claims = result["tables"].get("claims")
    for row in (claims.itertuples() if claims is not None else ()):
        print(f"  claim ({row.claim}): {row.verdict}: {row.statement}")
    return 0


def _add_calibrate(sub) -> None:
    p = sub.add_parser("calibrate", help="fit model parameters to target flock statistics",
                       description="Fit the free parameters of a calibration TOML with its method (emcee BSL, "
                                   "optimize, emulator or npe; --method picks another the file has settings for); "
                                   "writes the posterior or optimum, diagnostics, figures and the cost.")
    p.add_argument("config", help="calibration TOML, e.g. configs/calibration/recover_holland.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the calibration file, e.g. --set method.steps=500 (a flat [method] "
                        "table) or --set method.emcee.steps=500 (a [method.emcee] table)")
    p.add_argument("--method", metavar="emcee|optimize|emulator|npe",
                   help="run this method with its [method.<name>] settings instead of the file's method.kind; "
                        "its outputs go to results/calibration/<name>-<method> unless --out is given")
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


def cmd_calibrate(args) -> int:
    from analysis.calibration.accounting import lines as cost_lines
    from analysis.calibration.config import load_calibration
    from analysis.calibration.run import resume_hint, run_calibration

    check_workers(args.workers, args.executor)
    check_out("--out", args.out)
    if args.scheduler is not None and args.executor != "dask":
        raise ConfigError("--scheduler", "only used with --executor dask")
    config = load_calibration(args.config, args.overrides, args.method)
    command = f"{args.config} --method {args.method}" if args.method else args.config
    args.on_interrupt = lambda: resume_hint(command, args.out or Path("results") / "calibration" / config.folder_name)
    result = run_calibration(config, args.out, resume=args.resume, progress=not args.no_progress,
                             executor=args.executor, workers=args.workers, scheduler=args.scheduler,
                             yes=args.yes)
    if result.optimum:
        opt = result.optimum
        print("optimum: " + ", ".join(f"{k} = {v:.4g}" for k, v in opt["theta"].items()))
        se = float("nan") if opt["recheck_se"] is None else opt["recheck_se"]   # null: one batch
        print(f"  objective {opt['objective_common_seeds']:.4g} with the search's common seeds, "
              f"{opt['objective_recheck']:.4g} +- {se:.2g} re-checked with fresh seeds")
    else:
        print(result.summary.round(4).to_string())
    for message in result.verdicts(config):   # convergence, warnings, confirmation (failed too), truth
        print(f"  {message}")
    for line in cost_lines(result.report.get("accounting")):
        print(f"  {line}")
    print(f"  wrote {result.out} (report: {result.paths['html']})")
    return 0


def _add_targets(sub) -> None:
    p = sub.add_parser("targets", help="a calibration's targets: simulated at known parameters, or from tracks",
                       description="For parameter-recovery studies: run the calibration's model at the given "
                                   "truth and print a [targets] block to paste into the calibration file. "
                                   "With --from-tracks: the targets measured from tracks, one row per flock.")
    p.add_argument("config", help="calibration TOML")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the calibration file, as for calibrate (repeatable), e.g. "
                        "--set observation.velocity_interval=0.4")
    p.add_argument("--truth", action="append", default=[], metavar="NAME=VALUE",
                   help="value of a free parameter (repeat for each), e.g. --truth field=150")
    p.add_argument("--seed", type=int, default=0, help="seed of the synthetic runs (default 0)")
    p.add_argument("--replicates", type=int, default=1,
                   help="runs to average (default 1: one flock's statistics, as the likelihood assumes)")
    p.add_argument("--sd", help="measurement sd per stat, comma-separated (default: the file's sd)")
    p.add_argument("--from-tracks", nargs="?", const="", metavar="TRACKS",
                   help="instead: print the targets measured from tracks (the file's from_tracks, or TRACKS), "
                        "one row per flock, with the file's [observation] block")


def _targets_from_tracks(args) -> int:
    from analysis.calibration.synthetic import measured_targets_block

    if args.truth:
        raise ConfigError("--from-tracks", "measured targets take no --truth")
    print(measured_targets_block(args.config, args.from_tracks or None, args.overrides), end="")
    return 0


def cmd_targets(args) -> int:
    import numpy as np

    from analysis.calibration.config import load_calibration
    from analysis.calibration.synthetic import synthetic_observation, targets_block
    from simcore.schema import parse_value

    if args.from_tracks is not None:
        return _targets_from_tracks(args)
    check_count("--seed", args.seed, 0, 2 ** 63 - 1)
    check_count("--replicates", args.replicates, 1, 10_000)
    config = load_calibration(args.config, args.overrides)
    truth = {}
    for item in args.truth:
        name, sep, value = item.partition("=")
        name, value = name.strip(), parse_value(value.strip())
        if not sep or name not in config.names:
            raise ConfigError("--truth", f"got {item!r}; expected NAME=VALUE with NAME one of {', '.join(config.names)}"
                                         + (suggest(name, config.names) if sep else ""))
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value or abs(value) == float("inf"):
            raise ConfigError("--truth", f"got {item!r}; the value of {name} must be a finite number")
        truth[name] = value
    if args.sd:
        sd = parse_numbers("--sd", args.sd)
        if len(sd) != config.targets.k:
            raise ConfigError("--sd", f"got {len(sd)} values; expected {config.targets.k}, one per stat")
    elif config.targets.cov is not None:
        sd = np.sqrt(np.diag(config.targets.cov))
    else:
        raise ConfigError("--sd", "the file gives samples, not mean/sd: pass --sd with one value per stat")
    rows, flock = synthetic_observation(config, truth, args.seed, args.replicates, flock=True)
    if not np.isfinite(rows).all():
        raise ConfigError("--truth", "some runs gave undefined statistics at this truth; choose other stats")
    truth_text = ", ".join(f"{k} = {v}" for k, v in truth.items())
    print(f"# synthetic targets: {truth_text}; flocksweep targets --seed {args.seed} "
          f"--replicates {args.replicates}")
    print(targets_block(config, rows, sd, truth, flock if np.isfinite(flock).all() else None), end="")
    return 0


# Commands whose arguments and code live in their own module (DESCRIPTION, add_arguments(parser), run(args)),
# loaded when the parser is built (arguments) and when the command runs.
DELEGATED = {"compile": ("sweeps.compile_command", "compile the simulation and metric kernels now, into numba's cache"),
             "export": ("sweeps.export", "a sweep's runs (and time series) as CSV or Parquet"),
             "sbc": ("analysis.calibration.sbc_command",
                     "simulation-based calibration check of a calibration's posterior"),
             "compare": ("analysis.calibration.compare_command",
                         "which of several models explains the targets: classifier, model probabilities, confusion"),
             "posterior": ("analysis.calibration.posterior_command",
                           "one posterior per observed flock from a trained npe estimator (no simulation)"),
             "view": ("analysis.viewer.command", "interactive 3-D viewer page (and GIF/MP4) of a run"),
             "measure": ("analysis.reports.measure_command", "flock metrics of measured tracks (tables and a report)")}


def _add_delegated(sub, name: str) -> None:
    module = importlib.import_module(DELEGATED[name][0])
    module.add_arguments(sub.add_parser(name, help=DELEGATED[name][1], description=module.DESCRIPTION))


def cmd_delegated(args) -> int:
    return importlib.import_module(DELEGATED[args.command][0]).run(args)


ADDERS = {"simulate": _add_simulate, "run": _add_run, "status": _add_status, "report": _add_report,
          "calibrate": _add_calibrate, "targets": _add_targets}
ORDER = ("simulate", "run", "status", "compile", "export", "report", "calibrate", "targets", "posterior", "compare", "sbc", "view",
         "measure")


ALL = "*"   # build_parser(ALL): every command's arguments declared (tests and documentation)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser. Only the arguments of ``command`` (None: of none of the delegated commands) are declared
    from the delegated commands' modules; the others are listed by name and help line, so neither
    ``flocksweep simulate`` nor ``flocksweep --help`` imports the modules of export, view, measure, sbc or
    compile. ``build_parser(ALL)`` declares every command's arguments."""
    parser = argparse.ArgumentParser(prog="flocksweep", description="Reproducible flocking-model sweeps: "
                                     "simulate, sweep, report, calibrate, view. `flocksweep COMMAND --help` "
                                     "describes a command.")
    parser.add_argument("--version", action="version", version=f"flocksweep {version()}",
                        help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in ORDER:
        if name in ADDERS:
            ADDERS[name](sub)
        elif name == command or command == ALL:
            _add_delegated(sub, name)
        else:   # listed by name only: its module (and what it imports) is not loaded
            sub.add_parser(name, help=DELEGATED[name][1])
    return parser


COMMANDS = {"simulate": cmd_simulate, "run": cmd_run, "status": cmd_status, "report": cmd_report,
            "calibrate": cmd_calibrate, "targets": cmd_targets,
            **{name: cmd_delegated for name in DELEGATED}}


def _command_of(argv) -> str | None:
    """The subcommand named on the command line (its first word not starting with '-'), else None."""
    argv = sys.argv[1:] if argv is None else argv
    for word in argv:
        if not str(word).startswith("-"):
            return word if word in COMMANDS else None
    return None


def main(argv=None) -> int:
    args = build_parser(_command_of(argv)).parse_args(argv)
    show_warnings()
    try:
        with signals_as_exceptions():
            return COMMANDS[args.command](args)
    except BaseException as err:  # noqa: BLE001 - expected failures become one line; bugs raise
        known = explain(err)
        if known is None:
            raise
        code, message = known
        with ignored():   # a second Ctrl-C does not cut the message short
            print(f"flocksweep: {message}", file=sys.stderr)
            if isinstance(err, KeyboardInterrupt):
                _after_interrupt(args)
        return code


def _after_interrupt(args) -> None:
    """What an interrupted command saved and how to resume it (each command leaves ``args.on_interrupt``)."""
    hint = getattr(args, "on_interrupt", None)
    try:
        print(f"  {hint() if hint else 'nothing to resume: run the command again'}", file=sys.stderr)
    except Exception as err:  # noqa: BLE001 - the summary is a courtesy; the interrupt is what matters
        print(f"  (could not read what was saved: {type(err).__name__}: {err})", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
