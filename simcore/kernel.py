"""The compiled whole-run loop, one for every dynamics: perception -> the dynamics' hooks, recorded every k steps.

``run_model(state, params, key, n_steps, record_every, records, dynamics, kind)`` advances the state in
place by ``n_steps`` steps and fills the records. The groups are plain tuples of arrays
(:mod:`simcore.hooks` lists them): ``state`` = (pos, vel, fwd, up, side, acc, pattern, clock, escape,
agents), ``params`` = (fp, ip, dyn) and ``records`` =

* ``rec_pos``, ``rec_vel``  float64 (R, N, 3): state at steps 0, k, 2k, ... (R = n_steps // k + 1)
* ``rec_visible``           int32 (R, N): neighbours perceived at that state (union of rule sets)
* ``rec_binocular``         int32 (R, N): of those, seen by both eyes (binocular perception only)
* ``rec_leader``            bool (R, N): leaders at that state
* ``trig_step``, ``trig_boid`` int64 (E,): trigger events in order; ``n_trig`` int64 (1,) their count
* ``rec_agents``, ``capture_step``: what a dynamics records besides (Boids++ agents and captures;
  zero-length for the others)

State: ``pos, vel, fwd, up, side, acc`` float64 (N, 3), ``pattern`` uint32 (N,), leadership ``clock``
float64 (N,) and ``escape`` float64 (N, 3) (see :mod:`simcore.leadership`), ``agents`` (Boids++). ``key``
is the run's 64-bit key for counter-based draws. ``dynamics`` (``ip[I.DYNAMICS]``) and ``kind`` (the
perception kind, ``ip[I.PERCEPTION]``) are compile-time literals: the loop is compiled once per
(dynamics, kind), with that dynamics' hooks (:mod:`simcore.hooks`: ``sense``, ``move`` and the per-step
ones) and that kind's perception only (:mod:`simcore.jit`). The loop names no dynamics.

One step (docs/model.md section 0.6): the dynamics' ``begin_step``; the record of the state (and the
dynamics' ``record_extra``); the grid; ``before_boids``; then with ``synchronous`` order every boid
perceives the state at time t and ``sense`` stores what it decided, then all ``move``; with
``sequential`` order boid i perceives, senses and moves after boids 0..i-1 have moved (OpenSteer's
in-place loop), and its recorded count is what it saw when it moved; then ``after_boids``. The last
record (step n_steps) perceives the final state without moving. Leadership (``leadership.x > 0``): a
dynamics' ``sense`` returns whether boid i triggered (a triggered boid escapes from that same step on);
triggers are recorded in boid order and all clocks advance by dt at the end of the step. With x = 0
none of this code runs, so trajectories are exactly those without leadership.

Neighbour search (``perception.search``): each step the grid of :mod:`simcore.grid` is built from the
positions (``auto``: when it spares at least ``AUTO_MIN_SAVING`` candidates per boid, N (1 - 27 / cells
spanned): all pairs are cheaper for small or compact flocks), and in sequential order a boid that moves
is re-binned at once. Perception returns the same neighbours in the same order either way, so the search
never changes a trajectory.

Structure: the loop calls, per boid, compiled leaves without reference counting (:mod:`simcore.jit`):
``perceive`` (:mod:`simcore.perception`), the dynamics' ``sense`` and ``move`` and, in sequential order,
``grid.rebin``.

``run_model`` releases the GIL: a batch of independent runs is Python threads each calling it
(:func:`simcore.simulate.simulate_batch`), every run computed by the same compiled code as alone, so
results are bit-identical either way (and no second loop is compiled for batches).
:mod:`simcore.threaded` runs one big synchronous run on several threads.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from . import grid as cells
from . import hooks
from .jit import inline, kernel, leaf, run_loop
from .layout import (F, I, ORDER_SEQUENTIAL, PERCEPTION_TOPOLOGICAL, SEARCH_ALL_PAIRS, SEARCH_AUTO,
                     BOUNDARY_PERIODIC)
from .leadership import is_leader
from .neighbours import EYE_BOTH, new_neighbours
from .perception import perceive, query_radius
from .topological import cell_side
from .walls import contain

AUTO_MIN_SAVING = 250  # search = "auto": the grid when it spares this many candidates per boid


@kernel
def max_triggers(n, n_steps, duration, dt):
    """An upper bound on trigger events: a boid triggers at most once per duration."""
    per_boid = n_steps // max(1, int(duration / dt)) + 1
    return n * per_boid


@inline
def prepare_search(grid, pos, fp, ip):
    """Build the grid for this state when the search uses it; returns whether it does (otherwise the
    positions are mirrored for the all-pairs search, :func:`simcore.grid.mirror`)."""
    if _grid_built(grid, pos, fp, ip):
        return True
    cells.mirror(grid, pos)  # all pairs: the positions as rows for the vectorised distance pass
    return False


@inline
def _grid_built(grid, pos, fp, ip):
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


@inline
def record_trigger(step, i, records):
    trig_step, trig_boid, n_trig = records[5], records[6], records[7]
    e = n_trig[0]
    if e < trig_step.shape[0]:
        trig_step[e] = step
        trig_boid[e] = i
    n_trig[0] = e + 1


@inline
def sense_range(lo, hi, step, state, params, key, work, nbrs, grid, use_grid, dynamics, kind):
    """Synchronous order, boids lo..hi-1: perceive the state, store what they decided and their counts, mark
    triggers. ``work`` = (the dynamics' scratch, visible, binocular, triggered)."""
    pos, fwd, side = state[0], state[2], state[4]
    fp, ip = params[0], params[1]
    scratch, visible, binocular, triggered = work
    for i in range(lo, hi):
        m = perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)
        visible[i] = m
        binocular[i] = count_both_eyes(m, nbrs)
        triggered[i] = hooks.sense(dynamics, i, step, m, nbrs, state, params, key, scratch)


@inline
def move_range(lo, hi, state, params, scratch, dynamics):
    """Synchronous order, boids lo..hi-1: move with what they decided."""
    for i in range(lo, hi):
        hooks.move(dynamics, i, state, params, scratch)
        if params[1][I.ARENA] != 0:
            contain(i, state, params)


@inline
def record_triggers(step, triggered, records):
    """Append this step's triggers in boid order."""
    for i in range(triggered.shape[0]):
        if triggered[i]:
            record_trigger(step, i, records)


@inline
def step_sequential(step, state, params, key, work, nbrs, grid, use_grid, records, dynamics, kind):
    """Sequential order: boid i perceives, decides and moves before boid i + 1 perceives; a boid that moves
    is re-binned at once (the rest of the step searches all pairs if it leaves the grid's guarantee), or, in
    an all-pairs search, its position mirrored."""
    pos, fwd, side = state[0], state[2], state[4]
    fp, ip = params[0], params[1]
    scratch, visible, binocular, triggered = work
    for i in range(pos.shape[0]):
        m = perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)
        visible[i] = m
        binocular[i] = count_both_eyes(m, nbrs)
        if hooks.sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
            record_trigger(step, i, records)
        hooks.move(dynamics, i, state, params, scratch)
        if ip[I.ARENA] != 0:
            contain(i, state, params)
        if not use_grid:
            cells.mirror_one(grid, i, pos)
        elif not cells.rebin(grid, i, pos):
            use_grid = False  # the rest of the step searches all pairs
            cells.mirror(grid, pos)


@inline
def record_state(r, state, fp, records):
    pos, vel, clock = state[0], state[1], state[7]
    rec_pos, rec_vel, rec_leader = records[0], records[1], records[4]
    for i in range(pos.shape[0]):
        for c in range(3):
            rec_pos[r, i, c] = pos[i, c]
            rec_vel[r, i, c] = vel[i, c]
        rec_leader[r, i] = is_leader(clock[i], fp)


@inline
def record_perception(r, state, params, nbrs, grid, use_grid, records, kind):
    """What every boid perceives in the final state (the last record, which does not move)."""
    pos, fwd, side = state[0], state[2], state[4]
    fp, ip = params[0], params[1]
    rec_visible, rec_binocular = records[2], records[3]
    for i in range(pos.shape[0]):
        m = perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)
        rec_visible[r, i] = m
        rec_binocular[r, i] = count_both_eyes(m, nbrs)


@inline
def record_counts(r, visible, binocular, records):
    """This step's perceived counts into record r."""
    rec_visible, rec_binocular = records[2], records[3]
    for i in range(visible.shape[0]):
        rec_visible[r, i] = visible[i]
        rec_binocular[r, i] = binocular[i]


@inline
def tick(clock, dt):
    for i in range(clock.shape[0]):
        clock[i] += dt


@run_loop
def run_model(state, params, key, n_steps, record_every, records, dynamics, kind):
    nb.literally(dynamics)  # compiled for this dynamics (simcore.hooks) ...
    nb.literally(kind)  # ... and this perception kind only (simcore.perception.perceive)
    pos, clock = state[0], state[7]
    fp, ip = params[0], params[1]
    n = pos.shape[0]
    nbrs = new_neighbours(n)
    grid = cells.new_grid(n)
    scratch = hooks.scratch(dynamics, n)
    visible = np.zeros(n, np.int32)
    binocular = np.zeros(n, np.int32)
    triggered = np.zeros(n, np.bool_)
    work = (scratch, visible, binocular, triggered)
    sequential = ip[I.ORDER] == ORDER_SEQUENTIAL
    leadership = ip[I.LEADERSHIP] != 0
    r = np.int64(0)  # int64 from the start: the hooks it is passed to are compiled for int64 only
    for step in range(n_steps + 1):
        hooks.begin_step(dynamics, step, state, params, key)
        record = step % record_every == 0
        if record:
            record_state(r, state, fp, records)
            hooks.record_extra(dynamics, r, state, records)
        use_grid = prepare_search(grid, pos, fp, ip)
        if step == n_steps:
            if record:
                record_perception(r, state, params, nbrs, grid, use_grid, records, kind)
            break
        hooks.before_boids(dynamics, step, state, params, key, scratch, records)
        if sequential:
            step_sequential(step, state, params, key, work, nbrs, grid, use_grid, records, dynamics, kind)
        else:
            sense_range(0, n, step, state, params, key, work, nbrs, grid, use_grid, dynamics, kind)
            if leadership:
                record_triggers(step, triggered, records)
            move_range(0, n, state, params, scratch, dynamics)
        hooks.after_boids(dynamics, step, state, params, key, scratch)
        if leadership:
            tick(clock, fp[F.DT])
        if record:
            record_counts(r, visible, binocular, records)
            r += 1
