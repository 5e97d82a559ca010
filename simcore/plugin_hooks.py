"""The run-loop hooks (:mod:`simcore.hooks`) of every plug-in dynamics (:mod:`simcore.plugin`, docs/plugins.md).

``sense`` calls the plug-in's ``steer`` for boid i and stores its raw steering force in the per-boid
buffer, in the columns the ``opensteer`` dynamics uses; ``scratch`` and ``move`` are that dynamics' own
(:mod:`simcore.opensteer`: the OpenSteer vehicle physics of ``[vehicle]``,
:func:`simcore.dynamics.apply_steering`; without leadership there is no escape). ``pack`` puts the
plug-in's parameters, in field order, in the ``dyn`` group's float slots (``p``). A plug-in has no change
of leadership: ``sense`` never triggers. The shared intrinsic noise and cruise speed (:mod:`simcore.noise`,
``[noise]``, ``[cruise]``) act as under ``opensteer``: ``sense`` stores the boid's draws, ``move`` uses them.

The plug-in's function is reached through :func:`plugin_steer`, a stub whose numba typing gives, for the
literal dynamics number of a loaded plug-in, that plug-in's ``steer`` (compiled as a leaf without a cache
of its own, :mod:`simcore.plugin`). The hooks here are compiled once per plug-in number, as every
dynamics' hooks are per dynamics. ``THREADS``: ``steer`` writes nothing, so a synchronous run splits over
threads (:mod:`simcore.threaded`) with bit-identical results.
"""
from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.extending import overload

from .jit import COMPILED_ONLY, LEAF_OPTIONS
from .layout import I, OS
from .noise import store_draws
from .opensteer import DRAWS_AT, move, scratch  # noqa: F401 (hooks: the force in OpenSteer's columns, moved as OpenSteer's)
from .plugin import BY_NUMBER, load

THREADS = True
STEER_OPTIONS = {key: value for key, value in LEAF_OPTIONS.items() if key != "cache"}


def pack(model, dt):
    values = load(model.dynamics).values(model.plugin)
    return (np.array(values, np.float64), np.zeros(0, np.int64), np.zeros((0, 1)), np.zeros(0, np.int64),
            np.zeros((0, 3)))


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    fp, ip, dyn = params
    force = scratch[0]
    force[i, OS.FX], force[i, OS.FY], force[i, OS.FZ] = plugin_steer(dynamics, i, step, m, nbrs, state, fp, ip,
                                                                     dyn[0], key)
    if ip[I.DRIVE] != 0:   # [noise] and [cruise] act in OpenSteer's move, on the draws stored here
        store_draws(force, i, DRAWS_AT, key, step)
    return False


def plugin_steer(dynamics, i, step, m, nbrs, state, fp, ip, p, key):
    raise TypeError(COMPILED_ONLY)


_COMPILED: dict[int, object] = {}


def _adapter(number):
    """The implementation of :func:`plugin_steer` for plug-in ``number``: its ``steer``, compiled once."""
    if number not in _COMPILED:
        steer = numba.njit(**STEER_OPTIONS)(BY_NUMBER[number].module.steer)

        def call(dynamics, i, step, m, nbrs, state, fp, ip, p, key):
            return steer(i, step, m, nbrs, state, fp, ip, p, key)

        _COMPILED[number] = call
    return _COMPILED[number]


@overload(plugin_steer, jit_options=STEER_OPTIONS, prefer_literal=True)
def _plugin_steer_typing(dynamics, i, step, m, nbrs, state, fp, ip, p, key):
    if isinstance(dynamics, types.IntegerLiteral) and dynamics.literal_value in BY_NUMBER:
        return _adapter(dynamics.literal_value)
    return None
