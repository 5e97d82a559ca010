"""Topological perception: each boid's k nearest eligible neighbours (Ballerini et al. 2008). Compiled.

``nearest(i, pos, fwd, fp, ip, periodic, box, nbrs, grid, use_grid)`` fills the neighbour buffers of
:mod:`simcore.neighbours` with the k = ``perception.neighbours`` nearest boids j != i that are eligible:
closer than ``max_distance`` (|d| < r, squared compare; no limit when unset) and, with a blind angle
beta > 0, not in the blind cone behind (f . d >= -cos(beta/2) |d|; a boid at distance 0 is eligible).
"Nearest" ranks by the squared distance |d|^2 = dx^2 + dy^2 + dz^2 (minimum image in a periodic box),
ties broken by the smaller index; fewer than k eligible boids are all taken. The chosen set is returned
in ascending index order, feeding all three rules (mask ``RULE_ALL``), as the sphere does.

Search. All pairs, or the grid of :mod:`simcore.grid` built with cells of side :func:`cell_side`: cubic
shells of cells around the boid's cell, s = 0, 1, 2, ..., until the k-th best squared distance is
below (s h)^2 (less a rounding margin): every boid not yet visited is at least s h away, so none can
enter the list. A shell that would fold two cells onto one bucket makes that boid fall back to all
pairs. Both searches rank the same candidates by the same numbers, so they agree bit for bit.
"""
from __future__ import annotations

import math


from .jit import inline, leaf, llvm_inline, llvm_inline_nrt
from .grid import A_X, A_Y, A_Z, LAYOUT, N_CELLS, SORTED, cell_coord
from .layout import F, I
from .neighbours import RULE_ALL, offset, offset_from, sort_by_index, store

SHELL_MARGIN = 1e-6  # cells: rounding of cell coordinates is far below this (coordinates < 1e9 cells)
CELL_FACTOR = 1.2    # cell side over the expected distance of the k-th neighbour


@llvm_inline_nrt
def cell_side(pos, fp, ip, periodic, box):
    """Grid cell side for k-nearest searches: about 1.2 times the expected k-th neighbour distance at the
    flock's mean density (bounding box, or the periodic box; at most a third of the box), and no more
    than max_distance."""
    n = pos.shape[0]
    k = ip[I.NEIGHBOURS]
    if periodic:
        volume = box * box * box
    else:
        extent = [0.0, 0.0, 0.0]
        for c in range(3):
            lo, hi = math.inf, -math.inf
            for i in range(n):
                lo = min(lo, pos[i, c])
                hi = max(hi, pos[i, c])
            extent[c] = hi - lo
        floor = max(extent[0], extent[1], extent[2]) / max(1.0, n ** (1.0 / 3.0))
        volume = max(extent[0], floor) * max(extent[1], floor) * max(extent[2], floor)
    side = CELL_FACTOR * (3.0 * k * volume / (4.0 * math.pi * max(n, 1))) ** (1.0 / 3.0)
    if periodic:
        side = min(side, box / (3.0 * (1.0 + 1e-5)))  # at least 3 cells across the box
    return min(side, fp[F.TOPO_RADIUS])


@inline
def _offer(dd, j, count, k, best):
    """Insert (dd, j) into the ascending (dd, j) list best[:count] capped at k; returns the new count."""
    full = count == k
    worse = full and (dd > best[0, k - 1] or (dd == best[0, k - 1] and j > best[1, k - 1]))
    if not worse:
        if full:
            slot = k - 1
        else:
            slot = count
            count += 1
        while slot > 0 and (best[0, slot - 1] > dd or (best[0, slot - 1] == dd and best[1, slot - 1] > j)):
            best[0, slot], best[1, slot] = best[0, slot - 1], best[1, slot - 1]
            slot -= 1
        best[0, slot], best[1, slot] = dd, j
    return count


@inline
def _consider(i, j, x, y, z, count, k, pos, fwd, r2, blind, cos_half_blind, periodic, box, best):
    """Offer boid j (at x, y, z) to boid i's list when it is eligible."""
    dx, dy, dz = offset_from(x, y, z, pos, i, periodic, box)
    dd = dx * dx + dy * dy + dz * dz
    eligible = dd < r2
    if eligible and blind:
        eligible = fwd[i, 0] * dx + fwd[i, 1] * dy + fwd[i, 2] * dz >= -cos_half_blind * math.sqrt(dd)
    if eligible:
        count = _offer(dd, float(j), count, k, best)
    return count


@inline
def _all_pairs(i, k, pos, fwd, r2, blind, cos_half_blind, periodic, box, best):
    count = 0
    for j in range(pos.shape[0]):
        if j != i:
            count = _consider(i, j, pos[j, 0], pos[j, 1], pos[j, 2], count, k, pos, fwd, r2, blind, cos_half_blind,
                              periodic, box, best)
    return count


@inline
def _axis_range(c, s, lo, hi, nc):
    """Cells c - s .. c + s along one axis: (first, last) to visit; open worlds clip to [lo, hi]."""
    first, last = c - s, c + s
    if nc == 0:
        first, last = max(first, lo), min(last, hi)
    return first, last


@llvm_inline
def _shells(i, k, pos, fwd, r2, blind, cos_half_blind, periodic, box, grid, best):
    """k nearest through shells of grid cells; -1 when the search must fall back to all pairs."""
    nc = grid.shape[N_CELLS]
    h = grid.side[0]
    ax, ay, az = grid.shape[A_X], grid.shape[A_Y], grid.shape[A_Z]
    cx, cy, cz = cell_coord(pos[i, 0], h, nc), cell_coord(pos[i, 1], h, nc), cell_coord(pos[i, 2], h, nc)
    count = 0
    s = 0
    searching = True
    while searching:
        x0, x1 = _axis_range(cx, s, grid.lo[0], grid.hi[0], nc)
        y0, y1 = _axis_range(cy, s, grid.lo[1], grid.hi[1], nc)
        z0, z1 = _axis_range(cz, s, grid.lo[2], grid.hi[2], nc)
        if x1 - x0 + 1 > ax or y1 - y0 + 1 > ay or z1 - z0 + 1 > az:
            count = -1  # this shell would visit a bucket twice: fall back to all pairs
            searching = False
        else:
            for z in range(z0, z1 + 1):
                fz = z % az
                for y in range(y0, y1 + 1):
                    row = ax * (y % ay + ay * fz)  # cells fold modulo A (which divides a periodic count)
                    face = abs(z - cz) == s or abs(y - cy) == s
                    x = x0
                    fx = x0 % ax
                    while x <= x1:
                        if face or abs(x - cx) == s:
                            b = row + fx
                            if grid.shape[LAYOUT] == SORTED:
                                for q in range(grid.start[b], grid.start[b + 1]):
                                    j = grid.order[q]
                                    if j != i:
                                        count = _consider(i, j, grid.spos[q, 0], grid.spos[q, 1], grid.spos[q, 2],
                                                          count, k, pos, fwd, r2, blind, cos_half_blind, periodic,
                                                          box, best)
                            else:
                                j = grid.head[b]
                                while j >= 0:
                                    if j != i:
                                        count = _consider(i, j, pos[j, 0], pos[j, 1], pos[j, 2], count, k, pos, fwd,
                                                          r2, blind, cos_half_blind, periodic, box, best)
                                    j = grid.nxt[j]
                            x += 1
                            fx = fx + 1 if fx + 1 < ax else 0
                        else:  # inside the cube: visited in an earlier shell, jump to its far face
                            fx = (fx + (cx + s - x)) % ax
                            x = cx + s
            if nc > 0:
                covered = 2 * s + 1 >= nc
            else:
                covered = (x0 == grid.lo[0] and x1 == grid.hi[0] and y0 == grid.lo[1] and y1 == grid.hi[1]
                           and z0 == grid.lo[2] and z1 == grid.hi[2])
            reach = (s - SHELL_MARGIN) * h * (1.0 - 1e-9)  # every unvisited boid is farther than this
            reach2 = reach * reach if reach > 0.0 else 0.0
            done = reach > 0.0 and (reach2 >= r2 or (count == k and best[0, k - 1] < reach2))
            searching = not (covered or done)
            s += 1
    return count


@leaf
def nearest(i, pos, fwd, fp, ip, periodic, box, nbrs, grid, use_grid):
    """The k nearest eligible neighbours of boid i into ``nbrs`` (module docstring); returns their count."""
    k = min(ip[I.NEIGHBOURS], pos.shape[0] - 1)
    r = fp[F.TOPO_RADIUS]
    r2 = r * r
    blind = ip[I.BLIND] != 0
    cos_half_blind = fp[F.COS_HALF_BLIND]
    best = nbrs.occ_f  # rows 0, 1: squared distance and index of the best so far
    count = 0
    if k > 0:
        count = -1
        if use_grid:
            count = _shells(i, k, pos, fwd, r2, blind, cos_half_blind, periodic, box, grid, best)
        if count < 0:
            count = _all_pairs(i, k, pos, fwd, r2, blind, cos_half_blind, periodic, box, best)
        for a in range(count):
            j = int(best[1, a])
            dx, dy, dz = offset(pos, i, j, periodic, box)
            store(nbrs, a, j, dx, dy, dz, RULE_ALL, 0)
        sort_by_index(count, nbrs)
    return count
