"""Write the SYNTHETIC example tracks ``vicsek_command.csv.gz`` and its sidecar ``vicsek_command.json``: the flock
of ``configs/calibration/external_vicsek.toml``, which calibrates the shipped external Vicsek-like command.

Not real animals: one run of ``configs/external/vicsek_sim.py`` (the external simulator of docs/sweeps.md, run
as a program) with 20 agents at a known heading noise of 0.4 and speed 2 body lengths/s for 15 s, seen by a
tracker: samples every 0.2 s from t = 5 s (the flock formed), each agent detected with probability 0.9,
Gaussian position noise of sd 0.1 body lengths, in body lengths and seconds, positions only.

Run from the repository root:  python configs/tracks/make_vicsek_tracks.py   (a pure function of the seeds: the
same file byte for byte)
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
SIMULATOR = HERE.parent / "external" / "vicsek_sim.py"
TRUTH = {"noise": 0.4, "speed": 2.0}
AGENTS, DURATION, FIRST = 20, 15.0, 5.0
INTERVAL, DETECTION, POSITION_SD = 0.2, 0.9, 0.1
SEED = 77


def flock(truth: dict = TRUTH, seed: int = SEED) -> pd.DataFrame:
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "tracks.csv"
        subprocess.run([sys.executable, str(SIMULATOR), "--seed", str(seed), "--out", str(out), "--n_agents",
                        str(AGENTS), "--duration", repr(DURATION), *(a for k, v in truth.items() for a in (f"--{k}",
                                                                                                          repr(v)))],
                       check=True)
        tracks = pd.read_csv(out)
    step = np.round(tracks["t"] / INTERVAL, 6)
    kept = tracks[(tracks["t"] >= FIRST - 1e-9) & (step == np.round(step))].reset_index(drop=True)
    rng = np.random.default_rng([seed, 3])
    kept = kept[rng.random(len(kept)) < DETECTION].reset_index(drop=True)
    noise = rng.normal(0.0, POSITION_SD, (len(kept), 3))
    return pd.DataFrame({"id": kept["id"], "t": np.round(kept["t"], 6),
                         **{a: np.round(kept[a] + noise[:, j], 4) for j, a in enumerate("xyz")}})


def write(folder=HERE, name: str = "vicsek_command") -> Path:
    folder = Path(folder)
    path = folder / f"{name}.csv.gz"
    flock().to_csv(path, index=False, compression={"method": "gzip", "mtime": 0})
    (folder / f"{name}.json").write_text(json.dumps({
        "description": "SYNTHETIC tracks: one run of configs/external/vicsek_sim.py (20 agents, noise 0.4, speed 2 BL/s) "
                       "sampled at 5 Hz from t = 5 s, detection probability 0.9, position noise sd 0.1 BL. Made by "
                       "configs/tracks/make_vicsek_tracks.py", "synthetic": True,
        "units": {"length": "bl", "time": "s"}, "truth": TRUTH}, indent=2) + "\n")
    return path


if __name__ == "__main__":
    print(f"wrote {write()}")
