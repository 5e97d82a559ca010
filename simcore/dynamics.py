"""OpenSteer vehicle physics, banking frame and world boundary (docs/model.md sections 1, 0 and 3).
Compiled with numba.

``apply_steering(i, fx, fy, fz, pos, vel, fwd, up, side, acc, fp, ip)`` advances boid i by one step of
``dt`` in place, given its raw steering force:

1. low-speed cone clamp: when speed <= 0.2 max_speed and the force is non-zero, the force is turned into
   the cone about f of cosine 1 - 2 (speed / (0.2 max_speed))^20, keeping its length;
2. truncation to max_force, a = force / mass;
3. acceleration smoothing a_s += clip(9 dt, 0.15, 0.4) (a - a_s);
4. v = truncate(speed f + a_s dt, max_speed);
5. p += v dt;
6. banking frame: u = normalize(u + clip(3 dt, 0, 1)(0.05 a_s + (0, 0.2, 0) - u)); f = v/|v| when
   |v| > 0; s = normalize(f x u); u = s x f (rebuilt also when the boid is stopped, so the frame is
   always orthonormal; when f is parallel to u, s falls back to the old side made orthogonal to f);
   then the boundary (sphere wrap or periodic box).

With cruise or noise (docs/model.md section 3.5) the velocity of step 4 is driven by
:func:`simcore.noise.drive` before its truncation (off: not a bit changes).

In 2-D (``world.dimensions = 2``, docs/model.md section 15) the force's z is set to 0 before step 1 (the
Hartman-Beneš steers' z likewise) and step 6 keeps the frame in the plane (:func:`new_frame`: f = v/|v|
with z = 0, up = +z, side = f x up = (f_y, -f_x, 0)); from a start in the plane z = 0 every position,
velocity and heading then stays in it exactly.

All arrays are float64 (N, 3); ``vel`` holds v = speed f.
"""
from __future__ import annotations

import math


from .jit import inline, llvm_inline
from .layout import BOUNDARY_PERIODIC, BOUNDARY_SPHERE_WRAP, F, I
from .noise import drive_row
from .rules import normalized

SMOOTH_MIN, SMOOTH_MAX = 0.15, 0.4
GLOBAL_UP_Y = 0.2
BANK_ACCEL = 0.05


@inline
def truncated(x, y, z, limit):
    """(x, y, z) scaled down to length ``limit`` when longer."""
    n2 = x * x + y * y + z * z
    if n2 > limit * limit:
        k = limit / math.sqrt(n2)
        return x * k, y * k, z * k
    return x, y, z


@inline
def cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@inline
def cone_clamp(fx, fy, fz, ux, uy, uz, cosine):
    """Force turned into the cone of axis u (unit) and the given cosine, keeping its length."""
    length = math.sqrt(fx * fx + fy * fy + fz * fz)
    if length == 0.0:
        return fx, fy, fz
    along = (fx * ux + fy * uy + fz * uz)
    if along / length >= cosine:
        return fx, fy, fz
    px, py, pz = normalized(fx - along * ux, fy - along * uy, fz - along * uz)
    perp = math.sqrt(1.0 - cosine * cosine)
    return ((cosine * ux + perp * px) * length, (cosine * uy + perp * py) * length,
            (cosine * uz + perp * pz) * length)


@inline
def rebuild_frame(i, vx, vy, vz, speed, fwd, up, side, acc, dt):
    """Banking frame update of boid i after its move (module docstring, step 6)."""
    rate = min(max(3.0 * dt, 0.0), 1.0)
    ux = up[i, 0] + rate * (BANK_ACCEL * acc[i, 0] - up[i, 0])
    uy = up[i, 1] + rate * (BANK_ACCEL * acc[i, 1] + GLOBAL_UP_Y - up[i, 1])
    uz = up[i, 2] + rate * (BANK_ACCEL * acc[i, 2] - up[i, 2])
    un = math.sqrt(ux * ux + uy * uy + uz * uz)
    if un > 0.0:
        ux, uy, uz = ux / un, uy / un, uz / un
    else:
        ux, uy, uz = up[i, 0], up[i, 1], up[i, 2]
    if speed > 0.0:
        fwd[i, 0], fwd[i, 1], fwd[i, 2] = vx / speed, vy / speed, vz / speed
    f0, f1, f2 = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    sx, sy, sz = cross(f0, f1, f2, ux, uy, uz)
    sn = math.sqrt(sx * sx + sy * sy + sz * sz)
    if sn > 1e-12:
        sx, sy, sz = sx / sn, sy / sn, sz / sn
    else:
        along = side[i, 0] * f0 + side[i, 1] * f1 + side[i, 2] * f2
        sx, sy, sz = normalized(side[i, 0] - along * f0, side[i, 1] - along * f1, side[i, 2] - along * f2)
    side[i, 0], side[i, 1], side[i, 2] = sx, sy, sz
    up[i, 0], up[i, 1], up[i, 2] = cross(sx, sy, sz, f0, f1, f2)


@inline
def planar_axes(i, fx, fy, fwd, up, side):
    """The frame of a boid in the plane z = 0 with unit heading (fx, fy): up = +z, side = f x up."""
    fwd[i, 0], fwd[i, 1], fwd[i, 2] = fx, fy, 0.0
    up[i, 0], up[i, 1], up[i, 2] = 0.0, 0.0, 1.0
    side[i, 0], side[i, 1], side[i, 2] = fy, -fx, 0.0


@inline
def new_frame(i, vx, vy, vz, speed, fwd, up, side, acc, dt, planar):
    """The frame of boid i after its move: in the plane (``planar``) f = v/|v| (kept when stopped) with
    :func:`planar_axes`, else the banking frame of :func:`rebuild_frame`."""
    if planar:
        if speed > 0.0:
            planar_axes(i, vx / speed, vy / speed, fwd, up, side)
        else:
            planar_axes(i, fwd[i, 0], fwd[i, 1], fwd, up, side)
    else:
        rebuild_frame(i, vx, vy, vz, speed, fwd, up, side, acc, dt)


@inline
def apply_boundary(i, pos, fp, ip):
    kind = ip[I.BOUNDARY]
    if kind == BOUNDARY_SPHERE_WRAP:
        radius = fp[F.WORLD_RADIUS]
        r = math.sqrt(pos[i, 0] ** 2 + pos[i, 1] ** 2 + pos[i, 2] ** 2)
        if r > radius:
            k = 2.0 * radius / r
            pos[i, 0] -= k * pos[i, 0]
            pos[i, 1] -= k * pos[i, 1]
            pos[i, 2] -= k * pos[i, 2]
    elif kind == BOUNDARY_PERIODIC:
        box = fp[F.BOX]
        for c in range(3):
            pos[i, c] -= box * math.floor((pos[i, c] + 0.5 * box) / box)


@llvm_inline
def apply_steering(i, fx, fy, fz, pos, vel, fwd, up, side, acc, fp, ip, dvx, dvy, dvz, cap, draws, col):
    """One OpenSteer physics step of boid i under raw steering force (fx, fy, fz). A leader's escape
    adds (dvx, dvy, dvz) to the new velocity before truncation to ``cap`` (< 0: max_speed); with cruise or
    noise (``ip[I.DRIVE]``) the new velocity is driven (:func:`simcore.noise.drive`, boid i's draws in
    ``draws[i, col:]``) before the truncation."""
    dt = fp[F.DT]
    max_speed = fp[F.MAX_SPEED]
    planar = ip[I.DIMENSIONS] == 2
    if planar:
        fz = 0.0
    speed = math.sqrt(vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
    slow = 0.2 * max_speed
    if speed <= slow and (fx != 0.0 or fy != 0.0 or fz != 0.0):
        cosine = 1.0 - 2.0 * (speed / slow) ** 20
        fx, fy, fz = cone_clamp(fx, fy, fz, fwd[i, 0], fwd[i, 1], fwd[i, 2], cosine)
    fx, fy, fz = truncated(fx, fy, fz, fp[F.MAX_FORCE])
    mass = fp[F.MASS]
    rate = min(max(9.0 * dt, SMOOTH_MIN), SMOOTH_MAX)
    acc[i, 0] += rate * (fx / mass - acc[i, 0])
    acc[i, 1] += rate * (fy / mass - acc[i, 1])
    acc[i, 2] += rate * (fz / mass - acc[i, 2])
    vx = speed * fwd[i, 0] + acc[i, 0] * dt
    vy = speed * fwd[i, 1] + acc[i, 1] * dt
    vz = speed * fwd[i, 2] + acc[i, 2] * dt
    if dvx != 0.0 or dvy != 0.0 or dvz != 0.0:
        vx, vy, vz = vx + dvx, vy + dvy, vz + dvz
    if ip[I.DRIVE] != 0:
        vx, vy, vz = drive_row(vx, vy, vz, i, fwd, draws, col, fp)
    vx, vy, vz = truncated(vx, vy, vz, max_speed if cap < 0.0 else cap)
    vel[i, 0], vel[i, 1], vel[i, 2] = vx, vy, vz
    pos[i, 0] += vx * dt
    pos[i, 1] += vy * dt
    pos[i, 2] += vz * dt
    new_speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    new_frame(i, vx, vy, vz, new_speed, fwd, up, side, acc, dt, planar)
    apply_boundary(i, pos, fp, ip)


@llvm_inline
def hartman_benes_step(i, sx, sy, sz, kx, ky, kz, mx, my, mz, pos, vel, fwd, up, side, acc, fp, ip,
                       dvx, dvy, dvz, cap, draws, col):
    """One Hartman-Benes frame of boid i (docs/model.md section 5): p' = p + dt v (the old velocity), then
    v' = v + (S s + K k) / dt + M m (+ a leader's escape), driven by cruise and noise when on
    (:func:`simcore.noise.drive`, draws in ``draws[i, col:]``), clamped to ``cap``. ``acc`` holds the
    realised acceleration (v' - v) / dt, which drives the banking frame as in OpenSteer."""
    dt = fp[F.DT]
    vx0, vy0, vz0 = vel[i, 0], vel[i, 1], vel[i, 2]
    pos[i, 0] += vx0 * dt
    pos[i, 1] += vy0 * dt
    pos[i, 2] += vz0 * dt
    gs, gk, gm = fp[F.GAIN_S], fp[F.GAIN_K], fp[F.GAIN_M]
    planar = ip[I.DIMENSIONS] == 2
    if planar:
        sz = kz = mz = 0.0
    vx = vx0 + (gs * sx + gk * kx) / dt + gm * mx
    vy = vy0 + (gs * sy + gk * ky) / dt + gm * my
    vz = vz0 + (gs * sz + gk * kz) / dt + gm * mz
    if dvx != 0.0 or dvy != 0.0 or dvz != 0.0:
        vx, vy, vz = vx + dvx, vy + dvy, vz + dvz
    if ip[I.DRIVE] != 0:
        vx, vy, vz = drive_row(vx, vy, vz, i, fwd, draws, col, fp)
    vx, vy, vz = truncated(vx, vy, vz, cap)
    vel[i, 0], vel[i, 1], vel[i, 2] = vx, vy, vz
    acc[i, 0], acc[i, 1], acc[i, 2] = (vx - vx0) / dt, (vy - vy0) / dt, (vz - vz0) / dt
    new_frame(i, vx, vy, vz, math.sqrt(vx * vx + vy * vy + vz * vz), fwd, up, side, acc, dt, planar)
    apply_boundary(i, pos, fp, ip)
