"""The tank's wall scalars (observables.walls; docs/metrics.md "Where the flock keeps from the walls"):
analytic cases in a circle and a rectangle, a loop-by-loop twin, masking and the window, a simulated run in
an arena and measured tracks that declare their tank, and the calibration's refusals."""
from __future__ import annotations

import math

import numpy as np
import pytest

from paths import ROOT
from flocksweep.observables.columns import WALL_METRIC_NAMES, summary_columns
from flocksweep.observables.walls import Walls, tank_walls, wall_distance, wall_metrics
from flocksweep.simcore import load_preset
from flocksweep.simcore.schema import ConfigError

CIRCLE = Walls("cylinder", (2.0, -1.0), 10.0, (0.0, 0.0))
RECTANGLE = Walls("box", (1.0, 1.0), 0.0, (20.0, 10.0))


def on_circles(radii, records=50, radial=False, centre=CIRCLE.centre):
    """(pos, vel, times) of individuals on circles of ``radii`` about ``centre``, moving along them
    (``radial``: straight out from the centre instead)."""
    angles = np.linspace(0.0, 2.0 * np.pi, records, endpoint=False)[:, None] + np.arange(len(radii))[None, :]
    radii = np.asarray(radii, dtype=float)[None, :]
    pos = np.zeros((records, radii.shape[1], 3))
    pos[..., 0] = centre[0] + radii * np.cos(angles)
    pos[..., 1] = centre[1] + radii * np.sin(angles)
    vel = np.zeros_like(pos)
    vel[..., 0] = np.cos(angles) if radial else -np.sin(angles)
    vel[..., 1] = np.sin(angles) if radial else np.cos(angles)
    return pos, vel, np.arange(records) * 0.1


def test_individuals_circling_keep_their_distance_and_swim_along_the_wall():
    pos, vel, times = on_circles([9.0, 8.0, 7.0, 6.0])
    out = wall_metrics(pos, vel, times, 0.0, CIRCLE)
    assert tuple(out) == WALL_METRIC_NAMES
    assert out["wall_distance_mean"] == pytest.approx(2.5, abs=1e-12)        # (1 + 2 + 3 + 4) / 4
    assert out["wall_distance_q10"] == pytest.approx(1.0, abs=1e-12)
    assert out["wall_distance_q50"] == pytest.approx(2.5, abs=1e-12)         # between 2 and 3, linear rule
    assert out["wall_facing_near"] == pytest.approx(0.0, abs=1e-12)          # along the wall
    radial = wall_metrics(*on_circles([9.0, 8.0, 7.0, 6.0], radial=True), 0.0, CIRCLE)
    assert radial["wall_facing_near"] == pytest.approx(1.0, abs=1e-12)       # straight at it


def test_headings_uniform_in_angle_face_the_wall_two_over_pi_on_average():
    rng = np.random.default_rng(7)
    samples = 200_000
    r = 10.0 * np.sqrt(rng.uniform(0.0, 1.0, samples))
    phi, heading = rng.uniform(0.0, 2.0 * np.pi, (2, samples))
    pos = np.stack([CIRCLE.centre[0] + r * np.cos(phi), CIRCLE.centre[1] + r * np.sin(phi), np.zeros(samples)], -1)
    vel = np.stack([np.cos(heading), np.sin(heading), np.zeros(samples)], -1)
    out = wall_metrics(pos[None], vel[None], np.zeros(1), 0.0, CIRCLE)
    assert out["wall_facing_near"] == pytest.approx(2.0 / math.pi, abs=0.005)   # sd of the mean ~ 0.001
    # uniform in the disc: d = R - r has mean R / 3 and median R (1 - 1/sqrt(2))
    assert out["wall_distance_mean"] == pytest.approx(10.0 / 3.0, abs=0.02)
    assert out["wall_distance_q50"] == pytest.approx(10.0 * (1.0 - 1.0 / math.sqrt(2.0)), abs=0.03)


def test_a_rectangle_measures_to_its_nearest_side_with_that_sides_normal():
    x = np.array([10.5, 1.0, -7.0, 1.0, 12.0, 1.0 + 7.5])
    y = np.array([1.0, 5.0, 1.0, -3.5, 1.0, 1.0 + 2.5])
    d, nx, ny = wall_distance(RECTANGLE, x, y)
    np.testing.assert_allclose(d, [0.5, 1.0, 2.0, 0.5, -1.0, 2.5])   # (sides 10 and 5 from the centre)
    np.testing.assert_array_equal(nx, [1.0, 0.0, -1.0, 0.0, 1.0, 1.0])   # the last: a tie, x wins
    np.testing.assert_array_equal(ny, [0.0, 1.0, 0.0, -1.0, 0.0, 0.0])


def twin(pos, vel, times, warmup, walls):
    """The definitions sample by sample, in plain Python loops."""
    dists, normals, moves = [], [], []
    for r in range(pos.shape[0]):
        if times[r] < warmup:
            continue
        for i in range(pos.shape[1]):
            x, y = pos[r, i, 0], pos[r, i, 1]
            if not (math.isfinite(x) and math.isfinite(y)):
                continue
            dx, dy = x - walls.centre[0], y - walls.centre[1]
            if walls.kind == "cylinder":
                rho = math.hypot(dx, dy)
                dists.append(walls.radius - rho)
                normals.append((dx / rho, dy / rho) if rho > 0 else (0.0, 0.0))
            else:
                gx, gy = walls.size[0] / 2 - abs(dx), walls.size[1] / 2 - abs(dy)
                dists.append(min(gx, gy))
                normals.append((math.copysign(1.0, dx) if dx != 0 else 1.0, 0.0) if gx <= gy
                               else (0.0, math.copysign(1.0, dy) if dy != 0 else 1.0))
            moves.append((vel[r, i, 0], vel[r, i, 1]))
    if not dists:
        return {name: math.nan for name in WALL_METRIC_NAMES}
    q25 = float(np.quantile(dists, 0.25))
    facing = [abs(vx * nx + vy * ny) / math.hypot(vx, vy) for d, (nx, ny), (vx, vy) in zip(dists, normals, moves)
              if d <= q25 and math.isfinite(math.hypot(vx, vy)) and math.hypot(vx, vy) > 1e-12 and (nx, ny) != (0, 0)]
    return {"wall_distance_mean": sum(dists) / len(dists), "wall_distance_q10": float(np.quantile(dists, 0.1)),
            "wall_distance_q50": float(np.quantile(dists, 0.5)),
            "wall_facing_near": sum(facing) / len(facing) if facing else math.nan}


@pytest.mark.parametrize("walls", [CIRCLE, RECTANGLE])
def test_the_wall_scalars_match_their_loop_twin_with_gaps_and_a_warmup(walls):
    rng = np.random.default_rng(3)
    pos = rng.normal(0.0, 4.0, (40, 9, 3)) + [walls.centre[0], walls.centre[1], 0.0]
    vel = rng.normal(0.0, 1.0, (40, 9, 3))
    pos[rng.uniform(size=(40, 9)) < 0.2] = np.nan       # unseen
    vel[5, 3] = 0.0                                     # stopped: no heading
    times = np.arange(40) * 0.25
    got, want = wall_metrics(pos, vel, times, 2.0, walls), twin(pos, vel, times, 2.0, walls)
    for name in WALL_METRIC_NAMES:
        assert got[name] == pytest.approx(want[name], rel=1e-12, abs=1e-12), name


def test_no_sample_in_the_window_gives_nan():
    pos, vel, times = on_circles([5.0])
    assert all(math.isnan(v) for v in wall_metrics(pos, vel, times, 100.0, CIRCLE).values())
    pos[:] = np.nan
    assert all(math.isnan(v) for v in wall_metrics(pos, vel, times, 0.0, CIRCLE).values())


def _opensteer(**changes):
    preset = load_preset(ROOT / "configs" / "models" / "opensteer.toml",
                         ["init.n=10", "init.radius=4.0", "run.duration=3.0", "world.boundary='open'"])
    return preset.replace(changes) if changes else preset


def test_a_run_in_a_tank_has_the_wall_scalars_in_its_row_and_a_run_in_the_open_has_none():
    from flocksweep.observables.summary import MetricSettings, measure_run
    from flocksweep.simcore import simulate

    preset = _opensteer(arena={"kind": "cylinder", "radius": 12.0, "wall_weight": 60.0, "wall_range": 4.0})
    run = preset.run
    obs = simulate(preset.model, preset.init, 5, run.duration, run.dt, run.record_every)
    settings = MetricSettings(warmup=1.0).resolve(preset.model)
    assert settings.walls == Walls("cylinder", (0.0, 0.0), 12.0, tuple(preset.model.arena.size[:2]))
    row = measure_run(obs, settings).row
    assert list(row)[-len(WALL_METRIC_NAMES):] == list(WALL_METRIC_NAMES)
    direct = wall_metrics(obs.pos, obs.vel, obs.times, 1.0, settings.walls)
    assert {name: row[name] for name in WALL_METRIC_NAMES} == direct
    assert 0.0 < row["wall_distance_q10"] <= row["wall_distance_q50"] < 12.0   # the wall keeps them inside
    open_world = _opensteer()
    plain = measure_run(simulate(open_world.model, open_world.init, 5, run.duration, run.dt, run.record_every),
                        MetricSettings(warmup=1.0).resolve(open_world.model)).row
    assert not set(WALL_METRIC_NAMES) & set(plain)
    assert set(WALL_METRIC_NAMES) <= set(summary_columns(walls=True)) - set(summary_columns())


def test_identities_recorded_before_the_wall_scalars_stay_as_they_were():
    from flocksweep.observables.summary import MetricSettings

    plain = MetricSettings(warmup=1.0).resolve(_opensteer().model)
    assert "walls" not in plain.identity() and plain.identity()["warmup"] == 1.0
    tank = MetricSettings(warmup=1.0).resolve(_opensteer(arena={"kind": "cylinder", "radius": 12.0}).model)
    assert tank.identity()["walls"] == ("cylinder", (0.0, 0.0), 12.0, tuple(tank.walls.size))


def test_tracks_that_declare_their_tank_are_measured_against_its_walls(tmp_path):
    """The tank fixture: fish circling at 60 + 16 i px (+ 5 px in flock B) in a tank of radius 200 px, body
    length 20 px, so flock A's distances to the wall are 7.0, 6.2, 5.4, 4.6, 3.8 and 3.0 BL."""
    from tank_tracks import write_tank_tracks
    from flocksweep.observables.measured import measure_tracks, track_settings
    from flocksweep.observables.tracks import load_tracks, track_source

    path = write_tank_tracks(tmp_path)
    runs = measure_tracks(load_tracks(path, track_source(path, {})), track_settings(2.0)).runs.set_index("flock")
    a = runs.loc["A"]
    assert a["wall_distance_q10"] == pytest.approx(3.0, abs=1e-9)
    assert a["wall_distance_q50"] == pytest.approx(4.6, abs=1e-9)
    assert a["wall_distance_mean"] == pytest.approx(5.0, abs=0.01)          # fish 2 (5.4 BL) misses a few samples
    assert a["wall_facing_near"] < 0.03                                     # along the wall (chords: ~0.015)
    assert runs.loc["B", "wall_distance_q10"] == pytest.approx(3.0 - 0.25, abs=1e-9)   # 5 px nearer the wall
    bare = write_tank_tracks(tmp_path, name="bare", arena=None)
    plain = measure_tracks(load_tracks(bare, track_source(bare, {})), track_settings(2.0)).runs
    assert not set(WALL_METRIC_NAMES) & set(plain.columns)


def test_tank_walls_of_an_open_world_is_none():
    from flocksweep.simcore.arena import Arena

    assert tank_walls(None) is None and tank_walls(Arena()) is None


def test_a_calibration_targeting_the_walls_needs_a_tank():
    from flocksweep.analysis.calibration.config import calibration_from_dict

    data = {"name": "walls", "model": {"preset": str(ROOT / "configs" / "models" / "opensteer.toml"),
                                       "set": {"init.n": 8, "init.radius": 4.0, "world.boundary": "open"}},
            "run": {"duration": 2.0, "warmup": 0.5},
            "parameters": {"speed": {"key": "vehicle.max_speed", "prior": {"dist": "uniform", "low": 1.0, "high": 3.0}}},
            "targets": {"stats": ["polarization", "wall_distance_mean"], "mean": [0.9, 3.0], "sd": [0.1, 0.5]},
            "method": {"kind": "emcee"}}
    with pytest.raises(ConfigError, match=r"targets\.stats.*'wall_distance_mean'.*no tank"):
        calibration_from_dict(data, ROOT)
    data["model"]["set"]["arena"] = {"kind": "cylinder", "radius": 12.0}
    config = calibration_from_dict(data, ROOT)
    assert config.targets.columns == ("polarization_mean", "wall_distance_mean")
