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
``(rows, timeseries)`` with ``timeseries`` a DataFrame (run_id, t, one column per metric). Consecutive
runs of a batch that differ only in their seed (a design point's replicates: :func:`replicate_groups`;
built-in models only, in this process, under ``THREADED_MIN_N`` boids, at most ``GROUP_BYTES`` of records
together) are simulated by one :func:`simcore.simulate_batch` call on this thread (:func:`execute_group`),
each run bit-identical to its :func:`simcore.simulate`, then checked, stored and measured one by one as
a run alone is: a run that fails there is that run's failure, the others are kept; a group whose
simulation raises is executed again run by run. A grouped run's ``sim_s`` is its equal share of the
group's simulation seconds.

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

import contextlib
import dataclasses
import math
import threading
import time
import traceback
from pathlib import Path

import numba
import numpy as np
import pandas as pd

from flocksweep.observables.observed import ObservedFlock
from flocksweep.observables.summary import every_nth, measure_run
from flocksweep.simcore import placeholder_observations, simulate, simulate_batch
from flocksweep.simcore.registry import is_builtin
from flocksweep.simcore.simulate import THREADED_MIN_N

from .budget import run_bytes
from .design import RunSpec
from .external import run_external
from .files import WriteFailed
from .non_finite import check_finite_run
from .sandbox import Sandbox, TaskCrashed, TaskTimedOut
from .trajectory import write_trajectory

GROUP_BYTES = 64 * 2 ** 20   # a group of replicates simulated together holds at most this much (one run at least)


def prepare() -> None:
    """Ready numba's typing and target contexts (the registries every compiled call needs), as the first
    compiled call would; nothing is compiled or loaded."""
    from numba.core.registry import cpu_target

    cpu_target.typing_context.refresh()
    cpu_target.target_context.refresh()


def _record_step(spec: RunSpec) -> int:
    """Steps between the records a run is simulated with: gcd(record_every, trajectory_every) when
    trajectories are kept, else record_every."""
    step = spec.preset.run.record_every
    if spec.storage.keep == "trajectories":
        step = math.gcd(step, spec.storage.trajectory_every)
    return step


def _simulate(spec: RunSpec):
    """Simulate; returns the observations, recorded every :func:`_record_step` steps."""
    run = spec.preset.run
    return simulate(spec.preset.model, spec.preset.init, spec.seed, run.duration, run.dt, _record_step(spec))


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
    return _measured(spec, obs, out_dir)


def _measured(spec: RunSpec, obs, out_dir) -> tuple:
    """(record times, series, summary row) of a simulated run: its state checked finite, its trajectory
    saved (``keep = "trajectories"``), its records measured."""
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

    def work():
        if spec.command is None:
            return _simulated(spec, out_dir, start, row)
        # an external command: its output measured as tracks (sim_s: the command's seconds)
        times, series, summary, row["sim_s"] = run_external(spec.command, spec.seed, spec.metrics, spec.run_id,
                                                            spec.timeout_s)
        return times, series, summary

    return _recorded(spec, row, start, work)


def _recorded(spec: RunSpec, row: dict, start: float, work) -> tuple[dict, dict | None]:
    """The run's row (``row`` completed) and its series from ``work() -> (times, series, summary)``: ok,
    or failed with the reason when ``work`` raises (a failed write is raised: the disk's fault, not the
    run's); ``wall_s`` counted from ``start``."""
    try:
        times, series, summary = work()
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
    """The rows and series of ``specs``, in their order: the replicates of a design point that follow each
    other (:func:`replicate_groups`) simulated together (:func:`execute_group`), any other run alone."""
    rows, parts = [], []
    for group in replicate_groups(specs):
        for row, columns in (execute_group(group, out_dir) if len(group) > 1 else [_execute(group[0], out_dir)]):
            rows.append(row)
            if columns is not None:
                parts.append(columns)
    return rows, _series_table(parts)


def groupable(spec: RunSpec) -> bool:
    """Whether a run may be simulated in a group: a built-in model's run in this process (not a command's,
    nor a contained run: a plug-in's or one with a time limit), small enough to run on one thread (from
    :data:`simcore.simulate.THREADED_MIN_N` boids a run splits its steps over threads)."""
    return spec.command is None and not contained(spec) and spec.preset.init.n < THREADED_MIN_N


def _group_bytes(spec: RunSpec) -> float:
    """Memory of one run of a group while the group is simulated (:func:`sweeps.budget.run_bytes`)."""
    return run_bytes(spec.preset.init.n, spec.preset.run.n_steps, _record_step(spec))


def replicate_groups(specs: list[RunSpec]) -> list[list[RunSpec]]:
    """``specs`` cut into runs of consecutive specs that differ only in their seed (the same preset, metric
    and storage settings: the replicates of one design point), in order, each group holding at most
    :data:`GROUP_BYTES` of runs' memory (one run at least); a run that cannot be grouped
    (:func:`groupable`) is a group of its own."""
    groups: list[list[RunSpec]] = []
    for spec in specs:
        last = groups[-1][-1] if groups else None
        if (last is not None and groupable(spec) and groupable(last)
                and (spec.preset is last.preset or spec.preset == last.preset)
                and spec.metrics == last.metrics and spec.storage == last.storage
                and (len(groups[-1]) + 1) * _group_bytes(spec) <= GROUP_BYTES):
            groups[-1].append(spec)
        else:
            groups.append([spec])
    return groups


def execute_group(specs: list[RunSpec], out_dir=None) -> list[tuple[dict, dict | None]]:
    """Rows and series of runs that differ only in their seed (:func:`replicate_groups`), simulated by one
    :func:`simcore.simulate_batch` call on this thread (the model packed and its run loop looked up once,
    not per run; each run bit-identical to its :func:`simcore.simulate`), then each checked, stored and
    measured as :func:`execute_here` does it. ``sim_s`` of each is the group's simulation seconds shared
    equally. When the simulation raises, every run is executed alone, so that a failure is the failing
    run's own."""
    first = specs[0]
    run = first.preset.run
    start = time.perf_counter()
    try:
        with _one_thread():
            simulated = simulate_batch(first.preset.model, first.preset.init, [s.seed for s in specs],
                                       run.duration, run.dt, _record_step(first))
    except Exception:  # noqa: BLE001 - each run again alone: its failure recorded as its own
        return [execute_here(spec, out_dir) for spec in specs]
    share = (time.perf_counter() - start) / len(specs)
    out = []
    for spec, obs in zip(specs, simulated):
        row = base_row(spec)
        row["sim_s"] = share
        out.append(_recorded(spec, row, time.perf_counter() - share,
                             lambda spec=spec, obs=obs: _measured(spec, obs, out_dir)))
    return out


@contextlib.contextmanager
def _one_thread():
    """numba's thread count of this thread set to 1 while inside (restored after): a group's runs one after
    the other, as the runs alone would be (a worker process of a pool uses the cores its share gives it)."""
    threads = numba.get_num_threads()
    if threads != 1:
        numba.set_num_threads(1)
    try:
        yield
    finally:
        if threads != 1:
            numba.set_num_threads(threads)


def _series_table(parts: list[dict]) -> pd.DataFrame | None:
    """The runs' series in one table, as ``pd.concat`` of one table per run would give (one table is
    built, not one per run: about 1.3 ms a run)."""
    if not parts:
        return None
    if any(part.keys() != parts[0].keys() for part in parts):
        return pd.concat([pd.DataFrame(part) for part in parts], ignore_index=True)
    return pd.DataFrame({key: np.concatenate([part[key] for part in parts]) for key in parts[0]})
