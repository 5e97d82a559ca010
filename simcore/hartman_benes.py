"""The ``hartman_benes`` dynamics as run-loop hooks (:mod:`simcore.hooks`): Hartman and Beneš' steers
(docs/model.md section 5.1, :func:`simcore.rules.hartman_benes_forces`) and velocity update (section 5.2,
:func:`simcore.dynamics.hartman_benes_step`), with the change of leadership (section 5.4).

``sense`` stores boid i's separation, cohesion and alignment steers in its ``HB`` columns of the per-boid
buffer (and, with leadership, decides its trigger from the cohesion steer over its m neighbours);
``move`` applies the update with them (plus a leader's escape; cruise and noise when on,
:mod:`simcore.noise`, from the draws ``sense`` stores after the steers). Its gains live in the shared slots
``fp``/``ip``: its own group ``dyn`` is empty.
"""
from __future__ import annotations

import numpy as np

from .dynamics import hartman_benes_step
from .layout import HB, I
from .leadership import escape_of, sense_trigger
from .noise import DRAWS, store_draws
from .opensteer import empty_dyn
from .rules import hartman_benes_forces

DRAWS_AT = len(HB)  # the first column of the noise draws
WIDTH = DRAWS_AT + DRAWS  # per-boid scratch columns: the steers, then the noise draws (simcore.noise)


def pack(model, dt):
    return empty_dyn()


def scratch(dynamics, n):
    return np.zeros((n, WIDTH), np.float64), np.zeros((0, 3), np.float64)


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    steer = scratch[0]
    (steer[i, HB.SX], steer[i, HB.SY], steer[i, HB.SZ], steer[i, HB.KX], steer[i, HB.KY], steer[i, HB.KZ],
     steer[i, HB.MX], steer[i, HB.MY], steer[i, HB.MZ]) = hartman_benes_forces(i, m, vel, fp, nbrs.idx, nbrs.off)
    if ip[I.DRIVE] != 0:
        store_draws(steer, i, DRAWS_AT, key, step)
    if ip[I.LEADERSHIP] == 0:
        return False
    return sense_trigger(i, step, steer[i, HB.KX], steer[i, HB.KY], steer[i, HB.KZ], m, vel, clock, escape, fp, ip,
                         key)


def move(dynamics, i, state, params, scratch):
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    steer = scratch[0]
    dvx, dvy, dvz, cap = escape_of(i, vel, clock, escape, fp, ip)
    hartman_benes_step(i, steer[i, HB.SX], steer[i, HB.SY], steer[i, HB.SZ], steer[i, HB.KX], steer[i, HB.KY],
                       steer[i, HB.KZ], steer[i, HB.MX], steer[i, HB.MY], steer[i, HB.MZ], pos, vel, fwd, up, side,
                       acc, fp, ip, dvx, dvy, dvz, cap, steer, DRAWS_AT)
