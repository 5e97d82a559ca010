"""Two checkouts of flocksweep side by side: the same ``flocksweep`` command, interleaved.

    python bench/bench_checkouts.py OTHER_CHECKOUT [--repeats 5] -- run configs/sweeps/smoke.toml --workers 2

Each repeat runs the command (as ``python -m flocksweep.cli ...`` in a new process, with ``--out`` a fresh
folder appended, and PYTHONPATH set to the checkout) once with this checkout and once with the other,
in alternating order, so both see the same load on a shared machine. Prints the wall times, their
medians and the ratio this / other.
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

HERE = Path(__file__).resolve().parent.parent


def timed(checkout: Path, command: list[str]) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "PYTHONPATH": str(checkout)}
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "flocksweep.cli", *command, "--out", str(Path(tmp) / "out"),
                        "--no-progress"], cwd=HERE, env=env, check=True, stdout=subprocess.DEVNULL)
        return time.perf_counter() - start


def main() -> None:
    argv = sys.argv[1:]
    split = argv.index("--") if "--" in argv else len(argv)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path, help="the other checkout (e.g. a git worktree of main)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv[:split])
    command = argv[split + 1:]
    if not command:
        parser.error("give the flocksweep command after --")
    times = {"this": [], "other": []}
    for repeat in range(args.repeats):
        order = [("this", HERE), ("other", args.other)]
        for name, checkout in order if repeat % 2 == 0 else order[::-1]:
            times[name].append(timed(checkout, command))
        print(f"repeat {repeat + 1}: this {times['this'][-1]:.1f} s, other {times['other'][-1]:.1f} s", flush=True)
    this, other = statistics.median(times["this"]), statistics.median(times["other"])
    print(f"flocksweep {' '.join(command)}: this {this:.1f} s (min {min(times['this']):.1f}), "
          f"other ({args.other}) {other:.1f} s (min {min(times['other']):.1f}); ratio {this / other:.2f}")


if __name__ == "__main__":
    main()
