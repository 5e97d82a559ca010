"""Slow, plain numpy twins of the compiled analysis kernels and of ``simcore.rng.hash4``.

Written from the definitions (docs/metrics.md, the docstrings of ``observables.metrics``,
``observables.leadership`` and ``simcore.rng``), not from the kernels: whole-array numpy where
it is the obvious formula, Python loops where the definition is a loop, Python integers for the hash.
Not meant to be fast.
"""
from __future__ import annotations

import numpy as np

TINY = 1e-12
MASK64 = (1 << 64) - 1
GOLDEN = 0x9E3779B97F4A7C15
M1 = 0xBF58476D1CE4E5B9
M2 = 0x94D049BB133111EB


# -------------------------------------------------------------------------------------------- geometry

def offsets(pos: np.ndarray, box: float | None) -> np.ndarray:
    """(N, N, 3) offsets p_j - p_i, folded to the minimum image in a periodic box."""
    d = pos[None, :, :] - pos[:, None, :]
    return d if box is None else d - box * np.floor(d / box + 0.5)


def units(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(v/|v| with zeros where |v| = 0, |v| > 0)."""
    length = np.linalg.norm(v, axis=-1)
    moving = length > 0
    out = np.zeros_like(v)
    out[moving] = v[moving] / length[moving, None]
    return out, moving


def components(pos: np.ndarray, radius: float, box: float | None) -> np.ndarray:
    """Group label of each boid: 0 the largest group, ties by the lowest member index (union-find)."""
    n = len(pos)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    linked = np.linalg.norm(offsets(pos, box), axis=-1) < radius
    for i in range(n):
        for j in range(i + 1, n):
            if linked[i, j]:
                parent[find(j)] = find(i)
    roots = [find(i) for i in range(n)]
    members = {}
    for i, root in enumerate(roots):
        members.setdefault(root, []).append(i)
    ranked = sorted(members.values(), key=lambda group: (-len(group), min(group)))
    labels = np.empty(n, np.int64)
    for rank, group in enumerate(ranked):
        labels[group] = rank
    return labels


# ---------------------------------------------------------------------------------------------- metrics

def shape(points: np.ndarray, vel: np.ndarray, mask: np.ndarray) -> tuple[float, float, float, float]:
    """(gyration radius, elongation, aspect_heading, elongation_heading) of the selected boids of
    contiguous points."""
    if not mask.any():
        return np.nan, np.nan, np.nan, np.nan
    x = points[mask] - points[mask].mean(axis=0)
    gyration = x.T @ x / len(x)
    radius = float(np.sqrt(max(np.trace(gyration), 0.0)))
    values = np.linalg.eigvalsh(gyration)
    l1, l2 = values[2], values[1]
    elongation = float(np.sqrt(l1 / l2)) if len(x) >= 3 and l2 > 0 and l2 > TINY * l1 else np.nan
    heading, moving = units(vel[mask])
    total = heading.sum(axis=0)
    norm = np.linalg.norm(total)
    if not moving.any() or norm <= TINY * moving.sum():
        return radius, elongation, np.nan, np.nan
    h = total / norm
    extent = np.ptp(x @ h)
    across = np.eye(3) - np.outer(h, h)
    values, vectors = np.linalg.eigh(across @ gyration @ across)
    major = vectors[:, -1]                                          # the restricted gyration's major axis
    width = np.ptp(x @ major)
    aspect = float(extent / width) if width > 0 and width > TINY * extent else np.nan
    along, widest = h @ gyration @ h, values[-1]                    # second moments along h, and across it
    stretched = float(np.sqrt(along / widest)) if len(x) >= 3 and widest > 0 and widest > TINY * along else np.nan
    return radius, elongation, aspect, stretched


def overtakes(pos: np.ndarray, vel: np.ndarray, radius: float, interval: float, box: float | None = None) -> np.ndarray:
    """Overtakes per boid per second between consecutive records (R, N, 3): pairs closer than the radius
    at records r - 1 and r whose order along their group's heading swaps; nan at r = 0."""
    n_records, n = pos.shape[:2]
    out = np.full(n_records, np.nan)

    def order(r):
        """(linked (N, N), signed separation along the group's heading (N, N): (p_i - p_j).h, usable)."""
        d = offsets(pos[r], box)                       # d[i, j] = p_j - p_i (minimum image)
        linked = np.linalg.norm(d, axis=-1) < radius
        np.fill_diagonal(linked, False)
        labels = components(pos[r], radius, box)
        heads, moving = units(vel[r])
        ahead = np.zeros((n, n))
        usable = np.zeros(n, bool)
        for g in np.unique(labels):
            members = labels == g
            total = heads[members].sum(axis=0)
            movers = moving[members].sum()
            if movers and np.linalg.norm(total) > TINY * movers:
                usable[members] = True
                h = total / np.linalg.norm(total)
                ahead[np.ix_(members, members)] = -(d[np.ix_(members, members)] @ h)
        return linked, ahead, usable

    before = order(0)
    for r in range(1, n_records):
        now = order(r)
        both = before[0] & now[0] & np.outer(before[2] & now[2], before[2] & now[2])
        swapped = np.sign(before[1]) * np.sign(now[1]) < 0
        out[r] = np.triu(both & swapped, 1).sum() / n / interval
        before = now
    return out


def milling(pos: np.ndarray, vel: np.ndarray, box: float | None = None) -> float:
    """|mean r_hat x v_hat| about the centroid of the flock unwrapped around boid 0."""
    unwrapped = pos[0] + offsets(pos, box)[0]
    r_hat, at_centroid_not = units(unwrapped - unwrapped.mean(axis=0))
    v_hat, moving = units(vel)
    keep = at_centroid_not & moving
    if not keep.any():
        return np.nan
    return float(np.linalg.norm(np.cross(r_hat[keep], v_hat[keep]).mean(axis=0)))


def segregation(pos: np.ndarray, pattern: np.ndarray, radius: float, box: float | None = None) -> float:
    """Mean over linked boids of (same-pattern share of their links - (n_p - 1)/(N - 1))."""
    n = len(pos)
    linked = np.linalg.norm(offsets(pos, box), axis=-1) < radius
    np.fill_diagonal(linked, False)
    degree = linked.sum(axis=1)
    same = (linked & (pattern[:, None] == pattern[None, :])).sum(axis=1)
    expected = np.array([(np.sum(pattern == p) - 1) / max(n - 1, 1) for p in pattern])
    has = degree > 0
    if not has.any():
        return np.nan
    return float(np.mean(same[has] / degree[has] - expected[has]))


def follow(times, vel, pos, triggers, dt, record_every, radius, escape, box=None, max_lag=2.0):
    """(C(tau) for tau = 0, dr, ..., max_lag; the lag-0 correlation over the window before the trigger),
    from the definition in observables.leadership's docstring."""
    interval = dt * record_every
    n_rec = len(times)
    window = int(np.floor(escape / interval + 1e-9))
    n_lags = int(np.floor(max_lag / interval + 1e-9)) + 1
    head, moving = units(vel)

    def pair(b, f, lead, foll, terms):
        values = [head[lead + s, b] @ head[foll + s, f] for s in range(terms)
                  if 0 <= lead + s < n_rec and 0 <= foll + s < n_rec and moving[lead + s, b] and moving[foll + s, f]]
        return np.mean(values) if values else None

    sums, pairs, before = np.zeros(n_lags), np.zeros(n_lags), []
    for step, b in triggers:
        r0 = int(np.clip(np.floor((step * dt - times[0]) / interval + 0.5), 0, n_rec - 1))
        labels = components(pos[r0], radius, box)
        for f in np.flatnonzero(labels == labels[b]):
            if f == b:
                continue
            for j in range(min(n_lags, window + 1)):
                c = pair(b, f, r0, r0 + j, window - j + 1)
                if c is not None:
                    sums[j] += c
                    pairs[j] += 1
            c = pair(b, f, r0 - window, r0 - window, window + 1)
            if c is not None:
                before.append(c)
    curve = np.full(n_lags, np.nan)
    curve[pairs > 0] = np.clip(sums[pairs > 0] / pairs[pairs > 0], -1, 1)
    return curve, (float(np.clip(np.mean(before), -1, 1)) if before else np.nan)


# ------------------------------------------------------------------------------------------------- rng

def mix(z: int) -> int:
    """SplitMix64's finaliser on a 64-bit integer."""
    z = ((z ^ (z >> 30)) * M1) & MASK64
    z = ((z ^ (z >> 27)) * M2) & MASK64
    return z ^ (z >> 31)


def hash4(key: int, stream: int, step: int, index: int) -> int:
    """The keyed chain of simcore.rng: mix(key + g), then mix(h ^ (x + g)) for stream, step, index."""
    h = mix((key + GOLDEN) & MASK64)
    for word in (stream, step, index):
        h = mix(h ^ ((word + GOLDEN) & MASK64))
    return h


def uniform01(key: int, stream: int, step: int, index: int) -> float:
    return (hash4(key, stream, step, index) >> 11) / 2.0 ** 53


# ------------------------------------------------------------------------- obstacles, predator, prey

def fold(d, box):
    return d if box is None else d - box * np.floor(d / box + 0.5)


def centre(frame: np.ndarray, box) -> np.ndarray:
    """Mean position of one record, the flock unwrapped around boid 0 in a periodic box."""
    return (frame[0] + fold(frame - frame[0], box)).mean(axis=0)


def first_time(times, hits) -> float:
    for t, hit in zip(times, hits):
        if hit:
            return float(t)
    return np.nan


def obstacle_metrics(pos, times, obstacles, body_radius, warmup):
    """(series, scalars) of docs/metrics.md's obstacle metrics, boid by boid and record by record."""
    from reference_obstacles import signed_distance

    n_records, n = pos.shape[:2]
    gap = np.array([[min(float(signed_distance(o, pos[r, i])[0]) for o in obstacles) - body_radius
                     for i in range(n)] for r in range(n_records)])
    hit = gap < 0
    series = {"collisions": hit.sum(axis=1).astype(float), "collision_fraction": hit.sum(axis=1) / n,
              "clearance": gap.min(axis=1)}
    collided, events, lowest, previous = set(), 0, np.inf, None
    for r in range(n_records):
        if times[r] < warmup:
            continue
        for i in range(n):
            if hit[r, i]:
                collided.add(i)
                if previous is None or not hit[previous, i]:
                    events += 1
            lowest = min(lowest, gap[r, i])
        previous = r
    return series, {"collided_boids": float(len(collided)), "collision_events": float(events),
                    "clearance_min": lowest if previous is not None else np.nan}


def predator_metrics(pos, predator, times, capture_radius, near_distance, group_radius, warmup, box=None):
    """(series, scalars) of docs/metrics.md's predator metrics, with nearest neighbours and groups
    computed here (``components``)."""
    n_records, n = pos.shape[:2]
    distance = np.array([[np.linalg.norm(fold(pos[r, i] - predator[r], box)) for i in range(n)]
                         for r in range(n_records)])
    near = np.array([np.linalg.norm(fold(centre(pos[r], box) - predator[r], box)) <= near_distance
                     for r in range(n_records)])
    gyration = []
    for r in range(n_records):
        points = pos[r, 0] + fold(pos[r] - pos[r, 0], box)
        c = points.mean(axis=0)
        gyration.append(np.sqrt(np.mean([np.sum((p - c) ** 2) for p in points])))
    nn = np.array([np.mean([min(np.linalg.norm(fold(pos[r, j] - pos[r, i], box)) for j in range(n) if j != i)
                            for i in range(n)]) for r in range(n_records)])
    groups = np.array([components(pos[r], group_radius, box).max() + 1 for r in range(n_records)], dtype=float)
    series = {"predator_distance": distance.min(axis=1), "predator_near": near.astype(float),
              "predator_in_capture": (distance <= capture_radius).sum(axis=1).astype(float),
              "flock_gyration_radius": np.array(gyration)}
    window = [r for r in range(n_records) if times[r] >= warmup]
    near_records = [r for r in window if near[r]]
    before = [r for r in window if not near_records or r < near_records[0]]

    def mean(values, records):
        picked = [values[r] for r in records]
        return float(np.mean(picked)) if picked else np.nan

    def ratio(values):
        top, bottom = mean(values, near_records), mean(values, before)
        return top / bottom if bottom and not np.isnan(bottom) else np.nan

    remerge = np.nan
    if near_records:
        leave = next((r for r in window if r > near_records[0] and not near[r]), None)
        if leave is not None:
            whole = next((r for r in window if r >= leave and groups[r] == 1), None)
            remerge = np.nan if whole is None else float(times[whole] - times[leave])
    captured = {i for r in window for i in range(n) if distance[r, i] <= capture_radius}
    scalars = {"predator_captures": float(len(captured)),
               "predator_distance_min": min(distance[r].min() for r in window) if window else np.nan,
               "flash_nn_ratio": ratio(nn), "flash_gyration_ratio": ratio(series["flock_gyration_radius"]),
               "groups_before_predator": mean(groups, before), "groups_near_predator": mean(groups, near_records),
               "groups_near_predator_max": max(groups[r] for r in near_records) if near_records else np.nan,
               "remerge_time": remerge}
    return series, scalars


def prey_metrics(pos, prey, times, reach, box=None):
    """(series, scalars) of docs/metrics.md's prey metrics."""
    n_records, n = pos.shape[:2]
    gap = np.array([np.linalg.norm(fold(centre(pos[r], box) - prey[r], box)) for r in range(n_records)])
    within = np.array([[np.linalg.norm(fold(pos[r, i] - prey[r], box)) <= reach for i in range(n)]
                       for r in range(n_records)])
    series = {"prey_distance": gap, "prey_within_fraction": within.sum(axis=1) / n}
    return series, {"prey_reach_time": first_time(times, gap <= reach),
                    "prey_first_reach_time": first_time(times, within.any(axis=1))}
# -------------------------------------------------------------------------------------------- migration

def migration_metrics(pos, vel, times, direction, warmup: float) -> dict:
    """Migratory progress and efficiency (docs/metrics.md), by loops over the records in the window."""
    kept = [r for r in range(len(times)) if times[r] >= warmup]
    if len(kept) < 2:
        return {"migratory_progress": float("nan"), "migratory_efficiency": float("nan")}
    first, last = kept[0], kept[-1]
    g = np.asarray(direction, dtype=float)
    centre_first = sum(pos[first][i] for i in range(pos.shape[1])) / pos.shape[1]
    centre_last = sum(pos[last][i] for i in range(pos.shape[1])) / pos.shape[1]
    progress = float(np.dot(centre_last - centre_first, g) / (times[last] - times[first]))
    speeds = [np.mean([np.sqrt(np.dot(v, v)) for v in vel[r]]) for r in kept]
    speed = float(np.mean(speeds))
    return {"migratory_progress": progress,
            "migratory_efficiency": progress / speed if speed > 0 else float("nan")}


# ------------------------------------------------------------------- observables of collective motion

def unwrapped_layout(pos: np.ndarray, radius: float, box: float | None) -> np.ndarray:
    """Each boid placed at its breadth-first parent's position plus their minimum-image offset (links
    closer than the radius, neighbours visited in index order, each group from its lowest index)."""
    if box is None:
        return pos.copy()
    n = len(pos)
    d = offsets(pos, box)
    linked = np.linalg.norm(d, axis=-1) < radius
    out = np.full_like(pos, np.nan)
    seen = np.zeros(n, bool)
    for start in range(n):
        if seen[start]:
            continue
        seen[start] = True
        out[start] = pos[start]
        queue = [start]
        while queue:
            u = queue.pop(0)
            for v in range(n):
                if v != u and linked[u, v] and not seen[v]:
                    seen[v] = True
                    out[v] = out[u] + d[u, v]
                    queue.append(v)
    return out


def bearing_terms(d: np.ndarray, h: np.ndarray) -> tuple[float, float, float]:
    """(ahead 1 / abeam 0.5 / behind 0, bearing in degrees, cos^2 of the bearing) of offset d from heading h."""
    along = float(d @ h)
    across = float(np.linalg.norm(np.cross(d, h)))
    ahead = 1.0 if along > 0 else (0.5 if along == 0 else 0.0)
    return ahead, float(np.degrees(np.arctan2(across, along))), along ** 2 / (along ** 2 + across ** 2)


def focal_neighbours(pos: np.ndarray, vel: np.ndarray, k: int, box: float | None = None) -> np.ndarray:
    """(nn_ahead_fraction, nn_bearing_deg, nn_anisotropy, knn_ahead_fraction, knn_bearing_deg,
    knn_anisotropy) of one record: every moving boid's neighbours, ranked by distance (ties: lower index),
    others at its exact position left out."""
    heads, moving = units(vel)
    d = offsets(pos, box)
    nearest, knearest = [], []
    for i in np.flatnonzero(moving):
        others = [j for j in range(len(pos)) if j != i and np.sum(d[i, j] ** 2) > 0]
        if not others:
            continue
        ranked = sorted(others, key=lambda j: (np.sum(d[i, j] ** 2), j))
        terms = [bearing_terms(d[i, j], heads[i]) for j in ranked[:k]]
        nearest.append(terms[0])
        knearest += terms
    first = np.mean(nearest, axis=0) if nearest else np.full(3, np.nan)
    every = np.mean(knearest, axis=0) if knearest else np.full(3, np.nan)
    return np.concatenate([first, every])


def correlation_length(points: np.ndarray, vel: np.ndarray, mask: np.ndarray) -> float:
    """argmin over r of the largest S(r) = sum over pairs closer than or at r of dv_i . dv_j (S(0) = 0)."""
    if mask.sum() < 2:
        return np.nan
    v = vel[mask]
    dv = v - v.mean(axis=0)
    if not np.sum(dv ** 2) > TINY ** 2 * np.sum(v ** 2):
        return np.nan
    x = points[mask]
    pairs = [(float(np.linalg.norm(x[j] - x[i])), float(dv[i] @ dv[j]))
             for i in range(len(x)) for j in range(i + 1, len(x))]
    best, length = 0.0, 0.0
    for r in sorted({r for r, _ in pairs}):
        total = sum(p for s, p in pairs if s <= r)
        if total > best:
            best, length = total, r
    return length


def spacing_profile(points: np.ndarray, vel: np.ndarray, mask: np.ndarray, nn: np.ndarray) -> tuple[float, float]:
    """(mean nn of the outer half / inner half by distance to the centroid, mean nn of the front half / back
    half along the heading) of the selected boids; halves of floor(n / 2), stable ranks."""
    members = np.flatnonzero(mask)
    n = len(members)
    if n < 4:
        return np.nan, np.nan
    half = n // 2
    x = points[members] - points[members].mean(axis=0)
    spacing = nn[members]

    def ratio(key):
        rank = np.argsort(key, kind="stable")
        low = spacing[rank[:half]].mean()
        return float(spacing[rank[-half:]].mean() / low) if low > 0 else np.nan

    edge = ratio(np.linalg.norm(x, axis=1))
    heads, moving = units(vel[members])
    total = heads.sum(axis=0)
    if not moving.any() or np.linalg.norm(total) <= TINY * moving.sum():
        return edge, np.nan
    return edge, ratio(x @ (total / np.linalg.norm(total)))


def motion_series(pos: np.ndarray, vel: np.ndarray, radius: float, k: int, box: float | None = None) -> dict:
    """The per-record observables of collective motion of one record (N, 3), by their definitions."""
    labels = components(pos, radius, box)
    largest = labels == 0
    layout = unwrapped_layout(pos, radius, box)
    distance = np.linalg.norm(offsets(pos, box), axis=-1)
    np.fill_diagonal(distance, np.inf)
    nn = distance.min(axis=1)
    values = focal_neighbours(pos, vel, k, box)
    edge, front = spacing_profile(layout, vel, largest, nn)
    names = ("nn_ahead_fraction", "nn_bearing_deg", "nn_anisotropy", "knn_ahead_fraction", "knn_bearing_deg",
             "knn_anisotropy")
    return {**dict(zip(names, values)), "corr_length": correlation_length(layout, vel, largest),
            "edge_spacing_ratio": edge, "front_spacing_ratio": front}


def decay_time(lags, corr) -> float:
    """The 1/e time of C (C(0) = 1): log-linear between the lags around the crossing (linear when a C there
    is <= 0); past the last lag, -tau / ln C(tau); nan lags skipped."""
    points = [(0.0, 1.0)] + [(float(t), float(c)) for t, c in zip(lags, corr) if np.isfinite(c)]
    for (t0, c0), (t1, c1) in zip(points, points[1:]):
        if c1 <= np.exp(-1.0):
            if c0 > 0 and c1 > 0:
                return t0 + (np.log(c0) + 1.0) / (np.log(c0) - np.log(c1)) * (t1 - t0)
            return t0 + (c0 - np.exp(-1.0)) / (c0 - c1) * (t1 - t0)
    if len(points) == 1:
        return np.nan
    t, c = points[-1]
    return -t / np.log(c) if c < 1 - 1e-9 else np.nan


def motion_metrics(vel, times, interval, warmup, polarization, milling, high=0.65, low=0.35) -> dict:
    """The per-run scalars of collective motion by loops over individuals and records (nan = not seen)."""
    kept = [r for r in range(len(times)) if times[r] >= warmup]
    n = vel.shape[1]
    speed = {(r, i): float(np.sqrt(vel[kept[r], i] @ vel[kept[r], i])) for r in range(len(kept)) for i in range(n)
             if np.isfinite(vel[kept[r], i]).all()}
    head = {key: vel[kept[key[0]], key[1]] / s for key, s in speed.items() if s > 0}
    lags = np.arange(1, (len(kept) - 1) // 2 + 1)
    turns = [np.degrees(np.arctan2(np.linalg.norm(np.cross(head[r, i], head[r + 1, i])), head[r, i] @ head[r + 1, i]))
             / interval for r in range(len(kept) - 1) for i in range(n) if (r, i) in head and (r + 1, i) in head]
    out = {}

    def lagged(values):
        """(J,) mean over (r, i) seen at r and r + j of values[r, i] . values[r + j, i]."""
        result = []
        for j in lags:
            terms = [float(np.dot(values[r, i], values[r + j, i])) for r in range(len(kept) - j) for i in range(n)
                     if (r, i) in values and (r + j, i) in values]
            result.append(np.mean(terms) if terms else np.nan)
        return np.array(result, dtype=float)

    out["heading_autocorr_time"] = decay_time(lags * interval, lagged(head))
    out["turn_rate_mean"] = float(np.mean(turns)) if turns else np.nan
    out["turn_rate_q10"] = float(np.quantile(turns, 0.1)) if turns else np.nan
    out["turn_rate_q50"] = float(np.quantile(turns, 0.5)) if turns else np.nan
    out["turn_rate_q90"] = float(np.quantile(turns, 0.9)) if turns else np.nan
    own = {i: np.mean([s for (r, j), s in speed.items() if j == i]) for i in range(n)
           if any(j == i for (_, j) in speed)}
    fluct = {(r, i): s - own[i] for (r, i), s in speed.items()}
    seen = np.array(list(speed.values()))
    mean_speed = seen.mean() if len(seen) else np.nan
    square = np.mean([f * f for f in fluct.values()]) if fluct else np.nan
    if fluct and square > (TINY * mean_speed) ** 2:
        out["speed_autocorr_time"] = decay_time(lags * interval, lagged(fluct) / square)
    else:
        out["speed_autocorr_time"] = np.nan
    for q in (10, 50, 90):
        out[f"speed_q{q}"] = float(np.quantile(seen, q / 100)) if len(seen) else np.nan
    out["speed_cv_pooled"] = float(seen.std() / mean_speed) if len(seen) and mean_speed > 0 else np.nan
    states = [(polarization[r], milling[r]) for r in kept if np.isfinite(polarization[r]) and np.isfinite(milling[r])]
    for name, test in (("swarming_fraction", lambda p, m: p < low and m < low),
                       ("polarized_fraction", lambda p, m: p > high and m < low),
                       ("milling_fraction", lambda p, m: m > high and p < low)):
        out[name] = float(np.mean([test(p, m) for p, m in states])) if states else np.nan
    return out
