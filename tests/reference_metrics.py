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
