"""Slow, plain reference of docs/model.md "Reynolds 1987" (dynamics ``reynolds87``).

Written from the specification, sharing no code with the kernel: world and sphere perception come from
the Hartman-Benes twin (tests/reference_hb.py: same perception sphere, boundaries and minimum image), ray
casts, overlaps and normals from the obstacle twin (tests/reference_obstacles.py: golden-section/bisection
ray casts, central-difference normals); the silhouettes from support functions, here. Explicit Python loops over boids, neighbours summed
in ascending index order, float64 throughout. Not meant to be fast.

* requests in priority order (obstacle, separation, alignment, cohesion, migration), w_j = |d_j|^-k, a
  neighbour at distance 0 skipped;
* steer-to-avoid: inside (sd <= b) -> outward normal of the deepest overlap; else the nearest forward hit
  within lookahead -> toward T = S + margin o: the silhouette normal o minimises, over image directions,
  the inflated solid's support function minus o . p (a scan of the circle refined by Brent's method: the
  distance from the ray's image to the convex outline), S is the point of the solid's support set along
  o whose image is the silhouette point, lifted by b o (front-most where the support set is a segment
  along f); a plane -> f along the plane;
* allocation ``priority`` (|running vector sum| fills max_accel, the crossing request scaled by the root
  of the quadratic where |a + s r| leaves the ball, found here by ``numpy.roots``; reached from a share
  1 - 1e-12 of the budget), ``priority_magnitude`` (sum of magnitudes) or
  ``weighted_sum`` (sum, truncated);
* v' = v + a dt clamped into [min_speed, max_speed] (zero -> min_speed along f), p += v' dt, acc = realised
  acceleration, banking frame as in docs/model.md section 1, then the boundary.
"""
from __future__ import annotations

import numpy as np

import reference_obstacles as geo
from reference_hb import boundary, box_of, dot3, frame_after_move, in_plane, neighbours, norm3, offset

STATE_KEYS = ("pos", "vel", "fwd", "up", "side", "acc")
FULL = 1.0 - 1e-12  # the budget counts as reached from this share of max_accel (squares for the vector sum)


SCAN = 4096  # directions scanned around the image circle before refining the silhouette minimum
FREE = 1e-7  # a support direction component below this is taken as zero (the support set is an edge)


def support(obstacle, o) -> np.ndarray:
    """Support function h(o) = max over the solid of x . o, for unit directions o (M, 3)."""
    c = np.asarray(obstacle.centre, dtype=float)
    if obstacle.kind == "sphere":
        return o @ c + obstacle.radius
    if obstacle.kind == "box":
        return o @ c + np.abs(o) @ np.asarray(obstacle.half_extents)
    along = o @ np.asarray(obstacle.axis)
    return o @ c + 0.5 * obstacle.length * np.abs(along) + obstacle.radius * np.sqrt(np.maximum(0.0, 1.0 - along ** 2))


def silhouette(obstacle, p, f, b: float):
    """(delta, o): the minimum over image directions o (unit, perpendicular to f) of the inflated solid's
    support along o minus o . p, and its minimiser: the distance from the ray's image to the inflated
    outline and the outline's outward normal there. A scan of the circle, refined by bounded Brent."""
    from scipy.optimize import minimize_scalar

    e1 = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(f, e1)

    def gap(phi):
        o = np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2)
        return support(obstacle, o) + b - o @ p

    phis = np.arange(SCAN) * (2.0 * np.pi / SCAN)
    best = phis[int(np.argmin(gap(phis)))]
    step = 2.0 * np.pi / SCAN
    res = minimize_scalar(lambda x: gap(np.array([x]))[0], bounds=(best - step, best + step), method="bounded",
                          options={"xatol": 1e-13})
    o = np.cos(res.x) * e1 + np.sin(res.x) * e2
    return float(res.fun), o


def support_depth(obstacle, o, p, f, delta: float, b: float) -> float:
    """f . (S - p) for the support point S of the solid along o whose image is the silhouette point (the one
    nearest the boid where the support set is a segment along f), i.e. how far ahead the edge is."""
    c = np.asarray(obstacle.centre, dtype=float)
    if obstacle.kind == "sphere":
        return float(f @ (c + obstacle.radius * o - p))
    if obstacle.kind == "box":
        h = np.asarray(obstacle.half_extents)
        corner = c + np.where(np.abs(o) > FREE, np.sign(o), 0.0) * h
        free = [np.eye(3)[i] for i in range(3) if abs(o[i]) <= FREE]
    else:
        axis = np.asarray(obstacle.axis)
        radial = o - (o @ axis) * axis
        rim = c + obstacle.radius * radial / np.linalg.norm(radial)
        if abs(o @ axis) > FREE:
            corner, free = rim + 0.5 * obstacle.length * np.sign(o @ axis) * axis, []
        else:
            corner, free = rim, [axis]
    if not free:
        return float(f @ (corner - p))
    # corner + sum lambda_k e_k = p + (delta - b) o + t f: solve for (lambda, t)
    matrix = np.column_stack(free + [-f])
    solution = np.linalg.lstsq(matrix, p + (delta - b) * o - corner, rcond=None)[0]
    return float(solution[-1])


def avoidance(obstacles, p, f, u, b: float, lookahead: float, margin: float) -> np.ndarray:
    """Unit steer-to-avoid direction, or zero when nothing is ahead (module docstring)."""
    k, _sd = geo.deepest_overlap(obstacles, p, b)
    if k >= 0:
        n = geo.gradient(obstacles[k], [p])[0]
        return n / np.linalg.norm(n)
    hit, _t, _closeness = geo.first_hits(obstacles, [p], [f], b, lookahead)
    if hit[0] < 0:
        return np.zeros(3)
    obstacle = obstacles[int(hit[0])]
    if obstacle.kind == "plane":
        return geo.along_plane(obstacle.normal, f, u)
    delta, o = silhouette(obstacle, p, f, b)
    d = (delta + margin) * o + support_depth(obstacle, o, p, f, delta, b) * f
    return d / np.linalg.norm(d)


def requests(i, pos, vel, fwd, up, model) -> tuple[list, int]:
    """([obstacle, separation, alignment, cohesion, migration] acceleration requests, neighbour count)."""
    rey = model.reynolds
    box = box_of(model)
    nbrs = neighbours(i, pos, model.perception.radius, box)
    sep, wv, wd, wsum = np.zeros(3), np.zeros(3), np.zeros(3), 0.0
    ahead = False
    for j in nbrs:
        d = offset(pos[i], pos[j], box)
        ahead = ahead or dot3(fwd[i], d) > 0.0
        dist = norm3(d)
        if dist == 0.0:
            continue
        w = dist ** -rey.falloff_exponent
        sep = sep - d / dist * w
        wv = wv + w * vel[j]
        wd = wd + w * d
        wsum += w
    obstacle = np.zeros(3)
    if model.world.obstacles and rey.obstacle_weight > 0.0:
        obstacle = rey.obstacle_weight * avoidance(model.world.obstacles, pos[i], fwd[i], up[i], rey.body_radius,
                                                   rey.lookahead, rey.avoid_margin)
    alignment = rey.alignment_weight * (wv / wsum - vel[i]) if wsum > 0.0 else np.zeros(3)
    cohesion = rey.cohesion_weight * wd / wsum if wsum > 0.0 else np.zeros(3)
    migrate = rey.migration_weight > 0.0 and (rey.migration_who == "all" or not ahead)
    migration = rey.migration_weight * np.asarray(rey.migration_direction) if migrate else np.zeros(3)
    return [obstacle, rey.separation_weight * sep, alignment, cohesion, migration], len(nbrs)


def allocate(reqs, max_accel: float, mode: str) -> np.ndarray:
    """The allocated acceleration of a list of requests in priority order (module docstring)."""
    a = np.zeros(3)
    if mode == "weighted_sum":
        for r in reqs:
            a = a + r
        size = norm3(a)
        return a * (max_accel / size) if size > max_accel else a
    spent = 0.0
    for r in reqs:
        size = norm3(r)
        if size == 0.0:
            continue
        if mode == "priority_magnitude":
            if spent + size <= max_accel:
                a, spent = a + r, spent + size
                if spent >= max_accel * FULL:
                    return a
                continue
            return a + (max_accel - spent) / size * r
        if norm3(a + r) <= max_accel:
            a = a + r
            if dot3(a, a) >= max_accel ** 2 * FULL:
                return a
            continue
        roots = np.roots([dot3(r, r), 2.0 * dot3(a, r), dot3(a, a) - max_accel ** 2])
        s = max(x.real for x in roots)
        return a + s * r
    return a


def move(i, a, state, model, dt) -> None:
    """Velocity with speed limits, position, realised acceleration, banking frame, boundary (in place)."""
    rey = model.reynolds
    v0 = state["vel"][i].copy()
    v = v0 + in_plane(a, model) * dt
    speed = norm3(v)
    if speed > rey.max_speed:
        v = v * (rey.max_speed / speed)
    elif speed < rey.min_speed:
        v = v * (rey.min_speed / speed) if speed > 0.0 else rey.min_speed * state["fwd"][i]
    p = state["pos"][i] + v * dt
    acc = (v - v0) / dt
    f, up, side = frame_after_move(i, v, acc, state, model, dt)
    state["pos"][i] = boundary(p, model.world)
    state["vel"][i] = v
    state["acc"][i] = acc
    state["fwd"][i] = f
    state["side"][i] = side
    state["up"][i] = up


def step(state, model, dt) -> dict:
    """One step on copies of ``state``; returns the new arrays, ``visible`` and ``accel`` (allocated)."""
    inputs = {k: np.array(state[k] if isinstance(state, dict) else getattr(state, k), dtype=np.float64)
              for k in STATE_KEYS}
    current = {k: v.copy() for k, v in inputs.items()}
    n = len(current["pos"])
    rey = model.reynolds
    visible = np.zeros(n, dtype=np.int64)
    accel = np.zeros((n, 3))

    def decide(i, source):
        reqs, visible[i] = requests(i, source["pos"], source["vel"], source["fwd"], source["up"], model)
        accel[i] = allocate(reqs, rey.max_accel, rey.allocation)

    if model.world.update_order == "synchronous":
        for i in range(n):
            decide(i, inputs)
        for i in range(n):
            move(i, accel[i], current, model, dt)
    else:
        for i in range(n):
            decide(i, current)
            move(i, accel[i], current, model, dt)
    return {**current, "visible": visible, "accel": accel}
