"""``flocksweep measure``: the command line of :func:`analysis.reports.measured.measure_folder`.

    flocksweep measure TRACKS --group-radius R [--format auto|csv|parquet|mat|npy|idtracker|trex|trajr|movebank]
                       [--fps HZ] [--body-length-px PX] [--layout KEY=VALUE ...] [--columns ROLE=NAME ...]
                       [--units length=m|cm|mm|km|bl|px time=s|ms|min|h|datetime|frame] [--body-length METRES]
                       [--keep-padding] [--trim START:END] [--max-speed V] [--bad-speeds error|keep|drop]
                       [--burst-share F] [--burst-frames K] [--burst-jump X]
                       [--interval S] [--max-gap S] [--velocity-interval S|recorded] [--warmup S]
                       [--fragmentation-cohesion C] [--dcd-max-delay S] [--out DIR] [--no-figures] [--no-progress]

The reading options are parsed by the command (``flocksweep.commands.measure.reading_given``) into
``args.reading``, the :class:`~observables.tracks.TrackSource` settings given. Lengths given here (group
radius, max speed) are in the analysis units: body lengths with
``--body-length`` (or tracks already in body lengths), metres otherwise. Velocities: the tracks' own
when they have velocity columns and no ``--velocity-interval`` is given, else positions differenced over
``--velocity-interval`` (default one sampling interval). Output: ``results/measured/<file stem>/`` unless
``--out``. The command is declared in ``flocksweep/commands/measure.py``, whose handler calls :func:`run`; bad tracks, and
tracks of which no flock could be measured, exit with status 2 after listing every problem (and writing
``validation.csv``); warnings and flocks not measured are printed on stderr (the first 10).
"""
from __future__ import annotations

import dataclasses

import sys
from pathlib import Path

from flocksweep.observables.track_names import RECORDED
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.failures import check_out
from flocksweep.sweeps.progress import next_steps

# the reading and measuring (observables: numpy and the numba kernels; .measured: pandas, matplotlib) are
# imported by run(), so that `flocksweep measure --help` starts in a fraction of a second


def _velocity_interval(text: str | None):
    if text is None:
        return "auto"
    if text == RECORDED:
        return text
    try:
        return float(text)
    except ValueError:
        raise ConfigError("--velocity-interval", f"got {text!r}; expected seconds or 'recorded'") from None


SHOWN_WARNINGS = 10
# a metric setting's key (MetricSettings) -> the flag that sets it
SETTING_FLAGS = {"group_radius": "--group-radius", "warmup": "--warmup",
                 "fragmentation_cohesion": "--fragmentation-cohesion", "dcd_max_delay": "--dcd-max-delay",
                 "k_nearest": "--k-nearest", "state_high": "--state-high", "state_low": "--state-low"}


def _print_warnings(issues, line_offset, out: Path) -> None:
    """The errors (flocks not measured) and warnings on stderr, the first SHOWN_WARNINGS of them."""
    from flocksweep.observables.validation import describe

    loud = [i for i in issues if i.level in ("error", "warning")]
    for issue in loud[:SHOWN_WARNINGS]:
        print(f"flocksweep: {describe(issue, line_offset)}", file=sys.stderr)
    if len(loud) > SHOWN_WARNINGS:
        print(f"flocksweep: ... and {len(loud) - SHOWN_WARNINGS} more in {out / 'validation.csv'}", file=sys.stderr)


def run(args) -> int:
    from flocksweep.observables.directional_correlation import DCD_MAX_DELAY
    from flocksweep.observables.measured import track_settings
    from flocksweep.observables.metrics import FRAGMENTATION_COHESION
    from flocksweep.observables.tracks import track_source
    from flocksweep.observables.validation import TrackError

    from .measured import measure_folder

    if args.fragmentation_cohesion is None:
        args.fragmentation_cohesion = FRAGMENTATION_COHESION
    if args.dcd_max_delay is None:
        args.dcd_max_delay = DCD_MAX_DELAY
    source = track_source(args.tracks, args.reading, "")
    if not args.dcd_max_delay >= 0:
        raise ConfigError("--dcd-max-delay", f"got {args.dcd_max_delay}; expected seconds >= 0")
    for flag, value in (("--interval", args.interval), ("--max-gap", args.max_gap)):
        if value is not None and not value > 0:
            raise ConfigError(flag, f"got {value}; expected seconds > 0")
    try:
        settings = track_settings(args.group_radius, args.warmup, args.fragmentation_cohesion, args.dcd_max_delay)
        motion = {"k_nearest": args.k_nearest, "state_high": args.state_high, "state_low": args.state_low}
        settings = dataclasses.replace(settings, pairwise_metrics=not args.no_pairwise_metrics,
                                       **{key: value for key, value in motion.items() if value is not None})
    except ConfigError as err:
        raise ConfigError(SETTING_FLAGS.get(err.key, "--group-radius"), err.detail) from None
    except ValueError as err:
        raise ConfigError("--group-radius", str(err)) from None
    check_out("--out", args.out)
    out = args.out or Path("results") / "measured" / args.tracks.name.split(".")[0]
    try:
        result = measure_folder(args.tracks, source, settings, out, args.interval, args.max_gap,
                                _velocity_interval(args.velocity_interval), figures=not args.no_figures,
                                progress=not args.no_progress)
    except TrackError as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        print(f"  (every problem is listed in {out / 'validation.csv'})", file=sys.stderr)
        return 2
    runs = result["measurement"].runs
    table = result["measurement"].table
    print(f"{table.path.name}: {len(runs)} flock(s), {int((runs['status'] == 'ok').sum())} measured, "
          f"{table.dims}-D, lengths in {table.unit_label}; {len(result['issues'])} validation issue(s)")
    scales = ", ".join(f"{name} {entry['value']} ({entry['from']})" for name, entry in table.source.scales().items()
                       if name != "analysis length unit")
    clocks = sorted(set(runs.loc[runs["status"] == "ok", "clock"]))
    print(f"  units: {scales}" + (f"; records every {float(runs['interval'].iloc[0])!r} s: {clocks[0]}" if len(clocks) == 1
                                  else ""))
    shown = runs[["flock", "individuals", "records", "tracked_mean", "polarization_mean", "nn_distance_mean",
                  "speed_mean_mean", "cohesion_mean"]]
    print(shown.head(20).round(4).to_string(index=False))
    _print_warnings(result["measurement"].issues, table.line_offset, out)
    for path in result["paths"].values():
        print(f"  wrote {path}")
    print(f"  tables: {result['out'] / 'runs.parquet'}, {result['out'] / 'timeseries.parquet'}, "
          f"{result['out'] / 'validation.csv'}; {result['seconds']:.1f} s")
    next_steps(*after_measure(args.tracks, result))
    return 0


def after_measure(tracks: Path, result: dict) -> list[str]:
    """Look at the measurement and the flocks, then start a fit to these tracks (``flocksweep init``
    writes the calibration file)."""
    page = result["paths"].get("html") or result["paths"].get("md")
    steps = [f"open {page} in a browser (the flocks' metrics, figures and what the checks found)"] if page else []
    return steps + [f"flocksweep view {tracks}   (the flocks in the 3-D viewer)",
                    f"flocksweep init {tracks} --model configs/models/holland.toml --out fit.toml   (a "
                    "calibration file from these tracks: targets, observation block, priors; then "
                    "flocksweep calibrate fit.toml)"]
