"""The parts of ``flocksweep run`` that grow a sweep in rounds (``--until-ci``, ``--until-claims``) and
the closing line on runs left missing by dead workers; argument parsing stays in :mod:`flocksweep.cli`.

Each ``run_until_*_command(args, config, out)`` checks its flags (ConfigError naming the flag), runs the
rounds through :func:`sweeps.runner.run_until` and returns the command's exit status.
"""
from __future__ import annotations

import sys

from simcore.schema import ConfigError, suggest

from sweeps.failures import INCOMPLETE


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
    columns = summary_columns(leadership=True, migration=True, encounters=ENCOUNTER_FAMILIES)
    column = metric if metric in columns else f"{metric}_mean"
    if column not in columns:
        raise ConfigError("--until-ci", f"unknown metric {metric!r}{suggest(metric, columns)}; expected a summary "
                                        "column such as cohesion_mean or polarization_final")
    return column, target


def run_until_ci_command(args, config, out, metric: str, target: float) -> int:
    from sweeps.runner import run_until_ci

    if args.max_replicates < config.replicates:
        raise ConfigError("--max-replicates", f"got {args.max_replicates}; must be >= replicates ({config.replicates})")
    if args.dry_run:
        raise ConfigError("--until-ci", "cannot be combined with --dry-run (the rounds depend on the results)")
    print(f"{config.name}: adding replicates until the 95% CI half-width of {metric} <= {target:g} "
          f"(at most {args.max_replicates} per cell)")
    result = run_until_ci(config, args.sweep_text, out, metric, target, args.max_replicates,
                          executor=args.executor, workers=args.workers, scheduler=args.scheduler,
                          force=args.force, retry_failed=args.retry_failed, progress=not args.no_progress,
                          batch_size=args.batch_size, yes=args.yes)
    table = result.table
    print(f"{config.name}: {len(table)} runs in {out / 'runs.parquet'} "
          f"({int((table['status'] == 'ok').sum())} ok)")
    return report_lost(args, result)


def run_until_claims_command(args, config, out) -> int:
    from analysis.reports.claims.until import claims_rule
    from sweeps.claims import sweep_columns
    from sweeps.runner import run_until

    if not config.claims:
        raise ConfigError("--until-claims", f"{args.sweep or 'the sweep'} declares no claims ([[claims]] or include_claims)")
    if args.max_replicates < config.replicates:
        raise ConfigError("--max-replicates", f"got {args.max_replicates}; must be >= replicates ({config.replicates})")
    if args.dry_run:
        raise ConfigError("--until-claims", "cannot be combined with --dry-run (the rounds depend on the results)")
    print(f"{config.name}: adding replicates where a claim is undecided (at most {args.max_replicates} per cell); "
          f"claims {', '.join(c.id for c in config.claims)}")
    factors = sweep_columns(config.axes, config.sample or config.design, config.metrics.leadership).factors
    result = run_until(config, args.sweep_text, out,
                       claims_rule(config.claims, factors), args.max_replicates, executor=args.executor,
                       workers=args.workers, scheduler=args.scheduler, force=args.force,
                       retry_failed=args.retry_failed, progress=not args.no_progress, batch_size=args.batch_size,
                       yes=args.yes)
    table = result.table
    print(f"{config.name}: {len(table)} runs in {out / 'runs.parquet'} "
          f"({int((table['status'] == 'ok').sum())} ok); `flocksweep report {out}` shows the claims' evidence")
    return report_lost(args, result)
