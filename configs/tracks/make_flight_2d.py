"""Write the SYNTHETIC example tracks ``flight_2d.csv.gz`` and its sidecar ``flight_2d.json``: four flights of one
flock filmed from above, the file of docs/measured.md's worked example (from a tracks file to a verdict).

Not real birds: four simulated flights of the Holland & Semwal model (configs/models/holland.toml, 20 boids
started in a ball of radius 8 body lengths, maximum speed 7 body lengths/s, separation weight 10: the truth a
calibration should recover; its range of vision stays the preset's 20), seen the way a camera above the flock
sees it:

* the simulator's horizontal plane (x, z) only: 2-D tracks (a 2-D projection of a 3-D flock);
* sampled every 0.1 s (10 Hz) from t = 5 s (the flock formed) to 25 s;
* each bird detected at a sample with probability 0.9 (missed detections are absent rows);
* Gaussian position noise of sd 0.1 body lengths on both coordinates;
* lengths in metres for a body length of 0.25 m, rounded to the millimetre; times to the millisecond on the
  camera's clock (starting at 120 s);
* columns as a tracker writes them (flight, track_id, time, x_m, y_m) and an extra channel the reader ignores
  (``confidence``); the sidecar maps the columns and gives the units and the body length.

Run from the repository root:  python configs/tracks/make_flight_2d.py  (or ``write(folder, ...)`` from Python:
the end-to-end test and bench/bench_tracks_to_verdict.py write their own copies). The output is a pure function
of the arguments (the same files byte for byte).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
TRUTH = {"vehicle.max_speed": 7.0, "steering.separation_weight": 10.0}
BOIDS = 20
START_RADIUS = 8.0
BODY_LENGTH_M = 0.25
INTERVAL = 0.1
FIRST, LAST = 5.0, 25.0
DETECTION = 0.9
POSITION_SD_BL = 0.1
SEED = 2027
FLIGHTS = 4


def flight(truth: dict = TRUTH, boids: int = BOIDS, first: float = FIRST, last: float = LAST, seed: int = SEED,
           name: str = "F1") -> pd.DataFrame:
    """The tracks of one flight (module docstring) as a table."""
    from flocksweep.simcore import load_preset, simulate

    preset = load_preset(ROOT / "configs" / "models" / "holland.toml",
                         [f"init.n={boids}", f"init.radius={START_RADIUS}", *(f"{k}={v}" for k, v in truth.items())])
    every = int(round(INTERVAL / preset.run.dt))
    obs = simulate(preset.model, preset.init, seed, last + INTERVAL / 2, preset.run.dt, every)
    keep = obs.times >= first - 1e-9
    times, pos = obs.times[keep], obs.pos[keep][:, :, [0, 2]]          # seen from above: x and z
    rng = np.random.default_rng([seed, 2])
    detected = rng.random(pos.shape[:2]) < DETECTION
    seen = (pos + rng.normal(0.0, POSITION_SD_BL, pos.shape)) * BODY_LENGTH_M
    record, bird = np.nonzero(detected)
    return pd.DataFrame({"flight": name, "track_id": [f"b{b:02d}" for b in bird],
                         "time": np.round(times[record] + 115.0, 3),
                         "x_m": np.round(seen[record, bird, 0], 3), "y_m": np.round(seen[record, bird, 1], 3),
                         "confidence": np.round(rng.uniform(0.6, 1.0, len(record)), 2)})


def flights(truth: dict = TRUTH, count: int = FLIGHTS, **options) -> pd.DataFrame:
    """``count`` flights (seeds SEED, SEED + 1, ...), one table."""
    return pd.concat([flight(truth, seed=SEED + k, name=f"F{k + 1}", **options) for k in range(count)],
                     ignore_index=True)


def sidecar(truth: dict = TRUTH) -> dict:
    return {"description": "SYNTHETIC tracks, not real birds: four simulated flights of the holland model (20 boids from a ball of radius 8, "
                           f"maximum speed {truth['vehicle.max_speed']:g} BL/s, separation weight "
                           f"{truth['steering.separation_weight']:g}) filmed from above at 10 Hz: 2-D, detection "
                           "probability 0.9, position noise sd 0.1 body lengths, body length 0.25 m. Made by "
                           "configs/tracks/make_flight_2d.py",
            "synthetic": True, "columns": {"flock": "flight", "id": "track_id", "t": "time", "x": "x_m", "y": "y_m"},
            "units": {"length": "m", "time": "s"}, "body_length": BODY_LENGTH_M, "truth": truth}


def write(folder, name: str = "flight_2d", **options) -> Path:
    """``<folder>/<name>.csv.gz`` and its sidecar ``<name>.json``; the track file's path (``options``: those of
    :func:`flights`, e.g. ``count`` flights, ``last`` second)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.csv.gz"
    flights(**options).to_csv(path, index=False, compression={"method": "gzip", "mtime": 0})
    (folder / f"{name}.json").write_text(json.dumps(sidecar(options.get("truth", TRUTH)), indent=2) + "\n")
    return path


if __name__ == "__main__":
    print(f"wrote {write(HERE)}")
