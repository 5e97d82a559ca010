"""``flocksweep compile [MODEL.toml ...] [--jobs K]``: the command's work,
``run(args)``, for its declaration in ``flocksweep/commands/compile.py``. The kernels are compiled by :func:`sweeps.compile.compile_kernels`;
this module imports neither numba nor the simulator until the command runs, so ``compile --help`` is quick.
"""
from __future__ import annotations

import os
import time

# what every shipped preset's kernels take to compile (bench/RESULTS.md)
ESTIMATE = "usually 5-10 min for every shipped model on 2 cores, longer on a busy machine"


def run(args) -> int:
    """``flocksweep compile``: bad input (a --jobs below 1, a missing or invalid preset) is refused before
    anything compiles."""
    from flocksweep.simcore import load_preset

    from .compile import compile_kernels
    from .failures import check_count
    from .progress import Ticker

    check_count("--jobs", args.jobs, 1)
    for model in args.models:
        load_preset(model)
    jobs = args.jobs or os.cpu_count() or 1
    start = time.perf_counter()
    what = f"{len(args.models)} model(s)" if args.models else "the shipped presets"
    print(f"compiling the kernels of {what} in up to {jobs} processes ...", flush=True)
    ticker = Ticker("compile", ESTIMATE)
    results = compile_kernels(args.models or None, jobs, report=ticker.say, ticker=ticker)
    compiled = sum(r.compiled for r in results)
    print(f"{compiled} kernels compiled ({'now cached' if compiled else 'none: all were cached'}) in "
          f"{time.perf_counter() - start:.1f} s")
    return 0
