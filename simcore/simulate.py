"""The public entry point: simulate one run (or a batch of replicates) and return its observations.

``simulate(model, init, seed, duration, dt, record_every)`` draws the initial state from the seed
(docs/model.md section 7), runs ``round(duration / dt)`` steps in one compiled call and returns
:class:`Observations` (docs/model.md section 8), recorded at steps 0, k, 2k, ... with k = ``record_every``:

* ``times``      float64 (R,)       seconds
* ``pos``, ``vel`` float64 (R, N, 3)
* ``visible``    int32 (R, N)       neighbours perceived (union of the rule sets)
* ``binocular``  int32 (R, N)       of those, seen by both eyes
* ``pattern``    uint32 (N,)        each boid's pattern (0 outside pattern mode)
* ``leader``     bool (R, N)        leaders at each record (change of leadership)
* ``triggers``   int64 (E, 2)       trigger events (step, boid), in order
* ``final``      :class:`~simcore.state.State` after the last step
* ``predator``, ``prey`` float64 (R, 3) or None: the Boids++ agents' recorded positions (NaN while the
  predator has not appeared); None when the model has no such agent
* ``captures``   int64 (C, 2) or None: first captures (step, boid) by the Boids++ predator, by step then
  boid; None unless ``boidspp.predator.capture_radius`` is set

Every dynamics runs in the same compiled loop (:mod:`simcore.kernel`), compiled per dynamics and
perception kind with that dynamics' hooks (:mod:`simcore.hooks`). ``simulate_batch`` runs several seeds
of one (model, init) on threads, each a call of the same compiled loop (it releases the GIL); each run's
result is bit-identical to ``simulate`` with that seed. ``advance`` steps a given state (tests, tools).

Threads. ``threads`` (``simulate``, ``advance``) splits the boids of each step of one synchronous run
over that many threads (:mod:`simcore.threaded`); by default runs of at least ``THREADED_MIN_N`` boids
use numba's thread count and smaller ones one thread, and sequential runs are always serial (boid i
waits for boid i - 1). Every boid is computed by the same code either way: results are bit-identical
for any thread count. A dynamics whose descriptor says ``THREADS = False`` (``reynolds87``, ``boidspp``) runs
one thread per run (``threads`` does not apply); its batches run in parallel as every dynamics'.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numba
import numpy as np
from numba.core import event as numba_event

from . import hooks, kernel
from .jit import specialise
from .layout import I
from .params import PERCEPTION_KINDS, InitParams, ModelParams, Preset
from .registry import describe
from .rng import run_streams
from .state import FIELDS, State, initial_state
from flocksweep.ticker import Ticker

MODEL_VERSION = "1"  # bump whenever a change alters any trajectory for an unchanged spec
THREADED_MIN_N = 2000  # synchronous runs with this many boids use all of numba's threads by default


@dataclass(frozen=True)
class Observations:
    """What a run recorded, every ``record_every`` steps (R records of N boids; the module docstring lists
    each array's dtype and shape): ``times``, ``pos``, ``vel``, ``visible``, ``binocular``, ``leader``,
    ``triggers``, ``pattern``, the ``final`` state, ``dt`` and ``record_every``."""

    times: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    visible: np.ndarray
    binocular: np.ndarray
    leader: np.ndarray
    triggers: np.ndarray
    pattern: np.ndarray
    final: State
    dt: float
    record_every: int
    predator: np.ndarray | None = None
    prey: np.ndarray | None = None
    captures: np.ndarray | None = None

    @property
    def n(self) -> int:
        return self.pos.shape[1]


_NOTICE_SHOWN = False
_COMPILE_SECONDS = 0.0
COMPILE_ESTIMATE = "usually about a minute on 2 cores, a few minutes on a busy machine"   # bench/RESULTS.md
TICKER_ESTIMATE = "usually about 1 min, longer on a busy machine"   # the same, short enough for one line


def compile_seconds() -> float:
    """Seconds this process has spent compiling run loops (not loading them from the cache)."""
    return _COMPILE_SECONDS


class _CompileNotice(numba_event.Listener):
    """Tells the user on stderr when numba starts compiling a run loop rather than loading it from its
    on-disk cache (the first run after installing or editing simcore, or of a perception kind or
    dynamics not run before; numba signals only real compiles): one line per run loop, with an estimate,
    a :class:`flocksweep.ticker.Ticker` with the time so far while it compiles, and one line when it is
    done, with its time (also counted by :func:`compile_seconds`)."""

    def __init__(self, family: str):
        self.family, self.depth, self.started = family, 0, 0.0
        self.ticker: Ticker | None = None

    def on_start(self, event) -> None:
        global _NOTICE_SHOWN
        self.depth += 1
        if self.depth > 1:   # the run loop's own pieces, compiled inside it
            return
        self.started = time.perf_counter()
        what = "the simulation kernels:" if not _NOTICE_SHOWN else "one more run loop:"
        _NOTICE_SHOWN = True
        print(f"simcore: compiling {what} {self.family} (once, after installing or editing simcore; "
              f"{COMPILE_ESTIMATE}) ...", file=sys.stderr, flush=True)
        self.ticker = Ticker(f"simcore: compiling {self.family.split(' ', 1)[0]}", TICKER_ESTIMATE,
                             under_bars=True).__enter__()

    def on_end(self, event) -> None:
        global _COMPILE_SECONDS
        self.depth -= 1
        if self.depth == 0:
            if self.ticker is not None:
                self.ticker.stop()
                self.ticker = None
            elapsed = time.perf_counter() - self.started
            _COMPILE_SECONDS += elapsed
            print(f"simcore: compiled {self.family} in {elapsed:.0f} s (cached for later runs)",
                  file=sys.stderr, flush=True)


def _compiled_loop(dispatcher, args, params):
    """The compiled specialisation of a run loop for the dynamics and perception kind of ``params`` (its
    last two arguments, compile-time literals: :func:`simcore.jit.specialise`), compiled with the notice;
    call it with ``args`` and those two values (the second element returned)."""
    ip = params[1]
    dynamics, kind = int(ip[I.DYNAMICS]), int(ip[I.PERCEPTION])
    family = (f"{getattr(dispatcher, '__name__', 'run loop')} ({hooks.name_of(dynamics)} dynamics, "
              f"{PERCEPTION_KINDS[kind]} perception)")
    with numba_event.install_listener("numba:compile", _CompileNotice(family)):
        return specialise(dispatcher, (*args, dynamics, kind), 2), (dynamics, kind)


def _run_loop(dispatcher, *args, params) -> None:
    """Call a compiled run loop (:func:`_compiled_loop`) with the compile notice."""
    loop, literals = _compiled_loop(dispatcher, args, params)
    loop(*args, *literals)


def _each_on_threads(task, n: int, threads: int) -> None:
    """``task(b)`` for b in 0..n-1 on up to ``threads`` Python threads (the run loop releases the GIL);
    the first error is raised once every task has ended."""
    threads = max(1, min(n, threads))
    if threads == 1:
        for b in range(n):
            task(b)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(threads, thread_name_prefix="simcore-batch") as pool:
        for future in [pool.submit(task, b) for b in range(n)]:
            future.result()


def _state_group(s: State) -> tuple:
    """The ``state`` group of the run loops (:mod:`simcore.hooks`): the arrays of ``s``, in place."""
    return tuple(getattr(s, f) for f in FIELDS) + (s.agents,)


def _n_steps(duration: float, dt: float) -> int:
    if not (dt > 0 and np.isfinite(dt)):
        raise ValueError(f"dt: got {dt!r}; must be a finite number > 0")
    if not (duration > 0 and np.isfinite(duration)):
        raise ValueError(f"duration: got {duration!r}; must be a finite number > 0")
    return int(round(duration / dt))


def _records(model: ModelParams, n_records: int, n: int, n_events: int, lead: tuple = ()):
    """The ``records`` group of the run loops: (rec_pos, rec_vel, rec_visible, rec_binocular, rec_leader,
    trig_step, trig_boid, n_trig, rec_agents, capture_step); the last two are zero-length unless the
    dynamics has agents (its descriptor's ``AGENTS``, :mod:`simcore.registry`)."""
    agents = describe(model.dynamics).agents
    return (np.zeros(lead + (n_records, n, 3)), np.zeros(lead + (n_records, n, 3)),
            np.zeros(lead + (n_records, n), np.int32), np.zeros(lead + (n_records, n), np.int32),
            np.zeros(lead + (n_records, n), np.bool_), np.zeros(lead + (n_events,), np.int64),
            np.zeros(lead + (n_events,), np.int64), np.zeros(lead + (1,), np.int64),
            np.full(lead + (n_records if agents else 0, 2, 3), np.nan),
            np.full(lead + (n if agents else 0,), -1, np.int64))


def _n_events(model: ModelParams, n: int, n_steps: int, dt: float) -> int:
    if not model.leadership.enabled:
        return 0
    return int(kernel.max_triggers(n, n_steps, model.leadership.duration, dt))


def _observations(model: ModelParams, times, rec, final: State, dt: float, record_every: int) -> Observations:
    pos, vel, visible, binocular, leader, trig_step, trig_boid, n_trig = rec[:8]
    count = int(n_trig[0])
    if count > len(trig_step):
        raise RuntimeError(f"{count} leadership triggers exceed the bound of {len(trig_step)} (kernel bug)")
    triggers = np.stack([trig_step[:count], trig_boid[:count]], axis=1)
    dynamics = describe(model.dynamics)
    agents = dynamics.agent_observations(model, *rec[8:]) if dynamics.agents else {}
    return Observations(times, pos, vel, visible, binocular, leader, triggers, pattern=final.pattern.copy(),
                        final=final, dt=dt, record_every=record_every, **agents)


def _check_record_every(record_every) -> int:
    if isinstance(record_every, bool) or int(record_every) != record_every or record_every < 1:
        raise ValueError(f"record_every: got {record_every!r}; must be an integer >= 1 (steps)")
    return int(record_every)


def _thread_count(model: ModelParams, n: int, threads) -> int:
    """Threads for one run: the request, or the default of the module docstring; 1 for sequential order."""
    if threads is None:
        threads = numba.get_num_threads() if n >= THREADED_MIN_N else 1
    if isinstance(threads, bool) or int(threads) != threads or threads < 1:
        raise ValueError(f"threads: got {threads!r}; must be an integer >= 1 (or None: automatic)")
    sequential = model.world.update_order == "sequential"
    return 1 if sequential or not describe(model.dynamics).threads else int(threads)


def check_planar(model: ModelParams, state: State) -> None:
    """A 2-D model (``world.dimensions = 2``) runs only from a state in the plane z = 0 (ValueError naming
    the first boid off it, e.g. from an ``init.from_file`` state of a 3-D run)."""
    if model.world.dimensions != 2:
        return
    for name in ("pos", "vel", "fwd", "acc"):
        off = np.flatnonzero(getattr(state, name)[:, 2] != 0.0)
        if off.size:
            raise ValueError(f"world.dimensions = 2, but the initial state's {name} of boid {off[0]} has z = "
                             f"{getattr(state, name)[off[0], 2]!r}: a 2-D run starts in the plane z = 0")


def advance(model: ModelParams, state: State, n_steps: int, dt: float, record_every: int = 1,
            key: int = 0, threads: int | None = None) -> Observations:
    """Run ``n_steps`` steps from a copy of ``state``; the input is left untouched. ``key`` is the run's
    key for in-loop draws (leadership); ``threads`` as in the module docstring."""
    record_every = _check_record_every(record_every)
    threads = _thread_count(model, state.n, threads)
    check_planar(model, state)
    s = state.copy()
    params = hooks.pack(model, dt)
    n_records = n_steps // record_every + 1
    rec = _records(model, n_records, s.n, _n_events(model, s.n, n_steps, dt))
    args = (_state_group(s), params, np.uint64(key), n_steps, record_every, rec)
    if threads == 1:
        _run_loop(kernel.run_model, *args, params=params)
    else:
        from .threaded import run_threaded

        previous = numba.get_num_threads()
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        try:
            _run_loop(run_threaded, *args, threads, params=params)
        finally:
            numba.set_num_threads(previous)
    times = np.arange(n_records) * (record_every * dt)
    return _observations(model, times, rec, s, dt, record_every)


def simulate(model: ModelParams, init: InitParams, seed, duration: float, dt: float,
             record_every: int = 1, threads: int | None = None) -> Observations:
    """Simulate one run from its seed (see the module docstring).

    Parameters
    ----------
    model : ModelParams
        The validated model (``preset.model``).
    init : InitParams
        Initial conditions (``preset.init``): the initial state is drawn from the seed.
    seed : int or tuple of int or numpy.random.SeedSequence
        The run seed; the same seed always gives the same run, bit for bit.
    duration : float
        Simulated seconds; the run takes ``round(duration / dt)`` steps.
    dt : float
        Time step in seconds.
    record_every : int, default 1
        Record every this many steps (step 0 included).
    threads : int, optional
        Threads splitting each step's boids (default: numba's count from 2,000 boids, else 1); results
        do not depend on it.

    Returns
    -------
    Observations
        The records (times, positions, velocities, perception counts, leaders, trigger events) and the
        final state.
    """
    n_steps = _n_steps(duration, dt)
    rng, loop_key = run_streams(seed)
    state = initial_state(init, model.patterns, rng, model.world.dimensions)
    return advance(model, state, n_steps, dt, record_every, loop_key, threads)


def simulate_preset(preset: Preset, seed, record_every: int | None = None,
                    threads: int | None = None) -> Observations:
    """:func:`simulate` with the model, initial conditions and run settings of a preset.

    Parameters
    ----------
    preset : Preset
        From :func:`load_preset` (and :meth:`Preset.replace`).
    seed : int or tuple of int or numpy.random.SeedSequence
        The run seed.
    record_every : int, optional
        Steps between records (default: the preset's ``run.record_interval`` in steps).
    threads : int, optional
        As in :func:`simulate`.

    Returns
    -------
    Observations
        The run's records.
    """
    run = preset.run
    every = run.record_every if record_every is None else record_every
    return simulate(preset.model, preset.init, seed, run.duration, run.dt, every, threads)


def placeholder_observations(model: ModelParams, init: InitParams, seed, duration: float, dt: float,
                             record_every: int = 1) -> Observations:
    """What :func:`simulate` would return, in every array's type and shape, without running anything: every
    record holds the initial state drawn from ``seed`` (nobody moves, nothing is perceived, no leaders,
    triggers or captures; the Boids++ agents absent). For work that needs a run's shape and not its
    dynamics, such as compiling the metric kernels in one process while another compiles the run loop
    (:mod:`sweeps.warmup`): this compiles nothing."""
    record_every = _check_record_every(record_every)
    n_steps = _n_steps(duration, dt)
    rng, _ = run_streams(seed)
    state = initial_state(init, model.patterns, rng, model.world.dimensions)
    n_records = n_steps // record_every + 1
    rec = _records(model, n_records, state.n, 0)   # no triggers (counting their bound would compile)
    rec[0][:] = state.pos
    rec[1][:] = state.vel
    times = np.arange(n_records) * (record_every * dt)
    return _observations(model, times, rec, state, dt, record_every)


def simulate_batch(model: ModelParams, init: InitParams, seeds, duration: float, dt: float,
                   record_every: int = 1) -> list[Observations]:
    """Several runs of one (model, init), one per seed, in parallel on numba's thread count.

    Each run is one call of the compiled run loop, which releases the GIL, on a pool of
    ``numba.get_num_threads()`` Python threads (``numba.set_num_threads`` or ``NUMBA_NUM_THREADS``
    limits it). Run ``i`` is bit-identical to ``simulate(model, init, seeds[i], ...)`` whatever the other
    seeds and the thread count.

    Parameters
    ----------
    model : ModelParams
        The model.
    init : InitParams
        Initial conditions.
    seeds : sequence
        One run seed per run.
    duration : float
        Simulated seconds.
    dt : float
        Time step in seconds.
    record_every : int, default 1
        Steps between records.

    Returns
    -------
    list of Observations
        One per seed, in order.
    """
    record_every = _check_record_every(record_every)
    n_steps = _n_steps(duration, dt)
    streams = [run_streams(seed) for seed in seeds]
    states = [initial_state(init, model.patterns, rng, model.world.dimensions) for rng, _ in streams]
    for state in states[:1]:   # every state of a batch comes from the same file or draw
        check_planar(model, state)
    keys = np.array([key for _, key in streams], dtype=np.uint64)
    stacked = {f: np.stack([getattr(s, f) for s in states]) for f in FIELDS}
    agents = np.stack([s.agents for s in states])
    params = hooks.pack(model, dt)
    n_records = n_steps // record_every + 1
    rec = _records(model, n_records, init.n, _n_events(model, init.n, n_steps, dt), (len(states),))
    state_of = [tuple(stacked[f][b] for f in FIELDS) + (agents[b],) for b in range(len(states))]
    records_of = [tuple(r[b] for r in rec) for b in range(len(states))]
    loop, literals = _compiled_loop(kernel.run_model, (state_of[0], params, keys[0], n_steps, record_every,
                                                       records_of[0]), params)

    def run_one(b):
        loop(state_of[b], params, keys[b], n_steps, record_every, records_of[b], *literals)

    _each_on_threads(run_one, len(states), numba.get_num_threads())
    times = np.arange(n_records) * (record_every * dt)
    return [_observations(model, times, tuple(r[b] for r in rec),
                          State(**{f: stacked[f][b] for f in FIELDS}, agents=agents[b]), dt, record_every)
            for b in range(len(states))]
