"""The compiled whole-run loop: perception -> rules -> dynamics, recorded every k steps.

``run_opensteer(state arrays..., fp, ip, n_steps, record_every, rec_pos, rec_vel, rec_visible,
rec_binocular)`` advances the state in place by ``n_steps`` steps and fills the records:

* ``rec_pos``, ``rec_vel``  float64 (R, N, 3): state at steps 0, k, 2k, ... (R = n_steps // k + 1)
* ``rec_visible``           int32 (R, N): neighbours perceived at that state (union of rule sets)
* ``rec_binocular``         int32 (R, N): of those, seen by both eyes (binocular perception only)

With ``synchronous`` order every boid perceives the state at time t, then all move; with ``sequential``
order boid i perceives after boids 0..i-1 have moved (OpenSteer's in-place loop), and its recorded count
is what it saw when it moved. The last record (step n_steps) perceives the final state without moving.

``run_batch`` runs B independent runs (leading axis B on every array) in parallel threads; each run is
computed by the same code as alone, so results are bit-identical either way.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .dynamics import apply_steering
from .layout import I_ORDER, ORDER_SEQUENTIAL
from .perception import EYE_BOTH, perceive
from .rules import opensteer_force


@nb.njit(cache=True, error_model="numpy")
def _count(m, nb_label):
    both = 0
    for n in range(m):
        if nb_label[n] == EYE_BOTH:
            both += 1
    return both


@nb.njit(cache=True, error_model="numpy")
def run_opensteer(pos, vel, fwd, up, side, acc, pattern, fp, ip, n_steps, record_every,
                  rec_pos, rec_vel, rec_visible, rec_binocular):
    n = pos.shape[0]
    nb_idx = np.empty(n, np.int64)
    nb_off = np.empty((n, 3), np.float64)
    nb_mask = np.empty(n, np.int64)
    nb_label = np.empty(n, np.int64)
    work_f = np.empty((n, 5), np.float64)
    work_i = np.empty((n + 2, 4), np.int64)
    force = np.empty((n, 3), np.float64)
    visible = np.empty(n, np.int32)
    binocular = np.empty(n, np.int32)
    sequential = ip[I_ORDER] == ORDER_SEQUENTIAL
    r = 0
    for step in range(n_steps + 1):
        record = step % record_every == 0
        if record:
            rec_pos[r] = pos
            rec_vel[r] = vel
        if step == n_steps:
            if record:
                for i in range(n):
                    m = perceive(i, pos, fwd, side, fp, ip, nb_idx, nb_off, nb_mask, nb_label, work_f, work_i)
                    rec_visible[r, i] = m
                    rec_binocular[r, i] = _count(m, nb_label)
            break
        for i in range(n):
            m = perceive(i, pos, fwd, side, fp, ip, nb_idx, nb_off, nb_mask, nb_label, work_f, work_i)
            visible[i] = m
            binocular[i] = _count(m, nb_label)
            fx, fy, fz = opensteer_force(i, m, fwd, pattern, fp, ip, nb_idx, nb_off, nb_mask)
            if sequential:
                apply_steering(i, fx, fy, fz, pos, vel, fwd, up, side, acc, fp, ip)
            else:
                force[i, 0], force[i, 1], force[i, 2] = fx, fy, fz
        if not sequential:
            for i in range(n):
                apply_steering(i, force[i, 0], force[i, 1], force[i, 2], pos, vel, fwd, up, side, acc, fp, ip)
        if record:
            rec_visible[r] = visible
            rec_binocular[r] = binocular
            r += 1


@nb.njit(cache=True, error_model="numpy", parallel=True)
def run_batch(pos, vel, fwd, up, side, acc, pattern, fp, ip, n_steps, record_every,
              rec_pos, rec_vel, rec_visible, rec_binocular):
    for b in nb.prange(pos.shape[0]):
        run_opensteer(pos[b], vel[b], fwd[b], up[b], side[b], acc[b], pattern[b], fp, ip, n_steps,
                      record_every, rec_pos[b], rec_vel[b], rec_visible[b], rec_binocular[b])
