"""The compiled whole-run loop: perception -> rules (-> leadership) -> dynamics, recorded every k steps.

``run_model(state arrays..., fp, ip, key, n_steps, record_every, records...)`` advances the state in
place by ``n_steps`` steps and fills the records:

* ``rec_pos``, ``rec_vel``  float64 (R, N, 3): state at steps 0, k, 2k, ... (R = n_steps // k + 1)
* ``rec_visible``           int32 (R, N): neighbours perceived at that state (union of rule sets)
* ``rec_binocular``         int32 (R, N): of those, seen by both eyes (binocular perception only)
* ``rec_leader``            bool (R, N): leaders at that state
* ``trig_step``, ``trig_boid`` int64 (E,): trigger events in order; ``n_trig`` int64 (1,) their count

State: ``pos, vel, fwd, up, side, acc`` float64 (N, 3), ``pattern`` uint32 (N,), leadership ``clock``
float64 (N,) and ``escape`` float64 (N, 3) (see :mod:`simcore.leadership`). ``key`` is the run's
64-bit key for counter-based draws.

Dynamics ``opensteer`` (OpenSteer steering and vehicle) or ``hartman_benes`` (raw velocity update).
With ``synchronous`` order every boid perceives the state at time t, then all move; with
``sequential`` order boid i perceives after boids 0..i-1 have moved (OpenSteer's in-place loop), and
its recorded count is what it saw when it moved. The last record (step n_steps) perceives the final
state without moving. Leadership (``leadership.x > 0``): each boid's trigger is decided from the state
it perceives, a triggered boid escapes from that same step on, and all clocks advance by dt at the end
of the step. With x = 0 none of this code runs, so trajectories are exactly those without leadership.

``run_batch`` runs B independent runs (leading axis B on every per-run array, keys (B,)) in parallel
threads; each run is computed by the same code as alone, so results are bit-identical either way.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .dynamics import apply_steering, hartman_benes_step
from .layout import (DYNAMICS_HARTMAN_BENES, F_DT, F_MAX_SPEED, I_DYNAMICS, I_LEADERSHIP,
                     I_ORDER, ORDER_SEQUENTIAL)
from .leadership import decide, escape_step, is_leader, start
from .perception import EYE_BOTH, perceive
from .rules import cohesion_offset, hartman_benes_forces, opensteer_force


@nb.njit(cache=True, error_model="numpy", inline="always")
def _count(m, nb_label):
    both = 0
    for n in range(m):
        if nb_label[n] == EYE_BOTH:
            both += 1
    return both


@nb.njit(cache=True, error_model="numpy")
def max_triggers(n, n_steps, duration, dt):
    """An upper bound on trigger events: a boid triggers at most once per duration."""
    per_boid = n_steps // max(1, int(duration / dt)) + 1
    return n * per_boid


@nb.njit(cache=True, error_model="numpy", inline="always")
def _move(i, hb, force, pos, vel, fwd, up, side, acc, fp, ip, leadership, clock, escape):
    """Apply the dynamics to boid i with its stored steers (and its escape when it leads)."""
    dvx = dvy = dvz = 0.0
    cap = fp[F_MAX_SPEED]
    if leadership:
        dvx, dvy, dvz, cap = escape_step(i, vel[i, 0], vel[i, 1], vel[i, 2], clock, escape, fp)
    if hb:
        hartman_benes_step(i, force[i, 0], force[i, 1], force[i, 2], force[i, 3], force[i, 4], force[i, 5],
                           force[i, 6], force[i, 7], force[i, 8], pos, vel, fwd, up, side, acc, fp, ip,
                           dvx, dvy, dvz, cap)
    else:
        apply_steering(i, force[i, 0], force[i, 1], force[i, 2], pos, vel, fwd, up, side, acc, fp, ip,
                       dvx, dvy, dvz, cap)


@nb.njit(cache=True, error_model="numpy")
def run_model(pos, vel, fwd, up, side, acc, pattern, clock, escape, fp, ip, key, n_steps, record_every,
              rec_pos, rec_vel, rec_visible, rec_binocular, rec_leader, trig_step, trig_boid, n_trig):
    n = pos.shape[0]
    nb_idx = np.empty(n, np.int64)
    nb_off = np.empty((n, 3), np.float64)
    nb_mask = np.empty(n, np.int64)
    nb_label = np.empty(n, np.int64)
    work_f = np.empty((n, 5), np.float64)
    work_i = np.empty((n + 2, 4), np.int64)
    force = np.zeros((n, 9), np.float64)
    visible = np.empty(n, np.int32)
    binocular = np.empty(n, np.int32)
    sequential = ip[I_ORDER] == ORDER_SEQUENTIAL
    hb = ip[I_DYNAMICS] == DYNAMICS_HARTMAN_BENES
    leadership = ip[I_LEADERSHIP] != 0
    dt = fp[F_DT]
    r = 0
    for step in range(n_steps + 1):
        record = step % record_every == 0
        if record:
            rec_pos[r] = pos
            rec_vel[r] = vel
            for i in range(n):
                rec_leader[r, i] = is_leader(clock[i], fp)
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
            if hb:
                (force[i, 0], force[i, 1], force[i, 2], force[i, 3], force[i, 4], force[i, 5],
                 force[i, 6], force[i, 7], force[i, 8]) = hartman_benes_forces(i, m, vel, fp, nb_idx, nb_off)
                kx, ky, kz, m_coh = force[i, 3], force[i, 4], force[i, 5], m
            else:
                force[i, 0], force[i, 1], force[i, 2] = opensteer_force(i, m, fwd, pattern, fp, ip, nb_idx,
                                                                        nb_off, nb_mask)
                kx = ky = kz = 0.0
                m_coh = 0
                if leadership:
                    kx, ky, kz, m_coh = cohesion_offset(m, nb_off, nb_mask)
            if leadership:
                trigger, slow = decide(i, step, kx, ky, kz, m_coh, vel[i, 0], vel[i, 1], vel[i, 2], clock, fp,
                                       ip, key)
                if trigger:
                    start(i, slow, kx, ky, kz, clock, escape)
                    e = n_trig[0]
                    if e < trig_step.shape[0]:
                        trig_step[e] = step
                        trig_boid[e] = i
                    n_trig[0] = e + 1
            if sequential:
                _move(i, hb, force, pos, vel, fwd, up, side, acc, fp, ip, leadership, clock, escape)
        if not sequential:
            for i in range(n):
                _move(i, hb, force, pos, vel, fwd, up, side, acc, fp, ip, leadership, clock, escape)
        if leadership:
            for i in range(n):
                clock[i] += dt
        if record:
            rec_visible[r] = visible
            rec_binocular[r] = binocular
            r += 1


@nb.njit(cache=True, error_model="numpy", parallel=True)
def run_batch(pos, vel, fwd, up, side, acc, pattern, clock, escape, fp, ip, keys, n_steps, record_every,
              rec_pos, rec_vel, rec_visible, rec_binocular, rec_leader, trig_step, trig_boid, n_trig):
    for b in nb.prange(pos.shape[0]):
        run_model(pos[b], vel[b], fwd[b], up[b], side[b], acc[b], pattern[b], clock[b], escape[b], fp, ip,
                  keys[b], n_steps, record_every, rec_pos[b], rec_vel[b], rec_visible[b], rec_binocular[b],
                  rec_leader[b], trig_step[b], trig_boid[b], n_trig[b])
