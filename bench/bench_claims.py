"""What the claims cost: the per-record metrics with the leapfrog columns against another checkout's, and
judging a sweep's claims with and without the power analysis.

    python bench/bench_claims.py --other OTHER_CHECKOUT [--results results/holland648_r5] [--repeats 5]

Metrics: ``frame_metrics`` of recorded runs (holland preset, N = 100, 30 s, records every 1 s; the
simulations are done once, outside the timing), timed in a fresh process per checkout (PYTHONPATH set
to it, kernels loaded from numba's cache, one warm-up call), alternating the two checkouts repeat by
repeat so both see the same load; medians and the ratio this / other. Claims: ``evaluate`` of the
results folder's stored claims on its ok runs, with and without the power simulations (seed 0).
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent

METRICS = """
import time, inspect
import numpy as np
from flocksweep.simcore import load_preset, simulate_preset
from flocksweep.observables.metrics import frame_metrics
preset = load_preset("{root}/configs/models/holland.toml", ["init.n=100", "run.duration=30"])
runs = [simulate_preset(preset, seed=s) for s in range(4)]
extra = {{"record_interval": 1.0}} if "record_interval" in inspect.signature(frame_metrics).parameters else {{}}
def once():
    for obs in runs:
        frame_metrics(obs.pos, obs.vel, obs.visible, obs.binocular, obs.pattern, 20.0, None, **extra)
once()
times = []
for _ in range(7):
    start = time.perf_counter(); once(); times.append((time.perf_counter() - start) / len(runs))
print(sorted(times)[3] * 1e3)
"""


def metrics_ms(checkout: Path) -> float:
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    out = subprocess.run([sys.executable, "-c", METRICS.format(root=HERE)], cwd=checkout, env=env, check=True,
                         capture_output=True, text=True)
    return float(out.stdout.strip().splitlines()[-1])


def claims_seconds(results: str) -> dict:
    from flocksweep.analysis.reports.claims.evaluate import evaluate
    from flocksweep.analysis.reports.claims.load import claims_of
    from flocksweep.sweeps.results import load_results

    loaded = load_results(results)
    claims, columns, _ = claims_of(loaded)
    out = {}
    for power in (False, True):
        start = time.perf_counter()
        evaluate(claims, loaded.ok, columns.factors, seed=0, with_power=power)
        out["with power" if power else "tests only"] = time.perf_counter() - start
    out["claims"], out["tests"] = len(claims), sum(len(c.test.leaves()) for c in claims)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--other", type=Path, required=True,
                        help="the other checkout (e.g. a git worktree of main: git worktree add ../main main)")
    parser.add_argument("--results", default="results/holland648_r5")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    times = {"this": [], "other": []}
    for repeat in range(args.repeats):
        order = [("this", HERE), ("other", args.other)]
        for name, checkout in order if repeat % 2 == 0 else order[::-1]:
            times[name].append(metrics_ms(checkout))
        print(f"repeat {repeat + 1}: this {times['this'][-1]:.2f} ms, other {times['other'][-1]:.2f} ms", flush=True)
    this, other = statistics.median(times["this"]), statistics.median(times["other"])
    print(f"frame_metrics per run (N = 100, 31 records): this {this:.2f} ms, other {other:.2f} ms, "
          f"ratio {this / other:.2f}")
    if Path(args.results).exists():
        cost = claims_seconds(args.results)
        print(f"{args.results}: {cost['claims']} claims, {cost['tests']} tests: {cost['tests only']:.1f} s tests only, "
              f"{cost['with power']:.1f} s with the power analysis")


if __name__ == "__main__":
    main()
