"""Obstacle geometry (simcore.obstacles): hand-worked cases and agreement with the numpy twin.

Hand cases use b = 0.5 (body radius) and these solids, centred at the origin unless stated:
sphere R = 1 at (10, 0, 0) (inflated radius 1.5); the ground plane y = 0 with normal +y; the cube of half
extent 1 (inflated: rounded by 0.5); the cylinder along z with R = 1, length 4 (H = 2). The arithmetic
is written next to each case. Every hand case is also run through the twin (tests/reference_obstacles.py),
which shows the twin right before it is used to check thousands of random rays.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import reference_obstacles as ref
from obstacle_scenes import box, cylinder, packed, plane, random_obstacle, random_rays, sphere
from flocksweep.simcore import obstacles as geo

B = 0.5
SPHERE = sphere((10, 0, 0), 1.0)
GROUND = plane((0, 0, 0), (0, 1, 0))
CUBE = box((0, 0, 0), (1, 1, 1))
CAN = cylinder((0, 0, 0), (0, 0, 1), 1.0, 4.0)
S3 = math.sqrt(3.0)
S2 = math.sqrt(2.0)
R07 = math.sqrt(0.07)
TANGENT = 2e-6  # tangent hits are located to about sqrt(1e-12 * b) (docs/obstacles.md)

# (name, obstacle, start, direction, lookahead, hit, t, hit point, normal, tolerance)
HAND_RAYS = [
    ("sphere head-on: 10 - 1.5", SPHERE, (0, 0, 0), (1, 0, 0), 20, True, 8.5, (8.5, 0, 0), (-1, 0, 0), 0),
    ("sphere offset 0.9: x = 10 - sqrt(2.25 - 0.81)", SPHERE, (0, 0.9, 0), (1, 0, 0), 20, True, 8.8,
     (8.8, 0.9, 0), (-0.8, 0.6, 0), 1e-12),
    ("sphere miss by 0.5", SPHERE, (0, 2, 0), (1, 0, 0), 20, False, None, None, None, 0),
    ("sphere lookahead 8.4 < 8.5", SPHERE, (0, 0, 0), (1, 0, 0), 8.4, False, None, None, None, 0),
    ("sphere hit exactly at lookahead", SPHERE, (0, 0, 0), (1, 0, 0), 8.5, True, 8.5, (8.5, 0, 0), (-1, 0, 0), 0),
    ("sphere tangent at offset 1.5", SPHERE, (0, 1.5, 0), (1, 0, 0), 20, True, 10.0, (10, 1.5, 0), (0, 1, 0), 0),
    ("sphere 1e-9 outside the tangent", SPHERE, (0, 1.5 + 1e-9, 0), (1, 0, 0), 20, False, None, None, None, 0),
    ("sphere start touching: sd = 0 <= b", SPHERE, (10, 1, 0), (1, 0, 0), 20, True, 0.0, (10, 1, 0), (0, 1, 0), 0),
    ("sphere start at the centre: normal +y", SPHERE, (10, 0, 0), (0, 0, 1), 20, True, 0.0, (10, 0, 0), (0, 1, 0), 0),
    ("sphere moving away", SPHERE, (12, 0, 0), (1, 0, 0), 20, False, None, None, None, 0),
    ("sphere lookahead 0 outside", SPHERE, (0, 0, 0), (1, 0, 0), 0, False, None, None, None, 0),
    ("sphere lookahead 0 inside", SPHERE, (9, 0, 0), (1, 0, 0), 0, True, 0.0, (9, 0, 0), (-1, 0, 0), 0),
    ("plane straight down: 5 - 0.5", GROUND, (0, 5, 0), (0, -1, 0), 20, True, 4.5, (0, 0.5, 0), (0, 1, 0), 0),
    ("plane oblique: 4.5 / 0.8", GROUND, (0, 5, 0), (0.6, -0.8, 0), 20, True, 5.625, (3.375, 0.5, 0), (0, 1, 0),
     1e-15),
    ("plane parallel outside", GROUND, (0, 5, 0), (1, 0, 0), 20, False, None, None, None, 0),
    ("plane parallel touching", GROUND, (0, 0.5, 0), (1, 0, 0), 20, True, 0.0, (0, 0.5, 0), (0, 1, 0), 0),
    ("plane parallel under the ground", GROUND, (0, -3, 0), (1, 0, 0), 20, True, 0.0, (0, -3, 0), (0, 1, 0), 0),
    ("plane climbing away", GROUND, (0, 5, 0), (0, 1, 0), 20, False, None, None, None, 0),
    ("tilted plane, normal (1,1,0)/sqrt2: 10/sqrt2 - 0.5", plane((0, 0, 0), (1, 1, 0)), (5, 5, 0),
     (-1 / S2, -1 / S2, 0), 20, True, 10 / S2 - 0.5, (5 - (10 / S2 - 0.5) / S2,) * 2 + (0,), (1 / S2, 1 / S2, 0),
     1e-12),
    ("cube face: 5 - 1.5", CUBE, (5, 0.3, -0.2), (-1, 0, 0), 20, True, 3.5, (1.5, 0.3, -0.2), (1, 0, 0), 0),
    ("cube edge: (y-1)^2 + 0.3^2 = 0.25", CUBE, (0, 5, 1.3), (0, -1, 0), 20, True, 3.6, (0, 1.4, 1.3),
     (0, 0.8, 0.6), 1e-12),
    ("cube corner: (x-1)^2 + 2 * 0.3^2 = 0.25", CUBE, (5, 1.3, 1.3), (-1, 0, 0), 20, True, 4 - R07,
     (1 + R07, 1.3, 1.3), (R07 / 0.5, 0.6, 0.6), 1e-12),
    ("cube rounded corner missed: 0.45 * sqrt2 > 0.5", CUBE, (5, 1.45, 1.45), (-1, 0, 0), 20, False, None, None,
     None, 0),
    ("cube diagonal into the corner: 4 sqrt3 - 0.5", CUBE, (5, 5, 5), (-1 / S3, -1 / S3, -1 / S3), 20, True,
     4 * S3 - 0.5, (1 + 0.5 / S3,) * 3, (1 / S3,) * 3, 1e-12),
    ("cube face grazed at exactly b", CUBE, (-5, 1.5, 0), (1, 0, 0), 20, True, 4.0, (-1, 1.5, 0), (0, 1, 0),
     TANGENT),
    ("cube face passed 1e-9 beyond b", CUBE, (-5, 1.5 + 1e-9, 0), (1, 0, 0), 20, False, None, None, None, 0),
    ("cube start inside: nearest face +x", CUBE, (0.9, 0, 0), (0, 1, 0), 20, True, 0.0, (0.9, 0, 0), (1, 0, 0), 0),
    ("box (1,2,3) from above: 10 - 2.5", box((0, 0, 0), (1, 2, 3)), (0, 10, 0), (0, -1, 0), 20, True, 7.5,
     (0, 2.5, 0), (0, 1, 0), 0),
    ("cylinder side: 5 - 1.5", CAN, (5, 0, 0), (-1, 0, 0), 20, True, 3.5, (1.5, 0, 0), (1, 0, 0), 0),
    ("cylinder cap: 6 - 2.5", CAN, (0.3, 0, 6), (0, 0, -1), 20, True, 3.5, (0.3, 0, 2.5), (0, 0, 1), 0),
    ("cylinder rim: 0.3^2 + (z-2)^2 = 0.25", CAN, (1.3, 0, 6), (0, 0, -1), 20, True, 3.6, (1.3, 0, 2.4),
     (0.6, 0, 0.8), 1e-12),
    ("cylinder parallel to the axis outside", CAN, (1.6, 0, 6), (0, 0, -1), 20, False, None, None, None, 0),
    ("cylinder parallel to the axis at R + b", CAN, (1.5, 0, 6), (0, 0, -1), 20, True, 4.0, (1.5, 0, 2),
     (1, 0, 0), TANGENT),
    ("cylinder start inside: cap nearer", CAN, (0, 0, 1.9), (1, 0, 0), 20, True, 0.0, (0, 0, 1.9), (0, 0, 1), 0),
    ("cylinder start on the axis, side nearer: +y", CAN, (0, 0, 0), (1, 0, 0), 20, True, 0.0, (0, 0, 0),
     (0, 1, 0), 0),
    ("tilted cylinder axis (1,1,0)/sqrt2: side at 1.5", cylinder((0, 0, 0), (1, 1, 0), 1.0, 4.0), (0, 0, 5),
     (0, 0, -1), 20, True, 3.5, (0, 0, 1.5), (0, 0, 1), 1e-12),
]


def compiled_cast(obstacle, start, direction, lookahead, body_radius=B):
    table, kinds = packed(obstacle)
    f = np.asarray(direction, dtype=float)
    f = f / np.linalg.norm(f)
    return geo.ray_cast(table, kinds, 0, *map(float, start), *f, body_radius, float(lookahead))


@pytest.mark.slow
@pytest.mark.parametrize("case", HAND_RAYS, ids=[c[0] for c in HAND_RAYS])
def test_hand_worked_ray_casts(case):
    name, obstacle, start, direction, lookahead, hit, t, point, normal, tol = case
    got = compiled_cast(obstacle, start, direction, lookahead)
    assert got[0] is hit
    if not hit:
        assert got[1] == math.inf and got[2:] == (0.0,) * 6
    else:
        assert abs(got[1] - t) <= tol
        assert np.allclose(got[2:5], point, rtol=0, atol=tol)
        assert np.allclose(got[5:8], normal, rtol=0, atol=max(tol, 1e-15) * (5 if tol == TANGENT else 1))
    twin_hit, twin_t, min_gap = ref.ray_cast(obstacle, [start], [np.asarray(direction) / np.linalg.norm(direction)],
                                             B, lookahead)
    if hit and not twin_hit[0]:
        assert min_gap[0] <= 1e-12  # an exact tangent: the twin's sampled minimum touches within rounding
    else:
        assert twin_hit[0] == hit
    if twin_hit[0]:
        assert abs(twin_t[0] - t) <= max(tol, 1e-9)


# (obstacle, point, sd, normal); arithmetic beside each
HAND_DISTANCES = [
    (SPHERE, (13, 0, 0), 2.0, (1, 0, 0)),                      # 3 - 1
    (SPHERE, (10, 0, 0), -1.0, (0, 1, 0)),                     # centre: -R, fallback +y
    (GROUND, (3, -2, 7), -2.0, (0, 1, 0)),
    (CUBE, (3, 3, 0), math.sqrt(8.0), (1 / S2, 1 / S2, 0)),    # to the edge (1, 1, z)
    (CUBE, (0.5, 0, 0), -0.5, (1, 0, 0)),                      # depth to the +x face
    (CUBE, (0, 0, 0), -1.0, (1, 0, 0)),                        # all faces tie: x first
    (CUBE, (0, -0.2, 0.7), -0.3, (0, 0, 1)),
    (CAN, (4, 0, 5), math.sqrt(18.0), (1 / S2, 0, 1 / S2)),    # rim: (3, 3) from (R, H)
    (CAN, (0, 0.5, 0), -0.5, (0, 1, 0)),                       # side nearer than the cap
    (CAN, (0, 0, 0), -1.0, (0, 1, 0)),                         # on the axis: +y
    (CAN, (0.5, 0, -1.8), -0.2, (0, 0, -1)),                   # bottom cap nearer
]


@pytest.mark.slow
@pytest.mark.parametrize("obstacle, point, sd, normal", HAND_DISTANCES)
def test_hand_worked_signed_distances(obstacle, point, sd, normal):
    table, kinds = packed(obstacle)
    got = geo.signed_distance(table, kinds, 0, *map(float, point))
    assert abs(got[0] - sd) <= 1e-12
    assert np.allclose(got[4:], normal, rtol=0, atol=1e-12)
    nearest = np.asarray(got[1:4])
    assert abs(ref.signed_distance(obstacle, [nearest])[0]) <= 1e-12
    assert abs(np.linalg.norm(np.asarray(point) - nearest) - abs(sd)) <= 1e-12
    assert abs(ref.signed_distance(obstacle, [point])[0] - sd) <= 1e-12


KINDS = ("sphere", "plane", "box", "cylinder")


@pytest.mark.parametrize("kind", KINDS)
def test_signed_distance_agrees_with_the_twin_on_random_points(kind):
    """4,000 points around 20 random obstacles: sd to 1e-12, nearest point on the surface, normal equal
    to the twin's numerical gradient (1e-5) away from the surface and from inside ties."""
    rng = np.random.default_rng(17 + KINDS.index(kind))
    for _ in range(20):
        obstacle = random_obstacle(rng, kind)
        table, kinds = packed(obstacle)
        points = np.asarray(obstacle.centre) + rng.normal(0.0, 4.0, (200, 3))
        got = np.array([geo.signed_distance(table, kinds, 0, *p) for p in points])
        twin = ref.signed_distance(obstacle, points)
        assert np.allclose(got[:, 0], twin, rtol=0, atol=1e-12)
        assert np.allclose(ref.signed_distance(obstacle, got[:, 1:4]), 0.0, atol=1e-11)
        assert np.allclose(np.linalg.norm(points - got[:, 1:4], axis=1), np.abs(twin), atol=1e-11)
        assert np.allclose(np.linalg.norm(got[:, 4:], axis=1), 1.0, atol=1e-14)
        clear = np.abs(twin) > 1e-3
        outside = clear & (twin > 0)
        assert np.allclose(got[outside, 4:], ref.gradient(obstacle, points[outside]), atol=1e-5)
        grad = ref.gradient(obstacle, points[clear & (twin < 0)])
        unique = np.abs(np.linalg.norm(grad, axis=1) - 1) < 1e-9
        inside_normals = got[clear & (twin < 0), 4:]
        agree = np.all(np.abs(inside_normals - grad) < 1e-5, axis=1)
        # inside, the twin's gradient is exact where the nearest face is unique; ties are rare
        assert agree.mean() > 0.97 if len(agree) > 30 else True
        assert unique.all()


@pytest.mark.parametrize("kind", KINDS)
def test_ray_casts_agree_with_the_twin_on_random_rays(kind):
    """1,500 random rays per kind against random obstacles (fixed seed). Hit or miss must agree except
    within 1e-7 of a tangent or of the lookahead end; hit distances agree within 1e-9 for transversal
    hits (|dg/dt| >= 0.01) and 1e-6 otherwise; the compiled hit point is on the inflated surface (1e-9)
    and its normal is the twin's gradient (1e-5)."""
    rng = np.random.default_rng(101 + KINDS.index(kind))
    compared = hits = 0
    for _ in range(15):
        obstacle = random_obstacle(rng, kind)
        table, kinds = packed(obstacle)
        starts, dirs, radii, looks = random_rays(rng, obstacle, 100)
        twin_hit, twin_t, min_gap = ref.ray_cast(obstacle, starts, dirs, radii, looks)
        start_gap = ref.signed_distance(obstacle, starts) - radii
        end_gap = ref.signed_distance(obstacle, starts + looks[:, None] * dirs) - radii
        clear = (np.abs(min_gap) >= 1e-7) & (np.abs(start_gap) >= 1e-9) & (np.abs(end_gap) >= 1e-7)
        step = 1e-6
        t_safe = np.where(twin_hit, twin_t, 0.0)
        slope = (ref.signed_distance(obstacle, starts + (t_safe + step)[:, None] * dirs)
                 - ref.signed_distance(obstacle, starts + np.maximum(t_safe - step, 0.0)[:, None] * dirs)) / (2 * step)
        for i in np.flatnonzero(clear):
            p, f, b, look, t = starts[i], dirs[i], radii[i], looks[i], twin_t[i]
            got = geo.ray_cast(table, kinds, 0, *p, *f, b, look)
            compared += 1
            assert got[0] == twin_hit[i], (obstacle, p, f, b, look)
            if not got[0]:
                continue
            hits += 1
            tol = 1e-9 if (abs(slope[i]) >= 1e-2 or t == 0.0) else 1e-6
            assert abs(got[1] - t) <= tol * (1 + t), (obstacle, p, f, b, look, got[1], t)
            point = np.asarray(got[2:5])
            assert np.allclose(point, p + got[1] * f, atol=1e-12)
            if got[1] > 0.0:
                assert abs(ref.signed_distance(obstacle, [point])[0] - b) <= 1e-9
                assert np.allclose(got[5:8], ref.gradient(obstacle, [point])[0], atol=1e-5)
    assert compared > 1300 and hits > 300  # the sample really exercises both outcomes


def test_first_hit_takes_the_nearest_obstacle_and_the_lower_index_on_ties():
    table, kinds = packed(sphere((20, 0, 0), 1.0), CUBE, sphere((0, 0, -20), 1.0), box((20, 0, 0), (1, 1, 1)))
    got = geo.first_hit(table, kinds, -10.0, 0.0, 0.0, 1.0, 0.0, 0.0, B, 50.0)
    assert got[0] == 1 and got[1] == 8.5                    # the cube at x = -1.5 beats the far sphere
    got = geo.first_hit(table, kinds, 30.0, 0.0, 0.0, -1.0, 0.0, 0.0, B, 50.0)
    assert got[0] == 0 and got[1] == 8.5                    # sphere and box both at x = 21.5: index 0
    got = geo.first_hit(table, kinds, 0.0, 5.0, 0.0, 0.0, 1.0, 0.0, B, 50.0)
    assert got[0] == -1 and got[1] == math.inf
    empty_table, empty_kinds = packed()
    assert geo.first_hit(empty_table, empty_kinds, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, B, 50.0)[0] == -1


def test_first_hit_agrees_with_the_twin_in_random_scenes():
    """15 scenes of 6 mixed obstacles, 48 rays each: same obstacle and distance (1e-6), except rays
    within 1e-7 of a tangent or with two hits at t > 0 within 1e-7 of each other (starts inside several
    half-spaces are exact ties at t = 0 and stay in: both take the lower index)."""
    rng = np.random.default_rng(7)
    compared = 0
    for _ in range(15):
        obstacles = [random_obstacle(rng, KINDS[rng.integers(4)]) for _ in range(6)]
        obstacles = [replace(o, centre=tuple(4.0 * np.asarray(o.centre))) for o in obstacles]
        table, kinds = packed(*obstacles)
        starts = rng.uniform(-20, 20, (48, 3))
        dirs = rng.standard_normal((48, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        casts = [ref.ray_cast(o, starts, dirs, B, 25.0) for o in obstacles]
        all_t = np.column_stack([c[1] for c in casts])
        closeness = np.min(np.abs(np.column_stack([c[2] for c in casts])), axis=1)
        k_twin = np.where(np.isfinite(all_t.min(axis=1)), all_t.argmin(axis=1), -1)
        ordered = np.sort(all_t, axis=1)
        with np.errstate(invalid="ignore"):  # inf - inf for rays that hit nothing
            near_tie = (ordered[:, 0] > 0.0) & (ordered[:, 1] - ordered[:, 0] < 1e-7)
        for i, (p, f) in enumerate(zip(starts, dirs)):
            if closeness[i] < 1e-7 or near_tie[i]:
                continue
            got = geo.first_hit(table, kinds, *p, *f, B, 25.0)
            compared += 1
            assert got[0] == k_twin[i]
            if k_twin[i] >= 0:
                assert abs(got[1] - ordered[i, 0]) <= 1e-6 * (1 + ordered[i, 0])
    assert compared > 650


def test_deepest_overlap_and_nearest_clearance():
    table, kinds = packed(SPHERE, GROUND, CUBE)
    # at (0.9, 0.2, 0): cube sd = -0.1 (+x face), ground sd = 0.2, sphere sd = 8.1
    k, sd, nx, ny, nz = geo.deepest_overlap(table, kinds, 0.9, 0.2, 0.0, B)
    assert (k, round(sd, 12), (nx, ny, nz)) == (2, -0.1, (1.0, 0.0, 0.0))
    assert geo.nearest_clearance(table, kinds, 0.9, 0.2, 0.0)[0] == 2
    # at (5, 0.4, 0): ground sd = 0.4 <= b is the only overlap
    assert geo.deepest_overlap(table, kinds, 5.0, 0.4, 0.0, B)[:2] == (1, 0.4)
    assert geo.deepest_overlap(table, kinds, 5.0, 3.0, 0.0, B)[0] == -1
    k, sd = geo.nearest_clearance(table, kinds, 5.0, 3.0, 0.0)
    assert k == 1 and sd == 3.0


@pytest.mark.slow
def test_clearances_table_for_metrics():
    obstacles = (SPHERE, GROUND, CUBE, CAN)
    table, kinds = packed(*obstacles)
    points = np.random.default_rng(3).normal(0.0, 5.0, (50, 3))
    got = geo.clearances(table, kinds, points)
    assert got.shape == (50, 4)
    for k, obstacle in enumerate(obstacles):
        assert np.allclose(got[:, k], ref.signed_distance(obstacle, points), atol=1e-12)
