"""The ``couzin2002`` dynamics: Couzin, Krause, James, Ruxton & Franks (2002), as run-loop hooks
(:mod:`simcore.hooks`; docs/model.md, "Couzin et al. 2002").

Parameters (``[couzin]``, :mod:`simcore.couzin_params`) are packed into this dynamics' float slots ``C.*``.
Every boid has a unit heading f_i and moves at the constant speed s. Per step, from the sphere neighbours
of :func:`simcore.perception.perceive` within r_a = r_r + dr_o + dr_a (the grid or all-pairs search),
leaving out a neighbour at distance 0 and, with ``blind_deg`` = b > 0, those in the blind cone behind
(f_i . d_j < -cos(b/2) |d_j|):

1. desired direction d: when any neighbour is closer than r_r, d = -sum_{|d_j| < r_r} d_j/|d_j|
   (repulsion has priority); otherwise d_o = sum_{r_r <= |d_j| < r_o} f_j over the zone of orientation
   (r_o = r_r + dr_o) and d_a = sum_{r_o <= |d_j| < r_a} d_j/|d_j| over the zone of attraction, and d is
   d_o or d_a when only that zone has neighbours, (d_o/|d_o| + d_a/|d_a|) / 2 when both have. With no
   neighbour, or when d is zero, d = f_i. Then d is made unit.
2. angular noise: d turned by a wrapped Gaussian angle of sd sigma: in 2-D by sigma g about +z, in 3-D by
   the angle sigma |g| towards (g1 e1 + g2 e2)/|g| (:func:`simcore.headings.tilt`), g the counter-based
   standard normals of stream ``STREAMS["noise"]`` (:mod:`simcore.couzin_params`) at (step, i) in 2-D, (step, 2i) and (step, 2i + 1)
   in 3-D.
3. turning: the new heading is d when within theta dt of f_i, else f_i turned by theta dt towards d
   (:func:`simcore.headings.turn_toward`), then made unit.

``move`` sets v = s f_i (the new heading), p += v dt (the paper's c(t + tau) = c(t) + v(t + tau) tau),
the frame (:func:`simcore.headings.set_heading`) and the boundary. In 2-D (``world.dimensions = 2``) only
the x, y components are used and z stays 0. It has no leadership (never triggers).
"""
from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from .dynamics import apply_boundary
from .jit import inline, llvm_inline
from .headings import float_dyn, heading_scratch, rotate_planar, set_heading, tilt, turn_toward, unit_heading
from .layout import F, I, cos_deg
from .couzin_params import STREAMS
from .rng import normal

STREAM_NOISE = STREAMS["noise"]

C_SLOTS = {
    "R_R": lambda c: c.repulsion_radius,
    "R_O": lambda c: c.repulsion_radius + c.orientation_width,
    "R_A": lambda c: c.outer_radius,
    "BLIND": lambda c: float(c.blind_deg > 0.0),
    "COS_HALF_BLIND": lambda c: cos_deg(c.blind_deg / 2.0),
    "TURN_RATE": lambda c: math.radians(c.turning_rate_deg),
    "NOISE_SD": lambda c: c.noise_sd,
    "SPEED": lambda c: c.speed,
}
C = IntEnum("C", list(C_SLOTS), start=0)


def pack_couzin(couzin) -> np.ndarray:
    """The float slots ``C.*`` of a validated ``[couzin]`` table."""
    return np.array([value(couzin) for value in C_SLOTS.values()], dtype=np.float64)


@llvm_inline
def desired_direction(i, m, nbrs, fwd, cp, planar):
    """The unit desired direction d of boid i from its m neighbours (module docstring, step 1)."""
    rr, ro = cp[C.R_R], cp[C.R_O]
    blind, cos_blind = cp[C.BLIND] != 0.0, cp[C.COS_HALF_BLIND]
    fx, fy, fz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    rx = ry = rz = ox = oy = oz = ax = ay = az = 0.0
    n_r = n_o = n_a = 0
    for a in range(m):
        j = nbrs.idx[a]
        dx, dy, dz = nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2]
        if planar:
            dz = 0.0
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if dist == 0.0 or (blind and fx * dx + fy * dy + fz * dz < -cos_blind * dist):
            continue
        if dist < rr:
            rx, ry, rz = rx - dx / dist, ry - dy / dist, rz - dz / dist
            n_r += 1
        elif dist < ro:
            ox, oy, oz = ox + fwd[j, 0], oy + fwd[j, 1], oz + fwd[j, 2]
            n_o += 1
        else:
            ax, ay, az = ax + dx / dist, ay + dy / dist, az + dz / dist
            n_a += 1
    if n_r > 0:
        dx, dy, dz = rx, ry, rz
    elif n_o > 0 and n_a > 0:
        no = math.sqrt(ox * ox + oy * oy + oz * oz)
        na = math.sqrt(ax * ax + ay * ay + az * az)
        if no > 0.0:
            ox, oy, oz = ox / no, oy / no, oz / no
        if na > 0.0:
            ax, ay, az = ax / na, ay / na, az / na
        dx, dy, dz = 0.5 * (ox + ax), 0.5 * (oy + ay), 0.5 * (oz + az)
    elif n_o > 0:
        dx, dy, dz = ox, oy, oz
    else:
        dx, dy, dz = ax, ay, az
    if planar:
        dz = 0.0
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    if norm == 0.0:
        return fx, fy, fz
    return dx / norm, dy / norm, dz / norm


@inline
def noisy(dx, dy, dz, sd, key, step, i, planar):
    """d turned by the angular noise of boid i at this step (module docstring, step 2)."""
    if sd == 0.0:
        return dx, dy, dz
    if planar:
        x, y = rotate_planar(dx, dy, sd * normal(key, STREAM_NOISE, step, i))
        return x, y, 0.0
    g1 = normal(key, STREAM_NOISE, step, 2 * i)
    g2 = normal(key, STREAM_NOISE, step, 2 * i + 1)
    g = math.sqrt(g1 * g1 + g2 * g2)
    if g == 0.0:
        return dx, dy, dz
    return tilt(dx, dy, dz, sd * g, g1 / g, g2 / g)


@inline
def new_heading(i, step, m, nbrs, fwd, side, cp, dt, key, planar):
    """Boid i's unit heading after this step (module docstring, steps 1-3)."""
    dx, dy, dz = desired_direction(i, m, nbrs, fwd, cp, planar)
    dx, dy, dz = noisy(dx, dy, dz, cp[C.NOISE_SD], key, step, i, planar)
    hx, hy, hz = turn_toward(fwd[i, 0], fwd[i, 1], fwd[i, 2], dx, dy, dz, cp[C.TURN_RATE] * dt, side[i, 0],
                             side[i, 1], side[i, 2])
    return unit_heading(hx, hy, hz, planar)


# run-loop hooks (simcore.hooks)
scratch = heading_scratch   # per boid: its new heading


def pack(model, dt):
    """``dyn`` = (the ``C`` slots, no int slots, no obstacles, no ray fan)."""
    return float_dyn(pack_couzin(model.couzin))


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    """Boid i's new heading into its row of the per-boid buffer (no leadership: never triggers)."""
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    heading = scratch[0]
    heading[i, 0], heading[i, 1], heading[i, 2] = new_heading(i, step, m, nbrs, fwd, side, dyn[0], fp[F.DT], key,
                                                              ip[I.DIMENSIONS] == 2)
    return False


def move(dynamics, i, state, params, scratch):
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    heading = scratch[0]
    set_heading(i, heading[i, 0], heading[i, 1], heading[i, 2], dyn[0][C.SPEED], ip[I.DIMENSIONS] == 2, vel, fwd,
                up, side, acc, fp)
    dt = fp[F.DT]
    pos[i, 0] += vel[i, 0] * dt
    pos[i, 1] += vel[i, 1] * dt
    pos[i, 2] += vel[i, 2] * dt
    apply_boundary(i, pos, fp, ip)
