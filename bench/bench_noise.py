"""Cost of intrinsic noise and cruise speed: boid-steps per second with them on vs off, per dynamics.

    python bench/bench_noise.py [--models opensteer hartman_benes reynolds87 boidspp] [--sizes 100 1000]
                                [--duration 5] [--repeats 5]

For each preset and flock size N (``init.scale_with_n`` as the preset says) it times whole single-thread
``simulate_preset`` runs of the preset (off) and of the preset with every part of the drive switched on
but nearly without effect (``noise.kappa = 1e9``, ``noise.speed_sd = 1e-6``, ``cruise.speed`` = the
initial speed with ``cruise.tau = 1e9``: every draw and branch runs, the flock flies as without, so the
ratio is the drive's own cost and not that of a flock of another shape), interleaved run by run with
different seeds, and prints the median boid-steps/s of each, the median of the per-pair ratios (on /
off) and the mean visible neighbours of each (equal when the flocks are alike).
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


def variants(model: str, n: int, duration: float):
    off = load_preset(ROOT / f"configs/models/{model}.toml", [f"init.n={n}", f"run.duration={duration}",
                                                               "run.record_interval=1.0"])
    on = off.replace({"noise.kappa": 1e9, "noise.speed_sd": 1e-6, "cruise.speed": max(off.init.speed, 1.0),
                      "cruise.tau": 1e9})
    return off, on


def rate(preset, seed: int) -> tuple[float, float]:
    """(boid-steps/s, mean visible neighbours) of one run."""
    start = time.perf_counter()
    obs = simulate_preset(preset, seed=seed, threads=1)
    return preset.init.n * preset.run.n_steps / (time.perf_counter() - start), float(obs.visible.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=["opensteer", "hartman_benes", "reynolds87", "boidspp"])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(f"{args.duration:g} s runs, median of {args.repeats} interleaved pairs, NUMBA_NUM_THREADS="
          f"{os.environ['NUMBA_NUM_THREADS']}")
    print("| model | N | off: boid-steps/s | on: boid-steps/s | on / off | visible off / on |")
    print("|---|---:|---:|---:|---:|---:|")
    for model in args.models:
        for n in args.sizes:
            off, on = variants(model, n, args.duration)
            rate(off, 0), rate(on, 0)   # compile (or load) both first
            runs = {"off": [], "on": []}
            for r in range(args.repeats):
                runs["off"].append(rate(off, r + 1))
                runs["on"].append(rate(on, r + 1))
            a, b = (statistics.median(x for x, _ in runs[k]) for k in ("off", "on"))
            ratio = statistics.median(y[0] / x[0] for x, y in zip(runs["off"], runs["on"]))
            seen = " / ".join(f"{statistics.mean(v for _, v in runs[k]):.1f}" for k in ("off", "on"))
            print(f"| {model} | {n} | {a:,.0f} | {b:,.0f} | {ratio:.3f} | {seen} |", flush=True)


if __name__ == "__main__":
    main()
