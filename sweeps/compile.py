"""Compile the simulation and metric kernels ahead of use: ``flocksweep compile [MODEL.toml ...] [--jobs K]``.

numba compiles a kernel the first time a process needs it and keeps it in its on-disk cache, so later
processes load it. Several processes that start together on a fresh checkout (a sweep's workers, a test
run split over workers, jobs of a cluster sharing one file system) each compile what they need before
any of them has cached it: the same minute of work, once per process. :func:`compile_kernels` does it
once, up front.

Contract. The models (default: every preset of the shipped ``configs/models``) are grouped by what they
compile: their dynamics and perception kind (a run loop is compiled per perception kind, see
:mod:`simcore.jit`; the update order, boundary and every other setting are run-time values). Each group
is one task, run in a spawned process, ``jobs`` at a time, the largest (binocular vision) first; groups
share no run loop, so no two processes compile the same one (small per-boid pieces shared by several
kinds may be compiled twice). A task runs, for each of its models, tiny simulations (5 boids, 2 steps)
serially, as a batch of two runs and, in synchronous order, on two threads, and sends the runs back; the
calling process measures their metrics, with and without the leadership metrics, as each task ends (the
metric kernels are shared by every model, so they compile once, there). Together: every compiled path a
sweep, a calibration or the test suite takes for those models. While the tasks compile, the calling
process measures placeholder records of the same tiny runs (:func:`simcore.placeholder_observations`,
the arrays and types of a run without simulating), so the metric kernels compile alongside the run
loops rather than after the first of them; the real runs' metrics then load them (and compile what
the placeholders did not reach). Each step counts the kernels numba
compiled (rather than loaded from the cache). Results do not depend on it: a kernel compiled here is the
one a run would have compiled itself. The command's arguments and entry are in
:mod:`sweeps.compile_command` (which loads this module only when it runs).
"""
from __future__ import annotations

import concurrent.futures
import contextlib
import io
import dataclasses
import multiprocessing
import time
from pathlib import Path

from numba.core import event as numba_event

from flocksweep.observables.summary import MetricSettings, measure_run
from flocksweep.simcore import load_preset, placeholder_observations, simulate, simulate_batch
from flocksweep.simcore.registry import describe

SHIPPED_MODELS = Path(__file__).resolve().parent.parent / "configs" / "models"
TINY_N = 5
GROUP_RADIUS = 10.0  # any radius compiles the same metric kernels (topological models have no default)
# the order groups start in (heaviest compile first); kinds not listed follow, by name
KIND_ORDER = ("binocular", "topological", "opensteer", "sphere")


@dataclasses.dataclass(frozen=True)
class GroupResult:
    """What one task compiled: its group key, models, kernels compiled (not loaded) and seconds."""

    key: tuple[str, str]
    models: tuple[str, ...]
    compiled: int
    seconds: float


def shipped_models() -> list[Path]:
    """The presets of the shipped ``configs/models`` (an editable install or a checkout)."""
    if not SHIPPED_MODELS.is_dir():
        raise FileNotFoundError(f"no shipped model presets at {SHIPPED_MODELS}: name the MODEL.toml files "
                                f"to compile for")
    return sorted(SHIPPED_MODELS.glob("*.toml"))


def group_models(paths) -> list[tuple[tuple[str, str], list[str]]]:
    """The models by (dynamics, perception kind), heaviest group first (``KIND_ORDER``); loads and
    validates each preset, so a bad one is reported before anything compiles."""
    groups: dict[tuple[str, str], list[str]] = {}
    for path in paths:
        model = load_preset(path).model
        groups.setdefault((model.dynamics, model.perception.kind), []).append(str(path))

    def weight(key):
        kind = key[1]
        return (KIND_ORDER.index(kind) if kind in KIND_ORDER else len(KIND_ORDER), key)

    return sorted(groups.items(), key=lambda item: weight(item[0]))


def compile_group(key: tuple[str, str], paths: list[str], quiet: bool = False):
    """Simulate these models along every compiled path (see the module docstring), in its own process;
    returns its :class:`GroupResult` and the tiny runs (model, observations), for their metrics.
    ``quiet``: no compile notice on stderr (the calling process shows its own ticker)."""
    counter = CompileCounter()
    start = time.perf_counter()
    runs = []
    silenced = contextlib.redirect_stderr(io.StringIO()) if quiet else contextlib.nullcontext()
    with silenced, numba_event.install_listener("numba:compile", counter):
        for path in paths:
            runs += _simulations(path)
    result = GroupResult(key, tuple(Path(p).stem for p in paths), counter.count, time.perf_counter() - start)
    return result, runs


def compile_kernels(paths=None, jobs: int = 2, report=print, ticker=None) -> list[GroupResult]:
    """Compile (or find in the cache) every kernel the models need, ``jobs`` groups at a time, and the metric
    kernels in this process as the groups' runs come back; ``report`` is called with one line per finished
    group and one for the metrics. ``ticker`` (a :class:`flocksweep.ticker.Ticker`, not yet started) shows
    the time so far meanwhile, with how many groups are done. Returns the groups' results in the order
    they started, then the metrics' (key ``("metrics", "all")``)."""
    if isinstance(jobs, bool) or int(jobs) != jobs or jobs < 1:
        raise ValueError(f"jobs: got {jobs!r}; must be an integer >= 1")
    groups = group_models(shipped_models() if paths is None else paths)
    if not groups:
        return []
    context = multiprocessing.get_context("spawn")
    compiled_metrics, metric_seconds, results = 0, 0.0, {}
    ticking = ticker if ticker is not None else contextlib.nullcontext()
    if ticker is not None:
        ticker.status = f"0 of {len(groups)} model families done"
    with ticking, concurrent.futures.ProcessPoolExecutor(max_workers=min(int(jobs), len(groups)),
                                                         mp_context=context) as pool:
        futures = {pool.submit(compile_group, key, models, ticker is not None): key for key, models in groups}
        start = time.perf_counter()   # meanwhile, here: the metric kernels, on placeholder records
        compiled_metrics += measure_all(placeholder_runs([path for _, models in groups for path in models]))
        metric_seconds += time.perf_counter() - start
        for done in concurrent.futures.as_completed(futures):
            result, runs = done.result()
            results[result.key] = result
            if ticker is not None:
                ticker.status = f"{len(results)} of {len(groups)} model families done"
            report(f"  {result.key[1]} perception, {result.key[0]} dynamics ({', '.join(result.models)}): "
                   f"{result.compiled} kernels compiled in {result.seconds:.1f} s")
            start = time.perf_counter()
            compiled_metrics += measure_all(runs)
            metric_seconds += time.perf_counter() - start
    report(f"  metrics: {compiled_metrics} kernels compiled in {metric_seconds:.1f} s")
    every_model = tuple(m for key, _ in groups for m in results[key].models)
    metrics = GroupResult(("metrics", "all"), every_model, compiled_metrics, metric_seconds)
    return [results[key] for key, _ in groups] + [metrics]


class CompileCounter(numba_event.Listener):
    """Counts numba's compile events (numba signals only real compiles, never a load from its cache)."""

    def __init__(self):
        self.count = 0

    def on_start(self, event) -> None:
        self.count += 1

    def on_end(self, event) -> None:
        pass


def _simulations(path: str) -> list:
    """Tiny runs of one model along every compiled path: serial, a batch of two, two threads."""
    preset = load_preset(path)
    model, dt = preset.model, preset.run.dt
    init = dataclasses.replace(preset.init, n=TINY_N)
    runs = [simulate(model, init, 0, 2 * dt, dt, 1, threads=1)]
    runs += simulate_batch(model, init, [0, 1], 2 * dt, dt, 1)
    if model.world.update_order == "synchronous" and describe(model.dynamics).threads:
        runs.append(simulate(model, init, 0, 2 * dt, dt, 1, threads=2))
    return [(model, obs) for obs in runs]


def placeholder_runs(paths) -> list:
    """(model, placeholder observations) of each model's tiny run: a run's arrays and types without
    simulating (:func:`simcore.placeholder_observations`), for compiling the metric kernels while the
    run loops compile elsewhere."""
    runs = []
    for path in paths:
        try:
            preset = load_preset(path)
            dt = preset.run.dt
            init = dataclasses.replace(preset.init, n=TINY_N)
            runs.append((preset.model, placeholder_observations(preset.model, init, 0, 2 * dt, dt, 1)))
        except Exception:  # noqa: BLE001 - a model that cannot run fails in its own task, with its reason
            pass
    return runs


def measure_all(runs) -> int:
    """Measure each (model, observations) with and without the leadership metrics; returns the count of
    kernels compiled."""
    counter = CompileCounter()
    with numba_event.install_listener("numba:compile", counter):
        for model, obs in runs:
            for leadership in (False, True):
                measure_run(obs, MetricSettings(group_radius=GROUP_RADIUS, leadership=leadership).resolve(model))
    return counter.count
