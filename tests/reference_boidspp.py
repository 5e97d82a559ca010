"""Slow, plain reference of docs/model.md section 6: the Boids++ dynamics, its prey and its predator.

Written from docs/model.md; it shares no code with the kernel except the counter-based uniform draw
``simcore.rng.uniform01`` (the draws are part of the specification) and, for obstacles, the numpy
geometry twin ``reference_obstacles`` (ray casts by golden-section search and bisection, the fan by the
textbook spiral, the choice by brute force). Sphere perception only (|d| < radius), explicit Python
loops, neighbours in ascending index order. Not meant to be fast.

One step s, in order:

* R1 agents appear: a prey not yet placed takes random point 0 as position and point 1 as target (point
  k: z = 2 u0 - 1, azimuth 2 pi u1, radius R u2^(1/3) about the target centre, u_c the uniform of
  stream TARGETS at (k, c)); a waiting predator, once s >= its start step, appears at the mean boid
  position + start_distance times the unit vector from the uniforms at (0, 3), (0, 4); a hunting one
  leaves once s >= its leave step.
* R2 captures: a boid strictly within the capture radius of an appeared predator, not yet captured,
  gets capture step s.
* R3 per boid, from the state of time t: within avoid_radius of an appeared predator it flees
  v <- S_f (max_speed away) + (1 - S_f) v and skips the rules and the prey; else the blends in order
  alignment (mean neighbour velocity; scope flock: (sum of all v - v_i)/(N - 1), sums taken at the
  start of the step), cohesion (mean offset; scope flock: (sum of all p - p_i)/(N - 1) - p_i, or in a
  periodic box the mean minimum-image offset to every other boid's current position), separation
  (inverse square: mean of (p_i - p_j)/|p_i - p_j|^2 over neighbours with 0 < |d| < radius, scaled to
  max_speed; literal: mean of v_j/|d|), each only when it has neighbours, then the prey seek v += prey.weight dt unit(prey - p);
  then the random kick on steps s % every == 0 (uniforms of stream RANDOM_FORCE at (s, 2i), (s, 2i+1));
  then the fan avoidance v += avoid.weight dt d when the forward ray is blocked (d: the fan ray, or the
  outward normal when the body overlaps); then the speed clamp to [min_speed, max_speed] (a stopped
  boid: min_speed along f).
* R4 agents' velocities from the boids of time t: predator +-speed unit(mean offset to the boids) (a
  hunting predator with target "nearest": speed unit(offset to the nearest boid, lower index on ties));
  prey min(speed, dist/dt) unit(target - p).
* R5 boids move: acc = (v' - v)/dt, p += v' dt, banking frame (docs/model.md section 1), boundary;
  synchronous order moves all after all decided, sequential moves each at once.
* R6 agents move by v dt (predator through the boundary); the prey within arrive_radius of its target
  draws point k (k = points drawn so far) as its next target.
"""
from __future__ import annotations

import math

import numpy as np

import reference_obstacles as ro
from reference_hb import boundary, box_of, dot3, frame_after_move, in_plane, norm3, offset
from flocksweep.simcore.boidspp_params import STREAMS
from flocksweep.simcore.rng import uniform01

STREAM_RANDOM_FORCE, STREAM_TARGETS = STREAMS["random_force"], STREAMS["targets"]

STATE_KEYS = ("pos", "vel", "fwd", "up", "side", "acc")
WAITING, HUNTING, LEAVING = 0, 1, 2


def unit_from(u0: float, u1: float) -> np.ndarray:
    z = 2.0 * u0 - 1.0
    r = math.sqrt(max(0.0, 1.0 - z * z))
    return np.array([r * math.cos(2.0 * math.pi * u1), r * math.sin(2.0 * math.pi * u1), z])


def random_unit(u0: float, u1: float, model) -> np.ndarray:
    """unit_from in 3-D; in 2-D the unit vector at angle 2 pi u1 in the plane (docs/model.md section 15)."""
    if model.world.dimensions == 2:
        return np.array([math.cos(2.0 * math.pi * u1), math.sin(2.0 * math.pi * u1), 0.0])
    return unit_from(u0, u1)


def prey_point(key, k, prey, model) -> np.ndarray:
    """Uniform in the ball (in 2-D the disc) of the target radius about the target centre."""
    u = [uniform01(key, STREAM_TARGETS, k, c) for c in range(3)]
    power = 0.5 if model.world.dimensions == 2 else 1.0 / 3.0
    return np.asarray(prey.target_centre) + prey.target_radius * u[2] ** power * random_unit(u[0], u[1], model)


def first_step(seconds, dt) -> float:
    return math.inf if seconds is None else math.ceil(seconds / dt - 1e-9)


class Agents:
    """Predator and prey of one run (plain attributes)."""

    def __init__(self):
        self.pred = np.full(3, np.nan)
        self.prey = np.full(3, np.nan)
        self.target = np.full(3, np.nan)
        self.drawn = 0
        self.phase = WAITING


def mean_offset(pos, point, box) -> np.ndarray:
    total = np.zeros(3)
    for j in range(len(pos)):
        total = total + offset(point, pos[j], box)
    return total / len(pos)


def place(agents: Agents, step, pos, model, dt, key, box) -> None:
    """R1."""
    table = model.boidspp
    if table.prey.enabled and agents.drawn == 0:
        agents.prey, agents.target = prey_point(key, 0, table.prey, model), prey_point(key, 1, table.prey, model)
        agents.drawn = 2
    if not table.predator.enabled:
        return
    if agents.phase == WAITING and step >= first_step(table.predator.start_s, dt):
        direction = random_unit(uniform01(key, STREAM_TARGETS, 0, 3), uniform01(key, STREAM_TARGETS, 0, 4), model)
        agents.pred = mean_offset(pos, np.zeros(3), box) + table.predator.start_distance * direction
        agents.phase = HUNTING
    if agents.phase == HUNTING and step >= first_step(table.predator.leave_s, dt):
        agents.phase = LEAVING


def with_length(v, length) -> np.ndarray:
    n = norm3(v)
    return np.zeros(3) if n == 0.0 else v * (length / n)


def flock_sums(pos, vel) -> tuple[np.ndarray, np.ndarray]:
    """Sums of the positions and of the velocities over the flock, in boid order."""
    sp, sv = np.zeros(3), np.zeros(3)
    for j in range(len(pos)):
        sp, sv = sp + pos[j], sv + vel[j]
    return sp, sv


def rule_blends(i, v, pos, vel, sums, model, box) -> np.ndarray:
    table = model.boidspp
    n = len(pos)
    nbrs = [j for j in range(n) if j != i
            and dot3(offset(pos[i], pos[j], box), offset(pos[i], pos[j], box)) < model.perception.radius ** 2]
    if table.alignment.scope == "flock":
        if n > 1:
            v = table.alignment.blend * ((sums[1] - vel[i]) / (n - 1)) + (1.0 - table.alignment.blend) * v
    elif nbrs:
        mean_v = sum((vel[j] for j in nbrs), np.zeros(3)) / len(nbrs)
        v = table.alignment.blend * mean_v + (1.0 - table.alignment.blend) * v
    if table.cohesion.scope == "flock":
        if n > 1:
            if box is None:
                centre = (sums[0] - pos[i]) / (n - 1) - pos[i]
            else:  # minimum images of the current positions
                centre = sum((offset(pos[i], pos[j], box) for j in range(n) if j != i), np.zeros(3)) / (n - 1)
            v = table.cohesion.blend * centre + (1.0 - table.cohesion.blend) * v
    elif nbrs:
        centre = sum((offset(pos[i], pos[j], box) for j in nbrs), np.zeros(3)) / len(nbrs)
        v = table.cohesion.blend * centre + (1.0 - table.cohesion.blend) * v
    close = [j for j in nbrs if 0.0 < norm3(offset(pos[i], pos[j], box)) < table.separation.radius]
    if close:
        if table.separation.form == "inverse_square":
            push = sum((-offset(pos[i], pos[j], box) / norm3(offset(pos[i], pos[j], box)) ** 2 for j in close),
                       np.zeros(3)) / len(close)
            target = with_length(push, model.vehicle.max_speed)
        else:
            target = sum((vel[j] / norm3(offset(pos[i], pos[j], box)) for j in close), np.zeros(3)) / len(close)
        v = table.separation.blend * target + (1.0 - table.separation.blend) * v
    return v


def avoidance(i, state, model) -> np.ndarray | None:
    """The fan direction d of boid i (None when the forward ray is free)."""
    obstacles, avoid = model.world.obstacles, model.boidspp.avoid
    if not obstacles:
        return None
    p = state["pos"][i]
    k, _ = ro.deepest_overlap(obstacles, p, avoid.body_radius)
    if k >= 0:  # the outward normal: exact for a sphere, central differences otherwise
        if obstacles[k].kind == "sphere":
            return with_length(p - np.asarray(obstacles[k].centre), 1.0)
        return ro.gradient(obstacles[k], [p])[0]
    frame = (state["fwd"][i], state["up"][i], state["side"][i])
    ray, direction, _ = ro.fan_choice(obstacles, p, frame, ro.fan_coefficients(avoid.rays), avoid.body_radius,
                                      avoid.lookahead)
    return None if ray == -1 else direction


def new_velocity(i, step, state, agents: Agents, sums, model, dt, key, box) -> np.ndarray:
    """R3."""
    table = model.boidspp
    max_speed = model.vehicle.max_speed
    pos, vel = state["pos"], state["vel"]
    v = vel[i].copy()
    flee = False
    if table.predator.enabled and agents.phase != WAITING:
        away = offset(agents.pred, pos[i], box)
        if norm3(away) < table.predator.avoid_radius:
            flee = True
            target = with_length(away, max_speed) if norm3(away) > 0 else state["fwd"][i] * max_speed
            v = table.predator.flee_blend * target + (1.0 - table.predator.flee_blend) * v
    if not flee:
        v = rule_blends(i, v, pos, vel, sums, model, box)
        if table.prey.enabled:
            v = v + with_length(offset(pos[i], agents.prey, box), table.prey.weight * dt)
    kick = table.random_force
    if kick.magnitude > 0 and step % kick.every == 0:
        v = v + kick.magnitude * random_unit(uniform01(key, STREAM_RANDOM_FORCE, step, 2 * i),
                                             uniform01(key, STREAM_RANDOM_FORCE, step, 2 * i + 1), model)
    if table.avoid.weight > 0:
        d = avoidance(i, state, model)
        if d is not None:
            v = v + table.avoid.weight * dt * d
    v = in_plane(v, model)
    speed = norm3(v)
    if speed > max_speed:
        v = v * (max_speed / speed)
    elif speed < table.min_speed:
        v = state["fwd"][i] * table.min_speed if speed == 0 else v * (table.min_speed / speed)
    return v


def move(i, v, state, model, dt) -> None:
    """R5 for boid i, in place."""
    v0 = state["vel"][i].copy()
    a = (v - v0) / dt
    p = state["pos"][i] + v * dt
    f, up, side = frame_after_move(i, v, a, state, model, dt)
    state["pos"][i] = boundary(p, model.world)
    state["vel"][i], state["acc"][i], state["fwd"][i] = v, a, f
    state["up"][i], state["side"][i] = up, side


def step(state: dict, agents: Agents, capture: np.ndarray, model, dt, step_index: int, key) -> None:
    """R1-R6 of one step, in place on ``state`` (arrays), ``agents`` and ``capture`` (first capture steps)."""
    table = model.boidspp
    box = box_of(model)
    n = len(state["pos"])
    place(agents, step_index, state["pos"], model, dt, key, box)
    radius = table.predator.capture_radius
    if table.predator.enabled and radius is not None and agents.phase != WAITING:
        for i in range(n):
            if capture[i] < 0 and norm3(offset(agents.pred, state["pos"][i], box)) < radius:
                capture[i] = step_index
    pred_v = prey_v = np.zeros(3)
    if table.predator.enabled and agents.phase == HUNTING and table.predator.target == "nearest":
        gaps = [offset(agents.pred, p, box) for p in state["pos"]]
        nearest = min(range(n), key=lambda j: (dot3(gaps[j], gaps[j]), j))
        pred_v = with_length(gaps[nearest], table.predator.speed)
    elif table.predator.enabled and agents.phase != WAITING:
        sign = 1.0 if agents.phase == HUNTING else -1.0
        pred_v = with_length(sign * mean_offset(state["pos"], agents.pred, box), table.predator.speed)
    if table.prey.enabled:
        gap = agents.target - agents.prey
        prey_v = with_length(gap, min(table.prey.speed, norm3(gap) / dt))
    sums = flock_sums(state["pos"], state["vel"])
    sequential = model.world.update_order == "sequential"
    if sequential:
        for i in range(n):
            move(i, new_velocity(i, step_index, state, agents, sums, model, dt, key, box), state, model, dt)
    else:
        new = [new_velocity(i, step_index, state, agents, sums, model, dt, key, box) for i in range(n)]
        for i in range(n):
            move(i, new[i], state, model, dt)
    if table.predator.enabled and agents.phase != WAITING:
        agents.pred = boundary(agents.pred + pred_v * dt, model.world)
    if table.prey.enabled:
        agents.prey = agents.prey + prey_v * dt
        if norm3(agents.target - agents.prey) <= table.prey.arrive_radius:
            agents.target = prey_point(key, agents.drawn, table.prey, model)
            agents.drawn += 1


def run(state, model, dt, n_steps: int, key) -> tuple[dict, Agents, np.ndarray]:
    """``n_steps`` steps from copies of ``state``; then the agents placed for step ``n_steps`` (as the
    kernel does before its final record). Returns (state arrays, agents, capture steps)."""
    arrays = {name: np.array(getattr(state, name), dtype=np.float64, copy=True) for name in STATE_KEYS}
    agents = Agents()
    capture = np.full(len(arrays["pos"]), -1, dtype=np.int64)
    for s in range(n_steps):
        step(arrays, agents, capture, model, dt, s, key)
    place(agents, n_steps, arrays["pos"], model, dt, key, box_of(model))
    return arrays, agents, capture
