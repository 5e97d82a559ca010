"""sweeps/warmup.py: the warm-up before a sweep's workers start, with the metric kernels compiled in a
helper process on placeholder records while the run loop compiles here."""
from __future__ import annotations

import dataclasses
import os
import pickle
import subprocess
import sys

import pytest

from observables.summary import MetricSettings
from paths import ROOT
from simcore import load_preset, placeholder_observations, simulate
from sweeps.config import sweep_from_dict
from sweeps.design import expand
from sweeps.warmup import MetricsAlongside, measure_placeholders, warm_up_all
from tiny_sweeps import sweep

MODELS = sorted((ROOT / "configs" / "models").glob("*.toml"))
MEASURE_IN_A_FRESH_CACHE = """
import pickle, sys
from numba.core import event
from observables.summary import measure_run
compiled = []
class Count(event.Listener):
    def on_start(self, ev):
        func = ev.data["dispatcher"].py_func
        compiled.append(f"{func.__module__}.{func.__qualname__}")
    def on_end(self, ev):
        pass
event.register("numba:compile", Count())
cases = pickle.load(open(sys.argv[1], "rb"))
for placeholder, real, settings in cases:
    measure_run(placeholder, settings)
before = len(compiled)
for placeholder, real, settings in cases:
    measure_run(real, settings)
print(before, sorted(set(compiled[before:])))
"""


@pytest.mark.slow
def test_placeholder_records_compile_every_metric_kernel_a_real_run_needs(tmp_path):
    """In a fresh process with an empty numba cache, after measuring the placeholder records of a tiny run
    of every shipped model (with and without the leadership metrics), measuring the real runs compiles
    nothing more: the helper's warm-up leaves no metric kernel for the sweep's process to compile."""
    cases = []
    for path in MODELS:
        preset = load_preset(path)
        init, dt = dataclasses.replace(preset.init, n=5), preset.run.dt
        real = simulate(preset.model, init, 0, 2 * dt, dt, 1)
        placeholder = placeholder_observations(preset.model, init, 0, 2 * dt, dt, 1)
        for leadership in (False, True):
            settings = MetricSettings(group_radius=10.0, leadership=leadership).resolve(preset.model)
            cases.append((placeholder, real, settings))
    with open(tmp_path / "cases.pkl", "wb") as file:
        pickle.dump(cases, file)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", MEASURE_IN_A_FRESH_CACHE, str(tmp_path / "cases.pkl")], env=env,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    compiled_by_placeholders, compiled_after = done.stdout.split(" ", 1)
    assert int(compiled_by_placeholders) > 0   # the cache was empty: the placeholders compiled the kernels
    assert compiled_after.strip() == "[]"


def specs(n=1):
    return expand(sweep_from_dict(sweep(), ROOT))[:n]


def test_with_everything_compiled_no_helper_is_started():
    warm_up_all(specs())   # whatever this had to compile (a cold cache) ...
    assert warm_up_all(specs()).process is None   # ... a second warm-up compiles nothing: no helper


def test_the_helper_starts_once_at_the_first_compile_and_measures_the_placeholders():
    helper = MetricsAlongside(specs())
    assert helper.process is None
    helper.on_start(None)
    first = helper.process
    helper.on_start(None)
    assert helper.process is first
    helper.wait()
    assert first.exitcode == 0


def test_an_interrupted_warm_up_stops_its_helper():
    helper = MetricsAlongside(specs())
    helper.on_start(None)
    helper.stop()
    assert not helper.process.is_alive() and helper.process.exitcode != 0


def test_a_spec_that_cannot_be_measured_is_left_to_its_worker():
    bad = dataclasses.replace(specs()[0], metrics=None)   # measure_run would raise on it
    measure_placeholders([bad])   # the helper's work: no exception
    warm_up_all([bad])            # nor the warm-up's: the run fails in its worker, with its reason


def test_a_helper_that_cannot_start_is_no_error_inside_numbas_compile():
    helper = MetricsAlongside([lambda: None])   # a lambda does not pickle: the spawned process cannot start
    helper.on_start(None)
    assert helper.process is None and helper.failed
    helper.on_start(None)   # not tried again
    helper.wait()
    helper.stop()


def test_no_helper_is_spawned_from_an_unguarded_main_script(monkeypatch):
    """A serial sweep may run from a script without ``if __name__ == "__main__":``; a spawned helper would
    import that script and run its sweep again, so none is started (this process compiles alone)."""
    from sweeps import main_guard

    def unguarded():
        raise main_guard.UnguardedScript(main_guard.message())

    monkeypatch.setattr(main_guard, "check_caller_guarded", unguarded)
    helper = MetricsAlongside(specs())
    helper.on_start(None)
    assert helper.process is None and helper.failed


def test_a_helper_still_running_after_the_limit_is_stopped_and_the_warm_up_goes_on():
    """A stuck helper (or one starved on a crowded machine) never holds the sweep: waiting is bounded."""
    import multiprocessing
    import time

    helper = MetricsAlongside(specs())
    helper.process = multiprocessing.get_context("spawn").Process(target=time.sleep, args=(60,), daemon=True)
    helper.process.start()
    started = time.monotonic()
    helper.wait(timeout=1.0)
    assert time.monotonic() - started < 15
    assert not helper.process.is_alive() and helper.process.exitcode != 0
