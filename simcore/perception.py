"""Perception kernels: who boid i sees (docs/model.md, "Perception"). Compiled with numba.

``perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)`` fills the first ``m`` slots of the
neighbour buffers ``nbrs`` (:mod:`simcore.neighbours`) and returns ``m``:

* ``nbrs.idx``   int64 (N,)    neighbour index j, ascending
* ``nbrs.off``   float64 (N,3) offset d_j = p_j - p_i (minimum image in a periodic box)
* ``nbrs.mask``  int64 (N,)    rule bits: ``RULE_SEPARATION | RULE_ALIGNMENT | RULE_COHESION`` it feeds
* ``nbrs.label`` int64 (N,)    binocular eye label: ``EYE_LEFT``, ``EYE_RIGHT`` or ``EYE_BOTH`` (0 otherwise)

The rest of ``nbrs`` is scratch. Kinds:

* sphere: |d| < radius;
* opensteer: per rule, |d| < near_radius, else |d| <= r and f . d/|d| > c;
* binocular: view phase per eye (range from the eye, cone about the gaze axis), then the perspective
  phase (:mod:`simcore.occlusion`);
* topological: the k nearest eligible boids (:mod:`simcore.topological`).

Compilation. ``kind`` (``PERCEPTION_*``, the run's ``ip[I.PERCEPTION]``) is a compile-time literal in
compiled callers, and each kind has its own perceiver (``perceive_sphere``, ``perceive_opensteer``,
``perceive_binocular``, ``perceive_topological``), compiled as a leaf only when a caller asks for it: a
holland run never compiles the kNN, an opensteer run neither the view phase nor occlusion.

Search. With ``use_grid`` the candidates come from the cell lists of :mod:`simcore.grid` (built for this
state with :func:`query_radius`), otherwise from all pairs. Every candidate gets the same exact test and
the accepted ones are put in ascending index order, so both searches give bit-identical buffers, and the
rules downstream sum in the same order.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np
from numba import types
from numba.extending import overload

from .jit import LEAF_OPTIONS, call_with_literal_kind, inline, kernel, llvm_inline
from .grid import LAYOUT, SORTED, gather, runs
from .layout import (BOUNDARY_PERIODIC, F, I, PERCEPTION_BINOCULAR, PERCEPTION_OPENSTEER, PERCEPTION_SPHERE,
                     PERCEPTION_TOPOLOGICAL)
from .neighbours import (EYE_BOTH, EYE_LEFT, EYE_RIGHT, RULE_ALIGNMENT, RULE_ALL, RULE_COHESION,  # noqa: F401
                         RULE_SEPARATION, min_image, offset_from, offset_to, sort_by_index,
                         store)
from .occlusion import occlude
from .topological import nearest

SURE = 1e-12                # relative gap between squares beyond any rounding of the cone test (a few 1e-16)
TINY, HUGE = 1e-250, 1e250  # squares compared only between these (no underflow or overflow)


@inline
def query_radius(fp, ip):
    """Distance from a boid's centre beyond which its perception never reaches (grid cell size)."""
    kind = ip[I.PERCEPTION]
    if kind == PERCEPTION_SPHERE:
        return fp[F.SPHERE_RADIUS]
    if kind == PERCEPTION_OPENSTEER:
        return max(fp[F.NEAR_R], fp[F.SEP_R], fp[F.ALI_R], fp[F.COH_R])
    if kind == PERCEPTION_BINOCULAR:
        return fp[F.RANGE] + fp[F.HEAD_R]
    return fp[F.TOPO_RADIUS]


@inline
def _candidates(i, pos, fp, ip, periodic, box, nbrs, grid, use_grid):
    """(n_runs, first, last, indices, positions): the candidate neighbours of boid i (boid i among them)
    are ``indices[c]`` at ``positions[c]`` for c in the runs ``first[r]:last[r]``, r < n_runs: the grid's
    (read in place from a sorted grid, less the cells wholly beyond :func:`query_radius`; else gathered
    into ``nbrs.cand``/``nbrs.cpos``), or, searching all pairs, the boids within :func:`query_radius` in
    ascending order (:func:`_within`, into ``nbrs.cand``/``nbrs.cpos``). The runs live in rows 0 and 1 of
    the scratch ``nbrs.occ_i`` (free until the perspective phase)."""
    first, last = nbrs.occ_i[0], nbrs.occ_i[1]
    radius = query_radius(fp, ip)
    if use_grid:
        if grid.shape[LAYOUT] == SORTED:
            return runs(grid, i, pos, radius, first, last), first, last, grid.order, grid.spos
        first[0], last[0] = 0, gather(grid, i, pos, nbrs.cand, nbrs.cpos)
        return 1, first, last, nbrs.cand, nbrs.cpos
    first[0], last[0] = 0, _within(i, radius * radius, periodic, box, grid.flat, nbrs.d2, nbrs.cand, nbrs.cpos)
    return 1, first, last, nbrs.cand, nbrs.cpos


@llvm_inline
def _within(i, radius2, periodic, box, flat, d2, near, near_pos):
    """All pairs: the boids whose squared distance from boid i is at most ``radius2`` (boid i among them)
    into ``near``, ascending, and their positions (bit for bit) into ``near_pos``; returns their count.
    The squared distances of every boid come first, in one
    pass over the mirrored positions ``flat`` (:func:`simcore.grid.mirror`) that runs in SIMD lanes; each
    is computed exactly as the perceivers' own test computes it (offset, minimum image, then
    dx * dx + dy * dy + dz * dz), so no boid the test would accept is left out."""
    x, y, z = flat[0], flat[1], flat[2]
    px, py, pz = x[i], y[i], z[i]
    n = x.shape[0]
    if periodic:
        for c in range(n):
            dx = min_image(x[c] - px, box)
            dy = min_image(y[c] - py, box)
            dz = min_image(z[c] - pz, box)
            d2[c] = dx * dx + dy * dy + dz * dz
    else:
        for c in range(n):
            dx = x[c] - px
            dy = y[c] - py
            dz = z[c] - pz
            d2[c] = dx * dx + dy * dy + dz * dz
    count = 0
    for c in range(n):  # a branch beats branch-free stores here, dense flocks included (bench/RESULTS.md)
        if d2[c] <= radius2:
            near[count] = c
            near_pos[count, 0], near_pos[count, 1], near_pos[count, 2] = x[c], y[c], z[c]
            count += 1
    return count


@inline
def _sphere(i, n_runs, first, last, cand, cpos, pos, fp, periodic, box, nbrs):
    r2 = fp[F.SPHERE_RADIUS] * fp[F.SPHERE_RADIUS]
    m = 0
    for r in range(n_runs):
        for c in range(first[r], last[r]):
            j = cand[c]
            dx, dy, dz = offset_from(cpos[c, 0], cpos[c, 1], cpos[c, 2], pos, i, periodic, box)
            if dx * dx + dy * dy + dz * dz < r2 and j != i:
                store(nbrs, m, j, dx, dy, dz, RULE_ALL, 0)
                m += 1
    return m


@llvm_inline
def _opensteer(i, n_runs, first, last, cand, cpos, pos, fwd, fp, periodic, box, nbrs):
    near2 = fp[F.NEAR_R] * fp[F.NEAR_R]
    sep_r2 = fp[F.SEP_R] * fp[F.SEP_R]
    ali_r2 = fp[F.ALI_R] * fp[F.ALI_R]
    coh_r2 = fp[F.COH_R] * fp[F.COH_R]
    far2 = max(sep_r2, ali_r2, coh_r2)
    sep_cos, ali_cos, coh_cos = fp[F.SEP_COS], fp[F.ALI_COS], fp[F.COH_COS]
    fx, fy, fz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    m = 0
    for r in range(n_runs):
        for c in range(first[r], last[r]):
            j = cand[c]
            if j == i:
                continue
            dx, dy, dz = offset_from(cpos[c, 0], cpos[c, 1], cpos[c, 2], pos, i, periodic, box)
            dd = dx * dx + dy * dy + dz * dz
            if dd < near2:
                mask = RULE_ALL
            elif dd > far2:
                continue
            else:
                dist = math.sqrt(dd)
                forwardness = (fx * dx + fy * dy + fz * dz) / dist
                mask = 0
                if dd <= sep_r2 and forwardness > sep_cos:
                    mask |= RULE_SEPARATION
                if dd <= ali_r2 and forwardness > ali_cos:
                    mask |= RULE_ALIGNMENT
                if dd <= coh_r2 and forwardness > coh_cos:
                    mask |= RULE_COHESION
                if mask == 0:
                    continue
            store(nbrs, m, j, dx, dy, dz, mask, 0)
            m += 1
    return m


@llvm_inline
def _in_eye(dx, dy, dz, ex, ey, ez, ax, ay, az, range2, cos_half, cos_half2, see_all):
    """Is offset d (from the boid's centre) in the view of the eye at offset e with gaze axis a?

    The cone test is a . q >= cos_half |q| (for q within range). Its square root is spared when the answer
    is sure without it: the signs of a . q and cos_half differ, or the squares (a . q)^2 and
    cos_half^2 |q|^2 differ by far more than rounding (``SURE``); otherwise the test is computed as
    written, so the answer is always its."""
    qx = dx - ex
    qy = dy - ey
    qz = dz - ez
    along = ax * qx + ay * qy + az * qz
    if along < 0.0 and cos_half >= 0.0 and not see_all:  # behind the eye: out whatever the range
        return False
    q2 = qx * qx + qy * qy + qz * qz
    if q2 <= 0.0 or q2 > range2:
        return False
    if see_all or (along >= 0.0 and cos_half < 0.0):
        return True
    bound2 = cos_half2 * q2
    if TINY < bound2 < HUGE:
        along2 = along * along
        if along2 > bound2 * (1.0 + SURE):
            return cos_half >= 0.0
        if along2 < bound2 * (1.0 - SURE):
            return cos_half < 0.0
    return along >= cos_half * math.sqrt(q2)


@inline
def _in_narrow_eye(dx, dy, dz, ex, ey, ez, ax, ay, az, range2, cos_half2):
    """:func:`_in_eye` for an eye whose cos_half >= 0 (and not see_all), without branches: (in view for
    sure, unsure). When unsure, :func:`_in_eye` decides (its square root); otherwise the answer is its."""
    qx = dx - ex
    qy = dy - ey
    qz = dz - ez
    along = ax * qx + ay * qy + az * qz
    q2 = qx * qx + qy * qy + qz * qz
    bound2 = cos_half2 * q2
    along2 = along * along
    candidate = (along >= 0.0) & (q2 > 0.0) & (q2 <= range2)
    bounded = (bound2 > TINY) & (bound2 < HUGE)
    sure_in = bounded & (along2 > bound2 * (1.0 + SURE))
    sure_out = bounded & (along2 < bound2 * (1.0 - SURE))
    return candidate & sure_in, candidate & ~(sure_in | sure_out)


@inline
def _label(i, j, dx, dy, dz, lx, ly, lz, alx, aly, alz, rx, ry, rz, arx, ary, arz, range2, cos_half, cos_half2,
           see_all):
    """Eye label of candidate j at offset d (0 for boid i itself or out of both views)."""
    label = 0
    if j != i:
        if _in_eye(dx, dy, dz, lx, ly, lz, alx, aly, alz, range2, cos_half, cos_half2, see_all):
            label |= EYE_LEFT
        if _in_eye(dx, dy, dz, rx, ry, rz, arx, ary, arz, range2, cos_half, cos_half2, see_all):
            label |= EYE_RIGHT
    return label


@inline
def _eyes(i, fwd, side, fp):
    """Boid i's eye offsets from its centre and gaze axes: (left offset, right offset, left axis, right
    axis) as 12 numbers; the left eye uses -side, the right +side."""
    f0, f1, f2 = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    s0, s1, s2 = side[i, 0], side[i, 1], side[i, 2]
    h, ce, se = fp[F.HEAD_R], fp[F.COS_EYE], fp[F.SIN_EYE]
    cg, sg = fp[F.COS_GAZE], fp[F.SIN_GAZE]
    return (h * (ce * f0 - se * s0), h * (ce * f1 - se * s1), h * (ce * f2 - se * s2),
            h * (ce * f0 + se * s0), h * (ce * f1 + se * s1), h * (ce * f2 + se * s2),
            cg * f0 - sg * s0, cg * f1 - sg * s1, cg * f2 - sg * s2,
            cg * f0 + sg * s0, cg * f1 + sg * s1, cg * f2 + sg * s2)


@inline
def _view_limits(fp):
    """(range^2, reach^2, cos of the half field, its square); no eye sees beyond reach = range + head
    radius from the boid's centre."""
    rng, h, cos_half = fp[F.RANGE], fp[F.HEAD_R], fp[F.COS_HALF_FIELD]
    return rng * rng, (rng + h) * (rng + h), cos_half, cos_half * cos_half


@llvm_inline
def _view_phase(i, n_runs, first, last, cand, cpos, pos, fwd, side, fp, ip, periodic, box, nbrs):
    """In-view neighbours with their eye labels; returns their count."""
    lx, ly, lz, rx, ry, rz, alx, aly, alz, arx, ary, arz = _eyes(i, fwd, side, fp)
    range2, reach2, cos_half, cos_half2 = _view_limits(fp)
    see_all = ip[I.SEE_ALL] != 0
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    near = nbrs.slot  # scratch: the candidates within reach, in candidate order
    n_near = 0
    for r in range(n_runs):
        for c in range(first[r], last[r]):  # branch-free: most candidates are out of reach
            dx, dy, dz = offset_to(cpos[c, 0], cpos[c, 1], cpos[c, 2], px, py, pz, periodic, box)
            near[n_near] = c
            n_near += dx * dx + dy * dy + dz * dz <= reach2
    m = 0
    if not (cos_half >= 0.0 and not see_all):
        for t in range(n_near):
            c = near[t]
            j = cand[c]
            dx, dy, dz = offset_to(cpos[c, 0], cpos[c, 1], cpos[c, 2], px, py, pz, periodic, box)
            label = _label(i, j, dx, dy, dz, lx, ly, lz, alx, aly, alz, rx, ry, rz, arx, ary, arz, range2,
                           cos_half, cos_half2, see_all)
            if label != 0:
                store(nbrs, m, j, dx, dy, dz, RULE_ALL, label)
                m += 1
        return m
    # each eye's field at most 180 degrees: branch-free unless a test is unsure (rare), since in view or
    # not is a coin toss per candidate
    for t in range(n_near):
        c = near[t]
        j = cand[c]
        dx, dy, dz = offset_to(cpos[c, 0], cpos[c, 1], cpos[c, 2], px, py, pz, periodic, box)
        in_l, unsure_l = _in_narrow_eye(dx, dy, dz, lx, ly, lz, alx, aly, alz, range2, cos_half2)
        in_r, unsure_r = _in_narrow_eye(dx, dy, dz, rx, ry, rz, arx, ary, arz, range2, cos_half2)
        label = (j != i) * (in_l * EYE_LEFT + in_r * EYE_RIGHT)
        if unsure_l | unsure_r:
            label = _label(i, j, dx, dy, dz, lx, ly, lz, alx, aly, alz, rx, ry, rz, arx, ary, arz, range2,
                           cos_half, cos_half2, see_all)
        store(nbrs, m, j, dx, dy, dz, RULE_ALL, label)  # kept only when in view (m advances)
        m += label != 0
    return m


UNSURE = 4  # code bit of :func:`_view_all_pairs`: a narrow-eye test could not decide without its square root


@llvm_inline
def _view_all_pairs(i, fwd, side, fp, ip, periodic, box, flat, nbrs):
    """:func:`_view_phase` over all pairs when each eye's field is at most 180 degrees, in passes that run
    in SIMD lanes where they can: every boid's offset and squared distance from the mirrored positions
    ``flat`` (offsets into the scratch rows ``nbrs.occ_f``, free until the perspective phase); the boids
    within reach kept (their indices in ``nbrs.slot``, offsets moved up in place); the eye tests of those, a
    code per boid in ``nbrs.cand``, branch-free; then the in-view ones stored in ascending order. The
    arithmetic is :func:`_view_phase`'s, test for test, so the slots are the same bit for bit."""
    lx, ly, lz, rx, ry, rz, alx, aly, alz, arx, ary, arz = _eyes(i, fwd, side, fp)
    range2, reach2, cos_half, cos_half2 = _view_limits(fp)
    x, y, z = flat[0], flat[1], flat[2]
    px, py, pz = x[i], y[i], z[i]
    ox, oy, oz, d2 = nbrs.occ_f[0], nbrs.occ_f[1], nbrs.occ_f[2], nbrs.d2
    near, code = nbrs.slot, nbrs.cand
    n = x.shape[0]
    n_near = 0
    for c in range(n):
        dx, dy, dz = offset_to(x[c], y[c], z[c], px, py, pz, periodic, box)
        ox[c], oy[c], oz[c] = dx, dy, dz
        d2[c] = dx * dx + dy * dy + dz * dz
        near[c] = c
        n_near += d2[c] <= reach2
    if 2 * n_near > n:  # a dense flock: test every boid, the reach test among the others
        n_near = n
    else:  # a sparse one: keep the boids within reach first
        n_near = 0
        for c in range(n):
            if d2[c] <= reach2:
                near[n_near], d2[n_near] = c, d2[c]
                ox[n_near], oy[n_near], oz[n_near] = ox[c], oy[c], oz[c]
                n_near += 1
    for t in range(n_near):
        dx, dy, dz = ox[t], oy[t], oz[t]
        in_l, unsure_l = _in_narrow_eye(dx, dy, dz, lx, ly, lz, alx, aly, alz, range2, cos_half2)
        in_r, unsure_r = _in_narrow_eye(dx, dy, dz, rx, ry, rz, arx, ary, arz, range2, cos_half2)
        code[t] = ((near[t] != i) & (d2[t] <= reach2)) * (in_l * EYE_LEFT + in_r * EYE_RIGHT
                                                          + (unsure_l | unsure_r) * UNSURE)
    m = 0
    for t in range(n_near):
        label = code[t]
        if label != 0:
            j = near[t]
            dx, dy, dz = ox[t], oy[t], oz[t]
            if label >= UNSURE:
                label = _label(i, j, dx, dy, dz, lx, ly, lz, alx, aly, alz, rx, ry, rz, arx, ary, arz, range2,
                               cos_half, cos_half2, ip[I.SEE_ALL] != 0)   # False here, typed as _view_phase's
            store(nbrs, m, j, dx, dy, dz, RULE_ALL, label)
            m += label != 0
    return m


# The perceivers, one per kind, with a common signature (kind, i, pos, fwd, side, fp, ip, nbrs, grid,
# use_grid). Each is compiled as a leaf (``LEAF_OPTIONS``) by numba's typing of ``perceive`` below, only
# for a caller that asks for its kind; the unused ``kind`` argument is that literal.

def perceive_sphere(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid):
    periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
    n_runs, first, last, cand, cpos = _candidates(i, pos, fp, ip, periodic, fp[F.BOX], nbrs, grid, use_grid)
    m = _sphere(i, n_runs, first, last, cand, cpos, pos, fp, periodic, fp[F.BOX], nbrs)
    if use_grid:
        sort_by_index(m, nbrs)
    return m


def perceive_opensteer(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid):
    periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
    n_runs, first, last, cand, cpos = _candidates(i, pos, fp, ip, periodic, fp[F.BOX], nbrs, grid, use_grid)
    m = _opensteer(i, n_runs, first, last, cand, cpos, pos, fwd, fp, periodic, fp[F.BOX], nbrs)
    if use_grid:
        sort_by_index(m, nbrs)
    return m


def perceive_binocular(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid):
    periodic = ip[I.BOUNDARY] == BOUNDARY_PERIODIC
    if not use_grid and fp[F.COS_HALF_FIELD] >= 0.0 and ip[I.SEE_ALL] == 0:
        m = _view_all_pairs(i, fwd, side, fp, ip, periodic, fp[F.BOX], grid.flat, nbrs)
    else:
        n_runs, first, last, cand, cpos = _candidates(i, pos, fp, ip, periodic, fp[F.BOX], nbrs, grid, use_grid)
        m = _view_phase(i, n_runs, first, last, cand, cpos, pos, fwd, side, fp, ip, periodic, fp[F.BOX], nbrs)
    if ip[I.OCCLUSION] != 0 and m > 1:
        m = occlude(np.int64(m), fp, nbrs)  # int64 from the start: typing the call with the
        # literal 0 of the view phase's counter would compile occlude a second time
    if use_grid:
        sort_by_index(m, nbrs)
    return m


def perceive_topological(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid):
    return nearest(i, pos, fwd, fp, ip, ip[I.BOUNDARY] == BOUNDARY_PERIODIC, fp[F.BOX], nbrs, grid, use_grid)


PERCEIVERS = {PERCEPTION_SPHERE: perceive_sphere, PERCEPTION_OPENSTEER: perceive_opensteer,
              PERCEPTION_BINOCULAR: perceive_binocular, PERCEPTION_TOPOLOGICAL: perceive_topological}


def perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid):
    """Neighbours of boid i (see module docstring) by the perception ``kind`` (a ``PERCEPTION_*``, equal to
    ``ip[I.PERCEPTION]``); returns their count m.

    In compiled code ``kind`` must be a compile-time literal: a run loop's argument made literal with
    ``numba.literally`` (:mod:`simcore.jit`), or a ``PERCEPTION_*`` constant. The call then compiles into a
    call of that kind's perceiver alone, so a run compiles only the perception it uses. From Python it
    runs the same compiled perceiver (through :func:`perceive_one`)."""
    return call_with_literal_kind(perceive_one, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid, int(kind))


@overload(perceive, jit_options=LEAF_OPTIONS, prefer_literal=True)
def _perceiver_of_literal_kind(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid):
    """numba's typing of ``perceive``: with a literal kind, that kind's perceiver; with a kind known only at
    run time, no implementation (numba's typing error names ``perceive`` and the argument types)."""
    if isinstance(kind, types.IntegerLiteral):
        return PERCEIVERS.get(kind.literal_value)
    return None


@kernel
def perceive_one(i, pos, fwd, side, fp, ip, nbrs, grid, use_grid, kind):
    """``perceive`` as a compiled function Python can call (tests, :mod:`simcore.probe`)."""
    nb.literally(kind)
    return perceive(kind, i, pos, fwd, side, fp, ip, nbrs, grid, use_grid)
