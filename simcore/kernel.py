"""The compiled whole-run loop: perception -> rules (-> leadership) -> dynamics, recorded every k steps.

``run_model(state arrays..., fp, ip, key, n_steps, record_every, records..., kind)`` advances the state in
place by ``n_steps`` steps and fills the records:

* ``rec_pos``, ``rec_vel``  float64 (R, N, 3): state at steps 0, k, 2k, ... (R = n_steps // k + 1)
* ``rec_visible``           int32 (R, N): neighbours perceived at that state (union of rule sets)
* ``rec_binocular``         int32 (R, N): of those, seen by both eyes (binocular perception only)
* ``rec_leader``            bool (R, N): leaders at that state
* ``trig_step``, ``trig_boid`` int64 (E,): trigger events in order; ``n_trig`` int64 (1,) their count

State: ``pos, vel, fwd, up, side, acc`` float64 (N, 3), ``pattern`` uint32 (N,), leadership ``clock``
float64 (N,) and ``escape`` float64 (N, 3) (see :mod:`simcore.leadership`). ``key`` is the run's
64-bit key for counter-based draws. ``kind`` is the perception kind (``ip[I.PERCEPTION]``), a compile-time
literal: the loop is compiled once per kind, with that kind's perception only (:mod:`simcore.jit`).

Dynamics ``opensteer`` (OpenSteer steering and vehicle) or ``hartman_benes`` (raw velocity update).
With ``synchronous`` order every boid perceives the state at time t, then all move; with
``sequential`` order boid i perceives after boids 0..i-1 have moved (OpenSteer's in-place loop), and
its recorded count is what it saw when it moved. The last record (step n_steps) perceives the final
state without moving. Leadership (``leadership.x > 0``): each boid's trigger is decided from the state
it perceives, a triggered boid escapes from that same step on, and all clocks advance by dt at the end
of the step. With x = 0 none of this code runs, so trajectories are exactly those without leadership.

Neighbour search (``perception.search``): each step the grid of :mod:`simcore.grid` is built from the
positions (``auto``: when it spares at least ``AUTO_MIN_SAVING`` candidates per boid, N (1 - 27 / cells
spanned): all pairs are cheaper for small or compact flocks), and in sequential order a boid that moves
is re-binned at once. Perception returns the same neighbours in the same order either way, so the search
never changes a trajectory.

Structure: one compiled loop (``run_model``) calls, per boid, compiled leaves without reference counting
(:mod:`simcore.jit`): ``perceive`` (:mod:`simcore.perception`), ``sense`` (rules and the leadership
decision into the ``steer`` buffer, whose columns ``OS``/``HB`` are declared in :mod:`simcore.layout`),
``move`` (dynamics) and, in sequential order, ``grid.rebin``.

``run_batch`` runs B independent runs (leading axis B on every per-run array, keys (B,)) in parallel
threads; each run is computed by the same code as alone, so results are bit-identical either way.
:mod:`simcore.threaded` runs one big synchronous run on several threads.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from . import grid as cells
from .dynamics import apply_steering, hartman_benes_step
from .jit import inline, kernel, leaf
from .layout import (DYNAMICS_HARTMAN_BENES, F, HB, I, ORDER_SEQUENTIAL, OS, PERCEPTION_TOPOLOGICAL,
                     SEARCH_ALL_PAIRS, SEARCH_AUTO, STEER_WIDTH, BOUNDARY_PERIODIC)
from .leadership import decide, escape_step, is_leader, start
from .neighbours import EYE_BOTH, new_neighbours
from .perception import perceive, query_radius
from .rules import cohesion_offset, hartman_benes_forces, opensteer_force
from .topological import cell_side

AUTO_MIN_SAVING = 250  # search = "auto": the grid when it spares this many candidates per boid


@kernel
def max_triggers(n, n_steps, duration, dt):
    """An upper bound on trigger events: a boid triggers at most once per duration."""
    per_boid = n_steps // max(1, int(duration / dt)) + 1
    return n * per_boid


@inline
def prepare_search(grid, pos, fp, ip):
    """Build the grid for this state when the search uses it; returns whether it does."""
    search = ip[I.SEARCH]
    n = pos.shape[0]
    if search == SEARCH_ALL_PAIRS or n < 2:
        return False
    periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
    box = fp[F.BOX]
    if ip[I.PERCEPTION] == PERCEPTION_TOPOLOGICAL:
        radius = cell_side(pos, fp, ip, periodic, box)
    else:
        radius = query_radius(fp, ip)
    return cells.build(grid, pos, radius, periodic, box, AUTO_MIN_SAVING if search == SEARCH_AUTO else -np.inf,
                       ip[I.ORDER] == ORDER_SEQUENTIAL)


@leaf
def count_both_eyes(m, nbrs):
    both = 0
    for a in range(m):
        if nbrs.label[a] == EYE_BOTH:
            both += 1
    return both


@leaf
def sense(i, step, m, nbrs, vel, fwd, pattern, clock, escape, steer, fp, ip, key):
    """Rules of boid i from its m neighbours into ``steer[i]``; with leadership, the trigger decision
    (a triggered boid starts its escape now). Returns whether boid i triggered."""
    leadership = ip[I.LEADERSHIP] != 0
    if ip[I.DYNAMICS] == DYNAMICS_HARTMAN_BENES:
        (steer[i, HB.SX], steer[i, HB.SY], steer[i, HB.SZ], steer[i, HB.KX], steer[i, HB.KY], steer[i, HB.KZ],
         steer[i, HB.MX], steer[i, HB.MY], steer[i, HB.MZ]) = hartman_benes_forces(i, m, vel, fp, nbrs.idx,
                                                                                    nbrs.off)
        kx, ky, kz, m_coh = steer[i, HB.KX], steer[i, HB.KY], steer[i, HB.KZ], m
    else:
        steer[i, OS.FX], steer[i, OS.FY], steer[i, OS.FZ] = opensteer_force(i, m, fwd, pattern, fp, ip, nbrs.idx,
                                                                           nbrs.off, nbrs.mask)
        kx = ky = kz = 0.0
        m_coh = 0
        if leadership:
            kx, ky, kz, m_coh = cohesion_offset(m, nbrs.off, nbrs.mask)
    trigger = False
    if leadership:
        trigger, slow = decide(i, step, kx, ky, kz, m_coh, vel[i, 0], vel[i, 1], vel[i, 2], clock, fp, ip, key)
        if trigger:
            start(i, slow, kx, ky, kz, clock, escape)
    return trigger


@inline
def record_trigger(step, i, trig_step, trig_boid, n_trig):
    e = n_trig[0]
    if e < trig_step.shape[0]:
        trig_step[e] = step
        trig_boid[e] = i
    n_trig[0] = e + 1


@leaf
def move(i, steer, pos, vel, fwd, up, side, acc, fp, ip, clock, escape):
    """Apply the dynamics to boid i with its stored steers (and its escape when it leads)."""
    dvx = dvy = dvz = 0.0
    cap = fp[F.MAX_SPEED]
    if ip[I.LEADERSHIP] != 0:
        dvx, dvy, dvz, cap = escape_step(i, vel[i, 0], vel[i, 1], vel[i, 2], clock, escape, fp)
    if ip[I.DYNAMICS] == DYNAMICS_HARTMAN_BENES:
        hartman_benes_step(i, steer[i, HB.SX], steer[i, HB.SY], steer[i, HB.SZ], steer[i, HB.KX], steer[i, HB.KY],
                           steer[i, HB.KZ], steer[i, HB.MX], steer[i, HB.MY], steer[i, HB.MZ], pos, vel, fwd, up,
                           side, acc, fp, ip, dvx, dvy, dvz, cap)
    else:
        apply_steering(i, steer[i, OS.FX], steer[i, OS.FY], steer[i, OS.FZ], pos, vel, fwd, up, side, acc, fp, ip,
                       dvx, dvy, dvz, cap)


@inline
def sense_range(lo, hi, step, pos, vel, fwd, side, pattern, clock, escape, steer, visible, binocular, triggered,
                fp, ip, key, nbrs, grid, use_grid, kind):
    """Synchronous order, boids lo..hi-1: perceive the state, store their steers and counts, mark triggers."""
    for i in range(lo, hi):
        m = perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)
        visible[i] = m
        binocular[i] = count_both_eyes(m, nbrs)
        triggered[i] = sense(i, step, m, nbrs, vel, fwd, pattern, clock, escape, steer, fp, ip, key)


@inline
def move_range(lo, hi, steer, pos, vel, fwd, up, side, acc, fp, ip, clock, escape):
    """Synchronous order, boids lo..hi-1: move with the stored steers."""
    for i in range(lo, hi):
        move(i, steer, pos, vel, fwd, up, side, acc, fp, ip, clock, escape)


@inline
def record_triggers(step, triggered, trig_step, trig_boid, n_trig):
    """Append this step's triggers in boid order."""
    for i in range(triggered.shape[0]):
        if triggered[i]:
            record_trigger(step, i, trig_step, trig_boid, n_trig)


@inline
def step_sequential(step, pos, vel, fwd, up, side, acc, pattern, clock, escape, steer, visible, binocular, fp, ip,
                    key, nbrs, grid, use_grid, trig_step, trig_boid, n_trig, kind):
    """Sequential order: boid i perceives, decides and moves before boid i + 1 perceives; a boid that moves
    is re-binned at once (the rest of the step searches all pairs if it leaves the grid's guarantee)."""
    for i in range(pos.shape[0]):
        m = perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)
        visible[i] = m
        binocular[i] = count_both_eyes(m, nbrs)
        if sense(i, step, m, nbrs, vel, fwd, pattern, clock, escape, steer, fp, ip, key):
            record_trigger(step, i, trig_step, trig_boid, n_trig)
        move(i, steer, pos, vel, fwd, up, side, acc, fp, ip, clock, escape)
        if use_grid:
            use_grid = cells.rebin(grid, i, pos)


@inline
def record_state(r, pos, vel, clock, fp, rec_pos, rec_vel, rec_leader):
    for i in range(pos.shape[0]):
        for c in range(3):
            rec_pos[r, i, c] = pos[i, c]
            rec_vel[r, i, c] = vel[i, c]
        rec_leader[r, i] = is_leader(clock[i], fp)


@inline
def record_perception(r, pos, fwd, side, fp, ip, nbrs, grid, use_grid, rec_visible, rec_binocular, kind):
    """What every boid perceives in the final state (the last record, which does not move)."""
    for i in range(pos.shape[0]):
        m = perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)
        rec_visible[r, i] = m
        rec_binocular[r, i] = count_both_eyes(m, nbrs)


@inline
def tick(clock, dt):
    for i in range(clock.shape[0]):
        clock[i] += dt


@kernel
def run_model(pos, vel, fwd, up, side, acc, pattern, clock, escape, fp, ip, key, n_steps, record_every,
              rec_pos, rec_vel, rec_visible, rec_binocular, rec_leader, trig_step, trig_boid, n_trig, kind):
    nb.literally(kind)  # compiled for this perception kind only (simcore.perception.perceive)
    n = pos.shape[0]
    nbrs = new_neighbours(n)
    grid = cells.new_grid(n)
    steer = np.zeros((n, STEER_WIDTH), np.float64)
    visible = np.zeros(n, np.int32)
    binocular = np.zeros(n, np.int32)
    triggered = np.zeros(n, np.bool_)
    sequential = ip[I.ORDER] == ORDER_SEQUENTIAL
    leadership = ip[I.LEADERSHIP] != 0
    r = 0
    for step in range(n_steps + 1):
        record = step % record_every == 0
        if record:
            record_state(r, pos, vel, clock, fp, rec_pos, rec_vel, rec_leader)
        use_grid = prepare_search(grid, pos, fp, ip)
        if step == n_steps:
            if record:
                record_perception(r, pos, fwd, side, fp, ip, nbrs, grid, use_grid, rec_visible, rec_binocular, kind)
            break
        if sequential:
            step_sequential(step, pos, vel, fwd, up, side, acc, pattern, clock, escape, steer, visible, binocular,
                            fp, ip, key, nbrs, grid, use_grid, trig_step, trig_boid, n_trig, kind)
        else:
            sense_range(0, n, step, pos, vel, fwd, side, pattern, clock, escape, steer, visible, binocular,
                        triggered, fp, ip, key, nbrs, grid, use_grid, kind)
            if leadership:
                record_triggers(step, triggered, trig_step, trig_boid, n_trig)
            move_range(0, n, steer, pos, vel, fwd, up, side, acc, fp, ip, clock, escape)
        if leadership:
            tick(clock, fp[F.DT])
        if record:
            for i in range(n):
                rec_visible[r, i] = visible[i]
                rec_binocular[r, i] = binocular[i]
            r += 1


@nb.njit(cache=True, error_model="numpy", parallel=True)
def run_batch(pos, vel, fwd, up, side, acc, pattern, clock, escape, fp, ip, keys, n_steps, record_every,
              rec_pos, rec_vel, rec_visible, rec_binocular, rec_leader, trig_step, trig_boid, n_trig, kind):
    nb.literally(kind)
    for b in nb.prange(pos.shape[0]):
        run_model(pos[b], vel[b], fwd[b], up[b], side[b], acc[b], pattern[b], clock[b], escape[b], fp, ip,
                  keys[b], n_steps, record_every, rec_pos[b], rec_vel[b], rec_visible[b], rec_binocular[b],
                  rec_leader[b], trig_step[b], trig_boid[b], n_trig[b], kind)
