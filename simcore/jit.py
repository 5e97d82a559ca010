"""How simcore compiles its kernels: three numba decorators, used everywhere instead of bare ``njit``.

* ``@kernel``: a compiled function (a run loop, a per-step driver, a grid build). Cached on disk
  (``cache=True``), IEEE arithmetic without fastmath, and numpy's error model (no per-division zero
  checks: x / 0 gives inf or nan, as in numpy).
* ``@inline``: a small helper, inlined into its callers at numba's IR level, so it costs no call.
* ``@leaf``: a per-boid entry point (perceive, steer, move, re-bin), called once per boid per step. It
  is compiled without numba's reference counting (``_nrt=False``): a leaf only reads and writes arrays
  its caller owns, never creates, returns or keeps one, so there is nothing to count, and a call costs
  no atomic reference-count updates (with counting on, every array argument of every inlined helper
  costs two, which would dominate a boid's step). A leaf may call only ``@inline`` helpers.

Each ``@leaf`` and ``@kernel`` is compiled once and cached on its own, so the first compile and the
cold start stay short; ``simcore/_cache.py`` drops the cache when any source changes.
"""
from __future__ import annotations

import numba as nb

kernel = nb.njit(cache=True, error_model="numpy")
inline = nb.njit(cache=True, error_model="numpy", inline="always")
leaf = nb.njit(cache=True, error_model="numpy", _nrt=False)
