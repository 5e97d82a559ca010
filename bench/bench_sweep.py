"""The 648-run Holland grid end to end: wall time, resume time, peak memory, per-run overhead.

    python bench/bench_sweep.py [--repeats 3] [--sweep configs/sweeps/holland648.toml] [--workers K]

Each repeat runs the whole command ``flocksweep run SWEEP --out <fresh dir>`` in a new process (start-up,
design expansion, simulation, metrics and writing included) with the default executor, then runs it
again on the finished directory (everything done: the resume path). Peak memory is the largest sum of
resident memory of the runner and all its worker processes, sampled every 50 ms. Per-run overhead is
wall time minus simulation time of each run, from the results table, and the command's overhead is its
wall time minus (total simulation time / workers).
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


def timed(cmd: list[str]) -> tuple[float, int]:
    """(wall seconds, peak tree RSS bytes) of a command."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    watcher = psutil.Process(proc.pid)
    peak = 0
    while proc.poll() is None:
        peak = max(peak, tree_rss(watcher))
        time.sleep(0.05)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited with {proc.returncode}")
    return wall, peak


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--sweep", default="configs/sweeps/holland648.toml")
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    args = parser.parse_args()
    exe = [sys.executable, "-m", "flocksweep.entry", "run", args.sweep, "--no-progress", "--workers", str(args.workers)]
    full, again, peaks, overheads, command_overheads = [], [], [], [], []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "grid"
            wall, peak = timed(exe + ["--out", str(out)])
            wall2, _ = timed(exe + ["--out", str(out)])
            table = pd.read_parquet(out / "runs.parquet")
            assert (table["status"] == "ok").all(), "runs failed"
            full.append(wall)
            again.append(wall2)
            peaks.append(peak)
            overheads.append(float((table["wall_s"] - table["sim_s"]).mean()))
            command_overheads.append(wall - table["sim_s"].sum() / args.workers)
            print(f"run: {wall:.1f} s, again: {wall2:.2f} s, peak {peak / 2**20:.0f} MiB, "
                  f"{len(table)} runs, simulation {table['sim_s'].sum():.1f} s", flush=True)
    print(f"\n{args.sweep} with {args.workers} workers, median of {args.repeats}:")
    print(f"  whole command: {statistics.median(full):.1f} s (min {min(full):.1f}, max {max(full):.1f})")
    print(f"  second invocation (all done): {statistics.median(again):.2f} s")
    print(f"  peak memory (runner + workers): {statistics.median(peaks) / 2**20:.0f} MiB")
    print(f"  per-run overhead (wall - simulation, in the worker): {statistics.median(overheads) * 1e3:.1f} ms")
    print(f"  command overhead (wall - simulation / workers): {statistics.median(command_overheads):.1f} s")


if __name__ == "__main__":
    main()
