"""The 648-run Holland grid end to end: wall time, resume time, peak memory, per-run overhead.

    python bench/bench_sweep.py [--repeats 3] [--sweep configs/sweeps/holland648.toml] [--workers K]
                                [--against OTHER_CHECKOUT]

Each repeat runs the whole command ``flocksweep run SWEEP --out <fresh dir>`` in a new process (start-up,
design expansion, simulation, metrics and writing included) with the default executor, then runs it
again on the finished directory (everything done: the resume path). Peak memory is the largest sum of
resident memory of the runner and all its worker processes, sampled every 50 ms. Per-run overhead is
wall time minus simulation time of each run, from the results table, and the command's overhead is its
wall time minus (total simulation time / workers). The command runs as the console script does
(``python -m flocksweep.entry``) with this checkout on ``PYTHONPATH``; ``--against`` times another
checkout in turn, repeat by repeat, so both see the same load, and prints the median ratio.
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

import pandas as pd
import psutil

ROOT = Path(__file__).resolve().parent.parent


def tree_rss(proc: psutil.Process) -> int:
    total = 0
    for p in [proc] + proc.children(recursive=True):
        try:
            total += p.memory_info().rss
        except psutil.Error:
            pass
    return total


def timed(cmd: list[str], root: Path = ROOT) -> tuple[float, int]:
    """(wall seconds, peak tree RSS bytes) of a command run in the checkout ``root`` (cwd and PYTHONPATH)."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, "PYTHONPATH": str(root)})
    watcher = psutil.Process(proc.pid)
    peak = 0
    while proc.poll() is None:
        peak = max(peak, tree_rss(watcher))
        time.sleep(0.05)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited with {proc.returncode}")
    return wall, peak


def one_repeat(exe: list[str], root: Path, workers: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "grid"
        wall, peak = timed(exe + ["--out", str(out)], root)
        wall2, _ = timed(exe + ["--out", str(out)], root)
        table = pd.read_parquet(out / "runs.parquet")
        assert (table["status"] == "ok").all(), "runs failed"
        return {"full": wall, "again": wall2, "peak": peak, "runs": len(table), "sim": table["sim_s"].sum(),
                "overhead": float((table["wall_s"] - table["sim_s"]).mean()),
                "command_overhead": wall - table["sim_s"].sum() / workers}


def summary(name: str, results: list[dict], workers: int) -> None:
    full = [r["full"] for r in results]
    print(f"\n{name} with {workers} workers, median of {len(results)}:")
    print(f"  whole command: {statistics.median(full):.1f} s (min {min(full):.1f}, max {max(full):.1f})")
    print(f"  second invocation (all done): {statistics.median(r['again'] for r in results):.2f} s")
    print(f"  peak memory (runner + workers): {statistics.median(r['peak'] for r in results) / 2**20:.0f} MiB")
    print(f"  per-run overhead (wall - simulation, in the worker): "
          f"{statistics.median(r['overhead'] for r in results) * 1e3:.1f} ms")
    print(f"  command overhead (wall - simulation / workers): "
          f"{statistics.median(r['command_overhead'] for r in results):.1f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--sweep", default="configs/sweeps/holland648.toml")
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    parser.add_argument("--against", type=Path, help="another checkout (e.g. a clone at an older commit), "
                                                     "timed in turn with this one, repeat by repeat")
    args = parser.parse_args()
    exe = [sys.executable, "-m", "flocksweep.entry", "run", args.sweep, "--no-progress", "--workers", str(args.workers)]
    roots = [ROOT] + ([args.against.resolve()] if args.against else [])
    results = {root: [] for root in roots}
    for _ in range(args.repeats):
        for root in roots:
            r = one_repeat(exe, root, args.workers)
            results[root].append(r)
            print(f"{root}: run: {r['full']:.1f} s, again: {r['again']:.2f} s, peak {r['peak'] / 2**20:.0f} MiB, "
                  f"{r['runs']} runs, simulation {r['sim']:.1f} s, load {os.getloadavg()[0]:.1f}", flush=True)
    for root in roots:
        summary(f"{args.sweep} ({root})", results[root], args.workers)
    if args.against:
        ratios = [a["full"] / b["full"] for a, b in zip(results[ROOT], results[roots[1]])]
        print(f"\nthis checkout / the other, whole command, median of the repeats' ratios: "
              f"{statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main()
