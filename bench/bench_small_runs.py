"""A sweep of many small runs against the in-process batched kernel on the same runs (issue 43, point 1).

    python bench/bench_small_runs.py [--against OTHER_VENV_PYTHON] [--rounds 5] [--workers 2]
                                     [--sweep bench/sweeps/small_2000.toml] [--set KEY=VALUE ...]
                                     [--replicates R] [--command]

Each round runs, in fresh processes taking turns (so every side sees the same load):

* ``kernel``: the same runs simulated in one process by ``flocksweep.simcore.simulate_batch``, one call per
  design point with all its replicates' seeds, on numba's threads (``--workers`` of them), after a
  first call that loads the kernels; nothing else (no metrics, no files). Its wall time is the
  reference: the throughput of the compiled kernel on this machine at this moment. Then, untimed in
  that figure, the CPU seconds of measuring every run once (``observables.summary.measure_run``, what
  every sweep row needs), to say how much of a sweep's time its metrics take;
* ``sweep`` (this checkout, and with ``--against`` another checkout's Python, a virtualenv whose
  ``flocksweep`` is the other checkout): ``run_sweep`` of the sweep into a fresh folder, in a process that
  has started a local pool of ``--workers`` processes and had each load the kernels first (as
  ``flocksweep run`` starts its pool before reading the sweep). Timed: the whole ``run_sweep`` call
  (design, plan, the runs with their metrics, the parts and checksums, the consolidated table and
  manifest), and the CPU seconds of the runner process and of its workers during it;
* with ``--command``: the whole ``flocksweep run SWEEP --workers K`` command as a new process (start-up,
  pool start, compile check included), wall time.

The figure of the target is ``kernel wall / sweep wall`` (the sweep's simulation throughput as a share
of the kernel's), per round and its median; CPU milliseconds per run are printed beside it (kernel,
metrics, the sweep's workers and its runner). With ``--against`` the runs' results are compared bit for
bit across checkouts with ``bench/compare_results.py`` at the end.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SWEEP_CHILD = r"""
import json, sys, time
import psutil
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.runner import run_sweep
from flocksweep.sweeps import worker
from flocksweep.sweeps.design import expand

def tree_cpu():
    # (CPU seconds of this process, of its live children)
    me = psutil.Process()
    children = 0.0
    for child in me.children(recursive=True):
        try:
            children += sum(child.cpu_times()[:2])
        except psutil.Error:
            pass
    return sum(me.cpu_times()[:2]), children

if __name__ == "__main__":
    path, out, workers, overrides, replicates = sys.argv[1], sys.argv[2], int(sys.argv[3]), json.loads(sys.argv[4]), json.loads(sys.argv[5])
    config = load_sweep(path, overrides, replicates)
    first = expand(config)[0]
    with Executor("local", workers, preload=("flocksweep.sweeps.worker:prepare",)) as pool:
        pool.map(worker.warm_up, [first] * workers)
        worker.warm_up(first)
        (own, children), start = tree_cpu(), time.perf_counter()
        result = run_sweep(config, None, out, executor="local", workers=workers, progress=False, pool=pool)
        wall = time.perf_counter() - start
        own_after, children_after = tree_cpu()   # the pool still runs: its workers' CPU is readable
    table = result.table
    print(json.dumps({"wall": wall, "cpu": own_after - own + children_after - children, "runner_cpu": own_after - own,
                      "runs": len(table), "ok": int((table["status"] == "ok").sum()),
                      "sim_s": float(table["sim_s"].sum())}))
"""

KERNEL_CHILD = r"""
import json, sys, time
from collections import defaultdict
import numba
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from flocksweep.simcore import simulate_batch
from flocksweep.observables.summary import measure_run

path, workers, overrides, replicates = sys.argv[1], int(sys.argv[2]), json.loads(sys.argv[3]), json.loads(sys.argv[4])
numba.set_num_threads(workers)
specs = expand(load_sweep(path, overrides, replicates))
points = defaultdict(list)
for spec in specs:
    points[spec.point_index].append(spec)
groups = [(group[0].preset, [s.seed for s in group]) for group in points.values()]
def run(groups):
    out = []
    for preset, seeds in groups:
        r = preset.run
        out += simulate_batch(preset.model, preset.init, seeds, r.duration, r.dt, r.record_every)
    return out
run(groups[:1])
cpu, start = time.process_time(), time.perf_counter()
observations = run(groups)
wall, cpu = time.perf_counter() - start, time.process_time() - cpu
measured = [spec for group in points.values() for spec in group]
measure_run(observations[0], measured[0].metrics)   # its kernels loaded
metrics_cpu = time.process_time()
for spec, obs in zip(measured, observations):
    measure_run(obs, spec.metrics)
metrics_cpu = time.process_time() - metrics_cpu
print(json.dumps({"wall": wall, "cpu": cpu, "metrics_cpu": metrics_cpu, "runs": len(specs),
                  "boid_steps": sum(s.preset.init.n * s.preset.run.n_steps for s in specs)}))
"""


def _child(python: str, code: str, args: list[str], cwd: Path) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "child.py"
        script.write_text(code)
        done = subprocess.run([python, str(script), *args], cwd=cwd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{python} child failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _command(python: str, sweep: Path, out: Path, workers: int, overrides: list[str], replicates) -> float:
    cmd = [python, "-m", "flocksweep.entry", "run", str(sweep), "--out", str(out), "--workers", str(workers),
           "--no-progress", "--yes"]
    for item in overrides:
        cmd += ["--set", item]
    if replicates is not None:
        cmd += ["--replicates", str(replicates)]
    start = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, cwd=ROOT)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", type=Path, default=ROOT / "bench" / "sweeps" / "small_2000.toml")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--replicates", type=int)
    parser.add_argument("--against", help="the Python of another checkout's virtualenv, timed in turn")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--command", action="store_true", help="also time the whole flocksweep run command")
    parser.add_argument("--keep", type=Path, help="keep the last round's results folders here")
    args = parser.parse_args()
    sides = {"new": sys.executable}
    if args.against:
        sides["old"] = args.against
    sweep = args.sweep.resolve()
    extra = [json.dumps(args.overrides), json.dumps(args.replicates)]
    print(f"{sweep.name} {' '.join(args.overrides)}; load average {os.getloadavg()[0]:.1f}", flush=True)
    rows = {name: [] for name in [*sides, "kernel"]}
    commands = {name: [] for name in sides}
    keep = Path(tempfile.mkdtemp(prefix="small-runs-")) if args.keep is None else args.keep
    for r in range(args.rounds):
        order = list(sides.items()) if r % 2 == 0 else list(sides.items())[::-1]
        kernel = _child(sys.executable, KERNEL_CHILD, [str(sweep), str(args.workers), *extra], ROOT)
        rows["kernel"].append(kernel)
        line = [f"round {r + 1} (load {os.getloadavg()[0]:.1f}): kernel {kernel['wall']:.2f} s"]
        for name, python in order:
            out = keep / name
            subprocess.run(["rm", "-rf", str(out)], check=True)
            got = _child(python, SWEEP_CHILD, [str(sweep), str(out), str(args.workers), *extra], ROOT)
            assert got["ok"] == kernel["runs"], got
            rows[name].append(got)
            line.append(f"{name} {got['wall']:.2f} s ({kernel['wall'] / got['wall']:.0%} of the kernel's "
                        f"throughput, {got['cpu'] / got['runs'] * 1e3:.2f} ms CPU per run, of which runner "
                        f"{got['runner_cpu'] / got['runs'] * 1e3:.2f})")
            if args.command:
                cmd_out = keep / f"{name}-command"
                subprocess.run(["rm", "-rf", str(cmd_out)], check=True)
                commands[name].append(_command(python, sweep, cmd_out, args.workers, args.overrides,
                                               args.replicates))
                line.append(f"{name} command {commands[name][-1]:.2f} s")
        print("; ".join(line), flush=True)
    kernel = rows["kernel"]
    runs = kernel[0]["runs"]
    print(f"\nmedians of {args.rounds} rounds, {runs} runs, {args.workers} workers/threads:")
    print(f"  kernel (simulate_batch): {statistics.median(k['wall'] for k in kernel):.2f} s wall, "
          f"{statistics.median(k['cpu'] for k in kernel) / runs * 1e3:.3f} ms CPU per run "
          f"({runs / statistics.median(k['wall'] for k in kernel):.0f} runs/s); measuring the runs "
          f"(measure_run, one thread): {statistics.median(k['metrics_cpu'] for k in kernel) / runs * 1e3:.3f} ms "
          f"CPU per run")
    for name in sides:
        shares = [k["wall"] / s["wall"] for k, s in zip(kernel, rows[name])]
        cpu = statistics.median(s["cpu"] for s in rows[name]) / runs
        kcpu = statistics.median(k["cpu"] for k in kernel) / runs
        runner = statistics.median(s["runner_cpu"] for s in rows[name]) / runs
        print(f"  {name}: run_sweep {statistics.median(s['wall'] for s in rows[name]):.2f} s wall "
              f"({runs / statistics.median(s['wall'] for s in rows[name]):.0f} runs/s); throughput "
              f"{statistics.median(shares):.1%} of the kernel's (rounds {', '.join(f'{x:.0%}' for x in shares)}); "
              f"{cpu * 1e3:.3f} ms CPU per run ({(cpu - kcpu) * 1e3:+.3f} ms beyond the kernel's, of which the "
              f"runner process {runner * 1e3:.3f})"
              + (f"; whole command {statistics.median(commands[name]):.2f} s" if commands[name] else ""))
    if "old" in sides:
        subprocess.run([sys.executable, str(ROOT / "bench" / "compare_results.py"), str(keep / "old"),
                        str(keep / "new")], cwd=ROOT)
    print(f"results folders of the last round: {keep}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
