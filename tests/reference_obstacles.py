"""Slow, plain numpy twin of the obstacle geometry (simcore.obstacles, simcore.obstacle_avoidance).

Written from the definitions in docs/obstacles.md, not from the compiled code; only the ``Obstacle``
dataclass is shared. Every function works on arrays of points or rays at once.

* signed distances: the closed "rounded box" form sd = |max(q, 0)| + min(max_i q_i, 0), with
  q = |x - c| - h for a box and q = (distance from the axis - R, |axial| - H) for a cylinder;
  normals by central differences of sd;
* ray casts: the clearance along a ray, g(t) = sd(p + t f) - b, is convex, so golden-section search
  finds its minimum on [0, lookahead] and bisection then finds the first t with g(t) <= 0;
* silhouettes: the outline seen along f is the convex hull (scipy.spatial.ConvexHull) of the projected
  box corners or of 8192 projected points of each cylinder rim, grown by b; distances to it by facets;
* Fibonacci fan by the textbook formula z_i = 1 - i/n, azimuth i * 2 pi / phi^2; choices by brute force.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull

GOLDEN_SECTION_STEPS = 90
BISECTION_STEPS = 70
RIM_SAMPLES = 8192


def signed_distance(obstacle, points) -> np.ndarray:
    """Signed distance (M,) of points (M, 3) to the obstacle's surface, negative inside."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    c = np.asarray(obstacle.centre)
    if obstacle.kind == "sphere":
        return np.linalg.norm(pts - c, axis=1) - obstacle.radius
    if obstacle.kind == "plane":
        return (pts - c) @ np.asarray(obstacle.normal)
    if obstacle.kind == "box":
        q = np.abs(pts - c) - np.asarray(obstacle.half_extents)
    else:
        a = np.asarray(obstacle.axis)
        axial = (pts - c) @ a
        radial = np.linalg.norm((pts - c) - axial[:, None] * a, axis=1)
        q = np.column_stack([radial - obstacle.radius, np.abs(axial) - obstacle.length / 2.0])
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def gradient(obstacle, points, step: float = 1e-7) -> np.ndarray:
    """Outward normals (M, 3): central differences of the signed distance, normalised."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    grad = np.empty_like(pts)
    for axis in range(3):
        shift = np.zeros(3)
        shift[axis] = step
        grad[:, axis] = (signed_distance(obstacle, pts + shift) - signed_distance(obstacle, pts - shift)) / (2 * step)
    return grad / np.linalg.norm(grad, axis=1, keepdims=True)


def ray_cast(obstacle, starts, directions, body_radius, lookahead):
    """(hit, t, min_gap) per ray: first t in [0, lookahead] with sd(p + t f) <= b (t = inf on a miss),
    and the minimum of sd - b over the segment (to tell near-tangent cases). ``body_radius`` and
    ``lookahead`` are numbers or one per ray."""
    p = np.atleast_2d(np.asarray(starts, dtype=float))
    f = np.atleast_2d(np.asarray(directions, dtype=float))
    n = len(p)
    body_radius = np.broadcast_to(np.asarray(body_radius, dtype=float), (n,))
    lookahead = np.broadcast_to(np.asarray(lookahead, dtype=float), (n,))

    def gap(t):
        return signed_distance(obstacle, p + t[:, None] * f) - body_radius

    lo, hi = np.zeros(n), lookahead.copy()
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(GOLDEN_SECTION_STEPS):
        left, right = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        keep_left = gap(left) <= gap(right)
        hi = np.where(keep_left, right, hi)
        lo = np.where(keep_left, lo, left)
    candidates = np.column_stack([np.zeros(n), 0.5 * (lo + hi), lookahead])
    values = np.column_stack([gap(candidates[:, i]) for i in range(3)])
    t_min = candidates[np.arange(n), values.argmin(axis=1)]
    min_gap = values.min(axis=1)
    hit = min_gap <= 0.0
    start_gap = values[:, 0]
    lo, hi = np.zeros(n), t_min.copy()
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        inside = gap(mid) <= 0.0
        hi = np.where(inside, mid, hi)
        lo = np.where(inside, lo, mid)
    t = np.where(start_gap <= 0.0, 0.0, hi)
    return hit, np.where(hit, t, np.inf), min_gap


def image_basis(forward) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane perpendicular to ``forward``."""
    f = np.asarray(forward, dtype=float)
    helper = np.eye(3)[np.argmin(np.abs(f))]
    e1 = np.cross(f, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(f, e1)


def projected_points(obstacle, forward) -> np.ndarray:
    """Points (in 3-D) whose convex hull, projected along ``forward``, is the uninflated outline."""
    c = np.asarray(obstacle.centre)
    if obstacle.kind == "box":
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        return c + signs * np.asarray(obstacle.half_extents)
    a = np.asarray(obstacle.axis)
    v1, v2 = image_basis(a)
    angle = np.linspace(0.0, 2.0 * math.pi, RIM_SAMPLES, endpoint=False)
    ring = obstacle.radius * (np.cos(angle)[:, None] * v1 + np.sin(angle)[:, None] * v2)
    half = obstacle.length / 2.0
    return np.vstack([c + half * a + ring, c - half * a + ring])


def outline(obstacle, forward):
    """(e1, e2, hull vertices (V, 2) counter-clockwise, hull equations) of the uninflated outline; for a
    sphere the closed-form circle: (e1, e2, centre (2,), radius)."""
    e1, e2 = image_basis(forward)
    if obstacle.kind == "sphere":
        c = np.asarray(obstacle.centre)
        return e1, e2, np.array([c @ e1, c @ e2]), obstacle.radius
    pts = projected_points(obstacle, forward)
    flat = np.column_stack([pts @ e1, pts @ e2])
    hull = ConvexHull(flat)
    return e1, e2, flat[hull.vertices], hull.equations


def silhouette(obstacle, start, forward, body_radius: float):
    """(delta, o): distance from the ray's image point to the inflated outline (positive inside) and the
    outline's outward unit normal at its nearest point, as a 3-D vector perpendicular to ``forward``
    (None when the ray passes through a sphere's centre: every direction is nearest)."""
    e1, e2, shape, extra = outline(obstacle, forward)
    point = np.array([np.asarray(start) @ e1, np.asarray(start) @ e2])
    if obstacle.kind == "sphere":
        offset = point - shape
        dist = np.linalg.norm(offset)
        if dist == 0.0:
            return extra + body_radius, None
        o2 = offset / dist
        return extra + body_radius - dist, o2[0] * e1 + o2[1] * e2
    normals, offsets = extra[:, :2], extra[:, 2]
    signed = normals @ point + offsets
    if signed.max() <= 0.0:
        facet = int(np.argmax(signed))
        o2 = normals[facet] / np.linalg.norm(normals[facet])
        return -signed[facet] / np.linalg.norm(normals[facet]) + body_radius, o2[0] * e1 + o2[1] * e2
    starts, edges = shape, np.roll(shape, -1, axis=0) - shape
    lam = np.clip(np.einsum("ij,ij->i", point - starts, edges) / np.einsum("ij,ij->i", edges, edges), 0.0, 1.0)
    nearest = starts + lam[:, None] * edges
    dist = np.linalg.norm(point - nearest, axis=1)
    i = int(np.argmin(dist))
    o2 = (point - nearest[i]) / dist[i]
    return body_radius - dist[i], o2[0] * e1 + o2[1] * e2


def support_gap(obstacle, start, forward, body_radius: float, direction) -> float:
    """Support of the inflated outline along the image direction minus direction . P' (>= delta,
    equal to it exactly for the outline's outward normal at the point nearest to P')."""
    o = np.asarray(direction, dtype=float)
    if obstacle.kind == "sphere":
        reach = np.asarray(obstacle.centre) @ o + obstacle.radius
    else:
        reach = (projected_points(obstacle, forward) @ o).max()
    return reach + body_radius - np.asarray(start) @ o


def along_plane(normal, forward, up) -> np.ndarray:
    """Forward with its normal component removed, normalised (up likewise when forward is the normal)."""
    n = np.asarray(normal)
    for v in (np.asarray(forward, dtype=float), np.asarray(up, dtype=float)):
        d = v - (v @ n) * n
        if np.linalg.norm(d) > 1e-9:
            return d / np.linalg.norm(d)
    raise ValueError("up and forward both along the normal")


def first_hits(obstacles, starts, directions, body_radius: float, lookahead: float):
    """(k, t, closeness) per ray: nearest hit over the obstacles (lower index on ties; k = -1, t = inf
    when none) and the smallest |min gap| over the obstacles (how close any of them is to a tangent)."""
    starts = np.atleast_2d(np.asarray(starts, dtype=float))
    directions = np.atleast_2d(np.asarray(directions, dtype=float))
    best_k = np.full(len(starts), -1)
    best_t = np.full(len(starts), np.inf)
    closeness = np.full(len(starts), np.inf)
    for k, obstacle in enumerate(obstacles):
        hit, t, min_gap = ray_cast(obstacle, starts, directions, body_radius, lookahead)
        better = hit & (t < best_t)
        best_k[better] = k
        best_t[better] = t[better]
        closeness = np.minimum(closeness, np.abs(min_gap))
    return best_k, best_t, closeness


def deepest_overlap(obstacles, point, body_radius: float):
    """(k, sd): the obstacle with the smallest sd <= body_radius, or (-1, inf)."""
    best = (-1, math.inf)
    for k, obstacle in enumerate(obstacles):
        sd = float(signed_distance(obstacle, [point])[0])
        if sd <= body_radius and sd < best[1]:
            best = (k, sd)
    return best


def fan_coefficients(rays: int) -> np.ndarray:
    """(rays, 3) (forward, up, side) coefficients of the golden-spiral hemisphere fan."""
    golden_ratio = (1.0 + math.sqrt(5.0)) / 2.0
    rows = []
    for i in range(rays):
        z = 1.0 - i / rays
        azimuth = i * 2.0 * math.pi / golden_ratio ** 2
        r = math.sqrt(max(0.0, 1.0 - z * z))
        rows.append((z, r * math.cos(azimuth), r * math.sin(azimuth)))
    return np.array(rows)


def fan_choice(obstacles, start, frame, fan, body_radius: float, lookahead: float):
    """(ray, direction, closeness) by brute force: ray -2 when the body touches an obstacle, -1 when the
    forward ray is free (direction None), else the first free fan ray or, when all are blocked, the one
    with the farthest first hit (first on ties). closeness: how near any cast came to a tangent."""
    f, u, s = (np.asarray(v, dtype=float) for v in frame)
    if deepest_overlap(obstacles, start, body_radius)[0] >= 0:
        return -2, None, math.inf
    directions = fan[:, :1] * f + fan[:, 1:2] * u + fan[:, 2:] * s
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    directions[0] = f
    k, t, closeness = first_hits(obstacles, np.tile(start, (len(fan), 1)), directions, body_radius, lookahead)
    if k[0] < 0:
        return -1, None, closeness.min()
    free = np.flatnonzero(k < 0)
    ray = int(free[0]) if len(free) else int(np.argmax(t))
    return ray, directions[ray], closeness.min()
