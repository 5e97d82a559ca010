"""``flocksweep targets``: a calibration's targets: simulated at known parameters, or from tracks."""
from __future__ import annotations

from flocksweep.command import Command
from flocksweep.simcore.schema import ConfigError, suggest
from flocksweep.sweeps.failures import check_count, parse_numbers

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
                   help="runs to average (default 1: one flock's statistics, as the likelihood assumes)")
    p.add_argument("--sd", help="measurement sd per stat, comma-separated (default: the file's sd)")
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
    print(next_lines(args.config))
    return 0


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
