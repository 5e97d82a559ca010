"""Running a sweep: plan -> (dry run | execute and store) -> consolidated table and manifest.

``run_sweep(config, sweep_text, out_dir, ...)`` counts the design's runs and checks their memory
(:mod:`sweeps.budget`: a design over ``MAX_RUNS`` runs needs ``yes``), expands and validates it (nothing
is written before that succeeds), takes the store's lock, repairs the folder (temporary files of a
killed writer removed, damaged parts quarantined: :meth:`ResultsStore.repair`), skips finished runs
(resume; ``force`` recomputes all, ``retry_failed`` reruns failed ones), computes the rest in batches
on the chosen executor with a progress bar, writes finished runs in parts and consolidates
``runs.parquet`` at the end.

Failures, each kept apart (docs/errors.md):

* a run that raises or ends in a non-finite state is a row with ``status = "failed"`` and the reason;
* a run whose worker process died (:class:`~sweeps.executors.WorkerLost` after the executor's retries)
  is not recorded: it stays missing, listed in ``SweepResult.lost``, and a rerun computes it;
* a write that fails (disk full, read-only, permission) stops the sweep at once with
  :class:`~sweeps.files.WriteFailed` naming the file; the parts written before it are kept;
* an interrupt (SIGINT, SIGTERM as ``KeyboardInterrupt``) saves the finished runs, stops the workers and
  releases the folder before it propagates.

Finished runs are saved on time: at most :data:`FLUSH_SECONDS` after they finish (plus a heartbeat),
whatever the executor is busy with, and all of them at the end or on an interrupt.
``status(out_dir)`` and ``resume_hint`` live in :mod:`sweeps.status` (light: no simulator).
``run_until(config, ..., grow, max_replicates)`` adds replicates in rounds where a rule asks for them:
``run_until_ci`` (``--until-ci``) with :func:`ci_rule`, ``--until-claims`` with the rule of
:mod:`analysis.reports.claims.until`.
"""
from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from flocksweep.simcore import simulate
from flocksweep.simcore.schema import ConfigError

from . import worker
from .budget import check_sweep
from .claims import with_claims
from .confidence import ci_halfwidth
from .config import SweepConfig, describe
from .design import RunSpec, StoredRun, base_preset, expand, stored_runs
from .design_key import KEY as DESIGN_KEY, design_key, reusable_design
from .executors import Executor, WorkerLost, check_scheduler
from .files import WriteFailed
from . import main_guard
from .identity import canonical
from .plugin_check import check_specs
from .provenance import stamp
from .sandbox import TaskCrashed, TaskTimedOut
from .status import resume_hint, status  # noqa: F401 - their home; imported from here too
from .store import ResultsStore
from .sweep_toml import portable, relocated, relocated_workdir
from .warmup import warm_up_all

FLUSH_SECONDS = 5.0   # finished runs wait at most this long (plus HEARTBEAT) before they are written
HEARTBEAT = 0.5       # seconds between the executor's heartbeats while nothing finishes
PART_RUNS = 20_000    # a part holds at most this many runs ...
PART_SERIES_ROWS = 400_000   # ... and time series rows (its memory: about 200 bytes a row)
BATCHES_PER_WORKER = 32      # a batch holds about 1 / (workers x this) of the sweep's cost
MAX_BATCH_RUNS = 4096        # and at most this many runs
MAX_BATCH_COST = 5e8         # and at most this cost (steps x N^2): 4,096 runs of 20 boids for 5 s, seconds of work
MAX_COMMAND_BATCH = 16       # or this many runs of a command (their cost is unknown)


@dataclass
class Plan:
    """The runs of a sweep (``specs``) in three lists: ``done`` (ok), ``failed`` (kept) and ``todo``. A rerun
    that reused the stored design and found nothing to compute lists :class:`~sweeps.design.StoredRun` s
    (identity and position only) instead of :class:`~sweeps.design.RunSpec` s."""
    specs: list[RunSpec | StoredRun]
    done: list[RunSpec | StoredRun] = field(default_factory=list)
    failed: list[RunSpec | StoredRun] = field(default_factory=list)
    todo: list[RunSpec] = field(default_factory=list)


def design_table(specs: list[RunSpec]) -> pd.DataFrame:
    """One row per run; ``n`` and ``steps`` for runs of a preset (a command's are its own business)."""
    return pd.DataFrame([{"run_id": s.run_id, "index": s.index, "point_index": s.point_index,
                          "replicate": s.replicate, "seed": s.seed,
                          **({"n": s.preset.init.n, "steps": s.preset.run.n_steps} if s.preset else {}),
                          **dict(s.columns)} for s in specs])


def model_record(config: SweepConfig, folder=None) -> dict:
    """What is needed to rebuild any run of the design from its row: the base preset (its path relative to
    the results ``folder``; absolute without one), the swept keys. For a command model: the command
    (:meth:`~sweeps.external.CommandModel.record`, its folder relative to ``folder``) instead of a preset."""
    if config.command is not None:
        workdir = portable(config.command.workdir, folder) if folder is not None else None
        return {"command": config.command.record(workdir), "swept_keys": config.swept_keys,
                "analysis": config.analysis_record()}
    path = portable(config.preset_path, folder) if folder is not None else str(config.preset_path)
    return {"preset": config.preset_data, "preset_path": path,
            "swept_keys": config.swept_keys,
            "analysis": config.analysis_record()}


def make_plan(specs: list[RunSpec], store: ResultsStore, force: bool, retry_failed: bool) -> Plan:
    status = store.statuses()
    plan = Plan(specs=specs)
    for spec in specs:
        state = status.get(spec.run_id)
        if state == "ok" and not force:
            plan.done.append(spec)
        elif state == "failed" and not (force or retry_failed):
            plan.failed.append(spec)
        else:
            plan.todo.append(spec)
    return plan


def stored_plan(design: pd.DataFrame, store: ResultsStore, retry_failed: bool) -> Plan | None:
    """The plan of a rerun on the stored ``design`` (:mod:`sweeps.design_key`), its runs known by their
    rows (:class:`~sweeps.design.StoredRun`), when it has nothing to compute (every run ok, or failed and
    kept); None when it has: then the design is built and planned as always."""
    status = store.statuses()
    states = design["run_id"].map(status)
    if states.isna().any() or (retry_failed and (states == "failed").any()):
        return None
    plan = Plan(specs=stored_runs(design))
    for run, state in zip(plan.specs, states.tolist()):
        (plan.done if state == "ok" else plan.failed).append(run)
    return plan


def make_batches(todo: list[RunSpec], workers: int, batch_size: int | None = None) -> list[list[RunSpec]]:
    """Batches of similar cost, most expensive first (longest-processing-time scheduling): ``batch_size``
    runs each when given, else runs in cost order until a batch holds a share 1 / (``workers`` x
    :data:`BATCHES_PER_WORKER`) of the whole cost (at most :data:`MAX_BATCH_RUNS` runs; at most
    :data:`MAX_COMMAND_BATCH` runs of a command, whose cost is unknown). Many small runs then travel
    together (a task's overhead is paid once for them, and a design point's replicates, next to each other
    in this order, are simulated together: :func:`sweeps.worker.execute_batch`), a dear run goes alone,
    and the pool ends on batches small enough to keep every worker busy until the end."""
    if not todo:
        return []
    ordered = sorted(todo, key=lambda s: (-s.cost, s.index))
    if batch_size:
        return [ordered[k:k + batch_size] for k in range(0, len(ordered), batch_size)]
    share = min(MAX_BATCH_COST, sum(s.cost for s in ordered) / (max(workers, 1) * BATCHES_PER_WORKER))
    batches: list[list[RunSpec]] = []
    cost = 0.0
    for spec in ordered:
        limit = MAX_COMMAND_BATCH if spec.command is not None else MAX_BATCH_RUNS
        if not batches or cost + spec.cost > share * (1 + 1e-9) or len(batches[-1]) >= limit:
            batches.append([])
            cost = 0.0
        batches[-1].append(spec)
        cost += spec.cost
    return batches


def estimate(todo: list[RunSpec], workers: int, pilot_seconds: float = 1.0, pool: bool = False) -> dict:
    """What the user will wait for, measured here rather than assumed (docs/sweeps.md, "Dry runs"):

    * ``seconds``: simulation, from short pilots of the cheapest, median and dearest runs to do (one step
      first: a pilot whose one step already takes ``pilot_seconds / 4`` is timed on that step alone), per
      unit of cost (n^2 x steps), over ``workers``;
    * ``compile_s``: the run loops this dry run had to compile first (0 when numba's cache had them: the
      real run then loads them; when it had to, the cache now holds them);
    * ``startup_s``: this process's own start (imports, reading the sweep, loading the kernels), and with
      a ``pool`` the time
      its worker processes take to start and load the kernels (timed: the pool is started here, each
      worker warms up, and it is stopped);
    * ``per_run_s``: what a run costs besides its simulation (metrics, its row, the write), timed on the
      cheapest run, once warm;
    * ``total_s``: start-up + (simulation + per-run overhead x runs) / workers, without the compile.
    """
    from flocksweep.simcore.simulate import compile_seconds

    startup = _process_age()
    if any(s.command is not None for s in todo):   # a dry run executes nothing: a command's time is unknown
        return {"boid_steps": 0, "seconds": math.nan, "compile_s": 0.0, "startup_s": startup,
                "per_run_s": math.nan, "total_s": math.nan, "command": True}
    boid_steps = sum(s.preset.init.n * s.preset.run.n_steps for s in todo)
    if not todo:
        return {"boid_steps": 0, "seconds": 0.0, "compile_s": 0.0, "startup_s": startup, "per_run_s": 0.0,
                "total_s": startup}
    compiling, warming = compile_seconds(), time.perf_counter()
    for spec in _one_per_run_loop(todo):
        worker.warm_up(spec)   # compile (or load) what the runs need, as the real run's warm-up does
    compile_s = compile_seconds() - compiling
    startup += time.perf_counter() - warming - compile_s   # the run's own warm-up: loading the kernels
    ordered = sorted(todo, key=lambda s: s.cost)
    pilots = {id(s): s for s in (ordered[0], ordered[len(ordered) // 2], ordered[-1])}.values()
    rate = []  # seconds per unit of cost
    try:
        for spec in pilots:
            run = spec.preset.run
            steps, elapsed = 1, _pilot(spec, 1)
            if elapsed < pilot_seconds / 4:
                steps = max(1, min(run.n_steps, int(round(pilot_seconds / run.dt))))
                elapsed = _pilot(spec, steps)
            rate.append(elapsed / (steps * float(spec.preset.init.n) ** 2))
    except (TaskCrashed, TaskTimedOut) as err:   # a contained run's pilot (a plug-in's, or one with a limit)
        return {"boid_steps": boid_steps, "seconds": math.nan, "compile_s": compile_s, "startup_s": startup,
                "per_run_s": math.nan, "total_s": math.nan, "pilot_failed": f"{type(err).__name__}: {err}"}
    per_cost = sorted(rate)[len(rate) // 2]
    seconds = sum(s.cost for s in todo) * per_cost / max(workers, 1)
    per_run = _per_run_overhead(ordered[0], per_cost, pilot_seconds)
    startup_total = startup + (_pool_start(ordered[0], workers) if pool else 0.0)
    total = startup_total + seconds + per_run * len(todo) / max(workers, 1)
    return {"boid_steps": boid_steps, "seconds": seconds, "compile_s": compile_s, "startup_s": startup_total,
            "per_run_s": per_run, "total_s": total}


def _per_run_overhead(spec: RunSpec, per_cost: float, pilot_seconds: float) -> float:
    """Seconds a run costs besides its simulation: the cheapest run done whole (when its simulation is
    short) minus its simulation alone, best of three each, warm; 0 when it is too long to time here
    (its extrapolated simulation, and then its simulation timed once, longer than ``pilot_seconds``: the
    extrapolation alone overstates a tiny run on a busy machine)."""
    if spec.cost * per_cost > 20 * pilot_seconds:
        return 0.0
    alone = [_pilot(spec, spec.preset.run.n_steps)]
    if alone[0] > pilot_seconds:
        return 0.0
    worker.execute_run(spec)   # warm: the metric kernels loaded or compiled
    whole = []
    for _ in range(3):
        start = time.perf_counter()
        worker.execute_run(spec)
        whole.append(time.perf_counter() - start)
        alone.append(_pilot(spec, spec.preset.run.n_steps))
    return max(0.0, min(whole) - min(alone))


def _pool_start(spec: RunSpec, workers: int) -> float:
    """Seconds to start ``workers`` worker processes and have each load the kernels of ``spec``."""
    start = time.perf_counter()
    with Executor("local", workers) as pool:
        pool.map(worker.warm_up, [spec] * workers)
    return time.perf_counter() - start


def _process_age() -> float:
    """Seconds since this process started (its imports and reading the sweep), from /proc; else 0."""
    try:
        ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return max(0.0, uptime - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return 0.0


def _pilot(spec: RunSpec, steps: int) -> float:
    """Seconds of ``steps`` steps of the run (a contained run's in its sandbox, within its limit:
    TaskCrashed or TaskTimedOut)."""
    if worker.contained(spec):
        return worker.time_contained(spec, steps)
    return worker.time_steps(spec, steps)


def _progress(total: int, name: str, enabled: bool):
    return tqdm(total=total, desc=name, unit="run", disable=not enabled, file=sys.stderr,
                mininterval=0.5, dynamic_ncols=True)


def _manifest(config: SweepConfig, store: ResultsStore, plan: Plan, executor: str, workers: int,
              started: float, finished: float | None, table: pd.DataFrame | None, key: str | None = None) -> dict:
    counts = {"runs": len(plan.specs)}
    if table is not None:
        counts.update(ok=int((table["status"] == "ok").sum()), failed=int((table["status"] == "failed").sum()))
        counts["missing"] = counts["runs"] - counts["ok"] - counts["failed"]
    provenance = stamp()
    this = {"started": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(started)),
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(finished)) if finished else None,
            "started_unix": started, "computed": len(plan.todo), "executor": executor, "workers": workers,
            "git_revision": provenance["git_revision"], "model_version": provenance["model_version"]}
    # every invocation that computed runs stays on record, so a resumed or extended sweep keeps the
    # provenance of the runs it did not recompute; the top level describes the latest invocation
    history = [h for h in store.manifest().get("invocations", [])
               if h.get("computed") and h.get("started_unix") != started]
    if this["computed"]:
        history.append(this)
    return {"sweep": config.name, "description": config.description,
            "config_hash": stamp_hash(config), "seed": config.seed, "replicates": config.replicates,
            "common_random_numbers": config.common_random_numbers, "design": describe(config),
            "executor": executor, "workers": workers, "computed_this_invocation": len(plan.todo),
            "started": this["started"], "finished": this["finished"], "invocations": history,
            "counts": counts, **provenance, **({DESIGN_KEY: key} if key else {})}


def stamp_hash(config: SweepConfig) -> str:
    return hashlib.sha256(canonical(config.source).encode()).hexdigest()[:16]


class PartWriter:
    """Buffers finished batches and writes them as one part when ``max_runs`` rows or
    ``max_series_rows`` time series rows have accumulated or the oldest has waited ``max_seconds``
    (checked when a batch arrives and on every ``tick``), and on exit, also after an error or an
    interrupt, but not after a failed write (nothing more can be saved then): few files (a sweep of
    small runs writes one part every ``max_seconds``, whatever its runs), bounded memory, finished work
    saved on time."""

    def __init__(self, store: ResultsStore, max_runs: int = PART_RUNS, max_seconds: float | None = None,
                 max_series_rows: int = PART_SERIES_ROWS):
        self.store, self.max_runs, self.max_series_rows = store, max_runs, max_series_rows
        self.max_seconds = FLUSH_SECONDS if max_seconds is None else max_seconds
        self.rows: list[dict] = []
        self.frames: list[pd.DataFrame] = []
        self.series_rows = 0
        self.since = time.monotonic()

    def add(self, rows: list[dict], timeseries: pd.DataFrame | None) -> None:
        if not self.rows:
            self.since = time.monotonic()
        self.rows += rows
        if timeseries is not None:
            self.frames.append(timeseries)
            self.series_rows += len(timeseries)
        if len(self.rows) >= self.max_runs or self.series_rows >= self.max_series_rows:
            self.flush()
        else:
            self.tick()

    def tick(self, expected_wait: float = 0.0) -> None:
        """Flush when the buffered rows have waited, or would wait after ``expected_wait`` more
        seconds, ``max_seconds``."""
        if self.rows and time.monotonic() - self.since + expected_wait >= self.max_seconds:
            self.flush()

    def flush(self) -> None:
        if self.rows:
            ts = pd.concat(self.frames, ignore_index=True) if self.frames else None
            self.store.write_part(self.store.next_part(), self.rows, ts)
        self.rows, self.frames, self.series_rows, self.since = [], [], 0, time.monotonic()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None or not issubclass(exc_type, WriteFailed):
            self.flush()
        return False


@dataclass
class SweepResult:
    out_dir: Path
    plan: Plan
    table: pd.DataFrame | None
    wall_s: float
    estimate: dict | None = None
    lost: list[RunSpec] = field(default_factory=list)   # runs whose worker died: left missing
    lost_reasons: list[str] = field(default_factory=list)   # why (distinct messages), when runs were lost
    quarantined: list[Path] = field(default_factory=list)  # damaged files moved aside before computing


def run_sweep(config: SweepConfig, sweep_text: str | None, out_dir, executor: str = "local",
              workers: int | None = None, scheduler: str | None = None, force: bool = False, retry_failed: bool = False,
              dry_run: bool = False, progress: bool = True, batch_size: int | None = None,
              specs: list[RunSpec] | None = None, yes: bool = False, pool: Executor | None = None) -> SweepResult:
    """Run the sweep (or the given subset ``specs`` of its design); see the module docstring. ``sweep_text``
    is stored as ``sweep.toml``; None stores the text of the file the sweep was read from, or for a sweep
    built in Python :meth:`SweepConfig.to_toml`. ``pool``: an entered ``local`` :class:`Executor` of
    ``workers`` processes to compute on, started by the caller (the command line starts it first thing,
    so its workers import while the sweep is read and designed); the caller closes it. The public entry
    point is :func:`sweeps.run_sweep`."""
    main_guard.refuse_in_spawned_import()   # a worker re-running an unguarded script never runs its sweep
    if sweep_text is None:
        sweep_text = config.text if config.text is not None else config.to_toml()
    started = time.time()
    workers = cluster_workers(config) if executor == "cluster" else workers or os.cpu_count() or 1
    if not dry_run and ((executor == "local" and workers > 1) or (executor == "dask" and not scheduler)):
        main_guard.check_caller_guarded()   # before anything is written: UnguardedScript
    store = ResultsStore(out_dir)
    key, stored = None, None
    if specs is None:
        base_preset(config)   # the base model must be valid: ConfigError naming the key
        check_sweep(config, 1 if executor == "serial" else workers, yes)   # counts and sizes, builds nothing
        key = design_key(config)
        # this sweep's design, stored already (its key says so): read instead of built when the rerun has
        # nothing to compute, which is decided under the lock (where the design is read again); a design
        # with that key was validated when it was built, so building it there cannot fail on the config
        stored = reusable_design(ResultsStore(out_dir), key) if not force else None
        if stored is None:
            specs = expand(config)  # validates every run before anything is written
    if specs is not None:
        check_specs(specs)   # a plug-in's steer compiled alone: one message naming its line (sweeps.plugin_check)
    if executor == "dask" and scheduler and not dry_run:
        check_scheduler(scheduler)   # before anything is written
    if dry_run:
        plan = stored_plan(stored, store, retry_failed) if stored is not None else None
        if plan is None:
            plan = make_plan(specs if specs is not None else expand(config), store, force, retry_failed)
        return SweepResult(Path(out_dir), plan, None, time.time() - started,
                           estimate(plan.todo, 1 if executor == "serial" else workers,
                                    pool=executor != "serial" and workers > 1))
    with store.lock():
        quarantined = store.repair()
        stored = reusable_design(store, key) if stored is not None else None
        plan = stored_plan(stored, store, retry_failed) if stored is not None else None
        if plan is None:   # runs to compute: every run resolved and validated (the stored design is not enough)
            specs = specs if specs is not None else expand(config)
            plan, stored = make_plan(specs, store, force, retry_failed), None
        effective = with_claims({**config.source, "replicates": config.replicates}, config.claims)
        design = design_table(specs) if stored is None else stored
        stored_text = (relocated(sweep_text, config.preset_path, out_dir) if config.command is None
                       else relocated_workdir(sweep_text, config.command.workdir, out_dir))
        store.write_inputs(stored_text, effective, model_record(config, out_dir), None if stored is not None else design)
        store.write_manifest(_manifest(config, store, plan, executor, workers, started, None, None, key))
        lost, reasons = (_compute(config, store, plan, executor, workers, scheduler, progress, batch_size, pool)
                         if plan.todo else ([], []))
        table = store.consolidate(design)
        store.write_manifest(_manifest(config, store, plan, executor, workers, started, time.time(), table, key))
    return SweepResult(Path(out_dir), plan, table, time.time() - started, lost=lost, lost_reasons=reasons,
                       quarantined=quarantined)


def cluster_workers(config: SweepConfig) -> int:
    """The worker processes of the sweep's ``[cluster]`` (:mod:`sweeps.cluster`); ConfigError when it has
    none, before anything is read or written."""
    if config.cluster is None:
        raise ConfigError("--executor", "got 'cluster', but the sweep declares no [cluster] table: add one "
                                        "(kind = \"slurm\", jobs, cores, memory, walltime, ...; docs/sweeps.md, "
                                        "\"On a cluster\") or give it with --set cluster.kind=slurm "
                                        "--set cluster.jobs=4 ...")
    return config.cluster.workers


def _one_per_run_loop(specs: list[RunSpec]) -> list[RunSpec]:
    """The first run of each (dynamics, perception kind): simcore compiles a run loop for each."""
    first = {}
    for spec in specs:
        if spec.preset is None:   # a command model: the metric kernels only
            first.setdefault(("command",), spec)
            continue
        model = spec.preset.model
        first.setdefault((model.dynamics, model.perception.kind), spec)
    return list(first.values())


def _compute(config: SweepConfig, store: ResultsStore, plan: Plan, executor: str, workers: int,
             scheduler: str | None, progress: bool, batch_size: int | None,
             started: Executor | None = None) -> tuple[list[RunSpec], list[str]]:
    """Compute the plan's runs in batches on the executor (or the ``started`` pool), writing parts on
    time; returns the runs lost with their workers (not recorded) and the distinct reasons."""
    if started is not None and (executor, workers) != (started.kind, started.workers):
        raise ValueError(f"pool: a {started.description} pool, for a sweep on executor {executor!r} with "
                         f"{workers} worker(s)")
    with (_borrowed(started) if started is not None   # the caller's, already importing
          else Executor(executor, workers, scheduler, preload=(f"{worker.__name__}:prepare",),   # workers start importing
                        cluster=config.cluster if executor == "cluster" else None)) as pool:
        warm_up_all(_one_per_run_loop(plan.todo))   # sweeps/warmup.py: metric kernels alongside a first compile
        try:
            return _run_batches(config, store, make_batches(plan.todo, workers, batch_size), pool, progress)
        finally:
            if pool.in_process:   # the contained runs' child process (sweeps.worker), if any ran here
                worker.close_sandbox()


@contextlib.contextmanager
def _borrowed(pool: Executor):
    """The caller's pool for the sweep's batches: left running when they end, but stopped at once on an
    error or an interrupt, as the sweep's own pool would be (no worker writes after the store's lock)."""
    try:
        yield pool
    except BaseException:
        pool.close(wait=False)
        raise


def _run_batches(config: SweepConfig, store: ResultsStore, batches: list[list[RunSpec]], pool: Executor,
                 progress: bool) -> tuple[list[RunSpec], list[str]]:
    task = functools.partial(worker.execute_batch, out_dir=store.root)
    failures, lost, reasons = 0, [], []
    last_batch_s, clock = 0.0, time.monotonic()
    with _progress(sum(map(len, batches)), config.name, progress) as bar, PartWriter(store) as writer:
        for outcome in pool.as_completed(task, batches, idle=HEARTBEAT):
            if outcome is None:   # nothing finished yet: save what waits (serial: before the next batch)
                writer.tick(last_batch_s if pool.in_process else 0.0)
                continue
            last_batch_s, clock = time.monotonic() - clock, time.monotonic()
            if isinstance(outcome.error, (WriteFailed, WorkerLost)):
                if isinstance(outcome.error, WriteFailed):
                    raise outcome.error   # a worker could not write (trajectories): stop, keep what is saved
                lost += outcome.item
                reasons += [outcome.reason] if outcome.reason not in reasons else []
                bar.update(len(outcome.item))
                continue
            rows, ts = outcome.value if outcome.error is None else (worker.failed_rows(outcome.item, outcome.reason),
                                                                     None)
            writer.add(rows, ts)
            failures += sum(r["status"] != "ok" for r in rows)
            bar.set_postfix(failed=failures, lost=len(lost), refresh=False)
            bar.update(len(rows))
    return lost, reasons


def halfwidths(table: pd.DataFrame, metric: str, confidence: float = 0.95) -> pd.DataFrame:
    """Per design point: replicates with a value, and the Student-t CI half-width of the metric's mean
    (:func:`sweeps.confidence.ci_halfwidth`: +inf for fewer than two replicates)."""
    ok = table[(table["status"] == "ok")].dropna(subset=[metric])
    grouped = ok.groupby("point_index")[metric]
    out = pd.DataFrame({"n": grouped.count(), "sd": grouped.std(ddof=1)})
    out["halfwidth"] = ci_halfwidth(out["n"], out["sd"], confidence)
    return out


def run_until(config: SweepConfig, sweep_text: str, out_dir, grow, max_replicates: int, log=print,
              **run_options) -> SweepResult:
    """Add replicates in rounds to the design points a rule asks for, reusing the store (existing
    replicates are found as done), until the rule asks for nothing or every point it asks for has
    ``max_replicates``. ``grow(table, have) -> (wanted, message)``: ``table`` the runs so far, ``have``
    {point index: replicates}, ``wanted`` {point index: replicates it should have}; each round gives a
    point min(max_replicates, max(have + 1, wanted)). ``message`` goes into the round's log line."""
    counts: dict[int, int] = {}
    result = None
    check_sweep(dataclasses.replace(config, replicates=max(max_replicates, config.replicates)),
                1 if run_options.get("executor") == "serial" else (run_options.get("workers") or os.cpu_count() or 1),
                run_options.pop("yes", False))
    for round_number in range(1, 100):
        want = max(counts.values(), default=config.replicates)
        full = expand(dataclasses.replace(config, replicates=max(want, config.replicates)))
        chosen = [s for s in full if s.replicate < counts.get(s.point_index, config.replicates)]
        result = run_sweep(config, sweep_text, out_dir, specs=chosen, **run_options)
        have = {point: counts.get(point, config.replicates) for point in sorted({s.point_index for s in full})}
        wanted, message = grow(result.table, have)
        more = {point: min(max_replicates, max(have[point] + 1, int(n))) for point, n in wanted.items()
                if have.get(point, max_replicates) < max_replicates}
        capped = sum(1 for point in wanted if have.get(point, max_replicates) >= max_replicates)
        log(f"  round {round_number}: {len(chosen)} runs; {message}; {len(more)} points get more replicates, "
            f"{capped} at the cap")
        if not more:
            break
        counts.update(have)
        counts.update(more)
    return result


def ci_rule(metric: str, target: float):
    """The :func:`run_until` rule of ``--until-ci``: a point whose CI half-width of ``metric`` exceeds
    ``target`` wants n (h / target)^2 replicates (n its replicates with a value, h its half-width)."""
    def grow(table: pd.DataFrame, have: dict) -> tuple[dict, str]:
        if metric not in table:
            raise ValueError(f"--until-ci: metric {metric!r} is not a column of the results")
        widths = halfwidths(table, metric)
        wanted = {}
        for point in have:
            width = widths["halfwidth"].get(point, np.inf)
            if width > target:
                n = int(widths["n"].get(point, 0))
                wanted[point] = math.ceil(n * (width / target) ** 2) if np.isfinite(width) else have[point] + 1
        worst = float(widths["halfwidth"].replace(np.inf, np.nan).max())
        return wanted, f"largest {metric} CI half-width {worst:.4g} (target {target:g})"
    return grow


def run_until_ci(config: SweepConfig, sweep_text: str, out_dir, metric: str, target: float,
                 max_replicates: int, log=print, **run_options) -> SweepResult:
    """Add replicates only to the design points whose CI half-width of ``metric`` exceeds ``target``
    (:func:`run_until` with :func:`ci_rule`), until every point meets it or has ``max_replicates``."""
    return run_until(config, sweep_text, out_dir, ci_rule(metric, target), max_replicates, log, **run_options)
