"""A numpy twin of the arena's walls (simcore.walls, docs/model.md section 16): the same rule written out
plainly, one boid at a time, for checking the kernel."""
from __future__ import annotations

import math

import numpy as np


def walls(arena, p, planar):
    """[(d, inward normal)] of every wall of ``arena`` (a simcore.arena.Arena) for the point p."""
    c = np.asarray(arena.centre, float)
    q = np.asarray(p, float) - c
    out = []
    if arena.kind == "cylinder":
        r = math.hypot(q[0], q[1])
        n = np.array([-q[0] / r, -q[1] / r, 0.0]) if r > 0 else np.array([-1.0, 0.0, 0.0])
        out.append((arena.radius - r, n))
        if not planar and arena.height is not None:
            half = arena.height / 2.0
            out.append((q[2] + half, np.array([0.0, 0.0, 1.0])))
            out.append((half - q[2], np.array([0.0, 0.0, -1.0])))
        return out
    for axis in range(2 if planar else 3):
        half = arena.size[axis] / 2.0
        e = np.zeros(3)
        e[axis] = 1.0
        out.append((q[axis] + half, e))
        out.append((half - q[axis], -e))
    return out


def contain(arena, p, v, dt, planar, constant_speed):
    """(p, v) of one boid after the walls: the wall term, then the reflecting fallback."""
    p, v = np.array(p, float), np.array(v, float)
    a = np.zeros(3)
    for d, n in walls(arena, p, planar):
        if 0.0 <= d < arena.wall_range:
            a += arena.wall_weight * (1.0 - d / arena.wall_range) * n
    if planar:
        a[2] = 0.0
    if a.any():
        speed = np.linalg.norm(v)
        v = v + a * dt
        if constant_speed and np.linalg.norm(v) > 0:
            v = v * (speed / np.linalg.norm(v))
    if arena.reflect:
        for k, (_, _) in enumerate(walls(arena, p, planar)):
            d, n = walls(arena, p, planar)[k]
            if d >= 0.0:
                continue
            if arena.kind == "cylinder" and k == 0:
                q = p[:2] - np.asarray(arena.centre[:2])
                r = np.linalg.norm(q)
                p[:2] = np.asarray(arena.centre[:2]) + q * (max(2.0 * arena.radius - r, 0.0) / r)
            else:
                axis = int(np.flatnonzero(n)[0])
                half = arena.size[axis] / 2.0 if arena.kind == "box" else arena.height / 2.0
                centre = arena.centre[axis]
                p[axis] = min(max(p[axis] - 2.0 * d * n[axis], centre - half), centre + half)
            if v @ n < 0.0:
                v = v - 2.0 * (v @ n) * n
    return p, v
