"""Compiled per-record kernels behind ``groups`` and ``metrics`` (one frame = one record).

Everything compiled lives in this one module on purpose: numba's on-disk cache only notices changes to
the file that defines a function, so a kernel calling into another module could keep stale code.

Conventions: ``box`` <= 0 means an open world, otherwise the side of the periodic box (offsets folded to
the minimum image ``d - L floor(d/L + 0.5)``). Definitions are in docs/metrics.md; the Python wrappers
document the public behaviour. No fastmath: results are reproducible to the last bit.

The metric table that :func:`frame_kernel` fills has one column per name of :data:`COLUMNS`, in that
order; the kernel addresses a column as ``Column.<name>`` (an IntEnum generated from ``COLUMNS``), so
adding a metric is one name here plus the line of the kernel that computes it. Every column but one
reads a single record; ``overtake_rate`` compares each record with the one before (the kernel keeps the
previous record's group headings), so the records must be consecutive and evenly spaced.
"""
from __future__ import annotations

from enum import IntEnum

import numpy as np
from numba import njit

from .columns import SERIES

TINY = 1e-12  # relative size below which an eigenvalue, width or summed heading counts as zero

# the one declaration of the per-record metrics: the columns of frame_kernel's table, in order
COLUMNS = SERIES   # the series' names are declared in observables.columns (read without numba)
Column = IntEnum("Column", [(name, index) for index, name in enumerate(COLUMNS)])


@njit(cache=True)
def masked_mean(values, mask, mean):
    """mean[:] = the mean of the rows of ``values`` (N, 3) where ``mask`` is true (0 when none); their count."""
    count = 0
    for k in range(3):
        mean[k] = 0.0
    for i in range(values.shape[0]):
        if mask[i]:
            count += 1
            for k in range(3):
                mean[k] += values[i, k]
    if count > 0:
        for k in range(3):
            mean[k] /= count
    return count


@njit(cache=True)
def fold(d, box):
    """Minimum-image offset (box <= 0: unchanged)."""
    if box > 0.0:
        return d - box * np.floor(d / box + 0.5)
    return d


# ---------------------------------------------------------------------------------------------------
# neighbour graph


@njit(cache=True)
def graph_frame(p, pattern, radius, box, nbr, queue, comp, sizes, rank,
                labels, unwrapped, nn, degree, same):
    """Neighbour graph of one record p (N, 3); returns the number of groups.

    Scratch: nbr (N, N) int32, queue, comp, rank (N,) int32, sizes (N,) int64. Fills labels (group
    rank, 0 = largest, ties by lowest member index), unwrapped (N, 3), nn (nearest-neighbour distance,
    nan for N = 1), degree and same (links, and links to the same pattern)."""
    n = p.shape[0]
    radius2 = radius * radius
    for i in range(n):
        degree[i] = 0
        same[i] = 0
        nn[i] = np.inf
    for i in range(n):
        xi, yi, zi = p[i, 0], p[i, 1], p[i, 2]
        best = nn[i]
        for j in range(i + 1, n):
            dx = p[j, 0] - xi
            dy = p[j, 1] - yi
            dz = p[j, 2] - zi
            if box > 0.0:
                dx = fold(dx, box)
                dy = fold(dy, box)
                dz = fold(dz, box)
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < best:
                best = r2
            if r2 < nn[j]:
                nn[j] = r2
            if r2 < radius2:
                nbr[i, degree[i]] = j
                degree[i] += 1
                nbr[j, degree[j]] = i
                degree[j] += 1
                if pattern[i] == pattern[j]:
                    same[i] += 1
                    same[j] += 1
        nn[i] = best
    for i in range(n):
        nn[i] = np.sqrt(nn[i]) if nn[i] < np.inf else np.nan
    # connected components: breadth-first search from the lowest unvisited index; in a periodic box
    # each boid is placed at its tree parent plus their minimum-image offset
    for i in range(n):
        comp[i] = -1
    count = 0
    for s in range(n):
        if comp[s] >= 0:
            continue
        comp[s] = count
        for k in range(3):
            unwrapped[s, k] = p[s, k]
        head = 0
        tail = 1
        queue[0] = s
        while head < tail:
            u = queue[head]
            head += 1
            for a in range(degree[u]):
                v = nbr[u, a]
                if comp[v] >= 0:
                    continue
                comp[v] = count
                for k in range(3):
                    if box > 0.0:
                        unwrapped[v, k] = unwrapped[u, k] + fold(p[v, k] - p[u, k], box)
                    else:
                        unwrapped[v, k] = p[v, k]
                queue[tail] = v
                tail += 1
        sizes[count] = tail
        count += 1
    order = np.argsort(-sizes[:count], kind="mergesort")  # stable: ties keep discovery order
    for r in range(count):
        rank[order[r]] = r
    for i in range(n):
        labels[i] = rank[comp[i]]
    return count


@njit(cache=True)
def graph_run(pos, pattern, radius, box, labels, unwrapped, nn, degree, same, n_groups):
    """graph_frame for every record of pos (R, N, 3)."""
    n = pos.shape[1]
    nbr = np.empty((n, n), np.int32)
    queue = np.empty(n, np.int32)
    comp = np.empty(n, np.int32)
    sizes = np.empty(n, np.int64)
    rank = np.empty(n, np.int32)
    for f in range(pos.shape[0]):
        n_groups[f] = graph_frame(pos[f], pattern, radius, box, nbr, queue, comp, sizes, rank,
                                  labels[f], unwrapped[f], nn[f], degree[f], same[f])


# ---------------------------------------------------------------------------------------------------
# metrics of one record


@njit(cache=True)
def unit(v, out):
    """out = v/|v| (zeros when |v| = 0); returns whether |v| > 0."""
    s = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if s > 0.0:
        for k in range(3):
            out[k] = v[k] / s
        return True
    for k in range(3):
        out[k] = 0.0
    return False


@njit(cache=True)
def polarization_frame(vel, mask):
    """|mean unit heading| over the moving boids with mask true (nan when none)."""
    total = np.zeros(3)
    h = np.empty(3)
    count = 0
    for i in range(vel.shape[0]):
        if mask[i] and unit(vel[i], h):
            count += 1
            for k in range(3):
                total[k] += h[k]
    if count == 0:
        return np.nan
    return np.sqrt(total[0] ** 2 + total[1] ** 2 + total[2] ** 2) / count


@njit(cache=True)
def milling_frame(p, vel, box):
    """|mean_i r_hat_i x v_hat_i|, r_i = p_i - flock centroid (periodic: unwrapped around boid 0);
    boids at the centroid or stopped are left out (nan when none is left)."""
    n = p.shape[0]
    u = np.empty((n, 3))
    c = np.zeros(3)
    for i in range(n):
        for k in range(3):
            u[i, k] = p[0, k] + fold(p[i, k] - p[0, k], box) if box > 0.0 else p[i, k]
            c[k] += u[i, k]
    for k in range(3):
        c[k] /= n
    total = np.zeros(3)
    r = np.empty(3)
    rh = np.empty(3)
    vh = np.empty(3)
    count = 0
    for i in range(n):
        for k in range(3):
            r[k] = u[i, k] - c[k]
        if unit(r, rh) and unit(vel[i], vh):
            count += 1
            total[0] += rh[1] * vh[2] - rh[2] * vh[1]
            total[1] += rh[2] * vh[0] - rh[0] * vh[2]
            total[2] += rh[0] * vh[1] - rh[1] * vh[0]
    if count == 0:
        return np.nan
    return np.sqrt(total[0] ** 2 + total[1] ** 2 + total[2] ** 2) / count


@njit(cache=True)
def speed_frame(vel):
    """(mean speed, sd/mean of the speeds with population sd; cv nan when the mean is 0)."""
    n = vel.shape[0]
    s = np.empty(n)
    total = 0.0
    for i in range(n):
        s[i] = np.sqrt(vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
        total += s[i]
    mean = total / n
    var = 0.0
    for i in range(n):
        var += (s[i] - mean) ** 2
    sd = np.sqrt(var / n)
    return mean, (sd / mean if mean > 0.0 else np.nan)


@njit(cache=True)
def _range_along(x, mask, axis):
    lo = np.inf
    hi = -np.inf
    for i in range(x.shape[0]):
        if mask[i]:
            t = x[i, 0] * axis[0] + x[i, 1] * axis[1] + x[i, 2] * axis[2]
            lo = min(lo, t)
            hi = max(hi, t)
    return hi - lo


@njit(cache=True)
def _quadratic(g, u, v):
    """u^T g v for 3-vectors."""
    total = 0.0
    for i in range(3):
        for j in range(3):
            total += u[i] * g[i, j] * v[j]
    return total


@njit(cache=True)
def shape_frame(points, vel, mask):
    """(gyration radius, elongation, aspect_heading, elongation_heading) of the boids with mask true;
    points unwrapped.

    G = mean x x^T with x = p - centroid, eigenvalues l1 >= l2 >= l3. Gyration radius sqrt(trace G);
    elongation sqrt(l1/l2), nan below 3 boids or when l2 <= TINY l1. Aspect: h = normalised sum of
    unit headings of the moving selected boids; extent = range of x.h; width = range of x.e with e the
    major axis of G restricted to the plane perpendicular to h (the top eigenvector of P G P,
    P = I - h h^T, found in an orthonormal basis of that plane); extent/width, nan when no heading
    (|sum| <= TINY count) or width <= TINY extent. Elongation along the heading: sqrt(h^T G h / m)
    with m the top eigenvalue of P G P (the largest second moment across h); nan below 3 boids, without
    a heading, or when m <= TINY h^T G h."""
    n = points.shape[0]
    c = np.empty(3)
    count = masked_mean(points, mask, c)
    if count == 0:
        return np.nan, np.nan, np.nan, np.nan
    x = np.empty((n, 3))
    g = np.zeros((3, 3))
    for i in range(n):
        for k in range(3):
            x[i, k] = points[i, k] - c[k]
        if mask[i]:
            for a in range(3):
                for b in range(3):
                    g[a, b] += x[i, a] * x[i, b]
    g /= count
    radius = np.sqrt(max(g[0, 0] + g[1, 1] + g[2, 2], 0.0))
    w = np.linalg.eigvalsh(g)  # ascending
    l1, l2 = w[2], w[1]
    elong = np.sqrt(l1 / l2) if count >= 3 and l2 > 0.0 and l2 > TINY * l1 else np.nan

    total = np.zeros(3)
    hv = np.empty(3)
    moving = 0
    for i in range(n):
        if mask[i] and unit(vel[i], hv):
            moving += 1
            for k in range(3):
                total[k] += hv[k]
    norm = np.sqrt(total[0] ** 2 + total[1] ** 2 + total[2] ** 2)
    if moving == 0 or norm <= TINY * moving:
        return radius, elong, np.nan, np.nan
    h = total / norm
    extent = _range_along(x, mask, h)
    # orthonormal basis (a, b) of the plane perpendicular to h, then the major axis of the 2-D
    # gyration tensor there: angle 0.5 atan2(2 G_ab, G_aa - G_bb) from a
    ref = np.zeros(3)
    ref[np.argmin(np.abs(h))] = 1.0
    a = np.cross(h, ref)
    a /= np.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
    b = np.cross(h, a)
    gaa = _quadratic(g, a, a)
    gbb = _quadratic(g, b, b)
    gab = _quadratic(g, a, b)
    angle = 0.5 * np.arctan2(2.0 * gab, gaa - gbb)
    e = np.cos(angle) * a + np.sin(angle) * b
    width = _range_along(x, mask, e)
    aspect = extent / width if width > 0.0 and width > TINY * extent else np.nan
    along = _quadratic(g, h, h)
    across = 0.5 * (gaa + gbb) + np.sqrt(0.25 * (gaa - gbb) ** 2 + gab * gab)  # top eigenvalue in the plane
    elong_heading = np.sqrt(along / across) if count >= 3 and across > 0.0 and across > TINY * along else np.nan
    return radius, elong, aspect, elong_heading


@njit(cache=True)
def segregation_frame(degree, same, expected):
    """mean over linked boids of same_i/degree_i - expected_i (nan when no boid is linked)."""
    total = 0.0
    count = 0
    for i in range(degree.shape[0]):
        if degree[i] > 0:
            total += same[i] / degree[i] - expected[i]
            count += 1
    return total / count if count > 0 else np.nan


@njit(cache=True)
def group_headings(vel, labels, count, hsum, moving, head, ok):
    """head[i] = h_g, the normalised sum of the unit headings of the moving boids of i's group g
    (labels < count); ok[i] false when g has no heading (no boid of g moves, or |sum| <= TINY x
    movers). Scratch: hsum (N, 3), moving (N,)."""
    n = vel.shape[0]
    hv = np.empty(3)
    for g in range(count):
        moving[g] = 0
        for k in range(3):
            hsum[g, k] = 0.0
    for i in range(n):
        if unit(vel[i], hv):
            g = labels[i]
            moving[g] += 1
            for k in range(3):
                hsum[g, k] += hv[k]
    for i in range(n):
        g = labels[i]
        norm = np.sqrt(hsum[g, 0] ** 2 + hsum[g, 1] ** 2 + hsum[g, 2] ** 2)
        ok[i] = moving[g] > 0 and norm > TINY * moving[g]
        for k in range(3):
            head[i, k] = hsum[g, k] / norm if ok[i] else 0.0


@njit(cache=True)
def count_overtakes(p, p_before, nbr, degree, head, ok, head_before, ok_before, radius, box):
    """Pairs linked now (nbr, degree) and at the previous record (closer than ``radius`` in
    ``p_before``, tested as :func:`graph_frame` links) whose order along their group's heading swapped
    strictly: (p_i - p_j) . h_g changed sign between the two records (each record with its own
    positions and heading, minimum-image offsets)."""
    radius2 = radius * radius
    swaps = 0
    for i in range(degree.shape[0]):
        if not (ok[i] and ok_before[i]):
            continue
        h0, h1, h2 = head[i, 0], head[i, 1], head[i, 2]
        b0, b1, b2 = head_before[i, 0], head_before[i, 1], head_before[i, 2]
        for a in range(degree[i]):
            j = nbr[i, a]
            if j <= i:
                continue
            dx = p_before[j, 0] - p_before[i, 0]
            dy = p_before[j, 1] - p_before[i, 1]
            dz = p_before[j, 2] - p_before[i, 2]
            if box > 0.0:
                dx = fold(dx, box)
                dy = fold(dy, box)
                dz = fold(dz, box)
            if not dx * dx + dy * dy + dz * dz < radius2:
                continue
            ex = p_before[i, 0] - p_before[j, 0]
            ey = p_before[i, 1] - p_before[j, 1]
            ez = p_before[i, 2] - p_before[j, 2]
            nx = p[i, 0] - p[j, 0]
            ny = p[i, 1] - p[j, 1]
            nz = p[i, 2] - p[j, 2]
            if box > 0.0:
                ex = fold(ex, box)
                ey = fold(ey, box)
                ez = fold(ez, box)
                nx = fold(nx, box)
                ny = fold(ny, box)
                nz = fold(nz, box)
            before = ex * b0 + ey * b1 + ez * b2
            now = nx * h0 + ny * h1 + nz * h2
            if (before < 0.0 and now > 0.0) or (before > 0.0 and now < 0.0):
                swaps += 1
    return swaps



# ---------------------------------------------------------------------------------------------------
# observables of collective motion (docs/metrics.md "Observables of collective motion")


@njit(cache=True)
def _bearing_terms(d, h):
    """(ahead, bearing in degrees, cos^2 of the bearing) of offset d seen from unit heading h:
    ahead 1 when d.h > 0, 0.5 when d.h = 0, 0 behind; the bearing is the angle between d and h,
    atan2(|d x h|, d.h), in [0, 180]."""
    along = d[0] * h[0] + d[1] * h[1] + d[2] * h[2]
    cx = d[1] * h[2] - d[2] * h[1]
    cy = d[2] * h[0] - d[0] * h[2]
    cz = d[0] * h[1] - d[1] * h[0]
    across = np.sqrt(cx * cx + cy * cy + cz * cz)
    ahead = 1.0 if along > 0.0 else (0.5 if along == 0.0 else 0.0)
    angle = np.degrees(np.arctan2(across, along))
    norm2 = along * along + across * across
    return ahead, angle, (along * along / norm2 if norm2 > 0.0 else np.nan)   # 0: values past overflow


@njit(cache=True)
def focal_neighbours_frame(p, vel, box, k, pairwise, dist, order, out):
    """Where the neighbours sit in each moving individual's frame (its unit heading h_i), one record.

    For every moving i, the others j != i at a distance > 0 (minimum image) are ranked by distance (ties:
    lower index first); the nearest gives i's nearest-neighbour terms, the min(k, count) nearest its
    k-nearest terms (with ``pairwise`` only). out[0:3] = means over moving i with a neighbour of (ahead,
    bearing_deg, cos^2 bearing) of the nearest; out[3:6] the same over every (i, one of its k nearest)
    pair; nan when there is no term. Scratch: dist (N,) float, order (N,) int64 (the ranked few)."""
    n = p.shape[0]
    for c in range(6):
        out[c] = 0.0
    focal = 0
    pairs = 0
    h = np.empty(3)
    d = np.empty(3)
    for i in range(n):
        if not unit(vel[i], h):
            continue
        size = min(k, n - 1) if pairwise else 1
        kept = 0
        # the `size` nearest, kept sorted by an insertion that moves only past strictly larger distances,
        # so with j visited in index order equal distances keep the lower index first
        for j in range(n):
            if j == i:
                continue
            dx = p[j, 0] - p[i, 0]
            dy = p[j, 1] - p[i, 1]
            dz = p[j, 2] - p[i, 2]
            if box > 0.0:
                dx = fold(dx, box)
                dy = fold(dy, box)
                dz = fold(dz, box)
            r2 = dx * dx + dy * dy + dz * dz
            if not r2 > 0.0 or (kept == size and not r2 < dist[kept - 1]):
                continue
            at = kept if kept < size else size - 1
            while at > 0 and dist[at - 1] > r2:
                dist[at] = dist[at - 1]
                order[at] = order[at - 1]
                at -= 1
            dist[at] = r2
            order[at] = j
            if kept < size:
                kept += 1
        if kept == 0:
            continue
        for a in range(kept):
            j = order[a]
            d[0] = p[j, 0] - p[i, 0]
            d[1] = p[j, 1] - p[i, 1]
            d[2] = p[j, 2] - p[i, 2]
            if box > 0.0:
                for c in range(3):
                    d[c] = fold(d[c], box)
            ahead, angle, axial = _bearing_terms(d, h)
            if a == 0:
                out[0] += ahead
                out[1] += angle
                out[2] += axial
            if pairwise:
                out[3] += ahead
                out[4] += angle
                out[5] += axial
        focal += 1
        pairs += kept
    for c in range(3):
        out[c] = out[c] / focal if focal > 0 else np.nan
        out[3 + c] = out[3 + c] / pairs if pairwise and pairs > 0 else np.nan


@njit(cache=True)
def distance_order(key, m, order):
    """order[:m] = the indices 0..m-1 sorted by key[:m] (ascending; equal keys in any order): a bucket sort
    (about m / 4 buckets spaced evenly between the smallest and largest key, each sorted by insertion, or
    by a merge sort above 32 entries), several times faster than an argsort for the pairs of a group."""
    lo = key[0]
    hi = key[0]
    for a in range(m):
        if key[a] < lo:
            lo = key[a]
        if key[a] > hi:
            hi = key[a]
    if not hi > lo:
        for a in range(m):
            order[a] = a
        return
    buckets = max(1, m // 4)
    scale = buckets / (hi - lo)
    start = np.zeros(buckets + 1, np.int64)
    slot = np.empty(m, np.int64)
    for a in range(m):
        b = min(int((key[a] - lo) * scale), buckets - 1)   # monotone in the key: a larger key, no earlier bucket
        slot[a] = b
        start[b + 1] += 1
    for b in range(buckets):
        start[b + 1] += start[b]
    fill = start[:buckets].copy()
    for a in range(m):
        order[fill[slot[a]]] = a
        fill[slot[a]] += 1
    for b in range(buckets):
        first, stop = start[b], start[b + 1]
        if stop - first <= 32:
            for x in range(first + 1, stop):
                item = order[x]
                y = x
                while y > first and key[order[y - 1]] > key[item]:
                    order[y] = order[y - 1]
                    y -= 1
                order[y] = item
        else:
            members = order[first:stop].copy()
            ranked = np.argsort(key[members], kind="mergesort")
            for x in range(stop - first):
                order[first + x] = members[ranked[x]]


@njit(cache=True)
def correlation_length_frame(points, vel, mask, dist, prod):
    """Correlation length of the velocity fluctuations of the boids with mask true (points unwrapped).

    dv_i = v_i - mean v over the selection; for the pairs i < j of the selection, S(r) = sum of
    dv_i.dv_j over the pairs with |x_i - x_j| <= r; the length is the smallest r where S reaches its
    largest value, S(0) = 0 included (0 when no S(r) is above 0). In the limit of many pairs that is the
    first zero of the correlation function C(r) (Cavagna et al. 2010). nan below 2 boids or when the
    fluctuations vanish (sum |dv|^2 <= TINY^2 sum |v|^2). Scratch: dist, prod (N (N - 1) / 2,)."""
    n = points.shape[0]
    mean = np.empty(3)
    count = masked_mean(vel, mask, mean)
    if count < 2:
        return np.nan
    total = 0.0
    scale = 0.0
    for i in range(n):
        if mask[i]:
            for c in range(3):
                total += (vel[i, c] - mean[c]) ** 2
                scale += vel[i, c] ** 2
    if not total > TINY * TINY * scale:
        return np.nan
    m = 0
    for i in range(n):
        if not mask[i]:
            continue
        for j in range(i + 1, n):
            if not mask[j]:
                continue
            dx = points[j, 0] - points[i, 0]
            dy = points[j, 1] - points[i, 1]
            dz = points[j, 2] - points[i, 2]
            dist[m] = dx * dx + dy * dy + dz * dz   # squared: the same order, one root at the end
            prod[m] = ((vel[i, 0] - mean[0]) * (vel[j, 0] - mean[0]) + (vel[i, 1] - mean[1]) * (vel[j, 1] - mean[1])
                       + (vel[i, 2] - mean[2]) * (vel[j, 2] - mean[2]))
            m += 1
    order = np.empty(m, np.int64)
    distance_order(dist, m, order)
    running = 0.0
    best = 0.0
    length = 0.0
    for a in range(m):
        running += prod[order[a]]
        if a + 1 < m and dist[order[a + 1]] == dist[order[a]]:
            continue   # S(r) counts every pair at distance <= r: equal distances enter together
        if running > best:
            best = running
            length = dist[order[a]]
    return np.sqrt(length)


@njit(cache=True)
def _mean_over(values, order, start, stop):
    total = 0.0
    for a in range(start, stop):
        total += values[order[a]]
    return total / (stop - start)


@njit(cache=True)
def spacing_profile_frame(points, vel, mask, nn, key):
    """(edge_spacing_ratio, front_spacing_ratio) of the boids with mask true (points unwrapped; nn each
    boid's nearest-neighbour distance). With x_i = p_i - centroid, m = floor(n / 2): the mean nn of the m
    boids farthest from the centroid over that of the m nearest, and the mean nn of the m boids most ahead
    along the heading h (normalised sum of the unit headings of the moving selected boids) over that of
    the m most behind; ranks by a stable sort (ties: lower index first). nan below 4 boids, when the
    denominator is 0, and (front) without a heading. Scratch: key (N,)."""
    n = points.shape[0]
    c = np.empty(3)
    count = masked_mean(points, mask, c)
    if count < 4:
        return np.nan, np.nan
    members = np.empty(count, np.int64)
    m = 0
    for i in range(n):
        if mask[i]:
            members[m] = i
            m += 1
    half = count // 2
    for a in range(count):
        i = members[a]
        key[a] = np.sqrt((points[i, 0] - c[0]) ** 2 + (points[i, 1] - c[1]) ** 2 + (points[i, 2] - c[2]) ** 2)
    rank = np.argsort(key[:count], kind="mergesort")
    spacing = np.empty(count)
    for a in range(count):
        spacing[a] = nn[members[a]]
    inner = _mean_over(spacing, rank, 0, half)
    edge = _mean_over(spacing, rank, count - half, count) / inner if inner > 0.0 else np.nan
    total = np.zeros(3)
    hv = np.empty(3)
    moving = 0
    for a in range(count):
        if unit(vel[members[a]], hv):
            moving += 1
            for b in range(3):
                total[b] += hv[b]
    norm = np.sqrt(total[0] ** 2 + total[1] ** 2 + total[2] ** 2)
    if moving == 0 or norm <= TINY * moving:
        return edge, np.nan
    for a in range(count):
        i = members[a]
        key[a] = ((points[i, 0] - c[0]) * total[0] + (points[i, 1] - c[1]) * total[1]
                  + (points[i, 2] - c[2]) * total[2]) / norm
    rank = np.argsort(key[:count], kind="mergesort")
    back = _mean_over(spacing, rank, 0, half)
    front = _mean_over(spacing, rank, count - half, count) / back if back > 0.0 else np.nan
    return edge, front

# ---------------------------------------------------------------------------------------------------
# the whole table


@njit(cache=True)
def frame_kernel(pos, vel, visible, binocular, have_visible, pattern, expected, radius, box, interval, k_nearest,
                 pairwise, out):
    """out (R, len(COLUMNS)): every metric of every record, column ``Column.<name>``.

    ``overtake_rate`` of record f counts the overtakes between records f - 1 and f per boid per
    ``interval`` seconds (the time between records); nan at f = 0 and when interval <= 0. ``k_nearest``:
    the k of the ``knn_*`` columns; ``pairwise`` false leaves the columns that rank every pair (``knn_*``,
    ``corr_length``) nan."""
    n_frames, n = pos.shape[0], pos.shape[1]
    nbr = np.empty((n, n), np.int32)
    queue = np.empty(n, np.int32)
    comp = np.empty(n, np.int32)
    sizes = np.empty(n, np.int64)
    rank = np.empty(n, np.int32)
    labels = np.empty(n, np.int32)
    unwrapped = np.empty((n, 3))
    nn = np.empty(n)
    degree = np.empty(n, np.int32)
    same = np.empty(n, np.int32)
    everyone = np.ones(n, np.bool_)
    largest = np.empty(n, np.bool_)
    hsum = np.empty((n, 3))
    movers = np.empty(n, np.int64)
    head = np.empty((n, 3))
    ok = np.empty(n, np.bool_)
    head_before = np.zeros((n, 3))
    ok_before = np.zeros(n, np.bool_)
    dist = np.empty(n)
    order = np.empty(n, np.int64)
    focal = np.empty(6)
    pair_dist = np.empty(n * (n - 1) // 2)
    pair_prod = np.empty(n * (n - 1) // 2)
    for f in range(n_frames):
        count = graph_frame(pos[f], pattern, radius, box, nbr, queue, comp, sizes, rank,
                            labels, unwrapped, nn, degree, same)
        in_largest = 0
        strays = 0
        nn_total = 0.0
        for i in range(n):
            largest[i] = labels[i] == 0
            in_largest += largest[i]
            strays += degree[i] == 0
            nn_total += nn[i]
        out[f, Column.polarization] = polarization_frame(vel[f], everyone)
        out[f, Column.polarization_largest] = polarization_frame(vel[f], largest)
        out[f, Column.milling] = milling_frame(pos[f], vel[f], box)
        out[f, Column.n_groups] = count
        out[f, Column.cohesion] = in_largest / n
        out[f, Column.stray_fraction] = strays / n
        out[f, Column.nn_distance] = nn_total / n
        (out[f, Column.gyration_radius], out[f, Column.elongation], out[f, Column.aspect_heading],
         out[f, Column.elongation_heading]) = shape_frame(unwrapped, vel[f], largest)
        out[f, Column.speed_mean], out[f, Column.speed_cv] = speed_frame(vel[f])
        if have_visible:
            seen = 0.0
            both = 0.0
            for i in range(n):
                seen += visible[f, i]
                both += binocular[f, i]
            spread = 0.0
            for i in range(n):
                spread += (visible[f, i] - seen / n) ** 2
            out[f, Column.visible_mean] = seen / n
            out[f, Column.visible_sd] = np.sqrt(spread / n)
            out[f, Column.binocular_share] = both / seen if seen > 0 else 0.0
        else:
            out[f, Column.visible_mean] = np.nan
            out[f, Column.visible_sd] = np.nan
            out[f, Column.binocular_share] = np.nan
        out[f, Column.segregation] = segregation_frame(degree, same, expected)
        out[f, Column.overtake_rate] = np.nan
        if interval > 0.0:
            group_headings(vel[f], labels, count, hsum, movers, head, ok)
            if f > 0:
                swaps = count_overtakes(pos[f], pos[f - 1], nbr, degree, head, ok, head_before, ok_before,
                                        radius, box)
                out[f, Column.overtake_rate] = swaps / n / interval
            for i in range(n):
                ok_before[i] = ok[i]
                for k in range(3):
                    head_before[i, k] = head[i, k]
        focal_neighbours_frame(pos[f], vel[f], box, k_nearest, pairwise, dist, order, focal)
        out[f, Column.nn_ahead_fraction] = focal[0]
        out[f, Column.nn_bearing_deg] = focal[1]
        out[f, Column.nn_anisotropy] = focal[2]
        out[f, Column.knn_ahead_fraction] = focal[3]
        out[f, Column.knn_bearing_deg] = focal[4]
        out[f, Column.knn_anisotropy] = focal[5]
        out[f, Column.corr_length] = (correlation_length_frame(unwrapped, vel[f], largest, pair_dist, pair_prod)
                                      if pairwise else np.nan)
        out[f, Column.edge_spacing_ratio], out[f, Column.front_spacing_ratio] = \
            spacing_profile_frame(unwrapped, vel[f], largest, nn, dist)
