"""Throughput of one model from its preset: boid-steps per second, single thread, after compilation.

    python bench/bench_models.py --model reynolds87 [--sizes 100 1000] [--obstacles 10] [--repeats 5]
                                 [--set KEY=VALUE ...]

``--model`` names a preset in configs/models/ (``reynolds87``, ``reynolds87_obstacles``, ``hartman_benes``,
...; a model added later needs only its preset). ``--obstacles K`` keeps the first K obstacles of
configs/models/reynolds87_obstacles.toml's course in the model's world (only for dynamics that avoid
obstacles; 0 removes them; a model of another dynamics runs as its preset says). ``--set`` overrides preset
keys for every size (e.g. the box of a periodic world, to keep a density). For each flock size N (``init.scale_with_n`` keeps the preset's density) it
times whole ``simulate`` runs (``--duration`` simulated seconds at the preset's step) with different seeds,
the obstacle and obstacle-free variants interleaved run by run, and prints the median boid-steps/s over the
repeats with the mean number of visible neighbours.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from flocksweep.simcore import load_preset, simulate_preset  # noqa: E402
from flocksweep.simcore.registry import describe  # noqa: E402

COURSE = ROOT / "configs/models/reynolds87_obstacles.toml"


def variant(model: str, n: int, duration: float, obstacles: int | None, overrides=()):
    preset = load_preset(ROOT / f"configs/models/{model}.toml", [f"init.n={n}", f"run.duration={duration}",
                                                                 "run.record_interval=1.0", *overrides])
    if obstacles is None or not describe(preset.model.dynamics).obstacles:
        return preset
    course = load_preset(COURSE).model.world.obstacles[:obstacles]
    world = preset.model.world
    return preset.replace({"world": {"boundary": world.boundary, "update_order": world.update_order,
                                     "sphere_radius": world.sphere_radius, "box_size": world.box_size,
                                     "obstacles": [o.canonical() for o in course]}})


def time_run(preset, seed: int) -> tuple[float, float]:
    start = time.perf_counter()
    obs = simulate_preset(preset, seed=seed)
    elapsed = time.perf_counter() - start
    return preset.init.n * preset.run.n_steps / elapsed, float(obs.visible.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="reynolds87")
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--obstacles", type=int, default=10)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="preset overrides")
    args = parser.parse_args()
    print(f"model {args.model} {' '.join(args.set)}, {args.duration:g} s runs, median of {args.repeats}, "
          f"NUMBA_NUM_THREADS={os.environ['NUMBA_NUM_THREADS']}")
    print("| N | obstacles | boid-steps/s | visible neighbours |")
    print("|---:|---:|---:|---:|")
    for n in args.sizes:
        variants = {k: variant(args.model, n, args.duration, k, args.set) for k in (0, args.obstacles)}
        if not describe(variants[0].model.dynamics).obstacles:
            variants = {0: variants[0]}
        for preset in variants.values():
            simulate_preset(preset.replace({"run.duration": preset.run.dt * 10}), seed=999)  # compile or load
        rates = {k: [] for k in variants}
        visible = {k: [] for k in variants}
        for seed in range(args.repeats):
            for k, preset in variants.items():
                rate, vis = time_run(preset, seed)
                rates[k].append(rate)
                visible[k].append(vis)
        for k in variants:
            print(f"| {n:,} | {k} | {statistics.median(rates[k]):,.0f} | {statistics.mean(visible[k]):.1f} |",
                  flush=True)


if __name__ == "__main__":
    main()
