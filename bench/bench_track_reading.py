"""Reading and measuring measured tracks (the clock, padding, trim and burst-aware checks included).

    python bench/bench_track_reading.py [--repeats 7]

Two workloads, each ``load_tracks`` + ``measure_tracks`` without the directional correlations (their cost
does not depend on reading; with them the 60 fps file takes about a minute), steady state (one call to
warm up, then the median of ``--repeats``):

* ``60fps``: a long CSV of 40 individuals x 3,000 samples at 60 fps (120,000 rows, 3-D, recorded
  velocities), written by this script into a temporary folder;
* ``synthetic``: the shipped ``configs/tracks/synthetic_holland.csv.gz`` (8 flocks, jittered stamps, one
  glitch dropped), velocities differenced over 0.4 s.

To compare two versions, run it once per version in alternation (bench/RESULTS.md says how it was done).
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.tracks import TrackSource, load_tracks, track_source

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "configs/tracks/synthetic_holland.csv.gz"


def write_60fps(path: Path, n: int = 40, frames: int = 3000, fps: float = 60.0) -> Path:
    rng = np.random.default_rng(5)
    t = np.arange(frames) / fps
    heading = np.cumsum(rng.normal(0, 0.02, (n, frames)), axis=1)
    vel = np.stack([np.cos(heading), np.sin(heading), np.repeat(0.1 * np.sin(t)[None, :], n, 0)], -1) * 12.0
    pos = np.cumsum(vel, axis=1) / fps + rng.normal(0, 3, (n, 1, 3))
    pd.DataFrame({"id": np.repeat(np.arange(n), frames), "t": np.tile(t, n),
                  **{a: pos[..., k].reshape(-1) for k, a in enumerate("xyz")},
                  **{"v" + a: vel[..., k].reshape(-1) for k, a in enumerate("xyz")}}).to_csv(path, index=False)
    return path


def _median(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    settings = track_settings(20.0, dcd_max_delay=0.0)
    with tempfile.TemporaryDirectory() as folder:
        path = write_60fps(Path(folder) / "flock60.csv")

        def sixty():
            table = load_tracks(path, TrackSource())
            return measure_tracks(table, settings, velocity_interval="recorded")

        def synthetic():
            table = load_tracks(EXAMPLE, track_source(EXAMPLE, {}))
            return measure_tracks(table, settings, velocity_interval=0.4)

        records = int(sixty().runs["records"].iloc[0])
        print(f"60fps: {_median(sixty, args.repeats):.3f} s (records {records} of 3000)")
        print(f"synthetic: {_median(synthetic, args.repeats):.3f} s")


if __name__ == "__main__":
    main()
