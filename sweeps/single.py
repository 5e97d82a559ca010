"""One simulation from a model preset, with its outputs: the engine of ``flocksweep simulate``.

``run_single(preset, seed, out_dir=None, record_every=None) -> (summary, written paths, observations)``
simulates and returns a summary dict (final polarization, mean speed, mean visible neighbours, binocular
share, wall time); when ``out_dir`` is given it writes there atomically:

* ``trajectory.npz``: times (R,), pos and vel (R, N, 3), visible and binocular (R, N), pattern (N,);
* ``params.json``: the resolved preset, seed, record interval, the summary and the provenance stamp.

The trace figure of ``--plot`` is drawn by the CLI (:mod:`analysis.reports.traces`).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from analysis.observables.metrics import mean_speed, polarization
from simcore import Observations, Preset, simulate_preset

from .files import atomic_path, write_json
from .provenance import stamp


def summarize(obs: Observations) -> dict:
    visible = obs.visible[-1]
    seen = visible.sum()
    return {
        "n": int(obs.n),
        "time_s": float(obs.times[-1]),
        "final_polarization": float(polarization(obs.vel[-1])),
        "final_mean_speed": float(mean_speed(obs.vel[-1])),
        "final_mean_visible": float(visible.mean()),
        "final_binocular_share": float(obs.binocular[-1].sum() / seen) if seen else 0.0,
    }


def save_trajectory(obs: Observations, path: Path) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, times=obs.times, pos=obs.pos, vel=obs.vel, visible=obs.visible,
                                binocular=obs.binocular, pattern=obs.pattern)


def run_single(preset: Preset, seed, out_dir=None, record_every: int | None = None
               ) -> tuple[dict, list[Path], Observations]:
    """Simulate and write the trajectory and parameters; returns (summary, written paths, observations)."""
    started = time.perf_counter()
    obs = simulate_preset(preset, seed, record_every)
    summary = summarize(obs)
    summary["wall_s"] = time.perf_counter() - started
    written = []
    if out_dir is not None:
        out_dir = Path(out_dir)
        save_trajectory(obs, out_dir / "trajectory.npz")
        write_json(out_dir / "params.json", {"preset": preset.to_dict(), "seed": seed,
                                             "record_every_steps": obs.record_every,
                                             "summary": summary, "provenance": stamp()})
        written += [out_dir / "trajectory.npz", out_dir / "params.json"]
    return summary, written, obs
