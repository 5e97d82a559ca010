"""Write the SYNTHETIC example tracks ``synthetic_holland.csv.gz`` and its sidecar ``synthetic_holland.json``.

Not real birds: eight simulated flocks of the Holland & Semwal model (configs/models/holland.toml, 20
boids, separation weight 12, maximum speed 7 body lengths/s: the truth a calibration should recover),
seen the way a stereo-camera or GPS tracker sees real ones:

* sampled every 0.2 s (5 Hz) from t = 3.8 s to 12 s of each run, each sample taken at the nominal time
  plus a jitter of -1, 0 or +1 simulation steps (1/60 s) and stamped with its true time (irregular but
  correct time stamps, as a tracker's clock gives);
* each bird detected at a sample with probability 0.95 (missed detections are absent rows);
* Gaussian position noise of sd 0.15 body lengths on every coordinate;
* lengths in metres for a body length of 0.3 m (a jackdaw-sized bird), rounded to the millimetre, times
  to the millisecond, on a clock starting at 10:00 (36000 s) plus one minute per flock;
* one tracking glitch: bird 7 of flock F3 jumps 25 m along x at one sample (the speed check flags it;
  the sidecar says to drop it);
* columns named as a tracker might (event, bird, time_s, x_m, y_m, z_m): the sidecar maps them.

Run from the repository root:  python configs/tracks/make_synthetic_holland.py
The output is a pure function of the seeds below (same files byte for byte).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.simcore import load_preset, simulate

HERE = Path(__file__).resolve().parent
TRUTH = {"steering.separation_weight": 12.0, "vehicle.max_speed": 7.0}
FLOCKS = 8
BODY_LENGTH_M = 0.3
INTERVAL = 0.2
FIRST, LAST = 3.8, 12.0
DETECTION = 0.95
POSITION_SD_BL = 0.15
GLITCH = ("F3", 7, 20, 25.0)        # flock, bird, sample, jump along x in metres


def flock_rows(k: int, preset) -> pd.DataFrame:
    run = preset.run
    obs = simulate(preset.model, preset.init, 1000 + k, 12.5, run.dt, 1)   # every step; 12.5 s covers the jitter
    rng = np.random.default_rng([2026, k])
    nominal = np.round((FIRST + INTERVAL * np.arange(round((LAST - FIRST) / INTERVAL) + 1)) / run.dt).astype(int)
    n = obs.n
    steps = nominal[:, None] + rng.integers(-1, 2, size=(len(nominal), n))       # (samples, birds)
    detected = rng.random(steps.shape) < DETECTION
    noise = rng.normal(0.0, POSITION_SD_BL, steps.shape + (3,))
    birds = np.broadcast_to(np.arange(n), steps.shape)
    pos_m = (obs.pos[steps, birds] + noise) * BODY_LENGTH_M
    t = obs.times[steps] + 36000.0 + 60.0 * k
    name = f"F{k + 1}"
    frame = pd.DataFrame({"event": name, "bird": birds[detected], "time_s": np.round(t[detected], 3),
                          **{f"{a}_m": np.round(pos_m[..., j][detected], 3) for j, a in enumerate("xyz")}})
    if name == GLITCH[0]:
        bird_rows = frame.index[frame["bird"] == GLITCH[1]]          # that bird's rows, in time order
        frame.loc[bird_rows[GLITCH[2]], "x_m"] = round(frame.loc[bird_rows[GLITCH[2]], "x_m"] + GLITCH[3], 3)
    return frame


def main() -> None:
    preset = load_preset(HERE.parent / "models" / "holland.toml",
                         ["init.n=20", "init.radius=8.0"] + [f"{k}={v}" for k, v in TRUTH.items()])
    frame = pd.concat([flock_rows(k, preset) for k in range(FLOCKS)], ignore_index=True)
    out = HERE / "synthetic_holland.csv.gz"
    frame.to_csv(out, index=False, compression={"method": "gzip", "mtime": 0})
    sidecar = {
        "description": ("SYNTHETIC tracks, not real birds: 8 simulated flocks of the holland model (20 boids, "
                        "separation weight 12, maximum speed 7 BL/s), sampled at 5 Hz with +-1/60 s jitter, "
                        "detection probability 0.95, position noise sd 0.15 body lengths (4.5 cm), body length "
                        "0.3 m; one glitch (flock F3, bird 7). Made by configs/tracks/make_synthetic_holland.py"),
        "synthetic": True,
        "columns": {"flock": "event", "id": "bird", "t": "time_s", "x": "x_m", "y": "y_m", "z": "z_m"},
        "units": {"length": "m", "time": "s"},
        "body_length": BODY_LENGTH_M,
        "bad_speeds": "drop",
        "truth": TRUTH,
    }
    (HERE / "synthetic_holland.json").write_text(json.dumps(sidecar, indent=2) + "\n")
    print(f"wrote {out} ({out.stat().st_size / 1024:.0f} KiB, {len(frame)} rows) and synthetic_holland.json")


if __name__ == "__main__":
    main()
