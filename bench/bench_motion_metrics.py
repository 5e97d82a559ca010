"""What the observables of collective motion cost against the simulation they measure.

    python bench/bench_motion_metrics.py [--boids 30] [--duration 30] [--repeats 7]

The workload users run: a whole run of the holland preset (``--boids`` boids, ``--duration`` s, its
dt of 1/60 s), recorded every 1 s (the shipped presets) and every 0.1 s (a tracker's rate), simulated
afresh in each repeat. Timed per repeat, one after the other (interleaved, so all see the same load):

* ``simulate``: :func:`simcore.simulate_preset` of the whole run;
* ``row``: :func:`observables.summary.measure_run`, everything a sweep row and its series hold;
* ``new``: the observables of collective motion alone: the per-run scalars
  (:func:`observables.motion.motion_metrics`) plus the three per-record kernels ``frame_kernel`` runs
  for them (``focal_neighbours_frame``, ``correlation_length_frame``, ``spacing_profile_frame``) over
  every record, called from one compiled loop here on the groups ``frame_kernel`` already has
  (:func:`observables.kernels.graph_run`, outside the timing);
* ``new, pairwise off``: the same with ``pairwise_metrics = false`` (the k nearest and the correlation
  length skipped).

Prints medians over the repeats (kernels compiled and loaded first) and the median over the repeats of
each repeat's ratio to its own ``simulate`` (the share).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from numba import njit

from flocksweep.observables import kernels
from flocksweep.observables.motion import motion_metrics
from flocksweep.observables.summary import MetricSettings, measure_run, record_interval
from flocksweep.simcore import load_preset, simulate_preset

ROOT = Path(__file__).resolve().parent.parent


@njit(cache=False)
def new_series(pos, vel, box, k, pairwise, labels, unwrapped, nn, out):
    """The three kernels of the new per-record series, record by record, as frame_kernel calls them."""
    n = pos.shape[1]
    dist = np.empty(n)
    order = np.empty(n, np.int64)
    focal = np.empty(6)
    pair_dist = np.empty(n * (n - 1) // 2)
    pair_prod = np.empty(n * (n - 1) // 2)
    for f in range(pos.shape[0]):
        largest = labels[f] == 0
        kernels.focal_neighbours_frame(pos[f], vel[f], box, k, pairwise, dist, order, focal)
        out[f, 0] = focal[0] + focal[3]
        out[f, 1] = kernels.correlation_length_frame(unwrapped[f], vel[f], largest, pair_dist, pair_prod) \
            if pairwise else np.nan
        out[f, 2], out[f, 3] = kernels.spacing_profile_frame(unwrapped[f], vel[f], largest, nn[f], dist)


def groups(obs, radius: float):
    r, n = obs.pos.shape[:2]
    labels = np.empty((r, n), np.int32)
    unwrapped = np.empty((r, n, 3))
    nn = np.empty((r, n))
    degree = np.empty((r, n), np.int32)
    same = np.empty((r, n), np.int32)
    count = np.empty(r, np.int64)
    kernels.graph_run(np.ascontiguousarray(obs.pos), np.zeros(n, np.uint32), radius, 0.0, labels, unwrapped, nn,
                      degree, same, count)
    return labels, unwrapped, nn


def timed(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--boids", type=int, default=30)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    cases = {}
    for interval in (1.0, 0.1):
        preset = load_preset(ROOT / "configs/models/holland.toml",
                             [f"init.n={args.boids}", f"run.duration={args.duration}", f"run.record_interval={interval}"])
        settings = MetricSettings().resolve(preset.model)
        cases[interval] = (preset, settings)
    times = {(interval, part): [] for interval in cases for part in ("simulate", "row", "new", "new_off")}
    for repeat in range(args.repeats + 1):            # repeat 0 compiles and loads: not counted
        for interval, (preset, settings) in cases.items():
            holder = {}
            t_sim = timed(lambda: holder.setdefault("obs", simulate_preset(preset, seed=repeat)))
            obs = holder["obs"]
            t_row = timed(lambda: measure_run(obs, settings))
            series = measure_run(obs, settings).series
            labels, unwrapped, nn = groups(obs, settings.group_radius)
            pos, vel = np.ascontiguousarray(obs.pos), np.ascontiguousarray(obs.vel)
            out = np.empty((len(pos), 4))
            step = record_interval(obs)

            def new(pairwise: bool):
                new_series(pos, vel, 0.0, 6, pairwise, labels, unwrapped, nn, out)
                motion_metrics(vel, obs.times, step, settings.warmup, series["polarization"], series["milling"])
            t_new, t_off = timed(lambda: new(True)), timed(lambda: new(False))
            if repeat:
                for part, value in (("simulate", t_sim), ("row", t_row), ("new", t_new), ("new_off", t_off)):
                    times[interval, part].append(value)
    print(f"holland, {args.boids} boids, {args.duration:g} s, dt 1/60 s; medians of {args.repeats} interleaved "
          "repeats in ms (fastest in brackets) and shares of the simulation (median of the repeats' ratios; "
          "fastest / fastest in brackets)")
    print("| records every | simulate | row, every metric | share | new observables | share | new, pairwise off | share |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for interval in cases:
        cells = [f"{interval:g} s"]
        sim = np.array(times[interval, "simulate"])
        cells.append(f"{np.median(sim) * 1e3:.1f} ({sim.min() * 1e3:.1f})")
        for part in ("row", "new", "new_off"):
            values = np.array(times[interval, part])
            cells.append(f"{np.median(values) * 1e3:.2f} ({values.min() * 1e3:.2f})")
            cells.append(f"{np.median(values / sim):.1%} ({values.min() / sim.min():.1%})")
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
