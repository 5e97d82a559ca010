"""One big synchronous run on several threads: the boids of a step are split into chunks run in parallel.

``run_threaded(state arrays..., fp, ip, key, n_steps, record_every, records..., n_chunks, kind)`` has the
contract of :func:`simcore.kernel.run_model` for the synchronous update order. In a synchronous step
every boid perceives the same state and writes only its own rows (steer, counts, trigger flag, and its
own state when it moves), so the chunks are independent: each boid's numbers are computed by the same
code whatever the number of chunks or threads, and the results are bit-identical to the serial run.
Trigger events are appended after the perception phase, in boid order, as the serial loop does. The
grid is built once per step before the chunks start; every chunk has its own neighbour buffers.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from . import grid as cells
from .grid import Grid
from .jit import kernel
from .kernel import (move_range, prepare_search, record_perception, record_state, record_triggers, sense_range,
                     tick)
from .layout import F, I, STEER_WIDTH
from .neighbours import Neighbours


# The serial parts of a step run in these compiled functions, called from the parallel one: inlined
# into a parallel function, numba's parallel transforms rewrite their loops (the grid build became
# quadratic in N).
@kernel
def prepare_chunks(grid, pos, fp, ip):
    return prepare_search(grid, pos, fp, ip)


@kernel
def record_state_serial(r, pos, vel, clock, fp, rec_pos, rec_vel, rec_leader):
    record_state(r, pos, vel, clock, fp, rec_pos, rec_vel, rec_leader)


@kernel
def record_final_serial(r, pos, fwd, side, fp, ip, nbrs, grid, use_grid, rec_visible, rec_binocular, kind):
    """The final record's counts (the grid built by ``prepare_chunks``, whose compiled build is reused)."""
    record_perception(r, pos, fwd, side, fp, ip, nbrs, grid, use_grid, rec_visible, rec_binocular, kind)


@kernel
def finish_step_serial(step, r, record, leadership, triggered, trig_step, trig_boid, n_trig, clock, dt, visible,
                       binocular, rec_visible, rec_binocular):
    """Triggers in boid order, clocks, and this step's counts into the records."""
    if leadership:
        record_triggers(step, triggered, trig_step, trig_boid, n_trig)
        tick(clock, dt)
    if record:
        for i in range(visible.shape[0]):
            rec_visible[r, i] = visible[i]
            rec_binocular[r, i] = binocular[i]


@kernel
def sense_chunk(c, chunk, step, pos, vel, fwd, side, pattern, clock, escape, steer, visible, binocular, triggered,
                fp, ip, key, idx, off, mask, label, cand, cpos, everyone, occ_f, occ_i, bits, slot, head, nxt, prv,
                bucket, shape, lo, hi, cell_side, start, order, spos, use_grid, kind):
    """Chunk c of the perception phase (plain arrays in and out: parallel loops take no named tuples)."""
    nbrs = Neighbours(idx[c], off[c], mask[c], label[c], cand[c], cpos[c], everyone, occ_f[c], occ_i[c], bits[c],
                      slot[c])
    grid = Grid(head, nxt, prv, bucket, shape, lo, hi, cell_side, start, order, spos)
    n = pos.shape[0]
    sense_range(c * chunk, min(n, (c + 1) * chunk), step, pos, vel, fwd, side, pattern, clock, escape, steer,
                visible, binocular, triggered, fp, ip, key, nbrs, grid, use_grid, kind)


@kernel
def move_chunk(c, chunk, steer, pos, vel, fwd, up, side, acc, fp, ip, clock, escape):
    """Chunk c of the move phase."""
    move_range(c * chunk, min(pos.shape[0], (c + 1) * chunk), steer, pos, vel, fwd, up, side, acc, fp, ip, clock,
               escape)


@nb.njit(cache=True, error_model="numpy", parallel=True)
def run_threaded(pos, vel, fwd, up, side, acc, pattern, clock, escape, fp, ip, key, n_steps, record_every,
                 rec_pos, rec_vel, rec_visible, rec_binocular, rec_leader, trig_step, trig_boid, n_trig, n_chunks,
                 kind):
    nb.literally(kind)  # compiled for this perception kind only (simcore.perception.perceive)
    n = pos.shape[0]
    chunk = (n + n_chunks - 1) // n_chunks
    # per-chunk neighbour buffers (Neighbours fields, one slab per chunk)
    idx = np.empty((n_chunks, n), np.int64)
    off = np.empty((n_chunks, n, 3))
    mask = np.empty((n_chunks, n), np.int64)
    label = np.empty((n_chunks, n), np.int64)
    cand = np.empty((n_chunks, n), np.int64)
    cpos = np.empty((n_chunks, n, 3))
    everyone = np.arange(n)
    occ_f = np.empty((n_chunks, 4, n))
    occ_i = np.empty((n_chunks, 4, 2 * n + 66), np.int64)
    bits = np.zeros((n_chunks, (n + 63) // 64 + 1), np.uint64)
    slot = np.empty((n_chunks, n), np.int64)
    grid = cells.new_grid(n)
    head, nxt, prv, bucket, shape, lo, hi, cell_side = grid.head, grid.nxt, grid.prv, grid.bucket, grid.shape, \
        grid.lo, grid.hi, grid.side
    start, order, spos = grid.start, grid.order, grid.spos
    steer = np.zeros((n, STEER_WIDTH), np.float64)
    visible = np.zeros(n, np.int32)
    binocular = np.zeros(n, np.int32)
    triggered = np.zeros(n, np.bool_)
    leadership = ip[I.LEADERSHIP] != 0
    # int64 from the start: typed first as the literal 0, ``r`` would make numba compile every kernel it is
    # passed to twice (once for Literal[int](0), once for int64); likewise the prange index, uint64 in the
    # parallel body, is passed as int64
    r = np.int64(0)
    for step in range(n_steps + 1):
        record = step % record_every == 0
        if record:
            record_state_serial(r, pos, vel, clock, fp, rec_pos, rec_vel, rec_leader)
        if step == n_steps:
            if record:
                nbrs = Neighbours(idx[0], off[0], mask[0], label[0], cand[0], cpos[0], everyone, occ_f[0], occ_i[0],
                                  bits[0], slot[0])
                record_final_serial(r, pos, fwd, side, fp, ip, nbrs, grid, prepare_chunks(grid, pos, fp, ip),
                                    rec_visible, rec_binocular, kind)
            break
        use_grid = prepare_chunks(grid, pos, fp, ip)
        for c in nb.prange(n_chunks):
            sense_chunk(np.int64(c), chunk, step, pos, vel, fwd, side, pattern, clock, escape, steer, visible, binocular,
                        triggered, fp, ip, key, idx, off, mask, label, cand, cpos, everyone, occ_f, occ_i, bits, slot,
                        head, nxt, prv, bucket, shape, lo, hi, cell_side, start, order, spos, use_grid, kind)
        for c in nb.prange(n_chunks):
            move_chunk(np.int64(c), chunk, steer, pos, vel, fwd, up, side, acc, fp, ip, clock, escape)
        finish_step_serial(step, r, record, leadership, triggered, trig_step, trig_boid, n_trig, clock, fp[F.DT],
                           visible, binocular, rec_visible, rec_binocular)
        if record:
            r += 1
