"""Where the 648 grid's simulation time goes: CPU seconds per run of a sample of its cells, by flock size
and range (and by field and direction), in one process on one thread, kernels cached.

    python bench/bench_grid_cells.py [--every 7] [--offset 0] [--sweep configs/sweeps/holland648.toml]

Every ``every``-th cell of the sweep's design (in design order; an ``every`` prime to the axis lengths
samples every level of every axis) is simulated whole (the sweep's duration, its own seed), timed with
``time.process_time``. Prints the mean CPU per run by each axis level and by (N, range), with the mean
count of boids perceived after the warm-up, and the share of the sample's CPU in each (N, range) class:
what a faster kernel would have to speed up for the grid to go faster.
"""
from __future__ import annotations

import argparse
import collections
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from flocksweep.simcore import simulate  # noqa: E402
from flocksweep.sweeps.config import load_sweep  # noqa: E402
from flocksweep.sweeps.design import expand  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", default=str(ROOT / "configs" / "sweeps" / "holland648.toml"))
    parser.add_argument("--every", type=int, default=7)
    parser.add_argument("--offset", type=int, default=0)
    args = parser.parse_args()
    specs = expand(load_sweep(args.sweep))[args.offset::args.every]
    first = specs[0].preset
    simulate(first.model, first.init, 0, first.run.dt * 2, first.run.dt)   # load the kernels
    rows = []
    for spec in specs:
        run = spec.preset.run
        start = time.process_time()
        obs = simulate(spec.preset.model, spec.preset.init, spec.seed, run.duration, run.dt, run.record_every)
        cpu = time.process_time() - start
        window = obs.times >= spec.metrics.warmup
        rows.append({**dict(spec.columns), "cpu": cpu, "visible": float(obs.visible[window].mean())})
    total = sum(r["cpu"] for r in rows)
    print(f"{len(rows)} of {len(expand(load_sweep(args.sweep)))} runs, {total:.2f} s CPU "
          f"(x {args.every} = about {total * args.every:.0f} s for the grid on one core)")
    for axis in [k for k in rows[0] if k not in ("cpu", "visible")]:
        by = collections.defaultdict(list)
        for r in rows:
            by[r[axis]].append(r["cpu"])
        print(f"  {axis}: " + ", ".join(f"{level}: {1e3 * np.mean(v):.1f} ms" for level, v in sorted(by.items())))
    by = collections.defaultdict(list)
    for r in rows:
        by[(r["init.n"], r["perception.range"])].append(r)
    print("  (N, range): mean CPU per run, mean boids perceived after the warm-up, share of the CPU")
    for key, group in sorted(by.items()):
        cpu = [r["cpu"] for r in group]
        print(f"    {key}: {1e3 * np.mean(cpu):7.1f} ms  {np.mean([r['visible'] for r in group]):5.1f}  "
              f"{100 * sum(cpu) / total:5.1f} %")


if __name__ == "__main__":
    main()
