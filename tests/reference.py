"""Slow, plain reference implementation of docs/model.md sections 0-3 (opensteer dynamics), and of the
topological perception (docs/model.md).

Written independently of ``simcore``'s kernel (only the parameter dataclasses are shared) so the
fast kernel can be checked against it step by step. Everything is float64, explicit Python loops
over boids, neighbours summed in ascending index order. Not meant to be fast.

Project decisions beyond the spec's text ("decision n" below) follow the kernel's: e.g. side
s = normalize(f x u), exact trig at multiples of 90 degrees, minimum-image offsets in a periodic box.
"""
from __future__ import annotations

import math

import numpy as np

from reference_hb import in_plane, planar_frame

RULES = ("separation", "alignment", "cohesion")


# small vector helpers
def dot3(a, b) -> float:
    """Dot product of two 3-vectors, summed x, y, z in that order."""
    return float(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


def norm3(v) -> float:
    return math.sqrt(dot3(v, v))


def normalize(v) -> np.ndarray:
    """docs/model.md section 3: normalize(0) = 0."""
    n = norm3(v)
    return v / n if n > 0 else np.zeros(3)


def truncate(v, max_length: float) -> np.ndarray:
    """Shorten v to max_length if it is longer (OpenSteer truncateLength)."""
    n = norm3(v)
    return v * (max_length / n) if n > max_length else v


def cos_deg(x: float) -> float:
    """cos of an angle in degrees, exact at multiples of 90 (decision 2)."""
    if x % 90.0 == 0.0:
        return (1.0, 0.0, -1.0, 0.0)[int(x // 90.0) % 4]
    return math.cos(math.radians(x))


def sin_deg(x: float) -> float:
    """sin of an angle in degrees, exact at multiples of 90 (decision 2)."""
    if x % 90.0 == 0.0:
        return (0.0, 1.0, 0.0, -1.0)[int(x // 90.0) % 4]
    return math.sin(math.radians(x))


def offset(p_i, p_j, box=None) -> np.ndarray:
    """d = p_j - p_i; minimum image in a periodic box of side ``box`` (docs/model.md section 0.4, decision 16)."""
    d = np.asarray(p_j, dtype=np.float64) - np.asarray(p_i, dtype=np.float64)
    if box is not None:
        d = d - box * np.floor(d / box + 0.5)
    return d


def similarity(b_i, b_j, n_bits: int) -> float:
    """Pattern similarity w_ij = (n - popcount(b_i xor b_j)) / n (docs/model.md section 3)."""
    return (n_bits - bin(int(b_i) ^ int(b_j)).count("1")) / n_bits


# perception (docs/model.md section 2)
def _result(sets: dict, labels: dict, hidden: list) -> dict:
    union = sorted(set(sets["separation"]) | set(sets["alignment"]) | set(sets["cohesion"]))
    out = {rule: sorted(sets[rule]) for rule in RULES}
    out.update(visible=union, labels=labels, hidden=sorted(hidden))
    return out


def perceive(i, pos, fwd, side, model, box=None) -> dict:
    """Neighbour sets of boid i (docs/model.md section 2 and its decisions in section 10). See module docstring for the keys."""
    per = model.perception
    offsets = {j: offset(pos[i], pos[j], box) for j in range(len(pos)) if j != i}

    if per.kind == "sphere":  # j != i with |d| < radius (squared compare)
        seen = [j for j, d in offsets.items() if dot3(d, d) < per.radius * per.radius]
        return _result({rule: seen for rule in RULES}, {}, [])

    if per.kind == "opensteer":  # per rule: inside near_radius, or within r and inside the cone
        f = fwd[i]
        sets = {}
        for rule in RULES:
            r = getattr(per, f"{rule}_radius")
            c = getattr(per, f"{rule}_cos")
            members = []
            for j, d in offsets.items():
                d2 = dot3(d, d)
                if d2 < per.near_radius * per.near_radius:
                    members.append(j)
                elif 0 < d2 <= r * r and dot3(f, d / math.sqrt(d2)) > c:
                    members.append(j)
            sets[rule] = members
        return _result(sets, {}, [])

    if per.kind == "topological":  # the k nearest eligible, ties by index (Ballerini et al. 2008)
        limit2 = math.inf if per.max_distance is None else per.max_distance * per.max_distance
        cos_half_blind = cos_deg(per.blind_deg / 2.0)
        ranked = []
        for j, d in offsets.items():
            d2 = dot3(d, d)
            if not d2 < limit2:
                continue
            if per.blind_deg > 0 and dot3(fwd[i], d) < -cos_half_blind * math.sqrt(d2):
                continue  # in the blind cone behind
            ranked.append((d2, j))
        chosen = [j for _, j in sorted(ranked)[:per.neighbours]]
        return _result({rule: chosen for rule in RULES}, {}, [])

    if per.kind != "binocular":
        raise ValueError(f"unknown perception kind {per.kind!r}")

    # Holland & Semwal binocular view phase: label bit 1 = left eye, bit 2 = right eye.
    f, s, h = fwd[i], side[i], per.head_radius
    alpha = per.direction_deg if per.eye_position_deg is None else per.eye_position_deg  # MODEL sec 2 default
    ca, sa = cos_deg(alpha), sin_deg(alpha)
    cd, sd = cos_deg(per.direction_deg), sin_deg(per.direction_deg)
    cos_half = cos_deg(per.field_deg / 2.0)
    eyes = ((1, h * (ca * f - sa * s), cd * f - sd * s),   # (bit, e_L - p_i, gaze a_L)
            (2, h * (ca * f + sa * s), cd * f + sd * s))   # (bit, e_R - p_i, gaze a_R)
    labels = {}
    for j, d in offsets.items():
        label = 0
        for bit, eye_offset, gaze in eyes:
            q = d - eye_offset  # p_j - e_E (minimum image through d in a periodic box)
            q2 = dot3(q, q)
            if 0 < q2 <= per.range * per.range and (
                    per.field_deg >= 360.0 or dot3(gaze, q) >= cos_half * math.sqrt(q2)):
                label |= bit
        if label:
            labels[j] = label

    # Perspective phase (decision 3): k hidden when some other in-view j fully covers it.
    hidden = []
    if per.occlusion:
        disk = {}  # j -> (rho_j, u_j), seen from p_i
        for j in labels:
            dist = norm3(offsets[j])
            if dist > 0:  # a boid exactly at p_i has no projection; it neither hides nor is hidden
                disk[j] = (per.body_radius / dist, offsets[j] / dist)
        for k, (rho_k, u_k) in disk.items():
            for j, (rho_j, u_j) in disk.items():
                if j != k and rho_k < rho_j and norm3(u_j - u_k) <= rho_j - rho_k:
                    hidden.append(k)
                    break
    visible = [j for j in sorted(labels) if j not in hidden]
    return _result({rule: visible for rule in RULES}, labels, hidden)


# steering (docs/model.md section 3, decisions 7-9)
def steering_force(i, sets, pos, fwd, pattern, model, box=None) -> np.ndarray:
    """w_s S + w_a A + w_c C for boid i from its neighbour sets (docs/model.md section 3).

    Without patterns every weight is 1, so the weighted sums below are the plain sums and means.
    A rule with an empty set, or (pattern mode) whose weights sum to 0, contributes 0."""
    pat = model.patterns

    def weight(j, rule):
        if not pat.enabled:
            return 1.0
        w = similarity(pattern[i], pattern[j], pat.n_bits)
        if rule == "separation":
            return {"similarity": w, "dissimilarity": 1.0 - w, "uniform": 1.0}[pat.separation_weight]
        return w

    # separation S = normalize(sum_j w'_ij (-d_j / |d_j|^2))
    total, wsum = np.zeros(3), 0.0
    for j in sets["separation"]:
        d = offset(pos[i], pos[j], box)
        w = weight(j, "separation")
        d2 = dot3(d, d)
        if d2 > 0:  # a coincident neighbour has no direction; its term is taken as 0
            total = total + w * (-d / d2)
        wsum += w
    separation = normalize(total) if wsum > 0 else np.zeros(3)

    # alignment A = normalize(sum_j w_ij f_j / sum_j w_ij - f_i)
    total, wsum = np.zeros(3), 0.0
    for j in sets["alignment"]:
        w = weight(j, "alignment")
        total = total + w * fwd[j]
        wsum += w
    alignment = normalize(total / wsum - fwd[i]) if wsum > 0 else np.zeros(3)

    # cohesion C = normalize(sum_j w_ij d_j / sum_j w_ij)
    total, wsum = np.zeros(3), 0.0
    for j in sets["cohesion"]:
        w = weight(j, "cohesion")
        total = total + w * offset(pos[i], pos[j], box)
        wsum += w
    cohesion = normalize(total / wsum) if wsum > 0 else np.zeros(3)

    st = model.steering
    return (st.separation_weight * separation + st.alignment_weight * alignment
            + st.cohesion_weight * cohesion)


# vehicle physics, frame, boundary (docs/model.md section 3 steps 1-6, sec 1, sec 0; decisions 10-11)
def apply_boundary(p, world) -> np.ndarray:
    """docs/model.md section 0: sphere_wrap reflects through the centre; periodic_box wraps into [-L/2, L/2)."""
    if world.boundary == "sphere_wrap":
        r = norm3(p)
        if r > world.sphere_radius:
            p = p - 2.0 * world.sphere_radius * (p / r)
    elif world.boundary == "periodic_box":
        size = world.box_size
        p = p - size * np.floor((p + size / 2.0) / size)
    return p


def move(i, force, state, model, dt) -> None:
    """Apply the steering force to boid i in place in ``state`` (dict of (N,3) arrays)."""
    veh = model.vehicle
    f = state["fwd"][i].copy()
    speed = norm3(state["vel"][i])
    force = in_plane(force, model)  # docs/model.md section 15: a 2-D force has z = 0

    # 1. at low speed, clamp the force into a cone about f (keeping its length)
    low = 0.2 * veh.max_speed
    magnitude = norm3(force)
    if speed <= low and magnitude > 0:
        c = 1.0 - 2.0 * (speed / low) ** 20
        if dot3(force / magnitude, f) < c:
            perpendicular = normalize(force - dot3(force, f) * f)
            force = magnitude * (c * f + math.sqrt(1.0 - c * c) * perpendicular)
    # 2. truncate, a = F / m
    accel = truncate(force, veh.max_force) / veh.mass
    # 3. smoothed acceleration
    a_smooth = state["acc"][i] + min(max(9.0 * dt, 0.15), 0.4) * (accel - state["acc"][i])
    # 4. new velocity from speed * forward (not the stored velocity)
    v = truncate(speed * f + a_smooth * dt, veh.max_speed)
    # 5. semi-implicit move
    p = state["pos"][i] + v * dt

    # 6. rebuild the frame with banking (sec 1, decision 8; the planar frame in 2-D), then the boundary
    if model.world.dimensions == 2:
        f, u, s = planar_frame(i, v, state)
        state["pos"][i] = apply_boundary(p, model.world)
        state["vel"][i], state["fwd"][i], state["up"][i] = v, f, u
        state["side"][i], state["acc"][i] = s, a_smooth
        return
    u_old, s_old = state["up"][i], state["side"][i]
    u = u_old + min(max(3.0 * dt, 0.0), 1.0) * (0.05 * a_smooth + np.array([0.0, 0.2, 0.0]) - u_old)
    u_len = norm3(u)
    u = u / u_len if u_len > 0 else u_old.copy()
    v_len = norm3(v)
    if v_len > 0:
        f = v / v_len
    s = np.cross(f, u)
    s_len = norm3(s)
    s = s / s_len if s_len > 1e-12 else normalize(s_old - dot3(s_old, f) * f)
    u = np.cross(s, f)

    state["pos"][i] = apply_boundary(p, model.world)
    state["vel"][i], state["fwd"][i], state["up"][i] = v, f, u
    state["side"][i], state["acc"][i] = s, a_smooth


def step(pos, vel, fwd, up, side, acc, pattern, model, dt) -> dict:
    """One time step on copies of the inputs (docs/model.md section 0.3 update order, decisions 12 and 28)."""
    names = ("pos", "vel", "fwd", "up", "side", "acc")
    inputs = {k: np.array(a, dtype=np.float64, copy=True) for k, a in zip(names, (pos, vel, fwd, up, side, acc))}
    state = {k: a.copy() for k, a in inputs.items()}
    n = len(state["pos"])
    box = model.world.box_size if model.world.boundary == "periodic_box" else None
    visible = np.zeros(n, dtype=np.int64)
    binocular = np.zeros(n, dtype=np.int64)

    def sense(i, source):
        sets = perceive(i, source["pos"], source["fwd"], source["side"], model, box)
        visible[i] = len(sets["visible"])
        binocular[i] = sum(1 for j in sets["visible"] if sets["labels"].get(j) == 3)
        return steering_force(i, sets, source["pos"], source["fwd"], pattern, model, box)

    if model.world.update_order == "synchronous":
        forces = [sense(i, inputs) for i in range(n)]  # everyone reads the state at time t
        for i in range(n):
            move(i, forces[i], state, model, dt)
    elif model.world.update_order == "sequential":
        for i in range(n):  # boids < i have already moved in this step
            move(i, sense(i, state), state, model, dt)
    else:
        raise ValueError(f"unknown update order {model.world.update_order!r}")

    return dict(state, visible=visible, binocular=binocular)


def kernel_step_agrees(model, state, dt, k, tol=1e-12):
    """One kernel step (``simcore.advance``) from ``state`` against :func:`step`: every state array to
    ``tol``, the visible and binocular counts exactly, patterns unchanged (``k``: the step, for messages).
    Returns the kernel's observations and the reference's result."""
    from flocksweep.simcore import advance

    obs = advance(model, state, 1, dt)
    ref = step(state.pos, state.vel, state.fwd, state.up, state.side, state.acc, state.pattern, model, dt)
    for name in ("pos", "vel", "fwd", "up", "side", "acc"):
        np.testing.assert_allclose(getattr(obs.final, name), ref[name], rtol=tol, atol=tol, err_msg=f"step {k}: {name}")
    np.testing.assert_array_equal(obs.visible[0], ref["visible"], err_msg=f"step {k}: visible")
    np.testing.assert_array_equal(obs.binocular[0], ref["binocular"], err_msg=f"step {k}: binocular")
    np.testing.assert_array_equal(obs.final.pattern, state.pattern)
    return obs, ref
