"""The perspective phase's single-precision screen (``simcore.occlusion``): from ``SCREEN_MIN`` in-view
neighbours on, every pair is first tested in float32 with widened radii and a slack, and only the flagged
boids get the exact double-precision test. The hidden set must be exactly the double-precision one,
including pairs on the containment boundary to within rounding, boids so close that their angular radius
exceeds float32's range, and a boid at the observer's centre.

Each flock puts the observer (boid 0) at the origin, sees every direction (field 360, eyes at the centre)
and is checked against ``brute_force_hidden``, the numpy twin testing every pair as the spec states.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import make_model, state_from, unit_vectors
from flocksweep.simcore.occlusion import ALL_PAIRS_MAX, CAP, SCREEN_MIN
from flocksweep.simcore.probe import perceived
from test_search import brute_force_hidden

BODY = 0.5


def observed(offsets: np.ndarray, body: float = BODY):
    """The observer at the origin with the given neighbours: (kernel's visible indices, twin's idx, hidden)."""
    pos = np.vstack([np.zeros(3), offsets])
    rng = np.random.default_rng(5)
    state = state_from(pos, unit_vectors(rng, len(pos)), 1.0)
    model = make_model("binocular", direction_deg=0.0, field_deg=360.0, range=1e3, head_radius=0.0,
                       body_radius=body, search="all_pairs")
    idx, hidden = brute_force_hidden(state, 0, len(pos), body)
    return perceived(model, state, 0)["idx"].tolist(), idx, hidden


def scattered(rng, count: int, near: float = 3.0, far: float = 30.0) -> np.ndarray:
    directions = rng.standard_normal((count, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    return directions * rng.uniform(near, far, count)[:, None]


def on_the_boundary(rng, count: int, relative: float) -> np.ndarray:
    """``count`` pairs (j, k): k farther than j, their chord |u_j - u_k| equal to rho_j - rho_k times
    (1 + relative), so k is hidden just inside (relative < 0), exactly on, or just outside the boundary."""
    out = []
    for _ in range(count):
        u = rng.standard_normal(3)
        u /= np.linalg.norm(u)
        w = np.cross(u, rng.standard_normal(3))
        w /= np.linalg.norm(w)
        d_j = rng.uniform(2.0, 8.0)
        d_k = d_j * rng.uniform(1.5, 4.0)
        chord = (BODY / d_j - BODY / d_k) * (1.0 + relative)
        angle = 2.0 * np.arcsin(chord / 2.0)
        out += [d_j * u, d_k * (np.cos(angle) * u + np.sin(angle) * w)]
    return np.array(out)


@pytest.mark.parametrize("relative", [-1e-6, -1e-12, 0.0, 1e-12, 1e-6])
@pytest.mark.parametrize("in_view", [SCREEN_MIN - 2, SCREEN_MIN + 4, ALL_PAIRS_MAX, ALL_PAIRS_MAX + 20])
def test_boundary_pairs_are_decided_as_in_double_precision(relative, in_view):
    rng = np.random.default_rng(int(1e6 * relative) % 97 + in_view)
    pairs = on_the_boundary(rng, 6, relative)
    offsets = np.vstack([pairs, scattered(rng, in_view - len(pairs))])
    got, idx, hidden = observed(offsets)
    assert len(idx) == in_view
    assert got == idx[~hidden].tolist()
    if relative < 0:   # well inside by far more than rounding: the construction really hides them
        assert hidden[1:12:2].all()
    if relative >= 1e-6:
        assert not hidden[1:12:2].any()


@pytest.mark.parametrize("in_view", [SCREEN_MIN - 1, SCREEN_MIN, 50, ALL_PAIRS_MAX])
def test_random_dense_flocks_hide_the_double_precision_set(in_view):
    rng = np.random.default_rng(in_view)
    for trial in range(20):
        offsets = scattered(rng, in_view, near=1.0, far=6.0)
        got, idx, hidden = observed(offsets, body=0.6)
        assert got == idx[~hidden].tolist(), f"trial {trial}"
    assert hidden.any(), "occlusion was exercised"


def test_a_neighbour_closer_than_float32_can_scale_hides_everything_behind_it():
    rng = np.random.default_rng(2)
    close = 1e-40 * np.array([[1.0, 0.0, 0.0]])        # rho = 5e39: beyond float32 and the screen's CAP
    assert BODY / 1e-40 > max(CAP, float(np.finfo(np.float32).max))
    got, idx, hidden = observed(np.vstack([close, scattered(rng, SCREEN_MIN + 5)]))
    assert got == idx[~hidden].tolist() == [1]


def test_two_neighbours_beyond_float32_are_still_ordered_exactly():
    rng = np.random.default_rng(4)
    pair = np.array([[1e-40, 0.0, 0.0], [2e-40, 1e-41, 0.0]])   # rho 5e39 and about 2.5e39: k hidden
    got, idx, hidden = observed(np.vstack([pair, scattered(rng, SCREEN_MIN + 5)]))
    assert got == idx[~hidden].tolist()
    assert got[0] == 1 and 2 not in got
