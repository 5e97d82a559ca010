"""Obstacles as data: validation with keyed errors, normalisation, canonical form and the packed table."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from flocksweep.simcore.obstacle_spec import (COLUMN_NAMES, KIND_BOX, KIND_CYLINDER, KIND_PLANE, KIND_SPHERE, OBS_AX, OBS_AZ,
                                   OBS_BOUND, OBS_CX, OBS_CZ, OBS_HALF_LENGTH, OBS_HX, OBS_HZ, OBS_NX, OBS_NZ,
                                   OBS_RADIUS, OBSTACLE_COLUMNS, OBSTACLE_KINDS, Obstacle, canonical_obstacles,
                                   obstacle_from_dict, obstacles_from_dicts, pack_obstacles)
from flocksweep.simcore.schema import ConfigError, build

GOOD = [
    {"kind": "sphere", "centre": [1, 2, 3], "radius": 2},
    {"kind": "plane", "centre": [0, 0, 0], "normal": [0, 3, 4]},
    {"kind": "box", "centre": [5, 0, 0], "half_extents": [1, 2, 3]},
    {"kind": "cylinder", "centre": [0, 5, 0], "axis": [0, 0, 2], "radius": 1.5, "length": 4},
]


def error_of(items) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        obstacles_from_dicts(items)
    return info.value


def test_every_kind_loads_with_its_own_keys():
    obstacles = obstacles_from_dicts(GOOD)
    assert [o.kind for o in obstacles] == list(OBSTACLE_KINDS)
    assert obstacles[0].centre == (1.0, 2.0, 3.0) and obstacles[0].radius == 2.0
    assert obstacles[2].half_extents == (1.0, 2.0, 3.0)
    assert obstacles[3].length == 4.0


def test_normal_and_axis_are_normalised_on_load():
    plane, cylinder = obstacles_from_dicts([GOOD[1], GOOD[3]])
    assert plane.normal == (0.0, 0.6, 0.8)
    assert cylinder.axis == (0.0, 0.0, 1.0)


def test_normalisation_is_idempotent_so_the_canonical_form_reloads_to_the_same_bits():
    obstacle = obstacle_from_dict({"kind": "cylinder", "centre": [0, 0, 0], "axis": [1, 1, 1], "radius": 1,
                                   "length": 2})
    again = obstacle_from_dict(json.loads(json.dumps(obstacle.canonical())))
    assert again == obstacle
    assert abs(math.hypot(*obstacle.axis) - 1.0) <= 1e-15


def test_canonical_form_has_only_the_kinds_keys_in_order():
    forms = canonical_obstacles(obstacles_from_dicts(GOOD))
    assert forms[0] == {"kind": "sphere", "centre": [1.0, 2.0, 3.0], "radius": 2.0}
    assert forms[1] == {"kind": "plane", "centre": [0.0, 0.0, 0.0], "normal": [0.0, 0.6, 0.8]}
    assert list(forms[3]) == ["kind", "centre", "axis", "radius", "length"]
    assert json.loads(json.dumps(forms)) == forms


@pytest.mark.parametrize("index, table, key, words", [
    (0, {"kind": "sphre", "centre": [0, 0, 0], "radius": 1}, "kind", ["'sphre'", "did you mean 'sphere'"]),
    (1, {"kind": "sphere", "centre": [0, 0, 0], "radius": -1}, "radius", ["-1", "> 0"]),
    (2, {"kind": "sphere", "centre": [0, 0, 0]}, "radius", ["missing", "centre, radius"]),
    (3, {"kind": "box", "centre": [0, 0, 0], "half_extents": [1, 1, 1], "radius": 2}, "radius",
     ["does not apply to kind 'box'", "half_extents"]),
    (4, {"kind": "plane", "centre": [0, 0, 0], "normal": [0, 0, 0]}, "normal", ["non-zero"]),
    (5, {"kind": "box", "centre": [0, 0, 0], "half_extents": [1, 0, 1]}, "half_extents", ["component 1", "> 0"]),
    (6, {"kind": "sphere", "centre": [0, 0], "radius": 1}, "centre", ["[0.0, 0.0]", "3 numbers"]),
    (7, {"kind": "cylinder", "centre": [0, 0, 0], "axis": [0, 0, 1], "radius": 1, "length": math.inf}, "length",
     ["inf", "finite"]),
    (8, {"kind": "sphere", "centre": [0, 0, math.nan], "radius": 1}, "centre", ["finite"]),
    (9, {"kind": "sphere", "centre": [0, 0, 0], "raduis": 1}, "raduis", ["unknown key", "did you mean 'radius'"]),
    (10, {"kind": "sphere", "centre": [0, 0, 0], "radius": "big"}, "radius", ["expected a number", "'big'"]),
    (11, {"centre": [0, 0, 0], "radius": 1}, "kind", ["missing"]),
    (12, {"kind": "plane", "centre": [0, 0, 0], "normal": [0, 1, 0], "axis": [0, 1, 0]}, "axis",
     ["does not apply to kind 'plane'"]),
])
def test_bad_obstacle_tables_name_the_key_the_value_and_what_is_allowed(index, table, key, words):
    items = [GOOD[0]] * index + [table]
    err = error_of(items)
    assert err.key == f"world.obstacles[{index}].{key}"
    message = str(err)
    assert message.startswith(f"world.obstacles[{index}].{key}: ")
    for word in words:
        assert word in message


def test_an_obstacle_that_is_not_a_table_and_a_list_that_is_not_an_array_are_errors():
    assert error_of([GOOD[0], 3]).key == "world.obstacles[1]"
    with pytest.raises(ConfigError) as info:
        obstacles_from_dicts({"kind": "sphere"})
    assert info.value.key == "world.obstacles" and "[[world.obstacles]]" in str(info.value)


@dataclass(frozen=True)
class WorldWithObstacles:
    """How the models will carry obstacles: a tuple field of the world table."""

    boundary: str = "open"
    obstacles: tuple[Obstacle, ...] = field(default_factory=tuple)


def test_schema_build_on_a_world_table_keys_errors_as_world_obstacles_i_key():
    world = build(WorldWithObstacles, {"obstacles": GOOD}, "world")
    assert world.obstacles == obstacles_from_dicts(GOOD)
    with pytest.raises(ConfigError) as info:
        build(WorldWithObstacles, {"obstacles": [GOOD[0], {"kind": "box", "centre": [0, 0, 0],
                                                           "half_extents": [1, 1, 1], "normal": [1, 0, 0]}]},
              "world")
    assert info.value.key == "world.obstacles[1].normal"


def test_direct_construction_validates_too():
    with pytest.raises(ConfigError) as info:
        Obstacle("cylinder", centre=(0, 0, 0), axis=(0, 0, 1), radius=1.0)
    assert info.value.key == "length"
    unit = Obstacle("plane", centre=(0, 0, 0), normal=(0.6, 0.8, 0.0))
    assert unit.normal == (0.6, 0.8, 0.0)


def test_packed_table_layout():
    obstacles = obstacles_from_dicts(GOOD)
    table, kinds = pack_obstacles(obstacles)
    assert table.shape == (4, OBSTACLE_COLUMNS) == (4, len(COLUMN_NAMES)) and table.dtype == np.float64
    assert kinds.tolist() == [KIND_SPHERE, KIND_PLANE, KIND_BOX, KIND_CYLINDER] and kinds.dtype == np.int64
    assert table[:, OBS_CX:OBS_CZ + 1].tolist() == [[1, 2, 3], [0, 0, 0], [5, 0, 0], [0, 5, 0]]
    assert table[0, OBS_RADIUS] == 2.0 and table[0, OBS_BOUND] == 2.0
    assert table[1, OBS_NX:OBS_NZ + 1].tolist() == [0.0, 0.6, 0.8] and table[1, OBS_BOUND] == math.inf
    assert table[2, OBS_HX:OBS_HZ + 1].tolist() == [1, 2, 3] and table[2, OBS_BOUND] == math.sqrt(14.0)
    assert table[3, OBS_AX:OBS_AZ + 1].tolist() == [0, 0, 1]
    assert table[3, OBS_RADIUS] == 1.5 and table[3, OBS_HALF_LENGTH] == 2.0
    assert table[3, OBS_BOUND] == math.hypot(1.5, 2.0)
    # columns a kind does not use stay zero
    used = {0: {"centre_x", "centre_y", "centre_z", "radius", "bound_radius"},
            2: {"centre_x", "centre_y", "centre_z", "half_x", "half_y", "half_z", "bound_radius"}}
    for row, names in used.items():
        for col, name in enumerate(COLUMN_NAMES):
            if name not in names and table[row, col] != 0.0:
                pytest.fail(f"row {row} column {name} is {table[row, col]}")


def test_no_obstacles_pack_to_empty_arrays_of_the_right_shape():
    table, kinds = pack_obstacles(())
    assert table.shape == (0, OBSTACLE_COLUMNS) and kinds.shape == (0,)


def test_a_preset_without_obstacles_keeps_its_canonical_form():
    """world.obstacles is left out of the canonical dict when empty, so existing run ids stay."""
    from flocksweep.simcore.params import load_preset
    from paths import ROOT

    preset = load_preset(ROOT / "configs/models/opensteer.toml")
    assert preset.model.world.obstacles == ()
    assert "obstacles" not in preset.to_dict()["world"]


def test_obstacles_on_a_model_that_does_not_avoid_them_are_an_error():
    from flocksweep.simcore.params import preset_from_dict
    from flocksweep.simcore.schema import ConfigError

    with pytest.raises(ConfigError, match=r"world\.obstacles.*'opensteer'"):
        preset_from_dict({"world": {"obstacles": [{"kind": "sphere", "centre": [0, 0, 9], "radius": 2.0}]}})
