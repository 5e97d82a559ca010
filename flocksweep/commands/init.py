"""``flocksweep init``: a ready calibration file from a tracks file and a model preset.

The options and the handler; the work is :mod:`flocksweep.analysis.calibration.starter`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "write a ready calibration file from a tracks file and a model preset"
DESCRIPTION = ("Start a fit to a measured flock: measure the tracks and write a calibration file whose targets come "
               "from them, with an [observation] block that matches them (sampling interval, velocities, 2-D "
               "projection, detections), the model scaled to the tracks (flock size, speed, spacing) and priors sized "
               "from the measured scales, every line commented. Edit the priors, then run flocksweep calibrate on it.")


def arguments(p) -> None:
    p.add_argument("tracks", type=Path, help="the track file (long CSV/Parquet, or a tracker's format with its sidecar "
                                             "JSON or the options below), in body lengths (see --body-length)")
    p.add_argument("--model", type=Path, required=True, help="the model preset, e.g. configs/models/holland.toml")
    p.add_argument("--out", type=Path, help="the calibration file to write (default: <tracks>_<model>.toml here)")
    p.add_argument("--method", default="npe", help="the file's method (default npe; flocksweep calibrate --method "
                                                   "runs another)")
    p.add_argument("--stats", help="comma-separated statistics to fit (default polarization,nn_distance,speed_mean,"
                                   "speed_cv)")
    p.add_argument("--name", help="the calibration's name (default from the tracks and the model)")
    p.add_argument("--body-length", type=float, metavar="METRES",
                   help="body length in metres, for tracks in metres (lengths become body lengths)")
    p.add_argument("--units", nargs="+", default=[], metavar="KIND=UNIT",
                   help="length=m|cm|mm|km|bl|px and time=s|ms|min|h|datetime|frame, as flocksweep measure takes them")
    p.add_argument("--columns", nargs="+", default=[], metavar="ROLE=NAME", help="column map, e.g. id=bird t=time")
    p.add_argument("--format", default=None, help="file format (default: detected), as flocksweep measure takes it")
    p.add_argument("--fps", type=float, metavar="HZ", help="frames per second, for times given as frame numbers")
    p.add_argument("--body-length-px", type=float, metavar="PX", help="body length in pixels, for tracks in pixels")
    p.add_argument("--force", action="store_true", help="replace the file if it exists")


def _pairs(flag: str, items) -> dict:
    from flocksweep.simcore.schema import ConfigError

    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key or not value:
            raise ConfigError(flag, f"got {item!r}; expected KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def handler(args) -> int:
    from flocksweep.analysis.calibration.starter import STATS, start_calibration
    from flocksweep.sweeps.failures import check_out

    reading = {"body_length": args.body_length, "format": args.format, "fps": args.fps,
               "body_length_px": args.body_length_px}
    units = _pairs("--units", args.units)
    if units:
        reading["units"] = {("length" if key not in ("length", "time") else key): value for key, value in units.items()}
    columns = _pairs("--columns", args.columns)
    if columns:
        reading["columns"] = columns
    reading = {k: v for k, v in reading.items() if v is not None}
    stats = tuple(s.strip() for s in args.stats.split(",")) if args.stats else STATS
    out = args.out or Path(f"{args.tracks.name.split('.')[0]}_{args.model.stem}.toml")
    check_out("--out", out.parent if str(out.parent) not in ("", ".") else None)
    started = start_calibration(args.tracks, args.model, out, reading, stats, args.method, args.name, args.force)
    m = started.measured
    print(f"measured {m['flocks']} flock(s): {m['individuals']:.0f} individuals, speed {m['speed']:.3g} BL/s, "
          f"nearest-neighbour distance {m['nn_distance']:.3g} BL, polarization {m['polarization']:.3g}")
    print(f"free parameters: {', '.join(f'{k} ({v})' for k, v in started.parameters.items())}")
    print(f"wrote {started.path}")
    print(f"next: edit its priors, then: flocksweep calibrate {started.path}")
    return 0


COMMAND = Command("init", HELP, DESCRIPTION, arguments, handler)
