"""The ``reynolds87`` dynamics: Reynolds' (1987) boids, as run-loop hooks (:mod:`simcore.hooks`;
docs/model.md, "Reynolds 1987").

``pack_reynolds(model) -> (rp, ri, table, kinds)`` packs the ``[reynolds]`` table (float slots ``R.*``, int
slots ``RI.*``) and the obstacles (:func:`simcore.obstacle_spec.pack_obstacles`); ``pack`` makes them this
dynamics' ``dyn`` group. The run loops of :mod:`simcore.kernel` run it like every dynamics: ``sense``
stores each boid's acceleration, ``move`` moves it; ``fp, ip`` are the shared packed parameters
(:func:`simcore.layout.pack`: perception sphere, boundary, update order, search). It has no leadership
(never triggers) and runs one thread per run (``THREADS``).

Per boid and step (``boid_accel``), from the sphere neighbours of :func:`simcore.perception.perceive`
(the same grid or all-pairs search as the other models; a neighbour at distance 0 is skipped: it has no
direction and an infinite weight), with w_j = |d_j|^-k:

1. requests, in priority order: obstacle avoidance w_o * steer-to-avoid direction
   (:func:`simcore.obstacle_avoidance.steer_to_avoid`, every obstacle tested, culled by its bounding
   ball), separation w_s sum_j -d_j/|d_j| w_j, alignment w_a (sum_j w_j v_j / sum_j w_j - v_i), cohesion
   w_c sum_j w_j d_j / sum_j w_j, migration w_m g (every boid, or only front boids: no neighbour with
   f_i . d_j > 0);
2. allocation (``ALLOC_*``): ``priority`` adds requests while the running vector sum stays within
   ``max_accel``; the request that would carry |sum| past it is added scaled by the s in (0, 1] with
   |a + s r| = max_accel, and the rest are dropped (the budget counts as reached from ``FULL`` = 1 - 1e-12
   of it, so a request of exactly max_accel fills it whatever the last bit of its direction's rounding:
   otherwise a next request pointing back into the budget ball could still be added in part); ``priority_magnitude`` does the same with the sum of
   the requests' magnitudes (Reynolds' accumulator); ``weighted_sum`` adds all and truncates to
   ``max_accel``.

``move_boid`` then sets v' = v + a dt (driven by cruise and noise when on, :mod:`simcore.noise`), its length clamped into [min_speed, max_speed] (a boid at zero
speed restarts at min_speed along f), p += v' dt, stores the realised acceleration (v' - v) / dt in ``acc``,
rebuilds the banking frame (:func:`simcore.dynamics.rebuild_frame`; in 2-D the planar frame of
:func:`simcore.dynamics.new_frame`, with a's z set to 0 first) and applies the boundary.
Synchronous order: every boid's acceleration from the state at t, then all move; sequential: boid i
perceives, decides and moves before boid i + 1 (re-binned at once; :mod:`simcore.kernel`).
"""
from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from .dynamics import apply_boundary, new_frame
from .jit import inline, llvm_inline
from .layout import F, I
from .noise import DRAWS, drive_row, store_draws
from .obstacle_avoidance import steer_to_avoid
from .obstacle_spec import pack_obstacles
from .reynolds_params import ALLOCATIONS, MIGRATION_WHO

R_SLOTS = {
    "FALLOFF": lambda r: r.falloff_exponent,
    "MAX_ACCEL": lambda r: r.max_accel,
    "MIN_SPEED": lambda r: r.min_speed,
    "MAX_SPEED": lambda r: r.max_speed,
    "W_OBSTACLE": lambda r: r.obstacle_weight,
    "W_SEPARATION": lambda r: r.separation_weight,
    "W_ALIGNMENT": lambda r: r.alignment_weight,
    "W_COHESION": lambda r: r.cohesion_weight,
    "LOOKAHEAD": lambda r: r.lookahead,
    "MARGIN": lambda r: r.avoid_margin,
    "BODY_R": lambda r: r.body_radius,
    "GX": lambda r: r.migration_direction[0],
    "GY": lambda r: r.migration_direction[1],
    "GZ": lambda r: r.migration_direction[2],
    "W_MIGRATION": lambda r: r.migration_weight,
}
RI_SLOTS = {
    "ALLOCATION": lambda r: ALLOCATIONS.index(r.allocation),
    "WHO": lambda r: MIGRATION_WHO.index(r.migration_who),
}
R = IntEnum("R", list(R_SLOTS), start=0)
RI = IntEnum("RI", list(RI_SLOTS), start=0)
ALLOC_PRIORITY, ALLOC_PRIORITY_MAGNITUDE, ALLOC_WEIGHTED_SUM = range(3)
WHO_ALL, WHO_FRONT = range(2)
FULL = 1.0 - 1e-12  # the budget counts as reached from this share of max_accel (of its square, vector sum)
assert ALLOCATIONS == ("priority", "priority_magnitude", "weighted_sum")
assert MIGRATION_WHO == ("all", "front")


def pack_reynolds(model):
    """(rp float64, ri int64, obstacle table, obstacle kinds) of a validated reynolds87 model."""
    rey = model.reynolds
    rp = np.array([value(rey) for value in R_SLOTS.values()], dtype=np.float64)
    ri = np.array([value(rey) for value in RI_SLOTS.values()], dtype=np.int64)
    table, kinds = pack_obstacles(model.world.obstacles)
    return rp, ri, table, kinds


@inline
def crossing_scale(ax, ay, az, rx, ry, rz, limit):
    """The s in (0, 1] with |a + s r| = limit, for |a| < limit < |a + r| (the positive root of
    |r|^2 s^2 + 2 (a . r) s + |a|^2 - limit^2 = 0, in the form free of cancellation)."""
    room = limit * limit - (ax * ax + ay * ay + az * az)
    b = ax * rx + ay * ry + az * rz
    r2 = rx * rx + ry * ry + rz * rz
    root = math.sqrt(b * b + r2 * room)
    if b >= 0.0:
        return room / (b + root)
    return (root - b) / r2


@inline
def allocate(ax, ay, az, used, full, rx, ry, rz, limit, mode):
    """Add request r to the accumulator a (``used``: magnitudes spent so far; ``full``: budget reached) by
    the allocation ``mode``; returns the new (ax, ay, az, used, full)."""
    if full or (rx == 0.0 and ry == 0.0 and rz == 0.0):
        return ax, ay, az, used, full
    if mode == ALLOC_WEIGHTED_SUM:
        return ax + rx, ay + ry, az + rz, used, False
    if mode == ALLOC_PRIORITY_MAGNITUDE:
        size = math.sqrt(rx * rx + ry * ry + rz * rz)
        if used + size <= limit:
            return ax + rx, ay + ry, az + rz, used + size, used + size >= limit * FULL
        s = (limit - used) / size
        return ax + s * rx, ay + s * ry, az + s * rz, limit, True
    nx, ny, nz = ax + rx, ay + ry, az + rz
    n2 = nx * nx + ny * ny + nz * nz
    if n2 <= limit * limit:
        return nx, ny, nz, used, n2 >= limit * limit * FULL
    s = crossing_scale(ax, ay, az, rx, ry, rz, limit)
    return ax + s * rx, ay + s * ry, az + s * rz, used, True


@inline
def distance_weight(dd, dist, k):
    """|d|^-k from |d|^2 and |d|: 1/|d|^2, 1/|d| and 1 for k = 2, 1, 0 (no pow call: a pow costs ten
    times the rest of a neighbour's terms), pow otherwise."""
    if k == 2.0:
        return 1.0 / dd
    if k == 1.0:
        return 1.0 / dist
    if k == 0.0:
        return 1.0
    return dist ** -k


@llvm_inline
def boid_accel(i, m, nbrs, pos, vel, fwd, up, rp, ri, table, kinds):
    """(ax, ay, az): the allocated acceleration of boid i from its m neighbours (module docstring)."""
    k = rp[R.FALLOFF]
    sx = sy = sz = 0.0
    wvx = wvy = wvz = 0.0
    wdx = wdy = wdz = 0.0
    wsum = 0.0
    fx, fy, fz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    ahead = False
    for a in range(m):
        j = nbrs.idx[a]
        dx, dy, dz = nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2]
        if fx * dx + fy * dy + fz * dz > 0.0:
            ahead = True
        dd = dx * dx + dy * dy + dz * dz
        if dd == 0.0:
            continue
        dist = math.sqrt(dd)
        w = distance_weight(dd, dist, k)
        sx -= dx / dist * w
        sy -= dy / dist * w
        sz -= dz / dist * w
        wvx += w * vel[j, 0]
        wvy += w * vel[j, 1]
        wvz += w * vel[j, 2]
        wdx += w * dx
        wdy += w * dy
        wdz += w * dz
        wsum += w
    limit = rp[R.MAX_ACCEL]
    mode = ri[RI.ALLOCATION]
    ax = ay = az = 0.0
    used = 0.0
    full = False
    if kinds.shape[0] > 0 and rp[R.W_OBSTACLE] > 0.0:
        hit, t, ox, oy, oz = steer_to_avoid(table, kinds, pos[i, 0], pos[i, 1], pos[i, 2], fx, fy, fz, up[i, 0],
                                            up[i, 1], up[i, 2], rp[R.BODY_R], rp[R.LOOKAHEAD], rp[R.MARGIN])
        wo = rp[R.W_OBSTACLE]
        ax, ay, az, used, full = allocate(ax, ay, az, used, full, wo * ox, wo * oy, wo * oz, limit, mode)
    ws = rp[R.W_SEPARATION]
    ax, ay, az, used, full = allocate(ax, ay, az, used, full, ws * sx, ws * sy, ws * sz, limit, mode)
    if wsum > 0.0:
        wa = rp[R.W_ALIGNMENT]
        ax, ay, az, used, full = allocate(ax, ay, az, used, full, wa * (wvx / wsum - vel[i, 0]),
                                          wa * (wvy / wsum - vel[i, 1]), wa * (wvz / wsum - vel[i, 2]), limit, mode)
        wc = rp[R.W_COHESION]
        ax, ay, az, used, full = allocate(ax, ay, az, used, full, wc * (wdx / wsum), wc * (wdy / wsum),
                                          wc * (wdz / wsum), limit, mode)
    wm = rp[R.W_MIGRATION]
    if wm > 0.0 and (ri[RI.WHO] == WHO_ALL or not ahead):
        ax, ay, az, used, full = allocate(ax, ay, az, used, full, wm * rp[R.GX], wm * rp[R.GY], wm * rp[R.GZ],
                                          limit, mode)
    if mode == ALLOC_WEIGHTED_SUM:
        a2 = ax * ax + ay * ay + az * az
        if a2 > limit * limit:
            scale = limit / math.sqrt(a2)
            ax, ay, az = ax * scale, ay * scale, az * scale
    return ax, ay, az


@llvm_inline
def move_boid(i, ax, ay, az, pos, vel, fwd, up, side, acc, fp, ip, rp, draws, col):
    """Velocity, position, frame and boundary update of boid i under acceleration a (module docstring);
    boid i's noise draws (when cruise or noise is on) are in ``draws[i, col:]``."""
    dt = fp[F.DT]
    planar = ip[I.DIMENSIONS] == 2
    if planar:
        az = 0.0
    vx0, vy0, vz0 = vel[i, 0], vel[i, 1], vel[i, 2]
    vx, vy, vz = vx0 + ax * dt, vy0 + ay * dt, vz0 + az * dt
    if ip[I.DRIVE] != 0:
        vx, vy, vz = drive_row(vx, vy, vz, i, fwd, draws, col, fp)
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    lo, hi = rp[R.MIN_SPEED], rp[R.MAX_SPEED]
    if speed > hi:
        scale = hi / speed
        vx, vy, vz = vx * scale, vy * scale, vz * scale
    elif speed < lo:
        if speed > 0.0:
            scale = lo / speed
            vx, vy, vz = vx * scale, vy * scale, vz * scale
        else:
            vx, vy, vz = lo * fwd[i, 0], lo * fwd[i, 1], lo * fwd[i, 2]
    vel[i, 0], vel[i, 1], vel[i, 2] = vx, vy, vz
    pos[i, 0] += vx * dt
    pos[i, 1] += vy * dt
    pos[i, 2] += vz * dt
    acc[i, 0], acc[i, 1], acc[i, 2] = (vx - vx0) / dt, (vy - vy0) / dt, (vz - vz0) / dt
    new_frame(i, vx, vy, vz, math.sqrt(vx * vx + vy * vy + vz * vz), fwd, up, side, acc, dt, planar)
    apply_boundary(i, pos, fp, ip)


# run-loop hooks (simcore.hooks)


def pack(model, dt):
    """``dyn`` = (rp, ri, obstacle table, obstacle kinds, an empty ray fan)."""
    rp, ri, table, kinds = pack_reynolds(model)
    return rp, ri, table, kinds, np.zeros((0, 3))


def scratch(dynamics, n):
    """Per boid: its acceleration (columns 0-2), then its noise draws (:mod:`simcore.noise`)."""
    return np.zeros((n, 3 + DRAWS), np.float64), np.zeros((0, 3), np.float64)


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    """Boid i's allocated acceleration into its row of the per-boid buffer (no leadership: never triggers)."""
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    rp, ri, table, kinds, fan = dyn
    accel = scratch[0]
    accel[i, 0], accel[i, 1], accel[i, 2] = boid_accel(i, m, nbrs, pos, vel, fwd, up, rp, ri, table, kinds)
    if ip[I.DRIVE] != 0:
        store_draws(accel, i, 3, key, step)
    return False


def move(dynamics, i, state, params, scratch):
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    accel = scratch[0]
    move_boid(i, accel[i, 0], accel[i, 1], accel[i, 2], pos, vel, fwd, up, side, acc, fp, ip, dyn[0], accel, 3)
