"""Costs of measured flocks: measuring tracks, and the observation block's share of a calibration evaluation.

    python bench/bench_measured.py [--repeats 5]

* measure: ``measure_tracks`` (checks, resampling, metrics; no files, no figures) on the shipped synthetic
  tracks (8 flocks x 20 birds x 42 samples) and on one simulated flock of 200 boids x 301 records
  written as tracks (positions only, velocities by differencing), median of ``--repeats``;
* observation: one evaluation of ``tracks_holland.toml``'s simulator (16 runs of 20 boids, 12 s) with its
  ``[observation]`` block and without it (the runs recorded at the same 0.2 s), interleaved, median of
  ``--repeats`` x 3 calls each, and their ratio.
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.run import summary_simulator
from flocksweep.analysis.calibration.simulator import SummarySimulator
from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.tracks import TrackSource, load_tracks, track_source, tracks_frame
from flocksweep.simcore import load_preset, simulate_preset

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "configs/tracks/synthetic_holland.csv.gz"
CALIBRATION = ROOT / "configs/calibration/tracks_holland.toml"


def _median_time(fn, count: int) -> float:
    times = []
    for _ in range(count):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def measure(repeats: int) -> None:
    table = load_tracks(EXAMPLE, track_source(EXAMPLE, {}))
    settings = track_settings(20.0)
    measure_tracks(table, settings, 0.2, None, 0.4)          # load the kernels
    seconds = _median_time(lambda: measure_tracks(table, settings, 0.2, None, 0.4), repeats)
    records = 8 * 40
    print(f"synthetic example, 8 flocks x 20 birds: {seconds * 1000:.0f} ms ({seconds / records * 1e3:.2f} ms "
          "per record)")
    preset = load_preset(ROOT / "configs/models/holland.toml", ["init.n=200", "run.duration=30.0",
                                                                 "run.record_interval=0.1"])
    obs = simulate_preset(preset, 1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "big.parquet"
        tracks_frame(obs, "big").drop(columns=["vx", "vy", "vz"]).to_parquet(path, index=False)
        big = load_tracks(path, TrackSource(units={"length": "bl"}))
        seconds = _median_time(lambda: measure_tracks(big, settings, 0.1, None, 0.2), repeats)
        load = _median_time(lambda: load_tracks(path, TrackSource(units={"length": "bl"})), repeats)
    print(f"one flock of 200 boids x 301 samples: read {load * 1000:.0f} ms, measure {seconds * 1000:.0f} ms "
          f"({seconds / 300 * 1e3:.2f} ms per record)")


def observation(repeats: int) -> None:
    config = load_calibration(CALIBRATION)
    with_block = summary_simulator(config)
    data = dict(config.preset_data)
    data["run"] = {**data.get("run", {}), "record_interval": config.observation.interval}
    bare = SummarySimulator(data, config.keys, config.targets.columns, config.method.n_sim, config.warmup,
                            config.metrics.group_radius)
    theta = np.array([12.0, 8.0])
    seeds = list(range(config.method.n_sim))
    with_block.simulate(theta, seeds)
    bare.simulate(theta, seeds)
    observed, plain = [], []
    for _ in range(repeats):
        observed.append(_median_time(lambda: with_block.simulate(theta, seeds), 3))
        plain.append(_median_time(lambda: bare.simulate(theta, seeds), 3))
    a, b = statistics.median(observed), statistics.median(plain)
    print(f"evaluation ({config.method.n_sim} runs): with [observation] {a:.3f} s, without {b:.3f} s, "
          f"ratio {a / b:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    measure(args.repeats)
    observation(args.repeats)


if __name__ == "__main__":
    main()
