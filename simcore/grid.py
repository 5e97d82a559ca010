"""Cell lists: a spatial grid that finds the candidates near a boid in O(1), built in O(N). Compiled.

Space is cut into cubic cells of side ``h`` (at least the query radius, times 1 + 1e-6 so that rounding
can never put a boid within the radius more than one cell away). A boid's cell is
``floor(x / h)`` per axis in an open world (or a sphere-wrap one: neighbour distances do not wrap), and
``floor((x + L/2) / w) mod nc`` in a periodic box of side L cut into ``nc`` cells of side ``w = L / nc``
(so the cells tile the torus and neighbour cells wrap). Cells are stored in ``A_x A_y A_z`` buckets by
folding each coordinate modulo ``A`` (``A >= 3``, and ``nc`` a multiple of ``A``): the 27 cells around
any cell fall in 27 different buckets, far-apart cells may share one (their boids are extra candidates,
which the exact test rejects). Memory is O(N) whatever the spread of the flock.

In sequential update order each bucket is a doubly linked list of boids (``head``, ``nxt``, ``prv``), so
a boid that moves is re-binned in O(1) (``rebin``), as OpenSteer's lq database does: sequential order
stays exact. In synchronous order nobody moves while the flock perceives, so the grid is a sorted
snapshot instead: boids ordered by bucket with a copy of their positions, read as contiguous runs.
When the search is all pairs, ``flat`` holds the positions as three rows (``mirror``, ``mirror_one``): the
perceivers compute every squared distance from it in one vectorised pass.

Contract: ``gather(grid, i, pos, cand, cpos)`` writes into ``cand`` (and their positions, bit for bit,
into ``cpos``) every boid whose true distance from boid i can be at most the query radius (and others,
boid i included), each once, in no particular order. In the sorted layout ``runs(grid, i, pos, radius,
first, last)`` gives the same candidates in the same order without copying them, less the cells wholly
beyond the query radius in an open world: the slices ``first[r]:last[r]`` of ``order`` (and ``spos``),
r < the count it returns (at most 27). ``build``
returns False, and the caller must search all pairs for this step, when the grid cannot give that
guarantee: a non-finite position, coordinates beyond 1e9 cells (rounding), or a periodic box under 3
query radii. Topological searches (:mod:`simcore.topological`) walk cubic shells of cells with
``shell_bucket``, within the occupied cell range ``lo``/``hi`` (open worlds).
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from .jit import inline, leaf, llvm_inline, llvm_inline_nrt

CELL_MARGIN = 1e-6   # cells are this much wider than the query radius
MAX_CELL_COORD = 1e9  # beyond this many cells from the origin, rounding could misplace a boid
SKIP_TOLERANCE = 1e-6  # cells: far above the rounding of a cell face or of a boid's cell (< 1e9 cells out)

# head int64 (T,), nxt/prv/bucket int64 (N,): the lists; shape int64 (5,): A_x, A_y, A_z, nc (0 when open),
# layout (LISTS or SORTED); the occupied cell range lo (3,), hi (3,); side float64 (1,): the cell side;
# the sorted layout: start int64 (T + 1,), order int64 (N,) (boids by bucket), spos float64 (N, 3) (their
# positions in that order); flat float64 (3, N): the positions as three contiguous rows, for the all-pairs
# search (``mirror``)
Grid = namedtuple("Grid", "head nxt prv bucket shape lo hi side start order spos flat")
A_X, A_Y, A_Z, N_CELLS, LAYOUT = 0, 1, 2, 3, 4
LISTS, SORTED = 0, 1


@llvm_inline_nrt
def new_grid(n):
    """An empty grid for n boids (at most max(2n, 27) buckets)."""
    t = max(2 * n, 27)
    return Grid(np.full(t, -1, np.int64), np.empty(n, np.int64), np.empty(n, np.int64),
                np.full(n, -1, np.int64), np.zeros(5, np.int64), np.zeros(3, np.int64), np.zeros(3, np.int64),
                np.zeros(1, np.float64), np.zeros(t + 1, np.int64), np.empty(n, np.int64), np.empty((n, 3)),
                np.empty((3, n)))


@inline
def mirror(grid, pos):
    """Copy every position into ``grid.flat`` (the all-pairs search reads them there, one coordinate per
    contiguous row, so its distance pass runs in SIMD lanes)."""
    flat = grid.flat
    for i in range(pos.shape[0]):
        flat[0, i], flat[1, i], flat[2, i] = pos[i, 0], pos[i, 1], pos[i, 2]


@inline
def mirror_one(grid, i, pos):
    """Boid i's new position into ``grid.flat`` (sequential order, after it moved)."""
    grid.flat[0, i], grid.flat[1, i], grid.flat[2, i] = pos[i, 0], pos[i, 1], pos[i, 2]


@inline
def cell_coord(x, side, nc):
    """Cell coordinate of world coordinate x along one axis (cells of ``side``; ``nc`` cells per period in a
    periodic box, 0 in an open world)."""
    if nc == 0:
        c = np.int64(math.floor(x / side))
    else:
        c = np.int64(math.floor((x + 0.5 * nc * side) / side)) % nc
    return c


@inline
def bucket_of(cx, cy, cz, ax, ay, az):
    """Bucket of cell (cx, cy, cz) (any integers; periodic coordinates already wrapped) among ax ay az."""
    return cx % ax + ax * (cy % ay + ay * (cz % az))


@inline
def boid_bucket(grid, x, y, z):
    """Bucket of the cell holding point (x, y, z)."""
    side, nc = grid.side[0], grid.shape[N_CELLS]
    return bucket_of(cell_coord(x, side, nc), cell_coord(y, side, nc), cell_coord(z, side, nc),
                     grid.shape[A_X], grid.shape[A_Y], grid.shape[A_Z])


@inline
def _link(grid, i, b):
    first = grid.head[b]
    grid.nxt[i] = first
    grid.prv[i] = -1
    if first >= 0:
        grid.prv[first] = i
    grid.head[b] = i
    grid.bucket[i] = b


@inline
def _unlink(grid, i):
    b = grid.bucket[i]
    before, after = grid.prv[i], grid.nxt[i]
    if before >= 0:
        grid.nxt[before] = after
    else:
        grid.head[b] = after
    if after >= 0:
        grid.prv[after] = before
    grid.bucket[i] = -1


@inline
def _fold_sizes(extent_x, extent_y, extent_z, budget):
    """Bucket counts per axis: the cell extents (at least 3), halved on the largest until they fit."""
    ax, ay, az = max(3, extent_x), max(3, extent_y), max(3, extent_z)
    while ax * ay * az > budget:
        if ax >= ay and ax >= az:
            ax = max(3, ax // 2)
        elif ay >= az:
            ay = max(3, ay // 2)
        else:
            az = max(3, az // 2)
    return ax, ay, az


@llvm_inline_nrt
def build(grid, pos, radius, periodic, box, min_saving, lists):
    """Bin every boid in cells of side >= radius (1 + CELL_MARGIN); False when all pairs must be searched
    (see module docstring), or when the grid would save fewer than ``min_saving`` candidates per boid
    (N (1 - 27 / cells spanned), as if the boids filled the cells evenly). ``lists``: linked lists (boids
    will move and be re-binned); else the sorted layout (a snapshot: boids by bucket, with a copy of their
    positions in that order, so a bucket's candidates are read from contiguous memory)."""
    n = pos.shape[0]
    side = radius * (1.0 + CELL_MARGIN)
    if not (side > 0.0 and math.isfinite(side)):
        return False
    budget = grid.head.shape[0]
    if periodic:
        nc = np.int64(math.floor(box / side))
        if nc < 3 or n * (1.0 - 27.0 / (nc * nc * nc)) < min_saving:
            return False
        a = 3
        while (a + 1) * (a + 1) * (a + 1) <= budget and a + 1 <= nc:
            a += 1
        if nc > a:
            nc = a * (nc // a)
        grid.shape[A_X] = grid.shape[A_Y] = grid.shape[A_Z] = a
        grid.shape[N_CELLS] = nc
        grid.side[0] = box / nc
        for c in range(3):
            grid.lo[c] = 0
            grid.hi[c] = nc - 1
        for i in range(n):
            if not (math.isfinite(pos[i, 0]) and math.isfinite(pos[i, 1]) and math.isfinite(pos[i, 2])):
                return False
            if abs(pos[i, 0]) + abs(pos[i, 1]) + abs(pos[i, 2]) > MAX_CELL_COORD * grid.side[0]:
                return False
    else:
        grid.shape[N_CELLS] = 0
        grid.side[0] = side
        lo = np.empty(3)
        hi = np.empty(3)
        for c in range(3):
            lo[c] = np.inf
            hi[c] = -np.inf
        for i in range(n):
            for c in range(3):
                x = pos[i, c]
                if not math.isfinite(x):
                    return False
                lo[c] = min(lo[c], x)
                hi[c] = max(hi[c], x)
        for c in range(3):
            if max(abs(lo[c]), abs(hi[c])) > MAX_CELL_COORD * side:
                return False
            grid.lo[c] = np.int64(math.floor(lo[c] / side))
            grid.hi[c] = np.int64(math.floor(hi[c] / side))
        span = (grid.hi[0] - grid.lo[0] + 1) * (grid.hi[1] - grid.lo[1] + 1) * (grid.hi[2] - grid.lo[2] + 1)
        if n * (1.0 - 27.0 / span) < min_saving:
            return False
        ax, ay, az = _fold_sizes(grid.hi[0] - grid.lo[0] + 1, grid.hi[1] - grid.lo[1] + 1,
                                 grid.hi[2] - grid.lo[2] + 1, budget)
        grid.shape[A_X], grid.shape[A_Y], grid.shape[A_Z] = ax, ay, az
    n_buckets = grid.shape[A_X] * grid.shape[A_Y] * grid.shape[A_Z]
    if lists:
        grid.shape[LAYOUT] = LISTS
        for b in range(n_buckets):
            grid.head[b] = -1
        for i in range(n - 1, -1, -1):  # lists in ascending index order
            _link(grid, i, boid_bucket(grid, pos[i, 0], pos[i, 1], pos[i, 2]))
    else:
        grid.shape[LAYOUT] = SORTED
        start = grid.start
        for b in range(n_buckets + 1):
            start[b] = 0
        for i in range(n):
            b = boid_bucket(grid, pos[i, 0], pos[i, 1], pos[i, 2])
            grid.bucket[i] = b
            start[b + 1] += 1
        for b in range(n_buckets):
            start[b + 1] += start[b]
        for i in range(n):  # counting sort: ascending index within a bucket; start[b] ends at bucket b's end
            b = grid.bucket[i]
            k = start[b]
            grid.order[k] = i
            grid.spos[k, 0], grid.spos[k, 1], grid.spos[k, 2] = pos[i, 0], pos[i, 1], pos[i, 2]
            start[b] = k + 1
        for b in range(n_buckets, 0, -1):
            start[b] = start[b - 1]
        start[0] = 0
    return True


@leaf
def rebin(grid, i, pos):
    """Re-bin boid i after it moved (sequential order); False when its new position leaves the grid's
    guarantee (non-finite or too far), and the caller must search all pairs for the rest of the step."""
    x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
    ok = (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
          and abs(x) + abs(y) + abs(z) <= MAX_CELL_COORD * grid.side[0])
    if ok:
        side, nc = grid.side[0], grid.shape[N_CELLS]
        cx, cy, cz = cell_coord(x, side, nc), cell_coord(y, side, nc), cell_coord(z, side, nc)
        if nc == 0:  # the occupied range grows with the boid (topological shells stop at its edge)
            grid.lo[0], grid.hi[0] = min(grid.lo[0], cx), max(grid.hi[0], cx)
            grid.lo[1], grid.hi[1] = min(grid.lo[1], cy), max(grid.hi[1], cy)
            grid.lo[2], grid.hi[2] = min(grid.lo[2], cz), max(grid.hi[2], cz)
        b = bucket_of(cx, cy, cz, grid.shape[A_X], grid.shape[A_Y], grid.shape[A_Z])
        if b != grid.bucket[i]:
            _unlink(grid, i)
            _link(grid, i, b)
    return ok


@inline
def _fold(c, a):
    """c mod a (a > 0), without a division when c is already within one period."""
    if c >= a:
        c -= a
    elif c < 0:
        c += a
    return c


@inline
def _near_gap(x, c, side, d):
    """Open world: how far boid coordinate x (in cell c) is from the nearest face of its neighbour cell
    c + d (d = -1, 0, +1) along one axis, less ``SKIP_TOLERANCE`` cells for rounding; 0 when d = 0."""
    if d == 0:
        return 0.0
    if d < 0:
        gap = x - c * side
    else:
        gap = (c + 1) * side - x
    return max(gap - SKIP_TOLERANCE * side, 0.0)


@llvm_inline
def runs(grid, i, pos, radius, first, last):
    """Sorted layout: the candidates of :func:`gather`, in its order, as runs ``first[r]:last[r]`` of
    ``grid.order`` / ``grid.spos`` (buckets that follow each other in memory merged); returns the count.
    In an open world a neighbour cell lying wholly beyond ``radius`` (the query radius the grid was built
    for; with a margin of 1e-9 on its square, far above rounding) is left out: none of its boids is within
    the radius, and the boids of farther cells folded into its bucket are farther still."""
    side, nc = grid.side[0], grid.shape[N_CELLS]
    ax, ay, az = grid.shape[A_X], grid.shape[A_Y], grid.shape[A_Z]
    x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
    cx, cy, cz = cell_coord(x, side, nc), cell_coord(y, side, nc), cell_coord(z, side, nc)
    bx, by, bz = cx % ax, cy % ay, cz % az
    limit2 = radius * radius * (1.0 + 1e-9)
    count = 0
    previous = -2
    for dz in range(-1, 2):
        z2 = _near_gap(z, cz, side, dz) ** 2 if nc == 0 else 0.0
        zb = _fold(bz + dz, az)
        for dy in range(-1, 2):
            yz2 = z2 + _near_gap(y, cy, side, dy) ** 2 if nc == 0 else 0.0
            row = ax * (_fold(by + dy, ay) + ay * zb)
            for dx in range(-1, 2):
                if nc == 0 and yz2 + _near_gap(x, cx, side, dx) ** 2 > limit2:
                    previous = -2
                    continue
                b = row + _fold(bx + dx, ax)
                if b == previous + 1:
                    last[count - 1] = grid.start[b + 1]
                else:
                    first[count] = grid.start[b]
                    last[count] = grid.start[b + 1]
                    count += 1
                previous = b
    return count


@llvm_inline
def gather(grid, i, pos, cand, cpos):
    """Boids in the 27 cells around boid i (i included) into ``cand``, their positions into ``cpos``;
    returns their count.

    The neighbour cells are folded like their centre: with ``A`` dividing the periodic cell count, the
    bucket coordinate of cell c +- 1 is (c mod A) +- 1 mod A in either world, so no division is needed."""
    side, nc = grid.side[0], grid.shape[N_CELLS]
    ax, ay, az = grid.shape[A_X], grid.shape[A_Y], grid.shape[A_Z]
    bx = cell_coord(pos[i, 0], side, nc) % ax
    by = cell_coord(pos[i, 1], side, nc) % ay
    bz = cell_coord(pos[i, 2], side, nc) % az
    count = 0
    for dz in range(-1, 2):
        z = _fold(bz + dz, az)
        for dy in range(-1, 2):
            row = ax * (_fold(by + dy, ay) + ay * z)
            for dx in range(-1, 2):
                b = row + _fold(bx + dx, ax)
                if grid.shape[LAYOUT] == SORTED:
                    for k in range(grid.start[b], grid.start[b + 1]):
                        cand[count] = grid.order[k]
                        cpos[count, 0], cpos[count, 1], cpos[count, 2] = grid.spos[k, 0], grid.spos[k, 1], \
                            grid.spos[k, 2]
                        count += 1
                else:
                    j = grid.head[b]
                    while j >= 0:
                        cand[count] = j
                        cpos[count, 0], cpos[count, 1], cpos[count, 2] = pos[j, 0], pos[j, 1], pos[j, 2]
                        count += 1
                        j = grid.nxt[j]
    return count
