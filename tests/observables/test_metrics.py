"""Analytic cases for the flock metrics in observables.metrics."""
from __future__ import annotations

import math

import numpy as np
import pytest

from flocksweep.observables.metrics import mean_speed, polarization


def test_aligned_flock_has_polarization_one():
    vel = np.tile([0.3, -2.0, 1.0], (50, 1)) * np.linspace(0.5, 3.0, 50)[:, None]
    assert math.isclose(float(polarization(vel)), 1.0, rel_tol=1e-12)


def test_opposite_headings_cancel():
    vel = np.array([[1.0, 0, 0], [-2.0, 0, 0]])
    assert float(polarization(vel)) == 0.0


def test_random_headings_match_the_isotropic_expectation():
    # E|mean of N unit vectors uniform on the sphere| ~ sqrt(8 / (3 pi N)) for large N
    rng = np.random.default_rng(12)
    n, trials = 100, 4000
    vel = rng.standard_normal((trials, n, 3))
    values = polarization(vel)
    expected = math.sqrt(8 / (3 * math.pi * n))
    standard_error = values.std() / math.sqrt(trials)
    assert abs(values.mean() - expected) < 5 * standard_error + 0.01 * expected


def test_stopped_boids_are_left_out_and_all_stopped_is_nan():
    vel = np.array([[0.0, 0, 0], [0, 3.0, 0], [0, 1.0, 0]])
    assert float(polarization(vel)) == 1.0
    assert math.isnan(float(polarization(np.zeros((4, 3)))))


def test_time_series_shape_and_mean_speed():
    vel = np.zeros((7, 5, 3))
    vel[..., 0] = 2.0
    assert polarization(vel).shape == (7,)
    assert np.allclose(mean_speed(vel), 2.0)


# ---------------------------------------------------------------------------------------------------
# frame metrics: groups, milling, shape, segregation (observables.metrics.frame_metrics and its helpers)


import pytest  # noqa: E402
from scipy.sparse.csgraph import connected_components  # noqa: E402

from flocksweep.observables.columns import PERCEPTION_SERIES  # noqa: E402
from flocksweep.observables.groups import groups, neighbour_graph  # noqa: E402
from flocksweep.observables.metrics import (  # noqa: E402
    METRIC_NAMES, aspect_heading, binocular_share, elongation, frame_metrics, group_shape, gyration_radius,
    milling, segregation, speed_cv, summarize, visible_mean, visible_sd,
)
from flocksweep.observables.summary import default_group_radius, observation_metrics, world_box  # noqa: E402
from flocksweep.simcore import load_preset, simulate_preset  # noqa: E402
from flocksweep.simcore.params import ModelParams, Perception, World  # noqa: E402
from paths import ROOT

CONFIGS = ROOT / "configs" / "models"


def metrics_of(pos, vel=None, pattern=None, radius=2.0, box=None, visible=None, binocular=None):
    """frame_metrics of one record (N, 3) as plain floats; velocities default to +x."""
    pos = np.asarray(pos, dtype=np.float64)
    vel = np.tile([1.0, 0, 0], (len(pos), 1)) if vel is None else np.asarray(vel, dtype=np.float64)
    out = frame_metrics(pos, vel, visible, binocular, pattern, radius, box)
    return {name: float(value) for name, value in out.items()}


def cluster(rng, centre, n, spread=0.3):
    """n boids within a small ball around ``centre`` (all pairwise closer than 2 * spread * sqrt(3))."""
    return np.asarray(centre, dtype=np.float64) + rng.uniform(-spread, spread, (n, 3))


def ring(n, radius, centre=(0.0, 0.0, 0.0), speed=1.5, tilt=None):
    """n boids evenly on a circle with tangential velocities (a rigid rotation), optionally rotated."""
    angle = 2 * np.pi * np.arange(n) / n
    pos = radius * np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)
    vel = speed * np.stack([-np.sin(angle), np.cos(angle), np.zeros(n)], axis=1)
    if tilt is not None:
        pos, vel = pos @ tilt.T, vel @ tilt.T
    return pos + np.asarray(centre), vel


def random_rotation(rng):
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    return q * np.sign(np.diag(r))


def test_every_metric_is_reported_with_the_record_shape():
    rng = np.random.default_rng(0)
    pos, vel = rng.normal(size=(7, 12, 3)), rng.normal(size=(7, 12, 3))
    out = frame_metrics(pos, vel, np.ones((7, 12), np.int32), np.zeros((7, 12), np.int32),
                        np.zeros(12, np.uint32), 1.0)
    assert tuple(out) == METRIC_NAMES
    assert all(v.shape == (7,) and v.dtype == np.float64 for v in out.values())
    one = frame_metrics(pos[3], vel[3], None, None, None, 1.0)  # one record: 0-d results
    assert all(v.shape == () for v in one.values())
    assert all(np.array_equal(one[k], out[k][3], equal_nan=True) for k in METRIC_NAMES
               if k not in PERCEPTION_SERIES)
    assert np.allclose(out["polarization"], polarization(vel), rtol=1e-12, atol=0)


def test_rigid_rotation_mills_without_polarization():
    rng = np.random.default_rng(3)
    for tilt, centre in ((None, (0, 0, 0)), (random_rotation(rng), (40.0, -7.0, 3.0))):
        pos, vel = ring(24, 10.0, centre, tilt=tilt)
        m = metrics_of(pos, vel, radius=3.0)
        assert math.isclose(m["milling"], 1.0, rel_tol=1e-12)
        assert m["polarization"] < 1e-12
        assert math.isclose(float(milling(pos, -vel)), 1.0, rel_tol=1e-12)  # either sense of rotation


def test_translating_flock_does_not_mill_and_milling_is_nan_without_motion():
    pos, _ = ring(24, 10.0)
    assert float(milling(pos, np.tile([0, 0, 1.0], (24, 1)))) < 1e-12  # headings along the ring's axis
    assert math.isnan(float(milling(pos, np.zeros((24, 3)))))
    assert math.isnan(float(milling(np.zeros((1, 3)), np.ones((1, 3)))))  # a lone boid is its centroid


def test_ring_across_the_periodic_boundary_still_mills():
    box = 30.0
    pos, vel = ring(24, 5.0, centre=(box / 2, box / 2 - 1.0, 0.0))
    wrapped = pos - box * np.floor((pos + box / 2) / box)
    assert math.isclose(float(milling(wrapped, vel, box)), 1.0, rel_tol=1e-9)
    m = metrics_of(wrapped, vel, radius=1.5, box=box)
    assert m["n_groups"] == 1 and math.isclose(m["gyration_radius"], 5.0, rel_tol=1e-9)


def test_two_far_apart_clusters_are_two_groups():
    rng = np.random.default_rng(1)
    pos = np.concatenate([cluster(rng, (0, 0, 0), 3), cluster(rng, (50, 0, 0), 7)])
    m = metrics_of(pos, radius=2.0)
    assert m["n_groups"] == 2
    assert m["cohesion"] == 0.7
    assert m["stray_fraction"] == 0.0
    labels = groups(pos, 2.0)
    assert (labels[3:] == 0).all() and (labels[:3] == 1).all()  # 0 is the largest group


def test_equal_groups_rank_by_their_lowest_boid():
    pos = np.array([[50.0, 0, 0], [0, 0, 0], [50.5, 0, 0], [0.5, 0, 0]])
    assert groups(pos, 1.0).tolist() == [0, 1, 0, 1]


def test_a_lone_far_boid_is_a_stray_and_its_own_group():
    rng = np.random.default_rng(2)
    pos = np.concatenate([cluster(rng, (0, 0, 0), 9), [[0.0, 80.0, 0.0]]])
    m = metrics_of(pos, radius=2.0)
    assert m["n_groups"] == 2
    assert m["stray_fraction"] == 0.1
    assert m["cohesion"] == 0.9
    assert groups(pos, 2.0)[-1] == 1


def test_links_need_a_distance_strictly_below_the_radius():
    pos = np.array([[0.0, 0, 0], [2.0, 0, 0]])
    m = metrics_of(pos, radius=2.0)
    assert m["n_groups"] == 2 and m["stray_fraction"] == 1.0 and m["nn_distance"] == 2.0
    assert metrics_of(pos, radius=2.0 + 1e-9)["n_groups"] == 1


def test_a_chain_is_one_group_through_its_links():
    pos = np.zeros((10, 3))
    pos[:, 0] = np.arange(10) * 1.9  # each boid only reaches its two neighbours
    m = metrics_of(pos, radius=2.0)
    assert m["n_groups"] == 1 and m["cohesion"] == 1.0
    assert math.isclose(m["nn_distance"], 1.9, rel_tol=1e-12)


def test_periodic_box_links_across_the_boundary():
    box = 30.0
    pos = np.array([[-box / 2 + 0.5, 0, 0], [box / 2 - 0.5, 0, 0]])
    m = metrics_of(pos, radius=2.0, box=box)
    assert m["n_groups"] == 1 and m["cohesion"] == 1.0 and m["stray_fraction"] == 0.0
    assert math.isclose(m["nn_distance"], 1.0, rel_tol=1e-12)
    assert math.isclose(m["gyration_radius"], 0.5, rel_tol=1e-12)  # centroid of the unwrapped pair
    open_world = metrics_of(pos, radius=2.0)
    assert open_world["n_groups"] == 2 and math.isclose(open_world["nn_distance"], box - 1.0)


def test_periodic_group_longer_than_half_the_box_unwraps_along_its_links():
    box, n = 20.0, 16
    x = 5.0 + np.arange(n)  # a line of 16 boids spaced 1 apart from x = 5 to 20: crosses x = L/2
    pos = np.zeros((n, 3))
    pos[:, 0] = x - box * np.floor((x + box / 2) / box)
    vel = np.tile([1.0, 0, 0], (n, 1))
    vel[:, 1] = 0.01 * (-1.0) ** np.arange(n)  # headings still average to +x
    pos[:, 1] = 0.1 * (-1.0) ** np.arange(n)  # a little width so the aspect is defined
    m = metrics_of(pos, vel, radius=1.5, box=box)
    assert m["n_groups"] == 1
    spread2 = (n * n - 1) / 12  # variance of 0..15
    assert math.isclose(m["gyration_radius"], math.sqrt(spread2 + 0.01), rel_tol=1e-9)
    assert math.isclose(m["aspect_heading"], 15.0 / 0.2, rel_tol=1e-9)


def test_gyration_radius_elongation_and_aspect_of_exact_point_sets():
    pts = np.array([[5.0, 0, 0], [-5, 0, 0], [0, 1, 0], [0, -1, 0]])
    assert math.isclose(float(elongation(pts)), 5.0, rel_tol=1e-12)  # G = diag(12.5, 0.5, 0)
    assert math.isclose(float(gyration_radius(pts)), math.sqrt(13.0), rel_tol=1e-12)
    star = np.array([[3.0, 0, 0], [-3, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 0.5], [0, 0, -0.5]])
    for heading, expected in (((1, 0, 0), 3.0), ((0, 1, 0), 1 / 3), ((0, 0, 1), 1 / 6)):
        vel = np.tile(heading, (6, 1)).astype(float) * np.linspace(1, 2, 6)[:, None]
        assert math.isclose(float(aspect_heading(star, vel)), expected, rel_tol=1e-12)


@pytest.mark.slow
def test_shape_nan_rules():
    two = np.array([[0.0, 0, 0], [1, 0, 0]])
    assert math.isnan(float(elongation(two)))  # fewer than 3 boids
    line = np.outer(np.arange(5.0), [1, 2, 3])
    assert math.isnan(float(elongation(line)))  # l2 = 0
    assert math.isnan(float(aspect_heading(line, np.tile([1.0, 2, 3], (5, 1)))))  # no width
    cancel = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0]])
    vel = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 0, 0]])
    assert math.isnan(float(aspect_heading(cancel, vel)))  # headings cancel
    assert math.isnan(float(aspect_heading(cancel, np.zeros((3, 3)))))  # nobody moves
    assert float(gyration_radius(np.zeros((1, 3)))) == 0.0
    masked = group_shape(np.zeros((4, 3)), np.ones((4, 3)), np.zeros(4, bool))
    assert all(math.isnan(float(v)) for v in masked.values())


def test_elongation_of_gaussian_clouds():
    rng = np.random.default_rng(7)
    m = 4000
    rot = random_rotation(rng)
    cigar = rng.standard_normal((m, 3)) * [5.0, 1.0, 1.0]
    ball = rng.standard_normal((m, 3))
    # sample sd ratios are within ~2 % for 4000 points; rotation does not change the value
    assert abs(float(elongation(cigar)) - 5.0) < 0.25
    assert math.isclose(float(elongation(cigar @ rot.T)), float(elongation(cigar)), rel_tol=1e-9)
    assert abs(float(elongation(ball)) - 1.0) < 0.1


def test_aspect_heading_along_and_across_an_elongated_cloud():
    rng = np.random.default_rng(8)
    cloud = rng.standard_normal((400, 3)) * [5.0, 1.0, 1.0]
    noise = 0.1 * rng.standard_normal((400, 3))
    along = aspect_heading(cloud, np.array([3.0, 0, 0]) + noise)
    across = aspect_heading(cloud, np.array([0, 3.0, 0]) + noise)
    assert float(along) > 3.0 and float(across) < 1 / 3.0
    ball = rng.standard_normal((400, 3))
    assert 0.7 < float(aspect_heading(ball, np.array([0, 0, 2.0]) + noise)) < 1.4


def test_largest_group_polarization_and_shape_ignore_the_rest():
    rng = np.random.default_rng(4)
    big = cluster(rng, (0, 0, 0), 8)
    small = cluster(rng, (60, 0, 0), 4)
    pos = np.concatenate([big, small])
    vel = np.concatenate([np.tile([0, 2.0, 0], (8, 1)), rng.normal(size=(4, 3))])
    m = metrics_of(pos, vel, radius=2.0)
    assert math.isclose(m["polarization_largest"], 1.0, rel_tol=1e-12)
    assert m["polarization"] < 1.0
    assert math.isclose(m["gyration_radius"], float(gyration_radius(big)), rel_tol=1e-12)
    assert math.isclose(m["elongation"], float(elongation(big)), rel_tol=1e-9)


def test_segregation_of_two_single_pattern_clusters():
    rng = np.random.default_rng(5)
    pos = np.concatenate([cluster(rng, (0, 0, 0), 6), cluster(rng, (40, 0, 0), 4)])
    pattern = np.array([5] * 6 + [9] * 4, np.uint32)
    # every boid's neighbours all share its pattern: share 1; expected (n_p - 1)/(N - 1) is 5/9 and 3/9
    expected = (6 * (1 - 5 / 9) + 4 * (1 - 3 / 9)) / 10  # = 8/15
    m = metrics_of(pos, pattern=pattern, radius=2.0)
    assert math.isclose(m["segregation"], expected, rel_tol=1e-12)
    assert math.isclose(expected, 8 / 15)
    assert math.isclose(float(segregation(pos, pattern, 2.0)), 8 / 15, rel_tol=1e-12)


def test_segregation_zero_for_one_pattern_and_a_fully_linked_mix_nan_without_links():
    rng = np.random.default_rng(6)
    pos = cluster(rng, (0, 0, 0), 8)
    assert metrics_of(pos, pattern=np.full(8, 3, np.uint32))["segregation"] == 0.0
    # everyone sees everyone: share (n_p - 1)/(N - 1) exactly
    mixed = np.array([0, 1, 1, 2, 2, 2, 0, 2], np.uint32)
    assert abs(metrics_of(pos, pattern=mixed)["segregation"]) < 1e-15
    far = np.arange(5)[:, None] * np.array([10.0, 0, 0])
    assert math.isnan(metrics_of(far, pattern=np.arange(5, dtype=np.uint32))["segregation"])


def test_well_mixed_patterns_do_not_segregate():
    # patterns drawn independently of positions: zero expectation exactly, given the graph
    values = []
    table = np.array([0b00000000, 0b00111010, 0b11000101, 0b11111111], np.uint32)
    for seed in range(300):
        rng = np.random.default_rng(1000 + seed)
        pos = rng.uniform(0, 20, (60, 3))
        pattern = rng.permutation(np.repeat(table, [21, 21, 9, 9]))
        values.append(float(segregation(pos, pattern, 4.0)))
    values = np.array(values)
    standard_error = values.std() / math.sqrt(len(values))
    assert abs(values.mean()) < 4 * standard_error
    assert standard_error < 0.01  # the test can actually see a clustering of a few percent


def test_visible_mean_binocular_share_and_speed_cv():
    visible = np.array([[3, 0, 2], [0, 0, 0]], np.int32)
    binocular = np.array([[1, 0, 2], [0, 0, 0]], np.int32)
    assert np.allclose(visible_mean(visible), [5 / 3, 0.0])
    assert np.allclose(binocular_share(visible, binocular), [3 / 5, 0.0])
    pos = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    vel = np.array([[1.0, 0, 0], [3, 0, 0], [0, 2, 0]])
    m = metrics_of(pos, vel, visible=visible[0], binocular=binocular[0])
    assert math.isclose(m["binocular_share"], 0.6) and math.isclose(m["visible_mean"], 5 / 3)
    assert math.isclose(m["speed_mean"], 2.0)
    assert math.isclose(m["speed_cv"], math.sqrt(2 / 3) / 2, rel_tol=1e-12)
    assert math.isnan(metrics_of(pos, vel)["binocular_share"])  # nothing recorded


def test_visible_sd_by_hand_and_against_its_numpy_twin():
    """Population sd across boids of the perceived count: 0 when every boid perceives as many (topological
    perception), sqrt(mean squared deviation) otherwise; nan when nothing was recorded."""
    visible = np.array([[3, 3, 3, 3], [0, 2, 4, 2], [1, 1, 1, 5]], np.int32)
    expected = [0.0, math.sqrt(2.0), math.sqrt(3.0)]        # (4 + 0 + 4 + 0) / 4 = 2; (1 + 1 + 1 + 9) / 4 = 3
    assert np.allclose(visible_sd(visible), expected, rtol=1e-15, atol=0)
    rng = np.random.default_rng(5)
    pos, vel = rng.normal(size=(3, 4, 3)), rng.normal(size=(3, 4, 3))
    out = frame_metrics(pos, vel, visible, np.zeros_like(visible), None, 1.0)
    assert np.allclose(out["visible_sd"], expected, rtol=1e-15, atol=1e-15)
    many = rng.integers(0, 20, (30, 17)).astype(np.int32)
    pos, vel = rng.normal(size=(30, 17, 3)), rng.normal(size=(30, 17, 3))
    kernel = frame_metrics(pos, vel, many, np.zeros_like(many), None, 1.0)["visible_sd"]
    assert np.allclose(kernel, visible_sd(many), rtol=1e-12, atol=1e-12) and (kernel > 0).all()
    assert math.isnan(metrics_of(pos[0], vel[0])["visible_sd"])  # nothing recorded


def test_visible_sd_in_the_run_row_is_its_window_mean_and_final():
    """A hand-built run: the row's visible_sd_mean is the mean over the records after the warm-up of the
    across-boid sd, visible_sd_final its last record's."""
    from flocksweep.observables.summary import MetricSettings, summarize_run
    from flocksweep.simcore.simulate import Observations

    visible = np.array([[9, 0, 0, 0], [3, 3, 3, 3], [0, 2, 4, 2], [1, 1, 1, 5]], np.int32)   # record 0: warm-up
    pos = np.zeros((4, 4, 3))
    pos[:, :, 0] = np.arange(4.0)
    vel = np.tile([1.0, 0.0, 0.0], (4, 4, 1))
    obs = Observations(times=np.arange(4.0), pos=pos, vel=vel, visible=visible, binocular=np.zeros_like(visible),
                       leader=np.zeros((4, 4), bool), triggers=np.zeros((0, 2), np.int64),
                       pattern=np.zeros(4, np.uint32), final=None, dt=1.0, record_every=1)
    row = summarize_run(obs, MetricSettings(warmup=0.5, group_radius=2.0, escape_duration=1.0, body_radius=0.5))
    assert math.isclose(row["visible_sd_mean"], (0.0 + math.sqrt(2.0) + math.sqrt(3.0)) / 3, rel_tol=1e-14)
    assert math.isclose(row["visible_sd_final"], math.sqrt(3.0), rel_tol=1e-14)
    assert math.isclose(row["visible_mean_mean"], (3.0 + 2.0 + 2.0) / 3, rel_tol=1e-14)   # the same window
    assert math.isclose(float(speed_cv(np.array([[1.0, 0, 0], [0, 3.0, 0]]))), 0.5)
    assert math.isnan(float(speed_cv(np.zeros((3, 3)))))


def test_a_lone_boid():
    m = metrics_of(np.zeros((1, 3)), pattern=np.zeros(1, np.uint32))
    assert m["n_groups"] == 1 and m["cohesion"] == 1.0 and m["stray_fraction"] == 1.0
    assert m["polarization"] == 1.0 and m["gyration_radius"] == 0.0
    for name in ("nn_distance", "milling", "elongation", "aspect_heading", "segregation"):
        assert math.isnan(m[name]), name


def test_groups_and_nearest_neighbours_match_a_brute_force_reference():
    for seed, box in ((0, None), (1, 30.0), (2, 12.0)):
        rng = np.random.default_rng(seed)
        pos = rng.uniform(-15, 15, (5, 40, 3))
        graph = neighbour_graph(pos, 4.0, box)
        for f in range(5):
            d = pos[f][None, :, :] - pos[f][:, None, :]
            if box is not None:
                d -= box * np.floor(d / box + 0.5)
            dist = np.linalg.norm(d, axis=-1)
            np.fill_diagonal(dist, np.inf)
            n_comp, comp = connected_components(dist < 4.0, directed=False)
            assert graph.n_groups[f] == n_comp
            # the same partition: a bijection between labels
            assert len(set(zip(comp, graph.labels[f]))) == n_comp
            sizes = np.bincount(graph.labels[f])
            assert (np.diff(sizes) <= 0).all()
            assert np.allclose(graph.nn[f], dist.min(axis=1), rtol=1e-12)
            assert (graph.degree[f] == (dist < 4.0).sum(axis=1)).all()


def test_summarize_means_are_numpys_nan_skipping_mean_bit_for_bit():
    """The row's means are ``values[~isnan].mean()`` exactly (summarize skips mean's per-call overhead)."""
    rng = np.random.default_rng(43)
    times = None
    for size in [1, 2, 5, 7, 8, 9, 16, 127, 128, 129, 300, 1000]:
        times = np.arange(float(size))
        values = rng.normal(size=size) * 10.0 ** rng.integers(-8, 9, size=size)
        values[rng.random(size) < 0.2] = np.nan
        values[rng.random(size) < 0.05] = -0.0
        kept = values[~np.isnan(values)]
        got = summarize({"cohesion": values}, times, warmup=0.0)["cohesion_mean"]
        if kept.size:
            assert got == float(kept.mean()) and np.signbit(got) == np.signbit(kept.mean()), size
        else:
            assert math.isnan(got)
    assert summarize({"cohesion": np.array([np.inf, 1.0])}, np.arange(2.0), 0.0)["cohesion_mean"] == np.inf


def test_summarize_means_after_warmup_final_and_fragmentation():
    times = np.arange(10.0)
    cohesion = np.array([1.0, 0.3, 1, 1, 0.8, 0.5, 0.4, 0.45, 0.7, 0.3])
    speed = np.array([9.0, 9, 9, 1, 2, np.nan, 3, 4, 5, 6])
    out = summarize({"cohesion": cohesion, "speed_mean": speed}, times, warmup=3.0)
    assert math.isclose(out["cohesion_mean"], cohesion[3:].mean())
    assert math.isclose(out["speed_mean_mean"], 3.5)  # nan left out: (1+2+3+4+5+6)/6
    assert out["cohesion_final"] == 0.3 and out["speed_mean_final"] == 6.0
    assert out["time_to_fragmentation"] == 6.0  # 0.3 at t = 1 is before warmup, 0.5 is not below 0.5
    assert out["fragmented"] == 1.0
    assert summarize({"cohesion": cohesion}, times, 3.0, fragmentation_cohesion=0.4)["time_to_fragmentation"] == 9.0
    never = summarize({"cohesion": np.where(times < 3, 0.1, 0.9)}, times)  # default warmup 3 s
    assert math.isnan(never["time_to_fragmentation"]) and never["fragmented"] == 0.0
    late = summarize({"cohesion": cohesion}, times, warmup=20.0)
    assert math.isnan(late["cohesion_mean"]) and late["cohesion_final"] == 0.3
    with pytest.raises(ValueError):
        summarize({"speed_mean": speed}, times)


def test_default_group_radius_and_box_follow_the_model():
    assert default_group_radius(ModelParams(perception=Perception(kind="binocular", range=17.0))) == 17.0
    assert default_group_radius(ModelParams(perception=Perception(kind="sphere", radius=6.5))) == 6.5
    opensteer = Perception(kind="opensteer", separation_radius=5, alignment_radius=11, cohesion_radius=9)
    assert default_group_radius(ModelParams(perception=opensteer)) == 11.0
    assert default_group_radius(load_preset(CONFIGS / "holland.toml").model) == 20.0
    assert world_box(ModelParams(world=World(boundary="periodic_box", box_size=60.0))) == 60.0
    assert world_box(ModelParams(world=World(boundary="sphere_wrap"))) is None
    with pytest.raises(ValueError):
        frame_metrics(np.zeros((2, 3)), np.zeros((2, 3)), None, None, None, 0.0)


@pytest.mark.parametrize("preset", ["holland.toml", "holland_pattern.toml"])
def test_metrics_of_a_real_simulation(preset):
    p = load_preset(CONFIGS / preset, ["init.n=30", "run.duration=5"])
    obs = simulate_preset(p, seed=1)
    series = observation_metrics(obs, p.model)
    r = len(obs.times)
    assert all(v.shape == (r,) for v in series.values())
    for name in ("polarization", "polarization_largest", "milling", "cohesion", "stray_fraction",
                 "binocular_share"):
        assert ((series[name] >= 0) & (series[name] <= 1 + 1e-12)).all(), name
    assert ((series["n_groups"] >= 1) & (series["n_groups"] <= 30)).all()
    assert (series["cohesion"] >= 1 / 30).all()
    assert (series["nn_distance"] > 0).all() and (series["gyration_radius"] >= 0).all()
    assert (series["elongation"][np.isfinite(series["elongation"])] >= 1).all()
    assert (series["speed_mean"] > 0).all() and (series["visible_mean"] >= 0).all()
    assert np.allclose(series["polarization"], polarization(obs.vel), rtol=1e-12)
    assert np.allclose(series["speed_mean"], mean_speed(obs.vel), rtol=1e-12)
    seg = series["segregation"][np.isfinite(series["segregation"])]
    assert ((seg >= -1) & (seg <= 1)).all()
    summary = summarize(series, obs.times)
    assert set(summary) == ({f"{k}_mean" for k in series} | {f"{k}_final" for k in series}
                            | {"time_to_fragmentation", "fragmented"})


def test_a_flock_across_the_periodic_boundary_measures_as_in_open_space():
    p = load_preset(CONFIGS / "holland_pattern.toml", ["init.n=30", "run.duration=4"])
    obs = simulate_preset(p, seed=2)
    box = 1000.0  # far wider than the flock, so minimum images are the true offsets
    open_world = frame_metrics(obs.pos, obs.vel, obs.visible, obs.binocular, obs.pattern, 20.0)
    # move every record's flock centroid onto a corner of the box and wrap: the flock is cut in 8
    shifted = obs.pos - obs.pos.mean(axis=1, keepdims=True) + box / 2
    wrapped = shifted - box * np.floor((shifted + box / 2) / box)
    assert (np.abs(wrapped) > box / 4).all()  # every boid sits near a face of the box
    periodic = frame_metrics(wrapped, obs.vel, obs.visible, obs.binocular, obs.pattern, 20.0, box)
    for name in METRIC_NAMES:
        assert np.allclose(periodic[name], open_world[name], rtol=1e-9, atol=1e-9, equal_nan=True), name
