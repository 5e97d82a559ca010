"""Before a sweep's workers start: every kernel its runs need, compiled once (or loaded from numba's cache).

``warm_up_all(specs)`` takes one run per run loop (the runner's ``_one_per_run_loop``) and, for each,
compiles or loads its run loop on a tiny run (:func:`sweeps.worker.warm_up_run`), then its metric
kernels by measuring that run (:func:`sweeps.worker.warm_up_metrics`), so that the workers find
everything in the cache. A warm-up that fails is ignored here: the run fails in its worker and is
recorded with its reason.

Overlap. A first compile of a run loop takes about a minute on one core, and the metric kernels about
20 s more, which do not need the run loop: they need only a run's arrays. So when numba starts to compile
anything during the run loops' warm-up (never when everything is cached), one spawned process measures
placeholder records of the same tiny runs (:func:`simcore.placeholder_observations`: a run's arrays and
types, nothing of the simulator compiled) on the other core meanwhile; this process waits for it before
its own measurements, which then load the metric kernels from the cache. A kernel compiled by the helper
is the one this process would have compiled (same function, same argument types), so nothing a run
computes depends on it; if the helper fails or misses a kernel, this process compiles it as before. The
helper is stopped if the warm-up is interrupted, and if it is still running :data:`HELPER_LIMIT` seconds
after this process is ready for it (stuck, or starved on a crowded machine): this process then compiles
what is missing itself. No helper starts from a main script whose top level
runs the sweep outside ``if __name__ == "__main__":`` (a serial sweep may; the spawned process would
import the script and run it again, :mod:`sweeps.main_guard`).

Known warm. Loading a run loop and its metric kernels from the cache still takes this process about a
second, on the sweep's critical path, while the workers load the same kernels anyway as their first runs
start. So a warm-up that succeeded is recorded (:data:`RECORD`, in simcore's ``__pycache__``, next to
numba's cache) under a fingerprint of what numba's cache depends on: numba's and Python's versions, the
CPU numba compiles for, and the name, size and modification time of every source file of ``simcore``
and ``observables`` (an edit, a checkout or a reinstall changes it). A later warm-up of the same run
loops and metric families under the same fingerprint is skipped. Nothing computed depends on it: were
numba's cache to miss all the same (its files deleted by hand), each worker would compile what it needs,
as it would load it otherwise, and record it in the cache. With ``NUMBA_CACHE_DIR`` set, or a read-only
package, nothing is recorded and every warm-up runs.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

from contextlib import nullcontext

from numba.core import event as numba_event

from flocksweep.ticker import Ticker

from . import main_guard, worker

METRICS_ESTIMATE = "usually under a minute, once"   # the metric kernels' first compile (bench/RESULTS.md)
HELPER_LIMIT = 300.0   # seconds the warm-up waits for its helper (its whole job is about 20 s on one core)
FAILED = object()   # a warm-up run that failed (its run fails in its worker)
RECORD = "flocksweep-warm.txt"   # the warm-ups known to load everything from numba's cache (module docstring)


def measure_placeholders(specs) -> None:
    """The metric kernels of each spec's runs, on placeholder records (the helper process's work)."""
    for spec in specs:
        try:
            worker.warm_up_metrics(spec)
        except Exception:  # noqa: BLE001 - best effort: the sweep's own warm-up compiles what is missing
            pass


class MetricsAlongside(numba_event.Listener):
    """A numba compile listener: at the first compile it sees, starts :func:`measure_placeholders` of
    ``specs`` in one spawned process (never a second); :meth:`wait` joins it, :meth:`stop` ends it."""

    def __init__(self, specs):
        self.specs = list(specs)
        self.process = None
        self.skipped = False   # the warm-up was known warm (module docstring): nothing was loaded
        self.failed = False   # no helper could be started (an unguarded main script, specs that do not pickle)

    def on_start(self, event) -> None:
        if self.process is not None or self.failed:
            return
        import multiprocessing   # only when something compiles (a command's start-up stays light)

        try:   # a spawned process imports the main script: never start one from an unguarded script
            main_guard.check_caller_guarded()   # (a serial sweep may run from one; it compiles alone)
        except main_guard.UnguardedScript:
            self.failed = True
            return
        process = multiprocessing.get_context("spawn").Process(
            target=measure_placeholders, args=(self.specs,), name="flocksweep-metric-warm-up", daemon=True)
        try:   # inside numba's compile: never let the helper's trouble reach it
            process.start()
        except Exception:  # noqa: BLE001 - no helper: this process compiles the metric kernels itself
            self.failed = True
            return
        self.process = process

    def on_end(self, event) -> None:
        pass

    def wait(self, timeout: float = HELPER_LIMIT) -> None:
        """Join the helper; one still running after ``timeout`` seconds is stopped."""
        if self.process is not None:
            self.process.join(timeout)
            self.stop()

    def stop(self) -> None:
        if self.process is not None and self.process.is_alive():
            self.process.terminate()
            self.process.join()


def warm_up_all(specs) -> MetricsAlongside:
    """Warm up every spec's run loop, then its metric kernels (module docstring), unless the same warm-up
    is known warm; returns the listener (its ``process`` says whether a helper was started, ``skipped``
    whether the warm-up was skipped)."""
    specs = list(specs)
    helper = MetricsAlongside(specs)
    record = WarmRecord.here()
    keys = record.keys(specs) if record is not None else None
    if keys is not None and record.knows(keys):
        helper.skipped = True
        return helper
    ok = True
    try:
        with numba_event.install_listener("numba:compile", helper):
            runs = [(spec, _tiny_run(spec)) for spec in specs]
        compiling = helper.process is not None or helper.failed   # something compiled: the metrics may too
        with Ticker("sweep: compiling the metric kernels", METRICS_ESTIMATE) if compiling else nullcontext():
            helper.wait()
            for spec, obs in runs:
                ok &= obs is not FAILED
                if obs is not FAILED:
                    try:
                        worker.warm_up_metrics(spec, obs)
                    except Exception:  # noqa: BLE001 - a run that cannot be measured fails in its worker
                        ok = False
    finally:
        helper.stop()
    if ok and keys is not None:
        record.add(keys)
    return helper


class WarmRecord:
    """The file of warm-ups known to find everything in numba's cache: its first line the fingerprint of
    what that cache depends on (module docstring), then one line per warmed run loop and metric family."""

    def __init__(self, path: Path, packages: tuple[Path, ...]):
        self.path = Path(path)
        self.packages = packages

    @classmethod
    def here(cls) -> "WarmRecord | None":
        """The record next to simcore's cached kernels; None with ``NUMBA_CACHE_DIR`` set or where the
        package cannot be written."""
        import flocksweep.observables as observables
        import flocksweep.simcore as simcore
        if os.environ.get("NUMBA_CACHE_DIR"):
            return None
        packages = (Path(simcore.__file__).parent, Path(observables.__file__).parent)
        cache = packages[0] / "__pycache__"
        if not os.access(cache if cache.exists() else packages[0], os.W_OK):
            return None
        return cls(cache / RECORD, packages)

    def fingerprint(self) -> str:
        from numba import __version__ as numba_version
        from numba.core.registry import cpu_target

        digest = hashlib.sha256(repr((numba_version, sys.version, sys.platform,
                                      cpu_target.target_context.codegen().magic_tuple())).encode())
        for package in self.packages:
            for source in sorted(package.glob("*.py")):
                stat = source.stat()
                digest.update(f"{source}:{stat.st_size}:{stat.st_mtime_ns}\n".encode())
        return digest.hexdigest()

    def keys(self, specs) -> list[str] | None:
        """The lines of these specs' warm-ups; None when one cannot be told (nothing is then recorded)."""
        try:
            return [self.fingerprint()] + sorted({repr(_family(spec)) for spec in specs})
        except Exception:  # noqa: BLE001 - a spec the warm-up cannot describe: warm up, record nothing
            return None

    def knows(self, keys: list[str]) -> bool:
        lines = self._lines()
        return bool(lines) and lines[0] == keys[0] and set(keys[1:]) <= set(lines[1:])

    def add(self, keys: list[str]) -> None:
        """Record these warm-ups (with those already recorded under the same fingerprint), atomically; a
        failure to write is ignored (the next warm-up runs)."""
        lines = self._lines()
        known = set(lines[1:]) if lines and lines[0] == keys[0] else set()
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        try:
            tmp.write_text("\n".join([keys[0], *sorted(known | set(keys[1:]))]) + "\n")
            tmp.replace(self.path)
        except OSError:
            pass

    def _lines(self) -> list[str]:
        """The record's lines; none when it is missing or unreadable."""
        try:
            return self.path.read_text().splitlines()
        except (OSError, UnicodeError):
            return []


def _family(spec) -> tuple:
    """What decides the kernels a spec's warm-up compiles: its run loop (dynamics, perception kind; none for
    a command model) and the families of metric kernels its measurement uses."""
    metrics = spec.metrics
    measured = (bool(metrics.leadership), metrics.box is None, bool(metrics.obstacles), metrics.migration is None,
                bool(metrics.dcd))
    if spec.preset is None:
        return ("command",) + measured
    model = spec.preset.model
    return (model.dynamics, model.perception.kind) + measured


def _tiny_run(spec):
    """The tiny run's observations (None for a command model), or :data:`FAILED`."""
    try:
        return worker.warm_up_run(spec)
    except Exception:  # noqa: BLE001 - a run that cannot even start is recorded by its worker
        return FAILED
