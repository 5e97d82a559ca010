"""Neighbour search: the cell-list grid gives bit-identical trajectories to all pairs (docs/model.md,
"Neighbour search"), for every perception kind x world boundary x update order, and the choice stays out
of a run's identity.

Each case advances a random flock of ``N`` boids (enough cells that the grid really prunes candidates) a
few steps with ``perception.search = "grid"`` and with ``"all_pairs"`` from the same state, and compares
every state array and count bit for bit. Each case also checks it exercised what it claims: the grid was
used, boids saw neighbours, the world boundary was crossed.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import flock_state, make_model, state_from, unit_vectors
from flocksweep.simcore import advance, load_preset, simulate
from flocksweep.simcore.kernel import AUTO_MIN_SAVING
from flocksweep.simcore.occlusion import ALL_PAIRS_MAX, GRID_3D_MIN
from flocksweep.simcore.params import InitParams, Leadership, ModelParams, Perception, World
from flocksweep.simcore.probe import perceived

N = 160
STEPS = 6
BALL = 7.0       # flock ball radius; also the sphere_wrap world radius, so boids wrap within the steps
BOX = 12.0       # periodic box side
STATE_FIELDS = ("pos", "vel", "fwd", "up", "side", "acc", "clock", "escape")

KINDS = {
    "sphere": dict(kind="sphere", radius=2.4),
    "opensteer": dict(kind="opensteer", near_radius=0.8, separation_radius=1.5, alignment_radius=2.0,
                      cohesion_radius=2.4),
    "binocular": dict(kind="binocular", range=2.6, field_deg=150.0, direction_deg=40.0, body_radius=0.3),
    "topological": dict(kind="topological", neighbours=6, blind_deg=60.0),
}
BOUNDARIES = ("open", "sphere_wrap", "periodic_box")
ORDERS = ("synchronous", "sequential")


def model_for(kind, boundary, order, search, **extra):
    return make_model(**KINDS[kind], **extra, boundary=boundary, order=order, sphere_radius=BALL, box_size=BOX,
                      search=search)


def state_for(boundary, seed):
    if boundary == "periodic_box":
        return flock_state(seed, N, box_size=BOX)
    return flock_state(seed, N, ball_radius=BALL)


def assert_same_run(a, b):
    for name in STATE_FIELDS:
        assert np.array_equal(getattr(a.final, name), getattr(b.final, name)), f"final {name} differs"
    for name in ("pos", "vel", "visible", "binocular"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), f"{name} differs"


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("kind", KINDS)
def test_grid_is_bit_identical_to_all_pairs(kind, boundary, order):
    seed = 100 + list(KINDS).index(kind) * 10 + BOUNDARIES.index(boundary) * 2 + ORDERS.index(order)
    state = state_for(boundary, seed)
    grid = model_for(kind, boundary, order, "grid")
    pairs = model_for(kind, boundary, order, "all_pairs")
    assert perceived(grid, state, 0)["grid"], "the grid was not used"
    assert not perceived(pairs, state, 0)["grid"]
    a = advance(grid, state, STEPS, 1 / 30)
    b = advance(pairs, state, STEPS, 1 / 30)
    assert_same_run(a, b)
    assert a.visible.mean() >= 2.0, "too few neighbours for a meaningful comparison"
    if boundary != "open":
        jumps = np.linalg.norm(a.pos[1:] - a.pos[:-1], axis=2)
        assert (jumps > BALL / 2).any(), "no boid crossed the world boundary"
    if kind == "binocular":
        assert a.binocular.sum() > 0


@pytest.mark.parametrize("order", ORDERS)
def test_grid_with_leadership_matches_all_pairs(order):
    """Hartman-Benes with the change of leadership: triggers and escapes are the same with either search."""
    def model(search):
        return ModelParams(dynamics="hartman_benes", perception=Perception(kind="sphere", radius=2.0, search=search),
                           world=World(update_order=order), leadership=Leadership(x=4.0, front_gate="none"))

    state = state_for("open", 7)
    a = advance(model("grid"), state, 20, 1 / 30, key=99)
    b = advance(model("all_pairs"), state, 20, 1 / 30, key=99)
    assert_same_run(a, b)
    assert np.array_equal(a.triggers, b.triggers)
    assert len(a.triggers) > 0, "no boid triggered: the leadership path was not exercised"


def test_topological_ties_are_broken_by_index_with_the_grid():
    """On a lattice many distances tie exactly; both searches and every boid pick the lower indices."""
    side = 8
    grid_points = np.stack(np.meshgrid(*[np.arange(side, dtype=float)] * 3, indexing="ij"), -1).reshape(-1, 3)
    rng = np.random.default_rng(3)
    order = rng.permutation(len(grid_points))  # indices unrelated to position
    state = state_from(grid_points[order], unit_vectors(rng, len(order)), 1.0)
    for search in ("grid", "all_pairs"):
        model = make_model("topological", neighbours=4, search=search)
        for i in (0, 17, 200, 511):
            got = perceived(model, state, i)
            d2 = ((state.pos - state.pos[i]) ** 2).sum(axis=1)
            d2[i] = np.inf
            ranked = sorted(range(len(d2)), key=lambda j: (d2[j], j))[:4]
            assert got["idx"].tolist() == sorted(ranked), f"boid {i} with {search}"
        assert got["grid"] == (search == "grid")


def brute_force_hidden(state, i, n, body):
    """Indices other than i and which of them are hidden, testing every pair in numpy."""
    d = np.delete(state.pos, i, axis=0) - state.pos[i]
    idx = np.delete(np.arange(n), i)
    inv = 1.0 / np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + d[:, 2] ** 2)
    rho, u = body * inv, d * inv[:, None]                  # as the kernel computes them
    gap = rho[:, None] - rho[None, :]                      # [j, k]: j would hide k
    diff = u[:, None, :] - u[None, :, :]
    s = diff[..., 0] ** 2 + diff[..., 1] ** 2 + diff[..., 2] ** 2
    return idx, ((gap > 0) & (s <= gap * gap)).any(axis=0)


@pytest.mark.parametrize("n, body, min_hidden", [(700, 0.4, 50), (120, 0.7, 10), (60, 1.0, 5), (40, 1.6, 1)])
def test_occlusion_hides_the_brute_force_set(n, body, min_hidden):
    """Hundreds of in-view neighbours (the 3-D direction grid of the perspective phase), fewer than
    ``GRID_3D_MIN`` (the slots sorted along one axis) and at most ``ALL_PAIRS_MAX`` (every pair tested
    without branches): the hidden set is the brute-force one, checked pair by pair in numpy."""
    rng = np.random.default_rng(11)
    pos = rng.standard_normal((n, 3))
    pos *= (6.0 * rng.random(n) ** (1 / 3) / np.linalg.norm(pos, axis=1))[:, None]
    state = state_from(pos, unit_vectors(rng, n), 1.0)
    model = make_model("binocular", direction_deg=0.0, field_deg=360.0, range=30.0, head_radius=0.0,
                       body_radius=body, search="all_pairs")
    for i in (0, 1, 2):
        got = perceived(model, state, i)
        idx, hidden = brute_force_hidden(state, i, n, body)
        assert got["idx"].tolist() == idx[~hidden].tolist(), f"boid {i}"
        assert (len(idx) >= GRID_3D_MIN) == (n > GRID_3D_MIN), "the intended path was exercised"
        assert (len(idx) <= ALL_PAIRS_MAX) == (n <= ALL_PAIRS_MAX), "the intended path was exercised"
        assert hidden.sum() >= min_hidden, "real occlusion was exercised"


def test_search_is_not_part_of_the_run_identity():
    base = load_preset("configs/models/holland.toml")
    other = load_preset("configs/models/holland.toml", ["perception.search=all_pairs"])
    assert base.model.perception.search == "auto"
    assert base.to_dict() == other.to_dict()
    assert "search" not in base.to_dict()["perception"]


def test_auto_uses_the_grid_for_big_spread_flocks_only():
    spread = flock_state(1, 400, ball_radius=30.0)
    small = flock_state(1, 40, ball_radius=3.0)
    model = make_model("sphere", radius=2.0)
    assert 400 * (1 - 27 / (60 / 2.0) ** 3) > AUTO_MIN_SAVING > 40
    assert perceived(model, spread, 0)["grid"]
    assert not perceived(model, small, 0)["grid"]


def test_grid_and_all_pairs_agree_over_a_whole_run():
    """A whole preset run (open world, the flock drifting apart and the grid rebuilt every step)."""
    init = InitParams(n=300, radius=25.0)
    runs = [simulate(make_model("opensteer", search=s), init, seed=5, duration=2.0, dt=1 / 60, record_every=30)
            for s in ("grid", "all_pairs")]
    assert_same_run(*runs)


@pytest.mark.parametrize("kind", ("opensteer", "binocular", "topological"))
def test_threaded_run_is_bit_identical_to_the_serial_one(kind):
    """A synchronous run split over 1, 2 or 3 chunks of boids per step gives the same numbers."""
    model = model_for(kind, "open", "synchronous", "auto")
    init = InitParams(n=400, radius=10.0)
    runs = [simulate(model, init, seed=8, duration=0.3, dt=1 / 30, record_every=3, threads=t) for t in (1, 2, 3)]
    assert runs[0].visible.mean() >= 2.0
    for other in runs[1:]:
        assert_same_run(runs[0], other)


def test_leadership_triggers_are_recorded_in_boid_order_when_threaded():
    model = ModelParams(dynamics="hartman_benes", perception=Perception(kind="sphere", radius=2.0),
                        leadership=Leadership(x=4.0, front_gate="none"))
    state = state_for("open", 9)
    serial = advance(model, state, 20, 1 / 30, key=5, threads=1)
    threaded = advance(model, state, 20, 1 / 30, key=5, threads=2)
    assert_same_run(serial, threaded)
    assert np.array_equal(serial.triggers, threaded.triggers) and len(serial.triggers) > 0


@pytest.mark.parametrize("n, radius", [(150, 3.5), (20000, 3.5)])
def test_every_sorting_path_gives_all_pairs_order(n, radius):
    """Neighbour lists longer than the insertion-sort limit are ordered through a bitmap (small flocks) or a
    Shell sort of keys (big ones): both give the all-pairs lists, bit for bit."""
    from flocksweep.simcore.neighbours import BITMAP_SPAN, INSERTION_SORT_MAX
    state = flock_state(3, n, ball_radius=7.0 * (n / 160) ** (1 / 3))
    lists = [perceived(make_model("sphere", radius=radius, search=s), state, i) for s in ("grid", "all_pairs")
             for i in range(0, n, n // 20)]
    half = len(lists) // 2
    for a, b in zip(lists[:half], lists[half:]):
        assert a["grid"] and not b["grid"]
        assert a["idx"].tolist() == b["idx"].tolist()
        assert np.array_equal(a["offset"], b["offset"])
    longest = max(len(x["idx"]) for x in lists)
    assert longest > INSERTION_SORT_MAX
    words = (n + 63) // 64 + 1
    assert (words <= BITMAP_SPAN * longest) == (n == 150), "the case exercises the path it names"


@pytest.mark.parametrize("kind", ("sphere", "opensteer", "binocular"))
def test_a_boid_leaving_the_grid_mid_step_hands_the_rest_of_the_step_to_all_pairs(kind):
    """Sequential order: boid 0 moves first, past the grid's coordinate limit, so the grid is dropped for
    the rest of the step; boids 1.. then search all pairs from the mirrored positions (simcore.grid.mirror),
    which must hold everyone's current position: the run equals the all-pairs run bit for bit."""
    from flocksweep.simcore.grid import CELL_MARGIN, MAX_CELL_COORD
    from flocksweep.simcore.layout import pack
    from flocksweep.simcore.perception import query_radius

    state = flock_state(21, N, ball_radius=BALL)
    grid = model_for(kind, "open", "sequential", "grid")
    fp, ip = pack(grid, 1 / 30)
    limit = MAX_CELL_COORD * query_radius(fp, ip) * (1.0 + CELL_MARGIN)
    state.pos[0] = (limit - 0.01, 0.0, 0.0)
    state.fwd[0], state.vel[0] = (1.0, 0.0, 0.0), (5.0, 0.0, 0.0)  # 5 / 30 per step: beyond the limit at once
    state.up[0], state.side[0] = (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)
    assert perceived(grid, state, 1)["grid"], "the grid was not used at the start"
    a = advance(grid, state, STEPS, 1 / 30)
    b = advance(model_for(kind, "open", "sequential", "all_pairs"), state, STEPS, 1 / 30)
    assert a.pos[1, 0, 0] > limit, "boid 0 did not leave the grid"
    assert_same_run(a, b)
    assert a.visible[:, 1:].mean() >= 2.0
