"""Write the two start states of the Couzin et al. (2002) hysteresis sweep
(configs/sweeps/couzin2002_hysteresis.toml): ``couzin2002_torus.npz`` and ``couzin2002_parallel.npz``.

Each is the final state of one run of a shipped preset (100 boids, 150 s from a random start, seed 1):
``couzin2002_torus.toml`` (orientation zone width 1: a milling torus) and ``couzin2002_highly_parallel.toml``
(width 12: a polarised group), shifted so the flock's centroid is at the origin. Stored arrays: ``pos``,
``vel`` and ``up`` (docs/model.md section 0.7). The script prints the state's polarization and milling.

Run from the repository root:  python configs/states/make_couzin2002_states.py
The output is a pure function of the presets and the seed (same arrays bit for bit).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flocksweep.observables.summary import observation_metrics
from flocksweep.simcore import load_preset, simulate_preset

HERE = Path(__file__).resolve().parent
MODELS = HERE.parent / "models"
STATES = {"torus": "couzin2002_torus", "parallel": "couzin2002_highly_parallel"}
SEED = 1


def main() -> None:
    for state, preset_name in STATES.items():
        preset = load_preset(MODELS / f"{preset_name}.toml")
        obs = simulate_preset(preset, SEED)
        metrics = observation_metrics(obs, preset.model)
        final = obs.final
        np.savez(HERE / f"couzin2002_{state}.npz", pos=final.pos - final.pos.mean(axis=0), vel=final.vel,
                 up=final.up)
        print(f"{state}: polarization {metrics['polarization'][-1]:.3f}, milling {metrics['milling'][-1]:.3f}, "
              f"groups {int(metrics['n_groups'][-1])}")


if __name__ == "__main__":
    main()
