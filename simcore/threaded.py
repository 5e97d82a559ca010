"""One big synchronous run on several threads: the boids of a step are split into chunks run in parallel.

``run_threaded(state, params, key, n_steps, record_every, records, n_chunks, dynamics, kind)`` has the
contract of :func:`simcore.kernel.run_model` for the synchronous update order, for any dynamics (its
hooks, :mod:`simcore.hooks`; :mod:`simcore.simulate` uses it for the dynamics whose module says
``THREADS``). In a synchronous step every boid perceives the same state and writes only its own rows
(its scratch row, counts, trigger flag, and its own state when it moves), so the chunks are independent:
each boid's numbers are computed by the same code whatever the number of chunks or threads, and the
results are bit-identical to the serial run. Trigger events are appended after the perception phase, in
boid order, as the serial loop does. The grid is built once per step before the chunks start; every chunk
has its own neighbour buffers. The dynamics' per-step hooks run serially between the phases.
"""
from __future__ import annotations

import numba as nb
import numpy as np
from numba.core.cpu_options import ParallelOptions

from . import grid as cells
from . import hooks
from .grid import Grid
from .jit import kernel
from .kernel import (move_range, prepare_search, record_counts, record_perception, record_state, record_triggers,
                     sense_range, tick)
from .layout import F, I
from .neighbours import Neighbours


# The serial parts of a step run in these compiled functions (and the hooks, compiled leaves), called from
# the parallel one: inlined into a parallel function, numba's parallel transforms rewrite their loops (the
# grid build became quadratic in N).
@kernel
def prepare_chunks(grid, pos, fp, ip):
    return prepare_search(grid, pos, fp, ip)


@kernel
def record_state_serial(r, state, fp, records):
    record_state(r, state, fp, records)


@kernel
def record_final_serial(r, state, params, nbrs, grid, use_grid, records, kind):
    """The final record's counts (the grid built by ``prepare_chunks``, whose compiled build is reused)."""
    record_perception(r, state, params, nbrs, grid, use_grid, records, kind)


@kernel
def finish_step_serial(step, r, record, work, state, params, records):
    """Triggers in boid order, clocks, and this step's counts into the records."""
    scratch, visible, binocular, triggered = work
    fp, ip = params[0], params[1]
    if ip[I.LEADERSHIP] != 0:
        record_triggers(step, triggered, records)
        tick(state[7], fp[F.DT])
    if record:
        record_counts(r, visible, binocular, records)


@kernel
def sense_chunk(c, chunk, step, state, params, key, work, buffers, grid_arrays, use_grid, dynamics, kind):
    """Chunk c of the perception phase. ``buffers``: the Neighbours fields, one slab per chunk, and
    ``grid_arrays`` the Grid's fields, as plain tuples (parallel loops take no named tuples)."""
    idx, off, mask, label, cand, cpos, occ_f, occ_i, bits, slot, d2, occ_s = buffers
    nbrs = Neighbours(idx[c], off[c], mask[c], label[c], cand[c], cpos[c], occ_f[c], occ_i[c], bits[c], slot[c],
                      d2[c], occ_s[c])
    head, nxt, prv, bucket, shape, lo, hi, cell_side, start, order, spos, flat = grid_arrays
    grid = Grid(head, nxt, prv, bucket, shape, lo, hi, cell_side, start, order, spos, flat)
    n = state[0].shape[0]
    sense_range(c * chunk, min(n, (c + 1) * chunk), step, state, params, key, work, nbrs, grid, use_grid, dynamics,
                kind)


@kernel
def move_chunk(c, chunk, state, params, scratch, dynamics):
    """Chunk c of the move phase."""
    move_range(c * chunk, min(state[0].shape[0], (c + 1) * chunk), state, params, scratch, dynamics)


# No loop fusion: numba would fuse the perception and move phases (two parallel loops over the chunks),
# running chunk c's moves before chunk c + 1 perceives, since it cannot see that the groups built in their
# bodies share the state arrays. (An options object, not a dict: numba pops the keys of a dict when it
# compiles, so the dynamics and kinds compiled after the first would be fused again.)
NO_FUSION = ParallelOptions({"fusion": False})


@nb.njit(cache=True, error_model="numpy", parallel=NO_FUSION)
def run_threaded(state, params, key, n_steps, record_every, records, n_chunks, dynamics, kind):
    nb.literally(dynamics)  # compiled for this dynamics (simcore.hooks) ...
    nb.literally(kind)  # ... and this perception kind only (simcore.perception.perceive)
    # a parallel loop takes arrays, not tuples: the groups are taken apart here and rebuilt in its body
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    dfp, dip, table, kinds, fan = dyn
    n = pos.shape[0]
    chunk = (n + n_chunks - 1) // n_chunks
    # per-chunk neighbour buffers (Neighbours fields, one slab per chunk)
    idx = np.empty((n_chunks, n), np.int64)
    off = np.empty((n_chunks, n, 3))
    mask = np.empty((n_chunks, n), np.int64)
    label = np.empty((n_chunks, n), np.int64)
    cand = np.empty((n_chunks, n), np.int64)
    cpos = np.empty((n_chunks, n, 3))
    occ_f = np.empty((n_chunks, 4, n))
    occ_i = np.empty((n_chunks, 4, 2 * n + 66), np.int64)
    bits = np.zeros((n_chunks, (n + 63) // 64 + 1), np.uint64)
    slot = np.empty((n_chunks, n), np.int64)
    d2 = np.empty((n_chunks, n))
    occ_s = np.empty((n_chunks, 5, n), np.float32)
    grid = cells.new_grid(n)
    head, nxt, prv, bucket, shape, lo, hi, cell_side = grid.head, grid.nxt, grid.prv, grid.bucket, grid.shape, \
        grid.lo, grid.hi, grid.side
    start, order, spos, flat = grid.start, grid.order, grid.spos, grid.flat
    scratch = hooks.scratch(dynamics, n)
    steer, shared = scratch
    visible = np.zeros(n, np.int32)
    binocular = np.zeros(n, np.int32)
    triggered = np.zeros(n, np.bool_)
    work = (scratch, visible, binocular, triggered)
    # int64 from the start: typed first as the literal 0, ``r`` would make numba compile every kernel it is
    # passed to twice (once for Literal[int](0), once for int64); likewise the prange index, uint64 in the
    # parallel body, is passed as int64
    r = np.int64(0)
    for step in range(n_steps + 1):
        hooks.begin_step(dynamics, step, state, params, key)
        record = step % record_every == 0
        if record:
            record_state_serial(r, state, fp, records)
            hooks.record_extra(dynamics, r, state, records)
        if step == n_steps:
            if record:
                nbrs = Neighbours(idx[0], off[0], mask[0], label[0], cand[0], cpos[0], occ_f[0], occ_i[0], bits[0],
                                  slot[0], d2[0], occ_s[0])
                record_final_serial(r, state, params, nbrs, grid, prepare_chunks(grid, pos, fp, ip), records,
                                    kind)
            break
        use_grid = prepare_chunks(grid, pos, fp, ip)
        hooks.before_boids(dynamics, step, state, params, key, scratch, records)
        for c in nb.prange(n_chunks):
            sense_chunk(np.int64(c), chunk, step,
                        (pos, vel, fwd, up, side, acc, pattern, clock, escape, agents),
                        (fp, ip, (dfp, dip, table, kinds, fan)), key, ((steer, shared), visible, binocular, triggered),
                        (idx, off, mask, label, cand, cpos, occ_f, occ_i, bits, slot, d2, occ_s),
                        (head, nxt, prv, bucket, shape, lo, hi, cell_side, start, order, spos, flat), use_grid, dynamics,
                        kind)
        for c in nb.prange(n_chunks):
            move_chunk(np.int64(c), chunk, (pos, vel, fwd, up, side, acc, pattern, clock, escape, agents),
                       (fp, ip, (dfp, dip, table, kinds, fan)), (steer, shared), dynamics)
        hooks.after_boids(dynamics, step, state, params, key, scratch)
        finish_step_serial(step, r, record, work, state, params, records)
        if record:
            r += 1
