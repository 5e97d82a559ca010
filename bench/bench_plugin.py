"""Plug-in dynamics against built-ins: boid-steps per second, single thread, after compilation (docs/plugins.md).

    PYTHONPATH=. python bench/bench_plugin.py [--n 100] [--duration 10] [--repeats 7]

Three models on the same flock (the ``opensteer`` preset's initial conditions, N boids, dt = 1/60): the
built-in ``opensteer`` dynamics; ``examples.opensteer_rules``, a plug-in with the same rules and physics
(bit-identical trajectories, checked here), so their ratio is the cost of the plug-in route alone; and the
worked example ``examples.couzin_like`` (zones of repulsion, orientation, attraction; sphere perception of
radius 9, as far as the built-in's cohesion reaches), with the closest built-in: ``opensteer`` on the same
sphere perception. Runs are interleaved model by model for each seed; the table gives the median
boid-steps/s, the ratio to the built-in, the mean visible neighbours, and neighbour visits per second
(boid-steps/s x visible neighbours: the work of a dense flock is per neighbour).
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from flocksweep.simcore import load_preset, simulate_preset  # noqa: E402


def models(n: int, duration: float) -> dict:
    settings = [f"init.n={n}", f"run.duration={duration}", "run.record_interval=1.0"]
    built_in = load_preset(ROOT / "configs/models/opensteer.toml", settings)
    couzin = load_preset(ROOT / "examples/couzin_like.toml", settings + ["run.dt=0.016666666666666666"])
    couzin = couzin.replace({"init": built_in.to_dict()["init"]})   # the same initial flock
    same_rules = built_in.replace({"dynamics": "examples.opensteer_rules"})
    sphere = built_in.replace({"perception": {"kind": "sphere", "radius": 9.0}})
    return {"opensteer (built-in)": built_in, "examples.opensteer_rules (plug-in, same rules)": same_rules,
            "opensteer (built-in), sphere perception r = 9": sphere, "examples.couzin_like (plug-in)": couzin}


def time_run(preset, seed: int):
    start = time.perf_counter()
    obs = simulate_preset(preset, seed=seed)
    return preset.init.n * preset.run.n_steps / (time.perf_counter() - start), obs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    presets = models(args.n, args.duration)
    for preset in presets.values():          # compile (or load) first
        simulate_preset(preset.replace({"run.duration": 1.0}), seed=0)
    rates = {name: [] for name in presets}
    visible = {name: [] for name in presets}
    for seed in range(args.repeats):
        runs = {}
        for name, preset in presets.items():
            rate, runs[name] = time_run(preset, seed)
            rates[name].append(rate)
            visible[name].append(float(runs[name].visible.mean()))
        built_in, same = list(runs.values())[:2]
        assert np.array_equal(built_in.pos, same.pos), "the plug-in with OpenSteer's rules left the built-in's path"
    base = statistics.median(rates["opensteer (built-in)"])
    print(f"N = {args.n}, {args.duration:g} s at dt = 1/60, median of {args.repeats}, NUMBA_NUM_THREADS="
          f"{os.environ['NUMBA_NUM_THREADS']}; the same-rules plug-in matched the built-in bit for bit")
    print("| model | boid-steps/s | ratio to built-in | visible neighbours | neighbour visits/s |")
    print("|---|---:|---:|---:|---:|")
    for name in presets:
        rate, seen = statistics.median(rates[name]), statistics.mean(visible[name])
        print(f"| {name} | {rate:,.0f} | {rate / base:.2f} | {seen:.1f} | {rate * seen:,.0f} |")


if __name__ == "__main__":
    main()
