"""Warm start times of the commands that simulate nothing: ``flocksweep --version``, ``--help``, the help
of each subcommand, and ``status`` of a results folder, each as a new process, median of repeats.

    python bench/bench_startup.py --results results/smoke [--repeats 7] [--markdown]

The code is taken from this checkout (``PYTHONPATH``), the first run of each command is discarded
(warm: file cache, ``__pycache__``); ``python -c pass`` is the floor, and the load average is printed
because the 2-core reference machine is shared. Target: each < 0.5 s.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COMMANDS = ["--version", "--help", "run --help", "view --help", "measure --help", "report --help", "status {results}"]


def timed(argv: list[str], repeats: int) -> list[float]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    times = []
    for attempt in range(repeats + 1):
        start = time.perf_counter()
        subprocess.run(argv, env=env, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        if attempt:
            times.append(time.perf_counter() - start)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", default="results/smoke", help="a results folder for status")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args()
    rows = [("python -c pass (floor)", timed([sys.executable, "-c", "pass"], args.repeats))]
    for command in COMMANDS:
        words = command.format(results=args.results).split()
        rows.append((f"flocksweep {command}", timed([sys.executable, "-m", "flocksweep.cli", *words], args.repeats)))
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; median of {args.repeats}")
    if args.markdown:
        print("| command | median | min | max |\n|---|---:|---:|---:|")
    for name, times in rows:
        med, low, high = statistics.median(times), min(times), max(times)
        print(f"| `{name}` | {med:.2f} s | {low:.2f} | {high:.2f} |" if args.markdown
              else f"{name:45s} {med:6.2f} s  ({low:.2f}-{high:.2f})")


if __name__ == "__main__":
    main()
