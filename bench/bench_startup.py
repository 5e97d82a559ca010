"""Warm start times of the commands that simulate nothing: ``flocksweep --version``, ``--help``, the help
of every subcommand, ``status`` of a results folder (remembered, and ``--verify``: read in full) and
``export`` of its runs table as CSV (also with ``--with-fixed``) and as Parquet, each as a new process,
median of repeats.

    python bench/bench_startup.py --results results/smoke [--repeats 7] [--markdown] [--only status,export]
                                  [--against OTHER_CHECKOUT] [--pycache]

The code is taken from this checkout (``PYTHONPATH``), the first run of each command is discarded
(warm: file cache, status's remembered check, and ``__pycache__`` unless ``PYTHONDONTWRITEBYTECODE`` is
set, as it is on the reference machine: then every flocksweep module is compiled anew in every process;
``--pycache`` unsets it for the commands, as an installed flocksweep runs); ``python -c pass`` is the floor
(and ``python -c 'import pyarrow.parquet'`` that of an export, which must read a Parquet file),
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
            + ["status {results}", "status {results} --verify", "export {results} --csv --out {scratch}",
               "export {results} --csv --with-fixed --out {scratch}", "export {results} --parquet --out {scratch}"])


def timed(argv: list[str], repeats: int, roots=(ROOT,), pycache: bool = False) -> list[list[float] | None]:
    """Per code root (a checkout, as PYTHONPATH), the wall seconds of each repeat (the first run discarded),
    or None when the command fails there; the roots take turns, repeat by repeat, so they share the load."""
    times = [[] for _ in roots]
    env = {k: v for k, v in os.environ.items() if not (pycache and k == "PYTHONDONTWRITEBYTECODE")}
    for attempt in range(repeats + 1):
        for k, root in enumerate(roots):
            if times[k] is None:
                continue
            start = time.perf_counter()
            done = subprocess.run(argv, env={**env, "PYTHONPATH": str(root)}, cwd=root,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            if done.returncode:
                times[k] = None
            elif attempt:
                times[k].append(time.perf_counter() - start)
    return times


def cell(times) -> str:
    return "fails" if times is None else f"{statistics.median(times):.2f} s ({min(times):.2f}-{max(times):.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", default="results/smoke", help="a results folder for status")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    parser.add_argument("--only", help="comma-separated words: only the commands containing one of them")
    parser.add_argument("--against", type=Path, help="another checkout (e.g. a git archive of main), timed in turn "
                                                     "with this one")
    parser.add_argument("--pycache", action="store_true", help="let the commands write and use __pycache__ "
                                                               "(unset PYTHONDONTWRITEBYTECODE for them)")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    roots = (ROOT,) if args.against is None else (args.against.resolve(), ROOT)
    rows = [("python -c pass (floor)", timed([sys.executable, "-c", "pass"], args.repeats, roots, args.pycache))]
    chosen = [c for c in COMMANDS if not args.only or any(w in c for w in args.only.split(","))]
    if any(c.startswith("export {results}") for c in chosen):   # what any export of a Parquet table must load
        rows.append(("python -c 'import pyarrow.parquet'",
                     timed([sys.executable, "-c", "import pyarrow.parquet"], args.repeats, roots, args.pycache)))
    with tempfile.TemporaryDirectory() as scratch:
        for command in chosen:
            words = command.format(results=args.results, scratch=scratch).split()
            rows.append((f"flocksweep {command.replace(' --out {scratch}', '')}",
                         timed([sys.executable, "-m", "flocksweep.entry", *words], args.repeats, roots, args.pycache)))
    print(f"load average {load:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, on {os.cpu_count()} cores; "
          f"median (min-max) of {args.repeats}; __pycache__ "
          f"{'used' if args.pycache or not os.environ.get('PYTHONDONTWRITEBYTECODE') else 'off'}")
    names = [str(r) for r in roots]
    if args.markdown:
        print("| command | " + " | ".join(names) + " |\n|---|" + "---:|" * len(roots))
    for name, per_root in rows:
        print(f"| `{name}` | " + " | ".join(cell(t) for t in per_root) + " |" if args.markdown
              else f"{name:45s} " + "   ".join(f"{cell(t):24s}" for t in per_root))


if __name__ == "__main__":
    main()
