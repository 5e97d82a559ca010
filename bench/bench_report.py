"""Report generation time: ``flocksweep report`` on a finished sweep, whole command, median of repeats.

    python bench/bench_report.py [--results results/holland648_r5] [--repeats 3]

Each repeat runs ``flocksweep report RESULTS --out <fresh dir>`` in a new process (imports, statistics,
every figure, the re-simulated showcase runs, HTML and Markdown included).
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", default="results/holland648_r5")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    times = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "flocksweep.cli", "report", args.results, "--out", tmp],
                           cwd=ROOT, check=True, capture_output=True)
            times.append(time.perf_counter() - start)
            print(f"report: {times[-1]:.1f} s", flush=True)
    print(f"{args.results}: report in {statistics.median(times):.1f} s (median of {args.repeats}; "
          f"min {min(times):.1f}, max {max(times):.1f})")


if __name__ == "__main__":
    main()
