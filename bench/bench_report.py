"""Report generation time: ``flocksweep report`` on a finished sweep, whole command, medians of repeats;
optionally this checkout against another one, interleaved.

    python bench/bench_report.py [--results results/holland648] [--repeats 3] [--other CHECKOUT_PYTHON]

Each repeat runs ``flocksweep report RESULTS --out <fresh dir>`` in a new process (imports, statistics,
claims with their power analysis, every figure, the re-simulated showcase runs, HTML and Markdown
included) and records its wall time and CPU time (user + sys of the child, from ``getrusage``). With
``--other`` (the python of another checkout's virtualenv, e.g. one of main) each repeat runs both, in
alternating order, so both see the same load; the ratios this / other are of the medians. The machine's
load average is printed at the start and the end (a shared machine: CPU seconds and ratios hold, wall
times do not). ``--keep DIR`` keeps the last reports (DIR/this, DIR/other) for
``bench/compare_reports.py``.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def timed(python: str, results: str, out: Path) -> tuple[float, float]:
    """(wall s, CPU s) of one report in a new process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([python, "-m", "flocksweep.cli", "report", str(Path(results).resolve()), "--out", str(out)],
                   cwd=ROOT, check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", default="results/holland648")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--other", help="python of another checkout's virtualenv (compared interleaved)")
    parser.add_argument("--keep", type=Path, help="keep the last repeat's reports here (this/, other/)")
    args = parser.parse_args()
    sides = {"this": sys.executable}
    if args.other:
        sides["other"] = args.other
    times = {name: [] for name in sides}
    print(f"load average at start: {' '.join(f'{v:.2f}' for v in os.getloadavg())}", flush=True)
    for repeat in range(args.repeats):
        order = list(sides.items())
        for name, python in order if repeat % 2 == 0 else order[::-1]:
            with tempfile.TemporaryDirectory() as tmp:
                times[name].append(timed(python, args.results, Path(tmp) / "report"))
                if args.keep and repeat == args.repeats - 1:
                    shutil.rmtree(args.keep / name, ignore_errors=True)
                    shutil.copytree(Path(tmp) / "report", args.keep / name)
        print(f"repeat {repeat + 1}: " + ", ".join(f"{name} {times[name][-1][0]:.1f} s wall, {times[name][-1][1]:.1f} "
                                                  f"CPU-s" for name in sides), flush=True)
    print(f"load average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    medians = {name: (statistics.median(w for w, _ in times[name]), statistics.median(c for _, c in times[name]))
               for name in sides}
    for name in sides:
        walls, cpus = [w for w, _ in times[name]], [c for _, c in times[name]]
        print(f"{name} ({sides[name]}): report of {args.results} in {medians[name][0]:.1f} s wall (min "
              f"{min(walls):.1f}), {medians[name][1]:.1f} CPU-s (min {min(cpus):.1f}); median of {args.repeats}")
    if "other" in sides:
        print(f"ratio this / other: wall {medians['this'][0] / medians['other'][0]:.2f}, "
              f"CPU {medians['this'][1] / medians['other'][1]:.2f}")


if __name__ == "__main__":
    main()
