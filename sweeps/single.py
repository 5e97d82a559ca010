"""One simulation from a model preset, with its outputs: the engine of ``flocksweep simulate``.

``run_single(preset, seed, out_dir=None, record_every=None) -> (summary, written paths, observations)``
simulates and returns a summary dict (final polarization, mean speed, mean visible neighbours, binocular
share, wall time; boids that collided and the least clearance, predator captures and nearest approach,
the time the flock's centre reached the prey, when the run has obstacles, a predator, prey); when
``out_dir`` is given it writes there atomically:

* ``trajectory.npz``: times (R,), pos and vel (R, N, 3), visible and binocular (R, N), pattern (N,), and
  for a Boids++ run with a predator or prey their positions ``predator``, ``prey`` (R, 3) (NaN while
  absent);
* ``params.json``: the resolved preset, seed, record interval, the summary and the provenance stamp;
* with ``tracks = "csv"`` or ``"parquet"``: ``tracks.csv`` / ``tracks.parquet``, the records as long-format
  tracks (:func:`observables.tracks.tracks_frame`: flock, id, t, x, y, z, vx, vy, vz, pattern, in
  body lengths and seconds), and the sidecar ``tracks.json`` saying so, for ``flocksweep measure``.

The trace figure of ``--plot`` is drawn by the CLI (:mod:`analysis.reports.traces`).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from observables.encounters import (CAPTURE_RADIUS, PREDATOR_NEAR, PREY_REACH, obstacle_metrics,
                                             predator_metrics, prey_metrics)
from observables.metrics import mean_speed, polarization
from observables.tracks import TRACKS_SIDECAR, tracks_frame
from simcore import Observations, Preset, simulate_preset

from .files import atomic_path, write_csv, write_json, write_parquet
from .provenance import stamp


def summarize(obs: Observations, obstacles=(), body_radius: float = 0.5) -> dict:
    """The printed summary; with obstacles (and the boids' body radius), a predator or prey in the run,
    also their metrics over the whole run (docs/metrics.md, default settings, no warm-up)."""
    visible = obs.visible[-1]
    seen = visible.sum()
    out = {
        "n": int(obs.n),
        "time_s": float(obs.times[-1]),
        "final_polarization": float(polarization(obs.vel[-1])),
        "final_mean_speed": float(mean_speed(obs.vel[-1])),
        "final_mean_visible": float(visible.mean()),
        "final_binocular_share": float(obs.binocular[-1].sum() / seen) if seen else 0.0,
    }
    if obstacles:
        scalars = obstacle_metrics(obs.pos, obs.times, obstacles, body_radius, 0.0)[1]
        out.update(collided_boids=int(scalars["collided_boids"]), clearance_min=scalars["clearance_min"])
    if obs.predator is not None:
        ones = np.ones(len(obs.times))   # groups and spacing are not summarised here
        scalars = predator_metrics(obs.pos, obs.predator, obs.times, ones, ones, CAPTURE_RADIUS, PREDATOR_NEAR, 0.0)[1]
        out.update(predator_captures=int(scalars["predator_captures"]),
                   predator_distance_min=scalars["predator_distance_min"])
    if obs.prey is not None:
        out["prey_reach_time"] = prey_metrics(obs.pos, obs.prey, obs.times, PREY_REACH)[1]["prey_reach_time"]
    return out


def agent_arrays(obs: Observations, pick=slice(None)) -> dict:
    """The recorded agents of a run (``predator``, ``prey``: (R, 3) positions), those it has."""
    return {name: getattr(obs, name)[pick] for name in ("predator", "prey") if getattr(obs, name, None) is not None}


def save_trajectory(obs: Observations, path: Path) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, times=obs.times, pos=obs.pos, vel=obs.vel, visible=obs.visible,
                                binocular=obs.binocular, pattern=obs.pattern, **agent_arrays(obs))


def save_tracks(obs: Observations, out_dir: Path, fmt: str, flock: str, description: str) -> list[Path]:
    """``tracks.<fmt>`` and its sidecar ``tracks.json`` (units: body lengths, seconds)."""
    frame = tracks_frame(obs, flock)
    path = out_dir / f"tracks.{fmt}"
    if fmt == "csv":
        write_csv(path, frame, index=False)
    else:
        write_parquet(path, frame)
    write_json(out_dir / "tracks.json", {**TRACKS_SIDECAR, "description": description})
    return [path, out_dir / "tracks.json"]


def run_single(preset: Preset, seed, out_dir=None, record_every: int | None = None, tracks: str | None = None
               ) -> tuple[dict, list[Path], Observations]:
    """Simulate and write the trajectory and parameters; returns (summary, written paths, observations)."""
    from simcore.simulate import compile_seconds

    started, compiling = time.perf_counter(), compile_seconds()
    obs = simulate_preset(preset, seed, record_every)
    summary = summarize(obs, preset.model.world.obstacles, preset.model.perception.body_radius)
    summary["compile_s"] = compile_seconds() - compiling   # run loops compiled for this run (0 when cached)
    summary["wall_s"] = time.perf_counter() - started - summary["compile_s"]
    written = []
    if out_dir is not None:
        out_dir = Path(out_dir)
        save_trajectory(obs, out_dir / "trajectory.npz")
        write_json(out_dir / "params.json", {"preset": preset.to_dict(), "seed": seed,
                                             "record_every_steps": obs.record_every,
                                             "summary": summary, "provenance": stamp()})
        written += [out_dir / "trajectory.npz", out_dir / "params.json"]
        if tracks:
            flock = f"{preset.model.name}-seed{seed}"
            written += save_tracks(obs, out_dir, tracks, flock, f"simulated: {preset.model.name}, seed {seed}, "
                                   f"{obs.n} boids, records every {obs.dt * obs.record_every:g} s")
    return summary, written, obs
