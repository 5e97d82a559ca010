"""Perception kernels: who boid i sees (MODEL.md section 2). Compiled with numba.

``perceive(i, pos, fwd, side, fp, ip, nb_idx, nb_off, nb_mask, nb_label, work_f, work_i)`` fills the
first ``m`` slots of the neighbour buffers and returns ``m``:

* ``nb_idx``   int64 (N,)    neighbour index j, ascending
* ``nb_off``   float64 (N,3) offset d_j = p_j - p_i (minimum image in a periodic box)
* ``nb_mask``  int64 (N,)    rule bits: ``RULE_SEPARATION | RULE_ALIGNMENT | RULE_COHESION`` it feeds
* ``nb_label`` int64 (N,)    binocular eye label: ``EYE_LEFT``, ``EYE_RIGHT`` or ``EYE_BOTH`` (0 otherwise)

``work_f`` float64 (N, 5) and ``work_i`` int64 (N + 2, 4) are scratch for the occlusion phase. Kinds:

* sphere: |d| < radius;
* opensteer: per rule, |d| < near_radius, else |d| <= r and f . d/|d| > c;
* binocular: view phase per eye (range from the eye, cone about the gaze axis), then the perspective
  phase: a farther in-view k is hidden when a closer in-view j's projected disc contains k's,
  |u_j - u_k| <= rho_j - rho_k. Every in-view boid occludes, hidden or not, so the result is
  independent of the order of the checks. A neighbour exactly at the observer's centre (possible when
  the eyes sit off-centre) has no direction: it neither hides nor is hidden.
"""
from __future__ import annotations

import math

import numba as nb

from .layout import (F_BODY_R, F_COH_COS, F_COH_R, F_COS_EYE, F_COS_GAZE, F_COS_HALF_FIELD, F_ALI_COS,
                     F_ALI_R, F_BOX, F_HEAD_R, F_NEAR_R, F_RANGE, F_SEP_COS, F_SEP_R, F_SIN_EYE,
                     F_SIN_GAZE, F_SPHERE_RADIUS, I_BOUNDARY, I_OCCLUSION, I_PERCEPTION, I_SEE_ALL,
                     BOUNDARY_PERIODIC, PERCEPTION_BINOCULAR, PERCEPTION_OPENSTEER)

RULE_SEPARATION = 1
RULE_ALIGNMENT = 2
RULE_COHESION = 4
RULE_ALL = 7
EYE_LEFT = 1
EYE_RIGHT = 2
EYE_BOTH = 3


@nb.njit(cache=True, error_model="numpy", inline="always")
def min_image(x, box):
    """Minimum-image component of an offset in a periodic box of side ``box``."""
    return x - box * math.floor(x / box + 0.5)


@nb.njit(cache=True, error_model="numpy", inline="always")
def offset(pos, i, j, periodic, box):
    """d = p_j - p_i, minimum image when ``periodic``."""
    dx = pos[j, 0] - pos[i, 0]
    dy = pos[j, 1] - pos[i, 1]
    dz = pos[j, 2] - pos[i, 2]
    if periodic:
        dx = min_image(dx, box)
        dy = min_image(dy, box)
        dz = min_image(dz, box)
    return dx, dy, dz


@nb.njit(cache=True, error_model="numpy", inline="always")
def _store(m, j, dx, dy, dz, mask, label, nb_idx, nb_off, nb_mask, nb_label):
    nb_idx[m] = j
    nb_off[m, 0] = dx
    nb_off[m, 1] = dy
    nb_off[m, 2] = dz
    nb_mask[m] = mask
    nb_label[m] = label


@nb.njit(cache=True, error_model="numpy", inline="always")
def _perceive_sphere(i, pos, fp, periodic, box, nb_idx, nb_off, nb_mask, nb_label):
    r2 = fp[F_SPHERE_RADIUS] * fp[F_SPHERE_RADIUS]
    m = 0
    for j in range(pos.shape[0]):
        if j == i:
            continue
        dx, dy, dz = offset(pos, i, j, periodic, box)
        if dx * dx + dy * dy + dz * dz < r2:
            _store(m, j, dx, dy, dz, RULE_ALL, 0, nb_idx, nb_off, nb_mask, nb_label)
            m += 1
    return m


@nb.njit(cache=True, error_model="numpy", inline="always")
def _perceive_opensteer(i, pos, fwd, fp, periodic, box, nb_idx, nb_off, nb_mask, nb_label):
    near2 = fp[F_NEAR_R] * fp[F_NEAR_R]
    sep_r2 = fp[F_SEP_R] * fp[F_SEP_R]
    ali_r2 = fp[F_ALI_R] * fp[F_ALI_R]
    coh_r2 = fp[F_COH_R] * fp[F_COH_R]
    far2 = max(sep_r2, ali_r2, coh_r2)
    fx, fy, fz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    m = 0
    for j in range(pos.shape[0]):
        if j == i:
            continue
        dx, dy, dz = offset(pos, i, j, periodic, box)
        dd = dx * dx + dy * dy + dz * dz
        if dd < near2:
            mask = RULE_ALL
        elif dd > far2:
            continue
        else:
            dist = math.sqrt(dd)
            forwardness = (fx * dx + fy * dy + fz * dz) / dist
            mask = 0
            if dd <= sep_r2 and forwardness > fp[F_SEP_COS]:
                mask |= RULE_SEPARATION
            if dd <= ali_r2 and forwardness > fp[F_ALI_COS]:
                mask |= RULE_ALIGNMENT
            if dd <= coh_r2 and forwardness > fp[F_COH_COS]:
                mask |= RULE_COHESION
            if mask == 0:
                continue
        _store(m, j, dx, dy, dz, mask, 0, nb_idx, nb_off, nb_mask, nb_label)
        m += 1
    return m


@nb.njit(cache=True, error_model="numpy", inline="always")
def _in_eye(dx, dy, dz, ex, ey, ez, ax, ay, az, range2, cos_half, see_all):
    """Is offset d (from the boid's centre) in the view of the eye at offset e with gaze axis a?"""
    qx = dx - ex
    qy = dy - ey
    qz = dz - ez
    q2 = qx * qx + qy * qy + qz * qz
    if q2 <= 0.0 or q2 > range2:
        return False
    if see_all:
        return True
    return ax * qx + ay * qy + az * qz >= cos_half * math.sqrt(q2)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _view_phase(i, pos, fwd, side, fp, ip, periodic, box, nb_idx, nb_off, nb_mask, nb_label):
    """In-view neighbours with their eye labels; returns their count."""
    f0, f1, f2 = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    s0, s1, s2 = side[i, 0], side[i, 1], side[i, 2]
    h, ce, se = fp[F_HEAD_R], fp[F_COS_EYE], fp[F_SIN_EYE]
    cg, sg = fp[F_COS_GAZE], fp[F_SIN_GAZE]
    # eye offsets from the boid's centre and gaze axes; left uses -side, right +side
    lx, ly, lz = h * (ce * f0 - se * s0), h * (ce * f1 - se * s1), h * (ce * f2 - se * s2)
    rx, ry, rz = h * (ce * f0 + se * s0), h * (ce * f1 + se * s1), h * (ce * f2 + se * s2)
    alx, aly, alz = cg * f0 - sg * s0, cg * f1 - sg * s1, cg * f2 - sg * s2
    arx, ary, arz = cg * f0 + sg * s0, cg * f1 + sg * s1, cg * f2 + sg * s2
    rng = fp[F_RANGE]
    range2 = rng * rng
    reach2 = (rng + h) * (rng + h)  # no eye sees beyond range + head_radius from the centre
    cos_half = fp[F_COS_HALF_FIELD]
    see_all = ip[I_SEE_ALL] != 0
    m = 0
    for j in range(pos.shape[0]):
        if j == i:
            continue
        dx, dy, dz = offset(pos, i, j, periodic, box)
        if dx * dx + dy * dy + dz * dz > reach2:
            continue
        label = 0
        if _in_eye(dx, dy, dz, lx, ly, lz, alx, aly, alz, range2, cos_half, see_all):
            label |= EYE_LEFT
        if _in_eye(dx, dy, dz, rx, ry, rz, arx, ary, arz, range2, cos_half, see_all):
            label |= EYE_RIGHT
        if label != 0:
            _store(m, j, dx, dy, dz, RULE_ALL, label, nb_idx, nb_off, nb_mask, nb_label)
            m += 1
    return m


@nb.njit(cache=True, error_model="numpy", inline="always")
def _bin(x, n_bins):
    b = int((x + 1.0) * (0.5 * n_bins))
    return min(max(b, 0), n_bins - 1)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _occlude(m, fp, nb_idx, nb_off, nb_mask, nb_label, work_f, work_i):
    """Perspective phase: drop completely occluded neighbours in place; returns the new count.

    Candidate pairs come from bins along one world axis of the projected centres (the axis of widest
    spread): since |x_j - x_k| <= |u_j - u_k| <= rho_j - rho_k < rho_j, an occluder j can only hide a k
    whose coordinate lies within rho_j of its own. Every candidate gets the exact containment test, so
    the result is that of testing every pair.
    """
    body = fp[F_BODY_R]
    sum_x = sum_y = sum_z = 0.0
    sq_x = sq_y = sq_z = 0.0
    for a in range(m):
        dist = math.sqrt(nb_off[a, 0] ** 2 + nb_off[a, 1] ** 2 + nb_off[a, 2] ** 2)
        if dist > 0.0:
            inv = 1.0 / dist
            x, y, z = nb_off[a, 0] * inv, nb_off[a, 1] * inv, nb_off[a, 2] * inv
            work_f[a, 0] = body * inv
            work_f[a, 1], work_f[a, 2], work_f[a, 3] = x, y, z
            sum_x += x
            sum_y += y
            sum_z += z
            sq_x += x * x
            sq_y += y * y
            sq_z += z * z
        else:  # at the observer's centre (seen from an eye): no direction, neither hides nor is hidden
            work_f[a, 0] = -1.0
            work_f[a, 1] = work_f[a, 2] = work_f[a, 3] = 0.0
    # sweep along the world axis of widest spread of the projected centres (largest variance)
    spread_x = sq_x - sum_x * sum_x / m
    spread_y = sq_y - sum_y * sum_y / m
    spread_z = sq_z - sum_z * sum_z / m
    if spread_x >= spread_y and spread_x >= spread_z:
        axis = 1
    elif spread_y >= spread_z:
        axis = 2
    else:
        axis = 3
    # counting sort of the slots into m bins over [-1, 1]: work_i[:, 2] bin starts, work_i[:, 1] slots
    n_bins = m
    for b in range(n_bins + 1):
        work_i[b, 2] = 0
    for a in range(m):
        work_i[a, 0] = 0  # hidden flag, by slot
        work_i[_bin(work_f[a, axis], n_bins) + 1, 2] += 1
    for b in range(n_bins):
        work_i[b + 1, 2] += work_i[b, 2]
    for b in range(n_bins):
        work_i[b, 3] = work_i[b, 2]  # fill cursor
    for a in range(m):
        b = _bin(work_f[a, axis], n_bins)
        work_i[work_i[b, 3], 1] = a
        work_i[b, 3] += 1
    for j in range(m):
        rho_j = work_f[j, 0]
        reach = rho_j * (1.0 + 1e-9)
        lo = _bin(work_f[j, axis] - reach, n_bins)
        hi = _bin(work_f[j, axis] + reach, n_bins)
        for s in range(work_i[lo, 2], work_i[hi + 1, 2]):
            k = work_i[s, 1]
            gap = rho_j - work_f[k, 0]
            if gap <= 0.0 or work_i[k, 0] != 0 or work_f[k, 0] < 0.0:
                continue
            ux = work_f[j, 1] - work_f[k, 1]
            uy = work_f[j, 2] - work_f[k, 2]
            uz = work_f[j, 3] - work_f[k, 3]
            if ux * ux + uy * uy + uz * uz <= gap * gap:
                work_i[k, 0] = 1
    kept = 0
    for a in range(m):
        if work_i[a, 0] == 0:
            if kept != a:
                _store(kept, nb_idx[a], nb_off[a, 0], nb_off[a, 1], nb_off[a, 2], nb_mask[a], nb_label[a],
                       nb_idx, nb_off, nb_mask, nb_label)
            kept += 1
    return kept


@nb.njit(cache=True, error_model="numpy", inline="always")
def perceive(i, pos, fwd, side, fp, ip, nb_idx, nb_off, nb_mask, nb_label, work_f, work_i):
    """Neighbours of boid i (see module docstring); returns their count m."""
    periodic = ip[I_BOUNDARY] == BOUNDARY_PERIODIC
    box = fp[F_BOX]
    kind = ip[I_PERCEPTION]
    if kind == PERCEPTION_BINOCULAR:
        m = _view_phase(i, pos, fwd, side, fp, ip, periodic, box, nb_idx, nb_off, nb_mask, nb_label)
        if ip[I_OCCLUSION] != 0 and m > 1:
            m = _occlude(m, fp, nb_idx, nb_off, nb_mask, nb_label, work_f, work_i)
        return m
    if kind == PERCEPTION_OPENSTEER:
        return _perceive_opensteer(i, pos, fwd, fp, periodic, box, nb_idx, nb_off, nb_mask, nb_label)
    return _perceive_sphere(i, pos, fp, periodic, box, nb_idx, nb_off, nb_mask, nb_label)
