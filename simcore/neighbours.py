"""Neighbour buffers shared by the perception kinds, and the small helpers that fill them. Compiled.

``new_neighbours(n)`` returns a :data:`Neighbours` for a flock of n boids: the output slots ``idx``
int64 (n,), ``off`` float64 (n, 3), ``mask`` int64 (n,) (rule bits ``RULE_*``) and ``label`` int64 (n,)
(eye labels ``EYE_*``), and scratch: ``cand`` int64 (n,) candidate indices with their positions ``cpos``
float64 (n, 3) (the grid's gathered candidates, or the all-pairs search's boids within reach), ``occ_f`` float64 (4, n) and
``occ_i`` int64 (4, 2n + 66) (rows) for the perspective phase, the nearest-neighbour lists and sorting, ``bits``
uint64 (n/64 + 1,) (all zero between uses) and ``slot`` int64 (n,) for sorting (and the binocular view
phase's list of candidates within reach), ``d2`` float64 (n,): squared distances of the all-pairs search,
``occ_s`` float32 (5, n): the perspective phase's single-precision screen.
``sort_by_index(m, nbrs)`` puts the first m slots in ascending index order.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from .jit import inline, llvm_inline_nrt

RULE_SEPARATION = 1
RULE_ALIGNMENT = 2
RULE_COHESION = 4
RULE_ALL = 7
EYE_LEFT = 1
EYE_RIGHT = 2
EYE_BOTH = 3
INSERTION_SORT_MAX = 16  # neighbour lists up to this long are insertion-sorted in place...

BITMAP_SPAN = 4         # ... through a bitmap when the flock needs at most this many 64-bit words per
                        # neighbour, else through a Shell sort of keys

Neighbours = namedtuple("Neighbours", "idx off mask label cand cpos occ_f occ_i bits slot d2 occ_s")

# 64-bit de Bruijn sequence and table: the index of the lowest set bit of a word in one multiply
_DEBRUIJN = np.uint64(0x03F79D71B4CB0A89)
_DEBRUIJN_INDEX = np.zeros(64, np.int64)
for _b in range(64):
    _DEBRUIJN_INDEX[((1 << _b) * 0x03F79D71B4CB0A89 % (1 << 64)) >> 58] = _b


@llvm_inline_nrt
def new_neighbours(n):
    """Neighbour buffers and scratch for a flock of n boids."""
    return Neighbours(np.empty(n, np.int64), np.empty((n, 3)), np.empty(n, np.int64), np.empty(n, np.int64),
                      np.empty(n, np.int64), np.empty((n, 3)), np.empty((4, n)),
                      np.empty((4, 2 * n + 66), np.int64),
                      np.zeros((n + 63) // 64 + 1, np.uint64), np.empty(n, np.int64), np.empty(n),
                      np.empty((5, n), np.float32))


@inline
def min_image(x, box):
    """Minimum-image component of an offset in a periodic box of side ``box``."""
    return x - box * math.floor(x / box + 0.5)


@inline
def offset_from(x, y, z, pos, i, periodic, box):
    """d = (x, y, z) - p_i, minimum image when ``periodic``."""
    return offset_to(x, y, z, pos[i, 0], pos[i, 1], pos[i, 2], periodic, box)


@inline
def offset_to(x, y, z, px, py, pz, periodic, box):
    """d = (x, y, z) - (px, py, pz), minimum image when ``periodic``."""
    dx = x - px
    dy = y - py
    dz = z - pz
    if periodic:
        dx = min_image(dx, box)
        dy = min_image(dy, box)
        dz = min_image(dz, box)
    return dx, dy, dz


@inline
def offset(pos, i, j, periodic, box):
    """d = p_j - p_i, minimum image when ``periodic``."""
    return offset_from(pos[j, 0], pos[j, 1], pos[j, 2], pos, i, periodic, box)


@inline
def store(nbrs, m, j, dx, dy, dz, mask, label):
    """Write neighbour j into slot m."""
    nbrs.idx[m] = j
    nbrs.off[m, 0] = dx
    nbrs.off[m, 1] = dy
    nbrs.off[m, 2] = dz
    nbrs.mask[m] = mask
    nbrs.label[m] = label


@inline
def _stage(m, nbrs):
    """Copy the first m slots to the scratch rows (columns of occ_i: idx, mask, label; of occ_f: offset)."""
    tmp_f, tmp_i = nbrs.occ_f, nbrs.occ_i
    for a in range(m):
        tmp_i[0, a], tmp_i[1, a], tmp_i[2, a] = nbrs.idx[a], nbrs.mask[a], nbrs.label[a]
        tmp_f[0, a], tmp_f[1, a], tmp_f[2, a] = nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2]


@inline
def _unstage(k, a, nbrs):
    """Write staged slot a back into slot k."""
    tmp_f, tmp_i = nbrs.occ_f, nbrs.occ_i
    store(nbrs, k, tmp_i[0, a], tmp_f[0, a], tmp_f[1, a], tmp_f[2, a], tmp_i[1, a], tmp_i[2, a])


@inline
def _sort_through_keys(m, nbrs):
    """Ascending order of m slots with distinct indices: Shell sort of (index, slot) keys, then the staged
    records written back in that order (O(m^1.3), whatever the flock size)."""
    _stage(m, nbrs)
    keys = nbrs.slot  # (index << 24) | slot: distinct indices make distinct keys, ordered by index
    for a in range(m):
        keys[a] = (nbrs.idx[a] << 24) | a
    gap = 1
    while gap < m // 3:
        gap = 3 * gap + 1
    while gap > 0:
        for a in range(gap, m):
            key = keys[a]
            b = a
            while b >= gap and keys[b - gap] > key:
                keys[b] = keys[b - gap]
                b -= gap
            keys[b] = key
        gap //= 3
    for k in range(m):
        _unstage(k, keys[k] & 0xFFFFFF, nbrs)


@inline
def _sort_through_bitmap(m, nbrs):
    """Ascending order of m slots with distinct indices: stage them, mark their indices in a bitmap, read the
    bitmap back in order (the bitmap is left all zero)."""
    bits, slot = nbrs.bits, nbrs.slot
    _stage(m, nbrs)
    lo, hi = nbrs.idx[0], nbrs.idx[0]
    for a in range(m):
        j = nbrs.idx[a]
        lo, hi = min(lo, j), max(hi, j)
        slot[j] = a
        bits[j >> 6] |= np.uint64(1) << np.uint64(j & 63)
    k = 0
    for w in range(lo >> 6, (hi >> 6) + 1):
        word = bits[w]
        while word != np.uint64(0):
            lowest = word & (~word + np.uint64(1))
            _unstage(k, slot[(w << 6) + _DEBRUIJN_INDEX[(lowest * _DEBRUIJN) >> np.uint64(58)]], nbrs)
            k += 1
            word &= word - np.uint64(1)
        bits[w] = np.uint64(0)


@inline
def sort_by_index(m, nbrs):
    """Put the first m neighbour slots in ascending index order (indices are distinct, no allocation):
    insertion sort for short lists, a bitmap of the indices when the flock is small enough for it to be
    cheap (``BITMAP_SPAN`` words per neighbour), a Shell sort of keys otherwise."""
    if m <= INSERTION_SORT_MAX:
        for a in range(1, m):
            j = nbrs.idx[a]
            dx, dy, dz = nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2]
            mask, label = nbrs.mask[a], nbrs.label[a]
            b = a - 1
            while b >= 0 and nbrs.idx[b] > j:
                store(nbrs, b + 1, nbrs.idx[b], nbrs.off[b, 0], nbrs.off[b, 1], nbrs.off[b, 2], nbrs.mask[b],
                      nbrs.label[b])
                b -= 1
            store(nbrs, b + 1, j, dx, dy, dz, mask, label)
    elif nbrs.bits.shape[0] <= BITMAP_SPAN * m or m >= 1 << 24:
        _sort_through_bitmap(m, nbrs)
    else:
        _sort_through_keys(m, nbrs)
