"""The ``flocksweep`` command line. Subcommands parse their arguments here and call library code.

    flocksweep simulate MODEL.toml [--set key=value ...] [--seed S] [--n N] [--duration T] [--dt DT]
                        [--record-every STEPS] [--out DIR] [--plot] [--color-by auto|boid|pattern]

Exit status: 0 on success, 2 for bad input (a config error names the key, the value and what is allowed).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simcore import ConfigError, load_preset


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
    p.add_argument("--plot", action="store_true",
                   help="save a PNG of the 3-D traces (into --out, default results/simulate/NAME-seedS/)")
    p.add_argument("--color-by", choices=("auto", "boid", "pattern"), default="auto",
                   help="trace colours: one per boid, or per pattern (auto: pattern in pattern mode)")


def cmd_simulate(args) -> int:
    from sweeps.single import run_single

    overrides = list(args.overrides)
    for flag, key in ((args.n, "init.n"), (args.duration, "run.duration"), (args.dt, "run.dt")):
        if flag is not None:
            overrides.append(f"{key}={flag!r}")
    preset = load_preset(args.model, overrides)
    if args.record_every < 1:
        raise ConfigError("--record-every", f"got {args.record_every}; must be an integer >= 1")
    if args.seed < 0:
        raise ConfigError("--seed", f"got {args.seed}; must be an integer >= 0")
    out = args.out
    if out is None and args.plot:
        out = Path("results") / "simulate" / f"{preset.model.name}-seed{args.seed}"
    summary, written = run_single(preset, args.seed, out, args.plot, args.color_by, args.record_every)
    print(f"{preset.model.name}: N={summary['n']}, {summary['time_s']:g} s simulated in {summary['wall_s']:.2f} s")
    print(f"  final polarization     {summary['final_polarization']:.3f}")
    print(f"  final mean speed       {summary['final_mean_speed']:.3f}")
    print(f"  mean visible neighbours {summary['final_mean_visible']:.2f}"
          f" (binocular share {summary['final_binocular_share']:.2f})")
    for path in written:
        print(f"  wrote {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="flocksweep", description="Reproducible flocking-model sweeps.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_simulate(sub)
    return parser


COMMANDS = {"simulate": cmd_simulate}


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except ConfigError as err:
        print(f"flocksweep: config error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
