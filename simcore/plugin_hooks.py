"""The run-loop hooks (:mod:`simcore.hooks`) of every plug-in dynamics (:mod:`simcore.plugin`, docs/plugins.md).

A plug-in defines either the full hook set of a dynamics (``scratch``, ``sense``, ``move`` and, when it
wants them, ``begin_step``, ``record_extra``, ``before_boids``, ``after_boids`` and a Python ``pack``), with
the contract of :mod:`simcore.hooks`, or only the convenience ``steer``. Each hook here calls an adapter
stub (``plugin_<hook>``) whose numba typing gives, for the literal dynamics number of a loaded plug-in,
that plug-in's own function (compiled without a cache of its own, :mod:`simcore.plugin`: it lives on in
the run loop's cached code), or, when the plug-in does not define that hook, the convenience one below.
The hooks here are compiled once per plug-in number, as every dynamics' hooks are per dynamics.

The convenience hooks of a ``steer`` plug-in: ``sense`` calls its ``steer`` for boid i and stores its raw
steering force in the per-boid buffer, in the columns the ``opensteer`` dynamics uses; ``scratch`` and
``move`` are that dynamics' own (:mod:`simcore.opensteer`: the OpenSteer vehicle physics of ``[vehicle]``,
:func:`simcore.dynamics.apply_steering`; without leadership there is no escape). ``pack`` puts the
plug-in's parameters, in field order, in the ``dyn`` group's float slots (``p``, ``dyn[0]``) unless the
plug-in packs its own. A plug-in has no change of leadership unless it says so: the convenience ``sense``
never triggers. The shared intrinsic noise and cruise speed (:mod:`simcore.noise`, ``[noise]``,
``[cruise]``) act as under ``opensteer``: ``sense`` stores the boid's draws, ``move`` uses them.
"""
from __future__ import annotations

import inspect

import numba
import numpy as np
from numba import types
from numba.extending import overload

from . import opensteer
from .jit import COMPILED_ONLY, KERNEL_OPTIONS, LEAF_OPTIONS
from .layout import I, OS
from .noise import store_draws
from .opensteer import DRAWS_AT
from .plugin import BY_NUMBER, load

STEER_OPTIONS = {key: value for key, value in LEAF_OPTIONS.items() if key != "cache"}
SCRATCH_OPTIONS = {key: value for key, value in KERNEL_OPTIONS.items() if key != "cache"}


def pack(model, dt):
    plugin = load(model.dynamics)
    own = getattr(plugin.module, "pack", None)
    if callable(own):
        return tuple(own(model, dt))
    return (np.array(plugin.values(model.plugin), np.float64), np.zeros(0, np.int64), np.zeros((0, 1)),
            np.zeros(0, np.int64), np.zeros((0, 3)))


# the convenience hooks of a plug-in that defines only ``steer``

def steer_sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    fp, ip, dyn = params
    force = scratch[0]
    force[i, OS.FX], force[i, OS.FY], force[i, OS.FZ] = plugin_steer(dynamics, i, step, m, nbrs, state, fp, ip,
                                                                     dyn[0], key)
    if ip[I.DRIVE] != 0:   # [noise] and [cruise] act in OpenSteer's move, on the draws stored here
        store_draws(force, i, DRAWS_AT, key, step)
    return False


def no_begin_step(dynamics, step, state, params, key):
    pass


def no_record_extra(dynamics, r, state, records):
    pass


def no_before_boids(dynamics, step, state, params, key, scratch, records):
    pass


def no_after_boids(dynamics, step, state, params, key, scratch):
    pass


CONVENIENCE = {"scratch": opensteer.scratch, "sense": steer_sense, "move": opensteer.move,
               "begin_step": no_begin_step, "record_extra": no_record_extra, "before_boids": no_before_boids,
               "after_boids": no_after_boids}


# the hooks the run loops call (hooks._choose gives these for every plug-in number); each forwards to
# its adapter stub, typed per plug-in below

def scratch(dynamics, n):
    return plugin_scratch(dynamics, n)


def begin_step(dynamics, step, state, params, key):
    plugin_begin_step(dynamics, step, state, params, key)


def record_extra(dynamics, r, state, records):
    plugin_record_extra(dynamics, r, state, records)


def before_boids(dynamics, step, state, params, key, scratch, records):
    plugin_before_boids(dynamics, step, state, params, key, scratch, records)


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    return plugin_sense(dynamics, i, step, m, nbrs, state, params, key, scratch)


def move(dynamics, i, state, params, scratch):
    plugin_move(dynamics, i, state, params, scratch)


def after_boids(dynamics, step, state, params, key, scratch):
    plugin_after_boids(dynamics, step, state, params, key, scratch)


# the adapter stubs

def plugin_scratch(dynamics, n):
    raise TypeError(COMPILED_ONLY)


def plugin_begin_step(dynamics, step, state, params, key):
    raise TypeError(COMPILED_ONLY)


def plugin_record_extra(dynamics, r, state, records):
    raise TypeError(COMPILED_ONLY)


def plugin_before_boids(dynamics, step, state, params, key, scratch, records):
    raise TypeError(COMPILED_ONLY)


def plugin_sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    raise TypeError(COMPILED_ONLY)


def plugin_move(dynamics, i, state, params, scratch):
    raise TypeError(COMPILED_ONLY)


def plugin_after_boids(dynamics, step, state, params, key, scratch):
    raise TypeError(COMPILED_ONLY)


def plugin_steer(dynamics, i, step, m, nbrs, state, fp, ip, p, key):
    raise TypeError(COMPILED_ONLY)


_COMPILED: dict[tuple[int, str], object] = {}


def _own(number: int, hook: str, options: dict):
    """Plug-in ``number``'s own ``hook`` compiled once without a cache (None when it defines none)."""
    if (number, hook) not in _COMPILED:
        function = getattr(BY_NUMBER[number].module, hook, None)
        _COMPILED[number, hook] = numba.njit(**options)(function) if callable(function) else None
    return _COMPILED[number, hook]


def _implementation(hook: str, options: dict, dynamics):
    """numba's typing of adapter ``plugin_<hook>``: the literal plug-in's own function, else the convenience."""
    if not (isinstance(dynamics, types.IntegerLiteral) and dynamics.literal_value in BY_NUMBER):
        return None
    own = _own(dynamics.literal_value, hook, options)
    if own is None:
        return CONVENIENCE[hook]
    return _forward(own, hook)


_FORWARDS: dict[tuple[int, str], object] = {}


def _forward(compiled, hook: str):
    """An implementation with the adapter's signature that calls ``compiled`` with the same arguments
    (``steer`` takes them without ``dynamics``)."""
    if (id(compiled), hook) not in _FORWARDS:
        arguments = list(inspect.signature(globals()[f"plugin_{hook}"]).parameters)
        passed = arguments[1:] if hook == "steer" else arguments
        namespace = {"compiled": compiled}
        exec(f"def call({', '.join(arguments)}):\n    return compiled({', '.join(passed)})\n", namespace)
        _FORWARDS[id(compiled), hook] = namespace["call"]
    return _FORWARDS[id(compiled), hook]


def _register(stub, hook: str, options: dict):
    """Register numba's typing of adapter ``stub`` (a typing function must have the stub's own signature)."""
    arguments = ", ".join(inspect.signature(stub).parameters)
    namespace = {"_implementation": _implementation, "hook": hook, "options": options}
    exec(f"def typing({arguments}):\n    return _implementation(hook, options, dynamics)\n", namespace)
    overload(stub, jit_options=options, prefer_literal=True)(namespace["typing"])


_register(plugin_scratch, "scratch", SCRATCH_OPTIONS)
for _hook in ("begin_step", "record_extra", "before_boids", "sense", "move", "after_boids", "steer"):
    _register(globals()[f"plugin_{_hook}"], _hook, STEER_OPTIONS)
