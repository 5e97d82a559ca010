"""OpenSteer steering rules and Holland's pattern weighting (docs/model.md section 3). Compiled with numba.

``opensteer_force(i, m, fwd, pattern, fp, ip, nb_idx, nb_off, nb_mask)`` returns the combined steering
force (fx, fy, fz) of boid i from its ``m`` perceived neighbours (buffers as in :mod:`simcore.perception`):

    S = normalize(sum_j w'_ij (-d_j / |d_j|^2))
    A = normalize(sum_j w_ij f_j / sum_j w_ij - f_i)
    C = normalize(sum_j w_ij d_j / sum_j w_ij)
    force = w_s S + w_a A + w_c C

with w = w' = 1 outside pattern mode, and in pattern mode w_ij = (n - popcount(b_i ^ b_j)) / n and w'
chosen by ``patterns.separation_weight`` (similarity w, dissimilarity 1 - w, uniform 1). A rule with no
neighbours or zero total weight contributes 0; normalize(0) = 0. Sums run in ascending j. A neighbour
at distance exactly 0 adds nothing to separation (its direction is undefined).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import inline, llvm_inline
from .layout import F, I, SEPW_DISSIMILARITY, SEPW_SIMILARITY
from .neighbours import RULE_ALIGNMENT, RULE_COHESION, RULE_SEPARATION


@inline
def popcount32(x):
    """Number of set bits of a 32-bit pattern."""
    x = np.uint32(x)
    x = x - ((x >> np.uint32(1)) & np.uint32(0x55555555))
    x = (x & np.uint32(0x33333333)) + ((x >> np.uint32(2)) & np.uint32(0x33333333))
    x = (x + (x >> np.uint32(4))) & np.uint32(0x0F0F0F0F)
    return np.int64((x * np.uint32(0x01010101)) >> np.uint32(24))


@inline
def similarity(a, b, n_bits):
    """Holland's pattern match in [0, 1]: share of equal bits of two n-bit patterns."""
    return (n_bits - popcount32(np.uint32(a) ^ np.uint32(b))) / n_bits


@inline
def normalized(x, y, z):
    """(x, y, z) / |(x, y, z)|, or zeros for the zero vector."""
    n = math.sqrt(x * x + y * y + z * z)
    if n > 0.0:
        return x / n, y / n, z / n
    return 0.0, 0.0, 0.0


@llvm_inline
def opensteer_force(i, m, fwd, pattern, fp, ip, nb_idx, nb_off, nb_mask):
    """Combined steering force of boid i (see module docstring)."""
    use_patterns = ip[I.PATTERNS] != 0
    n_bits = ip[I.NBITS]
    sep_mode = ip[I.SEP_WEIGHT]
    sx = sy = sz = 0.0
    ax = ay = az = 0.0
    cx = cy = cz = 0.0
    w_ali = 0.0
    w_coh = 0.0
    for n in range(m):
        j = nb_idx[n]
        mask = nb_mask[n]
        dx, dy, dz = nb_off[n, 0], nb_off[n, 1], nb_off[n, 2]
        w = similarity(pattern[i], pattern[j], n_bits) if use_patterns else 1.0
        if mask & RULE_SEPARATION:
            dd = dx * dx + dy * dy + dz * dz
            if dd > 0.0:
                if not use_patterns or sep_mode == SEPW_SIMILARITY:
                    ws = w
                elif sep_mode == SEPW_DISSIMILARITY:
                    ws = 1.0 - w
                else:
                    ws = 1.0
                sx += ws * (-dx / dd)
                sy += ws * (-dy / dd)
                sz += ws * (-dz / dd)
        if mask & RULE_ALIGNMENT:
            ax += w * fwd[j, 0]
            ay += w * fwd[j, 1]
            az += w * fwd[j, 2]
            w_ali += w
        if mask & RULE_COHESION:
            cx += w * dx
            cy += w * dy
            cz += w * dz
            w_coh += w
    sx, sy, sz = normalized(sx, sy, sz)
    if w_ali > 0.0:
        ax, ay, az = normalized(ax / w_ali - fwd[i, 0], ay / w_ali - fwd[i, 1], az / w_ali - fwd[i, 2])
    if w_coh > 0.0:
        cx, cy, cz = normalized(cx / w_coh, cy / w_coh, cz / w_coh)
    ws_, wa_, wc_ = fp[F.SEP_W], fp[F.ALI_W], fp[F.COH_W]
    return (ws_ * sx + wa_ * ax + wc_ * cx,
            ws_ * sy + wa_ * ay + wc_ * cy,
            ws_ * sz + wa_ * az + wc_ * cz)


@llvm_inline
def hartman_benes_forces(i, m, vel, fp, nb_idx, nb_off):
    """Hartman-Benes steers of boid i from its m visible boids (docs/model.md section 5):
    s = sum_j (p_i - p_j) / |p_i - p_j|^f (f = gains.separation_falloff_exponent; 0 = the paper's literal
    sum), k = mean_j d_j (= c_i - p_i), mv = mean_j v_j; all zero when m = 0. Returns 9 floats."""
    sx = sy = sz = 0.0
    kx = ky = kz = 0.0
    mx = my = mz = 0.0
    falloff = fp[F.SEP_FALLOFF]
    for n in range(m):
        j = nb_idx[n]
        dx, dy, dz = nb_off[n, 0], nb_off[n, 1], nb_off[n, 2]
        if falloff == 0.0:
            w = 1.0
        else:
            dd = dx * dx + dy * dy + dz * dz
            if dd <= 0.0:
                w = 0.0
            elif falloff == 2.0:
                w = 1.0 / dd
            else:
                w = 1.0 / dd ** (0.5 * falloff)
        sx -= w * dx
        sy -= w * dy
        sz -= w * dz
        kx += dx
        ky += dy
        kz += dz
        mx += vel[j, 0]
        my += vel[j, 1]
        mz += vel[j, 2]
    if m > 0:
        kx, ky, kz = kx / m, ky / m, kz / m
        mx, my, mz = mx / m, my / m, mz / m
    return sx, sy, sz, kx, ky, kz, mx, my, mz


@inline
def cohesion_offset(m, nb_off, nb_mask):
    """(k_x, k_y, k_z, count): mean offset to the neighbours in the cohesion set (leadership's k_i)."""
    kx = ky = kz = 0.0
    count = 0
    for n in range(m):
        if nb_mask[n] & RULE_COHESION:
            kx += nb_off[n, 0]
            ky += nb_off[n, 1]
            kz += nb_off[n, 2]
            count += 1
    if count > 0:
        kx, ky, kz = kx / count, ky / count, kz / count
    return kx, ky, kz, count
