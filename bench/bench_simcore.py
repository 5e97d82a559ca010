"""Simulator throughput: boid-steps per second, single thread, after compilation.

    python bench/bench_simcore.py [--repeats 5] [--sizes 20 50 100 400] [--markdown]

For each model (``opensteer`` preset; ``holland`` preset with occlusion on, range 20, field 120,
direction 60; ``hartman_benes`` preset with leadership X = 1) and flock size N it times whole runs of
``simulate`` (30 simulated seconds at the preset's step, 10 s for N >= 400) with different seeds and reports the median boid-steps/s over the repeats, with the
mean number of visible neighbours (cost grows with it). It also times a fresh Python process from start
to its first simulated step (compilation loaded from numba's cache).
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from flocksweep.simcore import load_preset, simulate_preset  # noqa: E402

MODELS = {
    "opensteer": (ROOT / "configs/models/opensteer.toml", []),
    "holland": (ROOT / "configs/models/holland.toml",
                ["perception.occlusion=true", "perception.range=20", "perception.field_deg=120",
                 "perception.direction_deg=60"]),
    "hartman_benes X=1": (ROOT / "configs/models/hartman_benes.toml", ["leadership.x=1"]),
}


def measure(model: str, n: int, repeats: int) -> dict:
    path, overrides = MODELS[model]
    duration = 30.0 if n < 400 else 10.0
    preset = load_preset(path, overrides + [f"init.n={n}", f"run.duration={duration}"])
    simulate_preset(preset, seed=999)  # compile or load from cache
    rates, visible = [], []
    for seed in range(repeats):
        start = time.perf_counter()
        obs = simulate_preset(preset, seed=seed)
        elapsed = time.perf_counter() - start
        rates.append(n * preset.run.n_steps / elapsed)
        visible.append(float(obs.visible[1:].mean()))
    return {"model": model, "n": n, "median": statistics.median(rates), "min": min(rates), "max": max(rates),
            "visible": statistics.mean(visible), "steps": preset.run.n_steps}


def cold_start(repeats: int = 3) -> float:
    """Median seconds for a new process to import flocksweep.simcore and finish a one-step simulation."""
    code = ("import time; t = time.perf_counter(); from flocksweep.simcore import load_preset, simulate_preset; "
            f"p = load_preset(r'{MODELS['holland'][0]}', ['run.duration=0.016666666666666666']); "
            "simulate_preset(p, 0); print(time.perf_counter() - t)")
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def machine() -> str:
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.system()}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 50, 100, 400])
    args = parser.parse_args()
    print(f"machine: {machine()}")
    print("| model | N | steps | median boid-steps/s | min | max | mean visible |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for model in MODELS:
        for n in args.sizes:
            r = measure(model, n, args.repeats)
            print(f"| {model} | {n} | {r['steps']} | {r['median']:,.0f} | {r['min']:,.0f} | {r['max']:,.0f} "
                  f"| {r['visible']:.1f} |", flush=True)
    print(f"\ncold start (new process: import + cached kernels + one step), median of 3: {cold_start():.2f} s")


if __name__ == "__main__":
    main()
