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
``--out``. ``flocksweep/cli.py`` registers it with :func:`add_arguments` and :func:`run`; bad tracks, and
tracks of which no flock could be measured, exit with status 2 after listing every problem (and writing
``validation.csv``); warnings and flocks not measured are printed on stderr (the first 10).
"""
from __future__ import annotations

import sys
from pathlib import Path

from observables.track_names import FORMATS, LENGTH_UNITS, RECORDED, ROLES
from simcore.schema import ConfigError
from sweeps.failures import check_out

# the reading and measuring (observables: numpy and the numba kernels; .measured: pandas, matplotlib) are
# imported by run(), so that `flocksweep measure --help` starts in a fraction of a second

DESCRIPTION = ("Compute every flock metric from measured trajectories (long format: flock, id, t, x, y[, z]"
               "[, vx, vy, vz]): validate them, resample onto a regular interval, and write a runs table (one "
               "row per flock), time series per flock, a validation table and a short report with figures.")


def add_arguments(p) -> None:
    p.add_argument("tracks", type=Path, help="track file or folder: long CSV (also .csv.gz) or Parquet, one row per "
                                             "detection, or a tracker's or logger's file (--format)")
    p.add_argument("--group-radius", type=float, required=True, metavar="R",
                   help="individuals closer than R are linked into one group (analysis length units: body "
                        "lengths with --body-length, else metres); groups, cohesion and the shape metrics use it")
    p.add_argument("--format", choices=FORMATS, default=None,
                   help="file format (default: detected from the file): long csv or parquet; mat (MATLAB, with "
                        "--layout), idtracker (trajectories.npy/.npz), trex (a folder of per-individual exports), "
                        "trajr (a folder of one CSV per individual), movebank (GPS, projected to metres)")
    p.add_argument("--fps", type=float, metavar="HZ", help="frames per second, for times given as frame numbers")
    p.add_argument("--body-length-px", type=float, metavar="PX",
                   help="body length in pixels, for tracks in pixels (lengths become body lengths)")
    p.add_argument("--layout", nargs="+", default=[], metavar="KEY=VALUE",
                   help="a .mat file's array: variable=NAME axes=individual,channel,sample channels=x,y,vx,vy "
                        "[time=NAME]")
    p.add_argument("--columns", nargs="+", default=[], metavar="ROLE=NAME",
                   help=f"column map, e.g. id=bird t=time; roles: {', '.join(ROLES)}")
    p.add_argument("--units", nargs="+", default=[], metavar="KIND=UNIT",
                   help="length=m|cm|mm|km|bl|px and time=s|ms|min|h|datetime|frame (default m and s, or what the "
                        "format implies); a bare unit such as cm means length")
    p.add_argument("--body-length", type=float, metavar="METRES",
                   help="body length in metres: lengths become body lengths (BL), speeds BL/s")
    p.add_argument("--interval", type=float, metavar="S",
                   help="resample onto this sampling interval (default: each flock's median sample spacing)")
    p.add_argument("--max-gap", type=float, metavar="S", help="bridge gaps up to S seconds (default 2.5 intervals)")
    p.add_argument("--velocity-interval", metavar="S|recorded",
                   help="difference positions over S seconds (a whole number of intervals), or 'recorded' "
                        "(default: recorded when the file has velocities, else one interval)")
    p.add_argument("--warmup", type=float, default=0.0, help="seconds at the start left out of window means")
    p.add_argument("--fragmentation-cohesion", type=float, default=None,
                   help="cohesion below this counts as fragmented (default 0.5, "
                        "observables.metrics.FRAGMENTATION_COHESION)")
    p.add_argument("--max-speed", type=float, metavar="V",
                   help="impossible speed (analysis units/s; default 10 x each flock's median step speed)")
    p.add_argument("--bad-speeds", choices=("error", "keep", "drop"), default=None,
                   help="samples reached at an impossible speed: stop (default), keep them, or drop them")
    p.add_argument("--dcd-max-delay", type=float, default=None, metavar="S",
                   help="largest delay of the directional correlations (Nagy et al. 2010; default 2 s)")
    p.add_argument("--out", type=Path, help="output folder (default results/measured/<file stem>)")
    p.add_argument("--no-figures", action="store_true", help="write the report without figures (faster)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


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
                 "fragmentation_cohesion": "--fragmentation-cohesion", "dcd_max_delay": "--dcd-max-delay"}


def _print_warnings(issues, line_offset, out: Path) -> None:
    """The errors (flocks not measured) and warnings on stderr, the first SHOWN_WARNINGS of them."""
    from observables.validation import describe

    loud = [i for i in issues if i.level in ("error", "warning")]
    for issue in loud[:SHOWN_WARNINGS]:
        print(f"flocksweep: {describe(issue, line_offset)}", file=sys.stderr)
    if len(loud) > SHOWN_WARNINGS:
        print(f"flocksweep: ... and {len(loud) - SHOWN_WARNINGS} more in {out / 'validation.csv'}", file=sys.stderr)


def run(args) -> int:
    from observables.directional_correlation import DCD_MAX_DELAY
    from observables.measured import track_settings
    from observables.metrics import FRAGMENTATION_COHESION
    from observables.tracks import track_source
    from observables.validation import TrackError

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
