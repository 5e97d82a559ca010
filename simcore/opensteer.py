"""The ``opensteer`` dynamics as run-loop hooks (:mod:`simcore.hooks`): OpenSteer steering (docs/model.md
sections 3.1-3.3, :mod:`simcore.rules`) and vehicle physics (section 3.4, :mod:`simcore.dynamics`), with
the change of leadership (section 5.4, :mod:`simcore.leadership`).

``sense`` stores boid i's raw steering force in its ``OS`` columns of the per-boid buffer (and, with
leadership, decides its trigger from its cohesion offset); ``move`` applies the vehicle physics with that
force (plus a leader's escape), driven by cruise and noise when on (:mod:`simcore.noise`: ``sense`` stores
the boid's draws after its force). The shared slots ``fp``/``ip`` hold every parameter: its own group
``dyn`` is empty.
"""
from __future__ import annotations

import numpy as np

from .dynamics import apply_steering
from .layout import I, OS
from .leadership import escape_of, sense_trigger
from .noise import DRAWS, store_draws
from .rules import cohesion_offset, opensteer_force

DRAWS_AT = len(OS)  # the first column of the noise draws
WIDTH = DRAWS_AT + DRAWS  # per-boid scratch columns: the force, then the noise draws (simcore.noise)


def empty_dyn():
    """The ``dyn`` group of a dynamics whose parameters all live in the shared slots."""
    return (np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 1)), np.zeros(0, np.int64), np.zeros((0, 3)))


def pack(model, dt):
    return empty_dyn()


def scratch(dynamics, n):
    return np.zeros((n, WIDTH), np.float64), np.zeros((0, 3), np.float64)


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    steer = scratch[0]
    steer[i, OS.FX], steer[i, OS.FY], steer[i, OS.FZ] = opensteer_force(i, m, fwd, pattern, fp, ip, nbrs.idx,
                                                                       nbrs.off, nbrs.mask)
    if ip[I.DRIVE] != 0:
        store_draws(steer, i, DRAWS_AT, key, step)
    if ip[I.LEADERSHIP] == 0:
        return False
    kx, ky, kz, m_coh = cohesion_offset(m, nbrs.off, nbrs.mask)
    return sense_trigger(i, step, kx, ky, kz, m_coh, vel, clock, escape, fp, ip, key)


def move(dynamics, i, state, params, scratch):
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    steer = scratch[0]
    dvx, dvy, dvz, cap = escape_of(i, vel, clock, escape, fp, ip)
    apply_steering(i, steer[i, OS.FX], steer[i, OS.FY], steer[i, OS.FZ], pos, vel, fwd, up, side, acc, fp, ip,
                   dvx, dvy, dvz, cap, steer, DRAWS_AT)
