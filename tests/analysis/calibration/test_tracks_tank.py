"""Calibration from tracks that declare their tank (analysis.calibration.tracks_targets.shared_tank): the model
is put in the tracks' tank (converted to body lengths) or a preset tank of another geometry is refused naming
both; its runs start and stay inside; the geometry is no free parameter; 2-D tracks need projection "xy"."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import load_calibration
from flocksweep.analysis.calibration.run import summary_simulator
from flocksweep.simcore.schema import ConfigError
from tank_tracks import write_tank_tracks

PRESET = '''name = "tank_vicsek"
dynamics = "vicsek"
{units}
[perception]
kind = "sphere"

[vicsek]
radius = {radius}
speed = {speed}
noise = 0.5

[world]
dimensions = 2
boundary = "open"

[init]
n = 6
radius = {init_radius}
speed = {speed}
{arena}
[run]
dt = 0.1
duration = 4.0
'''


def calibration(tmp_path, arena: str = "", projection: str = "xy", init_radius: float = 3.0, units: str = "",
                parameter: str = "vicsek.noise", prior: str = "low = 0.1, high = 1.0", scale: float = 1.0,
                sidecar_arena="default", stats: str = '["polarization", "nn_distance"]') -> object:
    """A calibration of a tiny 2-D Vicsek model to the pixel tracks of fish in a round tank (radius 10 BL)."""
    kwargs = {} if sidecar_arena == "default" else {"arena": sidecar_arena}
    write_tank_tracks(tmp_path, **kwargs)
    (tmp_path / "model.toml").write_text(PRESET.format(units=units, arena=arena, init_radius=init_radius * scale,
                                                       radius=3.0 * scale, speed=1.5 * scale))
    (tmp_path / "cal.toml").write_text(f'''name = "tank"
seed = 1

[model]
preset = "model.toml"

[run]
n = 6
duration = 4.0
warmup = 1.0
group_radius = 10.0

[observation]
interval = 0.1
projection = "{projection}"

[parameters.free]
key = "{parameter}"
prior = {{ dist = "uniform", {prior} }}

[targets]
summary = "mean"
stats = {stats}
from_tracks = "tank.csv"

[method]
kind = "emcee"
n_sim = 4
walkers = 4
steps = 1
''')
    return load_calibration(tmp_path / "cal.toml")


def test_a_model_without_a_tank_is_put_in_the_tracks_tank_and_its_runs_stay_inside(tmp_path):
    config = calibration(tmp_path)
    arena = config.preset.model.arena
    assert arena.kind == "cylinder" and arena.radius == pytest.approx(10.0)     # 200 px / 20 px per BL
    assert arena.centre == (0.0, 0.0, 0.0)                                      # where the flock starts
    assert config.preset_data["arena"] == {"kind": "cylinder", "centre": [0.0, 0.0, 0.0], "radius": 10.0}
    assert config.targets.flocks == ("A", "B")                                  # the pixel tracks measured, gap and all
    obs, row = summary_simulator(config).run(np.array([0.5]), 7)               # built from preset_data
    distance = np.hypot(obs.pos[..., 0], obs.pos[..., 1])
    assert distance[0].max() <= 3.0 and distance.max() <= 10.0                 # starts inside, stays inside
    assert np.isfinite(row).all()


def test_a_preset_in_metres_gets_the_tank_in_metres(tmp_path):
    config = calibration(tmp_path, units='[units]\nlength = "m"\nbody_length_m = 0.02\n', scale=0.02)
    assert config.preset_data["arena"]["radius"] == pytest.approx(0.2)         # 10 BL of 2 cm
    assert config.preset.model.arena.radius == pytest.approx(10.0)


def test_a_preset_tank_of_the_same_geometry_is_kept_and_another_refused_naming_both(tmp_path):
    same = calibration(tmp_path, arena='[arena]\nkind = "cylinder"\nradius = 10.0\ncentre = [1.0, 0.5, 0.0]\n'
                                       "wall_weight = 7.0\n")
    assert same.preset.model.arena.centre == (1.0, 0.5, 0.0) and same.preset.model.arena.wall_weight == 7.0
    with pytest.raises(ConfigError) as err:
        calibration(tmp_path, arena='[arena]\nkind = "cylinder"\nradius = 8.0\n')
    assert err.value.key == "arena"
    assert "the model's tank (circle of radius 8 about (0, 0) body lengths)" in err.value.detail
    assert "the tank tank.csv declares (circle of radius 10 about (16, 12) body lengths)" in err.value.detail
    with pytest.raises(ConfigError) as err:
        calibration(tmp_path, arena='[arena]\nkind = "box"\nsize = [20.0, 20.0, 20.0]\n')
    assert "rectangle of sides 20 x 20" in err.value.detail


def test_what_would_break_the_shared_tank_is_refused_by_key(tmp_path):
    with pytest.raises(ConfigError) as err:                                    # the start region leaves the tank
        calibration(tmp_path, init_radius=12.0)
    assert err.value.key == "init.radius" and "the model is put in the tank tank.csv declares" in err.value.detail
    with pytest.raises(ConfigError) as err:                                    # the tank seen from the side
        calibration(tmp_path, projection="xz")
    assert err.value.key == "observation.projection" and 'use projection = "xy"' in err.value.detail
    with pytest.raises(ConfigError) as err:                                    # the tank's size is the tracks'
        calibration(tmp_path, parameter="arena.radius", prior="low = 8.0, high = 12.0")
    assert err.value.key == "parameters.free.key" and "fixed by the tank tank.csv declares" in err.value.detail
    walls = calibration(tmp_path, parameter="arena.wall_weight", prior="low = 5.0, high = 30.0")
    assert walls.keys == ("arena.wall_weight",)                                # its wall term may be fitted


def test_tracks_without_a_tank_leave_the_model_in_the_open(tmp_path):
    config = calibration(tmp_path, sidecar_arena=None)
    assert not config.preset.model.arena.enabled and "arena" not in config.preset_data


def test_flocksweep_init_writes_the_tracks_tank_into_the_calibration(tmp_path):
    from flocksweep.analysis.calibration.starter import start_calibration
    from paths import ROOT

    calibration(tmp_path)                                   # writes tank.csv and the 2-D model.toml
    started = start_calibration(tmp_path / "tank.csv", tmp_path / "model.toml", tmp_path / "fit.toml")
    assert '"arena.kind" = "cylinder"' in started.text and '"arena.radius" = 10.0' in started.text
    assert 'projection = "xy"' in started.text
    config = load_calibration(started.path)
    assert config.preset.model.arena.radius == pytest.approx(10.0) and config.preset.model.arena.kind == "cylinder"
    # a 3-D model whose start ball (radius 20) does not fit: seen along the tank's axis, its start region shrunk
    holland = start_calibration(tmp_path / "tank.csv", ROOT / "configs/models/holland.toml", tmp_path / "h.toml")
    assert 'projection = "xy"' in holland.text and '"init.radius" = 5.0' in holland.text
    assert load_calibration(holland.path).preset.model.arena.radius == pytest.approx(10.0)
    # the preset's own tank of that geometry: nothing to set, a comment says so
    (tmp_path / "walled.toml").write_text((tmp_path / "model.toml").read_text().replace(
        "[run]", '[arena]\nkind = "cylinder"\nradius = 10.0\n\n[run]'))
    walled = start_calibration(tmp_path / "tank.csv", tmp_path / "walled.toml", tmp_path / "w.toml")
    assert "arena.kind" not in walled.text and "is the preset's own" in walled.text


def test_compares_training_sweep_runs_in_the_tracks_tank(tmp_path):
    from flocksweep.analysis.calibration.compare import training_sweep
    from flocksweep.sweeps.design import base_preset

    config = calibration(tmp_path)
    sweep = training_sweep(config, np.array([[0.3], [0.6]]))
    arena = base_preset(sweep).model.arena
    assert arena.kind == "cylinder" and arena.radius == pytest.approx(10.0)


def test_the_walls_are_targets_measured_alike_on_the_tracks_and_on_the_runs_in_their_tank(tmp_path):
    stats = '["wall_distance_mean", "wall_facing_near"]'
    config = calibration(tmp_path, stats=stats)
    assert config.targets.columns == ("wall_distance_mean", "wall_facing_near")
    observed = config.targets.per_flock   # flock A: fish 3.0 .. 7.0 BL from the wall, swimming along it
    assert observed[0, 0] == pytest.approx(5.0, abs=0.01) and observed[0, 1] < 0.03
    obs, row = summary_simulator(config).run(np.array([0.5]), 7)
    assert np.isfinite(row).all() and 0.0 < row[0] < 10.0 and 0.0 <= row[1] <= 1.0
    with pytest.raises(ConfigError) as err:                                    # tracks without their tank
        calibration(tmp_path, stats=stats, sidecar_arena=None, arena='[arena]\nkind = "cylinder"\nradius = 10.0\n')
    assert err.value.key == "targets.stats" and "not measured on these tracks" in err.value.detail
    with pytest.raises(ConfigError) as err:                                    # and a model left in the open
        calibration(tmp_path, stats=stats, sidecar_arena=None)
    assert err.value.key == "targets.stats" and "the model has no tank" in err.value.detail
