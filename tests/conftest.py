"""Shared helpers for the simcore tests: model builders and hand-made states; for a run split over
workers (``pytest -n K``), every kernel compiled once before the workers start; and the suite's hygiene:
every test closes the matplotlib figures it opens and ends the processes it starts (checked after each
test, so the suite passes the same run serially, split over workers or in any order).

Only builders and the hygiene checks live here; every other assertion is in the test modules.
"""
from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from flocksweep.simcore import State
from flocksweep.simcore.opensteer_params import Steering
from flocksweep.simcore.params import HOLLAND_TABLE_1, ModelParams, Patterns, Perception, Vehicle, World
from flocksweep.simcore.state import frame_from_forward

# test modules import these helpers and tests/reference.py by module name, whatever pytest's import mode
sys.path.insert(0, str(Path(__file__).resolve().parent))


def _drop_stale_test_kernels() -> None:
    """Test modules compile their own ``numba.njit(cache=True)`` helpers that inline simcore's (slots,
    noise draws, ...); numba checks only the test file's timestamp, so after an edit of simcore a cached
    helper would still hold the old code. Clear the tests' cached kernels whenever simcore's sources or
    the tests' own differ from the last run (as ``simcore/_cache.py`` does for simcore)."""
    import hashlib

    import flocksweep.simcore as simcore
    from flocksweep.simcore._cache import STAMP, sources_digest

    tests = Path(__file__).resolve().parent
    digest = hashlib.sha256(sources_digest(Path(simcore.__file__).parent).encode())
    folders = sorted({path.parent for path in tests.rglob("*.py")})
    for folder in folders:
        digest.update(sources_digest(folder).encode())
    stamp = tests / "__pycache__" / STAMP
    try:
        if stamp.exists() and stamp.read_text().strip() == digest.hexdigest():
            return
        for folder in folders:
            for cached in list(folder.glob("__pycache__/*.nbi")) + list(folder.glob("__pycache__/*.nbc")):
                cached.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(digest.hexdigest())
    except OSError:
        pass


_drop_stale_test_kernels()
# what flocksweep remembers between commands (status's last full check) goes to a folder of this run,
# never the user's cache (also for the commands tests start as subprocesses)
if "FLOCKSWEEP_CACHE_DIR" not in os.environ:
    os.environ["FLOCKSWEEP_CACHE_DIR"] = tempfile.mkdtemp(prefix="flocksweep-test-cache-")
    atexit.register(shutil.rmtree, os.environ["FLOCKSWEEP_CACHE_DIR"], ignore_errors=True)
# the npe tests compile the same small flows again and again (each calibrate command a new process, each
# train_flow its own closures): XLA's compiled programs go to one folder of this run, shared by the
# workers and the commands they start, so a program is compiled once per run. A cached program is the
# one XLA would compile again (the cache is keyed on the program and the compiler's options), so results
# stay bit for bit those of a fresh compile. Every program, however quick to compile, is kept. A
# JAX_COMPILATION_CACHE_DIR set by the caller is used instead (kept between test runs). flocksweep's own
# cache (analysis/calibration/jax_cache.py, ~/.cache/flocksweep/jax) defers to JAX_COMPILATION_CACHE_DIR, so
# no test, nor any command a test starts, writes into the user's cache.
if "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="flocksweep-test-jax-")
    atexit.register(shutil.rmtree, os.environ["JAX_COMPILATION_CACHE_DIR"], ignore_errors=True)
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES", "0")

TABLE_1_VALUES = np.array([p.value for p in HOLLAND_TABLE_1], dtype=np.uint32)


def make_model(kind="opensteer", *, boundary="open", order="synchronous", sphere_radius=50.0,
               box_size=100.0, patterns=None, steering=None, vehicle=None, **perception) -> ModelParams:
    """ModelParams with the given perception kind/keys, world and (optional) pattern separation weight.

    ``patterns`` is None (pattern mode off) or one of the separation_weight options."""
    pat = Patterns() if patterns is None else Patterns(enabled=True, separation_weight=patterns)
    return ModelParams(
        perception=Perception(kind=kind, **perception),
        steering=steering or Steering(),
        vehicle=vehicle or Vehicle(),
        world=World(boundary=boundary, sphere_radius=sphere_radius, box_size=box_size, update_order=order),
        patterns=pat,
    )


def unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def state_from(pos, fwd, speed, acc=None, pattern=None) -> State:
    """State with headings ``fwd`` (unit), velocities speed * fwd and the canonical frame."""
    pos = np.array(pos, dtype=np.float64)
    fwd = np.array(fwd, dtype=np.float64)
    n = len(pos)
    up, side = frame_from_forward(fwd)
    speed = np.broadcast_to(np.asarray(speed, dtype=np.float64), (n,))
    acc = np.zeros((n, 3)) if acc is None else np.array(acc, dtype=np.float64)
    pattern = np.zeros(n, np.uint32) if pattern is None else np.asarray(pattern, dtype=np.uint32)
    return State(pos=pos, vel=fwd * speed[:, None], fwd=fwd, up=up, side=side, acc=acc, pattern=pattern)


def flock_state(seed: int, n: int = 24, *, ball_radius: float = 4.0, box_size: float | None = None,
                max_speed: float = 9.0) -> State:
    """A random but flock-like state: boids close enough to see each other, random headings, varied speeds.

    Positions are uniform in a ball of ``ball_radius`` (or, with ``box_size``, uniform in the periodic box
    [-L/2, L/2)^3). A quarter of the boids are slower than 0.2 max_speed (one of them stopped) so the
    low-speed cone clamp acts; the rest fly at 0.3..1 max_speed. The smoothed acceleration is non-zero and
    patterns are drawn from Holland's Table 1.
    """
    rng = np.random.default_rng(seed)
    if box_size is None:
        radius = ball_radius * rng.random(n) ** (1.0 / 3.0)
        pos = unit_vectors(rng, n) * radius[:, None]
    else:
        pos = rng.uniform(-box_size / 2, box_size / 2, (n, 3))
    fwd = unit_vectors(rng, n)
    speed = rng.uniform(0.3, 1.0, n) * max_speed
    n_slow = max(2, n // 4)
    speed[:n_slow] = rng.uniform(0.0, 0.2, n_slow) * max_speed
    speed[0] = 0.0
    acc = rng.normal(scale=4.0, size=(n, 3))
    pattern = rng.choice(TABLE_1_VALUES, n)
    return state_from(pos, fwd, speed, acc, pattern)


def pytest_sessionstart(session):
    """``pytest -n K``: compile every kernel of the shipped presets into numba's cache once, in two processes,
    before the workers start (xdist starts them after this hook), so that workers load kernels rather than
    each compiling the same ones at the same time (``flocksweep compile``, sweeps/compile.py). Tests that
    need an empty cache use their own. A failure here is only reported: the tests that need the kernel fail
    with the real error."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    from flocksweep.sweeps.compile import compile_kernels

    reporter = config.pluginmanager.get_plugin("terminalreporter")
    say = reporter.write_line if reporter is not None else print
    say("compiling the kernels of the shipped presets before the workers start (flocksweep compile) ...")
    ticker = compile_ticker(reporter)
    try:
        results = compile_kernels(jobs=2, report=ticker.say, ticker=ticker)
    except Exception as err:  # noqa: BLE001 - reported; the tests show the real failure
        say(f"  compile failed: {type(err).__name__}: {err}")
        return
    say(f"  {sum(r.compiled for r in results)} kernels compiled")


def compile_ticker(reporter):
    """The compile step's ticker, written through pytest's terminal reporter (stderr is captured while the
    session starts): on a terminal one line rewritten every second, otherwise a line every 20 s."""
    from flocksweep.sweeps.compile_command import ESTIMATE
    from flocksweep.sweeps.progress import Ticker

    if reporter is None:
        return Ticker("compiling", ESTIMATE, line=print)
    rewrite = clear = None
    if reporter.isatty:
        rewrite = lambda text: reporter.rewrite(text, erase=True)   # noqa: E731
        clear = lambda: (reporter.rewrite("", erase=True), reporter.write("\r", flush=True))   # noqa: E731
    return Ticker("compiling", ESTIMATE, line=reporter.write_line, rewrite=rewrite, clear=clear,
                  output=reporter.write_line)


# --- hygiene: what a test opens, it closes ---------------------------------------------------------------

def _child_pids() -> list[int]:
    """The pids of this process's children: each thread's /proc/self/task/T/children (a read of a few
    files, not a scan of every process); a scan of /proc where the kernel lacks those files."""
    me = os.getpid()
    try:
        pids = []
        for task in os.listdir(f"/proc/{me}/task"):
            with open(f"/proc/{me}/task/{task}/children") as listed:
                pids += [int(pid) for pid in listed.read().split()]
        return pids
    except (OSError, ValueError):
        pass
    pids = []
    for entry in Path("/proc").glob("[0-9]*"):
        try:
            if int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1]) == me:
                pids.append(int(entry.name))
        except (OSError, ValueError, IndexError):
            continue
    return pids


def _child_processes() -> dict[int, str]:
    """This process's live children (pid -> command line); zombies (ended, not yet reaped) do not
    count. Empty where /proc is missing."""
    children = {}
    for pid in _child_pids():
        try:
            if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in "ZX":
                continue
            command = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except (OSError, IndexError):
            continue
        children[pid] = command.strip()
    return children


# children that outlive a test by design: multiprocessing's resource tracker, one per process, started by
# the first pool and kept for the session
SESSION_HELPERS = ("multiprocessing.resource_tracker",)
PROCESS_GRACE_S = 20.0   # a stopped pool's workers are given this long to exit (they are not waited for)


def _leftover_children(before: set[int]) -> dict[int, str]:
    import time

    deadline = time.monotonic() + PROCESS_GRACE_S
    while True:
        left = {pid: command for pid, command in _child_processes().items()
                if pid not in before and not any(helper in command for helper in SESSION_HELPERS)}
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.1)


@pytest.fixture(autouse=True)
def closes_what_it_opens(request):
    """Fails the test (an error at its teardown) that leaves a matplotlib figure open, a child process
    running or dask's global scheduler set, then closes, kills or resets what it left, so that no other test
    inherits it (a figure left open by one module used to fail another's teardown when the suite ran in one
    process; a dask scheduler left set by a client that failed to start failed every later calibration's
    posterior.nc in that worker)."""
    dask_scheduler_before = _dask_scheduler()
    plt = sys.modules.get("matplotlib.pyplot")
    figures_before = set(plt.get_fignums()) if plt is not None else set()
    children_before = set(_child_processes())
    yield
    problems = []
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        left_open = sorted(set(plt.get_fignums()) - figures_before)
        for number in left_open:
            plt.close(number)
        if left_open:
            problems.append(f"left {len(left_open)} matplotlib figure(s) open (close them: plt.close(fig))")
    left_running = _leftover_children(children_before)
    for pid in left_running:
        try:
            os.kill(pid, 9)
        except OSError:
            pass
    if left_running:
        problems.append("left child processes running: " + "; ".join(f"{pid} {command[:120]}"
                                                                       for pid, command in left_running.items()))
    dask_scheduler = _dask_scheduler()
    if dask_scheduler != dask_scheduler_before:
        sys.modules["dask"].config.config.pop("scheduler", None)
        problems.append(f"left dask's global scheduler set to {dask_scheduler!r} (close the client it made)")
    if problems:
        pytest.fail(f"{request.node.nodeid}: " + " and ".join(problems), pytrace=False)


def _dask_scheduler():
    """dask's global ``scheduler`` setting, None when unset or dask not imported."""
    dask = sys.modules.get("dask")
    config = getattr(dask, "config", None)
    return config.get("scheduler", None) if config is not None else None
