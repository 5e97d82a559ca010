"""How simcore compiles its kernels: three numba decorators, used everywhere instead of bare ``njit``.

* ``@kernel``: a compiled function (a run loop, a per-step driver, a grid build). Cached on disk
  (``cache=True``), IEEE arithmetic without fastmath, and numpy's error model (no per-division zero
  checks: x / 0 gives inf or nan, as in numpy). ``@run_loop`` is ``@kernel`` releasing the GIL
  (``nogil``): a batch of runs is several Python threads each calling the one compiled run loop.
* ``@inline``: a small helper, inlined into its callers at numba's IR level, so it costs no call.
* ``@llvm_inline``: a larger helper (more than about 25 lines, or one inlined at several sites), compiled
  once on its own and inlined by LLVM instead (``forceinline``, without reference counting like a
  leaf; ``@llvm_inline_nrt`` for the few that allocate arrays, with it: numba would otherwise inherit the
  caller's setting). numba's IR inlining deep-copies and re-types the callee's IR at every site, nested
  helpers included: for the large helpers that was about a fifth of the binocular run loop's first
  compile. Every result is the same bit for bit, and a run takes the same time (bench/RESULTS.md,
  issue 30).
* ``@leaf``: a per-boid entry point (perceive, steer, move, re-bin), called once per boid per step. It
  is compiled without numba's reference counting (``_nrt=False``): a leaf only reads and writes arrays
  its caller owns, never creates, returns or keeps one, so there is nothing to count, and a call costs
  no atomic reference-count updates (with counting on, every array argument of every inlined helper
  costs two, which would dominate a boid's step). A leaf may call only ``@inline`` and ``@llvm_inline``
  helpers. It is also marked ``forceinline``: numba compiles (and caches) it on its own, and LLVM then
  inlines its machine-level code into the run loop that calls it. A call would pass every array of its groups
  flattened (7-9 words each: 200-250 words for ``perceive`` or ``sense``), and the loop would store them
  all again before every call: about a third of a small flock's whole run (bench/RESULTS.md, issue 30).
  numba's own inlining (``inline="always"``) would give the same code, but it re-types the leaf inside
  every loop, and the first compile took ten times longer.

Each ``@leaf``, ``@llvm_inline`` and ``@kernel`` is compiled once and cached on its own, so the first
compile and the cold start stay short; ``simcore/_cache.py`` drops the cache when any source changes.

A run loop takes the dynamics and the perception kind as its last two arguments, ``dynamics`` and
``kind``, made compile-time literals with ``numba.literally`` (:func:`simcore.hooks.sense`,
:func:`simcore.perception.perceive`): it is compiled once per (dynamics, kind) used, with that dynamics'
hooks and that kind's perception only. Python calls it through :func:`call_with_literals`.
"""
from __future__ import annotations

import numba as nb
from numba._dispatcher import compute_fingerprint

COMPILED_ONLY = "a compiled hook: numba gives its body inside a run loop; it cannot be called from Python"
KERNEL_OPTIONS = dict(cache=True, error_model="numpy")
kernel = nb.njit(**KERNEL_OPTIONS)
run_loop = nb.njit(**KERNEL_OPTIONS, nogil=True)  # a whole run: releases the GIL, so a batch runs on threads
inline = nb.njit(cache=True, error_model="numpy", inline="always")
LEAF_OPTIONS = dict(cache=True, error_model="numpy", _nrt=False, forceinline=True)  # see ``@leaf`` above
leaf = nb.njit(**LEAF_OPTIONS)
llvm_inline = nb.njit(**LEAF_OPTIONS)   # a leaf's options: see ``@llvm_inline`` above
llvm_inline_nrt = nb.njit(**{**LEAF_OPTIONS, "_nrt": True})   # one that allocates arrays
_SPECIALISED = {}  # (dispatcher, literal values, argument fingerprint) -> compiled specialisation


def specialise(dispatcher, args, n_literal):
    """The compiled specialisation of ``dispatcher`` for ``args`` whose last ``n_literal`` are compile-time
    literals (``numba.literally``), compiled or loaded from the cache: a plain callable (for a ``nogil``
    function it releases the GIL), called with the same arguments, literals included.

    Typing the arguments in Python costs about 0.8 ms for a run loop's groups of arrays (more than a short
    run's whole simulation), so each specialisation is remembered for the process under the fingerprint
    numba's own dispatcher uses to recognise argument types (dtype, dimensions, layout, writability of
    every array, recursively through tuples): the same fingerprint is the same types. (A Python integer is
    fingerprinted by kind alone; the loops' integer arguments, counts of steps and records, are far below
    the 2**63 from which numba would type one as uint64.)"""
    head, tail = args[:len(args) - n_literal], tuple(int(a) for a in args[len(args) - n_literal:])
    try:
        key = (dispatcher, tail, compute_fingerprint(head))
    except (TypeError, ValueError):   # a value numba cannot fingerprint: type it every time
        key = None
    found = _SPECIALISED.get(key) if key is not None else None
    if found is None:
        argtypes = tuple(dispatcher.typeof_pyval(a) for a in head) + tuple(nb.types.literal(a) for a in tail)
        found = dispatcher.compile(argtypes)
        if key is not None:
            _SPECIALISED[key] = found
    return found


def call_with_literals(dispatcher, args, n_literal):
    """``dispatcher(*args)`` for a compiled function whose last ``n_literal`` arguments are compile-time
    literals (``numba.literally``): the specialisation for their values is compiled (or loaded from the
    cache) and called directly. A plain call would give the same results, but numba would first type the
    whole function for int64 values on every call, only to be told to retry with the literals."""
    tail = tuple(int(a) for a in args[len(args) - n_literal:])
    return specialise(dispatcher, args, n_literal)(*args[:len(args) - n_literal], *tail)


def call_with_literal_kind(dispatcher, *args):
    """``dispatcher(*args)`` for a run loop whose last argument is the literal perception kind: the
    specialisation for that kind's value is compiled (or loaded from the cache) and called directly. A
    plain call would give the same results, but numba would first type the whole loop for an int64 kind on
    every call, only to be told to retry with the literal."""
    return call_with_literals(dispatcher, args, 1)
