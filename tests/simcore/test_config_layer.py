"""The one config layer: Preset.replace against the preset file it stands for, the schema engine's
types, the shared alias table, [model]/[run] tables and path resolver, the seed registry and the one
JSON convention."""
from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.observables.summary import MetricSettings, summary_columns
from flocksweep.simcore import ConfigError, load_preset, preset_from_dict
from flocksweep.simcore.params import KEY_ALIASES, canonical_key, read_toml
from flocksweep.simcore.schema import build, resolve_path, set_dotted
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.files import json_ready, write_json
from flocksweep.sweeps.seeds import ECDF_BAND, SBCStream, Tag
from paths import ROOT

MODELS = ROOT / "configs" / "models"


# -- Preset.replace --------------------------------------------------------------------------------------

CHANGES = [
    {"perception.field_deg": 200},
    {"n": 37, "perception.range": 15.5},
    {"run.dt": 0.01, "run.duration": 3.0, "run.record_interval": 0.5},
    {"patterns.enabled": True, "steering.cohesion_weight": 3},
    {"perception": {"kind": "sphere", "radius": 7.0}},
    {"patterns.set": [{"bits": "01", "fraction": 0.5}, {"bits": "10", "fraction": 0.5}]},
    {"leadership.x": 0.5, "leadership.duration": 2.0},
]


@pytest.mark.parametrize("changes", CHANGES, ids=lambda c: ",".join(c))
@pytest.mark.parametrize("model", ["holland", "opensteer", "hartman_benes"])
def test_replace_equals_the_preset_file_with_those_values(model, changes):
    """Equal presets, or the same error (key and message) when the file would be invalid."""
    data = read_toml(MODELS / f"{model}.toml")
    base = preset_from_dict(copy.deepcopy(data))
    for key, value in changes.items():
        set_dotted(data, canonical_key(key), value)
    try:
        expected = preset_from_dict(data)
    except ConfigError as err:
        with pytest.raises(ConfigError) as info:
            base.replace(changes)
        assert (info.value.key, str(info.value)) == (err.key, str(err))
        return
    assert base.replace(changes) == expected
    assert base.replace(**changes) == expected


@pytest.mark.parametrize("changes, key, words", [
    ({"perception.feild_deg": 90}, "perception.feild_deg", "did you mean 'field_deg'"),
    ({"perception.field_deg": 400}, "perception.field_deg", "(0.0, 360.0]"),
    ({"perception.radius": 5.0}, "perception.radius", "applies only to perception.kind = 'sphere'"),
    ({"run.dt": 0.3}, "run.record_interval", "whole multiple"),
    ({"init.n": 0}, "init.n", ">= 1"),
    ({"n": 2.5}, "init.n", "integer"),
    ({"perceptoin.range": 3}, "perceptoin", "did you mean 'perception'"),
    ({"patterns.set": [{"bits": "01", "fraction": 1.0, "colour": 1}]}, "patterns.set[0].colour", "unknown key"),
    ({"perception.field_deg.x": 1}, "perception.field_deg.x", "is a value, not a table"),
])
def test_replace_errors_name_the_key(changes, key, words):
    base = load_preset(MODELS / "holland.toml")
    with pytest.raises(ConfigError) as info:
        base.replace(changes)
    assert info.value.key == key and words in str(info.value)


def test_replace_leaves_the_original_untouched_and_follows_unset_defaults():
    base = load_preset(MODELS / "holland.toml")
    moved = base.replace({"perception.direction_deg": 30})
    assert base.model.perception.direction_deg != 30 and moved.model.perception.direction_deg == 30
    assert moved.model.perception.eye_position_deg is None   # still follows direction_deg
    assert moved.model.perception.eye_deg == 30


# -- the schema engine -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class Inner:
    size: int = 1


@dataclass(frozen=True)
class Outer:
    name: str = field(metadata={"expected": "a name for the thing"})
    mode: Literal["fast", "slow"] = "fast"
    tables: dict[str, Inner] = field(default_factory=dict)
    where: Path | None = None
    free: dict = field(default_factory=dict)


def test_schema_engine_types():
    built = build(Outer, {"name": "x", "mode": "slow", "tables": {"a": {"size": 3}}, "where": "out/dir",
                          "free": {"anything": [1, "b"]}})
    assert built == Outer("x", "slow", {"a": Inner(3)}, Path("out/dir"), {"anything": [1, "b"]})
    cases = [({"name": "x", "mode": "slwo"}, "mode", "did you mean 'slow'"),
             ({"name": "x", "tables": {"a": {"sise": 1}}}, "tables.a.sise", "did you mean 'size'"),
             ({"name": "x", "tables": {"a": {"size": 1.5}}}, "tables.a.size", "an integer"),
             ({}, "name", "expected a name for the thing"),
             ({"name": 3}, "name", "expected a name for the thing, got 3"),
             ({"name": "x", "where": 4}, "where", "a path")]
    for data, key, words in cases:
        with pytest.raises(ConfigError) as info:
            build(Outer, data)
        assert info.value.key == key and words in str(info.value), str(info.value)


def test_resolve_path_looks_next_to_the_file_then_in_the_working_directory(tmp_path, monkeypatch):
    (tmp_path / "here").mkdir()
    (tmp_path / "here" / "a.toml").write_text("")
    assert resolve_path("a.toml", tmp_path / "here", "k", "thing") == (tmp_path / "here" / "a.toml").resolve()
    monkeypatch.chdir(tmp_path)
    assert resolve_path("here/a.toml", tmp_path / "elsewhere", "k", "thing") == (tmp_path / "here" / "a.toml")
    with pytest.raises(ConfigError, match="thing not found") as info:
        resolve_path("b.toml", tmp_path / "here", "model.preset", "thing")
    assert info.value.key == "model.preset"


def test_one_alias_table_for_sweeps_calibrations_and_presets():
    assert KEY_ALIASES == {"n": "init.n"}
    sweep = {"name": "a", "seed": 1, "model": {"preset": str(MODELS / "holland.toml"), "set": {"n": 9}},
             "run": {"duration": 1.0, "warmup": 0.5}, "axes": [{"key": "n", "values": [6, 7]}]}
    specs = expand(sweep_from_dict(sweep, ROOT))
    assert [s.preset.init.n for s in specs] == [6, 7] and all("init.n" in dict(s.columns) for s in specs)
    calibration = {"name": "c", "model": {"preset": str(MODELS / "holland.toml"), "set": {"n": 9}},
                   "run": {"duration": 5.0},
                   "parameters": {"size": {"key": "n", "prior": {"dist": "uniform", "low": 5, "high": 20}}},
                   "targets": {"stats": ["cohesion"], "mean": [0.9], "sd": [0.1]},
                   "method": {"kind": "emcee", "n_sim": 4, "walkers": 4, "steps": 2}}
    config = calibration_from_dict(calibration, ROOT)
    assert config.keys == ("init.n",) and config.preset.init.n == 9
    assert load_preset(MODELS / "holland.toml").replace(n=11).init.n == 11


def test_sweep_and_calibration_run_tables_share_the_metric_settings():
    sweep = {"name": "a", "model": {"preset": str(MODELS / "holland.toml")},
             "run": {"duration": 5.0, "warmup": 1.0, "group_radius": 8, "fragmentation_cohesion": 0.4}}
    calibration = {"name": "c", "model": {"preset": str(MODELS / "holland.toml")}, "run": dict(sweep["run"]),
                   "parameters": {"f": {"key": "perception.field_deg", "prior": {"dist": "uniform", "low": 30,
                                                                                  "high": 300}}},
                   "targets": {"stats": ["cohesion"], "mean": [0.9], "sd": [0.1]},
                   "method": {"kind": "emcee", "n_sim": 4, "walkers": 4, "steps": 2}}
    expected = MetricSettings(warmup=1.0, group_radius=8.0, fragmentation_cohesion=0.4)
    assert sweep_from_dict(sweep, ROOT).metrics == expected
    assert calibration_from_dict(calibration, ROOT).metrics == expected
    for bad, key in (({"group_radius": -1}, "run.group_radius"), ({"warmup": -1}, "run.warmup"),
                     ({"fragmentation_cohesion": 2}, "run.fragmentation_cohesion"), ({"group_radius": "x"},
                                                                                    "run.group_radius")):
        with pytest.raises(ConfigError) as info:
            sweep_from_dict({**sweep, "run": {**sweep["run"], **bad}}, ROOT)
        assert info.value.key == key


# -- seeds and JSON --------------------------------------------------------------------------------------

def test_the_seed_registry_is_pinned():
    """Changing a tag changes stored results: the values are part of the contract."""
    assert {t.name: int(t) for t in Tag} == {"WALKERS": 0, "MOVES": 1, "EVALUATION": 2, "CONFIRM": 3,
                                             "RECHECK": 7, "PREDICTIVE": 0x5050, "SBC": 0x5BC,
                                             "DESIGN_SAMPLE": 0x5A3D1E,
                                             "DESIGN_SENSITIVITY": 24133, "PRIOR": 39440,
                                             "CLAIM_POWER": 0xC1A1, "NPE": 20062, "COMPARE": 0xC0DE}
    assert [int(s) for s in SBCStream] == [0, 1, 2, 3, 4] and ECDF_BAND == 0xECDF


def test_json_ready_turns_numpy_and_non_finite_numbers_into_plain_json(tmp_path):
    data = {"a": np.float64(1.5), "b": np.arange(3), "c": float("nan"), "d": [math.inf, -math.inf],
            "e": {"f": Path("x/y"), "g": np.int64(4)}, "h": (1, 2)}
    plain = json_ready(data)
    assert plain == {"a": 1.5, "b": [0, 1, 2], "c": None, "d": [None, None], "e": {"f": "x/y", "g": 4},
                     "h": [1, 2]}
    write_json(tmp_path / "x.json", data)   # never fails on a NaN
    assert json.loads((tmp_path / "x.json").read_text()) == plain


def test_summary_columns_are_the_rows_columns():
    assert summary_columns(False)[:2] == ("polarization_mean", "polarization_final")
    assert summary_columns(False)[-2:] == ("time_to_fragmentation", "fragmented")
    assert summary_columns(True)[-1] == "escape_gain" and len(summary_columns(True)) == len(summary_columns(False)) + 9
