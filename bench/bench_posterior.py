"""``flocksweep posterior`` of 100 flocks from a stored 5-flow estimator, in fresh processes, with JAX's
persistent compilation cache cold (an empty cache folder) and warm (the same folder again), and a second
calibration's flows: the compile of one training epoch, cold and warm (issue 43 point 2).

    python bench/bench_posterior.py [--repeats 3] [--before /path/to/old/tree/.venv/bin/flocksweep]
                                    [--estimator DIR --targets FLOCKS.csv] [--out results/bench_posterior]

Without ``--estimator``: recover_holland (configs/calibration/recover_holland.toml, 5 flows of the shipped
architecture: width 50, 5 layers, 8 knots) is trained once on 300 simulations (40 held out) into
``OUT/holland5`` and its last 100 stored runs' statistics are the 100 flocks (``OUT/flocks100.csv``); the
estimator's size does not change a posterior's cost, only its architecture does. ``--before``: the
``flocksweep`` command of another checkout (e.g. main before this change), timed in the same interleaved
rounds (each round: after-cold, after-warm, before, before-again). Every process is timed whole (wall, and
user + system CPU of the child), with JAX_COMPILATION_CACHE_DIR removed from its
environment and FLOCKSWEEP_CACHE_DIR pointing at a folder of the round. Prints medians and the load average.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FLOCKSWEEP = Path(sys.executable).parent / "flocksweep"

EPOCH = """
import time, numpy as np
started = time.time()
from flocksweep.analysis.calibration.npe_flow import FlowSettings, require_jax, train_flow
require_jax()   # JAX imported (and the cache set) before the clock starts: the epoch's time is compile + run
rng = np.random.default_rng(0)
theta, x = rng.uniform(size=(300, 2)), rng.normal(size=(300, 4))
imported = time.time()
train_flow(theta, x, FlowSettings(max_epochs=1), seed=1)
print(f"{time.time() - imported:.2f}")
"""


def run_child(command, env) -> dict:
    """Wall and CPU seconds (user + system, from the resource usage of reaped children) of ``command``, and
    the last line of its stdout."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        raise SystemExit(f"{' '.join(map(str, command))} failed:\n{done.stderr[-2000:]}")
    return {"wall": wall, "cpu": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "last": done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ""}


def environment(cache: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_COMPILATION", "JAX_PERSISTENT",
                                                                     "FLOCKSWEEP_JAX_CACHE"))}
    return {**env, "FLOCKSWEEP_CACHE_DIR": str(cache)}


def prepare(out: Path) -> tuple[Path, Path]:
    """The stored 5-flow estimator and a table of 100 flocks (module docstring)."""
    import numpy as np
    import pandas as pd

    estimator = out / "holland5" / "estimator"
    if not (estimator / "member4" / "flow.eqx").is_file():
        subprocess.run([str(FLOCKSWEEP), "calibrate", str(ROOT / "configs/calibration/recover_holland.toml"),
                        "--set", "method.npe.simulations=300", "--set", "method.npe.heldout=40",
                        "--out", str(out / "holland5"), "--no-progress"], check=True)
    targets = out / "flocks100.csv"
    if not targets.is_file():
        rows = np.concatenate([np.load(f)["rows"] for f in sorted((out / "holland5" / "training").glob("*.npz"))])
        columns = json.loads((estimator / "identity.json").read_text())["columns"]
        table = pd.DataFrame(rows[-100:], columns=columns)
        table.insert(0, "flock", [f"f{i:03d}" for i in range(len(table))])
        table.to_csv(targets, index=False)
    return estimator, targets


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", type=Path, help="the flocksweep command of the checkout to compare with")
    parser.add_argument("--estimator", type=Path)
    parser.add_argument("--targets", type=Path)
    parser.add_argument("--out", type=Path, default=Path("results/bench_posterior"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    estimator, targets = (args.estimator, args.targets) if args.estimator else prepare(args.out)
    results: dict[str, list] = {}
    loads = [os.getloadavg()[0]]
    for _ in range(args.repeats):
        work = Path(tempfile.mkdtemp(prefix="bench-posterior-"))
        try:
            def posterior(flocksweep, name, cache):
                command = [str(flocksweep), "posterior", str(estimator), "--targets", str(targets),
                           "--out", str(work / f"{name}.csv")]
                results.setdefault(name, []).append(run_child(command, environment(cache)))

            posterior(FLOCKSWEEP, "after, cold cache", work / "cache")
            posterior(FLOCKSWEEP, "after, warm cache", work / "cache")
            if args.before:
                posterior(args.before, "before", work / "cache-before")
                posterior(args.before, "before, again", work / "cache-before")
            for name, cache in (("first epoch, cold cache", work / "epoch"), ("first epoch, warm cache", work / "epoch")):
                results.setdefault(name, []).append(run_child([sys.executable, "-c", EPOCH], environment(cache)))
            loads.append(os.getloadavg()[0])
        finally:
            shutil.rmtree(work, ignore_errors=True)
    print(f"{args.repeats} interleaved rounds; load average (1 min) {min(loads):.1f}-{max(loads):.1f} on "
          f"{os.cpu_count()} cores")
    print("| process | wall s (median) | CPU s (median) | runs (wall) | train_flow(1 epoch) s, JAX imported |")
    print("|---|---|---|---|---|")
    for name, runs in results.items():
        walls = ", ".join(f"{r['wall']:.1f}" for r in runs)
        inner = f"{statistics.median(float(r['last']) for r in runs):.1f}" if name.startswith("first epoch") else ""
        print(f"| {name} | {statistics.median(r['wall'] for r in runs):.1f} | "
              f"{statistics.median(r['cpu'] for r in runs):.1f} | {walls} | {inner} |")


if __name__ == "__main__":
    main()
