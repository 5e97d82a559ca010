"""Boids++ throughput: boid-steps per second with 10 sphere obstacles and a predator, single thread.

    python bench/bench_boidspp.py [--repeats 5] [--sizes 100 1000] [--markdown]

For each flock size N the ``boidspp_predator`` preset (sphere perception radius 10, flock-wide alignment
and cohesion, a predator hunting from t = 0, 20 units away) is run with ten sphere obstacles of radius
3 scattered (fixed seed) in the ball of radius 40 the flock flies through (``with obstacles``), and, for
the cost of the features, without obstacles and predator (``rules only``). The initial ball grows as
(N/100)^(1/3) so the density is the same for every N. Variants are interleaved in each repeat (the
machine is shared; medians of the repeats); each repeat uses another seed. Reported: median
boid-steps/s, its spread (min..max over repeats), the mean number of perceived neighbours and the
share of boid-steps whose boid flees the predator.
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

PRESET = ROOT / "configs/models/boidspp_predator.toml"


def obstacles(count: int = 10, seed: int = 2026) -> list[dict]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        direction = rng.standard_normal(3)
        centre = direction / np.linalg.norm(direction) * 40.0 * rng.random() ** (1 / 3)
        out.append({"kind": "sphere", "centre": [float(c) for c in centre], "radius": 3.0})
    return out


def preset_for(n: int, variant: str):
    duration = 20.0 if n <= 100 else 4.0
    preset = load_preset(PRESET, [f"init.n={n}", "init.scale_with_n=true", f"run.duration={duration}"])
    if variant == "with obstacles":
        return preset.replace({"world.obstacles": obstacles(), "boidspp.predator.start_s": 0.0,
                               "boidspp.predator.start_distance": 20.0, "boidspp.predator.leave_s": None})
    return preset.replace({"boidspp.predator.enabled": False})


def fleeing_share(preset, obs) -> float:
    if obs.predator is None:
        return 0.0
    gap = np.linalg.norm(obs.pos - obs.predator[:, None, :], axis=2)
    return float(np.nanmean(gap < preset.model.boidspp.predator.avoid_radius))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args()
    variants = ("with obstacles", "rules only")
    presets = {(n, v): preset_for(n, v) for n in args.sizes for v in variants}
    for preset in presets.values():
        simulate_preset(preset, seed=999)  # compile or load from numba's cache
    rates = {key: [] for key in presets}
    extras = {}
    for repeat in range(args.repeats):
        for key, preset in presets.items():
            started = time.perf_counter()
            obs = simulate_preset(preset, seed=repeat)
            elapsed = time.perf_counter() - started
            rates[key].append(preset.init.n * preset.run.n_steps / elapsed)
            extras[key] = (float(obs.visible.mean()), fleeing_share(preset, obs))
    rows = []
    for (n, variant), values in rates.items():
        visible, fleeing = extras[(n, variant)]
        rows.append((n, variant, statistics.median(values), min(values), max(values), visible, fleeing))
    if args.markdown:
        print("| N | variant | boid-steps/s (median) | min..max | mean neighbours | fleeing share |")
        print("|---|---|---|---|---|---|")
        for n, variant, med, lo, hi, visible, fleeing in rows:
            print(f"| {n} | {variant} | {med:,.0f} | {lo:,.0f}..{hi:,.0f} | {visible:.1f} | {fleeing:.3f} |")
    else:
        for row in rows:
            print("N=%5d %-15s %12.0f boid-steps/s (%.0f..%.0f), neighbours %.1f, fleeing %.3f" % row)


if __name__ == "__main__":
    main()
