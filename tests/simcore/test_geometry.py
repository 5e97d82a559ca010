"""Perception geometry checked against cases worked out by hand (docs/model.md section 2).

Every case puts the observer, boid 0, at the origin heading +x, so its frame is
fwd f = (1, 0, 0), up = (0, 1, 0), side s = f x up = (0, 0, 1): +z is the observer's right, -z its left.
For the binocular kind the eyes and gaze axes are

    e_L/R = h (cos(alpha) f -/+ sin(alpha) s)        a_L/R = cos(delta) f -/+ sin(delta) s

with alpha = eye_position_deg, delta = direction_deg, h = head_radius; boid j is in an eye's view when
0 < |p_j - e| <= range and a . (p_j - e) >= cos(field/2) |p_j - e|. The arithmetic of each case is
written next to it. Labels: 1 left eye only, 2 right eye only, 3 both.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from flocksweep.simcore import State
from flocksweep.simcore.params import ModelParams, Perception
from flocksweep.simcore.probe import perceived
from flocksweep.simcore.state import frame_from_forward

LEFT, RIGHT, BOTH = 1, 2, 3
SEP, ALI, COH = 1, 2, 4  # rule mask bits: separation, alignment, cohesion


def state_of(positions) -> State:
    """State of boids at ``positions``, all heading +x (frame as in the module docstring)."""
    pos = np.array(positions, dtype=float)
    n = len(pos)
    fwd = np.tile([1.0, 0.0, 0.0], (n, 1))
    up, side = frame_from_forward(fwd)
    return State(pos=pos, vel=fwd.copy(), fwd=fwd, up=up, side=side, acc=np.zeros((n, 3)),
                 pattern=np.zeros(n, dtype=np.uint32))


def flock(*others) -> State:
    """The observer (index 0) at the origin and ``others`` (indices 1, 2, ...), all heading +x."""
    return state_of([(0.0, 0.0, 0.0), *others])


def binocular(**kw) -> ModelParams:
    return ModelParams(perception=Perception(kind="binocular", **kw))


def seen(model: ModelParams, state: State, i: int = 0) -> dict[int, int]:
    """{neighbour index: eye label} of boid i."""
    out = perceived(model, state, i)
    return dict(zip(out["idx"].tolist(), out["label"].tolist()))


def test_observer_frame_is_the_one_the_hand_calculations_assume():
    up, side = frame_from_forward(np.array([[1.0, 0.0, 0.0]]))
    assert up.tolist() == [[0.0, 1.0, 0.0]]
    assert side.tolist() == [[0.0, 0.0, 1.0]]


# --- view phase -----------------------------------------------------------------------------------

@pytest.mark.slow
def test_boid_straight_behind_is_unseen_by_forward_eyes():
    # direction 0, eye position 0: both eyes at (0.5, 0, 0), both gazes (1, 0, 0), cos(180/2) = 0.
    # q = (-5, 0, 0) - (0.5, 0, 0) = (-5.5, 0, 0); a . q = -5.5 < 0 * 5.5 -> outside the cone.
    model = binocular(direction_deg=0.0, field_deg=180.0, range=10.0, occlusion=False)
    assert seen(model, flock((-5.0, 0.0, 0.0))) == {}


@pytest.mark.parametrize("eyes", [dict(eye_position_deg=0.0), dict(head_radius=0.0)],
                         ids=["eyes_at_front", "point_head"])
def test_sideways_gaze_sees_exactly_behind_on_the_half_field_boundary(eyes):
    # direction 90: a_L = (0, 0, -1), a_R = (0, 0, 1); field 180: cos(90) = 0 exactly.
    # Eyes at the front (0.5, 0, 0) (or both at the centre when h = 0): q = (-5.5, 0, 0) (or (-5, 0, 0)),
    # a . q = 0 >= 0 * |q| -> on the boundary of both cones, and the boundary counts as seen.
    model = binocular(direction_deg=90.0, field_deg=180.0, range=10.0, occlusion=False, **eyes)
    assert seen(model, flock((-5.0, 0.0, 0.0))) == {1: BOTH}


def test_side_eyes_leave_a_blind_strip_on_the_centre_line():
    # direction 90 and, by default, eye position 90: e_L = (0, 0, -0.5), e_R = (0, 0, 0.5).
    # Right eye: a_R . q = (0, 0, 1) . (p - e_R) = z - 0.5 >= 0 -> sees the half-space z >= 0.5;
    # left eye likewise sees z <= -0.5. The slab -0.5 < z < 0.5 is blind, behind and ahead alike.
    model = binocular(direction_deg=90.0, field_deg=180.0, range=10.0, occlusion=False)
    assert model.perception.eye_deg == 90.0
    assert seen(model, flock((-5.0, 0.0, 0.0))) == {}  # behind: z = 0 -> -0.5 < 0 for both eyes
    assert seen(model, flock((5.0, 0.0, 0.0))) == {}   # straight ahead is blind too
    # (-5, 0, 1): right eye q = (-5, 0, 0.5), a_R . q = 0.5 >= 0 -> seen; left eye q = (-5, 0, 1.5),
    # a_L . q = -1.5 < 0 -> not seen. |q| = sqrt(25.25) < 10. Side +z is the right eye.
    assert seen(model, flock((-5.0, 0.0, 1.0))) == {1: RIGHT}
    assert seen(model, flock((-5.0, 0.0, -1.0))) == {1: LEFT}


def test_range_is_measured_from_the_eye_and_its_boundary_is_seen():
    # direction 0: both eyes at (0.5, 0, 0). Boid at (10.5, 0, 0): |q| = 10.5 - 0.5 = 10 = range -> seen.
    # At 10.5 + 1e-9 the eye distance is 10 + 1e-9 > 10 -> unseen.
    model = binocular(direction_deg=0.0, field_deg=120.0, range=10.0, occlusion=False)
    assert seen(model, flock((10.5, 0.0, 0.0))) == {1: BOTH}
    assert seen(model, flock((10.5 + 1e-9, 0.0, 0.0))) == {}


def test_boid_at_the_eye_itself_is_unseen():
    # 0 < |p_j - e| is strict: direction 0 puts both eyes at (0.5, 0, 0); a boid there has q = 0.
    model = binocular(direction_deg=0.0, field_deg=360.0, range=10.0, occlusion=False)
    assert seen(model, flock((0.5, 0.0, 0.0))) == {}


def _directions():
    """The 26 unit vectors towards the neighbours of a cube cell."""
    for d in itertools.product((-1.0, 0.0, 1.0), repeat=3):
        if d != (0.0, 0.0, 0.0):
            yield np.array(d) / np.linalg.norm(d)


def test_full_field_sees_every_direction_within_range_and_nothing_beyond():
    # field 360: no cone at all. Eyes are 0.5 from the centre (direction 60), so a boid at distance 5
    # is at most 5.5 <= 10 from either eye -> seen by both; one at distance 12 is at least
    # 12 - 0.5 = 11.5 > 10 from either eye -> unseen.
    model = binocular(direction_deg=60.0, field_deg=360.0, range=10.0, occlusion=False)
    near = [5.0 * d for d in _directions()]
    far = [12.0 * d for d in _directions()]
    state = flock(*near, *far)
    assert seen(model, state) == {j: BOTH for j in range(1, len(near) + 1)}


@pytest.mark.parametrize("position, expected", [
    ((10.0, 0.0, 0.0), {1: BOTH}),
    ((0.0, 0.0, -10.0), {1: LEFT}),
    ((0.0, 0.0, 10.0), {1: RIGHT}),
    ((-10.0, 0.0, 0.0), {}),
    ((0.0, 10.0, 0.0), {}),
], ids=["ahead", "left", "right", "behind", "above"])
def test_eye_labels_with_gaze_45_and_field_120(position, expected):
    # direction 45 = eye position, c = cos 45 = 0.7071, cos(120/2) = 0.5.
    # e_L = 0.5 (c, 0, -c) = (0.354, 0, -0.354), a_L = (c, 0, -c); right eye mirrored in z.
    # ahead (10,0,0): q_L = (9.646, 0, 0.354), a_L.q = c (9.646 - 0.354) = 6.571, |q| = 9.652,
    #   cos = 0.681 >= 0.5 -> seen; same for the right eye -> both.
    # left (0,0,-10): q_L = (-0.354, 0, -9.646), a_L.q = c (-0.354 + 9.646) = 6.571, cos = 0.681 -> seen;
    #   q_R = (-0.354, 0, -10.354), a_R.q = c (-0.354 - 10.354) < 0 -> not seen -> left only.
    # right (0,0,10): mirror image -> right only.
    # behind (-10,0,0): q_L = (-10.354, 0, 0.354), a_L.q = c (-10.354 - 0.354) < 0; same for R.
    # above (0,10,0): q_L = (-0.354, 10, 0.354), a_L.q = c (-0.354 - 0.354) < 0; same for R.
    model = binocular(direction_deg=45.0, field_deg=120.0, range=20.0, occlusion=False)
    assert seen(model, flock(position)) == expected


def test_labels_do_not_depend_on_the_world_orientation():
    # The ahead/left/right/behind cases above, with the whole scene (positions and the observer's
    # frame) turned by an arbitrary rotation: none of them is on a boundary, so the labels must match.
    angle = 0.7
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rot = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)  # Rodrigues
    model = binocular(direction_deg=45.0, field_deg=120.0, range=20.0, occlusion=False)
    points = [(10.0, 0.0, 0.0), (0.0, 0.0, -10.0), (0.0, 0.0, 10.0), (-10.0, 0.0, 0.0), (0.0, 10.0, 0.0)]
    state = flock(*points)
    turned = State(pos=state.pos @ rot.T, vel=state.vel @ rot.T, fwd=state.fwd @ rot.T,
                   up=state.up @ rot.T, side=state.side @ rot.T, acc=state.acc, pattern=state.pattern)
    assert seen(model, state) == {1: BOTH, 2: LEFT, 3: RIGHT}
    assert seen(model, turned) == seen(model, state)


# --- perspective phase (Holland & Semwal, Figure 5) -------------------------------------------------
# Measured from the observer's centre: rho = body_radius / d, u = offset / d. A farther k is hidden
# when a closer in-view j has rho_k < rho_j and |u_j - u_k| <= rho_j - rho_k.

def occluding(**kw) -> ModelParams:
    return binocular(field_deg=360.0, range=100.0, **{"occlusion": True, **kw})


def test_equal_distance_never_hides_even_when_the_discs_overlap():
    # Outcome 1: the farther boid's projected radius is not smaller. j = (5, 0, 0) and k = (4, 3, 0)
    # are both exactly 5 away; body 2: rho = 0.4 each, |u_j - u_k| = |(1,0,0) - (0.8,0.6,0)| = 0.632
    # < 0.8 (the discs overlap) but rho_j - rho_k = 0 -> neither is hidden.
    model = occluding(body_radius=2.0)
    assert set(seen(model, flock((5.0, 0.0, 0.0), (4.0, 3.0, 0.0)))) == {1, 2}


def test_boid_directly_behind_a_closer_one_is_hidden():
    # Outcome 2 on one ray: j = (5,0,0), k = (25,0,0); rho_j = 0.1, rho_k = 0.02, |u_j - u_k| = 0
    # <= 0.08 -> k hidden.
    model = occluding(body_radius=0.5)
    assert set(seen(model, flock((5.0, 0.0, 0.0), (25.0, 0.0, 0.0)))) == {1}


@pytest.mark.parametrize("body_radius, hidden", [
    (2.0, True),   # outcome 2: 0.16 b = 0.32 >= 0.283 -> completely covered
    (1.5, False),  # outcome 3: 0.24 < 0.283 < 0.36 -> partial overlap, visible
    (1.0, False),  # outcome 4: 0.283 >= 0.24 b = 0.24 -> disjoint discs, visible
], ids=["complete", "partial", "disjoint"])
def test_figure5_outcomes_for_one_pair(body_radius, hidden):
    # j = (5,0,0), k = (24,7,0) with |k| = 25 exactly. u_j = (1,0,0), u_k = (0.96, 0.28, 0),
    # |u_j - u_k| = sqrt(0.04^2 + 0.28^2) = sqrt(0.08) = 0.283.
    # rho_j = b/5, rho_k = b/25: difference 0.16 b, sum 0.24 b.
    model = occluding(body_radius=body_radius)
    visible = set(seen(model, flock((5.0, 0.0, 0.0), (24.0, 7.0, 0.0))))
    assert visible == ({1} if hidden else {1, 2})


@pytest.mark.parametrize("factor, hidden", [(1 + 1e-9, True), (1 - 1e-9, False)])
def test_containment_boundary_just_inside_and_just_outside(factor, hidden):
    # Same pair: k is hidden iff 0.16 b >= sqrt(0.08), i.e. b >= b* = sqrt(0.08) / 0.16 = 1.7678.
    b_star = math.sqrt(0.08) / 0.16
    model = occluding(body_radius=b_star * factor)
    visible = set(seen(model, flock((5.0, 0.0, 0.0), (24.0, 7.0, 0.0))))
    assert visible == ({1} if hidden else {1, 2})


def test_containment_boundary_exactly_equal_counts_as_hidden():
    # The only float-exact construction: opposite directions, so |u_j - u_k| = |(1,0,0) - (-1,0,0)| = 2.
    # body 5, j = (2,0,0): rho_j = 2.5; k = (-10,0,0): rho_k = 0.5; rho_j - rho_k = 2 = |u_j - u_k|.
    # (Geometrically degenerate: the observer sits inside j's body, so j's "disc" covers everything.)
    model = occluding(body_radius=5.0)
    assert set(seen(model, flock((2.0, 0.0, 0.0), (-10.0, 0.0, 0.0)))) == {1}
    # k slightly closer: rho_k = 5 / 9.99 = 0.5005, difference 1.9995 < 2 -> visible.
    assert set(seen(model, flock((2.0, 0.0, 0.0), (-9.99, 0.0, 0.0)))) == {1, 2}


# Chain: A hides B and B hides C (small-angle values, body 0.5):
#   A = (5,0,0):     rho 0.1,    u angle 0
#   B = (10,0.4,0):  rho 0.0500, |u_A - u_B| = 0.0400 <= 0.1 - 0.0500 = 0.0500
#   C = (20,1.2,0):  rho 0.0250, |u_B - u_C| = 0.0199 <= 0.0500 - 0.0250 = 0.0250
# Disc containment is transitive (|u_A - u_C| = 0.0599 <= 0.1 - 0.025 = 0.075), so A hides C directly
# as well: whether a hidden boid still occludes cannot change the visible set in this model; the test
# pins that the answer is the same whichever index order the checks run in.
CHAIN = {"A": (5.0, 0.0, 0.0), "B": (10.0, 0.4, 0.0), "C": (20.0, 1.2, 0.0)}


@pytest.mark.parametrize("order", list(itertools.permutations(["observer", "A", "B", "C"])),
                         ids=lambda order: "-".join(order))
def test_occlusion_chain_is_independent_of_index_order(order):
    # boids placed in the given index order; the observer is wherever "observer" falls
    points = {"observer": (0.0, 0.0, 0.0), **CHAIN}
    state = state_of([points[name] for name in order])
    i = order.index("observer")
    with_occlusion = {order[j] for j in seen(occluding(body_radius=0.5), state, i)}
    without = {order[j] for j in seen(occluding(body_radius=0.5, occlusion=False), state, i)}
    assert with_occlusion == {"A"}
    assert without == {"A", "B", "C"}


def test_occlusion_is_measured_from_the_body_centre_not_the_eyes():
    # body 0.1, j = (1,0,0): rho_j = 0.1; k = (10,0,0): rho_k = 0.01; same ray from the centre,
    # |u_j - u_k| = 0 <= 0.09 -> hidden. From the left eye at (0.354, 0, -0.354) (direction 45) the
    # two would be 26.6 degrees apart (atan(0.354/0.646) - atan(0.354/9.646) = 28.7 - 2.1) and k
    # would show; the spec measures from p_i.
    model = occluding(direction_deg=45.0, body_radius=0.1)
    assert set(seen(model, flock((1.0, 0.0, 0.0), (10.0, 0.0, 0.0)))) == {1}


def test_closer_boid_outside_the_view_does_not_occlude():
    # direction 0, field 180, eyes at (0.5,0,0): the view is the half-space x >= 0.5.
    # j = (0.4,0,0) is behind the eyes (q = (-0.1,0,0), a . q < 0) -> not in view.
    # k = (5,0,0) is on the same ray from the centre; with body 0.1, rho_j = 0.25 > rho_k = 0.02 and
    # |u_j - u_k| = 0, so j would hide k, but only in-view boids occlude -> k visible.
    model = binocular(direction_deg=0.0, field_deg=180.0, range=10.0, body_radius=0.1, occlusion=True)
    assert seen(model, flock((0.4, 0.0, 0.0), (5.0, 0.0, 0.0))) == {2: BOTH}


# --- sphere and opensteer kinds ---------------------------------------------------------------------

def test_sphere_radius_is_strict_and_feeds_all_rules():
    # radius 5: (4,0,0) |d| = 4 < 5 seen; (3,4,0) |d|^2 = 25, not < 25 -> unseen; (0,0,-4.9) and
    # (-4.9,0,0) seen (any direction: to the left, straight behind).
    model = ModelParams(perception=Perception(kind="sphere", radius=5.0))
    out = perceived(model, flock((4.0, 0.0, 0.0), (3.0, 4.0, 0.0), (0.0, 0.0, -4.9), (-4.9, 0.0, 0.0)), 0)
    assert out["idx"].tolist() == [1, 3, 4]
    assert out["mask"].tolist() == [SEP | ALI | COH] * 3
    assert out["label"].tolist() == [0, 0, 0]


def opensteer_mask(position, **kw) -> int:
    """Rule mask of a single neighbour at ``position`` (0 when it is no neighbour at all)."""
    model = ModelParams(perception=Perception(kind="opensteer", **kw))
    out = perceived(model, flock(position), 0)
    return int(out["mask"][0]) if len(out["idx"]) else 0


@pytest.mark.parametrize("position, mask", [
    # near_radius 1.5, any angle: behind at 1 -> |d|^2 = 1 < 2.25 -> all three rules
    ((-1.0, 0.0, 0.0), SEP | ALI | COH),
    # behind at exactly 1.5: 2.25 is not < 2.25 -> cone tests; forwardness -1 fails every cosine
    ((-1.5, 0.0, 0.0), 0),
    # behind at 3: forwardness -1; separation needs > -0.707 (no), alignment > 0.7 (no),
    # cohesion > -0.15 (no) -> no neighbour
    ((-3.0, 0.0, 0.0), 0),
    # ahead at 3: forwardness 1 passes every cone; 9 <= 25, 56.25, 81 -> all three
    ((3.0, 0.0, 0.0), SEP | ALI | COH),
    # ahead at 6: 36 > 25 -> no separation; alignment and cohesion
    ((6.0, 0.0, 0.0), ALI | COH),
    # ahead at 8: 64 > 56.25 -> cohesion only
    ((8.0, 0.0, 0.0), COH),
    # ahead at exactly 9: 81 <= 81 (inclusive) -> cohesion
    ((9.0, 0.0, 0.0), COH),
    ((9.0 + 1e-9, 0.0, 0.0), 0),
    # to the side at 3: forwardness 0 > -0.707 (separation), not > 0.7, > -0.15 (cohesion)
    ((0.0, 0.0, 3.0), SEP | COH),
    # 120 degrees off forward at distance 4: d = (-2, 0, 3.464), forwardness -0.5:
    # > -0.707 separation yes; > 0.7 no; > -0.15 no
    ((-2.0, 0.0, 2.0 * math.sqrt(3.0)), SEP),
], ids=["near_behind", "near_boundary", "behind_3", "ahead_3", "ahead_6", "ahead_8", "ahead_9",
        "beyond_9", "side_3", "rear_120deg"])
def test_opensteer_rule_masks(position, mask):
    assert opensteer_mask(position) == mask


def test_opensteer_cone_test_is_strict():
    # separation_cos 0 and a boid exactly to the side: forwardness 0 is not > 0 -> no separation bit;
    # cohesion (0 > -0.15) still applies.
    assert opensteer_mask((0.0, 0.0, 3.0), separation_cos=0.0) == COH


def test_coincident_neighbour_does_not_crash_the_occlusion_phase():
    # j at the observer's centre is 0.5 from each eye (direction 60), so it is in view of a full field;
    # k makes m > 1 so the perspective phase runs. rho_j = body / 0 is undefined.
    # The coincident boid has no direction from the centre: it neither hides nor is hidden, so k, which
    # it would otherwise cover completely (rho_j = infinity), stays visible.
    model = occluding(direction_deg=60.0)
    assert set(seen(model, flock((0.0, 0.0, 0.0), (3.0, 0.0, 0.0)))) == {1, 2}
