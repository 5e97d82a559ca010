"""The first compile of simcore, this checkout against another, interleaved (issue 10, start-up).

    python bench/bench_first_compile.py OTHER_CHECKOUT [--pairs 3] [--warm 7] [--all-models]

Each pair runs a tiny ``flocksweep simulate`` (holland, 3 boids, one step) as a new process with an empty
numba cache (``NUMBA_CACHE_DIR`` a new temporary directory) once with each checkout, in alternating
order, so both see the same load on a shared machine; it reports the CPU seconds of each child (user +
system: less sensitive to the machine's load than wall time), the ratio this / other per pair, and how
many times the "compiling" notice was printed. ``--warm N`` then times N interleaved repeats of the same
command with each checkout's kernels cached (wall and CPU seconds, medians). ``--all-models`` adds one
pair of a process that simulates every preset of ``configs/models`` (tiny runs) with an empty cache: what
a fresh checkout's test suite pays to compile every dynamics and perception kind.
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
TINY = ["-m", "flocksweep.entry", "simulate", "configs/models/holland.toml", "--n", "3", "--duration",
        "0.016666666666666666"]
EVERY_MODEL = """
from pathlib import Path
from flocksweep.simcore import load_preset, simulate
for path in sorted(Path("configs/models").glob("*.toml")):
    preset = load_preset(path, ["init.n=5"])
    simulate(preset.model, preset.init, 1, 2 * preset.run.dt, preset.run.dt)
"""


def child(checkout: Path, args: list[str], cache: str) -> tuple[float, float, str]:
    """(wall s, CPU s, stderr) of ``python *args`` run in ``checkout`` with that numba cache directory."""
    env = {**os.environ, "PYTHONPATH": str(checkout), "NUMBA_CACHE_DIR": cache}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *args], cwd=checkout, env=env, capture_output=True, text=True,
                          check=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), done.stderr


def cold(checkout: Path, args: list[str]) -> tuple[float, float, int]:
    with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
        wall, cpu, err = child(checkout, args, cache)
    return wall, cpu, err.count("compiling the simulation kernels")


def pairs(this: Path, other: Path, args: list[str], n: int, label: str) -> None:
    print(f"{label}: empty numba cache, CPU seconds of the child (wall), this / other", flush=True)
    ratios = []
    for p in range(n):
        order = [this, other] if p % 2 == 0 else [other, this]
        got = {checkout: cold(checkout, args) for checkout in order}
        (w1, c1, n1), (w2, c2, n2) = got[this], got[other]
        ratios.append(c1 / c2)
        print(f"  pair {p + 1}: this {c1:.1f} s ({w1:.1f}), other {c2:.1f} s ({w2:.1f}): {c1 / c2:.2f}x; "
              f"notices {n1} / {n2}; load {os.getloadavg()[0]:.1f}", flush=True)
    print(f"  median ratio {statistics.median(ratios):.2f}x", flush=True)


def warm(this: Path, other: Path, repeats: int) -> None:
    print("warm (kernels cached): median wall / CPU seconds", flush=True)
    with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
        caches = {this: a, other: b}
        for checkout, cache in caches.items():
            child(checkout, TINY, cache)   # compile once
        times = {this: [], other: []}
        for r in range(repeats):
            for checkout in ([this, other] if r % 2 == 0 else [other, this]):
                times[checkout].append(child(checkout, TINY, caches[checkout])[:2])
    med = {c: (statistics.median(w for w, _ in t), statistics.median(u for _, u in t)) for c, t in times.items()}
    print(f"  this {med[this][0]:.2f} / {med[this][1]:.2f} s, other {med[other][0]:.2f} / {med[other][1]:.2f} s: "
          f"{med[this][0] / med[other][0]:.2f}x wall, {med[this][1] / med[other][1]:.2f}x CPU", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path, help="the other checkout (e.g. a worktree of main)")
    parser.add_argument("--pairs", type=int, default=3)
    parser.add_argument("--warm", type=int, default=7, help="warm repeats per checkout (0: skip)")
    parser.add_argument("--all-models", action="store_true", help="also one pair compiling every preset")
    args = parser.parse_args()
    this, other = HERE, args.other.resolve()
    pairs(this, other, TINY, args.pairs, "tiny holland simulate")
    if args.warm:
        warm(this, other, args.warm)
    if args.all_models:
        pairs(this, other, ["-c", EVERY_MODEL], 1, "every preset of configs/models")


if __name__ == "__main__":
    main()
