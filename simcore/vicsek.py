"""The ``vicsek`` dynamics: Vicsek, Czirók, Ben-Jacob, Cohen & Shochet (1995), as run-loop hooks
(:mod:`simcore.hooks`; docs/model.md, "Vicsek et al. 1995").

Parameters (``[vicsek]``, :mod:`simcore.vicsek_params`) are packed into the float slots ``V.*``. Every boid
has a unit heading f_i and moves at the constant speed v0. Per step, from the sphere neighbours of
:func:`simcore.perception.perceive` closer than r (the grid or all-pairs search; minimum image in a
periodic box):

1. mean heading m = f_i + sum_j f_j (the boid itself included), made unit (m = f_i when the sum is zero:
   the headings cancel exactly);
2. noise: in 2-D the new heading is m turned about +z by eta (u - 1/2), u the counter-based uniform of
   stream ``STREAMS["noise"]`` (:mod:`simcore.vicsek_params`) at (step, i): the paper's theta(t + 1) = <theta(t)>_r + dtheta with
   dtheta uniform in [-eta/2, eta/2]; in 3-D it is m tilted by the polar angle acos(1 - u0 eta / pi)
   towards azimuth 2 pi u1 (:func:`simcore.headings.tilt`), u0, u1 at (step, 2i) and (step, 2i + 1):
   uniform on the cap about m of solid angle 2 eta.

``move`` first moves the boid along its old heading, p += v0 f_i(t) dt (the paper's x(t + dt) = x(t) +
v(t) dt), then sets v = v0 f_i(t + dt) with its frame (:func:`simcore.headings.set_heading`) and applies
the boundary. In 2-D (``world.dimensions = 2``) z stays 0. It has no leadership (never triggers).
"""
from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from .dynamics import apply_boundary
from .headings import float_dyn, heading_scratch, rotate_planar, set_heading, tilt, unit_heading
from .jit import inline
from .layout import F, I
from .rng import uniform01
from .vicsek_params import STREAMS

V_SLOTS = {
    "SPEED": lambda v: v.speed,
    "NOISE": lambda v: v.noise,
}
V = IntEnum("V", list(V_SLOTS), start=0)
STREAM_NOISE = STREAMS["noise"]


def pack_vicsek(vicsek) -> np.ndarray:
    """The float slots ``V.*`` of a validated ``[vicsek]`` table."""
    return np.array([value(vicsek) for value in V_SLOTS.values()], dtype=np.float64)


@inline
def mean_heading(i, m, nbrs, fwd, planar):
    """The unit mean heading of boid i and its m neighbours (module docstring, step 1)."""
    mx, my, mz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    for a in range(m):
        j = nbrs.idx[a]
        mx, my, mz = mx + fwd[j, 0], my + fwd[j, 1], mz + fwd[j, 2]
    if planar:
        mz = 0.0
    norm = math.sqrt(mx * mx + my * my + mz * mz)
    if norm == 0.0:
        return fwd[i, 0], fwd[i, 1], fwd[i, 2]
    return mx / norm, my / norm, mz / norm


@inline
def new_heading(i, step, m, nbrs, fwd, eta, key, planar):
    """Boid i's unit heading after this step (module docstring, steps 1-2)."""
    mx, my, mz = mean_heading(i, m, nbrs, fwd, planar)
    if eta == 0.0:
        return mx, my, mz
    if planar:
        hx, hy = rotate_planar(mx, my, eta * (uniform01(key, STREAM_NOISE, step, i) - 0.5))
        return unit_heading(hx, hy, 0.0, planar)
    u0 = uniform01(key, STREAM_NOISE, step, 2 * i)
    u1 = uniform01(key, STREAM_NOISE, step, 2 * i + 1)
    polar = math.acos(max(-1.0, 1.0 - u0 * eta / math.pi))
    azimuth = 2.0 * math.pi * u1
    hx, hy, hz = tilt(mx, my, mz, polar, math.cos(azimuth), math.sin(azimuth))
    return unit_heading(hx, hy, hz, planar)


# run-loop hooks (simcore.hooks)
scratch = heading_scratch   # per boid: its new heading


def pack(model, dt):
    """``dyn`` = (the ``V`` slots, no int slots, no obstacles, no ray fan)."""
    return float_dyn(pack_vicsek(model.vicsek))


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    """Boid i's new heading into its row of the per-boid buffer (no leadership: never triggers)."""
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    heading = scratch[0]
    heading[i, 0], heading[i, 1], heading[i, 2] = new_heading(i, step, m, nbrs, fwd, dyn[0][V.NOISE], key,
                                                              ip[I.DIMENSIONS] == 2)
    return False


def move(dynamics, i, state, params, scratch):
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    heading = scratch[0]
    speed, dt = dyn[0][V.SPEED], fp[F.DT]
    pos[i, 0] += speed * fwd[i, 0] * dt
    pos[i, 1] += speed * fwd[i, 1] * dt
    pos[i, 2] += speed * fwd[i, 2] * dt
    set_heading(i, heading[i, 0], heading[i, 1], heading[i, 2], speed, ip[I.DIMENSIONS] == 2, vel, fwd, up, side,
                acc, fp)
    apply_boundary(i, pos, fp, ip)
