"""What a learned summary costs in npe's training (issue 40 point 2): the flow alone on recover_holland's four
statistics against the flow trained jointly with the embedding of the same runs' raw inputs, on the same
training rows, interleaved.

    python bench/bench_learned_summary.py [--out results/bench_learned] [--simulations 2000] [--repeats 3]

The training rows of configs/calibration/recover_holland_learned.toml (statistics and raw inputs of every
run) are simulated into ``OUT/training`` once (found there again on a rerun). Each repeat trains one flow
(``train_flow`` on the statistics) and one flow with its embedding (``train_learned`` on statistics and raw
inputs), with the file's flow settings and the same seed, alternating which goes first. Prints the median
wall time of each, their ratio, the epochs each ran (early stopping) and the time per epoch.
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.learned_inputs import layout, max_individuals
from flocksweep.analysis.calibration.learned_summary import train_learned
from flocksweep.analysis.calibration.npe import _keys, npe_simulator, training_design, transformed
from flocksweep.analysis.calibration.npe_flow import train_flow
from flocksweep.analysis.calibration.training_runs import design_rows
from flocksweep.sweeps.executors import Executor

FILE = Path(__file__).resolve().parents[1] / "configs/calibration/recover_holland_learned.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/bench_learned")
    parser.add_argument("--simulations", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    config = load_calibration(FILE)
    theta = training_design(config)
    with Executor("local", 2) as pool:
        rows = design_rows(npe_simulator(config), theta, _keys(config, len(theta)), Path(args.out) / "training",
                           pool).rows
    n = args.simulations
    keep = np.isfinite(rows[:n]).all(axis=1)
    theta, x = theta[:n][keep], transformed(config, rows[:n][keep])
    k = len(config.targets.columns)
    summary = config.method.summary
    plan = layout(summary, max_individuals(config))
    settings = config.method.flow
    jobs = {"flow alone": lambda: train_flow(theta, x[:, :k], settings, seed=7),
            "flow + learned summary": lambda: train_learned(theta, x, settings, summary, plan, seed=7)}
    times = {name: [] for name in jobs}
    epochs = {}
    for repeat in range(args.repeats):
        for name in (list(jobs) if repeat % 2 == 0 else list(jobs)[::-1]):
            started = time.perf_counter()
            estimator = jobs[name]()
            times[name].append(time.perf_counter() - started)
            epochs[name] = len(estimator.losses["train"])
            print(f"repeat {repeat + 1}: {name}: {times[name][-1]:.1f} s, {epochs[name]} epochs", flush=True)
    print(f"\n{len(theta)} training rows, {x.shape[1] - k} raw inputs each; medians of {args.repeats} interleaved "
          "repeats (the first of each includes its compile)\n")
    print("| training | median wall (s) | epochs | s per epoch |")
    print("|---|---:|---:|---:|")
    for name in jobs:
        median = statistics.median(times[name])
        print(f"| {name} | {median:.1f} | {epochs[name]} | {median / epochs[name]:.2f} |")
    ratio = statistics.median(times["flow + learned summary"]) / statistics.median(times["flow alone"])
    print(f"\nratio (learned / alone): {ratio:.2f}")


if __name__ == "__main__":
    main()
