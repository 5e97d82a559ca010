"""Kill trials: a ``flocksweep`` command stopped at a random (seeded) moment, then run again.

``kill_trial(argv, cwd, ready, how, seed, window)`` starts ``python -m flocksweep.cli *argv`` in its own
session, waits until ``ready()`` (the command is computing), then after a delay drawn from ``window``
(seconds after ``ready()``, ``random.Random(seed)``) stops it ``how``:

* ``"sigint"``: SIGINT to the whole process group, as Ctrl-C in a terminal does;
* ``"sigterm"``: SIGTERM to the runner (a scheduler or ``kill`` stopping it);
* ``"sigkill"``: SIGKILL to the runner (nothing can be saved then, nor cleaned up);
* ``"worker"``: SIGKILL to one of its worker processes (the runner goes on);
* ``"tracker"``: SIGKILL to multiprocessing's resource tracker (the helper process that unlinks the pool's
  semaphores; the runner goes on, quietly starting a new one).

``sweep_argv(folder, executor)`` runs the sweep on the local pool (``"local"``) or on a dask LocalCluster
(``"dask"``): every way applies to both.

It returns a :class:`Trial`: the exit status (``EXPECTED_EXIT`` documents the one each way must give),
stderr, whether the command was still running when the signal went (``hit``), and the processes it
started that were still alive 20 s after it ended (``orphans``). The caller then runs the same command
again (no cleanup in between) and compares the results with an uninterrupted run: ``same_sweep`` and
``same_chain`` say how they differ ('' when bit for bit the same). ``sweep_trial`` and
``calibration_trial`` do all of it for the small sweep and the short calibration below; a trial whose
command had already finished when the signal was due is run again with the window halved.

The section "contained faults" holds the cases of issue 42 (:data:`CONTAINED`, run by
:func:`contained_trial`): plug-ins that crash, loop or return NaN, commands that flood stderr or leave
children behind, a results folder whose manifest was deleted after an edit, a full disk while npe writes
``posterior.nc`` (run through ``tests/full_disk.py``: a :class:`Contained` case's ``module``).
"""
from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from npe_tiny import CALIBRATION as NPE_TINY
from paths import ROOT

HOW = ("sigint", "sigterm", "sigkill", "worker", "tracker")
EXPECTED_EXIT = {"sigint": 130, "sigterm": 143, "sigkill": -signal.SIGKILL, "worker": 0, "tracker": 0}
TIMING = ("wall_s", "sim_s", "part")


@dataclass
class Trial:
    how: str
    seed: int
    delay: float
    hit: bool = False            # the command was still running when the signal was sent
    exit_code: int | None = None
    stderr: str = ""
    orphans: list = field(default_factory=list)
    elapsed_after_signal: float = 0.0
    sent_at: float = 0.0         # wall-clock time (time.time()) the signal was sent

    @property
    def traceback(self) -> bool:
        return "Traceback" in self.stderr


def command(argv, module: str = "flocksweep.cli") -> list[str]:
    return [sys.executable, "-m", module, *map(str, argv)]


def environment() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT)] + [p for p in sys.path if p])}


def children(pid: int) -> dict[int, list[int]]:
    """{parent pid: [child pids]} of every process (from /proc)."""
    tree: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        tree.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    return tree


def descendants(pid: int) -> set[int]:
    tree, out, todo = children(pid), set(), [pid]
    while todo:
        for child in tree.get(todo.pop(), []):
            if child not in out:
                out.add(child)
                todo.append(child)
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _descendants_running(pid: int, marker: str) -> list[int]:
    out = []
    for child in sorted(descendants(pid)):
        try:
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        if marker in cmdline:
            out.append(child)
    return out


def workers_of(pid: int) -> list[int]:
    """The executor's worker processes among ``pid``'s descendants (spawned interpreters)."""
    return _descendants_running(pid, "spawn_main")


def trackers_of(pid: int) -> list[int]:
    """multiprocessing's resource tracker among ``pid``'s descendants."""
    return _descendants_running(pid, "resource_tracker")


def kill_trial(argv, cwd, ready, how: str, seed: int, window: tuple[float, float], timeout: float = 300) -> Trial:
    """Run, stop and watch one command (see the module docstring)."""
    rng = random.Random(seed)
    trial = Trial(how=how, seed=seed, delay=rng.uniform(*window))
    err_path = Path(cwd) / f".trial-{how}-{seed}.stderr"
    seen: set[int] = set()
    with open(err_path, "w") as err:
        proc = subprocess.Popen(command(argv), cwd=cwd, stdout=subprocess.DEVNULL, stderr=err, env=environment(),
                                start_new_session=True)
        try:
            deadline = time.monotonic() + timeout
            while not ready() and proc.poll() is None and time.monotonic() < deadline:
                seen |= descendants(proc.pid)
                time.sleep(0.05)
            until = time.monotonic() + trial.delay   # the delay counts from ready(), whatever the signal
            targets_of = {"worker": workers_of, "tracker": trackers_of}.get(how)
            if targets_of is not None:
                while not targets_of(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
                    time.sleep(0.05)
            while time.monotonic() < until and proc.poll() is None:
                seen |= descendants(proc.pid)
                time.sleep(0.02)
            seen |= descendants(proc.pid)
            trial.hit = proc.poll() is None
            sent, trial.sent_at = time.monotonic(), time.time()
            if trial.hit:
                if how == "sigint":
                    os.killpg(proc.pid, signal.SIGINT)
                elif how == "sigterm":
                    os.kill(proc.pid, signal.SIGTERM)
                elif how == "sigkill":
                    os.kill(proc.pid, signal.SIGKILL)
                else:
                    workers = targets_of(proc.pid)
                    if workers:
                        os.kill(rng.choice(workers), signal.SIGKILL)
                    else:
                        trial.hit = False
            while proc.poll() is None and time.monotonic() < deadline:
                seen |= descendants(proc.pid)
                time.sleep(0.05)
            trial.elapsed_after_signal = time.monotonic() - sent
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    trial.exit_code = proc.returncode
    trial.stderr = err_path.read_text()
    err_path.unlink()
    grace = time.monotonic() + 20
    while any(alive(p) for p in seen) and time.monotonic() < grace:
        time.sleep(0.2)
    trial.orphans = sorted(p for p in seen if alive(p))
    return trial


def timed_run(argv, cwd, ready, timeout: float = 600) -> tuple[int, float]:
    """Run a command to its end: (exit status, seconds from ``ready()`` to the end), the span a kill
    should land in."""
    proc = subprocess.Popen(command(argv), cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=environment(), text=True)
    deadline = time.monotonic() + timeout
    while not ready() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    start = time.monotonic()
    _, err = proc.communicate(timeout=max(1.0, deadline - time.monotonic()))
    if proc.returncode:
        raise RuntimeError(f"the uninterrupted run failed: {err[-500:]}")
    return proc.returncode, time.monotonic() - start


def run_command(argv, cwd, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(command(argv), cwd=cwd, capture_output=True, text=True, env=environment(), timeout=timeout)


# ------------------------------------------------------------------------------------------- comparing

def _series(folder: Path) -> pd.DataFrame:
    frames = [pd.read_parquet(p) for p in sorted((folder / "timeseries").glob("part-*.parquet"))]
    runs = pd.read_parquet(folder / "runs.parquet")
    table = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["run_id", "t"])
    table = table[table["run_id"].isin(runs["run_id"])].drop_duplicates(["run_id", "t"], keep="last")
    return table.sort_values(["run_id", "t"], kind="stable").reset_index(drop=True)


def same_sweep(reference: Path, resumed: Path) -> str:
    """'' when ``resumed`` holds the same runs.parquet (every column but timing, bit for bit) and time
    series as ``reference``; else what differs."""
    if not (resumed / "runs.parquet").exists():
        return "no runs.parquet"
    a, b = pd.read_parquet(reference / "runs.parquet"), pd.read_parquet(resumed / "runs.parquet")
    if list(a["run_id"]) != list(b["run_id"]):
        return f"run ids differ ({len(a)} against {len(b)} runs)"
    if list(a.columns) != list(b.columns):
        return f"columns differ: {sorted(set(a.columns) ^ set(b.columns))}"
    keep = [c for c in a.columns if c not in TIMING]
    try:
        pd.testing.assert_frame_equal(a[keep], b[keep], check_exact=True)
        pd.testing.assert_frame_equal(_series(reference), _series(resumed), check_exact=True)
    except AssertionError as err:
        return str(err).splitlines()[0]
    return ""


def same_chain(reference: Path, resumed: Path) -> str:
    """'' when ``resumed``'s chain.h5 (chain, log-probabilities, acceptance) and posterior.csv equal the
    reference's bit for bit; else what differs."""
    import h5py

    for name in ("chain.h5", "posterior.csv"):
        if not (resumed / name).exists():
            return f"no {name}"
    with h5py.File(reference / "chain.h5", "r") as fa, h5py.File(resumed / "chain.h5", "r") as fb:
        for name in ("chain", "log_prob", "accepted"):
            x, y = fa["mcmc"][name][()], fb["mcmc"][name][()]
            if x.shape != y.shape or not np.array_equal(x, y, equal_nan=True):
                return f"{name} differs"
    if (reference / "posterior.csv").read_bytes() != (resumed / "posterior.csv").read_bytes():
        return "posterior.csv differs"
    return ""


# --------------------------------------------------------------------------------------- the battery

SWEEP = """name = "faults"
seed = 5
replicates = 4
[model]
preset = "{holland}"
[run]
n = 20
duration = 3.0
record_interval = 0.5
warmup = 1.0
[[axes]]
key = "perception.field_deg"
values = [60, 120, 180, 240]
"""

CALIBRATION = """name = "faults"
seed = 2
[model]
preset = "{holland}"
[run]
n = 8
duration = 1.5
record_interval = 0.5
warmup = 0.5
[parameters.field]
key = "perception.field_deg"
prior = {{ dist = "uniform", low = 60, high = 300 }}
[targets]
stats = ["polarization", "visible_mean"]
mean = [0.8, 3.0]
sd = [0.05, 0.2]
[method]
kind = "emcee"
n_sim = 5
walkers = 6
steps = 12
"""


def sweep_argv(folder: Path, executor: str = "local") -> list:
    path = folder / "faults.toml"
    if not path.exists():
        path.write_text(SWEEP.format(holland=ROOT / "configs" / "models" / "holland.toml"))
    return ["run", path, "--out", folder / "out", "--executor", executor, "--workers", "2", "--batch-size", "1",
            "--no-progress"]


def calibration_argv(folder: Path) -> list:
    path = folder / "faults.toml"
    if not path.exists():
        path.write_text(CALIBRATION.format(holland=ROOT / "configs" / "models" / "holland.toml"))
    return ["calibrate", path, "--out", folder / "out", "--executor", "local", "--workers", "2", "--no-progress"]


def sweep_ready(folder: Path):
    return lambda: (folder / "out" / "design.parquet").exists()


def calibration_ready(folder: Path):
    return lambda: (folder / "out" / "chain.h5").exists()


def completed_before(kind: str, out: Path, when: float) -> bool:
    """Whether the command had written its final result into ``out`` before the wall-clock time ``when``:
    the sweep's manifest with its finish time, the calibration's report.html. A signal sent after
    that reaches a process that is only exiting: the kernel drops a signal to a process already in
    exit(), so it ends 0 although ``poll()`` said it was running a moment before. Such a trial did not
    interrupt anything."""
    import json

    final = out / ("manifest.json" if kind == "sweep" else "report.html")
    try:
        written = final.stat().st_mtime
        if kind == "sweep" and json.loads(final.read_text()).get("finished") is None:
            return False
    except (OSError, ValueError):
        return False
    return written <= when


def _until_hit(kind: str, folder: Path, reference: Path, how: str, seed: int, window,
               executor: str = "local") -> tuple[Trial, object, str]:
    """Run the trial; when the command had finished before the signal (a busy machine ran it faster than
    the window assumed; or it had written its final result and was exiting, see
    :func:`completed_before`), run it again in a fresh folder with the window halved (at most 3
    attempts)."""
    argv_of, ready_of, same = ((sweep_argv, sweep_ready, same_sweep) if kind == "sweep"
                               else (calibration_argv, calibration_ready, same_chain))
    for attempt in range(3):
        where = folder / f"attempt{attempt}"
        where.mkdir()
        argv = argv_of(where, executor) if kind == "sweep" else argv_of(where)
        trial = kill_trial(argv, where, ready_of(where), how, seed, (window[0] / 2 ** attempt, window[1] / 2 ** attempt))
        if trial.hit and how not in ("worker", "tracker") and completed_before(kind, where / "out", trial.sent_at):
            trial.hit = False
        if trial.hit:
            break
    rerun = run_command(argv, where)
    return trial, rerun, same(reference, where / "out") if rerun.returncode == 0 else rerun.stderr[-300:]


def sweep_trial(folder: Path, reference: Path, how: str, seed: int, window=(0.0, 6.0),
                executor: str = "local") -> tuple[Trial, object, str]:
    """One kill trial of the small sweep in ``folder`` on ``executor`` (local or dask), then the same
    command again; (trial, the rerun, '' or how its results differ from ``reference``)."""
    return _until_hit("sweep", folder, reference, how, seed, window, executor)


def calibration_trial(folder: Path, reference: Path, how: str, seed: int,
                      window=(0.0, 8.0)) -> tuple[Trial, object, str]:
    """As :func:`sweep_trial` for the short calibration (rerun with the same command: no --resume needed)."""
    return _until_hit("calibration", folder, reference, how, seed, window)


# ------------------------------------------------- contained faults: plug-ins, commands, results (issue 42)
#
# Each case is a folder of files and the commands run in it, in order (``python -m flocksweep.cli``, as a
# user runs them), with the exit status and the words each must give; ``between`` damages the folder after
# the first command (as a user's edit would). A case is contained when every command gives its status and
# words, none prints a traceback, and no process the commands started is left running (20 s after each
# ends). :func:`contained_trial` also measures each command's seconds and its peak memory (that of the
# largest process it started, the runner itself unless a worker was larger): the figures
# bench/fault_battery.py reports.

FAULTY_PRESET = """name = "faulty"
dynamics = "{module}"
[perception]
kind = "sphere"
radius = 9.0
[init]
n = 6
[run]
dt = 0.05
duration = 1.0
record_interval = 0.5
"""
FAULTY_SWEEP = """name = "faulty"
seed = 2
[model]
preset = "faulty.toml"
[run]
warmup = 0.5
{run}
[[axes]]
key = "{key}"
values = {values}
"""
LONG_RUN_SWEEP = f"""name = "long"
seed = 3
[model]
preset = "{ROOT / 'configs' / 'models' / 'holland.toml'}"
[run]
record_interval = 0.5
warmup = 0.5
timeout_s = 2
[[axes]]
keys = ["init.n", "run.duration"]
values = [[6, 2.0], [400, 600.0]]
"""
COMMAND_SWEEP = """name = "command"
seed = 5
[model]
command = ["{python}", "{faulty_sim}", "--seed", "{{seed}}", "--out", "{{out}}", "{{params}}"]
timeout_s = 60
[model.parameters]
n_agents = {{ default = 8, bounds = [2, 100], integer = true }}
noise = {{ default = 0.3, bounds = [0.0, 3.0] }}
duration = {{ default = 3.0, bounds = [1.0, 60.0] }}
fault = {{ default = "none", choices = ["none", "flood", "daemon"] }}
[model.tracks]
units = {{ length = "bl" }}
[run]
group_radius = 5.0
warmup = 1.0
[[axes]]
key = "fault"
values = ["{fault}"]
"""
SMALL_SWEEP = f"""name = "small"
seed = 6
[model]
preset = "{ROOT / 'configs' / 'models' / 'holland.toml'}"
[run]
n = 6
duration = 1.0
record_interval = 0.5
warmup = 0.5
[[axes]]
key = "perception.field_deg"
values = [90, 270]
"""


COMMANDS = ("run", "status", "simulate", "calibrate")   # named in a case's problems


@dataclass(frozen=True)
class Contained:
    name: str
    files: dict                # written into the case's folder
    steps: tuple               # ((argv, exit status, words in stdout + stderr), ...), run in order
    between: object = None     # called with the folder after the first step
    env: dict = field(default_factory=dict)
    module: str = "flocksweep.cli"   # what runs the steps (full_disk: flocksweep with a full disk for one file)


def _plugin_files(values: str, run: str = "", module: str = "faulty_plugin", key: str = "plugin.fault") -> dict:
    return {"faulty.toml": FAULTY_PRESET.format(module=module),
            "s.toml": FAULTY_SWEEP.format(values=values, run=run, key=key)}


def _command_files(fault: str) -> dict:
    return {"s.toml": COMMAND_SWEEP.format(python=sys.executable, faulty_sim=ROOT / "tests" / "sweeps" / "faulty_sim.py",
                                           fault=fault)}


def _forge_and_delete_manifest(folder: Path) -> None:
    """A user's edit: a stored value overwritten, then manifest.json deleted so that nothing would check it."""
    path = sorted((folder / "out" / "runs").glob("part-*.parquet"))[0]
    pd.read_parquet(path).assign(cohesion_mean=0.123456789).to_parquet(path, index=False)
    (folder / "out" / "manifest.json").unlink()


RUN = ("run", "s.toml", "--out", "out", "--no-progress")
STATUS = ("status", "out")
CONTAINED = (
    Contained("plug-in: NaN force, --workers 1", _plugin_files("[1]"),
              ((RUN + ("--workers", "1"), 0, "1 runs, 0 ok, 1 failed"),
               (STATUS, 0, "boid 2's velocity became NaN in step 3 (t = 0.15 to 0.2 s)"))),
    Contained("plug-in: out-of-bounds write (SIGSEGV), --workers 1", _plugin_files("[0, 2]"),
              ((RUN + ("--workers", "1"), 0, "2 runs, 1 ok, 1 failed"),
               (STATUS, 0, "TaskCrashed: the run crashed: its process died (killed by SIGSEGV)"))),
    Contained("plug-in: out-of-bounds write (SIGSEGV), serial", _plugin_files("[2]"),
              ((RUN + ("--executor", "serial"), 0, "1 runs, 0 ok, 1 failed"), (STATUS, 0, "killed by SIGSEGV"))),
    Contained("plug-in: out-of-bounds write (SIGSEGV), 2 workers", _plugin_files("[0, 2]"),
              ((RUN + ("--workers", "2"), 0, "2 runs, 1 ok, 1 failed"), (STATUS, 0, "killed by SIGSEGV"))),
    Contained("plug-in: endless loop, run.timeout_s = 3, --workers 1", _plugin_files("[3]", "timeout_s = 3"),
              ((RUN + ("--workers", "1"), 0, "1 runs, 0 ok, 1 failed"),
               (STATUS, 0, "TaskTimedOut: the run was still going after 3 s (run.timeout_s)"))),
    Contained("plug-in: steer does not compile", _plugin_files("[5.0]", module="broken_plugin", key="init.radius"),
              ((RUN, 2, "broken_plugin.py, line 15 (return (nbrs.nonexistent[0], 0.0, 0.0))"),)),
    Contained("simulate: plug-in NaN force", _plugin_files("[1]"),
              ((("simulate", "faulty.toml", "--set", "plugin.fault=1"), 6,
                "the simulation failed: non-finite state: boid 2's velocity became NaN in step 3"),)),
    Contained("simulate: plug-in out-of-bounds write", _plugin_files("[2]"),
              ((("simulate", "faulty.toml", "--set", "plugin.fault=2"), 6, "killed by SIGSEGV"),)),
    Contained("built-in run over run.timeout_s = 2", {"s.toml": LONG_RUN_SWEEP},
              ((RUN + ("--executor", "serial"), 0, "2 runs, 1 ok, 1 failed"),
               (STATUS, 0, "still going after 2 s (run.timeout_s)"))),
    Contained("command: 200 MiB on stderr", _command_files("flood"),
              ((RUN + ("--executor", "serial"), 0, "1 runs, 0 ok, 1 failed"),
               (STATUS, 0, "stderr ends (of 209,715,239 bytes):")), env={"FLOOD_MIB": "200"}),
    Contained("command: a background child of a command that exits 0", _command_files("daemon"),
              ((RUN + ("--executor", "serial"), 0, "1 runs, 1 ok, 0 failed"),)),
    Contained("results: a value edited, then manifest.json deleted", {"s.toml": SMALL_SWEEP},
              ((RUN + ("--executor", "serial"), 0, "2 runs, 2 ok"),
               (STATUS, 0, "manifest.json is missing, so the 1 stored part of runs/ cannot be verified"),
               (RUN + ("--executor", "serial"), 0, "computed 2 now"),
               (("status", "--verify", "out"), 0, "2 runs: 2 done, 0 failed, 0 missing")),
              between=_forge_and_delete_manifest),
)
# a full disk while npe writes posterior.nc (tests/full_disk.py: that one file's writes go to /dev/full): exit
# 4 naming the file, no traceback, no SIGSEGV (HDF5 once wrote it itself and crashed at exit); the test
# (tests/analysis/calibration/test_calibration_faults.py) also reads the accounting kept
FULL_POSTERIOR = ("flocksweep.analysis.calibration.inference", "posterior.nc")
CONTAINED += (
    Contained("npe: a full disk while posterior.nc is written", {"c.toml": NPE_TINY},
              ((FULL_POSTERIOR + ("calibrate", "c.toml", "--out", "out", "--no-progress"), 4,
                "posterior.nc: No space left on device (ENOSPC, errno 28)"),), module="full_disk"),
)
CONTAINED_QUICK = ("plug-in: out-of-bounds write (SIGSEGV), 2 workers", "simulate: plug-in NaN force",
                   "command: 200 MiB on stderr", "command: a background child of a command that exits 0",
                   "results: a value edited, then manifest.json deleted")


@dataclass
class ContainedResult:
    problems: list = field(default_factory=list)    # '' when contained; else what went wrong, one per line
    seconds: list = field(default_factory=list)     # each command's wall time
    peak_mb: list = field(default_factory=list)     # each command's peak resident memory (MB, its largest process)
    orphans: list = field(default_factory=list)


# runs the command as its child and records the peak memory of the largest process it waited for (a
# launcher of its own: a child forked from the big test process would carry that process's memory in
# its ru_maxrss); a command killed by a signal kills the launcher by the same signal
LAUNCHER = """import os, resource, signal, subprocess, sys
code = subprocess.run(sys.argv[2:]).returncode
with open(sys.argv[1], "w") as out:
    out.write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
if code < 0:
    signal.signal(-code, signal.SIG_DFL)
    os.kill(os.getpid(), -code)
sys.exit(code)
"""


def _watched(argv, cwd: Path, env: dict, timeout: float = 900,
             module: str = "flocksweep.cli") -> tuple[int, str, float, float, set]:
    """Run one command: (exit status, stdout + stderr, seconds, the peak memory in MB of the largest
    process it started, every descendant seen while it ran)."""
    out_path, peak_path = cwd / ".contained.out", cwd / ".contained.peak"
    seen: set[int] = set()
    started = time.monotonic()
    with open(out_path, "w") as out:
        proc = subprocess.Popen([sys.executable, "-c", LAUNCHER, str(peak_path), *command(argv, module)], cwd=cwd,
                                stdout=out, stderr=subprocess.STDOUT, env={**environment(), **env},
                                start_new_session=True)
        deadline = started + timeout
        while proc.poll() is None and time.monotonic() < deadline:
            seen |= descendants(proc.pid)
            time.sleep(0.05)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    text = out_path.read_text()
    out_path.unlink()
    peak = float(peak_path.read_text()) / 1024 if peak_path.exists() else float("nan")
    peak_path.unlink(missing_ok=True)
    return proc.returncode, text, time.monotonic() - started, peak, seen


def contained_trial(case: Contained, folder: Path) -> ContainedResult:
    """Run ``case`` in the empty ``folder`` (see the section's comment)."""
    for name, text in case.files.items():
        (folder / name).write_text(text)
    result = ContainedResult()
    for number, (argv, code, words) in enumerate(case.steps):
        status, text, seconds, peak, seen = _watched(argv, folder, case.env, module=case.module)
        result.seconds.append(seconds)
        result.peak_mb.append(peak)
        grace = time.monotonic() + 20
        while any(alive(p) for p in seen) and time.monotonic() < grace:
            time.sleep(0.2)
        result.orphans += sorted(p for p in seen if alive(p))
        said = next((a for a in argv if a in COMMANDS), argv[0])
        if status != code:
            result.problems.append(f"{said}: exit status {status}, expected {code}: {text.strip()[-300:]}")
        if words not in text:
            result.problems.append(f"{said}: {words!r} not said: {text.strip()[-300:]}")
        if "Traceback" in text:
            result.problems.append(f"{said}: a traceback: {text.strip()[-300:]}")
        if number == 0 and case.between is not None:
            case.between(folder)
    if result.orphans:
        result.problems.append(f"processes left behind: {result.orphans}")
        for pid in result.orphans:   # ours: the case started them
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
    return result
