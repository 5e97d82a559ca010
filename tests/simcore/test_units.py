"""Presets in metres (docs/model.md section 12, simcore.units): converted to body lengths when read,
validated at the boundary, every numeric key classified."""
from __future__ import annotations

import dataclasses
import typing

import pytest

from paths import ROOT
from flocksweep.simcore import load_preset
from flocksweep.simcore.params import InitParams, ModelParams, RunSettings, preset_from_dict, read_toml
from flocksweep.simcore.schema import ConfigError
from flocksweep.simcore.units import LENGTH_POWER, NO_LENGTH, REFUSED

MODELS = ROOT / "configs" / "models"


def numeric_keys(cls, prefix=""):
    """Dotted names of every number (or tuple of numbers) field of a parameter dataclass, recursively."""
    out = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp, name = hints[f.name], f"{prefix}{f.name}"
        if dataclasses.is_dataclass(tp):
            out += numeric_keys(tp, name + ".")
            continue
        text = str(tp)
        if any(t in text for t in ("float", "int")) and "Obstacle" not in text and "PatternEntry" not in text:
            out.append(name)
    return out


def test_every_numeric_key_is_classified():
    keys = numeric_keys(ModelParams) + [f"init.{k}" for k in numeric_keys(InitParams)] + \
        [f"run.{k}" for k in numeric_keys(RunSettings)]
    keys = [k for k in keys if not k.startswith(REFUSED)]
    missing = [k for k in keys if k not in LENGTH_POWER and k not in NO_LENGTH]
    assert not missing, f"classify these keys in simcore/units.py: {missing}"
    assert not set(LENGTH_POWER) & NO_LENGTH
    assert set(LENGTH_POWER) | NO_LENGTH <= set(keys)   # no stale names


def in_metres(data, body_length_m):
    """A body-length preset dict rewritten in metres: every length-carrying value times L^power."""
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    for dotted, power in LENGTH_POWER.items():
        table, key = dotted.split(".")
        if isinstance(out.get(table), dict) and key in out[table]:
            p = power(data) if callable(power) else power
            out[table][key] = out[table][key] * body_length_m ** p
    out["units"] = {"length": "m", "body_length_m": body_length_m}
    return out


@pytest.mark.parametrize("name", ["opensteer", "holland", "hartman_benes", "reynolds87", "topological"])
def test_a_preset_in_metres_is_its_twin_in_body_lengths(name):
    data = read_toml(MODELS / f"{name}.toml")
    data.setdefault("vehicle", {})["max_speed"] = 8.0   # defaults are in body lengths: give the keys
    data.setdefault("init", {})["speed"] = 2.5
    bl = preset_from_dict(data)
    m = preset_from_dict(in_metres(data, 0.25))     # a power of 2: the round trip is exact
    assert m.model == bl.model and m.init == bl.init and m.run == bl.run
    assert m.to_dict() == bl.to_dict()               # the same run identity
    assert m.units.body_length_m == 0.25 and m.units.length == "m"


def test_conversion_divides_by_the_body_length():
    p = preset_from_dict({"dynamics": "reynolds87", "perception": {"kind": "sphere", "radius": 3.0},
                          "reynolds": {"max_speed": 15.0, "separation_weight": 0.09, "falloff_exponent": 1.0},
                          "cruise": {"speed": 14.0, "tau": 0.5}, "noise": {"speed_sd": 0.6, "kappa": 50},
                          "init": {"speed": 14.0, "radius": 6.0},
                          "units": {"length": "m", "body_length_m": 0.3}})
    assert p.model.perception.radius == pytest.approx(10.0)
    assert p.model.reynolds.max_speed == pytest.approx(50.0)
    assert p.model.reynolds.separation_weight == pytest.approx(0.09 / 0.3 ** 2)
    assert p.model.cruise.speed == pytest.approx(14.0 / 0.3) and p.model.cruise.tau == 0.5
    assert p.model.noise.speed_sd == pytest.approx(2.0) and p.model.noise.kappa == 50
    assert p.init.speed == pytest.approx(14.0 / 0.3) and p.init.radius == pytest.approx(20.0)


def test_body_lengths_is_the_default_and_changes_nothing():
    p = load_preset(MODELS / "holland.toml")
    assert p.units.length == "bl" and p.units.body_length_m is None
    q = preset_from_dict({**read_toml(MODELS / "holland.toml"), "units": {"body_length_m": 0.3}})
    assert q.model == p.model and q.to_dict() == p.to_dict()


@pytest.mark.parametrize("units, key, text", [
    ({"length": "m"}, "units.body_length_m", "required"),
    ({"length": "ft", "body_length_m": 0.3}, "units.length", "ft"),
    ({"length": "m", "body_length_m": -0.3}, "units.body_length_m", "-0.3"),
    ({"lenght": "m"}, "units.lenght", "length"),
    ("m", "units", "table"),
])
def test_bad_units_name_their_key(units, key, text):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")) as err:
        preset_from_dict({"units": units})
    assert text in str(err.value)


def test_tables_not_converted_are_refused_in_metres():
    with pytest.raises(ConfigError, match=r"\[boidspp\] keys are not converted"):
        load_preset(MODELS / "boidspp.toml", ["units.length='m'", "units.body_length_m=0.3"])
    with pytest.raises(ConfigError, match="obstacles"):
        load_preset(MODELS / "reynolds87_obstacles.toml", ["units.length='m'", "units.body_length_m=0.3"])


def test_overrides_are_in_the_files_units():
    p = load_preset(MODELS / "opensteer.toml", ["units.length='m'", "units.body_length_m=0.5",
                                                "vehicle.max_speed=7"])
    assert p.model.vehicle.max_speed == 14.0


@pytest.mark.slow
def test_the_pigeon_preset_flies_as_docs_model_md_says():
    """docs/model.md section 12.4: one group at about 14 m/s, 1.7 m apart, polarization about 0.997 (two
    seeds, the first 10 s left out; bounds a little wider than the 8 seeds' range stated there)."""
    from flocksweep.observables.summary import MetricSettings, summarize_run
    from flocksweep.simcore import simulate_batch

    p = load_preset(MODELS / "pigeon.toml")
    assert p.units.body_length_m == 0.3 and p.model.cruise.speed == pytest.approx(14.0 / 0.3)
    m, i, r = p.model, p.init, p.run
    for obs in simulate_batch(m, i, [0, 1], r.duration, r.dt, r.record_every):
        row = summarize_run(obs, MetricSettings(warmup=10.0).resolve(m))
        assert row["n_groups_mean"] == 1.0 and row["n_groups_final"] == 1.0
        assert 1.6 < row["nn_distance_mean"] * 0.3 < 1.8      # metres
        assert 13.3 < row["speed_mean_mean"] * 0.3 < 14.2      # m/s
        assert 0.995 < row["polarization_mean"] < 0.998
