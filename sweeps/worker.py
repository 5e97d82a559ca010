"""Executing runs: one :class:`~sweeps.design.RunSpec` -> one table row and its metric time series.

``execute_run(spec, out_dir)`` never raises for a failing run: an exception or a non-finite state
becomes a row with ``status = "failed"`` and the reason in ``error``, and the sweep goes on.
``execute_batch(specs, out_dir)`` runs several in a row (a worker's unit of work) and returns
``(rows, timeseries)`` with ``timeseries`` a DataFrame (run_id, t, one column per metric).

Trajectories (``keep = "trajectories"``) are written by the worker itself, atomically, to
``<out_dir>/trajectories/<run_id>.npz``; on a cluster ``out_dir`` must be on a shared file system.
"""
from __future__ import annotations

import math
import time
import traceback
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.leadership import leadership_metrics
from analysis.metrics import frame_metrics, summarize, world_box
from simcore import simulate

from .atomic import atomic_path
from .design import RunSpec


class NonFiniteState(RuntimeError):
    pass


def _simulate(spec: RunSpec):
    """Simulate; returns (metric-step observations, trajectory observations or None)."""
    run = spec.preset.run
    every = run.record_every
    keep = spec.analysis.keep == "trajectories"
    step = math.gcd(every, spec.analysis.trajectory_every) if keep else every
    obs = simulate(spec.preset.model, spec.preset.init, spec.seed, run.duration, run.dt, step)
    return obs, every // step


def _check_finite(obs) -> None:
    bad = ~(np.isfinite(obs.pos).all(axis=(1, 2)) & np.isfinite(obs.vel).all(axis=(1, 2)))
    if bad.any():
        raise NonFiniteState(f"non-finite position or velocity at t = {obs.times[np.argmax(bad)]:g} s")


def _save_trajectory(spec: RunSpec, obs, out_dir: Path) -> None:
    """Positions and velocities every ``trajectory_every`` steps (the observations are recorded every
    gcd(record_every, trajectory_every) steps)."""
    pick = slice(None, None, spec.analysis.trajectory_every // obs.record_every)
    path = Path(out_dir) / "trajectories" / f"{spec.run_id}.npz"
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, times=obs.times[pick], pos=obs.pos[pick], vel=obs.vel[pick],
                                pattern=obs.pattern, seed=spec.seed)


def _base_row(spec: RunSpec) -> dict:
    """Identity and parameters first, then status columns; metrics are appended after them."""
    row = {"run_id": spec.run_id, "index": spec.index, "point_index": spec.point_index,
           "replicate": spec.replicate, "seed": spec.seed}
    row.update(dict(spec.columns))
    row.update(status="failed", error="", sim_s=float("nan"), wall_s=float("nan"))
    return row


def execute_run(spec: RunSpec, out_dir=None) -> tuple[dict, pd.DataFrame | None]:
    row = _base_row(spec)
    start = time.perf_counter()
    try:
        obs, stride = _simulate(spec)
        sim_s = time.perf_counter() - start
        _check_finite(obs)
        if spec.analysis.keep == "trajectories" and out_dir is not None:
            _save_trajectory(spec, obs, out_dir)
        pick = slice(None, None, stride)
        series = frame_metrics(obs.pos[pick], obs.vel[pick], obs.visible[pick], obs.binocular[pick],
                               obs.pattern, spec.group_radius, world_box(spec.preset.model))
        times = obs.times[pick]
        row.update(summarize(series, times, spec.analysis.warmup, spec.analysis.fragmentation_cohesion))
        if spec.analysis.leadership:
            model = spec.preset.model
            row.update(leadership_metrics(obs, spec.group_radius, model.leadership.duration, world_box(model)))
            series["leaders"] = obs.leader[pick].sum(axis=1).astype(np.float64)
        row.update(status="ok", error="", sim_s=sim_s, wall_s=time.perf_counter() - start)
        ts = pd.DataFrame({"run_id": spec.run_id, "t": times, **series})
        return row, ts
    except Exception as err:  # a failing run is recorded, never fatal to the sweep
        detail = traceback.format_exception_only(type(err), err)[-1].strip()
        row.update(status="failed", error=detail, sim_s=float("nan"), wall_s=time.perf_counter() - start)
        return row, None


def warm_up(spec: RunSpec) -> None:
    """Compile (or load from numba's cache) every kernel a run needs, on a 3-boid, 2-step run, so that
    forked workers inherit them instead of each compiling its own."""
    from dataclasses import replace

    run = spec.preset.run
    obs = simulate(spec.preset.model, replace(spec.preset.init, n=3), 0, 2 * run.dt, run.dt, 1)
    frame_metrics(obs.pos, obs.vel, obs.visible, obs.binocular, obs.pattern, spec.group_radius,
                  world_box(spec.preset.model))
    if spec.analysis.leadership:
        leadership_metrics(obs, spec.group_radius, spec.preset.model.leadership.duration,
                           world_box(spec.preset.model))


def execute_batch(specs: list[RunSpec], out_dir=None) -> tuple[list[dict], pd.DataFrame | None]:
    rows, frames = [], []
    for spec in specs:
        row, ts = execute_run(spec, out_dir)
        rows.append(row)
        if ts is not None:
            frames.append(ts)
    return rows, (pd.concat(frames, ignore_index=True) if frames else None)
