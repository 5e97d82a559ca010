"""Topological perception (docs/model.md, "Topological perception"): hand-made cases with known answers.

The step-by-step agreement with the numpy reference is in test_kernel_vs_reference.py and the grid's
bit-identity in test_search.py; here: the k nearest, ties, the blind cone and the distance limit on
boundaries, fewer eligible boids than k, a whole run, and config checks.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import make_model, state_from
from flocksweep.simcore import ConfigError, InitParams, simulate
from flocksweep.simcore.params import Leadership, ModelParams, Perception
from flocksweep.simcore.probe import perceived

EAST = [1.0, 0.0, 0.0]


def observer_state(others, fwd=EAST):
    """Boid 0 at the origin heading ``fwd``; the others at the given positions, all heading east."""
    pos = [[0.0, 0.0, 0.0]] + [list(p) for p in others]
    headings = [fwd] + [EAST] * len(others)
    return state_from(pos, headings, 1.0)


@pytest.mark.parametrize("search", ("all_pairs", "grid"))
def test_the_k_nearest_are_chosen_and_returned_by_index(search):
    state = observer_state([[5, 0, 0], [1, 0, 0], [0, 3, 0], [0, 0, 2], [4, 4, 0], [0, -2.5, 0]])
    got = perceived(make_model("topological", neighbours=3, search=search), state, 0)
    assert got["idx"].tolist() == [2, 4, 6]          # distances 1, 2, 2.5 (boids 2, 4, 6), in index order
    assert got["mask"].tolist() == [7, 7, 7]          # all three rules, as for the sphere


def test_equal_distances_go_to_the_lower_index():
    state = observer_state([[0, 2, 0], [2, 0, 0], [0, 0, 2], [-2, 0, 0]])
    assert perceived(make_model("topological", neighbours=2), state, 0)["idx"].tolist() == [1, 2]


def test_fewer_eligible_than_k_takes_them_all():
    state = observer_state([[1, 0, 0], [0, 9, 0]])
    assert perceived(make_model("topological", neighbours=7), state, 0)["idx"].tolist() == [1, 2]


def test_blind_cone_boundary_is_seen_and_behind_is_not():
    # blind angle 180: the half-space behind; a boid exactly sideways (f . d = 0) is on the boundary, seen
    state = observer_state([[-1, 0, 0], [0, 3, 0], [-1e-9, 4, 0], [2, 5, 0]])
    got = perceived(make_model("topological", neighbours=3, blind_deg=180.0), state, 0)
    assert got["idx"].tolist() == [2, 4]               # boid 1 behind and boid 3 just behind are excluded


def test_max_distance_is_strict():
    state = observer_state([[2, 0, 0], [0, 2 - 1e-12, 0], [0, 0, 1]])
    got = perceived(make_model("topological", neighbours=5, max_distance=2.0), state, 0)
    assert got["idx"].tolist() == [2, 3]


def test_every_boid_sees_exactly_k_in_a_run():
    model = make_model("topological", neighbours=5)
    obs = simulate(model, InitParams(n=60, radius=8.0), seed=2, duration=1.0, dt=1 / 60, record_every=10)
    assert (obs.visible == 5).all()


def test_config_checks():
    with pytest.raises(ConfigError, match="perception.neighbours"):
        Perception(kind="topological", neighbours=0)
    with pytest.raises(ConfigError, match="perception.blind_deg"):
        Perception(kind="topological", blind_deg=360.0)
    with pytest.raises(ConfigError, match="perception.max_distance"):
        Perception(kind="topological", max_distance=-1.0)
    with pytest.raises(ConfigError, match="perception.max_distance"):
        ModelParams(perception=Perception(kind="topological"), leadership=Leadership(x=1.0))
    with_limit = ModelParams(perception=Perception(kind="topological", max_distance=9.0), leadership=Leadership(x=1.0))
    assert with_limit.perception_range == 9.0
    assert Perception(kind="topological", max_distance=4.0).resolved() == {
        "kind": "topological", "neighbours": 7, "max_distance": 4.0, "blind_deg": 0.0}


def test_topological_reacts_to_its_neighbours():
    """Not just counting: a boid's steering depends on which k it picks (k = 1 vs k = 6 differ)."""
    init = InitParams(n=40, radius=6.0)
    a = simulate(make_model("topological", neighbours=1), init, seed=4, duration=0.5, dt=1 / 60)
    b = simulate(make_model("topological", neighbours=6), init, seed=4, duration=0.5, dt=1 / 60)
    assert np.array_equal(a.pos[0], b.pos[0]) and not np.allclose(a.final.pos, b.final.pos)
