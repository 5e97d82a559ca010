"""``flocksweep simulate``: run one simulation from a model preset."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command
from flocksweep.sweeps.failures import check_count, check_out

HELP = "run one simulation from a model preset"
DESCRIPTION = "Run one simulation from a model preset TOML and print a short summary."


def arguments(p) -> None:
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
    p.add_argument("--init-state", type=Path, metavar="FILE",
                   help="start from the state in FILE (.npz with pos, vel or fwd + speed, optional up, acc, "
                        "pattern; or a trajectory.npz, whose last record is used); sets init.from_file and init.n")


def handler(args) -> int:
    import json

    from flocksweep.simcore import load_preset
    from flocksweep.simcore.params import RUN_SHORTHANDS
    from flocksweep.sweeps.progress import next_steps
    from flocksweep.sweeps.single import run_single

    overrides = list(args.overrides)
    if args.init_state is not None:
        from flocksweep.simcore.initfile import boid_count

        overrides.append(f"init.from_file={json.dumps(str(args.init_state))}")
        if args.n is None:
            overrides.append(f"init.n={boid_count(args.init_state)}")
    for short in ("n", "duration", "dt"):  # the [run] shorthands of sweep files
        if getattr(args, short) is not None:
            overrides.append(f"{RUN_SHORTHANDS[short]}={getattr(args, short)!r}")
    from flocksweep.sweeps.budget import check_runs

    preset = load_preset(args.model, overrides)
    check_count("--record-every", args.record_every, 1, preset.run.n_steps)   # at least one record after t = 0
    check_count("--seed", args.seed, 0, 2 ** 63 - 1)
    check_out("--out", args.out)
    check_runs("init.n", preset.init.n, preset.run.n_steps, args.record_every)
    out = args.out
    if out is None and (args.plot or args.tracks):
        out = Path("results") / "simulate" / f"{preset.model.name}-seed{args.seed}"
    summary, written, obs = run_single(preset, args.seed, out, args.record_every, args.tracks)
    if args.plot:
        from flocksweep.analysis.reports.traces import plot_traces, wrap_distance

        title = (f"{preset.model.name}: N={obs.n}, {obs.times[-1]:g} s, seed {args.seed}, "
                 f"final polarization {summary['polarization_final']:.2f}")
        written.append(plot_traces(obs.pos, Path(out) / "traces.png", obs.pattern, args.color_by,
                                   wrap_distance(preset.model), title, preset.model.world.obstacles,
                                   obs.predator, obs.prey))
    compiled = f" (+ {summary['compile_s']:.1f} s compiling its run loop, once)" if summary["compile_s"] else ""
    print(f"{preset.model.name}: N={summary['n']}, {summary['time_s']:g} s simulated in {summary['wall_s']:.2f} s"
          f"{compiled}")
    print(f"  final polarization     {summary['polarization_final']:.3f}")
    print(f"  final mean speed       {summary['speed_mean_final']:.3f}")
    print(f"  mean visible neighbours {summary['visible_mean_final']:.2f}"
          f" (binocular share {summary['binocular_share_final']:.2f})")
    if "collided_boids" in summary:
        print(f"  obstacles: {summary['collided_boids']:g} boids collided, least clearance "
              f"{summary['clearance_min']:.3f}")
    if "predator_captures" in summary:
        print(f"  predator: {summary['predator_captures']:g} boids captured, nearest approach "
              f"{summary['predator_distance_min']:.2f}")
    if "prey_reach_time" in summary:
        print(f"  prey: the flock's centre reached it at t = {summary['prey_reach_time']:g} s (nan: never)")
    for path in written:
        print(f"  wrote {path}")
    next_steps(*after_simulate(args, out, written))
    return 0


def after_simulate(args, out, written) -> list[str]:
    """Watch the run in 3-D (its trajectory, or the preset re-simulated), then sweep a parameter of it."""
    import shlex

    trajectory = [p for p in written if Path(p).name == "trajectory.npz"]
    if trajectory:
        view = f"flocksweep view {trajectory[0]}"
    else:
        extra = [f"--set={item}" for item in args.overrides] + [f"--seed={args.seed}"]
        extra += [f"--{flag}={getattr(args, flag)}" for flag in ("n", "duration", "dt") if getattr(args, flag) is not None]
        view = "flocksweep view " + " ".join(shlex.quote(str(word)) for word in [args.model, *extra])
    return [f"{view}   (this run in 3-D)",
            f"flocksweep run --model {args.model} --axis perception.field_deg=60,120,180   "
            f"(a sweep: any key, several values; docs/sweeps.md)"]


COMMAND = Command("simulate", HELP, DESCRIPTION, arguments, handler)
