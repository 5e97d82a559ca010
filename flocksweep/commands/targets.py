"""``flocksweep targets``: a calibration's targets: simulated at known parameters, or from tracks."""
from __future__ import annotations

from flocksweep.command import Command
from flocksweep.simcore.schema import ConfigError, suggest
from flocksweep.sweeps.failures import check_count, check_out_file, parse_numbers

HELP = "a calibration's targets: simulated at known parameters, or from tracks"
DESCRIPTION = ("For parameter-recovery studies: run the calibration's model at the given truth and print a [targets]"
               " block to paste into the calibration file. With --from-tracks: the targets measured from tracks, one"
               " row per flock.")


def arguments(p) -> None:
    p.add_argument("config", help="calibration TOML")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key of the calibration file, as for calibrate (repeatable), e.g. "
                        "--set observation.velocity_interval=0.4")
    p.add_argument("--truth", action="append", default=[], metavar="NAME=VALUE",
                   help="value of a free parameter (repeat for each), e.g. --truth field=150")
    p.add_argument("--seed", type=int, default=0, help="seed of the synthetic runs (default 0)")
    p.add_argument("--replicates", type=int, default=1,
                   help="flocks to simulate (default 1: one flock's statistics); several are averaged, or with "
                        "--samples written one row each")
    p.add_argument("--sd", help="measurement sd per stat, comma-separated (default: the file's sd)")
    p.add_argument("--samples", metavar="CSV",
                   help="instead of averaging the --replicates runs: write each run's statistics as a row of CSV "
                        "(one observed flock each) and print a [targets] table that reads them (samples = CSV)")
    p.add_argument("--from-tracks", nargs="?", const="", metavar="TRACKS",
                   help="instead: print the targets measured from tracks (the file's from_tracks, or TRACKS), "
                        "one row per flock, with the file's [observation] block")


def handler(args) -> int:
    import numpy as np

    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.synthetic import synthetic_observation, targets_block
    from flocksweep.simcore.schema import parse_value

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
    if args.samples is not None:
        check_samples_path(args.samples)        # before any run
        if args.sd:
            raise ConfigError("--sd", "not with --samples: the rows carry their own spread (the flocks' run-to-run "
                                      "variation); drop --sd, or drop --samples for mean and sd targets")
        sd = None
    elif args.sd:
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
    samples = None if args.samples is None else write_samples(config, rows, args.samples, args.config)
    print(f"# synthetic targets: {truth_text}; flocksweep targets --seed {args.seed} "
          f"--replicates {args.replicates}" + (f" --samples {args.samples}" if samples else ""))
    print(targets_block(config, rows, sd, truth, flock if np.isfinite(flock).all() else None, samples=samples), end="")
    print(next_lines(args.config))
    return 0


def check_samples_path(path) -> None:
    """``--samples``: a .csv file we may write (not a folder, not below a file)."""
    check_out_file("--samples", path)
    if not str(path).lower().endswith(".csv"):
        raise ConfigError("--samples", f"got {path!r}; expected a .csv file to write the runs' rows to")


def write_samples(config, rows, path, config_path) -> str:
    """Write ``rows`` (replicates, k) as CSV at ``path`` (atomically; one column per stat, named as
    ``targets.samples`` reads them) and return the path as the calibration file names it: relative to
    the file's folder when it lies under it, else absolute."""
    import os
    from pathlib import Path

    import pandas as pd

    from flocksweep.sweeps.files import atomic_path

    where = Path(path)
    where.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(where) as tmp:
        pd.DataFrame(rows, columns=list(config.targets.stats)).to_csv(tmp, index=False, float_format="%.17g")
    base = Path(config_path).resolve().parent
    absolute = where.resolve()
    return os.path.relpath(absolute, base) if absolute.is_relative_to(base) else str(absolute)


def next_lines(config) -> str:
    """The next steps as TOML comments (this command's output is a [targets] table to paste)."""
    return (f"# next: put this [targets] table in {config} (in place of its own), then run\n"
            f"#   flocksweep calibrate {config}")

def _targets_from_tracks(args) -> int:
    from flocksweep.analysis.calibration.synthetic import measured_targets_block

    if args.truth:
        raise ConfigError("--from-tracks", "measured targets take no --truth")
    print(measured_targets_block(args.config, args.from_tracks or None, args.overrides), end="")
    print(next_lines(args.config))
    return 0


COMMAND = Command("targets", HELP, DESCRIPTION, arguments, handler)
