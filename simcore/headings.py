"""Headings of constant-speed models (``couzin2002``, ``vicsek``): turning a unit heading, angular noise
and the move at constant speed, in 3-D or in the plane z = 0. Compiled (inlined into the dynamics' hooks).

* ``tangent_basis(h)``: an orthonormal pair (e1, e2) across unit h, a fixed function of h: e1 = h x a /
  |h x a| with a = x when |h_x| < 0.9, else y; e2 = h x e1.
* ``tilt(h, angle, c, s)``: cos(angle) h + sin(angle) (c e1 + s e2), h turned by ``angle`` towards the
  tangent direction (c, s) (c^2 + s^2 = 1) of that basis; ``rotate_planar(h, angle)`` turns a heading of
  the plane counter-clockwise about +z.
* ``turn_toward(f, d, max_turn, side)``: d when the angle from f to d is at most ``max_turn`` (or
  max_turn >= pi), else f turned by ``max_turn`` towards d in the plane of f and d (towards ``side``
  when d is opposite to f and that plane is undefined).
* ``unit_heading(h, planar)``: h made unit (its z set to 0 first in the plane).
* ``set_heading(i, h, speed, ...)``: vel = speed h, acc = the realised acceleration (v' - v) / dt and the
  frame: in 2-D fwd = h, up = +z, side = f x up; in 3-D the banking frame of
  :func:`simcore.dynamics.rebuild_frame`. The position is the caller's (the models differ in which
  velocity moves a boid).

Shared hook pieces of these dynamics (:mod:`simcore.hooks`): ``float_dyn(slots)``, the ``dyn`` group of a
dynamics whose parameters are float slots only, and ``heading_scratch``, the per-boid buffer of the new
headings ``sense`` leaves for ``move`` (N, 3).
"""
from __future__ import annotations

import math

import numpy as np

from .dynamics import planar_axes, rebuild_frame
from .jit import inline
from .layout import F
from .rules import normalized

PARALLEL = 1e-12   # |d - (f . d) f| below this: d is along f (or opposite), no plane to turn in


@inline
def tangent_basis(hx, hy, hz):
    if abs(hx) < 0.9:
        ex, ey, ez = normalized(0.0, hz, -hy)        # h x (1, 0, 0)
    else:
        ex, ey, ez = normalized(-hz, 0.0, hx)        # h x (0, 1, 0)
    return ex, ey, ez, hy * ez - hz * ey, hz * ex - hx * ez, hx * ey - hy * ex


@inline
def tilt(hx, hy, hz, angle, c, s):
    ex, ey, ez, gx, gy, gz = tangent_basis(hx, hy, hz)
    ca, sa = math.cos(angle), math.sin(angle)
    return (ca * hx + sa * (c * ex + s * gx), ca * hy + sa * (c * ey + s * gy),
            ca * hz + sa * (c * ez + s * gz))


@inline
def rotate_planar(hx, hy, angle):
    c, s = math.cos(angle), math.sin(angle)
    return c * hx - s * hy, s * hx + c * hy


@inline
def turn_toward(fx, fy, fz, dx, dy, dz, max_turn, sx, sy, sz):
    cosine = fx * dx + fy * dy + fz * dz
    if max_turn >= math.pi or cosine >= math.cos(max_turn):
        return dx, dy, dz
    wx, wy, wz = dx - cosine * fx, dy - cosine * fy, dz - cosine * fz
    w = math.sqrt(wx * wx + wy * wy + wz * wz)
    if w > PARALLEL:
        wx, wy, wz = wx / w, wy / w, wz / w
    else:
        wx, wy, wz = sx, sy, sz
    c, s = math.cos(max_turn), math.sin(max_turn)
    return c * fx + s * wx, c * fy + s * wy, c * fz + s * wz


@inline
def unit_heading(hx, hy, hz, planar):
    if planar:
        hz = 0.0
    norm = math.sqrt(hx * hx + hy * hy + hz * hz)
    return hx / norm, hy / norm, hz / norm


def float_dyn(slots):
    return slots, np.zeros(0, np.int64), np.zeros((0, 1)), np.zeros(0, np.int64), np.zeros((0, 3))


def heading_scratch(dynamics, n):
    return np.zeros((n, 3), np.float64), np.zeros((0, 3), np.float64)


@inline
def set_heading(i, hx, hy, hz, speed, planar, vel, fwd, up, side, acc, fp):
    dt = fp[F.DT]
    vx, vy, vz = speed * hx, speed * hy, speed * hz
    acc[i, 0], acc[i, 1], acc[i, 2] = (vx - vel[i, 0]) / dt, (vy - vel[i, 1]) / dt, (vz - vel[i, 2]) / dt
    vel[i, 0], vel[i, 1], vel[i, 2] = vx, vy, vz
    if planar:
        planar_axes(i, hx, hy, fwd, up, side)
    else:
        rebuild_frame(i, vx, vy, vz, math.sqrt(vx * vx + vy * vy + vz * vz), fwd, up, side, acc, dt)
