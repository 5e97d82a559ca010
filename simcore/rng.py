"""Randomness: SeedSequence-based initial-condition generators and counter-based in-loop draws.

docs/model.md section 7. A run's seed (an int >= 0 or a tuple of ints) becomes a ``numpy.random.SeedSequence``;
its first child seeds the ``Generator(PCG64)`` for initial conditions, its second child gives a 64-bit
``loop_key`` for draws made inside the compiled loop. Its third child (spawn key 2) is reserved for the
observation model (``observables.observation``: missed detections and position noise).

In-loop draws are a pure function of ``(loop_key, stream, step, index)``: the 4-tuple is mixed with the
SplitMix64 finaliser (Steele, Lea & Flood 2014) in a keyed chain, so a draw never depends on which
thread, batch or evaluation order asked for it. ``uniform01`` has 53 random bits in [0, 1);
``normal`` uses Box-Muller on two such uniforms (indices 2 index and 2 index + 1), so a stream
must be used either for uniform or for normal draws, never both.

Streams are small integers naming what the draw is for (``STREAM_*`` below, the shared ones; a dynamics
declares its own in its descriptor's ``STREAMS``, :mod:`simcore.registry`, and a test keeps them all
distinct), so adding a new use of randomness never shifts an existing one.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import inline

STREAM_LEADERSHIP = 1
STREAM_HEADING_NOISE = 4  # simcore.noise: the von Mises-Fisher turn (uniforms at 2 boid, 2 boid + 1)
STREAM_SPEED_NOISE = 5  # simcore.noise: the speed kick (normal at boid)
STREAM_PLUGIN = 16   # a plug-in dynamics' own draws (simcore.plugin); far from the built-ins' next numbers

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def seed_sequence(seed) -> np.random.SeedSequence:
    """SeedSequence of a run seed: an int >= 0 or a sequence of ints >= 0."""
    if isinstance(seed, np.random.SeedSequence):
        return seed
    items = list(seed) if isinstance(seed, (list, tuple)) else [seed]
    ok = bool(items) and all(isinstance(s, (int, np.integer)) and not isinstance(s, (bool, np.bool_))
                             and s >= 0 for s in items)
    if not ok:
        raise ValueError(f"seed: got {seed!r}; must be an integer >= 0 or a non-empty list of them")
    entropy = [int(s) for s in items]
    return np.random.SeedSequence(entropy if isinstance(seed, (list, tuple)) else entropy[0])


def run_streams(seed) -> tuple[np.random.Generator, np.uint64]:
    """(initial-condition generator, in-loop key) of a run seed."""
    init_ss, loop_ss = seed_sequence(seed).spawn(2)
    return np.random.Generator(np.random.PCG64(init_ss)), loop_ss.generate_state(1, np.uint64)[0]


@inline
def _mix(z):
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@inline
def hash4(key, stream, step, index):
    """64-bit hash of (key, stream, step, index); all arguments are converted to uint64."""
    h = _mix(np.uint64(key) + _GOLDEN)
    h = _mix(h ^ (np.uint64(stream) + _GOLDEN))
    h = _mix(h ^ (np.uint64(step) + _GOLDEN))
    return _mix(h ^ (np.uint64(index) + _GOLDEN))


@inline
def uniform01(key, stream, step, index):
    """Uniform double in [0, 1) from the top 53 bits of ``hash4``."""
    return np.float64(hash4(key, stream, step, index) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@inline
def box_muller(u1, u2):
    """The standard normal Box-Muller makes of two uniforms in [0, 1)."""
    return math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)


@inline
def normal(key, stream, step, index):
    """Standard normal draw (Box-Muller) for (key, stream, step, index)."""
    u1 = uniform01(key, stream, step, np.uint64(2) * np.uint64(index))
    u2 = uniform01(key, stream, step, np.uint64(2) * np.uint64(index) + np.uint64(1))
    return box_muller(u1, u2)
