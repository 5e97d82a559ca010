"""Slow, plain numpy twin of :mod:`simcore.noise` (the draws, the von Mises-Fisher turn, the drive) and of
the per-step constants :mod:`simcore.layout` packs for it; docs/model.md section 3.5."""
from __future__ import annotations

import math

import numpy as np

from reference_metrics import uniform01

STREAM_HEADING_NOISE, STREAM_SPEED_NOISE = 4, 5


def normal(key: int, stream: int, step: int, index: int) -> float:
    """Box-Muller on the uniforms at indices 2 index and 2 index + 1 (docs/model.md section 7.2)."""
    u1 = uniform01(key, stream, step, 2 * index)
    u2 = uniform01(key, stream, step, 2 * index + 1)
    return math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)


def draws(key: int, step: int, i: int) -> tuple[float, float, float]:
    """(U1, U2, z) of boid i at a step."""
    return (uniform01(key, STREAM_HEADING_NOISE, step, 2 * i), uniform01(key, STREAM_HEADING_NOISE, step, 2 * i + 1),
            normal(key, STREAM_SPEED_NOISE, step, i))


def vmf_turn(d, u1: float, u2: float, kappa: float) -> np.ndarray:
    """The turned heading: cosine w from the inverse CDF of the vMF cosine on the sphere, azimuth 2 pi u2 in
    the basis any orthonormal completion gives (here Duff et al.'s, written out with numpy)."""
    d = np.asarray(d, dtype=np.float64)
    v = 1.0 - u1
    w = 1.0 + np.log(v + (1.0 - v) * np.exp(-2.0 * kappa)) / kappa
    w = float(np.clip(w, -1.0, 1.0))
    sign = 1.0 if d[2] >= 0.0 else -1.0
    g = -1.0 / (sign + d[2])
    h = d[0] * d[1] * g
    a = np.array([1.0 + sign * d[0] ** 2 * g, sign * h, -sign * d[0]])
    b = np.array([h, sign + d[1] ** 2 * g, -d[1]])
    assert abs(a @ d) < 1e-12 and abs(b @ d) < 1e-12 and abs(a @ b) < 1e-12
    phi = 2.0 * np.pi * u2
    return w * d + np.sqrt(max(0.0, 1.0 - w * w)) * (np.cos(phi) * a + np.sin(phi) * b)


def drive(v, f, u1: float, u2: float, z: float, kappa: float, kick: float, v0: float | None,
          decay: float, planar_sd: float = 0.0) -> np.ndarray:
    """Cruise, speed kick and turn of a candidate velocity v with heading f; in 2-D (``planar_sd`` > 0, kappa
    0) the turn is the rotation about +z by planar_sd times the Box-Muller normal of u1, u2."""
    v = np.asarray(v, dtype=np.float64)
    s = float(np.linalg.norm(v))
    d = v / s if s > 0 else np.asarray(f, dtype=np.float64)
    if v0 is not None:
        s = v0 + (s - v0) * decay
    if kick > 0:
        s = max(s + kick * z, 0.0)
    if kappa > 0:
        d = vmf_turn(d, u1, u2, kappa)
    if planar_sd > 0:
        angle = planar_sd * math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
        d = np.array([math.cos(angle) * d[0] - math.sin(angle) * d[1], math.sin(angle) * d[0] + math.cos(angle) * d[1],
                      d[2]])
    return s * d


def mean_cosine(kappa: float) -> float:
    """E[w] of the vMF on the sphere: coth(kappa) - 1/kappa."""
    return 1.0 / math.tanh(kappa) - 1.0 / kappa
