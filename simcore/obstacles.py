"""Compiled obstacle geometry: signed clearance, nearest surface point and ray casts for the four kinds.

Obstacles arrive packed by :func:`simcore.obstacle_spec.pack_obstacles` as ``table`` float64 (K, C) and
``kinds`` int64 (K,). Every function is ``numba.njit`` (cached, no fastmath), takes scalars and those two
arrays, returns a tuple of scalars and allocates nothing, except :func:`clearances` (for metrics). The
per-kind distances and the per-ray dispatch are inlined into their callers (``inline="always"``: about 40%
less time per ray cast than plain calls, measured).

Signed clearance
    ``signed_distance`` gives sd(x), the Euclidean distance from x to the solid's surface, negative
    inside, with the nearest surface point q = x - sd n and the outward unit normal n (the gradient of
    sd). Inside a box or cylinder the nearest face wins (ties: box axes in the order x, y, z; a cylinder
    prefers its side to its cap). Where the outward direction is not unique (the centre of a sphere, a
    point on a cylinder's axis) n is the unit vector perpendicular to the axis nearest to world +y
    (world +y itself for a sphere; world +x when the axis is along y).

Body-inflated shape
    A boid is a ball of radius b. Its centre collides with the inflated solid {x : sd(x) <= b}, the exact
    Minkowski sum of the solid and the ball: a sphere of radius R + b, the plane shifted by b, a box with
    rounded edges (quarter cylinders of radius b) and corners (ball octants), a cylinder with rounded
    rims (a torus quarter of tube radius b). No shape is approximated.

Ray cast
    ``ray_cast`` returns the first point of the segment p + t f, 0 <= t <= lookahead (f unit), that lies in
    the closed inflated shape: ``(hit, t, hit point, outward normal there)``. Consequences, all tested:
    a start inside or touching (sd(p) <= b) is a hit at t = 0 with the normal at p; a tangent ray
    touches, so it hits; a hit at exactly t = lookahead counts; lookahead 0 hits only from inside; a ray
    parallel to a plane (or to a cylinder's axis outside its inflated side) never hits from outside; a
    miss returns t = +inf and zeros. Sphere and plane are closed forms. Box and cylinder use that the
    distance to a convex solid along a line, g(t) = sd(p + t f), is convex and continuously
    differentiable outside it: Newton's method on g(t) = b from the entry into the solid's bounding ball
    never steps past the first root (each tangent lies below g), stops with a miss as soon as g stops
    decreasing or the next iterate is beyond lookahead, and stops with a hit when g(t) - b <=
    CONTACT_TOLERANCE (1e-12 world units). The reported t therefore lies between the first contact of
    the ball of radius b + 1e-12 and that of radius b: exact to rounding for a transversal hit; for an
    exactly tangent ray it is located to about sqrt(1e-12 * b).

Over all obstacles
    ``first_hit`` keeps the smallest t (ties: lower index); ``nearest_hit`` is its (k, t) alone and can skip
    the inside tests once the caller knows the body touches nothing. ``deepest_overlap`` finds the
    obstacle the body overlaps most (sd(p) <= b, most negative sd, lower index on ties);
    ``nearest_clearance`` the smallest sd. The scans first drop, exactly, every obstacle whose bounding
    ball (``OBS_BOUND``; never a plane) is out of reach.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from .obstacle_spec import (KIND_BOX, KIND_PLANE, KIND_SPHERE, OBS_AX, OBS_AY, OBS_AZ, OBS_BOUND,
                            OBS_CX, OBS_CY, OBS_CZ, OBS_HALF_LENGTH, OBS_HX, OBS_HY, OBS_HZ, OBS_NX, OBS_NY,
                            OBS_NZ, OBS_RADIUS)

CONTACT_TOLERANCE = 1e-12
MAX_NEWTON_STEPS = 64
DEGENERATE = 1e-12


@nb.njit(cache=True, error_model="numpy")
def perpendicular_near_up(ax, ay, az):
    """Unit vector perpendicular to the unit vector a, nearest to world +y (world +x if a is along y)."""
    px, py, pz = -ay * ax, 1.0 - ay * ay, -ay * az
    norm = math.sqrt(px * px + py * py + pz * pz)
    if norm <= DEGENERATE:
        px, py, pz = 1.0 - ax * ax, -ax * ay, -ax * az
        norm = math.sqrt(px * px + py * py + pz * pz)
    return px / norm, py / norm, pz / norm


@nb.njit(cache=True, error_model="numpy", inline="always")
def sphere_distance(cx, cy, cz, radius, x, y, z):
    """(sd, nx, ny, nz) of a point to a ball's surface."""
    ox, oy, oz = x - cx, y - cy, z - cz
    dist = math.sqrt(ox * ox + oy * oy + oz * oz)
    if dist > 0.0:
        return dist - radius, ox / dist, oy / dist, oz / dist
    return -radius, 0.0, 1.0, 0.0


@nb.njit(cache=True, error_model="numpy", inline="always")
def plane_distance(cx, cy, cz, nx, ny, nz, x, y, z):
    """(sd, nx, ny, nz) of a point to the half-space n . (x - c) <= 0 (n unit, pointing to the free side)."""
    return nx * (x - cx) + ny * (y - cy) + nz * (z - cz), nx, ny, nz


@nb.njit(cache=True, error_model="numpy", inline="always")
def box_distance(cx, cy, cz, hx, hy, hz, x, y, z):
    """(sd, nx, ny, nz) of a point to an axis-aligned box's surface (inside: nearest face, ties x, y, z)."""
    ox, oy, oz = x - cx, y - cy, z - cz
    dx = ox - min(max(ox, -hx), hx)
    dy = oy - min(max(oy, -hy), hy)
    dz = oz - min(max(oz, -hz), hz)
    if dx != 0.0 or dy != 0.0 or dz != 0.0:
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        return dist, dx / dist, dy / dist, dz / dist
    depth_x, depth_y, depth_z = hx - abs(ox), hy - abs(oy), hz - abs(oz)
    if depth_x <= depth_y and depth_x <= depth_z:
        return 0.0 - depth_x, 1.0 if ox >= 0.0 else -1.0, 0.0, 0.0
    if depth_y <= depth_z:
        return 0.0 - depth_y, 0.0, 1.0 if oy >= 0.0 else -1.0, 0.0
    return 0.0 - depth_z, 0.0, 0.0, 1.0 if oz >= 0.0 else -1.0


@nb.njit(cache=True, error_model="numpy", inline="always")
def cylinder_distance(cx, cy, cz, ax, ay, az, radius, half_length, x, y, z):
    """(sd, nx, ny, nz) of a point to a capped cylinder's surface (axis a unit; side, cap or rim region)."""
    ox, oy, oz = x - cx, y - cy, z - cz
    along = ox * ax + oy * ay + oz * az
    rx, ry, rz = ox - along * ax, oy - along * ay, oz - along * az
    rho = math.sqrt(rx * rx + ry * ry + rz * rz)
    if rho > DEGENERATE:
        ux, uy, uz = rx / rho, ry / rho, rz / rho
    else:
        ux, uy, uz = perpendicular_near_up(ax, ay, az)
    side = 1.0 if along >= 0.0 else -1.0
    d_side = rho - radius
    d_cap = abs(along) - half_length
    if d_side > 0.0 and d_cap > 0.0:
        dist = math.sqrt(d_side * d_side + d_cap * d_cap)
        return (dist, (d_side * ux + d_cap * side * ax) / dist, (d_side * uy + d_cap * side * ay) / dist,
                (d_side * uz + d_cap * side * az) / dist)
    if d_side > 0.0 or (d_cap <= 0.0 and d_side >= d_cap):
        return d_side, ux, uy, uz
    return d_cap, side * ax, side * ay, side * az


@nb.njit(cache=True, error_model="numpy", inline="always")
def distance_normal(table, kinds, k, x, y, z):
    """(sd, nx, ny, nz) of point x to obstacle k."""
    kind = kinds[k]
    cx, cy, cz = table[k, OBS_CX], table[k, OBS_CY], table[k, OBS_CZ]
    if kind == KIND_SPHERE:
        return sphere_distance(cx, cy, cz, table[k, OBS_RADIUS], x, y, z)
    if kind == KIND_PLANE:
        return plane_distance(cx, cy, cz, table[k, OBS_NX], table[k, OBS_NY], table[k, OBS_NZ], x, y, z)
    if kind == KIND_BOX:
        return box_distance(cx, cy, cz, table[k, OBS_HX], table[k, OBS_HY], table[k, OBS_HZ], x, y, z)
    return cylinder_distance(cx, cy, cz, table[k, OBS_AX], table[k, OBS_AY], table[k, OBS_AZ], table[k, OBS_RADIUS],
                             table[k, OBS_HALF_LENGTH], x, y, z)


@nb.njit(cache=True, error_model="numpy")
def signed_distance(table, kinds, k, x, y, z):
    """(sd, qx, qy, qz, nx, ny, nz): signed clearance of x to obstacle k, nearest surface point, normal."""
    sd, nx, ny, nz = distance_normal(table, kinds, k, x, y, z)
    return sd, x - sd * nx, y - sd * ny, z - sd * nz, nx, ny, nz


@nb.njit(cache=True, error_model="numpy", inline="always")
def beyond_reach(table, k, x, y, z, reach):
    """True when obstacle k's bounding ball is farther than ``reach`` from x (never for a plane): a
    cheap exact cull, nothing of the obstacle can be within ``reach``."""
    dx, dy, dz = x - table[k, OBS_CX], y - table[k, OBS_CY], z - table[k, OBS_CZ]
    limit = table[k, OBS_BOUND] + reach
    return dx * dx + dy * dy + dz * dz > limit * limit


@nb.njit(cache=True, error_model="numpy", inline="always")
def ball_entry(ox, oy, oz, radius, fx, fy, fz, lookahead):
    """(hit, t): first t in [0, lookahead] with |o + t f| <= radius, for a start outside the ball."""
    beta = ox * fx + oy * fy + oz * fz
    if beta >= 0.0:
        return False, math.inf
    excess = ox * ox + oy * oy + oz * oz - radius * radius
    disc = beta * beta - excess
    if disc < 0.0:
        return False, math.inf
    t = max(excess / (math.sqrt(disc) - beta), 0.0)
    if t > lookahead:
        return False, math.inf
    return True, t


@nb.njit(cache=True, error_model="numpy")
def convex_entry(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, lookahead):
    """(hit, t) for a box or cylinder and a start outside the inflated shape (see module docstring)."""
    ox, oy, oz = px - table[k, OBS_CX], py - table[k, OBS_CY], pz - table[k, OBS_CZ]
    bound = table[k, OBS_BOUND] + body_radius
    t = 0.0
    if ox * ox + oy * oy + oz * oz > bound * bound:
        hit, t = ball_entry(ox, oy, oz, bound, fx, fy, fz, lookahead)
        if not hit:
            return False, math.inf
    for _ in range(MAX_NEWTON_STEPS):
        dist, nx, ny, nz = distance_normal(table, kinds, k, px + t * fx, py + t * fy, pz + t * fz)
        gap = dist - body_radius
        if gap <= CONTACT_TOLERANCE:
            return True, t
        slope = nx * fx + ny * fy + nz * fz
        if slope >= 0.0:
            return False, math.inf
        t_next = t - gap / slope
        if t_next > lookahead:
            return False, math.inf
        if t_next <= t:
            return True, t
        t = t_next
    return False, math.inf


@nb.njit(cache=True, error_model="numpy", inline="always")
def ray_entry(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, lookahead):
    """(hit, t) of the ray cast against obstacle k's inflated shape, for a start known to be outside it
    (sd(p) > body_radius)."""
    kind = kinds[k]
    if kind == KIND_SPHERE:
        return ball_entry(px - table[k, OBS_CX], py - table[k, OBS_CY], pz - table[k, OBS_CZ],
                          table[k, OBS_RADIUS] + body_radius, fx, fy, fz, lookahead)
    if kind == KIND_PLANE:
        nx, ny, nz = table[k, OBS_NX], table[k, OBS_NY], table[k, OBS_NZ]
        rate = nx * fx + ny * fy + nz * fz
        if rate >= 0.0:
            return False, math.inf
        gap = nx * (px - table[k, OBS_CX]) + ny * (py - table[k, OBS_CY]) + nz * (pz - table[k, OBS_CZ]) - body_radius
        t = gap / -rate
        if t > lookahead:
            return False, math.inf
        return True, t
    return convex_entry(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, lookahead)


@nb.njit(cache=True, error_model="numpy", inline="always")
def ray_distance(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, lookahead):
    """(hit, t) of the ray cast against obstacle k's inflated shape (see module docstring)."""
    if distance_normal(table, kinds, k, px, py, pz)[0] <= body_radius:
        return True, 0.0
    return ray_entry(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, lookahead)


@nb.njit(cache=True, error_model="numpy")
def ray_cast(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, lookahead):
    """(hit, t, hx, hy, hz, nx, ny, nz): first contact of a ball of radius ``body_radius`` moving from p
    along unit f, within ``lookahead``, with obstacle k; the hit point (the ball's centre) and the
    outward normal there. A miss is (False, inf, 0, 0, 0, 0, 0, 0)."""
    hit, t = ray_distance(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, lookahead)
    if not hit:
        return False, math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    hx, hy, hz = px + t * fx, py + t * fy, pz + t * fz
    sd, nx, ny, nz = distance_normal(table, kinds, k, hx, hy, hz)
    return True, t, hx, hy, hz, nx, ny, nz


@nb.njit(cache=True, error_model="numpy")
def first_hit(table, kinds, px, py, pz, fx, fy, fz, body_radius, lookahead):
    """(k, t, hx, hy, hz, nx, ny, nz): the nearest hit over all obstacles (ties: lower k); k = -1 and
    t = inf when the ray meets none within lookahead."""
    best_k, best_t = nearest_hit(table, kinds, px, py, pz, fx, fy, fz, body_radius, lookahead, False)
    if best_k < 0:
        return -1, math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    hx, hy, hz = px + best_t * fx, py + best_t * fy, pz + best_t * fz
    sd, nx, ny, nz = distance_normal(table, kinds, best_k, hx, hy, hz)
    return best_k, best_t, hx, hy, hz, nx, ny, nz


@nb.njit(cache=True, error_model="numpy")
def nearest_hit(table, kinds, px, py, pz, fx, fy, fz, body_radius, lookahead, start_outside):
    """(k, t) of ``first_hit`` without the hit point; with ``start_outside`` the caller vouches that the
    body touches no obstacle at p (as after ``deepest_overlap`` found none), which skips K clearances."""
    best_k = -1
    best_t = math.inf
    reach = lookahead
    for k in range(kinds.shape[0]):
        if beyond_reach(table, k, px, py, pz, body_radius + reach):
            continue
        if start_outside:
            hit, t = ray_entry(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, reach)
        else:
            hit, t = ray_distance(table, kinds, k, px, py, pz, fx, fy, fz, body_radius, reach)
        if hit and t < best_t:
            best_k, best_t, reach = k, t, t
    return best_k, best_t


@nb.njit(cache=True, error_model="numpy")
def deepest_overlap(table, kinds, x, y, z, body_radius):
    """(k, sd, nx, ny, nz): the obstacle a body of radius ``body_radius`` at x touches or overlaps most
    (sd <= body_radius, smallest sd, lower k on ties) with its outward normal; k = -1 when none."""
    best_k = -1
    best_sd = math.inf
    bx = by = bz = 0.0
    for k in range(kinds.shape[0]):
        if beyond_reach(table, k, x, y, z, body_radius):
            continue
        sd, nx, ny, nz = distance_normal(table, kinds, k, x, y, z)
        if sd <= body_radius and sd < best_sd:
            best_k, best_sd, bx, by, bz = k, sd, nx, ny, nz
    return best_k, best_sd, bx, by, bz


@nb.njit(cache=True, error_model="numpy")
def nearest_clearance(table, kinds, x, y, z):
    """(k, sd): the smallest signed clearance of x over all obstacles (lower k on ties); (-1, inf) if none."""
    best_k = -1
    best_sd = math.inf
    for k in range(kinds.shape[0]):
        sd, nx, ny, nz = distance_normal(table, kinds, k, x, y, z)
        if sd < best_sd:
            best_k, best_sd = k, sd
    return best_k, best_sd


@nb.njit(cache=True, error_model="numpy")
def clearances(table, kinds, points):
    """float64 (M, K): signed clearance of every point (M, 3) to every obstacle (for metrics)."""
    out = np.empty((points.shape[0], kinds.shape[0]), dtype=np.float64)
    for m in range(points.shape[0]):
        for k in range(kinds.shape[0]):
            out[m, k] = distance_normal(table, kinds, k, points[m, 0], points[m, 1], points[m, 2])[0]
    return out
