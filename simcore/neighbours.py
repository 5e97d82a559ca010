"""Neighbour buffers shared by the perception kinds, and the small helpers that fill them. Compiled.

``new_neighbours(n)`` returns a :data:`Neighbours` for a flock of n boids: the output slots ``idx``
int64 (n,), ``off`` float64 (n, 3), ``mask`` int64 (n,) (rule bits ``RULE_*``) and ``label`` int64 (n,)
(eye labels ``EYE_*``), and scratch: ``cand`` int64 (n,) candidate indices, ``occ_f`` float64 (n, 4) and
``occ_i`` int64 (2n + 66, 4) for the perspective phase and the nearest-neighbour lists.
``sort_by_index(m, nbrs)`` puts the first m slots in ascending index order.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from .jit import inline, kernel

RULE_SEPARATION = 1
RULE_ALIGNMENT = 2
RULE_COHESION = 4
RULE_ALL = 7
EYE_LEFT = 1
EYE_RIGHT = 2
EYE_BOTH = 3
INSERTION_SORT_MAX = 32  # neighbour lists up to this long are insertion-sorted, longer ones heapsorted

Neighbours = namedtuple("Neighbours", "idx off mask label cand occ_f occ_i")


@kernel
def new_neighbours(n):
    """Neighbour buffers and scratch for a flock of n boids."""
    return Neighbours(np.empty(n, np.int64), np.empty((n, 3)), np.empty(n, np.int64), np.empty(n, np.int64),
                      np.empty(n, np.int64), np.empty((n, 4)), np.empty((2 * n + 66, 4), np.int64))


@inline
def min_image(x, box):
    """Minimum-image component of an offset in a periodic box of side ``box``."""
    return x - box * math.floor(x / box + 0.5)


@inline
def offset(pos, i, j, periodic, box):
    """d = p_j - p_i, minimum image when ``periodic``."""
    dx = pos[j, 0] - pos[i, 0]
    dy = pos[j, 1] - pos[i, 1]
    dz = pos[j, 2] - pos[i, 2]
    if periodic:
        dx = min_image(dx, box)
        dy = min_image(dy, box)
        dz = min_image(dz, box)
    return dx, dy, dz


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
def _swap(nbrs, a, b):
    j, dx, dy, dz, mask, label = nbrs.idx[a], nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2], nbrs.mask[a], nbrs.label[a]
    store(nbrs, a, nbrs.idx[b], nbrs.off[b, 0], nbrs.off[b, 1], nbrs.off[b, 2], nbrs.mask[b], nbrs.label[b])
    store(nbrs, b, j, dx, dy, dz, mask, label)


@inline
def _sift_down(nbrs, root, end):
    while 2 * root + 1 < end:
        child = 2 * root + 1
        if child + 1 < end and nbrs.idx[child + 1] > nbrs.idx[child]:
            child += 1
        if nbrs.idx[root] >= nbrs.idx[child]:
            root = end  # in place: stop
        else:
            _swap(nbrs, root, child)
            root = child


@inline
def sort_by_index(m, nbrs):
    """Put the first m neighbour slots in ascending index order (indices are distinct): insertion sort
    for short lists, heapsort for long ones (no allocation)."""
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
    else:
        for root in range(m // 2 - 1, -1, -1):
            _sift_down(nbrs, root, m)
        for end in range(m - 1, 0, -1):
            _swap(nbrs, 0, end)
            _sift_down(nbrs, 0, end)
