"""Executing runs: one :class:`~sweeps.design.RunSpec` -> one table row and its metric time series.

``execute_run(spec, out_dir)`` never raises for a failing run: an exception or a non-finite state
becomes a row with ``status = "failed"`` and the reason in ``error``, and the sweep goes on. A failed
write (:class:`~sweeps.files.WriteFailed`: the trajectory file on a full or read-only disk) is not the
run's failure: it is raised, and the runner stops.
``execute_batch(specs, out_dir)`` runs several in a row (a worker's unit of work) and returns
``(rows, timeseries)`` with ``timeseries`` a DataFrame (run_id, t, one column per metric).

A row is the run's identity and swept parameters, then ``status``, ``error``, ``sim_s``, ``wall_s``,
then its summary (:func:`observables.summary.measure_run` of the records at the run's record
interval). A run of a command model (``spec.command``, :mod:`sweeps.external`) runs the command and
measures its output as tracks instead (``sim_s``: the command's seconds); its timeout, non-zero exit or
malformed output is the run's failure, recorded like any other. Trajectories (``keep = "trajectories"``) are written by the worker itself, atomically, to
``<out_dir>/trajectories/<run_id>.npz`` (:mod:`sweeps.trajectory`, every ``trajectory_every`` steps);
on a cluster ``out_dir`` must be on a shared file system.
``prepare()`` is a pool worker's set-up before its first task (:class:`~sweeps.executors.Executor`'s
``preload``): numba's typing and target contexts readied, which its first compiled call would otherwise
do (about 0.3 s, while the runner is still reading the sweep).
"""
from __future__ import annotations

import dataclasses
import math
import time
import traceback
from pathlib import Path

import pandas as pd

import numpy as np

from flocksweep.observables.observed import ObservedFlock
from flocksweep.observables.summary import check_finite, every_nth, measure_run
from flocksweep.simcore import placeholder_observations, simulate

from .design import RunSpec
from .external import run_external
from .files import WriteFailed
from .trajectory import write_trajectory


def prepare() -> None:
    """Ready numba's typing and target contexts (the registries every compiled call needs), as the first
    compiled call would; nothing is compiled or loaded."""
    from numba.core.registry import cpu_target

    cpu_target.typing_context.refresh()
    cpu_target.target_context.refresh()


def _simulate(spec: RunSpec):
    """Simulate; returns the observations, recorded every gcd(record_every, trajectory_every) steps
    when trajectories are kept, else every record_every steps."""
    run = spec.preset.run
    step = run.record_every
    if spec.storage.keep == "trajectories":
        step = math.gcd(step, spec.storage.trajectory_every)
    return simulate(spec.preset.model, spec.preset.init, spec.seed, run.duration, run.dt, step)


def _save_trajectory(spec: RunSpec, obs, out_dir: Path) -> None:
    """The run's trajectory file, every ``trajectory_every`` steps."""
    records = every_nth(obs, spec.storage.trajectory_every // obs.record_every)
    write_trajectory(Path(out_dir) / "trajectories" / f"{spec.run_id}.npz", records, spec.seed)


def base_row(spec: RunSpec) -> dict:
    """Identity and parameters first, then status columns; metrics are appended after them."""
    row = {"run_id": spec.run_id, "index": spec.index, "point_index": spec.point_index,
           "replicate": spec.replicate, "seed": spec.seed}
    row.update(dict(spec.columns))
    row.update(status="failed", error="", sim_s=float("nan"), wall_s=float("nan"))
    return row


def failed_rows(specs, reason: str) -> list[dict]:
    """Rows recording ``specs`` as failed for ``reason`` (e.g. their worker died)."""
    rows = []
    for spec in specs:
        row = base_row(spec)
        row["error"] = reason
        rows.append(row)
    return rows


def _simulated(spec: RunSpec, out_dir, start: float) -> tuple:
    """(record times, series, summary row, simulation seconds) of a run of a preset."""
    obs = _simulate(spec)
    sim_s = time.perf_counter() - start
    check_finite(obs)
    if spec.storage.keep == "trajectories" and out_dir is not None:
        _save_trajectory(spec, obs, out_dir)
    records = every_nth(obs, spec.preset.run.record_every // obs.record_every)
    series, summary = measure_run(records, spec.metrics)
    return records.times, series, summary, sim_s


def execute_run(spec: RunSpec, out_dir=None) -> tuple[dict, pd.DataFrame | None]:
    row, columns = _execute(spec, out_dir)
    return row, None if columns is None else pd.DataFrame(columns)


def _execute(spec: RunSpec, out_dir) -> tuple[dict, dict | None]:
    """The run's row and its series as columns (run_id, t, one per metric), None when it failed."""
    row = base_row(spec)
    start = time.perf_counter()
    try:
        if spec.command is None:
            times, series, summary, sim_s = _simulated(spec, out_dir, start)
        else:   # an external command: its output measured as tracks (sim_s: the command's seconds)
            times, series, summary, sim_s = run_external(spec.command, spec.seed, spec.metrics, spec.run_id)
        row.update(summary)
        row.update(status="ok", error="", sim_s=sim_s, wall_s=time.perf_counter() - start)
        return row, {"run_id": np.full(len(times), spec.run_id, dtype=object), "t": times, **series}
    except WriteFailed:
        raise   # the disk's fault, not the run's
    except Exception as err:  # a failing run is recorded, never fatal to the sweep
        detail = traceback.format_exception_only(type(err), err)[-1].strip()
        row.update(status="failed", error=detail, sim_s=float("nan"), wall_s=time.perf_counter() - start)
        return row, None


def warm_up(spec: RunSpec) -> None:
    """Compile (or load from numba's cache) every kernel a run needs, on a 3-boid, 2-step run (the file's
    boids when the run starts from ``init.from_file``: its count is fixed; for a command model: the metric
    kernels, on a 3-individual observed flock), so that workers find them in the cache instead of each
    compiling its own. :func:`warm_up_run` then :func:`warm_up_metrics`."""
    warm_up_metrics(spec, warm_up_run(spec))


def warm_up_run(spec: RunSpec):
    """The run loop of ``spec``'s runs, compiled or loaded, on a 3-boid, 2-step run; returns its
    observations (None for a command model: it has no run loop)."""
    if spec.command is not None:
        return None
    run = spec.preset.run
    return simulate(spec.preset.model, _warm_up_init(spec), 0, 2 * run.dt, run.dt, 1)


def warm_up_metrics(spec: RunSpec, obs=None) -> None:
    """The metric kernels of ``spec``'s runs, compiled or loaded, by measuring ``obs`` (from
    :func:`warm_up_run`) or, without it, the placeholder records of the same tiny run
    (:func:`simcore.placeholder_observations`: the same arrays and types, and nothing of the simulator
    compiles); for a command model, a 3-individual observed flock."""
    if spec.command is not None:
        measure_run(_tiny_flock(), spec.metrics)
        return
    if obs is None:
        run = spec.preset.run
        obs = placeholder_observations(spec.preset.model, _warm_up_init(spec), 0, 2 * run.dt, run.dt, 1)
    measure_run(obs, spec.metrics)


def _warm_up_init(spec: RunSpec):
    """A warm-up run's initial conditions: 3 boids (the file's, when it starts from ``init.from_file``)."""
    init = spec.preset.init
    return init if init.from_file is not None else dataclasses.replace(init, n=3)


def _tiny_flock() -> ObservedFlock:
    """Three individuals flying along x for three records, all seen."""
    times = np.arange(3) * 0.5
    pos = np.zeros((3, 3, 3))
    pos[:, :, 0] = times[:, None] + np.arange(3)[None, :]
    vel = np.zeros((3, 3, 3))
    vel[:, :, 0] = 2.0
    return ObservedFlock(name="warm-up", ids=np.arange(3), times=times, pos=pos, vel=vel,
                         present=np.ones((3, 3), dtype=bool), interval=0.5)


def execute_batch(specs: list[RunSpec], out_dir=None) -> tuple[list[dict], pd.DataFrame | None]:
    rows, parts = [], []
    for spec in specs:
        row, columns = _execute(spec, out_dir)
        rows.append(row)
        if columns is not None:
            parts.append(columns)
    return rows, _series_table(parts)


def _series_table(parts: list[dict]) -> pd.DataFrame | None:
    """The runs' series in one table, as ``pd.concat`` of one table per run would give (one table is
    built, not one per run: about 1.3 ms a run)."""
    if not parts:
        return None
    if any(part.keys() != parts[0].keys() for part in parts):
        return pd.concat([pd.DataFrame(part) for part in parts], ignore_index=True)
    return pd.DataFrame({key: np.concatenate([part[key] for part in parts]) for key in parts[0]})
