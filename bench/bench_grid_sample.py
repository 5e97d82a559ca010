"""CPU seconds per run of the 648 grid, simulation against metrics, for checkouts side by side.

    python bench/bench_grid_sample.py [--every 25] [--repeats 3] [CHECKOUT ...]

For each repeat and each checkout (default: this one) a fresh process with ``PYTHONPATH=<checkout>``
expands ``configs/sweeps/holland648.toml``, warms the kernels up (``sweeps.worker.warm_up``) and runs
every ``--every``-th run (the sample shifts by one each repeat), timing with the process clock
(``time.process_time``, less disturbed by other jobs than wall time) the simulation and the metrics
(``measure_run``) of each run. Prints, per checkout, the CPU seconds of both, their ratio to the first
checkout (median over repeats) and the simulation time by flock size and range (a checkout older than
``observables`` is timed on the simulation alone). Checkouts are
interleaved, so they see the same load; an older checkout's kernels compile on its first repeat.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

WORKER = """
import json, sys, time
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.worker import warm_up, _simulate
try:
    from flocksweep.observables.summary import every_nth, measure_run
except ImportError:  # a checkout from before observables: simulation only
    measure_run = None
specs = expand(load_sweep(sys.argv[1]))
warm_up(specs[0])
every, start = int(sys.argv[2]), int(sys.argv[3])
out = []
for s in specs[start::every]:
    t0 = time.process_time(); obs = _simulate(s); t1 = time.process_time()
    if measure_run is not None:
        measure_run(every_nth(obs, s.preset.run.record_every // obs.record_every), s.metrics)
    out.append([s.preset.init.n, s.preset.model.perception.range, t1 - t0, time.process_time() - t1])
print(json.dumps(out))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkouts", nargs="*", default=[str(ROOT)])
    parser.add_argument("--every", type=int, default=25)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    results = defaultdict(list)
    for rep in range(args.repeats):
        for tree in args.checkouts:
            sweep = str(Path(tree) / "configs" / "sweeps" / "holland648.toml")
            env = dict(os.environ, PYTHONPATH=tree)
            done = subprocess.run([sys.executable, "-c", WORKER, sweep, str(args.every), str(rep % args.every)],
                                  capture_output=True, text=True, env=env, cwd=Path(tree).parent, check=True)
            results[tree].append(json.loads(done.stdout.strip().splitlines()[-1]))
    first = args.checkouts[0]
    for tree in args.checkouts:
        sim = [sum(r[2] for r in runs) for runs in results[tree]]
        met = [sum(r[3] for r in runs) for runs in results[tree]]
        ratio = statistics.median(s / f for s, f in zip(sim, (sum(r[2] for r in runs) for runs in results[first])))
        print(f"{tree}: simulation {statistics.median(sim):.2f} s CPU, metrics {statistics.median(met):.2f} s "
              f"(median of {args.repeats} samples of {len(results[tree][0])} runs); simulation vs first {ratio:.3f}")
        by = defaultdict(float)
        for runs in results[tree]:
            for n, rng, s, _ in runs:
                by[(n, rng)] += s
        print("   " + ", ".join(f"N={n} range {rng:g}: {t:.2f}" for (n, rng), t in sorted(by.items())))


if __name__ == "__main__":
    main()
