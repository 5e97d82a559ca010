"""Silhouettes of body-inflated obstacles seen along a ray: the geometry of Reynolds' steer-to-avoid.

``silhouette_target(table, kinds, k, p, f, u, b, margin)`` looks at obstacle k (packed as in
:mod:`simcore.obstacle_spec`) from a boid at p with unit forward f, up u and body radius b. Seen along the
ray (orthographic projection on the plane perpendicular to f) the inflated obstacle, {x : sd(x) <= b}, has
a convex outline; P' is where the ray pierces that plane. It returns ``(tx, ty, tz, ox, oy, oz, delta)``:

* delta: the distance from P' to the outline (positive when P' is inside it, as after a hit);
* o: the outline's outward unit normal at the outline point nearest to P' (perpendicular to f);
* T = S + margin o: S is the point of the inflated surface that projects onto that outline point (the
  support point of the inflated solid along o; where several do, as on a face or cap seen edge-on, the
  one nearest the boid along f), and the target lies ``margin`` beyond it.

So T projects to P' + (delta + margin) o, and by convexity the line through T parallel to f passes the
inflated obstacle with at least ``margin`` to spare. Per kind:

* sphere: the outline is the circle of radius R + b about the centre's projection; o is the normalised
  offset of the ray from the centre, so the silhouette edge lies in the plane of f and that offset, and
  T = c + (R + b + margin) o;
* box: the outline is the projected box (a rectangle or hexagon) grown by b. Its edges are the images
  of the silhouette edges, those whose two faces are one front-facing (f . n < 0) and one not; the
  nearest point of those segments to P' gives o (the edge's outward normal when P' is inside the
  projected box, the direction from the nearest point to P' in the rounded rim) and S = edge point + b o;
* cylinder (axis a, radius R, half length H): the outline is the projected axis segment (half length
  H sin(theta), theta the angle between a and f) plus the projected cap ellipse (half axes R |cos theta|
  and R), grown by b. delta is the minimum over image directions o of (support of the inflated cylinder
  along o) - o . P': exact for the two side lines; on each cap half the function is scanned at its ends
  and CAP_SCAN angles between, and every scan point no higher than its neighbours is refined by
  bisection on the derivative (to rounding). When a is within VIEW_DEGENERATE (1e-7, in sine or cosine)
  of f the outline is taken as the circle of radius R (S on the rim of the cap facing the boid); when
  within 1e-7 of perpendicular, as the rectangle of half sides H and R; either changes the outline by at
  most 1e-7 times the cylinder's size;
* plane: an unbounded plane has no silhouette; the request is to fly along it: the target is p + d with
  d = f without its normal part, normalised, o = d and delta = inf.

Ties: a ray through a sphere's centre (or a cylinder seen end-on through its axis) and f along a plane's
normal take the boid's up vector made perpendicular; equally near box edges or cylinder candidates go to
the first in a fixed order (box edges by axis x, y, z then signs; cylinder side +e2, side -e2, cap halves).
Compiled with numba (cached, no fastmath); no allocation.
"""
from __future__ import annotations

import math

import numba as nb

from .obstacle_spec import (KIND_BOX, KIND_PLANE, KIND_SPHERE, OBS_AX, OBS_AY, OBS_AZ, OBS_CX, OBS_CY, OBS_CZ,
                            OBS_HALF_LENGTH, OBS_HX, OBS_HY, OBS_HZ, OBS_NX, OBS_NY, OBS_NZ, OBS_RADIUS)
from .obstacles import DEGENERATE, perpendicular_near_up

CAP_SCAN = 32           # interior scan angles per cap half in the cylinder outline search
VIEW_DEGENERATE = 1e-7  # a cylinder axis this close (sine or cosine) to along or across f is taken as such


@nb.njit(cache=True, error_model="numpy")
def across_from_up(fx, fy, fz, ux, uy, uz):
    """The boid's up vector made perpendicular to f and unit (any perpendicular if up is along f)."""
    along = ux * fx + uy * fy + uz * fz
    px, py, pz = ux - along * fx, uy - along * fy, uz - along * fz
    norm = math.sqrt(px * px + py * py + pz * pz)
    if norm > DEGENERATE:
        return px / norm, py / norm, pz / norm
    return perpendicular_near_up(fx, fy, fz)


@nb.njit(cache=True, error_model="numpy")
def perpendicular_part(vx, vy, vz, fx, fy, fz):
    """v with its component along the unit vector f removed."""
    along = vx * fx + vy * fy + vz * fz
    return vx - along * fx, vy - along * fy, vz - along * fz


@nb.njit(cache=True, error_model="numpy")
def sphere_silhouette(cx, cy, cz, radius, px, py, pz, fx, fy, fz, ux, uy, uz, body_radius, margin):
    """(tx, ty, tz, ox, oy, oz, delta): target, outward image normal and ray-to-outline distance."""
    grown = radius + body_radius
    wx, wy, wz = perpendicular_part(px - cx, py - cy, pz - cz, fx, fy, fz)
    offset = math.sqrt(wx * wx + wy * wy + wz * wz)
    if offset > DEGENERATE * grown:
        ox, oy, oz = wx / offset, wy / offset, wz / offset
    else:
        ox, oy, oz = across_from_up(fx, fy, fz, ux, uy, uz)
    reach = grown + margin
    return cx + reach * ox, cy + reach * oy, cz + reach * oz, ox, oy, oz, grown - offset


@nb.njit(cache=True, error_model="numpy")
def placed(k, along_k, along_i, along_j):
    """(x, y, z) from components along axis k, i = k+1 and j = k+2 (mod 3)."""
    if k == 0:
        return along_k, along_i, along_j
    if k == 1:
        return along_j, along_k, along_i
    return along_i, along_j, along_k


@nb.njit(cache=True, error_model="numpy")
def box_edge(axis, s_i, s_j, centre, half, px, py, pz, fx, fy, fz):
    """One box edge along ``axis`` at signs (s_i, s_j) of the other axes, seen along f: (outward, dist,
    qx, qy, qz, vx, vy, vz, mx, my, mz) with m the edge line's outward image normal, outward = (p - edge) . m
    (> 0: P' is outside that line), q the edge point nearest to P' in the image and v = P' - q'."""
    fwd = (fx, fy, fz)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    f_i, f_j = fwd[i], fwd[j]
    across = f_i * f_i + f_j * f_j
    ax, ay, az = placed(axis, centre[axis] - half[axis], centre[i] + s_i * half[i], centre[j] + s_j * half[j])
    scale = 1.0 / math.sqrt(across)   # m = +-(f x e_axis) / |f x e_axis|, pointing away from the centre
    if s_i * half[i] * f_j - s_j * half[j] * f_i < 0.0:
        scale = -scale
    mx, my, mz = placed(axis, 0.0, f_j * scale, -f_i * scale)
    dx, dy, dz = px - ax, py - ay, pz - az
    lam = ((dx, dy, dz)[axis] - fwd[axis] * (dx * fx + dy * fy + dz * fz)) / across
    qx, qy, qz = placed(axis, min(max(lam, 0.0), 2.0 * half[axis]), 0.0, 0.0)
    qx, qy, qz = ax + qx, ay + qy, az + qz
    vx, vy, vz = perpendicular_part(px - qx, py - qy, pz - qz, fx, fy, fz)
    return (dx * mx + dy * my + dz * mz, math.sqrt(vx * vx + vy * vy + vz * vz),
            qx, qy, qz, vx, vy, vz, mx, my, mz)


@nb.njit(cache=True, error_model="numpy")
def box_silhouette(table, k, px, py, pz, fx, fy, fz, body_radius, margin):
    """(tx, ty, tz, ox, oy, oz, delta) for an axis-aligned box (see module docstring)."""
    centre = (table[k, OBS_CX], table[k, OBS_CY], table[k, OBS_CZ])
    half = (table[k, OBS_HX], table[k, OBS_HY], table[k, OBS_HZ])
    fwd = (fx, fy, fz)
    inside = True
    best = math.inf
    ex = ey = ez = wx = wy = wz = nx = ny = nz = 0.0
    for axis in range(3):
        f_i, f_j = fwd[(axis + 1) % 3], fwd[(axis + 2) % 3]
        for s_i in (-1.0, 1.0):
            for s_j in (-1.0, 1.0):
                if (s_i * f_i < 0.0) == (s_j * f_j < 0.0):
                    continue  # not a silhouette edge: both faces front-facing or neither
                out, dist, qx, qy, qz, vx, vy, vz, mx, my, mz = box_edge(axis, s_i, s_j, centre, half, px, py,
                                                                         pz, fx, fy, fz)
                inside = inside and out <= 0.0
                if dist < best:
                    best, ex, ey, ez, wx, wy, wz, nx, ny, nz = dist, qx, qy, qz, vx, vy, vz, mx, my, mz
    if inside or best == 0.0:
        ox, oy, oz, delta = nx, ny, nz, best + body_radius
    else:
        ox, oy, oz, delta = wx / best, wy / best, wz / best, body_radius - best
    reach = body_radius + margin
    return ex + reach * ox, ey + reach * oy, ez + reach * oz, ox, oy, oz, delta


@nb.njit(cache=True, error_model="numpy")
def cap_gap(phi, side, u1, u2, half_proj, ca2, radius, body_radius):
    """Support of the inflated cylinder's outline along image angle phi on cap half ``side`` minus o . P'."""
    c, s = math.cos(phi), math.sin(phi)
    return side * half_proj * c + radius * math.sqrt(ca2 * c * c + s * s) + body_radius - u1 * c - u2 * s


@nb.njit(cache=True, error_model="numpy")
def cap_gap_slope(phi, side, u1, u2, half_proj, ca2, sa2, radius):
    """d cap_gap / d phi."""
    c, s = math.cos(phi), math.sin(phi)
    return -side * half_proj * s + radius * sa2 * s * c / math.sqrt(ca2 * c * c + s * s) + u1 * s - u2 * c


@nb.njit(cache=True, error_model="numpy")
def refine_cap_minimum(lo, hi, side, u1, u2, half_proj, ca2, sa2, radius):
    """(found, phi): the angle in [lo, hi] where cap_gap_slope changes sign from - to +, by bisection to
    rounding; found is False when the slope at the ends does not bracket a minimum."""
    if not (cap_gap_slope(lo, side, u1, u2, half_proj, ca2, sa2, radius) < 0.0
            and cap_gap_slope(hi, side, u1, u2, half_proj, ca2, sa2, radius) > 0.0):
        return False, lo
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if cap_gap_slope(mid, side, u1, u2, half_proj, ca2, sa2, radius) < 0.0:
            lo = mid
        else:
            hi = mid
    return True, 0.5 * (lo + hi)


@nb.njit(cache=True, error_model="numpy")
def cylinder_outline_minimum(u1, u2, radius, half_proj, ca2, sa2, body_radius):
    """(delta, kind, phi) for the general cylinder view: kind +1/-1 side line along +-e2, 2 cap half with
    cos(phi) > 0, -2 cap half with cos(phi) < 0; phi the image angle from e1 toward e2.

    Each cap half [start, start + pi] is scanned at its two ends and CAP_SCAN angles between; every scan
    point no higher than its neighbours is refined by bisection on the slope between those neighbours.
    An end of a half that is not refined into the half is left to the side-line candidate it equals."""
    best, kind, best_phi = radius + body_radius - u2, 1, 0.5 * math.pi
    if radius + body_radius + u2 < best:
        best, kind, best_phi = radius + body_radius + u2, -1, -0.5 * math.pi
    step = math.pi / (CAP_SCAN + 1)
    last = CAP_SCAN + 1
    for side in (1.0, -1.0):
        start = -0.5 * math.pi if side > 0.0 else 0.5 * math.pi
        prev_phi = prev = math.inf
        cur_phi = start
        cur = cap_gap(cur_phi, side, u1, u2, half_proj, ca2, radius, body_radius)
        for j in range(last + 1):
            if j < last:
                next_phi = start + (j + 1) * step if j + 1 < last else start + math.pi
                nxt = cap_gap(next_phi, side, u1, u2, half_proj, ca2, radius, body_radius)
            else:
                next_phi, nxt = math.inf, math.inf
            if cur <= prev and cur <= nxt:
                lo = prev_phi if j > 0 else cur_phi
                hi = next_phi if j < last else cur_phi
                found, phi = refine_cap_minimum(lo, hi, side, u1, u2, half_proj, ca2, sa2, radius)
                if not found:
                    phi = cur_phi
                # the two ends of a half are the side lines, already candidates (lifted to the side)
                if found or 0 < j < last:
                    value = cap_gap(phi, side, u1, u2, half_proj, ca2, radius, body_radius)
                    if value < best:
                        best, kind, best_phi = value, 2 if side > 0.0 else -2, phi
            prev_phi, prev, cur_phi, cur = cur_phi, cur, next_phi, nxt
    return best, kind, best_phi


@nb.njit(cache=True, error_model="numpy")
def end_on_outline(cx, cy, cz, ax, ay, az, radius, half, ca, wx, wy, wz, fx, fy, fz, ux, uy, uz, body_radius):
    """(ex, ey, ez, ox, oy, oz, delta), axis along f: a circle; S on the rim of the cap facing the boid."""
    offset = math.sqrt(wx * wx + wy * wy + wz * wz)
    if offset > DEGENERATE * radius:
        ox, oy, oz = wx / offset, wy / offset, wz / offset
    else:
        ox, oy, oz = across_from_up(fx, fy, fz, ux, uy, uz)
    near = -half if ca > 0.0 else half
    return (cx + near * ax + radius * ox, cy + near * ay + radius * oy, cz + near * az + radius * oz,
            ox, oy, oz, radius + body_radius - offset)


@nb.njit(cache=True, error_model="numpy")
def side_on_outline(cx, cy, cz, ax, ay, az, radius, half, sa, e1x, e1y, e1z, e2x, e2y, e2z, fx, fy, fz,
                    u1, u2, body_radius):
    """(ex, ey, ez, ox, oy, oz, delta), axis across f: the rectangle [-H, H] x [-R, R] (in e1, e2) grown by
    b; S is the front-most point of the cross-section chord at the nearest outline point (q1, q2)."""
    if abs(u1) <= half and abs(u2) <= radius:
        sign1 = 1.0 if u1 >= 0.0 else -1.0
        sign2 = 1.0 if u2 >= 0.0 else -1.0
        if radius - abs(u2) <= half - abs(u1):
            q1, q2, o1, o2, delta = u1, sign2 * radius, 0.0, sign2, radius - abs(u2) + body_radius
        else:
            q1, q2, o1, o2, delta = sign1 * half, u2, sign1, 0.0, half - abs(u1) + body_radius
    else:
        q1, q2 = min(max(u1, -half), half), min(max(u2, -radius), radius)
        dist = math.sqrt((u1 - q1) ** 2 + (u2 - q2) ** 2)
        o1, o2, delta = (u1 - q1) / dist, (u2 - q2) / dist, body_radius - dist
    along = min(max(q1 / sa, -half), half)
    chord = -math.sqrt(max(radius * radius - q2 * q2, 0.0))
    return (cx + along * ax + q2 * e2x + chord * fx, cy + along * ay + q2 * e2y + chord * fy,
            cz + along * az + q2 * e2z + chord * fz,
            o1 * e1x + o2 * e2x, o1 * e1y + o2 * e2y, o1 * e1z + o2 * e2z, delta)


@nb.njit(cache=True, error_model="numpy")
def oblique_outline(cx, cy, cz, ax, ay, az, radius, half, ca, sa, e1x, e1y, e1z, e2x, e2y, e2z, fx, fy, fz,
                    u1, u2, body_radius):
    """(ex, ey, ez, ox, oy, oz, delta) in general position: S on a side line, or the rim point of the cap
    whose support direction is o (o - (a . o) a, written in the e1, e2, f basis to stay accurate)."""
    ca2 = ca * ca
    delta, kind, phi = cylinder_outline_minimum(u1, u2, radius, half * sa, ca2, sa * sa, body_radius)
    if kind == 1 or kind == -1:
        sign = float(kind)
        along = min(max(u1 / sa, -half), half)
        ox, oy, oz = sign * e2x, sign * e2y, sign * e2z
        return (cx + along * ax + radius * ox, cy + along * ay + radius * oy, cz + along * az + radius * oz,
                ox, oy, oz, delta)
    side = 1.0 if kind > 0 else -1.0
    c, s = math.cos(phi), math.sin(phi)
    scale = radius / math.sqrt(ca2 * c * c + s * s)
    return (cx + side * half * ax + scale * (ca2 * c * e1x + s * e2x - sa * ca * c * fx),
            cy + side * half * ay + scale * (ca2 * c * e1y + s * e2y - sa * ca * c * fy),
            cz + side * half * az + scale * (ca2 * c * e1z + s * e2z - sa * ca * c * fz),
            c * e1x + s * e2x, c * e1y + s * e2y, c * e1z + s * e2z, delta)


@nb.njit(cache=True, error_model="numpy")
def cylinder_silhouette(table, k, px, py, pz, fx, fy, fz, ux, uy, uz, body_radius, margin):
    """(tx, ty, tz, ox, oy, oz, delta) for a capped cylinder (see module docstring)."""
    cx, cy, cz = table[k, OBS_CX], table[k, OBS_CY], table[k, OBS_CZ]
    ax, ay, az = table[k, OBS_AX], table[k, OBS_AY], table[k, OBS_AZ]
    radius, half = table[k, OBS_RADIUS], table[k, OBS_HALF_LENGTH]
    ca = ax * fx + ay * fy + az * fz
    e1x, e1y, e1z = ax - ca * fx, ay - ca * fy, az - ca * fz
    sa = math.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
    wx, wy, wz = perpendicular_part(px - cx, py - cy, pz - cz, fx, fy, fz)
    if sa <= VIEW_DEGENERATE:
        ex, ey, ez, ox, oy, oz, delta = end_on_outline(cx, cy, cz, ax, ay, az, radius, half, ca, wx, wy, wz,
                                                       fx, fy, fz, ux, uy, uz, body_radius)
    else:
        e1x, e1y, e1z = e1x / sa, e1y / sa, e1z / sa
        e2x, e2y, e2z = fy * e1z - fz * e1y, fz * e1x - fx * e1z, fx * e1y - fy * e1x
        u1 = wx * e1x + wy * e1y + wz * e1z
        u2 = wx * e2x + wy * e2y + wz * e2z
        if abs(ca) <= VIEW_DEGENERATE:
            ex, ey, ez, ox, oy, oz, delta = side_on_outline(cx, cy, cz, ax, ay, az, radius, half, sa, e1x, e1y,
                                                            e1z, e2x, e2y, e2z, fx, fy, fz, u1, u2, body_radius)
        else:
            ex, ey, ez, ox, oy, oz, delta = oblique_outline(cx, cy, cz, ax, ay, az, radius, half, ca, sa, e1x,
                                                            e1y, e1z, e2x, e2y, e2z, fx, fy, fz, u1, u2,
                                                            body_radius)
    reach = body_radius + margin
    return ex + reach * ox, ey + reach * oy, ez + reach * oz, ox, oy, oz, delta


@nb.njit(cache=True, error_model="numpy")
def along_plane(nx, ny, nz, fx, fy, fz, ux, uy, uz):
    """Unit direction along a plane of normal n: f without its normal part (up likewise if f is along n)."""
    dx, dy, dz = perpendicular_part(fx, fy, fz, nx, ny, nz)
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    if norm > DEGENERATE:
        return dx / norm, dy / norm, dz / norm
    return across_from_up(nx, ny, nz, ux, uy, uz)


@nb.njit(cache=True, error_model="numpy")
def silhouette_target(table, kinds, k, px, py, pz, fx, fy, fz, ux, uy, uz, body_radius, margin):
    """(tx, ty, tz, ox, oy, oz, delta): steer-to-avoid target of obstacle k for the ray from p along f,
    the outline's outward image normal o and the ray-to-outline distance delta (see module docstring).
    For a plane: target p + d with d along the plane, o = d, delta = inf."""
    kind = kinds[k]
    if kind == KIND_SPHERE:
        return sphere_silhouette(table[k, OBS_CX], table[k, OBS_CY], table[k, OBS_CZ], table[k, OBS_RADIUS],
                                 px, py, pz, fx, fy, fz, ux, uy, uz, body_radius, margin)
    if kind == KIND_BOX:
        return box_silhouette(table, k, px, py, pz, fx, fy, fz, body_radius, margin)
    if kind == KIND_PLANE:
        dx, dy, dz = along_plane(table[k, OBS_NX], table[k, OBS_NY], table[k, OBS_NZ], fx, fy, fz, ux, uy, uz)
        return px + dx, py + dy, pz + dz, dx, dy, dz, math.inf
    return cylinder_silhouette(table, k, px, py, pz, fx, fy, fz, ux, uy, uz, body_radius, margin)
