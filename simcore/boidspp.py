"""The Boids++ dynamics (docs/model.md section 6), as run-loop hooks (:mod:`simcore.hooks`).

The run loops of :mod:`simcore.kernel` run it like every dynamics, with its per-step hooks
(``begin_step``, ``record_extra``, ``before_boids``, ``after_boids``) for the agents, and fill, besides the
common records, ``rec_agents`` float64 (R, 2, 3) (predator and prey positions, NaN while absent) and
``capture_step`` int64 (N,): the first step at which each boid was within the predator's capture radius
(-1: never; only when a radius is set). ``agents`` is the state's agent array
(:mod:`simcore.boidspp_layout`); ``fp``/``ip`` the shared slots (perception, world, dt, max_speed), its
``dyn`` group (``pack``) the Boids++ slots ``bp``/``bi``, the obstacles ``table``/``kinds`` and the ray fan.

One step s (time s dt):

1. agents appear: the prey (when enabled and not yet placed) at a random point of its target ball, with
   its first target; the predator (when enabled, from its start step) at ``start_distance`` from the
   flock centre in a random direction; it hunts until its leave step, then leaves;
2. record (every ``record_every`` steps; the last record perceives the final state without moving);
3. captures: boids within the capture radius of a present predator get their first capture step;
4. each boid perceives and computes its new velocity (:func:`boid_velocity`): within ``avoid_radius`` of
   the predator it flees and skips the rules and the prey; else the blends alignment, cohesion,
   separation (alignment and cohesion over the neighbours, or with scope ``flock`` over every other
   boid, from sums over the flock taken once at the start of the step), then the prey seek; then the
   random kick (steps that are multiples of ``every``), the obstacle fan avoidance, cruise and noise
   when on (:func:`simcore.noise.drive`, drawn here), and the clamp to [min_speed, max_speed];
5. the agents move, steered by the flock of time t: the predator toward (hunting) the mean offset to
   the boids (or, with ``target = "nearest"``, the offset to the nearest boid), or away from (leaving)
   the mean offset, the prey straight to its target (a new one on arrival);
6. the boids move: p += v dt, frame rebuilt with the realised acceleration (v - v_old)/dt, boundary.

In 2-D (``world.dimensions = 2``) the random kick and the predator's start direction are uniform on the
circle (angle 2 pi times the second of their two uniforms), the prey's points are uniform in the disc of
its target radius (radius R u^(1/2)), the new velocity's z is set to 0 before its clamp and the frame
stays in the plane (:func:`simcore.dynamics.new_frame`); obstacles and a prey centre off the plane are
refused (:func:`simcore.params.ModelParams`).

Synchronous order computes every velocity from the state at time t, then moves all; sequential order
moves boid i before boid i + 1 perceives (re-binned at once). In-loop draws are counter-based
(:mod:`simcore.rng`): the random kick of boid i at step s uses stream ``STREAMS["random_force"]`` at
(s, 2 i) and (s, 2 i + 1); the prey's k-th point and the predator's start direction use
``STREAMS["targets"]`` at (k, 0..2) and (0, 3..4). Batches run B runs in parallel threads, each by the same
code as alone (:func:`simcore.simulate.simulate_batch`); one run is one thread (``THREADS``).
"""
from __future__ import annotations

import math

import numpy as np

from .boidspp_layout import (B, BI, COUNTERS, PHASE_HUNTING, PHASE_LEAVING, PHASE_WAITING, PRED_POS, PRED_VEL,
                             PREY_POS, PREY_TARGET, PREY_VEL, SCOPE_FLOCK, SEP_INVERSE_SQUARE, TARGET_NEAREST,
                             pack_boidspp)
from .dynamics import apply_boundary, new_frame
from .jit import inline, llvm_inline
from .layout import BOUNDARY_PERIODIC, F, I
from .neighbours import RULE_ALIGNMENT, RULE_COHESION, RULE_SEPARATION, offset_to
from .obstacle_avoidance import FAN_CLEAR, fan_avoid_direction
from .noise import drive
from .boidspp_params import STREAMS
from .rng import STREAM_HEADING_NOISE, STREAM_SPEED_NOISE, normal, uniform01

STREAM_RANDOM_FORCE, STREAM_TARGETS = STREAMS["random_force"], STREAMS["targets"]


@inline
def unit_from(u0, u1):
    """A unit vector, uniform on the sphere, from two uniforms in [0, 1) (z = 2 u0 - 1, azimuth 2 pi u1)."""
    z = 2.0 * u0 - 1.0
    r = math.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * u1
    return r * math.cos(phi), r * math.sin(phi), z


@inline
def random_unit(u0, u1, planar):
    """:func:`unit_from` in 3-D; in the plane z = 0 the unit vector at angle 2 pi u1 (u0 unused)."""
    if planar:
        phi = 2.0 * math.pi * u1
        return math.cos(phi), math.sin(phi), 0.0
    return unit_from(u0, u1)


@inline
def prey_point(key, k, bp, planar):
    """The prey's k-th random point: uniform in the ball of its target radius about its target centre (in
    the plane: the disc, radius R u^(1/2) at the angle of :func:`random_unit`)."""
    ux, uy, uz = random_unit(uniform01(key, STREAM_TARGETS, k, 0), uniform01(key, STREAM_TARGETS, k, 1), planar)
    r = bp[B.PREY_TARGET_R] * uniform01(key, STREAM_TARGETS, k, 2) ** (0.5 if planar else 1.0 / 3.0)
    return bp[B.PREY_CX] + r * ux, bp[B.PREY_CY] + r * uy, bp[B.PREY_CZ] + r * uz


@inline
def flock_offset(pos, x, y, z, periodic, box):
    """Mean offset from (x, y, z) to the boids (minimum image in a periodic box), in boid order."""
    sx = sy = sz = 0.0
    for j in range(pos.shape[0]):
        dx, dy, dz = offset_to(pos[j, 0], pos[j, 1], pos[j, 2], x, y, z, periodic, box)
        sx += dx
        sy += dy
        sz += dz
    n = pos.shape[0]
    return sx / n, sy / n, sz / n


@inline
def nearest_offset(pos, x, y, z, periodic, box):
    """Offset from (x, y, z) to the nearest boid (minimum image; the lower index on ties)."""
    bx = by = bz = 0.0
    best = math.inf
    for j in range(pos.shape[0]):
        dx, dy, dz = offset_to(pos[j, 0], pos[j, 1], pos[j, 2], x, y, z, periodic, box)
        dd = dx * dx + dy * dy + dz * dz
        if dd < best:
            best, bx, by, bz = dd, dx, dy, dz
    return bx, by, bz


@inline
def scaled(x, y, z, length):
    """(x, y, z) with the given length (zero stays zero)."""
    norm = math.sqrt(x * x + y * y + z * z)
    if norm == 0.0:
        return 0.0, 0.0, 0.0
    k = length / norm
    return x * k, y * k, z * k


@inline
def place_agents(step, pos, agents, fp, ip, bp, bi, key):
    """Step 1 of the module docstring: the prey's first point and target, the predator's appearance and
    departure."""
    if bi[BI.PREY_ON] != 0 and agents[COUNTERS, 0] == 0.0:
        planar = ip[I.DIMENSIONS] == 2
        agents[PREY_POS, 0], agents[PREY_POS, 1], agents[PREY_POS, 2] = prey_point(key, 0, bp, planar)
        agents[PREY_TARGET, 0], agents[PREY_TARGET, 1], agents[PREY_TARGET, 2] = prey_point(key, 1, bp, planar)
        agents[PREY_VEL, 0] = agents[PREY_VEL, 1] = agents[PREY_VEL, 2] = 0.0
        agents[COUNTERS, 0] = 2.0
    if bi[BI.PRED_ON] == 0:
        return
    if agents[COUNTERS, 1] == PHASE_WAITING and step >= bi[BI.PRED_START]:
        periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
        cx, cy, cz = flock_offset(pos, 0.0, 0.0, 0.0, periodic, fp[F.BOX])
        ux, uy, uz = random_unit(uniform01(key, STREAM_TARGETS, 0, 3), uniform01(key, STREAM_TARGETS, 0, 4),
                                 ip[I.DIMENSIONS] == 2)
        d = bp[B.PRED_START_DIST]
        agents[PRED_POS, 0], agents[PRED_POS, 1], agents[PRED_POS, 2] = cx + d * ux, cy + d * uy, cz + d * uz
        agents[PRED_VEL, 0] = agents[PRED_VEL, 1] = agents[PRED_VEL, 2] = 0.0
        agents[COUNTERS, 1] = PHASE_HUNTING
    if agents[COUNTERS, 1] == PHASE_HUNTING and step >= bi[BI.PRED_LEAVE]:
        agents[COUNTERS, 1] = PHASE_LEAVING


@inline
def agent_velocities(pos, agents, fp, ip, bp, bi):
    """New velocities of the predator and the prey from the state of time t (step 5), without moving."""
    periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
    box = fp[F.BOX]
    dt = fp[F.DT]
    phase = agents[COUNTERS, 1]
    qx = qy = qz = 0.0
    if bi[BI.PRED_ON] != 0 and phase != PHASE_WAITING:
        px, py, pz = agents[PRED_POS, 0], agents[PRED_POS, 1], agents[PRED_POS, 2]
        if phase == PHASE_HUNTING and bi[BI.PRED_TARGET] == TARGET_NEAREST:
            ox, oy, oz = nearest_offset(pos, px, py, pz, periodic, box)
        else:
            ox, oy, oz = flock_offset(pos, px, py, pz, periodic, box)
        sign = 1.0 if phase == PHASE_HUNTING else -1.0
        qx, qy, qz = scaled(sign * ox, sign * oy, sign * oz, bp[B.PRED_SPEED])
    yx = yy = yz = 0.0
    if bi[BI.PREY_ON] != 0:
        dx = agents[PREY_TARGET, 0] - agents[PREY_POS, 0]
        dy = agents[PREY_TARGET, 1] - agents[PREY_POS, 1]
        dz = agents[PREY_TARGET, 2] - agents[PREY_POS, 2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        yx, yy, yz = scaled(dx, dy, dz, min(bp[B.PREY_SPEED], dist / dt))
    return qx, qy, qz, yx, yy, yz


@inline
def move_agents(qx, qy, qz, yx, yy, yz, agents, fp, ip, bp, bi, key):
    """Move the agents with the velocities of :func:`agent_velocities`; the prey draws a new target when
    within its arrival radius; the predator obeys the world boundary (the prey stays in its ball)."""
    dt = fp[F.DT]
    if bi[BI.PRED_ON] != 0 and agents[COUNTERS, 1] != PHASE_WAITING:
        agents[PRED_VEL, 0], agents[PRED_VEL, 1], agents[PRED_VEL, 2] = qx, qy, qz
        agents[PRED_POS, 0] += qx * dt
        agents[PRED_POS, 1] += qy * dt
        agents[PRED_POS, 2] += qz * dt
        apply_boundary(PRED_POS, agents, fp, ip)
    if bi[BI.PREY_ON] != 0:
        agents[PREY_VEL, 0], agents[PREY_VEL, 1], agents[PREY_VEL, 2] = yx, yy, yz
        agents[PREY_POS, 0] += yx * dt
        agents[PREY_POS, 1] += yy * dt
        agents[PREY_POS, 2] += yz * dt
        dx = agents[PREY_TARGET, 0] - agents[PREY_POS, 0]
        dy = agents[PREY_TARGET, 1] - agents[PREY_POS, 1]
        dz = agents[PREY_TARGET, 2] - agents[PREY_POS, 2]
        if dx * dx + dy * dy + dz * dz <= bp[B.PREY_ARRIVE] * bp[B.PREY_ARRIVE]:
            k = agents[COUNTERS, 0]
            agents[PREY_TARGET, 0], agents[PREY_TARGET, 1], agents[PREY_TARGET, 2] = prey_point(key, int(k), bp,
                                                                                              ip[I.DIMENSIONS] == 2)
            agents[COUNTERS, 0] = k + 1.0


@inline
def blend(s, tx, ty, tz, vx, vy, vz):
    """v <- S target + (1 - S) v."""
    return s * tx + (1.0 - s) * vx, s * ty + (1.0 - s) * vy, s * tz + (1.0 - s) * vz


@inline
def flock_sums(pos, vel, sums):
    """sums[0] = sum of the positions, sums[1] = sum of the velocities, in boid order (state of time t)."""
    for c in range(3):
        sums[0, c] = 0.0
        sums[1, c] = 0.0
    for j in range(pos.shape[0]):
        for c in range(3):
            sums[0, c] += pos[j, c]
            sums[1, c] += vel[j, c]


@inline
def flock_targets(i, pos, vel, sums, fp, ip):
    """(mean velocity, mean offset) of the other boids of the flock, from the sums of time t; in a periodic
    box the offsets are minimum images summed in boid order (returns n_others = 0 for a lone boid)."""
    n_others = pos.shape[0] - 1
    if n_others == 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0
    ax = (sums[1, 0] - vel[i, 0]) / n_others
    ay = (sums[1, 1] - vel[i, 1]) / n_others
    az = (sums[1, 2] - vel[i, 2]) / n_others
    if ip[I.BOUNDARY] == BOUNDARY_PERIODIC:
        cx = cy = cz = 0.0
        for j in range(pos.shape[0]):
            if j != i:
                dx, dy, dz = offset_to(pos[j, 0], pos[j, 1], pos[j, 2], pos[i, 0], pos[i, 1], pos[i, 2], True,
                                       fp[F.BOX])
                cx += dx
                cy += dy
                cz += dz
        return ax, ay, az, cx / n_others, cy / n_others, cz / n_others, n_others
    cx = (sums[0, 0] - pos[i, 0]) / n_others - pos[i, 0]
    cy = (sums[0, 1] - pos[i, 1]) / n_others - pos[i, 1]
    cz = (sums[0, 2] - pos[i, 2]) / n_others - pos[i, 2]
    return ax, ay, az, cx, cy, cz, n_others


@llvm_inline
def rules(i, m, nbrs, pos, vel, sums, vx, vy, vz, fp, ip, bp, bi):
    """The three blends in order (alignment, cohesion, separation) over boid i's m neighbours (or, for a
    rule whose scope is the flock, every other boid); a rule with nobody to follow leaves v as it is."""
    ax = ay = az = cx = cy = cz = sx = sy = sz = 0.0
    na = nc = ns = 0
    sep_r2 = bp[B.SEP_R] * bp[B.SEP_R]
    inverse_square = bi[BI.SEP_FORM] == SEP_INVERSE_SQUARE
    for a in range(m):
        j, mask = nbrs.idx[a], nbrs.mask[a]
        dx, dy, dz = nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2]
        if mask & RULE_ALIGNMENT:
            ax += vel[j, 0]
            ay += vel[j, 1]
            az += vel[j, 2]
            na += 1
        if mask & RULE_COHESION:
            cx += dx
            cy += dy
            cz += dz
            nc += 1
        dd = dx * dx + dy * dy + dz * dz
        if mask & RULE_SEPARATION and 0.0 < dd < sep_r2:
            if inverse_square:
                sx -= dx / dd
                sy -= dy / dd
                sz -= dz / dd
            else:
                dist = math.sqrt(dd)
                sx += vel[j, 0] / dist
                sy += vel[j, 1] / dist
                sz += vel[j, 2] / dist
            ns += 1
    if na > 0:
        ax, ay, az = ax / na, ay / na, az / na
    if nc > 0:
        cx, cy, cz = cx / nc, cy / nc, cz / nc
    if bi[BI.ALI_SCOPE] == SCOPE_FLOCK or bi[BI.COH_SCOPE] == SCOPE_FLOCK:
        fax, fay, faz, fcx, fcy, fcz, others = flock_targets(i, pos, vel, sums, fp, ip)
        if bi[BI.ALI_SCOPE] == SCOPE_FLOCK:
            ax, ay, az, na = fax, fay, faz, others
        if bi[BI.COH_SCOPE] == SCOPE_FLOCK:
            cx, cy, cz, nc = fcx, fcy, fcz, others
    if na > 0:
        vx, vy, vz = blend(bp[B.ALI_S], ax, ay, az, vx, vy, vz)
    if nc > 0:
        vx, vy, vz = blend(bp[B.COH_S], cx, cy, cz, vx, vy, vz)
    if ns > 0:
        tx, ty, tz = sx / ns, sy / ns, sz / ns
        if inverse_square:
            tx, ty, tz = scaled(tx, ty, tz, fp[F.MAX_SPEED])
        vx, vy, vz = blend(bp[B.SEP_S], tx, ty, tz, vx, vy, vz)
    return vx, vy, vz


@inline
def clamp_speed(vx, vy, vz, fx, fy, fz, lo, hi):
    """v with its speed clamped to [lo, hi]; a stopped boid takes speed lo along its heading f."""
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    if speed > hi:
        k = hi / speed
        return vx * k, vy * k, vz * k
    if speed < lo:
        if speed == 0.0:
            return fx * lo, fy * lo, fz * lo
        k = lo / speed
        return vx * k, vy * k, vz * k
    return vx, vy, vz


@llvm_inline
def boid_velocity(i, step, m, nbrs, pos, vel, fwd, up, side, agents, sums, fp, ip, bp, bi, key, table, kinds, fan):
    """Boid i's new velocity from the state it perceives (step 4 of the module docstring)."""
    periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
    box = fp[F.BOX]
    dt = fp[F.DT]
    max_speed = fp[F.MAX_SPEED]
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
    flee = False
    if bi[BI.PRED_ON] != 0 and agents[COUNTERS, 1] != PHASE_WAITING:
        dx, dy, dz = offset_to(px, py, pz, agents[PRED_POS, 0], agents[PRED_POS, 1], agents[PRED_POS, 2],
                               periodic, box)
        dd = dx * dx + dy * dy + dz * dz
        if dd < bp[B.PRED_AVOID_R] * bp[B.PRED_AVOID_R]:
            flee = True
            if dd > 0.0:
                tx, ty, tz = scaled(dx, dy, dz, max_speed)
            else:
                tx, ty, tz = fwd[i, 0] * max_speed, fwd[i, 1] * max_speed, fwd[i, 2] * max_speed
            vx, vy, vz = blend(bp[B.PRED_FLEE_S], tx, ty, tz, vx, vy, vz)
    if not flee:
        vx, vy, vz = rules(i, m, nbrs, pos, vel, sums, vx, vy, vz, fp, ip, bp, bi)
        if bi[BI.PREY_ON] != 0:
            dx, dy, dz = offset_to(agents[PREY_POS, 0], agents[PREY_POS, 1], agents[PREY_POS, 2], px, py, pz,
                                   periodic, box)
            gx, gy, gz = scaled(dx, dy, dz, bp[B.PREY_W] * dt)
            vx, vy, vz = vx + gx, vy + gy, vz + gz
    magnitude = bp[B.RF_MAG]
    if magnitude > 0.0 and step % bi[BI.RF_EVERY] == 0:
        ux, uy, uz = random_unit(uniform01(key, STREAM_RANDOM_FORCE, step, 2 * i),
                                 uniform01(key, STREAM_RANDOM_FORCE, step, 2 * i + 1), ip[I.DIMENSIONS] == 2)
        vx, vy, vz = vx + magnitude * ux, vy + magnitude * uy, vz + magnitude * uz
    if table.shape[0] > 0 and bp[B.AVOID_W] > 0.0:
        ray, dx, dy, dz, free = fan_avoid_direction(table, kinds, fan, px, py, pz, fwd[i, 0], fwd[i, 1], fwd[i, 2],
                                                    up[i, 0], up[i, 1], up[i, 2], side[i, 0], side[i, 1],
                                                    side[i, 2], bp[B.AVOID_BODY], bp[B.LOOKAHEAD])
        if ray != FAN_CLEAR:
            w = bp[B.AVOID_W] * dt
            vx, vy, vz = vx + w * dx, vy + w * dy, vz + w * dz
    if ip[I.DRIVE] != 0:
        vx, vy, vz = drive(vx, vy, vz, fwd[i, 0], fwd[i, 1], fwd[i, 2], uniform01(key, STREAM_HEADING_NOISE, step, 2 * i),
                           uniform01(key, STREAM_HEADING_NOISE, step, 2 * i + 1),
                           normal(key, STREAM_SPEED_NOISE, step, i), fp)
    if ip[I.DIMENSIONS] == 2:
        vz = 0.0
    return clamp_speed(vx, vy, vz, fwd[i, 0], fwd[i, 1], fwd[i, 2], bp[B.MIN_SPEED], max_speed)


@inline
def move_boid(i, vx, vy, vz, pos, vel, fwd, up, side, acc, fp, ip):
    """Step 6 for boid i: p += v dt, realised acceleration, frame, boundary."""
    dt = fp[F.DT]
    acc[i, 0], acc[i, 1], acc[i, 2] = (vx - vel[i, 0]) / dt, (vy - vel[i, 1]) / dt, (vz - vel[i, 2]) / dt
    vel[i, 0], vel[i, 1], vel[i, 2] = vx, vy, vz
    pos[i, 0] += vx * dt
    pos[i, 1] += vy * dt
    pos[i, 2] += vz * dt
    new_frame(i, vx, vy, vz, math.sqrt(vx * vx + vy * vy + vz * vz), fwd, up, side, acc, dt,
              ip[I.DIMENSIONS] == 2)
    apply_boundary(i, pos, fp, ip)


@inline
def mark_captures(step, pos, agents, fp, ip, bp, bi, capture_step):
    """Boids within the capture radius of the (appeared) predator get their first capture step."""
    radius = bp[B.PRED_CAPTURE_R]
    if bi[BI.PRED_ON] == 0 or radius < 0.0 or agents[COUNTERS, 1] == PHASE_WAITING:
        return
    periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
    for i in range(pos.shape[0]):
        if capture_step[i] < 0:
            dx, dy, dz = offset_to(pos[i, 0], pos[i, 1], pos[i, 2], agents[PRED_POS, 0], agents[PRED_POS, 1],
                                   agents[PRED_POS, 2], periodic, fp[F.BOX])
            if dx * dx + dy * dy + dz * dz < radius * radius:
                capture_step[i] = step


# run-loop hooks (simcore.hooks). Shared scratch rows: the flock sums (rows 0, 1; :func:`flock_sums`), then
# the new predator (row 2) and prey (row 3) velocities of this step, from the state of time t.
SUMS_POS, SUMS_VEL, PRED_NEW_VEL, PREY_NEW_VEL, SHARED_ROWS = range(5)
assert (SUMS_POS, SUMS_VEL) == (0, 1)  # the rows flock_sums and flock_targets use


def pack(model, dt):
    """``dyn`` = (bp, bi, obstacle table, obstacle kinds, ray fan) (:mod:`simcore.boidspp_layout`)."""
    return pack_boidspp(model, dt)


def scratch(dynamics, n):
    return np.zeros((n, 3), np.float64), np.zeros((SHARED_ROWS, 3), np.float64)


def begin_step(dynamics, step, state, params, key):
    """Step 1: the agents appear (or the predator leaves)."""
    fp, ip, (bp, bi, table, kinds, fan) = params
    place_agents(step, state[0], state[9], fp, ip, bp, bi, key)


def record_extra(dynamics, r, state, records):
    """The agents' positions with record r."""
    agents, rec_agents = state[9], records[8]
    for c in range(3):
        rec_agents[r, 0, c] = agents[PRED_POS, c]
        rec_agents[r, 1, c] = agents[PREY_POS, c]


def before_boids(dynamics, step, state, params, key, scratch, records):
    """Step 3, the agents' new velocities (step 5, from the state of time t) and the flock sums."""
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, (bp, bi, table, kinds, fan) = params
    shared = scratch[1]
    mark_captures(step, pos, agents, fp, ip, bp, bi, records[9])
    (shared[PRED_NEW_VEL, 0], shared[PRED_NEW_VEL, 1], shared[PRED_NEW_VEL, 2], shared[PREY_NEW_VEL, 0],
     shared[PREY_NEW_VEL, 1], shared[PREY_NEW_VEL, 2]) = agent_velocities(pos, agents, fp, ip, bp, bi)
    if bi[BI.ALI_SCOPE] == SCOPE_FLOCK or bi[BI.COH_SCOPE] == SCOPE_FLOCK:
        flock_sums(pos, vel, shared)


def sense(dynamics, i, step, m, nbrs, state, params, key, scratch):
    """Step 4: boid i's new velocity into its row of the per-boid buffer (no leadership: never triggers)."""
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, (bp, bi, table, kinds, fan) = params
    new_vel, shared = scratch
    new_vel[i, 0], new_vel[i, 1], new_vel[i, 2] = boid_velocity(i, step, m, nbrs, pos, vel, fwd, up, side, agents,
                                                                shared, fp, ip, bp, bi, key, table, kinds, fan)
    return False


def move(dynamics, i, state, params, scratch):
    """Step 6 for boid i."""
    pos, vel, fwd, up, side, acc, pattern, clock, escape, agents = state
    fp, ip, dyn = params
    new_vel = scratch[0]
    move_boid(i, new_vel[i, 0], new_vel[i, 1], new_vel[i, 2], pos, vel, fwd, up, side, acc, fp, ip)


def after_boids(dynamics, step, state, params, key, scratch):
    """Step 5: the agents move."""
    fp, ip, (bp, bi, table, kinds, fan) = params
    shared = scratch[1]
    move_agents(shared[PRED_NEW_VEL, 0], shared[PRED_NEW_VEL, 1], shared[PRED_NEW_VEL, 2], shared[PREY_NEW_VEL, 0],
                shared[PREY_NEW_VEL, 1], shared[PREY_NEW_VEL, 2], state[9], fp, ip, bp, bi, key)
