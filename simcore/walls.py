"""The arena's walls in the run loop (docs/model.md section 16): the wall term and the reflecting fallback,
applied to boid i right after its dynamics moved it, whatever the dynamics. Compiled (inlined into the
run loops, :mod:`simcore.kernel`); :mod:`simcore.arena` holds the ``[arena]`` table.

Walls. A cylinder (a circle in 2-D) has a side wall and, in 3-D with a height, a floor and a ceiling; a
box (a rectangle in 2-D) a pair of walls per axis (x, y and, in 3-D, z). Each wall k of boid i has a
signed distance d_k (positive inside) and an inward unit normal n_k at the point of the wall nearest to
the boid (the cylinder's side: n = -(p - c)_xy / |(p - c)_xy|, pointing at the axis; at the axis itself
n = -x, a fixed choice).

After boid i's move, with its new position p and velocity v:

1. the wall term: a = sum over the walls with 0 <= d_k < range of weight (1 - d_k / range) n_k, an
   acceleration of ``wall_weight`` at contact falling linearly to 0 at ``wall_range``; v <- v + a dt (its
   z left alone in 2-D). A constant-speed dynamics (its descriptor's ``HEADING``) keeps its speed: v is
   then scaled back to |v| before the term;
2. the fallback (``reflect``): for each wall with d_k < 0 the position is mirrored across it (a box face,
   a floor or a ceiling: p_c <- 2 wall_c - p_c, kept between the two faces across axis c; the cylinder's
   side: the distance from the axis r <- 2 R - r, at least 0) and the velocity's outward part reversed
   (v <- v - 2 (v . n_k) n_k when v . n_k < 0);
3. when v changed, the frame follows it: fwd = v / |v|; in 2-D the planar axes, in 3-D side = fwd x up
   made unit and up = side x fwd (the banking of the move is kept).

Without an arena (``ip[I.ARENA] == 0``) nothing here runs.
"""
from __future__ import annotations

import math

from .dynamics import cross, planar_axes
from .jit import inline
from .layout import ARENA_BOX, ARENA_CYLINDER, F, I

MAX_WALLS = 6


@inline
def wall(k, x, y, z, fp, ip, planar):
    """(present, d, nx, ny, nz) of wall k (0..5) of the arena for the point (x, y, z)."""
    px, py, pz = x - fp[F.ARENA_CX], y - fp[F.ARENA_CY], z - fp[F.ARENA_CZ]
    if ip[I.ARENA] == ARENA_CYLINDER:
        if k == 0:
            r = math.sqrt(px * px + py * py)
            if r > 0.0:
                return True, fp[F.ARENA_RADIUS] - r, -px / r, -py / r, 0.0
            return True, fp[F.ARENA_RADIUS], -1.0, 0.0, 0.0
        half = fp[F.ARENA_HALF_Z]
        if planar or k > 2 or not math.isfinite(half):
            return False, 0.0, 0.0, 0.0, 0.0
        if k == 1:
            return True, pz + half, 0.0, 0.0, 1.0      # the floor
        return True, half - pz, 0.0, 0.0, -1.0         # the ceiling
    axis = k // 2
    if axis == 2 and planar:
        return False, 0.0, 0.0, 0.0, 0.0
    c = px if axis == 0 else (py if axis == 1 else pz)
    half = fp[F.ARENA_HALF_X] if axis == 0 else (fp[F.ARENA_HALF_Y] if axis == 1 else fp[F.ARENA_HALF_Z])
    sign = 1.0 if k % 2 == 0 else -1.0                  # even: the low wall (normal +axis); odd: the high one
    d = c + half if k % 2 == 0 else half - c
    if axis == 0:
        return True, d, sign, 0.0, 0.0
    if axis == 1:
        return True, d, 0.0, sign, 0.0
    return True, d, 0.0, 0.0, sign


@inline
def wall_accel(x, y, z, fp, ip, planar):
    """The wall term's acceleration at (x, y, z) (module docstring, step 1)."""
    ax = ay = az = 0.0
    reach, weight = fp[F.WALL_RANGE], fp[F.WALL_WEIGHT]
    for k in range(MAX_WALLS):
        present, d, nx, ny, nz = wall(k, x, y, z, fp, ip, planar)
        if present and 0.0 <= d < reach:
            g = weight * (1.0 - d / reach)
            ax, ay, az = ax + g * nx, ay + g * ny, az + g * nz
    return ax, ay, az


@inline
def mirror(i, k, d, nx, ny, nz, pos, vel, fp, ip):
    """Boid i, outside wall k by -d: its position mirrored back across the wall, its velocity's outward
    part reversed (module docstring, step 2)."""
    if ip[I.ARENA] == ARENA_CYLINDER and k == 0:
        px, py = pos[i, 0] - fp[F.ARENA_CX], pos[i, 1] - fp[F.ARENA_CY]
        r = math.sqrt(px * px + py * py)
        inside = max(2.0 * fp[F.ARENA_RADIUS] - r, 0.0)
        pos[i, 0] = fp[F.ARENA_CX] + px * (inside / r)
        pos[i, 1] = fp[F.ARENA_CY] + py * (inside / r)
    else:   # a face across axis c: mirrored, then kept within the pair of faces (a jump of more than a width)
        c = 0 if nx != 0.0 else (1 if ny != 0.0 else 2)
        centre = fp[F.ARENA_CX] if c == 0 else (fp[F.ARENA_CY] if c == 1 else fp[F.ARENA_CZ])
        half = fp[F.ARENA_HALF_X] if c == 0 else (fp[F.ARENA_HALF_Y] if c == 1 else fp[F.ARENA_HALF_Z])
        pos[i, c] = min(max(pos[i, c] - 2.0 * d * (nx + ny + nz), centre - half), centre + half)
    along = vel[i, 0] * nx + vel[i, 1] * ny + vel[i, 2] * nz
    if along < 0.0:
        vel[i, 0] -= 2.0 * along * nx
        vel[i, 1] -= 2.0 * along * ny
        vel[i, 2] -= 2.0 * along * nz


@inline
def reorient(i, vel, fwd, up, side, planar):
    """The frame of boid i after its velocity turned (module docstring, step 3)."""
    vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    if speed == 0.0:
        return
    if planar:
        planar_axes(i, vx / speed, vy / speed, fwd, up, side)
        return
    fx, fy, fz = vx / speed, vy / speed, vz / speed
    sx, sy, sz = cross(fx, fy, fz, up[i, 0], up[i, 1], up[i, 2])
    sn = math.sqrt(sx * sx + sy * sy + sz * sz)
    if sn > 1e-12:
        sx, sy, sz = sx / sn, sy / sn, sz / sn
    else:
        sx, sy, sz = side[i, 0], side[i, 1], side[i, 2]
    fwd[i, 0], fwd[i, 1], fwd[i, 2] = fx, fy, fz
    side[i, 0], side[i, 1], side[i, 2] = sx, sy, sz
    up[i, 0], up[i, 1], up[i, 2] = cross(sx, sy, sz, fx, fy, fz)


@inline
def contain(i, state, params):
    """The arena's walls for boid i after its move (module docstring)."""
    pos, vel, fwd, up, side = state[0], state[1], state[2], state[3], state[4]
    fp, ip = params[0], params[1]
    planar = ip[I.DIMENSIONS] == 2
    ax, ay, az = wall_accel(pos[i, 0], pos[i, 1], pos[i, 2], fp, ip, planar)
    turned = ax != 0.0 or ay != 0.0 or az != 0.0
    if turned:
        vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
        before = math.sqrt(vx * vx + vy * vy + vz * vz)
        dt = fp[F.DT]
        vx, vy, vz = vx + ax * dt, vy + ay * dt, vz + (0.0 if planar else az * dt)
        if ip[I.CONSTANT_SPEED] != 0:
            after = math.sqrt(vx * vx + vy * vy + vz * vz)
            if after > 0.0:
                vx, vy, vz = vx * (before / after), vy * (before / after), vz * (before / after)
        vel[i, 0], vel[i, 1], vel[i, 2] = vx, vy, vz
    if ip[I.REFLECT] != 0:
        for k in range(MAX_WALLS):
            present, d, nx, ny, nz = wall(k, pos[i, 0], pos[i, 1], pos[i, 2], fp, ip, planar)
            if present and d < 0.0:
                mirror(i, k, d, nx, ny, nz, pos, vel, fp, ip)
                turned = True
    if turned:
        reorient(i, vel, fwd, up, side, planar)
