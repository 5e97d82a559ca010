"""Tanks (simcore.arena, simcore.walls; docs/model.md section 16): an arena with walls that every
dynamics avoids, with a reflecting fallback.

Fast: the table is validated (kinds, keys naming errors, an open world, the start region inside); it is
absent from the canonical form when off (run ids kept) and recorded with its kind's keys when on; it
converts from metres; it is sweepable as any preset key. Slow: the kernel's wall term and fallback agree
with the numpy twin (tests/reference_walls.py) on boids near, at and beyond every wall, in 2-D and 3-D;
with noise, the wall term alone (no fallback) keeps every boid inside over a long run; every built-in
dynamics runs in an arena and stays inside.
"""
from __future__ import annotations

import numpy as np
import pytest

import reference_walls
from paths import ROOT
from flocksweep.simcore import ConfigError, load_preset, simulate
from flocksweep.simcore.arena import Arena
from flocksweep.simcore.params import preset_from_dict

MODELS = ROOT / "configs" / "models"
CIRCLE = {"kind": "cylinder", "radius": 12.0, "wall_weight": 60.0, "wall_range": 4.0}
BOX = {"kind": "box", "size": [30.0, 20.0, 16.0], "centre": [1.0, -1.0, 0.5], "wall_weight": 60.0,
       "wall_range": 4.0}


def opensteer(**changes):
    preset = load_preset(MODELS / "opensteer.toml", ["init.n=12", "init.radius=4.0", "run.duration=2.0",
                                                     "world.boundary='open'"])
    return preset.replace(changes) if changes else preset


def test_an_arena_is_off_by_default_and_absent_from_the_canonical_form():
    preset = opensteer()
    assert not preset.model.arena.enabled and "arena" not in preset.to_dict()
    on = opensteer(arena=CIRCLE)
    assert on.to_dict()["arena"] == {"kind": "cylinder", "centre": [0.0, 0.0, 0.0], "radius": 12.0,
                                     "wall_weight": 60.0, "wall_range": 4.0, "reflect": True}
    box = opensteer(arena=BOX).to_dict()["arena"]
    assert box["size"] == [30.0, 20.0, 16.0] and "radius" not in box


@pytest.mark.parametrize("changes, key", [
    ({"arena": {"kind": "bowl"}}, "arena.kind"),
    ({"arena": {"kind": "cylinder", "radius": 0.0}}, "arena.radius"),
    ({"arena": {"kind": "box", "size": [10.0, -1.0, 3.0]}}, "arena.size"),
    ({"arena": {"kind": "box", "centre": [0.0, 1.0]}}, "arena.centre"),
    ({"arena": {"kind": "cylinder", "wall_range": 0.0}}, "arena.wall_range"),
    ({"arena": {"kind": "cylinder", "radius": 30.0}, "world.boundary": "sphere_wrap"}, "world.boundary"),
    ({"arena": {"kind": "cylinder", "radius": 3.0}}, "init.radius"),     # the start region would not fit
    ({"arena": {"kind": "cylinder", "radius": 30.0, "colour": 1}}, "arena.colour"),
])
def test_bad_arenas_are_refused_naming_the_key(changes, key):
    with pytest.raises(ConfigError) as err:
        opensteer(**changes)
    assert err.value.key == key


def test_an_arena_in_metres_is_its_twin_in_body_lengths():
    data = {"dynamics": "couzin2002", "perception": {"kind": "sphere"}, "world": {"dimensions": 2},
            "arena": {"kind": "cylinder", "radius": 3.0, "centre": [0.5, 0.25, 0.0], "wall_range": 0.5,
                      "wall_weight": 2.0},
            "init": {"n": 10, "radius": 1.0}}
    metres = preset_from_dict({**data, "units": {"length": "m", "body_length_m": 0.25}})
    assert metres.model.arena.radius == 12.0 and metres.model.arena.centre == (2.0, 1.0, 0.0)
    assert metres.model.arena.wall_weight == 8.0 and metres.model.arena.wall_range == 2.0


def test_an_arena_key_is_sweepable():
    preset = opensteer(arena=CIRCLE)
    assert preset.replace({"arena.radius": 15.0}).model.arena.radius == 15.0
    assert preset.replace({"arena.radius": 15.0}).to_dict() != preset.to_dict()


def _kernel_contain(arena_table, dimensions, pos, vel, dynamics="opensteer", perception="opensteer"):
    """The kernel's walls applied to every boid of (pos, vel) once, from Python."""
    from flocksweep.simcore import hooks, walls

    preset = opensteer(arena=arena_table, dynamics=dynamics, perception={"kind": perception},
                       **{"world.dimensions": dimensions})
    params = hooks.pack(preset.model, preset.run.dt)
    n = len(pos)
    group = (pos.copy(), vel.copy(), np.tile([1.0, 0.0, 0.0], (n, 1)), np.tile([0.0, 0.0, 1.0], (n, 1)),
             np.tile([0.0, -1.0, 0.0], (n, 1)))
    for i in range(n):
        walls.contain(i, group, params)
    return group[0], group[1], preset


@pytest.mark.slow
@pytest.mark.parametrize("table, dimensions", [(CIRCLE, 2), (CIRCLE, 3), ({**CIRCLE, "height": 10.0}, 3),
                                               (BOX, 2), (BOX, 3)])
def test_the_walls_match_their_numpy_twin(table, dimensions):
    rng = np.random.default_rng(7)
    n = 200
    pos = rng.uniform(-20.0, 20.0, (n, 3))
    vel = rng.normal(0.0, 5.0, (n, 3))
    if dimensions == 2:
        pos[:, 2] = vel[:, 2] = 0.0
        table = {**table, "centre": [*table.get("centre", [0.0, 0.0])[:2], 0.0]}
    new_pos, new_vel, preset = _kernel_contain(table, dimensions, pos, vel)
    arena, dt = preset.model.arena, preset.run.dt
    for i in range(n):
        p, v = reference_walls.contain(arena, pos[i], vel[i], dt, dimensions == 2, constant_speed=False)
        np.testing.assert_allclose(new_pos[i], p, rtol=0, atol=1e-12)
        np.testing.assert_allclose(new_vel[i], v, rtol=0, atol=1e-12)
        assert arena.contains(new_pos[i], dimensions) or not arena.reflect


@pytest.mark.slow
def test_a_heading_model_keeps_its_speed_at_a_wall():
    rng = np.random.default_rng(3)
    pos = rng.uniform(-13.0, 13.0, (50, 3))
    pos[:, 2] = 0.0
    vel = np.zeros((50, 3))
    vel[:, 0] = 3.0
    new_pos, new_vel, preset = _kernel_contain(CIRCLE, 2, pos, vel, dynamics="couzin2002", perception="sphere")
    np.testing.assert_allclose(np.linalg.norm(new_vel, axis=1), 3.0, rtol=1e-12)
    for i in range(50):
        p, v = reference_walls.contain(preset.model.arena, pos[i], vel[i], preset.run.dt, True, constant_speed=True)
        np.testing.assert_allclose(new_vel[i], v, rtol=0, atol=1e-12)


def _inside(arena, pos, dimensions):
    return all(arena.contains(p, dimensions) for p in pos.reshape(-1, 3))


@pytest.mark.slow
@pytest.mark.parametrize("table, dimensions", [(CIRCLE, 2), ({**BOX, "centre": [0.0, 0.0, 0.0]}, 3)])
def test_the_wall_term_alone_keeps_a_noisy_flock_inside_over_a_long_run(table, dimensions):
    """No fallback (reflect = false): the wall term by itself holds 20 noisy boids for 120 s (7,200 steps)."""
    preset = opensteer(arena={**table, "reflect": False}, noise={"angular_sd_deg": 60.0, "speed_sd": 2.0},
                       **{"world.dimensions": dimensions, "init.n": 20, "run.duration": 120.0,
                          "run.record_interval": 0.25})
    obs = simulate(preset.model, preset.init, 5, preset.run.duration, preset.run.dt, 15)
    assert _inside(preset.model.arena, obs.pos, dimensions)
    spread = np.abs(obs.pos[-40:]).max()
    assert spread > 0.5 * preset.model.arena.inner_extent(dimensions)   # it went near the walls


@pytest.mark.slow
@pytest.mark.parametrize("name", ["hartman_benes", "reynolds87", "boidspp", "couzin2002_torus_2d", "vicsek"])
def test_every_dynamics_stays_in_its_tank(name):
    preset = load_preset(MODELS / f"{name}.toml", ["init.n=16", "init.radius=3.0", "world.boundary='open'"])
    dimensions = preset.model.world.dimensions
    speed = 0.03 if name == "vicsek" else 5.0
    preset = preset.replace({"arena": {"kind": "cylinder", "radius": 8.0, "height": 8.0, "wall_range": 2.0,
                                       "wall_weight": 4.0 * speed}, "run.duration": 40 * preset.run.dt * 10,
                             "run.record_interval": preset.run.dt * 10})
    obs = simulate(preset.model, preset.init, 2, preset.run.duration, preset.run.dt, 10)
    assert _inside(preset.model.arena, obs.pos, dimensions)
