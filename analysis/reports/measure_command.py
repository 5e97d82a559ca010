"""``flocksweep measure``: the command line of :func:`analysis.reports.measured.measure_folder`.

    flocksweep measure TRACKS --group-radius R [--format auto|csv|parquet|mat|idtracker|trex|trajr|movebank]
                       [--fps HZ] [--body-length-px PX] [--layout KEY=VALUE ...] [--columns ROLE=NAME ...]
                       [--units length=m|cm|mm|km|bl|px time=s|ms|min|h|datetime|frame] [--body-length METRES]
                       [--interval S] [--max-gap S] [--velocity-interval S|recorded] [--warmup S]
                       [--fragmentation-cohesion C] [--max-speed V] [--bad-speeds error|keep|drop] [--out DIR]
                       [--no-figures] [--no-progress]

Lengths given here (group radius, max speed) are in the analysis units: body lengths with
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

from flocksweep.observables.track_names import LENGTH_UNITS, RECORDED
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.failures import check_out

# the reading and measuring (observables: numpy and the numba kernels; .measured: pandas, matplotlib) are
# imported by run(), so that `flocksweep measure --help` starts in a fraction of a second


def _pairs(items, flag: str, bare: str | None = None) -> dict:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            if bare is None:
                raise ConfigError(flag, f"got {item!r}; expected KEY=VALUE")
            key, value = bare, item
        out[key.strip()] = value.strip()
    return out


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
    units = _pairs(args.units, "--units", bare="length")
    if "length" in units and units["length"] not in LENGTH_UNITS:
        units["length"] = units["length"].lower()
    given = {"columns": _pairs(args.columns, "--columns"), "units": units, "body_length": args.body_length,
             "max_speed": args.max_speed, "bad_speeds": args.bad_speeds, "format": args.format, "fps": args.fps,
             "body_length_px": args.body_length_px, "layout": _pairs(args.layout, "--layout")}
    given = {k: v for k, v in given.items() if v not in (None, {})}
    source = track_source(args.tracks, given, "")
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
    shown = runs[["flock", "individuals", "records", "tracked_mean", "polarization_mean", "nn_distance_mean",
                  "speed_mean_mean", "cohesion_mean"]]
    print(shown.head(20).round(4).to_string(index=False))
    _print_warnings(result["measurement"].issues, table.line_offset, out)
    for path in result["paths"].values():
        print(f"  wrote {path}")
    print(f"  tables: {result['out'] / 'runs.parquet'}, {result['out'] / 'timeseries.parquet'}, "
          f"{result['out'] / 'validation.csv'}; {result['seconds']:.1f} s")
    return 0
