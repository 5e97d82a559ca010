"""Slow, plain references of docs/model.md "Couzin et al. 2002" (dynamics ``couzin2002``) and "Vicsek et al.
1995" (``vicsek``), in 2-D and 3-D.

Written from the specification, sharing no code with the kernels: neighbours by all pairs in ascending
index order (minimum image in a periodic box), world boundaries and the 3-D banking frame from the
Hartman-Benes twin (tests/reference_hb.py), vectors as numpy arrays, angles with numpy's trigonometry.
The in-loop draws are simcore.rng's (the counter-based streams are the specification of the noise).
Not meant to be fast.
"""
from __future__ import annotations

import math

import numpy as np

from reference_hb import banked_frame, boundary, box_of, offset
from flocksweep.simcore.couzin_params import STREAMS as COUZIN_STREAMS
from flocksweep.simcore.rng import normal, uniform01
from flocksweep.simcore.vicsek_params import STREAMS as VICSEK_STREAMS

STREAM_COUZIN_NOISE, STREAM_VICSEK_NOISE = COUZIN_STREAMS["noise"], VICSEK_STREAMS["noise"]

STATE_KEYS = ("pos", "vel", "fwd", "up", "side", "acc")


def unit(v):
    return v / np.linalg.norm(v)


def around(h):
    """An orthonormal pair across unit h: e1 along h x x (h x y when h is within 26 degrees of x), e2 = h x e1."""
    axis = np.array([1.0, 0.0, 0.0]) if abs(h[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = unit(np.cross(h, axis))
    return e1, np.cross(h, e1)


def tilted(h, angle, azimuth_cos, azimuth_sin):
    e1, e2 = around(h)
    return np.cos(angle) * h + np.sin(angle) * (azimuth_cos * e1 + azimuth_sin * e2)


def turned_in_plane(h, angle):
    return np.array([np.cos(angle) * h[0] - np.sin(angle) * h[1], np.sin(angle) * h[0] + np.cos(angle) * h[1], 0.0])


def neighbours(i, pos, radius, box):
    """[(j, offset)] of the boids j != i closer than radius, ascending j."""
    out = []
    for j in range(len(pos)):
        d = offset(pos[i], pos[j], box)
        if j != i and float(d @ d) < radius * radius:
            out.append((j, d))
    return out


def new_frame(i, h, speed, state, planar, dt):
    """(vel, acc, fwd, up, side) of boid i with the new unit heading h at constant speed."""
    v = speed * h
    a = (v - state["vel"][i]) / dt
    if planar:
        return v, a, np.array([h[0], h[1], 0.0]), np.array([0.0, 0.0, 1.0]), np.array([h[1], -h[0], 0.0])
    f, u, s = banked_frame(i, v, a, state, dt)
    return v, a, f, u, s


def as_dict(state):
    return {k: np.array(getattr(state, k), dtype=np.float64) for k in STATE_KEYS}


# ----------------------------------------------------------------------------------------- Couzin 2002
def couzin_desired(i, state, model, planar):
    c = model.couzin
    f = state["fwd"][i]
    r_o = c.repulsion_radius + c.orientation_width
    half_blind = math.radians(c.blind_deg / 2.0)
    rep, ori, att = [], [], []
    for j, d in neighbours(i, state["pos"], c.outer_radius, box_of(model)):
        if planar:
            d = np.array([d[0], d[1], 0.0])
        dist = np.linalg.norm(d)
        if dist == 0.0:
            continue
        if c.blind_deg > 0.0 and float(f @ d) < -math.cos(half_blind) * dist:   # behind: in the blind cone
            continue
        if dist < c.repulsion_radius:
            rep.append(-d / dist)
        elif dist < r_o:
            ori.append(state["fwd"][j])
        else:
            att.append(d / dist)
    if rep:
        d = np.sum(rep, axis=0)
    elif ori and att:
        d_o, d_a = np.sum(ori, axis=0), np.sum(att, axis=0)
        d = 0.5 * ((d_o / np.linalg.norm(d_o) if np.linalg.norm(d_o) > 0 else d_o)
                   + (d_a / np.linalg.norm(d_a) if np.linalg.norm(d_a) > 0 else d_a))
    elif ori or att:
        d = np.sum(ori or att, axis=0)
    else:
        d = f.copy()
    if planar:
        d[2] = 0.0
    return f.copy() if np.linalg.norm(d) == 0.0 else unit(d)


def couzin_heading(i, state, model, key, step, dt, planar):
    c = model.couzin
    d = couzin_desired(i, state, model, planar)
    if c.noise_sd > 0.0:
        if planar:
            d = turned_in_plane(d, c.noise_sd * float(normal(key, STREAM_COUZIN_NOISE, step, i)))
        else:
            g = np.array([float(normal(key, STREAM_COUZIN_NOISE, step, 2 * i + k)) for k in range(2)])
            if np.linalg.norm(g) > 0:
                d = tilted(d, c.noise_sd * np.linalg.norm(g), *(g / np.linalg.norm(g)))
    f = state["fwd"][i]
    limit = math.radians(c.turning_rate_deg) * dt
    cosine = float(f @ d)
    if limit >= math.pi or cosine >= math.cos(limit):
        h = d
    else:   # turn by the limit towards d, in the plane of f and d
        w = d - cosine * f
        w = w / np.linalg.norm(w) if np.linalg.norm(w) > 1e-12 else state["side"][i]
        h = math.cos(limit) * f + math.sin(limit) * w
    if planar:
        h = np.array([h[0], h[1], 0.0])
    return unit(h)


def couzin_step(state, model, dt, key=0, step=0):
    """One synchronous step of couzin2002 from ``state`` (a State); returns the new state arrays."""
    s = as_dict(state)
    planar = model.world.dimensions == 2
    headings = [couzin_heading(i, s, model, key, step, dt, planar) for i in range(len(s["pos"]))]
    out = {k: v.copy() for k, v in s.items()}
    for i, h in enumerate(headings):
        v, a, f, u, side = new_frame(i, h, model.couzin.speed, s, planar, dt)
        out["vel"][i], out["acc"][i], out["fwd"][i], out["up"][i], out["side"][i] = v, a, f, u, side
        out["pos"][i] = boundary(s["pos"][i] + v * dt, model.world)
    return out


# ------------------------------------------------------------------------------------------ Vicsek 1995
def vicsek_heading(i, state, model, key, step, planar):
    v = model.vicsek
    mean = state["fwd"][i] + sum((state["fwd"][j] for j, _ in neighbours(i, state["pos"], v.radius,
                                                                          box_of(model))), np.zeros(3))
    if planar:
        mean[2] = 0.0
    mean = state["fwd"][i].copy() if np.linalg.norm(mean) == 0.0 else unit(mean)
    if v.noise == 0.0:
        return mean
    if planar:
        return unit(turned_in_plane(mean, v.noise * (float(uniform01(key, STREAM_VICSEK_NOISE, step, i)) - 0.5)))
    u0, u1 = (float(uniform01(key, STREAM_VICSEK_NOISE, step, 2 * i + k)) for k in range(2))
    polar = math.acos(max(-1.0, 1.0 - u0 * v.noise / math.pi))   # uniform on the cap of solid angle 2 eta
    return unit(tilted(mean, polar, math.cos(2 * math.pi * u1), math.sin(2 * math.pi * u1)))


def vicsek_step(state, model, dt, key=0, step=0):
    """One synchronous step of vicsek from ``state`` (a State); returns the new state arrays."""
    s = as_dict(state)
    planar = model.world.dimensions == 2
    headings = [vicsek_heading(i, s, model, key, step, planar) for i in range(len(s["pos"]))]
    out = {k: v.copy() for k, v in s.items()}
    for i, h in enumerate(headings):
        moved = s["pos"][i] + model.vicsek.speed * s["fwd"][i] * dt    # along the old heading
        v, a, f, u, side = new_frame(i, h, model.vicsek.speed, s, planar, dt)
        out["vel"][i], out["acc"][i], out["fwd"][i], out["up"][i], out["side"][i] = v, a, f, u, side
        out["pos"][i] = boundary(moved, model.world)
    return out
