"""Executing runs: one :class:`~sweeps.design.RunSpec` -> one table row and its metric time series.

``execute_run(spec, out_dir)`` never raises for a failing run: an exception or a non-finite state
becomes a row with ``status = "failed"`` and the reason in ``error``, and the sweep goes on. A failed
write (:class:`~sweeps.files.WriteFailed`: the trajectory file on a full or read-only disk) is not the
run's failure: it is raised, and the runner stops. A failed row keeps its accounting: ``wall_s`` is the
time the run took until it failed, and ``sim_s`` the simulation's (or the command's) seconds when the
failure came after it (measuring, say), else NaN. A non-finite state names the step and the boid where
it began (:func:`sweeps.non_finite.where_non_finite`: the run is simulated again to the first record that shows it, at every
step, when it recorded more sparsely).

Contained runs (:func:`contained`): a run of a plug-in dynamics (a user's compiled code, which can write
outside an array or loop for ever) and every run with a wall-time limit (``spec.timeout_s``, the sweep's
``run.timeout_s``) run in a child process, this thread's :class:`~sweeps.sandbox.Sandbox` (one per worker
thread, reused from run to run; :func:`close_sandbox`), whatever the executor (serial, a local pool of any
size, dask): a crash of that process (SIGSEGV) is the run's failure ``TaskCrashed``, a run still going after
its limit is killed and failed ``TaskTimedOut``, and the worker goes on with a fresh child. The child first
loads the run's kernels with no step simulated and no limit (:func:`prepare_contained`), so the limit
counts the run itself. A command model's run gets ``run.timeout_s`` as its command's limit when it is the
shorter (:mod:`sweeps.external`). A built-in run without a limit runs in the worker itself, as before.
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
import threading
import time
import traceback
from pathlib import Path

import pandas as pd

import numpy as np

from flocksweep.observables.observed import ObservedFlock
from flocksweep.observables.summary import every_nth, measure_run
from flocksweep.simcore import placeholder_observations, simulate
from flocksweep.simcore.registry import is_builtin

from .design import RunSpec
from .external import run_external
from .files import WriteFailed
from .non_finite import check_finite_run
from .sandbox import Sandbox, TaskCrashed, TaskTimedOut
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


def is_plugin(spec: RunSpec) -> bool:
    """Whether the run's dynamics is a plug-in (a user's module, :mod:`simcore.plugin`)."""
    return spec.preset is not None and not is_builtin(spec.preset.model.dynamics)


def contained(spec: RunSpec) -> bool:
    """Whether the run runs in a child process (module docstring): a plug-in's, or one with a time limit."""
    return spec.preset is not None and (spec.timeout_s is not None or is_plugin(spec))


def _simulated(spec: RunSpec, out_dir, start: float, row: dict) -> tuple:
    """(record times, series, summary row) of a run of a preset; its simulation seconds go in ``row``."""
    obs = _simulate(spec)
    row["sim_s"] = time.perf_counter() - start
    check_finite_run(spec.preset, spec.seed, obs)
    if spec.storage.keep == "trajectories" and out_dir is not None:
        _save_trajectory(spec, obs, out_dir)
    records = every_nth(obs, spec.preset.run.record_every // obs.record_every)
    series, summary = measure_run(records, spec.metrics)
    return records.times, series, summary


def execute_run(spec: RunSpec, out_dir=None) -> tuple[dict, pd.DataFrame | None]:
    row, columns = _execute(spec, out_dir)
    return row, None if columns is None else pd.DataFrame(columns)


def _execute(spec: RunSpec, out_dir) -> tuple[dict, dict | None]:
    """The run's row and its series as columns (run_id, t, one per metric), None when it failed; a
    contained run in this thread's sandbox."""
    return _contained(spec, out_dir) if contained(spec) else execute_here(spec, out_dir)


def execute_here(spec: RunSpec, out_dir) -> tuple[dict, dict | None]:
    """:func:`_execute` in this process."""
    row = base_row(spec)
    start = time.perf_counter()
    try:
        if spec.command is None:
            times, series, summary = _simulated(spec, out_dir, start, row)
        else:   # an external command: its output measured as tracks (sim_s: the command's seconds)
            times, series, summary, row["sim_s"] = run_external(spec.command, spec.seed, spec.metrics, spec.run_id,
                                                                spec.timeout_s)
        row.update(summary)
        row.update(status="ok", error="", wall_s=time.perf_counter() - start)
        return row, {"run_id": np.full(len(times), spec.run_id, dtype=object), "t": times, **series}
    except WriteFailed:
        raise   # the disk's fault, not the run's
    except Exception as err:  # a failing run is recorded, never fatal to the sweep
        detail = traceback.format_exception_only(type(err), err)[-1].strip()
        row.update(status="failed", error=detail, wall_s=time.perf_counter() - start)
        return row, None


_SANDBOXES = threading.local()


def _sandbox() -> Sandbox:
    box = getattr(_SANDBOXES, "box", None)
    if box is None:
        box = _SANDBOXES.box = Sandbox()
    return box


def has_sandbox() -> bool:
    """Whether this thread has a sandbox process running (a caller that starts one closes it after)."""
    return getattr(_SANDBOXES, "box", None) is not None


def close_sandbox() -> None:
    """End this thread's sandbox process, if it has one (the runner, after an in-process sweep)."""
    box = getattr(_SANDBOXES, "box", None)
    _SANDBOXES.box = None
    if box is not None:
        box.close()


def prepare_contained(spec: RunSpec) -> None:
    """In the sandbox, before a contained run: its run loop and metric kernels loaded (or compiled), with
    no step of a plug-in's simulated, so nothing of its code runs untimed."""
    warm_up_metrics(spec, warm_up_run(spec))


def time_steps(spec: RunSpec, steps: int) -> float:
    """Seconds of ``steps`` steps of the run, simulated here."""
    run = spec.preset.run
    start = time.perf_counter()
    simulate(spec.preset.model, spec.preset.init, spec.seed, steps * run.dt, run.dt, steps)
    return time.perf_counter() - start


def time_contained(spec: RunSpec, steps: int) -> float:
    """Seconds of ``steps`` steps of a contained run, timed in its sandbox within its limit (a dry run's
    pilot); TaskCrashed or TaskTimedOut as :meth:`Sandbox.call` raises them."""
    box = _sandbox()
    box.call(prepare_contained, spec)
    return box.call(time_steps, spec, steps, timeout=spec.timeout_s)


def _contained(spec: RunSpec, out_dir) -> tuple[dict, dict | None]:
    """The run in this thread's sandbox, within ``spec.timeout_s``; a crash or an overrun is its failure."""
    start = time.perf_counter()
    box = _sandbox()
    try:
        box.call(prepare_contained, spec)
        start = time.perf_counter()
        return box.call(execute_here, spec, out_dir, timeout=spec.timeout_s)
    except WriteFailed:
        raise   # the disk's fault, not the run's
    except TaskTimedOut:
        error = TaskTimedOut(f"the run was still going after {spec.timeout_s:g} s (run.timeout_s): stopped, its "
                             "process killed; raise run.timeout_s and rerun with --retry-failed to give it longer")
    except TaskCrashed as err:
        where = ("in compiled code: for a plug-in, an index outside an array in its steer (docs/plugins.md)"
                 if is_plugin(spec) else "in compiled code, or out of memory")
        error = TaskCrashed(f"the run crashed: {err} {where}")
    except Exception as err:  # noqa: BLE001 - its kernels would not compile or load: the run's failure
        error = err
    row = base_row(spec)
    row.update(status="failed", error=traceback.format_exception_only(type(error), error)[-1].strip(),
               wall_s=time.perf_counter() - start)
    return row, None


def warm_up(spec: RunSpec) -> None:
    """Compile (or load from numba's cache) every kernel a run needs, on a 3-boid, 2-step run (the file's
    boids when the run starts from ``init.from_file``: its count is fixed; for a command model: the metric
    kernels, on a 3-individual observed flock), so that workers find them in the cache instead of each
    compiling its own. :func:`warm_up_run` then :func:`warm_up_metrics`."""
    warm_up_metrics(spec, warm_up_run(spec))


def warm_up_run(spec: RunSpec):
    """The run loop of ``spec``'s runs, compiled or loaded, on a 3-boid, 2-step run; returns its
    observations (None for a command model: it has no run loop; None for a plug-in, whose loop is
    compiled with no step simulated)."""
    if spec.command is not None:
        return None
    run = spec.preset.run
    if is_plugin(spec):   # compiled, with no step simulated: a plug-in's code runs only in a sandbox
        simulate(spec.preset.model, _warm_up_init(spec), 0, 0.25 * run.dt, run.dt, 1)
        return None
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
