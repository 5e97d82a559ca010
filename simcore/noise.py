"""Intrinsic noise and cruise speed: the one drive every dynamics applies to a boid's new velocity.

docs/model.md section 3.5. A dynamics computes boid i's candidate velocity v from its rules; when the model
has ``[noise]`` or ``[cruise]`` (``ip[I.DRIVE] == 1``) the drive turns it into

1. speed s = |v| and heading d = v / s (the boid's heading f when s = 0);
2. cruise (``cruise.speed`` = v0, ``cruise.tau``): s <- v0 + (s - v0) e^(-dt/tau), the exact step of
   ds/dt = (v0 - s) / tau (a force m (v0 - s) / tau along the heading);
3. speed noise (``noise.speed_sd`` = sigma, per sqrt(s)): s <- s + k z with z standard normal and k =
   sigma sqrt(tau (1 - e^(-2 dt/tau)) / 2) with cruise (the exact Ornstein-Uhlenbeck step: the
   stationary speed is normal with mean v0 and sd sigma sqrt(tau / 2), for any dt) or sigma sqrt(dt)
   without (a random walk); a speed below 0 becomes 0;
4. angular noise: d <- a draw of the von Mises-Fisher distribution on the sphere with mean d and
   concentration kappa per step (``noise.kappa``, or kappa = 1 / (sd^2 dt) from ``noise.angular_sd_deg`` =
   sd in radians per sqrt(s)): the cosine w of the turn has E[w] = coth(kappa) - 1/kappa (Wood 1994's exact
   draw, w = 1 + ln(V + (1 - V) e^(-2 kappa)) / kappa with V = 1 - U1), its azimuth 2 pi U2 about d in the
   basis of :func:`perpendicular_basis`;
5. v <- s d; the dynamics then applies its own speed limits, moves and rebuilds the frame.

Off (no ``[noise]``, no ``[cruise]``) nothing of this runs, so trajectories are bit-identical to a model
without it. In 2-D (``world.dimensions = 2``; the slot ``PLANAR_TURN_SD`` is set and ``NOISE_KAPPA`` is 0)
step 4 turns d about +z by the wrapped normal angle sd z' (:func:`turn_in_plane`), z' the Box-Muller
normal of the same two uniforms U1, U2 (so ``normal(key, STREAM_HEADING_NOISE, step, i)``) and sd =
1 / sqrt(kappa) per step (the angle sd of a 3-D turn's tangential components for large kappa; sd_rad
sqrt(dt) from ``noise.angular_sd_deg``).

Draws are counter-based (:mod:`simcore.rng`), a pure function of (run key, stream, step, boid): U1, U2 are
``uniform01(key, STREAM_HEADING_NOISE, step, 2 i)`` and ``(..., 2 i + 1)``, z is ``normal(key,
STREAM_SPEED_NOISE, step, i)``. A dynamics whose ``move`` has no key draws them in ``sense``
(:func:`store_draws`, into ``DRAWS`` columns of its per-boid buffer) and applies them in ``move``
(:func:`drive`); so runs stay deterministic whatever the batch, the thread count or the update order.
"""
from __future__ import annotations

import math

from .jit import inline
from .layout import F
from .rng import STREAM_HEADING_NOISE, STREAM_SPEED_NOISE, box_muller, normal, uniform01

DRAWS = 3  # per-boid columns the draws take: U1, U2 (heading), z (speed)


@inline
def perpendicular_basis(x, y, z):
    """Two unit vectors a, b with (a, b, d) orthonormal for a unit d = (x, y, z) (Duff et al. 2017,
    "Building an orthonormal basis, revisited", JCGT 6(1)): ``(ax, ay, az, bx, by, bz)``."""
    sign = math.copysign(1.0, z)
    g = -1.0 / (sign + z)
    h = x * y * g
    return 1.0 + sign * x * x * g, sign * h, -sign * x, h, sign + y * y * g, -y


@inline
def vmf_turn(x, y, z, u1, u2, kappa):
    """A von Mises-Fisher draw of concentration ``kappa`` (> 0) about the unit d = (x, y, z), from the
    uniforms u1, u2 in [0, 1) (module docstring, step 4)."""
    v = 1.0 - u1
    t = -math.log(v + (1.0 - v) * math.exp(-2.0 * kappa)) / kappa  # 1 - w, in [0, 2]
    t = min(max(t, 0.0), 2.0)
    w = 1.0 - t
    s = math.sqrt(t * (2.0 - t))
    phi = 2.0 * math.pi * u2
    c, sn = s * math.cos(phi), s * math.sin(phi)
    ax, ay, az, bx, by, bz = perpendicular_basis(x, y, z)
    return w * x + c * ax + sn * bx, w * y + c * ay + sn * by, w * z + c * az + sn * bz


@inline
def turn_in_plane(fx, fy, z, sd):
    """A heading (fx, fy) in the plane turned by the wrapped normal angle ``sd z`` (radians)."""
    angle = sd * z
    c, s = math.cos(angle), math.sin(angle)
    return c * fx - s * fy, s * fx + c * fy


@inline
def store_draws(row, i, col, key, step):
    """Boid i's draws of this step into ``row[i, col:col + DRAWS]`` (module docstring)."""
    row[i, col] = uniform01(key, STREAM_HEADING_NOISE, step, 2 * i)
    row[i, col + 1] = uniform01(key, STREAM_HEADING_NOISE, step, 2 * i + 1)
    row[i, col + 2] = normal(key, STREAM_SPEED_NOISE, step, i)


@inline
def drive(vx, vy, vz, fx, fy, fz, u1, u2, z, fp):
    """The candidate velocity v of a boid with heading f after cruise and noise (module docstring,
    steps 1-5), from its draws u1, u2, z."""
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    if s > 0.0:
        dx, dy, dz = vx / s, vy / s, vz / s
    else:
        dx, dy, dz = fx, fy, fz
    decay = fp[F.CRUISE_DECAY]
    if decay < 1.0:
        v0 = fp[F.CRUISE_SPEED]
        s = v0 + (s - v0) * decay
    kick = fp[F.SPEED_KICK]
    if kick > 0.0:
        s = max(s + kick * z, 0.0)
    kappa = fp[F.NOISE_KAPPA]
    if kappa > 0.0:
        dx, dy, dz = vmf_turn(dx, dy, dz, u1, u2, kappa)
    sd = fp[F.PLANAR_TURN_SD]
    if sd > 0.0:
        dx, dy = turn_in_plane(dx, dy, box_muller(u1, u2), sd)
    return s * dx, s * dy, s * dz


@inline
def drive_row(vx, vy, vz, i, fwd, row, col, fp):
    """:func:`drive` with boid i's heading ``fwd[i]`` and its draws stored at ``row[i, col:]``."""
    return drive(vx, vy, vz, fwd[i, 0], fwd[i, 1], fwd[i, 2], row[i, col], row[i, col + 1], row[i, col + 2], fp)
