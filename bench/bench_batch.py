"""A calibration's batch: ``simulate_batch`` of 16 seeds of holland (20 boids, 5 s) on numba's threads.

    python bench/bench_batch.py [--checkout OTHER] [--rounds 5] [--calls 5]

Each round runs, in fresh processes taking turns, this checkout and (with ``--checkout``) another one;
each process calls the batch once to load (or compile) the kernels, then ``--calls`` times, and reports the
median call and a digest of the positions (the same digest: the same runs, bit for bit).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CHILD = """
import hashlib, statistics, sys, time
import numba
from flocksweep.simcore import load_preset
from flocksweep.simcore.simulate import simulate_batch
pre = load_preset(sys.argv[1] + "/configs/models/holland.toml",
                  ["init.n=20", "run.duration=5.0", "perception.field_deg=150", "perception.direction_deg=45"])
seeds = list(range(16))
run = lambda: simulate_batch(pre.model, pre.init, seeds, pre.run.duration, pre.run.dt, pre.run.record_every)
run()
times = []
for _ in range(int(sys.argv[2])):
    start = time.perf_counter()
    out = run()
    times.append(time.perf_counter() - start)
digest = hashlib.sha256(b"".join(o.pos.tobytes() for o in out)).hexdigest()[:12]
print(f"{statistics.median(times) * 1000:.1f} ms {digest} ({numba.get_num_threads()} threads)")
"""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkout", type=Path, help="another checkout, timed in turn with this one")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--calls", type=int, default=5)
    args = parser.parse_args()
    roots = [ROOT] + ([args.checkout.resolve()] if args.checkout else [])
    print(f"load average {os.getloadavg()[0]:.1f}")
    for r in range(args.rounds):
        for root in roots:
            env = {**os.environ, "PYTHONPATH": str(root)}
            done = subprocess.run([sys.executable, "-c", CHILD, str(root), str(args.calls)], env=env, cwd=root,
                                  capture_output=True, text=True, check=True)
            print(f"round {r + 1} {root}: {done.stdout.strip().splitlines()[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
