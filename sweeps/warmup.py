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
"""
from __future__ import annotations

from numba.core import event as numba_event

from . import main_guard, worker

HELPER_LIMIT = 300.0   # seconds the warm-up waits for its helper (its whole job is about 20 s on one core)
FAILED = object()   # a warm-up run that failed (its run fails in its worker)


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
    """Warm up every spec's run loop, then its metric kernels (module docstring); returns the listener
    (its ``process`` says whether a helper was started)."""
    specs = list(specs)
    helper = MetricsAlongside(specs)
    try:
        with numba_event.install_listener("numba:compile", helper):
            runs = [(spec, _tiny_run(spec)) for spec in specs]
        helper.wait()
        for spec, obs in runs:
            if obs is not FAILED:
                try:
                    worker.warm_up_metrics(spec, obs)
                except Exception:  # noqa: BLE001 - a run that cannot be measured fails in its worker
                    pass
    finally:
        helper.stop()
    return helper


def _tiny_run(spec):
    """The tiny run's observations (None for a command model), or :data:`FAILED`."""
    try:
        return worker.warm_up_run(spec)
    except Exception:  # noqa: BLE001 - a run that cannot even start is recorded by its worker
        return FAILED
