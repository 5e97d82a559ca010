"""A sweep of 100,000 small runs end to end (issue 43, point 4): run, status, resume, export, report.

    python bench/bench_scale_sweep.py [--python OTHER_CHECKOUT_PYTHON] [--sweep bench/sweeps/small_100k.toml]
                                      [--set KEY=VALUE ...] [--workers 2] [--out DIR] [--skip report ...]
                                      [--repeat 3] [--sample 50] [--json FILE]

Every step is the ``flocksweep`` command of the checkout whose Python is given (default: this one), run as
a new process (``python -m flocksweep.entry``) from an empty folder (never the checkout, whose
``flocksweep/`` folder would shadow another checkout's), with its own status cache (``FLOCKSWEEP_CACHE_DIR``):

* ``run``: ``flocksweep run SWEEP --out DIR --workers K --yes --no-progress``: wall time, CPU seconds of the
  command and every process it started (``RUSAGE_CHILDREN``), and the peak resident memory of the whole
  process tree (sampled every 50 ms; sampling can miss a short peak);
* then ``--repeat`` rounds, interleaved, of ``status`` (a full check: a fresh cache), ``status_again`` (the
  same, remembered) and ``resume`` (the same run command again: nothing to do): medians;
* ``export --csv``, ``export --parquet``, ``export --csv --timeseries`` and ``report``, once each: wall time
  and peak memory;
* ``simulation``: CPU seconds per run of ``simcore.simulate`` alone, and of the simulation and its
  metrics (``observables.summary.measure_run``, what every run of the sweep computes), on every
  ``--sample``-th run of the design in one process (kernels loaded first, the second of two passes), so
  that the overhead beyond simulation is ``(run CPU - runs x simulation CPU per run) / runs`` and the
  runner's own (design, scheduling, rows, parts, checksums, table) the same beyond simulation and
  metrics: figures the machine's load barely moves; and ``(wall x workers - sum of the rows' sim_s) /
  runs`` beside them, the wall-time view.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
STEPS = ("run", "status", "status_again", "resume", "export_csv", "export_parquet", "export_timeseries", "report")

SIMULATION = r"""
import json, sys, time
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from flocksweep.simcore import simulate
from flocksweep.observables.summary import every_nth, measure_run
config = load_sweep(sys.argv[1], json.loads(sys.argv[2]))
specs = expand(config)[::int(sys.argv[3])]
def simulated(spec):
    r = spec.preset.run
    return simulate(spec.preset.model, spec.preset.init, spec.seed, r.duration, r.dt, r.record_every)
def measured(spec):
    measure_run(every_nth(simulated(spec), 1), spec.metrics)
from flocksweep.sweeps.worker import execute_batch
measured(specs[0])
out = {"runs": len(specs)}
for name, work in (("cpu_per_run", simulated), ("measured_cpu_per_run", measured), ("worker_cpu_per_run", None)) * 2:
    start = time.process_time()
    if work is None:   # what a worker does with them: one batch (rows, series table)
        execute_batch(specs)
    else:
        for spec in specs:
            work(spec)
    out[name] = (time.process_time() - start) / len(specs)   # the second pass counts (warm)
print(json.dumps(out))
"""


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _tree(proc: psutil.Process, cpu: dict) -> int:
    """The resident memory of ``proc`` and its descendants now; each one's CPU seconds so far go into
    ``cpu`` (by pid: the last sample of a process that has ended stays)."""
    total = 0
    try:
        members = [proc] + proc.children(recursive=True)
    except psutil.Error:
        return 0
    for p in members:
        try:
            with p.oneshot():
                total += p.memory_info().rss
                times = p.cpu_times()
                cpu[p.pid] = times.user + times.system
        except psutil.Error:
            pass
    return total


def timed(cmd: list[str], env: dict) -> dict:
    """Wall seconds, CPU seconds of the process tree (and of the command's own process alone, sampled) and
    its peak resident memory."""
    cpu, start = _children_cpu(), time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=env["BENCH_CWD"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    watcher, peak, seen = psutil.Process(proc.pid), 0, {}
    while proc.poll() is None:
        peak = max(peak, _tree(watcher, seen))
        time.sleep(0.05)
    out, err = proc.communicate()
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited with {proc.returncode}:\n{err[-3000:]}")
    return {"wall": wall, "cpu": _children_cpu() - cpu, "command_cpu": seen.get(proc.pid, 0.0),
            "peak_mib": peak / 2**20, "stdout": out[-2000:], "stderr": err[-2000:]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--python", default=sys.executable, help="the Python of the checkout to measure")
    parser.add_argument("--sweep", type=Path, default=ROOT / "bench" / "sweeps" / "small_100k.toml")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, help="results folder (default: a new temporary one, removed)")
    parser.add_argument("--skip", nargs="*", default=[], choices=STEPS + ("simulation",))
    parser.add_argument("--sample", type=int, default=50, help="simulate every this many runs alone")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of status, status again and resume "
                        "(interleaved; medians reported)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    base = Path(tempfile.mkdtemp(prefix="scale-sweep-"))
    out = args.out or base / "results"
    (base / "cwd").mkdir()   # not the checkout: its flocksweep/ folder would shadow another checkout's
    env = {**os.environ, "FLOCKSWEEP_CACHE_DIR": str(base / "cache"), "BENCH_CWD": str(base / "cwd")}
    exe = [args.python, "-m", "flocksweep.entry"]
    sets = [x for item in args.overrides for x in ("--set", item)]
    run = exe + ["run", str(args.sweep.resolve()), "--out", str(out), "--workers", str(args.workers), "--yes",
                 "--no-progress", *sets]
    commands = {"run": run, "status": exe + ["status", str(out)], "status_again": exe + ["status", str(out)],
                "resume": run, "export_csv": exe + ["export", str(out), "--csv", "--out", str(base / "csv")],
                "export_parquet": exe + ["export", str(out), "--parquet", "--out", str(base / "parquet")],
                "export_timeseries": exe + ["export", str(out), "--csv", "--timeseries", "--out",
                                            str(base / "series")],
                "report": exe + ["report", str(out), "--out", str(base / "report")]}
    print(f"{args.python}: {args.sweep.name} {' '.join(args.overrides)}; load average {os.getloadavg()[0]:.1f}",
          flush=True)
    results = {}
    quick = ("status", "status_again", "resume")
    order = ["run"] + [step for _ in range(args.repeat) for step in quick] + [
        step for step in STEPS if step not in quick and step != "run"]
    for k, step in enumerate(order):
        if step in args.skip:
            continue
        if step == "status":   # a fresh cache: a full check (status_again then finds it remembered)
            env["FLOCKSWEEP_CACHE_DIR"] = str(base / f"cache{k}")
        got = timed(commands[step], env)
        record = {key: v for key, v in got.items() if key not in ("stdout", "stderr")}
        record["load"] = os.getloadavg()[0]
        results.setdefault(step, []).append(record)
        print(f"  {step}: {got['wall']:.2f} s wall, {got['cpu']:.1f} s CPU (the command's own process "
              f"{got['command_cpu']:.1f} s), peak {got['peak_mib']:.0f} MiB (load {record['load']:.1f})", flush=True)
        if step == "status" and len(results[step]) == 1:
            print("    " + got["stdout"].strip().replace("\n", "\n    ")[:600])
    for step in [s for s in STEPS if s in results]:
        got = results[step]
        results[step] = {key: statistics.median(r[key] for r in got) for key in got[0]}
        results[step]["rounds"] = len(got)
        if len(got) > 1:
            print(f"  {step}, median of {len(got)}: {results[step]['wall']:.2f} s wall, "
                  f"{results[step]['cpu']:.2f} s CPU, peak {results[step]['peak_mib']:.0f} MiB")
    if "run" in results:
        import pandas as pd

        table = pd.read_parquet(out / "runs.parquet", columns=["status", "sim_s"])
        runs = len(table)
        results["runs"] = runs
        results["ok"] = int((table["status"] == "ok").sum())
        results["sim_s"] = float(table["sim_s"].sum())
        wall_view = (results["run"]["wall"] * args.workers - results["sim_s"]) / runs
        print(f"  {runs:,} runs ({results['ok']:,} ok); wall x workers - sum(sim_s) = {wall_view * 1e3:.2f} ms per run")
        if "simulation" not in args.skip:
            with tempfile.TemporaryDirectory() as tmp:
                script = Path(tmp) / "simulation.py"
                script.write_text(SIMULATION)
                done = subprocess.run([args.python, str(script), str(args.sweep.resolve()),
                                       json.dumps(args.overrides), str(args.sample)], cwd=env["BENCH_CWD"], env=env,
                                      capture_output=True, text=True, check=True)
            sim = json.loads(done.stdout.strip().splitlines()[-1])
            results["simulation"] = sim
            overhead = (results["run"]["cpu"] - runs * sim["cpu_per_run"]) / runs
            runner = (results["run"]["cpu"] - runs * sim["measured_cpu_per_run"]) / runs
            results["overhead_cpu_ms"] = overhead * 1e3
            results["runner_overhead_cpu_ms"] = runner * 1e3
            parts = (results["run"]["command_cpu"] / runs + sim["worker_cpu_per_run"] - sim["measured_cpu_per_run"])
            results["runner_parts_cpu_ms"] = parts * 1e3
            print(f"  by its parts: the runner process {results['run']['command_cpu'] / runs * 1e3:.3f} ms CPU per run "
                  f"(design, batches, parts, checksums, table, start-up) + a worker's own beyond simulation and "
                  f"metrics {(sim['worker_cpu_per_run'] - sim['measured_cpu_per_run']) * 1e3:.3f} ms (rows, series "
                  f"table; measured in one process, {sim['worker_cpu_per_run'] * 1e3:.3f} ms a run in a batch) = "
                  f"{parts * 1e3:.3f} ms per run")
            print(f"  simulation alone: {sim['cpu_per_run'] * 1e3:.3f} ms CPU per run, simulated and measured "
                  f"(measure_run): {sim['measured_cpu_per_run'] * 1e3:.3f} ms ({sim['runs']} runs); the run's CPU "
                  f"beyond the simulation: {overhead * 1e3:.3f} ms per run, beyond simulation and metrics (the "
                  f"runner's own): {runner * 1e3:.3f} ms per run")
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    if args.out is None:
        shutil.rmtree(base, ignore_errors=True)
    else:
        shutil.rmtree(base, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
