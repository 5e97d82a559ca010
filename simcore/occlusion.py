"""Holland & Semwal's perspective phase: drop the completely occluded neighbours. Compiled with numba.

``occlude(m, fp, nbrs)`` takes the m in-view neighbours in the buffers ``nbrs`` (:mod:`simcore.neighbours`),
removes the hidden ones in place (keeping the order of the rest) and returns how many remain.

Seen from boid i, neighbour a is a disc of angular radius rho_a = body_radius / |d_a| about the unit
direction u_a = d_a / |d_a|. A farther k is hidden when some in-view j has rho_j > rho_k and
|u_j - u_k| <= rho_j - rho_k (its disc contains k's); every in-view boid occludes, hidden or not, so the
hidden set does not depend on the order of the checks. A neighbour exactly at the observer's centre
(possible when the eyes sit off-centre) has no direction: it neither hides nor is hidden.

Cost. With at most ``ALL_PAIRS_MAX`` in-view neighbours every pair gets the exact test, without branches
(the compiler vectorises it): in a flock occlusion hides about 1 % of them, so the work is proving that
nothing is hidden, and m^2 branch-free tests beat any structure at these sizes. Beyond that, an occluder j
can only hide a k within rho_j of it along every axis. With up to ``GRID_3D_MIN`` neighbours the
slots are sorted by their direction's coordinate along the axis of widest spread, and j meets the run of
slots within its reach on that axis; with many (``GRID_3D_MIN``) candidates come from a 3-D grid of bins
over the directions, so an occluder meets only the boids whose directions lie within its own disc's
reach, and the work grows with the number of such pairs (about (3/4) (body_radius / range)^2 m^2 in a
uniform flock), not with m^2. An occluder already hidden "robustly" (with a margin of 1e-7 (1 + rho),
far above rounding) is skipped: containment is transitive, so whatever it would hide, the disc hiding it
hides too. Every candidate pair gets the exact containment test, so the hidden set is exactly that of
testing every pair.
"""
from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from .jit import inline, leaf
from .layout import F

# scratch rows: nbrs.occ_f float64 (4, N): the discs; nbrs.occ_i int64 (4, 2N + 66): the bins
DISC = IntEnum("DISC", "RHO UX UY UZ", start=0)
BINS = IntEnum("BINS", "FLAG SLOT START KEY", start=0)

SCREEN = IntEnum("SCREEN", "HI LO UX UY UZ", start=0)   # rows of nbrs.occ_s float32 (5, N)

SCREEN_MIN = 32       # from this many in-view neighbours on, the all-pairs test is screened in float32
ALL_PAIRS_MAX = 80     # up to this many in-view neighbours, every pair is tested (no sort)
GRID_3D_MIN = 256     # from this many in-view neighbours on, a 3-D grid of directions
ROBUST = 1e-7         # margin of a "robust" containment, relative to 1 + rho_j
NOT_HIDDEN, HIDDEN, ROBUSTLY_HIDDEN = 0, 1, 2
WIDEN = 1e-6                # the single-precision screen's relative widening of the radii, ...
SLACK = np.float32(1e-5)    # ... its slack on squared chords (both far above float32 rounding: see
CAP = 1e30                  # _occlude_all_pairs), and the cap on its radii
ZERO32 = np.float32(0.0)


@inline
def _bin(x, n_bins):
    b = np.int64((x + 1.0) * (0.5 * n_bins))
    if b < 0:
        b = 0
    if b > n_bins - 1:
        b = n_bins - 1
    return b


@inline
def _discs(m, fp, nbrs):
    """Projected radius and centre of each slot (branch-free, so the compiler can vectorise it)."""
    body = fp[F.BODY_R]
    rho, ux, uy, uz = nbrs.occ_f[DISC.RHO], nbrs.occ_f[DISC.UX], nbrs.occ_f[DISC.UY], nbrs.occ_f[DISC.UZ]
    off = nbrs.off
    for a in range(m):
        dist = math.sqrt(off[a, 0] ** 2 + off[a, 1] ** 2 + off[a, 2] ** 2)
        inv = 1.0 / dist
        away = dist > 0.0
        rho[a] = body * inv if away else -1.0
        ux[a] = off[a, 0] * inv if away else 0.0
        uy[a] = off[a, 1] * inv if away else 0.0
        uz[a] = off[a, 2] * inv if away else 0.0


@inline
def _widest_axis(m, disc):
    """The row (UX, UY or UZ) of the axis along which the m directions spread most."""
    sum_x = sum_y = sum_z = 0.0
    sq_x = sq_y = sq_z = 0.0
    for a in range(m):
        x, y, z = disc[DISC.UX, a], disc[DISC.UY, a], disc[DISC.UZ, a]
        sum_x += x
        sum_y += y
        sum_z += z
        sq_x += x * x
        sq_y += y * y
        sq_z += z * z
    spread_x = sq_x - sum_x * sum_x / m
    spread_y = sq_y - sum_y * sum_y / m
    spread_z = sq_z - sum_z * sum_z / m
    axis = DISC.UZ
    if spread_x >= spread_y and spread_x >= spread_z:
        axis = DISC.UX
    elif spread_y >= spread_z:
        axis = DISC.UY
    return axis


@inline
def _sort_into_bins(m, disc, bins, nx, ny, nz, axis):
    """Counting sort of the slots by bin: bins[START, b] .. bins[START, b + 1] index bins[SLOT, :]; every
    flag cleared. (m slices along ``axis`` when ny = nz = 1, else an nx ny nz grid over x, y, z.)"""
    n_bins = nx * ny * nz
    for b in range(n_bins + 1):
        bins[BINS.START, b] = 0
    for a in range(m):
        if ny == 1 and nz == 1:
            key = _bin(disc[axis, a], nx)
        else:
            key = _bin(disc[DISC.UX, a], nx) + nx * (_bin(disc[DISC.UY, a], ny) + ny * _bin(disc[DISC.UZ, a], nz))
        bins[BINS.KEY, a] = key
        bins[BINS.START, key + 1] += 1
        bins[BINS.FLAG, a] = NOT_HIDDEN
    for b in range(n_bins):
        bins[BINS.START, b + 1] += bins[BINS.START, b]
    for a in range(m):  # place, advancing each bin's start to its end...
        key = bins[BINS.KEY, a]
        bins[BINS.SLOT, bins[BINS.START, key]] = a
        bins[BINS.START, key] += 1
    for b in range(n_bins, 0, -1):  # ... then shift the ends back into starts
        bins[BINS.START, b] = bins[BINS.START, b - 1]
    bins[BINS.START, 0] = 0


@inline
def _hide(j, k, xj, yj, zj, rho_j, margin, disc, flags):
    """The exact containment test of k in occluder j's disc; marks k (robustly) hidden."""
    rho_k = disc[DISC.RHO, k]
    gap = rho_j - rho_k
    ux = xj - disc[DISC.UX, k]
    uy = yj - disc[DISC.UY, k]
    uz = zj - disc[DISC.UZ, k]
    dist2 = ux * ux + uy * uy + uz * uz
    if (gap > 0.0) & (rho_k >= 0.0) & (dist2 <= gap * gap):
        robust = gap - margin
        flag = ROBUSTLY_HIDDEN if robust > 0.0 and dist2 <= robust * robust else HIDDEN
        if flag > flags[k]:
            flags[k] = flag


@inline
def _occlude_from(j, disc, bins, nx, ny, nz):
    """3-D grid: test occluder j against every slot in the bins within its reach."""
    rho_j = disc[DISC.RHO, j]
    reach = rho_j * (1.0 + 1e-9)
    x0, x1 = _bin(disc[DISC.UX, j] - reach, nx), _bin(disc[DISC.UX, j] + reach, nx)
    y0, y1 = _bin(disc[DISC.UY, j] - reach, ny), _bin(disc[DISC.UY, j] + reach, ny)
    z0, z1 = _bin(disc[DISC.UZ, j] - reach, nz), _bin(disc[DISC.UZ, j] + reach, nz)
    xj, yj, zj = disc[DISC.UX, j], disc[DISC.UY, j], disc[DISC.UZ, j]
    margin = ROBUST * (1.0 + rho_j)
    flags = bins[BINS.FLAG]
    for bz in range(z0, z1 + 1):
        for by in range(y0, y1 + 1):
            row = nx * (by + ny * bz)
            for s in range(bins[BINS.START, row + x0], bins[BINS.START, row + x1 + 1]):
                _hide(j, bins[BINS.SLOT, s], xj, yj, zj, rho_j, margin, disc, flags)


@inline
def _sort_along(m, disc, bins, axis):
    """bins[SLOT, :m]: the slots in ascending order of their coordinate along ``axis`` (counting sort into
    m slices, then an insertion sort that has little left to do); every flag cleared."""
    _sort_into_bins(m, disc, bins, m, 1, 1, axis)
    order = bins[BINS.SLOT]
    for p in range(1, m):
        a = order[p]
        x = disc[axis, a]
        q = p - 1
        while q >= 0 and disc[axis, order[q]] > x:
            order[q + 1] = order[q]
            q -= 1
        order[q + 1] = a


@inline
def _occlude_sorted(m, disc, bins, axis):
    """Few neighbours: walk the slots sorted along ``axis``; occluder j meets the slots whose coordinate
    lies within its reach (rho_j (1 + 1e-9), far above rounding: a k outside it has |u_j - u_k| > rho_j
    and cannot be contained), each given the exact test."""
    order, flags = bins[BINS.SLOT], bins[BINS.FLAG]
    for p in range(m):
        j = order[p]
        rho_j = disc[DISC.RHO, j]
        if rho_j <= 0.0 or flags[j] == ROBUSTLY_HIDDEN:
            continue
        reach = rho_j * (1.0 + 1e-9)
        xj, yj, zj = disc[DISC.UX, j], disc[DISC.UY, j], disc[DISC.UZ, j]
        aj = disc[axis, j]
        margin = ROBUST * (1.0 + rho_j)
        q = p + 1
        while q < m and disc[axis, order[q]] - aj <= reach:
            _hide(j, order[q], xj, yj, zj, rho_j, margin, disc, flags)
            q += 1
        q = p - 1
        while q >= 0 and aj - disc[axis, order[q]] <= reach:
            _hide(j, order[q], xj, yj, zj, rho_j, margin, disc, flags)
            q -= 1


@inline
def _screen_discs(m, disc, screen):
    """The discs in single precision for the screen of :func:`_occlude_all_pairs`: each radius widened
    upwards (row HI, for an occluder) and downwards (row LO, for the occluded) by ``WIDEN``, capped at
    ``CAP`` so that float32 stays finite, and the centres."""
    for a in range(m):
        rho = disc[DISC.RHO, a]
        screen[SCREEN.HI, a] = min(rho * (1.0 + WIDEN), CAP * (1.0 + WIDEN))
        screen[SCREEN.LO, a] = min(rho * (1.0 - WIDEN), CAP)
        screen[SCREEN.UX, a] = disc[DISC.UX, a]
        screen[SCREEN.UY, a] = disc[DISC.UY, a]
        screen[SCREEN.UZ, a] = disc[DISC.UZ, a]


@inline
def _occlude_all_pairs(m, disc, flags, screen):
    """Few neighbours: every pair gets the containment test of :func:`_hide`, in double precision below
    ``SCREEN_MIN`` slots. From there on, first in single precision (eight SIMD lanes instead of four), with
    the radii widened and a slack on the squared chord, so that it flags every k the exact test would hide
    (and a few more; a disc is not screened against itself: widened, it would contain itself); each flagged
    k then gets the exact test against every j. The loops are branch-free (the compiler vectorises them);
    flags[k] is HIDDEN (1) or NOT_HIDDEN (0), exactly as testing every pair in double precision.

    Why no hidden k escapes the screen: the centres are unit vectors, so each float32 coordinate is within
    3e-8 of its double, each chord component within 2e-7, and the squared chord within 2e-6 of the exact
    one (``SLACK`` is 1e-5); the widened radii give a float32 gap at least 8e-7 (rho_j + rho_k) above the
    exact gap, so its square stays above the exact square after rounding."""
    if m < SCREEN_MIN:
        _occlude_exactly(m, disc, flags)
        return
    _screen_discs(m, disc, screen)
    hi, lo, sx, sy, sz = screen[SCREEN.HI], screen[SCREEN.LO], screen[SCREEN.UX], screen[SCREEN.UY], screen[SCREEN.UZ]
    rho, ux, uy, uz = disc[DISC.RHO], disc[DISC.UX], disc[DISC.UY], disc[DISC.UZ]
    for k in range(m):
        lo_k, sx_k, sy_k, sz_k = lo[k], sx[k], sy[k], sz[k]
        maybe = False
        for j in range(m):
            gap = hi[j] - lo_k
            dx = sx[j] - sx_k
            dy = sy[j] - sy_k
            dz = sz[j] - sz_k
            maybe |= (gap > ZERO32) & (dx * dx + dy * dy + dz * dz <= gap * gap + SLACK) & (j != k)
        flags[k] = _hidden_exactly(k, m, rho, ux, uy, uz) if maybe else NOT_HIDDEN


@inline
def _hidden_exactly(k, m, rho, ux, uy, uz):
    """HIDDEN (1) if some slot's disc contains slot k's by the exact test of :func:`_hide`, else NOT_HIDDEN;
    branch-free over the m slots."""
    rho_k, xk, yk, zk = rho[k], ux[k], uy[k], uz[k]
    hidden = False
    for j in range(m):
        gap = rho[j] - rho_k
        dx = ux[j] - xk
        dy = uy[j] - yk
        dz = uz[j] - zk
        hidden |= (gap > 0.0) & (dx * dx + dy * dy + dz * dz <= gap * gap)
    return np.int64(hidden & (rho_k >= 0.0))


@inline
def _occlude_exactly(m, disc, flags):
    """Every pair in double precision (fewer than ``SCREEN_MIN`` slots: the screen would not pay)."""
    rho, ux, uy, uz = disc[DISC.RHO], disc[DISC.UX], disc[DISC.UY], disc[DISC.UZ]
    for k in range(m):
        flags[k] = _hidden_exactly(k, m, rho, ux, uy, uz)


@leaf
def occlude(m, fp, nbrs):
    """Perspective phase on the m in-view neighbours of ``nbrs``; returns the number left (module docstring)."""
    disc, bins = nbrs.occ_f, nbrs.occ_i
    _discs(m, fp, nbrs)
    if m <= ALL_PAIRS_MAX:
        _occlude_all_pairs(m, disc, bins[BINS.FLAG], nbrs.occ_s)
    elif m < GRID_3D_MIN:
        axis = _widest_axis(m, disc)
        _sort_along(m, disc, bins, axis)
        _occlude_sorted(m, disc, bins, axis)
    else:
        nx = ny = nz = int(math.floor((2.0 * m) ** (1.0 / 3.0)))
        _sort_into_bins(m, disc, bins, nx, ny, nz, DISC.UX)
        for j in range(m):
            if disc[DISC.RHO, j] > 0.0 and bins[BINS.FLAG, j] != ROBUSTLY_HIDDEN:
                _occlude_from(j, disc, bins, nx, ny, nz)
    kept = 0
    for a in range(m):
        if bins[BINS.FLAG, a] == NOT_HIDDEN:
            if kept != a:
                nbrs.idx[kept] = nbrs.idx[a]
                nbrs.off[kept, 0], nbrs.off[kept, 1], nbrs.off[kept, 2] = nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2]
                nbrs.mask[kept] = nbrs.mask[a]
                nbrs.label[kept] = nbrs.label[a]
            kept += 1
    return kept
