"""The hooks of a dynamics, chosen at compile time: the one place the run loops learn what a dynamics does.

A dynamics is one module (``simcore/opensteer.py``, ``hartman_benes.py``, ``reynolds87.py``,
``boidspp.py``, ``couzin2002.py``, ``vicsek.py``), registered in ``MODULES`` below under its ``DYNAMICS_*``
number (its position in :data:`simcore.params.DYNAMICS`). The run loops of :mod:`simcore.kernel` and :mod:`simcore.threaded` take
the dynamics as a compile-time literal (``numba.literally``, as the perception kind, :mod:`simcore.jit`)
and call the stubs below with it as first argument; numba's typing of a stub gives that dynamics' own
function, so a run compiles only its dynamics. The groups the hooks receive (plain tuples of arrays,
fixed compositions, so that the parallel loops can take them apart and rebuild them):

* ``state``   = (pos, vel, fwd, up, side, acc, pattern, clock, escape, agents) (:mod:`simcore.state`)
* ``params``  = (fp, ip, dyn): the shared slots (:mod:`simcore.layout`) and the dynamics' own 5 arrays
  ``dyn`` = (dfp float64 (K,), dip int64 (L,), obstacle table, obstacle kinds, ray fan), from its
  ``pack(model, dt)`` (unused ones empty)
* ``records`` = (rec_pos, rec_vel, rec_visible, rec_binocular, rec_leader, trig_step, trig_boid, n_trig,
  rec_agents, capture_step) (:func:`simcore.simulate._records`)
* ``scratch`` = (per_boid float64 (N, W), shared float64 (S, 3)): the dynamics' own buffers, from its
  ``scratch(dynamics, n)``; ``per_boid[i]`` is what boid i's ``sense`` leaves for its ``move``

Hooks of a dynamics module (each a plain Python function; numba compiles it as a leaf, :mod:`simcore.jit`,
except ``scratch``, which allocates):

* required: ``pack(model, dt) -> dyn`` (Python), ``scratch(dynamics, n)``,
  ``sense(dynamics, i, step, m, nbrs, state, params, key, scratch) -> triggered`` (boid i from its m
  perceived neighbours ``nbrs``; True when a leadership trigger fired) and
  ``move(dynamics, i, state, params, scratch)``;
* optional (default: nothing): ``begin_step(dynamics, step, state, params, key)`` (first thing of every
  step, before its record), ``record_extra(dynamics, r, state, records)`` (with the state record r),
  ``before_boids(dynamics, step, state, params, key, scratch, records)`` (after the record, before any
  boid perceives) and ``after_boids(dynamics, step, state, params, key, scratch)`` (after every boid moved);
* ``THREADS`` (Python): whether a synchronous run of this dynamics is split over threads
  (:mod:`simcore.threaded`); without it, one thread per run.

A plug-in dynamics (:mod:`simcore.plugin`: a user's module named in a preset) is not in ``MODULES``: its
number (from ``PLUGIN_BASE`` on) chooses the hooks of :mod:`simcore.plugin_hooks`, which call its own
function.
"""
from __future__ import annotations

import inspect

from numba import types
from numba.extending import overload

from . import boidspp, couzin2002, hartman_benes, opensteer, reynolds87, vicsek
from . import plugin_hooks
from .jit import COMPILED_ONLY, KERNEL_OPTIONS, LEAF_OPTIONS
from .layout import (DYNAMICS_BOIDSPP, DYNAMICS_COUZIN2002, DYNAMICS_HARTMAN_BENES, DYNAMICS_OPENSTEER,
                     DYNAMICS_REYNOLDS87, DYNAMICS_VICSEK)
from .params import DYNAMICS
from .plugin import BY_NUMBER

MODULES = {DYNAMICS_OPENSTEER: opensteer, DYNAMICS_HARTMAN_BENES: hartman_benes,
           DYNAMICS_REYNOLDS87: reynolds87, DYNAMICS_BOIDSPP: boidspp, DYNAMICS_COUZIN2002: couzin2002,
           DYNAMICS_VICSEK: vicsek}
assert sorted(MODULES) == list(range(len(DYNAMICS)))


def module_of(dynamics: str):
    """The module of a dynamics named as in presets (``model.dynamics``; a plug-in's: plugin_hooks)."""
    return MODULES[DYNAMICS.index(dynamics)] if dynamics in DYNAMICS else plugin_hooks


def name_of(number: int) -> str:
    """The name presets give the dynamics of run-loop literal ``number``."""
    return DYNAMICS[number] if number in MODULES else BY_NUMBER[number].name


def pack(model, dt):
    """``params`` = (fp, ip, dyn) of a validated model (module docstring)."""
    from .layout import pack as pack_shared

    fp, ip = pack_shared(model, dt)
    return fp, ip, tuple(module_of(model.dynamics).pack(model, dt))


# the stubs: in compiled code, numba's typing of each one (below) gives the literal dynamics' function;
# their Python bodies only say so when called from Python (COMPILED_ONLY)

def scratch(dynamics, n):
    raise TypeError(COMPILED_ONLY)


def begin_step(dynamics, step, state, params, key):
    raise TypeError(COMPILED_ONLY)


def record_extra(dynamics, r, state, records):
    raise TypeError(COMPILED_ONLY)


def before_boids(dynamics, step, state, params, key, scratch, records):
    raise TypeError(COMPILED_ONLY)


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    raise TypeError(COMPILED_ONLY)


def move(dynamics, i, state, params, scratch):
    raise TypeError(COMPILED_ONLY)


def after_boids(dynamics, step, state, params, key, scratch):
    raise TypeError(COMPILED_ONLY)


# the defaults of the optional hooks (a dynamics without per-step work)

def no_begin_step(dynamics, step, state, params, key):
    pass


def no_record_extra(dynamics, r, state, records):
    pass


def no_before_boids(dynamics, step, state, params, key, scratch, records):
    pass


def no_after_boids(dynamics, step, state, params, key, scratch):
    pass


OPTIONAL = {"begin_step": no_begin_step, "record_extra": no_record_extra, "before_boids": no_before_boids,
            "after_boids": no_after_boids}


def _choose(name, dynamics):
    """numba's typing of hook ``name``: with a literal dynamics, its module's function (or the optional
    hook's default); otherwise none (numba's typing error names the hook and the argument types)."""
    if isinstance(dynamics, types.IntegerLiteral) and dynamics.literal_value in MODULES:
        return getattr(MODULES[dynamics.literal_value], name, OPTIONAL.get(name))
    if isinstance(dynamics, types.IntegerLiteral) and dynamics.literal_value in BY_NUMBER:
        return getattr(plugin_hooks, name, OPTIONAL.get(name))
    return None


def _register(stub, jit_options):
    """Register numba's typing of ``stub`` (a typing function must have the stub's own signature)."""
    arguments = ", ".join(inspect.signature(stub).parameters)
    namespace = {"_choose": _choose}
    exec(f"def typing({arguments}):\n    return _choose({stub.__name__!r}, dynamics)\n", namespace)
    overload(stub, jit_options=jit_options, prefer_literal=True)(namespace["typing"])


_register(scratch, KERNEL_OPTIONS)
for _stub in (begin_step, record_extra, before_boids, sense, move, after_boids):
    _register(_stub, LEAF_OPTIONS)
