"""Interrupts, dead workers and dead runners over sweeps (docs/errors.md).

The kill battery (slow) stops a small sweep at random (seeded) moments with SIGINT to its process
group, SIGTERM or SIGKILL to the runner, or SIGKILL to one worker, and checks: no traceback, the
documented exit status, no process left behind, and the same command run again (no cleanup in
between) gives runs.parquet and the time series bit for bit as an uninterrupted run. Quick tests check
the same rules in this process: an interrupt saves the finished runs, releases the folder, exits 130
(143 for SIGTERM) and says how to resume; a worker killed once is retried, one that dies every time
leaves its runs missing (never failed, exit 5); finished runs are saved on time while a worker is busy;
a lock held by what a dead runner left behind is recognised. The contained-fault battery of issue 42
(tests/faults.py ``CONTAINED``: crashing, looping and NaN plug-ins, commands that flood stderr or leave
children, an edit behind a deleted manifest) runs its representative cases here, all in
bench/fault_battery.py.
"""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time

import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

import faults
from paths import ROOT
from flocksweep.sweeps import lock, runner, worker
from flocksweep.cli import main
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.interrupts import Terminated
from flocksweep.sweeps.runner import run_sweep, status
from flocksweep.sweeps.store import ResultsStore, StoreLocked

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
TIMING = ["wall_s", "sim_s", "part"]
SWEEP = f"""name = "faulty"
seed = 8
[model]
preset = "{HOLLAND}"
[run]
n = 6
duration = 1.0
record_interval = 0.5
warmup = 0.5
[[axes]]
key = "init.n"
values = {{values}}
"""


def write_sweep(folder, values="[6, 7, 8, 9]"):
    path = folder / "faulty.toml"
    path.write_text(SWEEP.format(values=values))
    return path


def run(path, out, **options):
    options.setdefault("executor", "serial")
    return run_sweep(load_sweep(path), path.read_text(), out, progress=False, batch_size=1, **options)


def results(out):
    return pd.read_parquet(out / "runs.parquet").drop(columns=TIMING)


# -- interrupts ------------------------------------------------------------------------------------

def interrupting_batch(after: int, error):
    """A worker.execute_batch that raises ``error`` on its call number ``after + 1`` (in this process)."""
    real, calls = worker.execute_batch, []

    def patched(specs, out_dir=None):
        calls.append(1)
        if len(calls) > after:
            raise error
        return real(specs, out_dir)
    return patched


@pytest.mark.parametrize("error, code, name", [(KeyboardInterrupt(), 130, "SIGINT"), (Terminated(), 143, "SIGTERM")])
def test_an_interrupt_saves_what_finished_releases_the_folder_and_says_how_to_resume(error, code, name, tmp_path,
                                                                                      capsys, monkeypatch):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    reference = tmp_path / "reference"
    run(sweep, reference)
    monkeypatch.setattr(worker, "execute_batch", interrupting_batch(2, error))
    argv = ["run", str(sweep), "--out", str(out), "--executor", "serial", "--no-progress", "--batch-size", "1"]
    assert main(argv) == code
    err = capsys.readouterr().err
    assert err.splitlines()[0] == f"flocksweep: interrupted ({name})" and "Traceback" not in err
    assert f"saved: 2 ok and 0 failed of 4 runs in {out}; resume with: flocksweep run {sweep} --out {out}" in err
    assert ResultsStore(out).holder() is None
    assert status(out)["ok"] == 2
    monkeypatch.undo()
    assert main(argv) == 0
    assert "computed 2 now, 2 already done" in capsys.readouterr().out
    assert_frame_equal(results(out), results(reference), check_exact=True)


# -- dead workers --------------------------------------------------------------------------------------

def dying_batch(marker_dir, n_dies: int, times: int):
    """A worker.execute_batch whose worker process dies on the batch with init.n == ``n_dies``, the first
    ``times`` times it is run (counted by files in ``marker_dir``); shipped to the spawned workers."""
    real = worker.execute_batch

    def patched(specs, out_dir=None):
        if any(s.preset.init.n == n_dies for s in specs):
            done = len(list(marker_dir.glob("died-*")))
            if done < times:
                (marker_dir / f"died-{done}").write_text("")
                os._exit(9)
        return real(specs, out_dir)
    return patched


@pytest.mark.slow
def test_a_worker_killed_once_is_retried_and_nothing_is_lost(tmp_path, monkeypatch):
    sweep = write_sweep(tmp_path)
    out, reference = tmp_path / "out", tmp_path / "reference"
    run(sweep, reference)
    monkeypatch.setattr(worker, "execute_batch", dying_batch(tmp_path, 7, times=1))
    result = run(sweep, out, executor="local", workers=2)
    assert result.lost == [] and (tmp_path / "died-0").exists()
    assert_frame_equal(results(out), results(reference), check_exact=True)


@pytest.mark.slow
def test_a_run_whose_worker_always_dies_is_left_missing_never_failed(tmp_path, monkeypatch, capsys):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    monkeypatch.setattr(worker, "execute_batch", dying_batch(tmp_path, 7, times=99))
    argv = ["run", str(sweep), "--out", str(out), "--executor", "local", "--workers", "2", "--no-progress",
            "--batch-size", "1"]
    assert main(argv) == 5
    captured = capsys.readouterr()
    assert "1 runs were left missing: their worker processes died" in captured.err and "Traceback" not in captured.err
    table = pd.read_parquet(out / "runs.parquet")
    assert sorted(table["init.n"]) == [6, 8, 9] and (table["status"] == "ok").all()
    info = status(out)
    assert (info["ok"], info["failed"], info["missing"]) == (3, 0, 1)
    assert len(list(tmp_path.glob("died-*"))) == 3            # tried MAX_ATTEMPTS times, alone after the first
    monkeypatch.undo()
    assert main(argv) == 0                                   # the cause is gone: the rerun completes
    assert status(out)["missing"] == 0


# -- saving on time --------------------------------------------------------------------------------------

@pytest.mark.slow
def test_finished_runs_are_saved_on_time_while_a_worker_is_busy_with_a_long_run(tmp_path, monkeypatch):
    monkeypatch.setattr(runner, "FLUSH_SECONDS", 1.0)
    sweep = write_sweep(tmp_path, values="[6, 7, 8, 9, 10, 11, 12, 13, 1000]")   # the long run: several seconds
    out = tmp_path / "out"
    config = load_sweep(sweep, ["run.duration=6.0", "run.warmup=0.5"])
    done = threading.Event()
    worker_thread = threading.Thread(target=lambda: (run_sweep(config, sweep.read_text(), out, "local", 2,
                                                               progress=False, batch_size=1), done.set()))
    worker_thread.start()
    try:
        deadline, saved = time.monotonic() + 300, pd.DataFrame({"init.n": []})
        while len(saved) < 8 and not done.is_set() and time.monotonic() < deadline:
            time.sleep(0.1)
            saved = ResultsStore(out).all_rows() if (out / "runs").is_dir() else saved
        # every small run is on disk while the 1,000-boid run still computes
        assert not done.is_set(), "the long run ended before the small runs were saved"
        assert sorted(saved["init.n"]) == [6, 7, 8, 9, 10, 11, 12, 13]
    finally:
        worker_thread.join(timeout=600)
    assert done.is_set() and len(pd.read_parquet(out / "runs.parquet")) == 9


# -- the lock -------------------------------------------------------------------------------------------

HOLDER = """
import fcntl, sys, time
handle = open(sys.argv[1], "a+")
fcntl.flock(handle, fcntl.LOCK_EX)
print("held", flush=True)
time.sleep(float(sys.argv[2]))
"""


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_a_lock_kept_by_processes_a_dead_runner_left_behind_is_recognised(tmp_path, monkeypatch):
    monkeypatch.setattr(lock, "SETTLE", 0.1)
    monkeypatch.setattr(lock, "ORPHAN_GRACE", 1.0)
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / ".lock").write_text(f"pid {dead_pid()} on {socket.gethostname()} since earlier")
    script = tmp_path / "holder.py"
    script.write_text(HOLDER)
    leftover = subprocess.Popen([sys.executable, str(script), str(folder / ".lock"), "60"], stdout=subprocess.PIPE,
                                text=True)
    try:
        assert leftover.stdout.readline().strip() == "held"
        with pytest.raises(StoreLocked) as info:
            with ResultsStore(folder).lock():
                pass
        message = str(info.value)
        assert "no longer running" in message and str(leftover.pid) in message
    finally:
        leftover.kill()
        leftover.wait()
    with ResultsStore(folder).lock():   # they are gone: the folder is free
        assert f"pid {os.getpid()}" in ResultsStore(folder).holder()


@pytest.mark.slow
def test_a_lock_whose_leftovers_exit_in_the_grace_period_is_taken(tmp_path, monkeypatch):
    monkeypatch.setattr(lock, "SETTLE", 0.1)
    monkeypatch.setattr(lock, "ORPHAN_GRACE", 20.0)
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / ".lock").write_text(f"pid {dead_pid()} on {socket.gethostname()} since earlier")
    script = tmp_path / "holder.py"
    script.write_text(HOLDER)
    leftover = subprocess.Popen([sys.executable, str(script), str(folder / ".lock"), "1.5"], stdout=subprocess.PIPE,
                                text=True)
    assert leftover.stdout.readline().strip() == "held"
    start = time.monotonic()
    with ResultsStore(folder).lock():
        assert f"pid {os.getpid()}" in (folder / ".lock").read_text()
    assert time.monotonic() - start < 15
    leftover.wait()


def test_a_killed_runner_frees_the_folder_at_once(tmp_path):
    folder = tmp_path / "out"
    script = tmp_path / "runner.py"
    script.write_text("import sys, time\nfrom flocksweep.sweeps.store import ResultsStore\n"
                      "with ResultsStore(sys.argv[1]).lock():\n    print('locked', flush=True)\n    time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, str(script), str(folder)], stdout=subprocess.PIPE, text=True,
                            env=faults.environment())
    assert proc.stdout.readline().strip() == "locked"
    assert f"pid {proc.pid}" in ResultsStore(folder).holder()
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert ResultsStore(folder).holder() is None
    with ResultsStore(folder).lock():
        pass


# -- the kill battery ------------------------------------------------------------------------------------

def test_a_signal_after_the_sweep_wrote_its_results_does_not_count_as_a_hit(tmp_path):
    """The kill battery's guard against a false alarm: a signal sent when the runner had written its final
    manifest reaches a process that is only exiting (the kernel drops it, exit 0)."""
    import json

    sweep = write_sweep(tmp_path, values="[6]")
    out = tmp_path / "out"
    started = time.time()
    run(sweep, out)
    assert not faults.completed_before("sweep", out, started - 1.0)
    assert faults.completed_before("sweep", out, time.time() + 0.01)
    manifest = json.loads((out / "manifest.json").read_text())
    (out / "manifest.json").write_text(json.dumps({**manifest, "finished": None}))   # as while it runs
    assert not faults.completed_before("sweep", out, time.time() + 0.01)
    assert not faults.completed_before("sweep", tmp_path / "nowhere", time.time())


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("uninterrupted")
    _, span = faults.timed_run(faults.sweep_argv(folder), folder, faults.sweep_ready(folder))
    return folder / "out", span


@pytest.mark.slow
@pytest.mark.parametrize("executor, seed, how", [("local", seed, how) for how in faults.HOW for seed in (1, 2)]
                         + [("dask", 1, how) for how in faults.HOW])
def test_a_sweep_killed_at_a_random_moment_resumes_bit_for_bit(executor, how, seed, tmp_path, uninterrupted):
    reference, seconds = uninterrupted
    # dask's cluster starts after design.parquet is written: its window starts at once, to catch the start
    window = (0.1, 0.8 * seconds) if executor == "local" else (0.0, 0.8 * seconds + 3.0)
    trial, rerun, difference = faults.sweep_trial(tmp_path, reference, how, seed, window=window, executor=executor)
    assert trial.hit, f"the sweep had finished before the signal ({trial.delay:.1f} s)"
    assert trial.exit_code == faults.EXPECTED_EXIT[how], trial.stderr
    assert not trial.traceback, trial.stderr
    if how in ("sigint", "sigterm"):
        assert trial.stderr.startswith("flocksweep: interrupted (") and "resume with: flocksweep run" in trial.stderr
        assert trial.elapsed_after_signal < 15
    assert trial.orphans == []
    assert rerun.returncode == 0 and "Traceback" not in rerun.stderr, rerun.stderr
    assert difference == ""


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 1.0, 2.0])
def test_ctrl_c_while_the_dask_cluster_starts_is_never_lost_nor_a_traceback(delay, tmp_path, uninterrupted):
    """The cluster starts a second or more after design.parquet is written: a Ctrl-C in those seconds
    used to be ignored (exit 0), or printed the workers' "Stream is closed" tracebacks."""
    reference, _ = uninterrupted
    argv = faults.sweep_argv(tmp_path, "dask")
    trial = faults.kill_trial(argv, tmp_path, faults.sweep_ready(tmp_path), "sigint", 0, (delay, delay))
    assert trial.hit
    if faults.completed_before("sweep", tmp_path / "out", trial.sent_at):   # the signal came too late to stop it:
        assert trial.exit_code in (0, 130) and "Traceback" not in trial.stderr, trial.stderr   # a clean end,
        assert trial.orphans == []                                                      # nothing left running
        return
    assert trial.exit_code == 130, trial.stderr
    assert "Traceback" not in trial.stderr and "ERROR" not in trial.stderr, trial.stderr
    assert trial.stderr.startswith("flocksweep: interrupted (SIGINT)") or \
        trial.stderr.split("\n", 1)[1].startswith("flocksweep: interrupted (SIGINT)"), trial.stderr
    assert trial.orphans == []
    rerun = faults.run_command(argv, tmp_path)
    assert rerun.returncode == 0 and faults.same_sweep(reference, tmp_path / "out") == ""


def _square(x):
    return x * x


@pytest.mark.slow
def test_a_killed_resource_tracker_is_restarted_quietly_and_keeps_the_pool_semaphores(capfd):
    from multiprocessing import resource_tracker

    from flocksweep.sweeps.executors import Executor, mend_resource_tracker

    with Executor("local", workers=2) as pool:
        assert pool.map(_square, range(4)) == [0, 1, 4, 9]
        os.kill(resource_tracker._resource_tracker._pid, signal.SIGKILL)
        time.sleep(0.5)
        assert pool.map(_square, range(4, 8)) == [16, 25, 36, 49]
        assert not mend_resource_tracker()   # mended at the loop's first turn
    time.sleep(1.0)   # the tracker prints what it is told to release as it reads it
    err = capfd.readouterr().err
    assert "KeyError" not in err and "Traceback" not in err and "relaunching" not in err, err


TRACKER_DIED_BEFORE = """
import multiprocessing, os, signal, sys, time
from multiprocessing import resource_tracker
from flocksweep.sweeps.executors import Executor

if __name__ == "__main__":
    lock = multiprocessing.get_context("spawn").Lock()   # starts the tracker, which records its name
    os.kill(resource_tracker._resource_tracker._pid, signal.SIGKILL)
    time.sleep(0.3)
    with Executor(sys.argv[1], workers=int(sys.argv[2])) as pool:
        print(pool.map(abs, [-1, -2, -3]))
    del lock   # released: the tracker is told the name
    time.sleep(0.5)   # the tracker prints what it is told to release as it reads it
"""


@pytest.mark.slow
@pytest.mark.parametrize("kind, workers", [("dask", 1), ("local", 2)])
def test_a_tracker_killed_before_the_workers_start_is_relaunched_knowing_the_earlier_names(kind, workers, tmp_path):
    """The kill battery's tracker trial on dask: the tracker killed just before or while the cluster
    starts was relaunched by the cluster's own queues, before the executor's first turn mended it, and
    every name registered earlier came back as a KeyError traceback when it was released."""
    script = tmp_path / "killed_tracker.py"
    script.write_text(TRACKER_DIED_BEFORE)
    done = subprocess.run([sys.executable, str(script), kind, str(workers)], capture_output=True, text=True,
                          env=faults.environment(), timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "[1, 2, 3]", done.stderr
    assert "KeyError" not in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert "relaunching" not in done.stderr, done.stderr


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_a_tracker_relaunched_by_multiprocessing_itself_learns_the_pool_semaphores(capfd):
    """The tracker killed, then a new semaphore (multiprocessing relaunches the tracker on its own, before
    the executor's next turn): the relaunched tracker is told the live names, so releasing them at the
    pool's end prints nothing."""
    import multiprocessing
    from multiprocessing import resource_tracker

    from flocksweep.sweeps.executors import Executor

    with Executor("local", workers=2) as pool:
        assert pool.map(_square, range(4)) == [0, 1, 4, 9]
        os.kill(resource_tracker._resource_tracker._pid, signal.SIGKILL)
        time.sleep(0.5)
        lock = multiprocessing.get_context("spawn").Lock()   # registers, so relaunches the dead tracker
        del lock
    time.sleep(1.0)   # the tracker prints what it is told to release as it reads it
    err = capfd.readouterr().err
    assert "KeyError" not in err and "Traceback" not in err and "relaunching" not in err, err


CONTAINED = {case.name: case for case in faults.CONTAINED}


@pytest.mark.slow
@pytest.mark.parametrize("name", faults.CONTAINED_QUICK)
def test_a_contained_fault_ends_in_its_documented_way(name, tmp_path):
    """The contained-fault battery (issue 42; all of it in bench/fault_battery.py): a plug-in's crash under
    2 workers, a NaN force through simulate (exit 6), 200 MiB of a command's stderr (the runner's peak
    memory stays that of a run: 798 MB before), a command's background child (ended with the run), an
    edited value behind a deleted manifest (recomputed, never vouched for)."""
    result = faults.contained_trial(CONTAINED[name], tmp_path)
    assert result.problems == []
    if "stderr" in name:
        assert result.peak_mb[0] < 400, result.peak_mb
