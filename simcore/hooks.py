"""The hooks of a dynamics, chosen at compile time: the one place the run loops learn what a dynamics does.

A dynamics' hooks are one module (``simcore/opensteer.py``, ``vicsek.py``, ...; a plug-in's own module),
named by its descriptor in the registry (:mod:`simcore.registry`), which also gives its number: a
built-in's position there, a plug-in's from ``PLUGIN_BASE`` on. The run loops of :mod:`simcore.kernel` and
:mod:`simcore.threaded` take the dynamics as a compile-time literal (``numba.literally``, as the perception
kind, :mod:`simcore.jit`) and call the stubs below with it as first argument; numba's typing of a stub
gives that dynamics' own function, so a run compiles (and imports) only its dynamics. The groups the hooks
receive (plain tuples of arrays, fixed compositions, so that the parallel loops can take them apart and
rebuild them):

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
Whether a synchronous run of a dynamics may split over threads is its descriptor's ``THREADS``
(:mod:`simcore.simulate`). A plug-in that defines only ``steer`` runs through the hooks of
:mod:`simcore.plugin_hooks`; one with the full hook set is reached through the same module's adapters,
which compile its functions without a cache of their own (they live on in the run loop's cached code).
"""
from __future__ import annotations

import inspect

from numba import types
from numba.extending import overload

from . import registry
from .jit import COMPILED_ONLY, KERNEL_OPTIONS, LEAF_OPTIONS


def module_of(dynamics: str):
    """The hooks module the run loops use for a dynamics named as in presets (``model.dynamics``; every
    plug-in's: :mod:`simcore.plugin_hooks`)."""
    return _hooks_of(registry.describe(dynamics))


def name_of(number: int) -> str:
    """The name presets give the dynamics of run-loop literal ``number``."""
    return registry.by_number(number).name


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
    """numba's typing of hook ``name``: with a literal dynamics, its hooks module's function (or the
    optional hook's default); otherwise none (numba's typing error names the hook and the argument types)."""
    if not isinstance(dynamics, types.IntegerLiteral):
        return None
    try:
        described = registry.by_number(dynamics.literal_value)
    except (KeyError, IndexError):
        return None
    return getattr(_hooks_of(described), name, OPTIONAL.get(name))


def _hooks_of(described):
    """A built-in's hooks module; for every plug-in, :mod:`simcore.plugin_hooks` (whose adapters reach the
    plug-in's own functions, compiled without a cache)."""
    if described.builtin:
        return described.hooks()
    from . import plugin_hooks

    return plugin_hooks


def _register(stub, jit_options):
    """Register numba's typing of ``stub`` (a typing function must have the stub's own signature)."""
    arguments = ", ".join(inspect.signature(stub).parameters)
    namespace = {"_choose": _choose}
    exec(f"def typing({arguments}):\n    return _choose({stub.__name__!r}, dynamics)\n", namespace)
    overload(stub, jit_options=jit_options, prefer_literal=True)(namespace["typing"])


_register(scratch, KERNEL_OPTIONS)
for _stub in (begin_step, record_extra, before_boids, sense, move, after_boids):
    _register(_stub, LEAF_OPTIONS)
