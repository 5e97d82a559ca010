"""sweeps/warmup.py: the warm-up before a sweep's workers start, with the metric kernels compiled in a
helper process on placeholder records while the run loop compiles here."""
from __future__ import annotations

import dataclasses
import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from flocksweep.observables.summary import MetricSettings
from paths import ROOT
from flocksweep.simcore import load_preset, placeholder_observations, simulate
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.warmup import MetricsAlongside, measure_placeholders, warm_up_all
from tiny_sweeps import sweep

MODELS = sorted((ROOT / "configs" / "models").glob("*.toml"))
MEASURE_IN_A_FRESH_CACHE = """
import pickle, sys
from numba.core import event
from flocksweep.observables.summary import measure_run
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


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
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
    from flocksweep.sweeps import main_guard

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


# -- known warm: a warm-up that found everything in numba's cache is not done again -----------------------

def packages():
    import flocksweep.observables as observables
    import flocksweep.simcore as simcore
    return Path(simcore.__file__).parent, Path(observables.__file__).parent


@pytest.fixture
def record(tmp_path, monkeypatch):
    """Warm-ups recorded in a file of this test's own (the real record is the session's)."""
    from flocksweep.sweeps import warmup

    here = warmup.WarmRecord(tmp_path / "warm.txt", packages())
    monkeypatch.setattr(warmup.WarmRecord, "here", classmethod(lambda cls: here))
    return here


def test_a_warm_up_known_warm_is_skipped_and_loads_nothing(record, monkeypatch):
    from flocksweep.sweeps import worker

    first = warm_up_all(specs())
    assert not first.skipped and record.path.exists()

    def loaded(*args, **kwargs):
        raise AssertionError("a known warm-up loaded a kernel")

    monkeypatch.setattr(worker, "warm_up_run", loaded)
    monkeypatch.setattr(worker, "warm_up_metrics", loaded)
    assert warm_up_all(specs()).skipped


def test_other_run_loops_or_metric_families_are_warmed_up_again(record):
    warm_up_all(specs())
    leadership = expand(sweep_from_dict(sweep(leadership_metrics=True), ROOT))[:1]
    vicsek = dataclasses.replace(specs()[0], preset=load_preset(ROOT / "configs" / "models" / "vicsek.toml"))
    for other in (leadership, [vicsek]):
        keys = record.keys(other)
        assert not record.knows(keys)   # its family is not recorded ...
    assert record.knows(record.keys(specs()))   # ... the first is


def test_the_record_is_void_after_any_source_file_changes(tmp_path):
    """Numba's cache misses when a kernel's source file is edited or touched (or numba, Python or the CPU
    changes): so does the record."""
    from flocksweep.sweeps.warmup import WarmRecord

    package = tmp_path / "pkg"
    package.mkdir()
    source = package / "kernels.py"
    source.write_text("x = 1\n")
    record = WarmRecord(tmp_path / "warm.txt", (package,))
    record.add(record.keys(specs()))
    assert record.knows(record.keys(specs()))
    os.utime(source, ns=(source.stat().st_atime_ns, source.stat().st_mtime_ns + 1_000_000))   # touched
    assert not record.knows(record.keys(specs()))
    record.add(record.keys(specs()))
    assert record.knows(record.keys(specs()))
    source.write_text("x = 22\n")   # edited
    assert not record.knows(record.keys(specs()))


def test_a_failed_warm_up_is_not_recorded(record, monkeypatch):
    from flocksweep.sweeps import worker

    def fails(spec):
        raise RuntimeError("no run")

    monkeypatch.setattr(worker, "warm_up_run", fails)
    assert not warm_up_all(specs()).skipped
    assert not record.path.exists()
    bad = dataclasses.replace(specs()[0], metrics=None)   # cannot even be described: warmed up, not recorded
    assert record.keys([bad]) is None
    assert not warm_up_all([bad]).skipped and not record.path.exists()


def test_nothing_is_recorded_with_a_cache_directory_of_its_own(monkeypatch):
    from flocksweep.sweeps.warmup import WarmRecord

    monkeypatch.setenv("NUMBA_CACHE_DIR", "/tmp/elsewhere")
    assert WarmRecord.here() is None
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    here = WarmRecord.here()
    assert here is None or here.path.parent == packages()[0] / "__pycache__"


def test_a_damaged_record_means_warm_up(record):
    record.path.write_bytes(b"\xff\xfe not text")
    assert not record.knows(record.keys(specs()))
    warm_up_all(specs())   # warmed up, and the record rewritten
    assert record.knows(record.keys(specs()))
