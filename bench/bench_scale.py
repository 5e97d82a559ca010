"""Scale and start-up of the simulator: O(N) neighbour search, big flocks, threads, compile and start-up.

    python bench/bench_scale.py [--only scaling holland1000 big startup compile] [--repeats 3] [--json FILE]

* ``scaling``: cost per boid-step at constant density (ball radius growing as N^(1/3), open world) for
  ``opensteer`` (the preset in an open world), ``sphere`` (the Hartman-Benes preset), ``topological``
  and ``holland`` (range 20, field 120, direction 60, occlusion on), at N = 2,000 and 20,000 (and the sizes
  given with ``--sizes``), one thread, ``--steps`` steps from the preset's initial state; reports the
  ratio of the cost per boid-step at the largest N to that at the smallest (O(N) search: close to 1).
* ``holland1000``: boid-steps per second of ``holland`` with occlusion at N = 1,000 in Holland's density
  (the start radius 20 scaled from N = 100), one thread, 5 simulated seconds.
* ``big``: 100,000 boids of ``opensteer`` (open world, constant density): seconds per step on all cores
  (threaded synchronous run), in a fresh process whose peak resident memory is reported.
* ``startup``: a warm ``flocksweep simulate`` of a 3-boid, 1-step run as a new process (kernels cached),
  median wall time; both ``python -m flocksweep.cli`` and the installed ``flocksweep`` script when found,
  interleaved with what any numba program pays (``import numba``; ``numba_floor``: one cached kernel called).
* ``compile``: the same command with an empty numba cache (``NUMBA_CACHE_DIR`` set to a new temporary
  directory): the first compile of simcore's kernels, and whether the "compiling" notice was printed.

Timings are medians of ``--repeats``; the machine is shared, so compare ratios taken in one run.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "configs" / "models"
TINY = ["simulate", str(MODELS / "holland.toml"), "--n", "3", "--duration", "0.016666666666666666"]
SCALING = {
    "opensteer": (MODELS / "opensteer.toml", ["world.boundary=open", "init.scale_with_n=true"]),
    "sphere": (MODELS / "hartman_benes.toml", []),
    "topological": (MODELS / "topological.toml", []),
    "holland": (MODELS / "holland.toml", ["init.scale_with_n=true", "perception.range=20", "perception.field_deg=120",
                                          "perception.direction_deg=60", "perception.occlusion=true"]),
}


def _env(threads: int | None = None, cache_dir: str | None = None) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    return env


def _python(code: str, threads: int | None = None) -> dict:
    """Run ``code`` in a fresh interpreter; it prints one JSON line, returned parsed."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(threads), check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


_PER_STEP = """
import json, statistics, time
from flocksweep.simcore import load_preset
from flocksweep.simcore.simulate import advance
from flocksweep.simcore.rng import run_streams
from flocksweep.simcore.state import initial_state
p = load_preset({path!r}, {overrides!r} + ["init.n={n}"])
rng, key = run_streams(1)
state = initial_state(p.init, p.model.patterns, rng)
advance(p.model, state, 1, p.run.dt, 1, key, threads={threads})
times = []
for _ in range({repeats}):
    t = time.perf_counter()
    obs = advance(p.model, state, {steps}, p.run.dt, {steps}, key, threads={threads})
    times.append(time.perf_counter() - t)
print(json.dumps({{"seconds_per_step": statistics.median(times) / {steps}, "visible": float(obs.visible[-1].mean())}}))
"""


def scaling(sizes, steps: int, repeats: int) -> list[dict]:
    """Sizes interleaved (small, large, small, large, ...), each in a fresh process; medians per size and of
    the per-repeat ratios."""
    rows = []
    for model, (path, overrides) in SCALING.items():
        costs = {n: [] for n in sizes}
        visible = {}
        for _ in range(repeats):
            for n in sizes:
                r = _python(_PER_STEP.format(path=str(path), overrides=overrides, n=n, steps=steps, repeats=1,
                                             threads=1), threads=1)
                costs[n].append(r["seconds_per_step"] / n)
                visible[n] = r["visible"]
        for n in sizes:
            cost = statistics.median(costs[n])
            rows.append({"model": model, "n": n, "us_per_boid_step": cost * 1e6, "visible": visible[n]})
            print(f"  {model:12s} N={n:6d}: {cost * 1e6:7.3f} us per boid-step (visible {visible[n]:.1f})", flush=True)
        ratios = [big / small for big, small in zip(costs[max(sizes)], costs[min(sizes)])]
        rows.append({"model": model, "ratio": statistics.median(ratios), "ratio_min": min(ratios),
                     "ratio_max": max(ratios)})
        print(f"  {model:12s} cost ratio N={max(sizes)} / N={min(sizes)}: {rows[-1]['ratio']:.2f} "
              f"({min(ratios):.2f}-{max(ratios):.2f})", flush=True)
    return rows


def holland1000(repeats: int) -> dict:
    code = """
import json, statistics, time
from flocksweep.simcore import load_preset, simulate_preset
p = load_preset({path!r}, ["init.n=1000", "init.scale_with_n=true", "perception.range=20", "perception.field_deg=120",
                          "perception.direction_deg=60", "perception.occlusion=true", "run.duration=5",
                          "run.record_interval=5"])
simulate_preset(p, 0)
rates = []
for seed in range(1, {repeats} + 1):
    t = time.perf_counter(); obs = simulate_preset(p, seed)
    rates.append(1000 * p.run.n_steps / (time.perf_counter() - t))
print(json.dumps({{"boid_steps_per_s": statistics.median(rates), "min": min(rates), "max": max(rates),
                  "visible": float(obs.visible[1:].mean())}}))
""".format(path=str(MODELS / "holland.toml"), repeats=repeats)
    r = _python(code, threads=1)
    print(f"  holland N=1000, Holland's density: {r['boid_steps_per_s']:,.0f} boid-steps/s "
          f"({r['min']:,.0f}-{r['max']:,.0f}), visible {r['visible']:.1f}", flush=True)
    return r


def big(n: int, steps: int) -> dict:
    code = """
import json, resource, statistics, time, numba
from flocksweep.simcore import load_preset
from flocksweep.simcore.simulate import advance
from flocksweep.simcore.rng import run_streams
from flocksweep.simcore.state import initial_state
p = load_preset({path!r}, ["world.boundary=open", "init.scale_with_n=true", "init.n={n}"])
rng, key = run_streams(1)
state = initial_state(p.init, p.model.patterns, rng)
advance(p.model, state, 1, p.run.dt, 1, key)
times = []
for _ in range({steps}):
    t = time.perf_counter(); state = advance(p.model, state, 1, p.run.dt, 1, key).final
    times.append(time.perf_counter() - t)
print(json.dumps({{"seconds_per_step": statistics.median(times), "threads": numba.get_num_threads(),
                  "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}}))
""".format(path=str(MODELS / "opensteer.toml"), n=n, steps=steps)
    r = _python(code)
    print(f"  opensteer N={n:,}: {r['seconds_per_step']:.3f} s per step on {r['threads']} threads, "
          f"peak RSS {r['peak_rss_mib']:.0f} MiB", flush=True)
    return r


def _time_commands(cmds: dict, env, repeats: int, cwd=ROOT) -> dict:
    """Median wall seconds of each command, the commands interleaved in every repeat (same load for all)."""
    times = {name: [] for name in cmds}
    for _ in range(repeats):
        for name, cmd in cmds.items():
            start = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True, env=env, cwd=cwd)
            times[name].append(time.perf_counter() - start)
    return {name: statistics.median(values) for name, values in times.items()}


NUMBA_FLOOR = """import numba
@numba.njit(cache=True)
def one(x):
    return x + 1
one(1)
"""


def startup(repeats: int) -> dict:
    """The tiny simulate command against what any numba program pays: a bare interpreter, ``import numba``,
    and ``numba_floor`` (import numba and call one kernel loaded from numba's cache: numba then sets up
    its compiler target, which imports its numpy implementations and scipy.linalg for BLAS)."""
    env = _env()
    module = [sys.executable, "-m", "flocksweep.entry", *TINY]
    subprocess.run(module, check=True, capture_output=True, env=env, cwd=ROOT)  # compile or load once
    with tempfile.TemporaryDirectory(prefix="numba-floor-") as tmp:
        floor = Path(tmp) / "floor.py"
        floor.write_text(NUMBA_FLOOR)
        subprocess.run([sys.executable, str(floor)], check=True, env=env, cwd=tmp)  # cache the kernel
        cmds = {"python_m_sweeps_cli": module, "bare_python": [sys.executable, "-c", "pass"],
                "import_numba": [sys.executable, "-c", "import numba"], "numba_floor": [sys.executable, str(floor)]}
        script = Path(sys.executable).parent / "flocksweep"
        if script.exists():
            cmds["flocksweep_script"] = [str(script), *TINY]
        out = _time_commands(cmds, env, repeats)
    for key, value in out.items():
        print(f"  {key}: {value:.2f} s", flush=True)
    return out


def compile_time() -> dict:
    with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "flocksweep.entry", *TINY], capture_output=True, text=True,
                              env=_env(cache_dir=cache), cwd=ROOT, check=True)
        seconds = time.perf_counter() - start
    notices = done.stderr.count("compiling")
    print(f"  first compile (empty numba cache): {seconds:.1f} s, notice printed {notices} time(s)", flush=True)
    return {"seconds": seconds, "notices": notices}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["scaling", "holland1000", "big", "startup", "compile"])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2000, 20000])
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--big-n", type=int, default=100_000)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    results = {}
    if "scaling" in args.only:
        print("scaling at constant density (one thread):", flush=True)
        results["scaling"] = scaling(args.sizes, args.steps, args.repeats)
    if "holland1000" in args.only:
        results["holland1000"] = holland1000(args.repeats)
    if "big" in args.only:
        results["big"] = big(args.big_n, 5)
    if "startup" in args.only:
        print("start-up of a warm tiny `flocksweep simulate`:", flush=True)
        results["startup"] = startup(max(5, args.repeats))
    if "compile" in args.only and shutil.which(sys.executable):
        results["compile"] = compile_time()
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
