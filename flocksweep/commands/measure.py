"""``flocksweep measure``: flock metrics of measured tracks (tables and a report).

The options and the handler; the work is :mod:`flocksweep.analysis.reports.measure_command`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "flock metrics of measured tracks (tables and a report)"
DESCRIPTION = ("Compute every flock metric from measured trajectories (long format: flock, id, t, x, y[, z]"
               "[, vx, vy, vz]): validate them, resample onto a regular interval, and write a runs table (one "
               "row per flock), time series per flock, a validation table and a short report with figures.")


def add_reading_options(p, formats, roles, fps_flag: str = "--fps") -> None:
    """How a track file is read: the options `measure` and `view` share (observables.tracks.TrackSource;
    a command module that imports this one pays nothing: it declares options only). ``fps_flag`` names
    the frame-rate option (`view` has its own --fps, the animation's)."""
    p.add_argument("--format", choices=formats, default=None,
                   help="file format (default: detected from the file): long csv or parquet; mat (MATLAB) and npy "
                        "(numpy .npy/.npz), both with --layout; idtracker (trajectories.npy/.npz), trex (a folder of "
                        "per-individual exports), trajr (a folder of one CSV per individual), movebank (GPS, "
                        "projected to metres)")
    p.add_argument(fps_flag, dest="tracks_fps", type=float, metavar="HZ",
                   help="frames per second of the tracks, for times given as frame numbers")
    p.add_argument("--body-length-px", type=float, metavar="PX",
                   help="body length in pixels, for tracks in pixels (lengths become body lengths)")
    p.add_argument("--layout", nargs="+", default=[], metavar="KEY=VALUE",
                   help="an array file's layout (mat, npy): a 3-D array: channels=x,y,vx,vy,-,- (- skips a channel; "
                        "or x:0,y:1 by index) [axes=individual,channel,sample] [time=NAME]; a 2-D detection table "
                        "(one row per individual per sample): columns=id,t,x,y,z,-,... (t or frame); "
                        "[variable=NAME]")
    p.add_argument("--columns", nargs="+", default=[], metavar="ROLE=NAME",
                   help=f"column map, e.g. id=bird t=time; roles: {', '.join(roles)}")
    p.add_argument("--units", nargs="+", default=[], metavar="KIND=UNIT",
                   help="length=m|cm|mm|km|bl|px and time=s|ms|min|h|datetime|frame (default m and s, or what the "
                        "format implies); a bare unit such as cm means length")
    p.add_argument("--body-length", type=float, metavar="METRES",
                   help="body length in metres: lengths become body lengths (BL), speeds BL/s")
    p.add_argument("--keep-padding", action="store_true", default=None,
                   help="keep trailing (and leading) samples at which every recorded velocity is exactly zero "
                        "(default: dropped as a logger's padding, with a warning)")
    p.add_argument("--trim", metavar="START:END",
                   help="measure only these samples of each flock: whole numbers count samples, numbers with s "
                        "seconds, negative ones from the end (10:-10, 2s:, :-0.5s)")
    p.add_argument("--max-speed", type=float, metavar="V",
                   help="impossible speed (analysis units/s; default 10 x each flock's median step speed)")
    p.add_argument("--bad-speeds", choices=("error", "keep", "drop"), default=None,
                   help="glitches (samples reached at an impossible speed while the group does not move so): "
                        "stop (default), keep them, or drop them")
    p.add_argument("--burst-share", type=float, metavar="F",
                   help="a fast sample is the group's burst (kept) when this share of the others moves with it "
                        "(default 0.5)")
    p.add_argument("--burst-frames", type=float, metavar="K",
                   help="... within K sampling intervals (default 5)")
    p.add_argument("--burst-jump", type=float, metavar="X",
                   help="... each faster than X times its own recent speed (default 3)")


def arguments(p) -> None:
    from flocksweep.observables.track_names import FORMATS, ROLES   # only when its options are declared

    p.add_argument("tracks", type=Path, help="track file or folder: long CSV (also .csv.gz) or Parquet, one row per "
                                             "detection, or a tracker's or logger's file (--format)")
    p.add_argument("--group-radius", type=float, required=True, metavar="R",
                   help="individuals closer than R are linked into one group (analysis length units: body "
                        "lengths with --body-length, else metres); groups, cohesion and the shape metrics use it")
    add_reading_options(p, FORMATS, ROLES)
    p.add_argument("--interval", type=float, metavar="S",
                   help="resample onto this sampling interval (default: each flock's own, from its frame rate or "
                        "its time stamps)")
    p.add_argument("--max-gap", type=float, metavar="S", help="bridge gaps up to S seconds (default 2.5 intervals)")
    p.add_argument("--velocity-interval", metavar="S|recorded",
                   help="difference positions over S seconds (a whole number of intervals), or 'recorded' "
                        "(default: recorded when the file has velocities, else one interval)")
    p.add_argument("--warmup", type=float, default=0.0, help="seconds at the start left out of window means")
    p.add_argument("--fragmentation-cohesion", type=float, default=None,
                   help="cohesion below this counts as fragmented (default 0.5, "
                        "observables.metrics.FRAGMENTATION_COHESION)")
    p.add_argument("--dcd-max-delay", type=float, default=None, metavar="S",
                   help="largest delay of the directional correlations (Nagy et al. 2010; default 2 s)")
    p.add_argument("--k-nearest", type=int, default=None, metavar="K",
                   help="the k of the knn_* metrics (where the k nearest neighbours sit; default 6)")
    p.add_argument("--state-high", type=float, default=None, metavar="X",
                   help="state fractions (Tunstrom et al. 2013): an order parameter above X is high (default 0.65)")
    p.add_argument("--state-low", type=float, default=None, metavar="X",
                   help="... and below X low (default 0.35)")
    p.add_argument("--no-pairwise-metrics", action="store_true",
                   help="skip the metrics that rank every pair of every record (knn_*, corr_length: nan); "
                        "faster for large groups")
    p.add_argument("--out", type=Path, help="output folder (default results/measured/<file stem>)")
    p.add_argument("--no-figures", action="store_true", help="write the report without figures (faster)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def _pairs(items, flag: str, bare: str | None = None) -> dict:
    from flocksweep.simcore.schema import ConfigError

    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            if bare is None:
                raise ConfigError(flag, f"got {item!r}; expected KEY=VALUE")
            key, value = bare, item
        if key.strip() in out:
            raise ConfigError(flag, f"{key.strip()} is given twice")
        out[key.strip()] = value.strip()
    return out


def reading_given(args) -> dict:
    """The track-reading settings given on the command line (observables.tracks.TrackSource keys), each
    only when given: the sidecar's and the format's defaults fill the rest."""
    from flocksweep.observables.track_names import LENGTH_UNITS

    units = _pairs(args.units, "--units", bare="length")
    if "length" in units and units["length"] not in LENGTH_UNITS:
        units["length"] = units["length"].lower()
    given = {"columns": _pairs(args.columns, "--columns"), "units": units, "body_length": args.body_length,
             "max_speed": args.max_speed, "bad_speeds": args.bad_speeds, "format": args.format, "fps": args.tracks_fps,
             "body_length_px": args.body_length_px, "layout": _pairs(args.layout, "--layout"),
             "keep_padding": args.keep_padding, "trim": args.trim, "burst_share": args.burst_share,
             "burst_frames": args.burst_frames, "burst_jump": args.burst_jump}
    return {k: v for k, v in given.items() if v not in (None, {})}


def handler(args) -> int:
    from flocksweep.analysis.reports.measure_command import run

    args.reading = reading_given(args)
    return run(args)


COMMAND = Command("measure", HELP, DESCRIPTION, arguments, handler)
