"""A tiny ``flocksweep simulate`` against numba's own start-up floor, interleaved (issue 30, start-up).

    python bench/bench_simulate_startup.py [--repeats 9] [--model configs/models/holland.toml] [--pycache]

The floor is what any numba program pays before its first compiled call returns: a new Python process
that imports numba and calls one cached ``@njit(cache=True)`` function (written to a temporary module,
its cache filled beforehand). The tiny simulate is ``python -m flocksweep.entry simulate MODEL --n 3
--duration <one step>`` with the kernels cached (run once beforehand). Both run as new processes in
turn, ``--repeats`` times each, so both see the same load; reported: their medians (wall seconds), the
median of the per-pair differences (simulate - floor; the target is <= 0.3 s) and the load average.
``--pycache`` unsets ``PYTHONDONTWRITEBYTECODE`` for both (set on the reference machine, it makes every
process compile each flocksweep module from source; an installed flocksweep keeps its bytecode).
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FLOOR_MODULE = """
import numba

@numba.njit(cache=True)
def one(x):
    return x + 1
"""


def wall(cmd: list[str], env: dict, cwd: Path) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--model", default="configs/models/holland.toml")
    parser.add_argument("--pycache", action="store_true", help="let both write and use __pycache__ "
                                                               "(unset PYTHONDONTWRITEBYTECODE)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="numba-floor-") as tmp:
        Path(tmp, "floor_module.py").write_text(FLOOR_MODULE)
        base = {k: v for k, v in os.environ.items() if not (args.pycache and k == "PYTHONDONTWRITEBYTECODE")}
        env = {**base, "PYTHONPATH": os.pathsep.join([tmp, str(ROOT), os.environ.get("PYTHONPATH", "")])}
        floor = [sys.executable, "-c", "import floor_module; floor_module.one(1)"]
        tiny = [sys.executable, "-m", "flocksweep.entry", "simulate", args.model, "--n", "3", "--duration",
                "0.016666666666666666"]
        wall(floor, env, ROOT)  # fill both caches
        wall(tiny, env, ROOT)
        floors, tinies = [], []
        for _ in range(args.repeats):
            floors.append(wall(floor, env, ROOT))
            tinies.append(wall(tiny, env, ROOT))
    load = os.getloadavg()
    diffs = [t - f for t, f in zip(tinies, floors)]
    bytecode = "bytecode kept" if args.pycache or not os.environ.get("PYTHONDONTWRITEBYTECODE") else \
        "PYTHONDONTWRITEBYTECODE set"
    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}; medians of {args.repeats} interleaved pairs; "
          f"{bytecode}")
    print("| measure | seconds (median) | min-max |")
    print("|---|---:|---:|")
    print(f"| numba floor: import numba + one cached call | {statistics.median(floors):.3f} | "
          f"{min(floors):.3f}-{max(floors):.3f} |")
    print(f"| tiny `flocksweep simulate` ({args.model}, 3 boids, one step) | {statistics.median(tinies):.3f} | "
          f"{min(tinies):.3f}-{max(tinies):.3f} |")
    print(f"| simulate - floor, per pair | **{statistics.median(diffs):.3f}** | {min(diffs):.3f}-{max(diffs):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
