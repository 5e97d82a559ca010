"""Parameter validation: every bad input raises a ConfigError that names the dotted key and says what
is allowed; good input (the shipped presets, override strings) loads into frozen dataclasses.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from flocksweep.simcore import ConfigError, Preset, load_preset, preset_from_dict
from flocksweep.simcore.params import InitParams, ModelParams, Perception, RunSettings
from paths import ROOT

MODELS = ROOT / "configs" / "models"
HOLLAND = MODELS / "holland.toml"


def config_error(data: dict) -> ConfigError:
    """The ConfigError that ``preset_from_dict(data)`` raises."""
    with pytest.raises(ConfigError) as info:
        preset_from_dict(data)
    return info.value


def binocular(**kw) -> dict:
    return {"perception": {"kind": "binocular", **kw}}


# --- unknown keys -----------------------------------------------------------------------------------

def test_unknown_top_level_key_is_named_with_a_suggestion():
    err = config_error({"perceptoin": {}})
    assert err.key == "perceptoin"
    assert "unknown key" in str(err)
    assert "did you mean 'perception'" in str(err)


def test_unknown_perception_key_suggests_the_close_one():
    err = config_error(binocular(feild_deg=90.0))
    assert err.key == "perception.feild_deg"
    assert "did you mean 'field_deg'" in str(err)


def test_unknown_key_in_init_and_run_tables():
    assert config_error({"init": {"count": 10}}).key == "init.count"
    assert config_error({"run": {"step": 0.1}}).key == "run.step"


def test_unknown_key_in_a_pattern_entry():
    err = config_error({"patterns": {"set": [{"bits": "01", "fraction": 1.0, "colour": "red"}]}})
    assert err.key == "patterns.set[0].colour"


# --- ranges -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("n", [0, -5])
def test_flock_size_must_be_positive(n):
    err = config_error({"init": {"n": n}})
    assert err.key == "init.n"
    assert repr(n) in str(err)


@pytest.mark.parametrize("field_deg", [0.0, -10.0, 361.0])
def test_field_outside_0_to_360_is_rejected(field_deg):
    err = config_error(binocular(field_deg=field_deg))
    assert err.key == "perception.field_deg"
    assert "(0.0, 360.0]" in str(err)


def test_field_of_exactly_360_is_allowed():
    assert preset_from_dict(binocular(field_deg=360.0)).model.perception.field_deg == 360.0


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_range_must_be_a_finite_positive_number(value):
    assert config_error(binocular(range=value)).key == "perception.range"


@pytest.mark.parametrize("key, value", [("direction_deg", 91.0), ("direction_deg", -1.0),
                                        ("eye_position_deg", 90.5), ("head_radius", -0.1),
                                        ("body_radius", 0.0)])
def test_other_binocular_ranges(key, value):
    assert config_error(binocular(**{key: value})).key == f"perception.{key}"


@pytest.mark.parametrize("dt", [0.0, -0.01])
def test_time_step_must_be_positive(dt):
    assert config_error({"run": {"dt": dt}}).key == "run.dt"


@pytest.mark.parametrize("interval", [0.015, 0.005])  # 1.5 steps; half a step
def test_record_interval_must_be_a_whole_multiple_of_dt(interval):
    err = config_error({"run": {"dt": 0.01, "record_interval": interval}})
    assert err.key == "run.record_interval"
    assert "multiple" in str(err)


def test_record_interval_of_whole_steps_gives_the_step_count():
    run = preset_from_dict({"run": {"dt": 0.01, "record_interval": 0.25, "duration": 2.0}}).run
    assert (run.record_every, run.n_steps) == (25, 200)


# --- patterns ---------------------------------------------------------------------------------------

def pattern_set(*entries) -> dict:
    return {"patterns": {"enabled": True, "set": [{"bits": b, "fraction": f} for b, f in entries]}}


@pytest.mark.parametrize("bits", ["0" * 33, "0012", "01 1", ""], ids=["33_bits", "digit_2", "space", "empty"])
def test_bad_bit_strings_are_rejected(bits):
    err = config_error(pattern_set((bits, 1.0)))
    assert err.key == "patterns.set[0].bits"
    assert "1 to 32" in str(err)


def test_thirty_two_bits_are_allowed():
    patterns = preset_from_dict(pattern_set(("1" * 32, 1.0))).model.patterns
    assert patterns.n_bits == 32
    assert patterns.set[0].value == 2**32 - 1


def test_fractions_must_sum_to_one():
    err = config_error(pattern_set(("01", 0.5), ("10", 0.4)))
    assert err.key == "patterns.set"
    assert "sum" in str(err)


def test_fraction_outside_0_1_names_the_entry():
    assert config_error(pattern_set(("01", 1.5), ("10", -0.5))).key == "patterns.set[0].fraction"


def test_patterns_must_all_have_the_same_length():
    err = config_error(pattern_set(("01", 0.5), ("011", 0.5)))
    assert err.key == "patterns.set"
    assert "same length" in str(err)


def test_empty_pattern_set_is_rejected():
    assert config_error({"patterns": {"set": []}}).key == "patterns.set"


# --- types ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("data, key", [
    (binocular(range="far"), "perception.range"),            # string for a number
    ({"init": {"n": 10.5}}, "init.n"),                        # fractional float for an int
    ({"init": {"n": True}}, "init.n"),                        # bool is not an int here
    (binocular(occlusion=1), "perception.occlusion"),        # number for a bool
    ({"init": {"scale_with_n": "yes"}}, "init.scale_with_n"),  # string for a bool
    (binocular(field_deg=True), "perception.field_deg"),     # bool for a number
    ({"world": {"boundary": 3}}, "world.boundary"),          # number for a string
    ({"perception": 5}, "perception"),                       # value for a table
    ({"init": [1, 2]}, "init"),
    ({"patterns": {"set": {"bits": "01"}}}, "patterns.set"),  # table for a list
], ids=["str_for_float", "float_for_int", "bool_for_int", "int_for_bool", "str_for_bool",
        "bool_for_float", "int_for_str", "value_for_table", "list_for_table", "table_for_list"])
def test_wrong_types_name_the_key(data, key):
    assert config_error(data).key == key


def test_integral_float_is_accepted_for_an_int_and_int_for_a_float():
    preset = preset_from_dict({"init": {"n": 10.0}, **binocular(range=20)})
    assert preset.init.n == 10 and isinstance(preset.init.n, int)
    assert preset.model.perception.range == 20.0 and isinstance(preset.model.perception.range, float)


# --- choices ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("data, key, allowed", [
    ({"world": {"boundary": "torus"}}, "world.boundary", ("'open'", "'sphere_wrap'", "'periodic_box'")),
    ({"world": {"update_order": "random"}}, "world.update_order", ("'synchronous'", "'sequential'")),
    ({"perception": {"kind": "eyes"}}, "perception.kind", ("'sphere'", "'opensteer'", "'binocular'")),
    ({"patterns": {"separation_weight": "none"}}, "patterns.separation_weight",
     ("'similarity'", "'dissimilarity'", "'uniform'")),
    ({"dynamics": "reynolds"}, "dynamics", ("'opensteer'",)),
])
def test_unknown_choice_lists_the_allowed_values(data, key, allowed):
    err = config_error(data)
    assert err.key == key
    for value in allowed:
        assert value in str(err)


def test_misspelt_choice_gets_a_suggestion():
    assert "did you mean 'sequential'" in str(config_error({"world": {"update_order": "sequentail"}}))


@pytest.mark.parametrize("perception, key", [
    ({"kind": "opensteer", "field_deg": 90.0}, "perception.field_deg"),
    ({"field_deg": 90.0}, "perception.field_deg"),  # kind defaults to opensteer
    ({"kind": "binocular", "separation_radius": 4.0}, "perception.separation_radius"),
    ({"kind": "binocular", "radius": 4.0}, "perception.radius"),
    ({"kind": "sphere", "occlusion": False}, "perception.occlusion"),
])
def test_key_of_another_perception_kind_is_rejected(perception, key):
    err = config_error({"perception": perception})
    assert err.key == key
    assert "applies only to perception.kind" in str(err)


# --- files and overrides ----------------------------------------------------------------------------

@pytest.mark.parametrize("path", sorted(MODELS.glob("*.toml")), ids=lambda p: p.stem)
def test_every_shipped_preset_loads(path):
    preset = load_preset(path)
    assert isinstance(preset, Preset)
    assert preset.run.record_every >= 1


def test_shipped_presets_exist():
    assert {p.stem for p in MODELS.glob("*.toml")} >= {"opensteer", "holland", "holland_pattern"}


def test_overrides_are_applied_with_toml_values():
    preset = load_preset(HOLLAND, ["perception.field_deg=90", " perception.range = 30.5 ",
                                   "perception.occlusion=false", "world.boundary=periodic_box",
                                   "init.n=20"])
    per = preset.model.perception
    assert (per.field_deg, per.range, per.occlusion) == (90.0, 30.5, False)
    assert preset.model.world.boundary == "periodic_box"  # bare word read as a string
    assert preset.init.n == 20


def test_overrides_do_not_touch_the_file_defaults():
    load_preset(HOLLAND, ["perception.field_deg=90"])
    assert load_preset(HOLLAND).model.perception.field_deg == 120.0


@pytest.mark.parametrize("override, key", [
    ("perception.field_deg", "perception.field_deg"),    # no '='
    ("perception.kind.x=1", "perception.kind.x"),          # descends into a value
    ("perception.field_deg=wide", "perception.field_deg"),  # not a number
    ("perception.feild_deg=90", "perception.feild_deg"),   # unknown key
    ("init.n=10.5", "init.n"),
])
def test_malformed_overrides_are_rejected(override, key):
    with pytest.raises(ConfigError) as info:
        load_preset(HOLLAND, [override])
    assert info.value.key == key


def test_missing_and_invalid_files_raise_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_preset(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_preset(bad)


# --- defaults and immutability ----------------------------------------------------------------------

def test_eye_position_defaults_to_direction():
    assert Perception(kind="binocular", direction_deg=30.0).eye_deg == 30.0
    assert Perception(kind="binocular", direction_deg=30.0, eye_position_deg=0.0).eye_deg == 0.0
    assert load_preset(HOLLAND, ["perception.direction_deg=80"]).model.perception.eye_deg == 80.0
    preset = load_preset(HOLLAND, ["perception.direction_deg=80", "perception.eye_position_deg=10"])
    assert preset.model.perception.eye_deg == 10.0


@pytest.mark.parametrize("obj, name", [
    (ModelParams(), "name"), (Perception(), "range"), (InitParams(), "n"), (RunSettings(), "dt"),
    (load_preset(HOLLAND), "model"),
])
def test_parameters_are_frozen(obj, name):
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(obj, name, getattr(obj, name))


def test_constructing_dataclasses_directly_also_validates():
    with pytest.raises(ConfigError) as info:
        Perception(kind="binocular", field_deg=400.0)
    assert info.value.key == "perception.field_deg"
    with pytest.raises(ConfigError) as info:
        InitParams(n=0)
    assert info.value.key == "init.n"


# --- round trips and error paths found in review -------------------------------------------------------

@pytest.mark.parametrize("path", sorted(MODELS.glob("*.toml")), ids=lambda p: p.stem)
def test_preset_round_trips_through_to_dict(path):
    preset = load_preset(path)
    again = preset_from_dict(preset.to_dict())
    assert again.to_dict() == preset.to_dict()
    assert again.model.perception.eye_deg == preset.model.perception.eye_deg


def test_misspelt_kind_is_reported_on_the_kind_key():
    assert config_error(binocular(kind="binocluar", field_deg=90.0)).key == "perception.kind"


def test_non_string_kind_gives_a_config_error():
    assert config_error({"perception": {"kind": ["sphere"], "field_deg": 90.0}}).key == "perception.kind"


def test_missing_pattern_fraction_gives_a_config_error():
    assert config_error({"patterns": {"set": [{"bits": "01"}]}}).key == "patterns.set[0].fraction"


def test_eye_position_follows_a_replaced_direction():
    # the default is resolved when used, so dataclasses.replace cannot leave a stale eye position
    from dataclasses import replace

    per = replace(Perception(kind="binocular", direction_deg=30.0), direction_deg=70.0)
    assert per.eye_deg == 70.0


def test_canonical_dict_drops_keys_of_other_kinds_and_resolves_the_eye():
    preset = load_preset(HOLLAND, ["perception.direction_deg=40"])
    perception = preset.to_dict()["perception"]
    assert perception["eye_position_deg"] == 40.0
    assert "radius" not in perception and "alignment_cos" not in perception


def test_duration_must_be_a_whole_number_of_steps():
    with pytest.raises(ConfigError) as info:
        load_preset(HOLLAND, ["run.dt=0.01", "run.duration=1.005"])
    assert info.value.key == "run.duration"
