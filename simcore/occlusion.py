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

ALL_PAIRS_MAX = 80     # up to this many in-view neighbours, every pair is tested (no sort)
GRID_3D_MIN = 256     # from this many in-view neighbours on, a 3-D grid of directions
ROBUST = 1e-7         # margin of a "robust" containment, relative to 1 + rho_j
NOT_HIDDEN, HIDDEN, ROBUSTLY_HIDDEN = 0, 1, 2


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
def _occlude_all_pairs(m, disc, flags):
    """Few neighbours: every pair gets the exact test of :func:`_hide`, without branches (so the compiler
    can vectorise the inner loop); flags[k] is HIDDEN (1) or NOT_HIDDEN (0)."""
    rho, ux, uy, uz = disc[DISC.RHO], disc[DISC.UX], disc[DISC.UY], disc[DISC.UZ]
    for k in range(m):
        rho_k, xk, yk, zk = rho[k], ux[k], uy[k], uz[k]
        hidden = 0
        for j in range(m):
            gap = rho[j] - rho_k
            dx = ux[j] - xk
            dy = uy[j] - yk
            dz = uz[j] - zk
            dist2 = dx * dx + dy * dy + dz * dz
            hidden |= (gap > 0.0) & (dist2 <= gap * gap)
        flags[k] = hidden & (rho_k >= 0.0)


@leaf
def occlude(m, fp, nbrs):
    """Perspective phase on the m in-view neighbours of ``nbrs``; returns the number left (module docstring)."""
    disc, bins = nbrs.occ_f, nbrs.occ_i
    _discs(m, fp, nbrs)
    if m <= ALL_PAIRS_MAX:
        _occlude_all_pairs(m, disc, bins[BINS.FLAG])
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
