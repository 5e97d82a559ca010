"""Warm start times of the commands that simulate nothing: ``flocksweep --version``, ``--help``, the help
of every subcommand, ``status`` of a results folder (remembered, and ``--verify``: read in full) and
``export`` of its runs table as CSV, each as a new process, median of repeats.

    python bench/bench_startup.py --results results/smoke [--repeats 7] [--markdown] [--only status,export]

The code is taken from this checkout (``PYTHONPATH``), the first run of each command is discarded
(warm: file cache, ``__pycache__``, and status's remembered check); ``python -c pass`` is the floor,
and the load average is printed before and after because the 2-core reference machine is shared.
Target: each < 0.5 s.
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
sys.path.insert(0, str(ROOT))
from flocksweep.cli import ORDER  # noqa: E402  (the subcommands; importing the CLI is cheap)

COMMANDS = (["--version", "--help"] + [f"{name} --help" for name in ORDER]
            + ["status {results}", "status {results} --verify", "export {results} --csv --out {scratch}"])


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
    parser.add_argument("--only", help="comma-separated words: only the commands containing one of them")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    rows = [("python -c pass (floor)", timed([sys.executable, "-c", "pass"], args.repeats))]
    chosen = [c for c in COMMANDS if not args.only or any(w in c for w in args.only.split(","))]
    with tempfile.TemporaryDirectory() as scratch:
        for command in chosen:
            words = command.format(results=args.results, scratch=scratch).split()
            rows.append((f"flocksweep {command.replace(' --out {scratch}', '')}",
                         timed([sys.executable, "-m", "flocksweep.cli", *words], args.repeats)))
    print(f"load average {load:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, on {os.cpu_count()} cores; "
          f"median of {args.repeats}")
    if args.markdown:
        print("| command | median | min | max |\n|---|---:|---:|---:|")
    for name, times in rows:
        med, low, high = statistics.median(times), min(times), max(times)
        print(f"| `{name}` | {med:.2f} s | {low:.2f} | {high:.2f} |" if args.markdown
              else f"{name:45s} {med:6.2f} s  ({low:.2f}-{high:.2f})")


if __name__ == "__main__":
    main()
