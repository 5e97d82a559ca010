"""The ``flocksweep`` command line. Subcommands parse their arguments here and call library code.

    flocksweep simulate MODEL.toml [--set key=value ...] [--seed S] [--n N] [--duration T] [--dt DT]
                        [--record-every STEPS] [--out DIR] [--tracks csv|parquet] [--plot]
                        [--color-by auto|boid|pattern]
    flocksweep run SWEEP.toml [--workers K] [--executor serial|local|dask] [--scheduler ADDR]
                   [--replicates R] [--set key=value ...] [--out DIR] [--dry-run] [--force]
                   [--retry-failed] [--batch-size B] [--no-progress]
    flocksweep status DIR
    flocksweep report RESULTS_DIR [--metrics NAME ...] [--by FACTOR ...] [--out DIR] [--format html|md|both]
    flocksweep calibrate CALIB.toml [--set key=value ...] [--out DIR] [--resume] [--no-progress]
                         [--executor serial|local|dask] [--workers K] [--scheduler ADDR]
    flocksweep targets CALIB.toml --truth NAME=VALUE ... [--seed S] [--replicates R] [--sd SD,...]
    flocksweep targets CALIB.toml --from-tracks [TRACKS]
    flocksweep sbc CALIB.toml [--datasets L] [--draws S] [--workers K] [--out DIR] [--steps N] [--walkers W]
    flocksweep view MODEL.toml | RESULTS_DIR (--run ID | --where "K=V, ..." | --showcase NAME) | TRAJ.npz
                    [--out PAGE.html] [--animate OUT.gif|OUT.mp4] [--color-by MODE] ... (analysis/viewer/command.py)
    flocksweep measure TRACKS --group-radius R [--columns ROLE=NAME ...] [--units ...] [--body-length M]
                       [--interval S] [--velocity-interval S] [--out DIR] ... (analysis/reports/measure_command.py)

Exit status: 0 on success, 2 for bad input (a config error names the key, the value and what is allowed),
3 when another runner holds the results directory.

This module is the top of the import graph (docs/architecture.md): it may import every layer. Each
command imports what it needs when it runs, so ``flocksweep simulate`` does not load the calibration.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from analysis.observables.summary import summary_columns
from simcore import ConfigError, load_preset
from simcore.params import RUN_SHORTHANDS

from .store import StoreLocked


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


def cmd_simulate(args) -> int:
    from analysis.reports.traces import plot_traces, wrap_distance
    from sweeps.single import run_single

    overrides = list(args.overrides)
    for short in ("n", "duration", "dt"):  # the [run] shorthands of sweep files
        if getattr(args, short) is not None:
            overrides.append(f"{RUN_SHORTHANDS[short]}={getattr(args, short)!r}")
    preset = load_preset(args.model, overrides)
    if args.record_every < 1:
        raise ConfigError("--record-every", f"got {args.record_every}; must be an integer >= 1")
    if args.seed < 0:
        raise ConfigError("--seed", f"got {args.seed}; must be an integer >= 0")
    out = args.out
    if out is None and (args.plot or args.tracks):
        out = Path("results") / "simulate" / f"{preset.model.name}-seed{args.seed}"
    summary, written, obs = run_single(preset, args.seed, out, args.record_every, args.tracks)
    if args.plot:
        title = (f"{preset.model.name}: N={obs.n}, {obs.times[-1]:g} s, seed {args.seed}, "
                 f"final polarization {summary['final_polarization']:.2f}")
        written.append(plot_traces(obs.pos, Path(out) / "traces.png", obs.pattern, args.color_by,
                                   wrap_distance(preset.model), title))
    print(f"{preset.model.name}: N={summary['n']}, {summary['time_s']:g} s simulated in {summary['wall_s']:.2f} s")
    print(f"  final polarization     {summary['final_polarization']:.3f}")
    print(f"  final mean speed       {summary['final_mean_speed']:.3f}")
    print(f"  mean visible neighbours {summary['final_mean_visible']:.2f}"
          f" (binocular share {summary['final_binocular_share']:.2f})")
    for path in written:
        print(f"  wrote {path}")
    return 0


def _add_run(sub) -> None:
    p = sub.add_parser("run", help="run (or resume) a sweep from a sweep TOML",
                       description="Run a parameter sweep. Finished runs are skipped (resume); results go "
                                   "to results/<sweep name>/ unless --out is given.")
    p.add_argument("sweep", help="sweep TOML, e.g. configs/sweeps/holland648.toml")
    p.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    p.add_argument("--executor", choices=("serial", "local", "dask"), default="local",
                   help="local process pool (default), serial in this process, or dask")
    p.add_argument("--scheduler", metavar="ADDR", help="dask scheduler address; without it a LocalCluster starts")
    p.add_argument("--replicates", type=int, help="override the sweep's replicates")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the sweep file, e.g. --set run.duration=10 (repeatable)")
    p.add_argument("--out", type=Path, help="results directory (default results/<sweep name>)")
    p.add_argument("--dry-run", action="store_true", help="print runs, done and estimated cost; run nothing")
    p.add_argument("--force", action="store_true", help="recompute every run, finished or not")
    p.add_argument("--retry-failed", action="store_true", help="rerun the runs recorded as failed")
    p.add_argument("--batch-size", type=int, help="runs per task (default: automatic)")
    p.add_argument("--until-ci", metavar="METRIC=HALFWIDTH",
                   help="add replicates to the cells whose 95%% CI half-width of METRIC (e.g. cohesion_mean) "
                        "exceeds HALFWIDTH, until all meet it")
    p.add_argument("--max-replicates", type=int, default=30, help="cap for --until-ci (default 30)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def cmd_run(args) -> int:
    from sweeps.config import load_sweep
    from sweeps.runner import run_sweep

    if args.workers is not None and args.workers < 1:
        raise ConfigError("--workers", f"got {args.workers}; must be an integer >= 1")
    if args.replicates is not None and args.replicates < 1:
        raise ConfigError("--replicates", f"got {args.replicates}; must be an integer >= 1")
    if args.scheduler and args.executor != "dask":
        raise ConfigError("--scheduler", "only applies with --executor dask")
    config = load_sweep(args.sweep, args.overrides, args.replicates)
    out = args.out or Path("results") / config.name
    if args.until_ci:
        return _run_until_ci(args, config, out)
    result = run_sweep(config, Path(args.sweep).read_text(), out, args.executor, args.workers, args.scheduler,
                       args.force, args.retry_failed, args.dry_run, not args.no_progress, args.batch_size)
    plan = result.plan
    if args.dry_run:
        est = result.estimate
        print(f"{config.name}: {len(plan.specs)} runs; {len(plan.done)} done, {len(plan.failed)} failed "
              f"(kept; --retry-failed reruns them), {len(plan.todo)} to run")
        print(f"  estimated cost: {est['boid_steps']:,} boid-steps, about {est['seconds']:.0f} s of compute "
              f"on {args.workers or os.cpu_count()} worker(s) (from short pilot runs)")
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
    return 0


def _parse_until_ci(text: str) -> tuple[str, float]:
    metric, _, value = text.partition("=")
    try:
        target = float(value)
    except ValueError:
        target = float("nan")
    if not metric or not target > 0:
        raise ConfigError("--until-ci", f"got {text!r}; expected METRIC=HALFWIDTH with HALFWIDTH > 0, "
                                        "e.g. cohesion_mean=0.05")
    return (metric if metric in summary_columns(leadership=True) else f"{metric}_mean"), target


def _run_until_ci(args, config, out) -> int:
    from sweeps.runner import run_until_ci

    metric, target = _parse_until_ci(args.until_ci)
    if args.max_replicates < config.replicates:
        raise ConfigError("--max-replicates", f"got {args.max_replicates}; must be >= replicates ({config.replicates})")
    if args.dry_run:
        raise ConfigError("--until-ci", "cannot be combined with --dry-run (the rounds depend on the results)")
    print(f"{config.name}: adding replicates until the 95% CI half-width of {metric} <= {target:g} "
          f"(at most {args.max_replicates} per cell)")
    result = run_until_ci(config, Path(args.sweep).read_text(), out, metric, target, args.max_replicates,
                          executor=args.executor, workers=args.workers, scheduler=args.scheduler,
                          force=args.force, retry_failed=args.retry_failed, progress=not args.no_progress,
                          batch_size=args.batch_size)
    table = result.table
    print(f"{config.name}: {len(table)} runs in {out / 'runs.parquet'} "
          f"({int((table['status'] == 'ok').sum())} ok)")
    return 0


def _add_status(sub) -> None:
    p = sub.add_parser("status", help="done / failed / missing runs of a results directory")
    p.add_argument("dir", type=Path, help="results directory of a sweep")


def cmd_status(args) -> int:
    from sweeps.runner import status

    try:
        info = status(args.dir)
    except FileNotFoundError as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    manifest = info["manifest"]
    print(f"{manifest.get('sweep', args.dir)}: {info['runs']} runs: {info['ok']} done, {info['failed']} failed, "
          f"{info['missing']} missing")
    if manifest.get("finished"):
        print(f"  last run finished {manifest['finished']} (git {manifest.get('git_revision')})")
    elif manifest:
        print(f"  last run started {manifest.get('started')} and did not finish (resume with flocksweep run)")
    for run_id, error in info["failures"][:50]:
        print(f"  failed {run_id}: {error}")
    if len(info["failures"]) > 50:
        print(f"  ... and {len(info['failures']) - 50} more")
    return 0


def _add_report(sub) -> None:
    p = sub.add_parser("report", help="statistics, figures and findings from a results directory",
                       description="Write a self-contained HTML report, the same as Markdown with figures, "
                                   "and the tables behind it as CSV (default: RESULTS_DIR/report/).")
    p.add_argument("dir", type=Path, help="results directory of a sweep (with runs.parquet)")
    p.add_argument("--metrics", nargs="+", metavar="NAME",
                   help="metrics (default: cohesion alignment stray_fraction groups elongation speed); "
                        "names like cohesion or columns like cohesion_final")
    p.add_argument("--by", nargs="+", metavar="FACTOR", help="factors to analyse (default: all swept factors)")
    p.add_argument("--out", type=Path, help="output directory (default RESULTS_DIR/report)")
    p.add_argument("--format", choices=("html", "md", "both"), default="both")
    p.add_argument("--seed", type=int, default=0, help="seed of the bootstrap resampling (default 0)")


def cmd_report(args) -> int:
    from analysis.reports.report import ReportError, build_report

    formats = ("html", "md") if args.format == "both" else (args.format,)
    try:
        result = build_report(args.dir, args.out, args.metrics, args.by, formats, args.seed)
    except (ReportError, FileNotFoundError) as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    for kind, path in result["paths"].items():
        print(f"  wrote {path}")
    print(f"  tables: {result['out'] / 'tables'} ({len(result['tables'])} CSV files); {result['seconds']:.1f} s")
    for name in ("findings", "leadership_findings"):
        findings = result["tables"].get(name)
        if findings is not None and len(findings):
            for key, group in findings.groupby("finding", sort=True):
                print(f"  {name.replace('_', ' ')[:-1]} ({key}): {group['verdict'].iloc[0]}: {group['claim'].iloc[0]}")
    return 0


def _add_calibrate(sub) -> None:
    p = sub.add_parser("calibrate", help="fit model parameters to target flock statistics",
                       description="Bayesian synthetic-likelihood MCMC (emcee) of the free parameters of a "
                                   "calibration TOML; writes the chain, posterior table, diagnostics and figures.")
    p.add_argument("config", help="calibration TOML, e.g. configs/calibration/recover_holland.toml")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the calibration file, e.g. --set method.steps=500")
    p.add_argument("--out", type=Path, help="output directory (default results/calibration/<name>)")
    p.add_argument("--resume", action="store_true", help="continue the stored chain up to method.steps")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--executor", choices=("serial", "local", "dask"), default="serial",
                   help="where simulations run: serial = this process, each evaluation's replicates on all "
                        "cores in one threaded compiled call (default); local = a "
                        "process pool evaluating walkers' proposals in parallel; dask = a cluster")
    p.add_argument("--workers", type=int, help="worker processes for local/dask (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDR", help="dask scheduler address; without it a LocalCluster starts")


def cmd_calibrate(args) -> int:
    from analysis.calibration.config import load_calibration
    from analysis.calibration.run import calibrate

    config = load_calibration(args.config, args.overrides)
    if args.workers is not None and args.workers < 1:
        raise ConfigError("--workers", f"got {args.workers}; expected an integer >= 1")
    if args.scheduler and args.executor != "dask":
        raise ConfigError("--scheduler", "only used with --executor dask")
    result = calibrate(config, args.out, resume=args.resume, progress=not args.no_progress,
                       executor=args.executor, workers=args.workers, scheduler=args.scheduler)
    if "optimum" in result:
        opt = result["optimum"]
        print("optimum: " + ", ".join(f"{k} = {v:.4g}" for k, v in opt["theta"].items()))
        print(f"  objective {opt['objective_common_seeds']:.4g} with the search's common seeds, "
              f"{opt['objective_recheck']:.4g} +- {opt['recheck_se']:.2g} re-checked with fresh seeds")
        print(f"  wrote {result['out']}")
        return 0
    print(result["summary"].round(4).to_string())
    for message in result["convergence"]["messages"] + result["warnings"]:
        print(f"  {message}")
    print(f"  wrote {result['out']}")
    return 0


def _add_targets(sub) -> None:
    p = sub.add_parser("targets", help="a calibration's targets: simulated at known parameters, or from tracks",
                       description="For parameter-recovery studies: run the calibration's model at the given "
                                   "truth and print a [targets] block to paste into the calibration file. "
                                   "With --from-tracks: the targets measured from tracks, one row per flock.")
    p.add_argument("config", help="calibration TOML")
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
    print(measured_targets_block(args.config, args.from_tracks or None), end="")
    return 0


def cmd_targets(args) -> int:
    import numpy as np

    from analysis.calibration.config import load_calibration
    from analysis.calibration.synthetic import synthetic_observation, targets_block
    from simcore.schema import parse_value

    if args.from_tracks is not None:
        return _targets_from_tracks(args)
    config = load_calibration(args.config)
    truth = {}
    for item in args.truth:
        name, sep, value = item.partition("=")
        if not sep:
            raise ConfigError("--truth", f"got {item!r}; expected NAME=VALUE")
        truth[name.strip()] = parse_value(value.strip())
    if args.replicates < 1:
        raise ConfigError("--replicates", f"got {args.replicates}; expected an integer >= 1")
    if args.sd:
        sd = [float(v) for v in args.sd.split(",")]
        if len(sd) != config.targets.k:
            raise ConfigError("--sd", f"got {len(sd)} values; expected {config.targets.k}, one per stat")
    elif config.targets.cov is not None:
        sd = np.sqrt(np.diag(config.targets.cov))
    else:
        raise ConfigError("--sd", "the file gives samples, not mean/sd: pass --sd with one value per stat")
    rows = synthetic_observation(config, truth, args.seed, args.replicates)
    if not np.isfinite(rows).all():
        raise ConfigError("--truth", "some runs gave undefined statistics at this truth; choose other stats")
    truth_text = ", ".join(f"{k} = {v}" for k, v in truth.items())
    print(f"# synthetic targets: {truth_text}; flocksweep targets --seed {args.seed} "
          f"--replicates {args.replicates}")
    print(targets_block(config, rows, sd), end="")
    return 0


def _add_sbc(sub) -> None:
    p = sub.add_parser("sbc", help="simulation-based calibration check of a calibration's posterior",
                       description="Talts et al. (2018): draw parameters from the prior, simulate a dataset at "
                                   "each, fit it with the file's emcee settings and test the ranks of the truths "
                                   "for uniformity. Finished datasets are kept: re-running resumes.")
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


def cmd_sbc(args) -> int:
    from analysis.calibration.config import load_calibration
    from analysis.calibration.sbc import run_sbc

    config = load_calibration(args.config, args.overrides)
    if config.method.kind != "emcee":
        raise ConfigError("method.kind", f"got {config.method.kind!r}; SBC checks the emcee (BSL) posterior")
    for flag, value in (("--datasets", args.datasets), ("--draws", args.draws), ("--workers", args.workers)):
        if value < 1:
            raise ConfigError(flag, f"got {value}; expected an integer >= 1")
    result = run_sbc(config, datasets=args.datasets, draws=args.draws, out_dir=args.out,
                     progress=not args.no_progress, steps=args.steps, walkers=args.walkers, workers=args.workers)
    print(result["table"].round(4).to_string())
    print(f"  {result['verdict']}")
    print(f"  wrote {result['out']}")
    return 0


def _add_view(sub) -> None:
    from analysis.viewer.command import DESCRIPTION, add_arguments

    add_arguments(sub.add_parser("view", help="interactive 3-D viewer page (and GIF/MP4) of a run",
                                 description=DESCRIPTION))


def cmd_view(args) -> int:
    from analysis.viewer.command import run

    return run(args)


def _add_measure(sub) -> None:
    from analysis.reports.measure_command import DESCRIPTION, add_arguments

    add_arguments(sub.add_parser("measure", help="flock metrics of measured tracks (tables and a report)",
                                 description=DESCRIPTION))


def cmd_measure(args) -> int:
    from analysis.reports.measure_command import run

    return run(args)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="flocksweep", description="Reproducible flocking-model sweeps.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_simulate(sub)
    _add_run(sub)
    _add_status(sub)
    _add_report(sub)
    _add_calibrate(sub)
    _add_targets(sub)
    _add_sbc(sub)
    _add_view(sub)
    _add_measure(sub)
    return parser


COMMANDS = {"simulate": cmd_simulate, "run": cmd_run, "status": cmd_status, "report": cmd_report,
            "calibrate": cmd_calibrate, "targets": cmd_targets, "sbc": cmd_sbc,
            "view": cmd_view, "measure": cmd_measure}


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except ConfigError as err:
        print(f"flocksweep: config error: {err}", file=sys.stderr)
        return 2
    except StoreLocked as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
