"""Slow, plain reference of docs/model.md section 5: Hartman-Benes dynamics and the change of leadership.

Written from docs/model.md (sections 0, 1, 5, 7) and the project decisions stated in the docstrings of
``simcore.rules``, ``simcore.dynamics`` and ``simcore.leadership``; it shares no code with the kernel
except the counter-based normal draw ``simcore.rng.normal`` (the draws are part of the specification:
a pure function of (run key, stream, step, boid)). Everything is float64, explicit Python loops over
boids, neighbours summed in ascending index order. Not meant to be fast.

Decisions followed (beyond the spec's text):

* D1 separation s = sum_j (p_i - p_j) / |p_i - p_j|^f, f = ``gains.separation_falloff_exponent``;
  a neighbour at distance 0 adds nothing. k = mean_j (p_j - p_i), mv = mean_j v_j over the sphere
  neighbours (|d| < radius, compared squared); all zero when there are none.
* D2 p' = p + dt v (old velocity); v' = v + (S s + K k)/dt + M mv (+ escape dv), truncated to the cap
  (max_speed, or a leader's raised cap); acc = (v' - v)/dt drives the banking frame.
* D3 the frame is rebuilt as in docs/model.md section 1 even for a stopped boid (forward kept); when f is
  parallel to the new up, side falls back to the old side made orthogonal to f. Then the boundary.
* D4 leadership trigger (only when ``leadership.x > 0``), per boid, in this order: not a leader and
  not refractory (clock >= duration + refractory - dt/2); m >= 1; |k| > 0; eccentricity x = |k| / e;
  a boid slower than slow_speed passes the gate (and escapes along -k/|k|); otherwise
  front = -(k/|k|).(v/|v|) and the gate ``positive`` needs front > 0, ``weighted`` uses
  x max(front, 0) as the score, ``none`` passes; trigger when X score > g, g = clip(1/2 + sigma z, 0, 1).
* D5 a boid that triggers at a step escapes from that same step on (clock = 0); escape
  dv = gain b(clock/T) max(|v|, slow_speed) d with d = v/|v| (or the fixed escape direction of a slow
  boid; no dv for a stopped boid without one), cap = max_speed (1 + boost b(clock/T)); a boid whose
  profile value is 0 (not a leader) keeps cap = max_speed. All clocks advance by dt at the end of
  the step.
* D6 synchronous order: every boid perceives and decides from the state at t, then all move;
  sequential: boid i perceives and decides after boids 0..i-1 have moved.
"""
from __future__ import annotations

import math

import numpy as np

from flocksweep.simcore.rng import STREAM_LEADERSHIP, normal

# The escape profile of docs/model.md section 5 (Figure 5 of the paper, 30 samples equally spaced on [0, 1]).
PROFILE_SAMPLES = (0.01, 0.05, 0.10, 0.16, 0.27, 0.40, 0.55, 0.72, 0.85, 0.96,
                   1.00, 0.98, 0.90, 0.80, 0.65, 0.51, 0.36, 0.25, 0.18, 0.14,
                   0.12, 0.10, 0.08, 0.07, 0.06, 0.05, 0.04, 0.03, 0.02, 0.00)

STATE_KEYS = ("pos", "vel", "fwd", "up", "side", "acc", "clock", "escape")


# ---------------------------------------------------------------------------------------------------
# small vector helpers
def dot3(a, b) -> float:
    return float(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


def norm3(a) -> float:
    return math.sqrt(dot3(a, a))


def cross3(a, b) -> np.ndarray:
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def clamp_length(v, limit: float) -> np.ndarray:
    length = norm3(v)
    if length > limit:
        return v * (limit / length)
    return v


# ---------------------------------------------------------------------------------------------------
# world (docs/model.md section 0)
def box_of(model):
    """Side of the periodic box, or None for the other boundaries."""
    return model.world.box_size if model.world.boundary == "periodic_box" else None


def offset(p_i, p_j, box=None) -> np.ndarray:
    """d = p_j - p_i, minimum image in a periodic box."""
    d = np.asarray(p_j, dtype=np.float64) - np.asarray(p_i, dtype=np.float64)
    if box is not None:
        d = d - box * np.floor(d / box + 0.5)
    return d


def boundary(p, world) -> np.ndarray:
    if world.boundary == "sphere_wrap":
        r = norm3(p)
        if r > world.sphere_radius:
            p = p - (2.0 * world.sphere_radius / r) * p
    elif world.boundary == "periodic_box":
        side = world.box_size
        p = p - side * np.floor((p + 0.5 * side) / side)
    return p


# ---------------------------------------------------------------------------------------------------
# perception and the Hartman-Benes terms (docs/model.md sections 2 and 5, decision D1)
def neighbours(i, pos, radius, box=None) -> list:
    """Ascending j != i with |p_j - p_i| < radius."""
    out = []
    for j in range(len(pos)):
        if j == i:
            continue
        d = offset(pos[i], pos[j], box)
        if dot3(d, d) < radius * radius:
            out.append(j)
    return out


def hb_terms(i, nbrs, pos, vel, falloff, box=None):
    """(s, k, mv) of boid i from its neighbour list."""
    s = np.zeros(3)
    k = np.zeros(3)
    mv = np.zeros(3)
    for j in nbrs:
        d = offset(pos[i], pos[j], box)  # p_j - p_i
        dist = norm3(d)
        if falloff == 0.0:
            s = s + (-d)
        elif dist > 0.0:
            s = s + (-d) / dist ** falloff
        k = k + d
        mv = mv + vel[j]
    if nbrs:
        k = k / len(nbrs)
        mv = mv / len(nbrs)
    return s, k, mv


# ---------------------------------------------------------------------------------------------------
# change of leadership (docs/model.md section 5, decisions D4-D5)
def profile(u: float) -> float:
    """Escape profile b(u): the samples linearly interpolated on [0, 1), 0 elsewhere."""
    if not (0.0 <= u < 1.0):
        return 0.0
    grid = np.linspace(0.0, 1.0, len(PROFILE_SAMPLES))
    return float(np.interp(u, grid, PROFILE_SAMPLES))


def slow_speed_of(model) -> float:
    lead = model.leadership
    return 0.05 * model.vehicle.max_speed if lead.slow_speed is None else lead.slow_speed


def gauss_rand01(key, step, i, sigma) -> float:
    """GaussRand01 = clip(1/2 + sigma z, 0, 1), z the counter-based normal of (key, stream, step, i)."""
    z = float(normal(np.uint64(key), STREAM_LEADERSHIP, np.uint64(step), np.uint64(i)))
    return min(1.0, max(0.0, 0.5 + sigma * z))


def is_leader(clock_i, model, dt):
    """Leader while clock < duration - dt/2: the summed clock's rounding never adds or drops a step."""
    return clock_i < model.leadership.duration - 0.5 * dt


def trigger_score(k, m, v, clock_i, model, dt):
    """(score, slow) of the trigger test, or (None, False) when the boid cannot trigger at all.
    The boid triggers when X score > g."""
    lead = model.leadership
    if clock_i < lead.duration + lead.refractory - 0.5 * dt or m < 1:
        return None, False
    k_len = norm3(k)
    if k_len == 0.0:
        return None, False
    x = k_len / model.perception.radius
    speed = norm3(v)
    if speed < slow_speed_of(model):
        return x, True
    front = -dot3(k, v) / (k_len * speed)
    if lead.front_gate == "positive":
        return (x, False) if front > 0.0 else (None, False)
    if lead.front_gate == "weighted":
        return x * max(front, 0.0), False
    if lead.front_gate == "none":
        return x, False
    raise ValueError(f"unknown front gate {lead.front_gate!r}")


def decide(i, step, k, m, v, clock_i, model, key, dt):
    """(trigger?, slow?) of boid i at ``step``."""
    score, slow = trigger_score(k, m, v, clock_i, model, dt)
    if score is None:
        return False, False
    g = gauss_rand01(key, step, i, model.leadership.sigma)
    return model.leadership.x * score > g, slow


def escape(v, clock_i, direction, model, dt):
    """(dv, cap) of a boid in this step (dv = 0 and cap = max_speed when it is not a leader)."""
    lead, max_speed = model.leadership, model.vehicle.max_speed
    if not is_leader(clock_i, model, dt):
        return np.zeros(3), max_speed
    b = profile(clock_i / lead.duration)
    if b == 0.0:
        return np.zeros(3), max_speed
    cap = max_speed * (1.0 + lead.boost * b)
    speed = norm3(v)
    if norm3(direction) > 0.0:
        d = np.asarray(direction, dtype=np.float64)
    elif speed > 0.0:
        d = v / speed
    else:
        return np.zeros(3), cap
    return lead.gain * b * max(speed, slow_speed_of(model)) * d, cap


def banked_frame(i, v, a, state, dt):
    """The frame of boid i rebuilt after a move (section 1: banking toward 0.05 a + 0.2 y, forward along the
    new velocity ``v``, a stopped boid keeping its heading), from its frame in ``state``: (fwd, up, side)."""
    up_old, side_old = state["up"][i], state["side"][i]
    rate = min(max(3.0 * dt, 0.0), 1.0)
    u = up_old + rate * (0.05 * a + np.array([0.0, 0.2, 0.0]) - up_old)
    u_len = norm3(u)
    u = u / u_len if u_len > 0.0 else up_old.copy()
    speed = norm3(v)
    f = v / speed if speed > 0.0 else state["fwd"][i].copy()
    side = cross3(f, u)
    side_len = norm3(side)
    if side_len > 1e-12:
        side = side / side_len
    else:
        side = side_old - dot3(side_old, f) * f
        side = side / norm3(side) if norm3(side) > 0.0 else np.zeros(3)
    return f, cross3(side, f), side


def planar_frame(i, v, state):
    """The frame of boid i in the plane z = 0 after a move (docs/model.md section 15): f = v/|v| (the old
    heading when stopped) with z = 0, up = +z, side = f x up."""
    speed = norm3(v)
    f = v / speed if speed > 0.0 else state["fwd"][i].copy()
    f = np.array([f[0], f[1], 0.0])
    return f, np.array([0.0, 0.0, 1.0]), np.array([f[1], -f[0], 0.0])


def frame_after_move(i, v, a, state, model, dt):
    """(fwd, up, side) after a move: the planar frame in 2-D, else the banking frame."""
    if model.world.dimensions == 2:
        return planar_frame(i, v, state)
    return banked_frame(i, v, a, state, dt)


def in_plane(v, model) -> np.ndarray:
    """v with its z set to 0 in a 2-D model (a force or steer before it is used)."""
    v = np.array(v, dtype=np.float64)
    if model.world.dimensions == 2:
        v[2] = 0.0
    return v


# ---------------------------------------------------------------------------------------------------
# motion (docs/model.md sections 5 and 1, decisions D2-D3)
def move(i, s, k, mv, dv, cap, state, model, dt) -> None:
    """One Hartman-Benes frame of boid i, in place in ``state``."""
    g = model.gains
    s, k, mv = in_plane(s, model), in_plane(k, model), in_plane(mv, model)
    v0 = state["vel"][i].copy()
    p = state["pos"][i] + dt * v0
    v = v0 + (g.separation * s + g.cohesion * k) / dt + g.alignment * mv
    v = clamp_length(v + dv, cap)
    a = (v - v0) / dt

    f, u, side = frame_after_move(i, v, a, state, model, dt)

    state["pos"][i] = boundary(p, model.world)
    state["vel"][i] = v
    state["acc"][i] = a
    state["fwd"][i] = f
    state["up"][i] = u
    state["side"][i] = side


def step(state, model, dt, step_index=0, key=0) -> dict:
    """One step on copies of ``state`` (a mapping or object with the ``STATE_KEYS`` arrays).

    Returns a dict with the new arrays, ``visible`` (neighbours each boid perceived when it decided)
    and ``triggers``: list of (step_index, boid) in boid order."""
    def get(name):
        return np.array(state[name] if isinstance(state, dict) else getattr(state, name), dtype=np.float64,
                        copy=True)

    inputs = {name: get(name) for name in STATE_KEYS}
    current = {name: a.copy() for name, a in inputs.items()}
    n = len(current["pos"])
    box = box_of(model)
    radius = model.perception.radius
    falloff = model.gains.separation_falloff_exponent
    leading = model.leadership.x > 0.0
    visible = np.zeros(n, dtype=np.int64)
    triggers = []

    def sense(i, source):
        """Terms of boid i from ``source``; the trigger test (and start) when leadership is on."""
        nbrs = neighbours(i, source["pos"], radius, box)
        visible[i] = len(nbrs)
        s, k, mv = hb_terms(i, nbrs, source["pos"], source["vel"], falloff, box)
        if leading:
            fire, slow = decide(i, step_index, k, len(nbrs), source["vel"][i], current["clock"][i], model, key, dt)
            if fire:
                triggers.append((step_index, i))
                current["clock"][i] = 0.0
                current["escape"][i] = -k / norm3(k) if slow else np.zeros(3)
        return s, k, mv

    def go(i, terms):
        if leading:
            dv, cap = escape(current["vel"][i], current["clock"][i], current["escape"][i], model, dt)
        else:
            dv, cap = np.zeros(3), model.vehicle.max_speed
        move(i, *terms, dv, cap, current, model, dt)

    order = model.world.update_order
    if order == "synchronous":
        terms = [sense(i, inputs) for i in range(n)]
        for i in range(n):
            go(i, terms[i])
    elif order == "sequential":
        for i in range(n):
            go(i, sense(i, current))
    else:
        raise ValueError(f"unknown update order {order!r}")

    if leading:
        current["clock"] = current["clock"] + dt
    return dict(current, visible=visible, triggers=triggers)
