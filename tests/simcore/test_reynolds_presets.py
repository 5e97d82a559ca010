"""The shipped reynolds87 presets: they load, keep what they promise (a cohesive, polarised flock that
migrates; a course of every obstacle kind across its path that the flock flies through while avoiding
the obstacles), fixed seeds, stated tolerances."""
from __future__ import annotations

import numpy as np
import pytest

from paths import ROOT
from flocksweep.simcore import load_preset, simulate_preset
from flocksweep.simcore.obstacle_spec import pack_obstacles
from flocksweep.simcore.obstacles import clearances

OPEN = ROOT / "configs/models/reynolds87.toml"
COURSE = ROOT / "configs/models/reynolds87_obstacles.toml"


def test_presets_load_with_the_documented_keys():
    flock, course = load_preset(OPEN), load_preset(COURSE)
    for preset in (flock, course):
        rey = preset.model.reynolds
        assert preset.model.dynamics == "reynolds87" and preset.model.perception.kind == "sphere"
        assert rey.allocation == "priority" and rey.migrates and rey.migration_direction == (1.0, 0.0, 0.0)
        assert preset.to_dict()["reynolds"]["migration_weight"] == 3.0
    kinds = [o.kind for o in course.model.world.obstacles]
    assert {k: kinds.count(k) for k in set(kinds)} == {"plane": 2, "sphere": 3, "box": 3, "cylinder": 3}
    assert not flock.model.world.obstacles


def polarization(vel):
    heading = vel / np.linalg.norm(vel, axis=-1, keepdims=True)
    return np.linalg.norm(heading.mean(axis=-2), axis=-1)


@pytest.mark.slow
def test_open_preset_flock_is_cohesive_polarised_and_migrates():
    obs = simulate_preset(load_preset(OPEN), seed=1)
    late = obs.times >= 10.0
    assert polarization(obs.vel[late]).min() > 0.95
    centre = obs.pos.mean(axis=1)
    gyration = np.sqrt(((obs.pos - centre[:, None]) ** 2).sum(axis=2).mean(axis=1))
    assert gyration[late].max() < 10.0
    progress = (centre[-1, 0] - centre[late][0, 0]) / (obs.times[-1] - obs.times[late][0])
    assert progress > 0.9 * load_preset(OPEN).model.reynolds.max_speed


@pytest.mark.slow
def test_course_flock_passes_the_obstacles_and_avoids_them():
    """Through the course, steer-to-avoid keeps body overlaps rare; with obstacle_weight = 0 they are not."""
    preset = load_preset(COURSE)
    table, kinds = pack_obstacles(preset.model.world.obstacles)

    def overlap_share(p):
        obs = simulate_preset(p, seed=2, record_every=6)
        sd = clearances(table, kinds, obs.pos.reshape(-1, 3))
        return float((sd.min(axis=1) < p.model.reynolds.body_radius).mean()), obs

    avoiding, obs = overlap_share(preset)
    blind, _ = overlap_share(preset.replace({"reynolds.obstacle_weight": 0.0}))
    assert obs.pos[-1, :, 0].mean() > 140.0          # the flock got past the last obstacle
    assert avoiding < 0.002 and blind > 5 * max(avoiding, 0.001)
