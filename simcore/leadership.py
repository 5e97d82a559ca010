"""Hartman-Benes change of leadership (docs/model.md section 5), for every dynamics. Compiled with numba.

Per boid the state holds ``clock`` (seconds since its last trigger; +inf when it never triggered) and
``escape`` (unit escape direction fixed at the trigger for a slow boid, zeros otherwise). A boid is a
leader while ``clock < duration - dt/2`` (the clock is a running sum of dt; the half step makes an escape
last exactly round(duration / dt) steps).

``decide(...)`` is the trigger test of boid i at a step, from its cohesion offset k_i (mean offset to
the m boids it perceives), its velocity and clock:

* not a leader and not refractory (``clock >= duration + refractory - dt/2``), m >= 1;
* eccentricity x_i = |k_i| / e (e: the perception range), 0 when m = 0;
* front_i = -(k_i/|k_i|) . (v_i/|v_i|); the gate ``positive`` needs front_i > 0, ``weighted`` uses
  x_i max(front_i, 0) instead of x_i, ``none`` passes; a boid slower than ``slow_speed`` passes the gate
  and escapes along -k_i/|k_i|;
* trigger when X x_i > g, g = GaussRand01 = clip(1/2 + sigma z, 0, 1), z a standard normal that is a
  pure function of (run key, leadership stream, step, boid).

``escape(...)`` gives the velocity added in one step of an escape and the raised speed cap:
dv = gain b(tau/T) max(|v|, slow_speed) d, cap = max_speed (1 + boost b(tau/T)), with tau = clock,
T = duration, d = v/|v| (or the fixed escape direction of a slow boid) and b the escape profile: the
bump digitised from the paper's Figure 5, 30 samples equally spaced on [0, 1], peak 1, linearly
interpolated, 0 outside [0, 1).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import inline
from .layout import F, GATE_POSITIVE, GATE_WEIGHTED, I
from .rng import STREAM_LEADERSHIP, normal

ESCAPE_PROFILE = np.array([
    0.01, 0.05, 0.10, 0.16, 0.27, 0.40, 0.55, 0.72, 0.85, 0.96, 1.00, 0.98, 0.90, 0.80, 0.65,
    0.51, 0.36, 0.25, 0.18, 0.14, 0.12, 0.10, 0.08, 0.07, 0.06, 0.05, 0.04, 0.03, 0.02, 0.00])


@inline
def profile(u):
    """Escape profile b(u) for u = tau / T."""
    if u < 0.0 or u >= 1.0:
        return 0.0
    x = u * (ESCAPE_PROFILE.shape[0] - 1)
    k = int(x)
    frac = x - k
    return ESCAPE_PROFILE[k] + frac * (ESCAPE_PROFILE[k + 1] - ESCAPE_PROFILE[k])


@inline
def gauss_rand01(key, step, i, sigma):
    """GaussRand01: a normal draw of mean 1/2 and sd sigma, clipped to [0, 1]."""
    return min(max(0.5 + sigma * normal(key, STREAM_LEADERSHIP, step, i), 0.0), 1.0)


@inline
def is_leader(clock_i, fp):
    """Leader while the clock is below the duration; half a step of tolerance makes an escape last
    exactly round(duration / dt) steps whatever the rounding of the summed clock."""
    return clock_i < fp[F.LEAD_DURATION] - 0.5 * fp[F.DT]


@inline
def decide(i, step, kx, ky, kz, m, vx, vy, vz, clock, fp, ip, key):
    """(trigger?, slow?) for boid i at ``step`` (see module docstring)."""
    trigger = slow = False
    if m >= 1 and not clock[i] < fp[F.LEAD_DURATION] + fp[F.LEAD_REFRACTORY] - 0.5 * fp[F.DT]:
        k_len = math.sqrt(kx * kx + ky * ky + kz * kz)
        if k_len != 0.0:
            eccentricity = k_len / fp[F.PERCEPTION_RANGE]
            speed = math.sqrt(vx * vx + vy * vy + vz * vz)
            is_slow = speed < fp[F.SLOW_SPEED]
            score = eccentricity
            gate_open = True
            if not is_slow:
                front = -(kx * vx + ky * vy + kz * vz) / (k_len * speed)
                gate = ip[I.FRONT_GATE]
                if gate == GATE_POSITIVE and not front > 0.0:
                    gate_open = False
                if gate == GATE_WEIGHTED:
                    score = eccentricity * max(front, 0.0)
            if gate_open:
                g = gauss_rand01(key, step, i, fp[F.LEAD_SIGMA])
                trigger, slow = fp[F.LEAD_X] * score > g, is_slow
    return trigger, slow


@inline
def start(i, slow, kx, ky, kz, clock, escape):
    """Make boid i a leader now; a slow boid's escape direction is fixed to -k/|k|."""
    clock[i] = 0.0
    escape[i, 0] = escape[i, 1] = escape[i, 2] = 0.0
    if slow:
        k_len = math.sqrt(kx * kx + ky * ky + kz * kz)
        escape[i, 0], escape[i, 1], escape[i, 2] = -kx / k_len, -ky / k_len, -kz / k_len


@inline
def escape_step(i, vx, vy, vz, clock, escape, fp):
    """(dvx, dvy, dvz, speed cap) of boid i for this step; (0, 0, 0, max_speed) when not a leader."""
    max_speed = fp[F.MAX_SPEED]
    dvx = dvy = dvz = 0.0
    cap = max_speed
    if is_leader(clock[i], fp):
        b = profile(clock[i] / fp[F.LEAD_DURATION])
        if b != 0.0:
            cap = max_speed * (1.0 + fp[F.LEAD_BOOST] * b)
            speed = math.sqrt(vx * vx + vy * vy + vz * vz)
            moving = True
            if escape[i, 0] != 0.0 or escape[i, 1] != 0.0 or escape[i, 2] != 0.0:
                dx, dy, dz = escape[i, 0], escape[i, 1], escape[i, 2]
            elif speed > 0.0:
                dx, dy, dz = vx / speed, vy / speed, vz / speed
            else:
                dx = dy = dz = 0.0
                moving = False
            if moving:
                size = fp[F.LEAD_GAIN] * b * max(speed, fp[F.SLOW_SPEED])
                dvx, dvy, dvz = size * dx, size * dy, size * dz
    return dvx, dvy, dvz, cap


@inline
def sense_trigger(i, step, kx, ky, kz, m_coh, vel, clock, escape, fp, ip, key):
    """The trigger decision of boid i (with leadership on), from its cohesion offset k over m_coh
    neighbours; a triggered boid starts its escape now. Returns whether it triggered."""
    trigger, slow = decide(i, step, kx, ky, kz, m_coh, vel[i, 0], vel[i, 1], vel[i, 2], clock, fp, ip, key)
    if trigger:
        start(i, slow, kx, ky, kz, clock, escape)
    return trigger


@inline
def escape_of(i, vel, clock, escape, fp, ip):
    """(dvx, dvy, dvz, cap): what boid i's escape adds to its new velocity and its speed cap (no escape
    and max_speed without leadership)."""
    dvx = dvy = dvz = 0.0
    cap = fp[F.MAX_SPEED]
    if ip[I.LEADERSHIP] != 0:
        dvx, dvy, dvz, cap = escape_step(i, vel[i, 0], vel[i, 1], vel[i, 2], clock, escape, fp)
    return dvx, dvy, dvz, cap
