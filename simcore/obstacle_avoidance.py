"""Obstacle avoidance directions: Reynolds' steer-to-avoid and the Boids++ golden-angle ray fan.

Both take the packed obstacles (``table``, ``kinds``, see :mod:`simcore.obstacle_spec`), the boid's
centre p, its body frame (forward f, up u, side s = f x u, orthonormal) and its body radius b, and
return a unit direction the rules can weight. Compiled with numba (cached, no fastmath), no allocation;
:func:`golden_fan` builds the fan table once, in Python.

Inside first
    When the body already touches or overlaps an obstacle (sd(p) <= b, see :mod:`simcore.obstacles`)
    both behaviours ask for the outward normal of the obstacle overlapped most: the shortest way out.

Steer-to-avoid (Reynolds 1987)
    Only obstacles whose inflated shape the forward ray meets within ``lookahead`` count; the nearest
    hit (lower index on ties) is avoided: the request is normalize(T - p) toward the target one
    ``margin`` beyond the silhouette edge nearest to the ray (:mod:`simcore.silhouettes`), or, for a
    plane, f with its normal part removed.

Boids++ ray fan (Zhao and Osama)
    ``golden_fan(rays)`` gives ray directions in the body frame: ray i at polar angle theta_i from f with
    cos(theta_i) = 1 - i/rays (equal areas of the forward hemisphere per ray, ray 0 exactly forward) and
    azimuth i times the golden angle pi (3 - sqrt 5), measured from u toward s; so the rays are ordered
    from forward outward. When the forward ray hits an inflated obstacle within lookahead the boid asks
    for the first fan ray that hits none; when every ray hits, for the ray whose first hit is farthest
    (first in order on ties).
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from .obstacle_spec import KIND_PLANE
from .obstacles import deepest_overlap, nearest_hit
from .silhouettes import silhouette_target

FAN_CLEAR = -1   # forward ray unobstructed: no avoidance
FAN_INSIDE = -2  # body overlaps an obstacle: escape along its normal
GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


@nb.njit(cache=True, error_model="numpy")
def steer_to_avoid(table, kinds, px, py, pz, fx, fy, fz, ux, uy, uz, body_radius, lookahead, margin):
    """(k, t, dx, dy, dz): Reynolds' steer-to-avoid for a boid at p with forward f and up u.

    k is the obstacle avoided (-1: none, d = 0), t the distance to its hit (0 when the body already
    touches or overlaps it, inf when none), d the requested unit direction."""
    k, sd, nx, ny, nz = deepest_overlap(table, kinds, px, py, pz, body_radius)
    if k >= 0:
        return k, 0.0, nx, ny, nz
    k, t = nearest_hit(table, kinds, px, py, pz, fx, fy, fz, body_radius, lookahead, True)
    if k < 0:
        return -1, math.inf, 0.0, 0.0, 0.0
    tx, ty, tz, ox, oy, oz, delta = silhouette_target(table, kinds, k, px, py, pz, fx, fy, fz, ux, uy, uz,
                                                      body_radius, margin)
    if kinds[k] == KIND_PLANE:
        return k, t, ox, oy, oz
    dx, dy, dz = tx - px, ty - py, tz - pz
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    return k, t, dx / norm, dy / norm, dz / norm


def golden_fan(rays: int) -> np.ndarray:
    """float64 (rays, 3): fan directions as (forward, up, side) coefficients (see module docstring)."""
    if rays < 1:
        raise ValueError(f"golden_fan: rays must be >= 1, got {rays!r}")
    index = np.arange(rays, dtype=np.float64)
    frac = index / rays
    sin_polar = np.sqrt(frac * (2.0 - frac))
    azimuth = np.mod(index * GOLDEN_ANGLE, 2.0 * math.pi)
    return np.column_stack([1.0 - frac, sin_polar * np.cos(azimuth), sin_polar * np.sin(azimuth)])


@nb.njit(cache=True, error_model="numpy")
def fan_direction(fan, i, fx, fy, fz, ux, uy, uz, sx, sy, sz):
    """World direction of fan ray i in the body frame (f, u, s), normalised (ray 0 is f itself)."""
    if i == 0:
        return fx, fy, fz
    a, b, c = fan[i, 0], fan[i, 1], fan[i, 2]
    dx, dy, dz = a * fx + b * ux + c * sx, a * fy + b * uy + c * sy, a * fz + b * uz + c * sz
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx / norm, dy / norm, dz / norm


@nb.njit(cache=True, error_model="numpy")
def fan_avoid_direction(table, kinds, fan, px, py, pz, fx, fy, fz, ux, uy, uz, sx, sy, sz, body_radius,
                        lookahead):
    """(ray, dx, dy, dz, free): the Boids++ avoidance direction of a boid at p with frame (f, u, s).

    ray = FAN_CLEAR (-1) when the forward ray is unobstructed (d = 0, free = lookahead); FAN_INSIDE (-2)
    when the body touches or overlaps an obstacle (d its outward normal, free = 0); otherwise the index
    of the chosen fan ray, d its direction and free the distance to its first hit (lookahead if none)."""
    k, sd, nx, ny, nz = deepest_overlap(table, kinds, px, py, pz, body_radius)
    if k >= 0:
        return FAN_INSIDE, nx, ny, nz, 0.0
    k, t = nearest_hit(table, kinds, px, py, pz, fx, fy, fz, body_radius, lookahead, True)
    if k < 0:
        return FAN_CLEAR, 0.0, 0.0, 0.0, lookahead
    best_ray, best_free = 0, t
    bx, by, bz = fx, fy, fz
    for i in range(1, fan.shape[0]):
        dx, dy, dz = fan_direction(fan, i, fx, fy, fz, ux, uy, uz, sx, sy, sz)
        k, t = nearest_hit(table, kinds, px, py, pz, dx, dy, dz, body_radius, lookahead, True)
        if k < 0:
            return i, dx, dy, dz, lookahead
        if t > best_free:
            best_ray, best_free, bx, by, bz = i, t, dx, dy, dz
    return best_ray, bx, by, bz, best_free
