"""Bad input gets one clear message and exit status 2 before anything is written (docs/errors.md).

The catalogue (tests/malformed.py) holds over 200 malformed inputs to every command; each must be
refused with its exit status, a message holding the words the catalogue names, no traceback, and no
file written. A representative few run in the quick loop, all of them in the slow one. The rest of this
module checks the rules behind them one by one: dates and encodings, names, the run window, the
memory and size budget (counted without building the design), ``model.set`` merging into the preset
and ``--set model.<key>``, and the command line's numbers.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from malformed import CASES, QUICK, attempt
from paths import ROOT
from flocksweep.simcore import load_preset, simulate
from flocksweep.simcore.schema import ConfigError, apply_overrides, read_toml
from flocksweep.sweeps import budget
from flocksweep.sweeps.config import load_sweep, sweep_from_dict
from flocksweep.sweeps.design import expand

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
BY_NAME = {case.name: case for case in CASES}


@pytest.mark.parametrize("name", QUICK)
def test_representative_bad_inputs_are_refused_before_any_write(name, tmp_path):
    case = BY_NAME[name]
    refusal = attempt(case, tmp_path)
    assert refusal.crash == "", refusal.crash
    assert refusal.code == case.code, refusal.stderr
    assert case.expect.lower() in refusal.stderr.lower(), refusal.stderr
    assert refusal.stderr.strip().startswith("flocksweep: ") and "Traceback" not in refusal.stderr
    assert {p for p in refusal.written if not (case.may_write and p.startswith(case.may_write))} == set()


@pytest.mark.slow
def test_every_catalogued_bad_input_is_refused_cleanly(tmp_path):
    assert len(CASES) >= 161
    unclean = []
    for number, case in enumerate(CASES):
        folder = tmp_path / f"case{number}"
        folder.mkdir()
        refusal = attempt(case, folder)
        if not refusal.clean(case):
            unclean.append(f"{case.name}: status {refusal.code}, wrote {sorted(refusal.written)[:3]}, "
                           f"{(refusal.crash or refusal.stderr).strip()[-300:]}")
    assert unclean == []


# -- what a file may hold ------------------------------------------------------------------------------

def test_non_utf8_file_names_the_byte_and_its_offset(tmp_path):
    path = tmp_path / "m.toml"
    path.write_bytes(b'name = "caf\xe9"\n')
    with pytest.raises(ConfigError, match=r"not UTF-8 text \(byte 0xe9 at offset 11\)"):
        read_toml(path, "model file")


@pytest.mark.parametrize("text, key", [("when = 2024-01-02", "when"), ("[a]\nb = 10:30:00", "a.b"),
                                       ("c = [1979-05-27T07:32:00Z]", "c[0]")])
def test_dates_and_times_are_refused_naming_their_key(text, key, tmp_path):
    path = tmp_path / "d.toml"
    path.write_text(text + "\n")
    with pytest.raises(ConfigError) as info:
        read_toml(path, "sweep file")
    assert info.value.key == key and "date/time" in str(info.value)
    with pytest.raises(ConfigError, match="date/time"):
        apply_overrides({}, ["description=2020-01-01"])


@pytest.mark.parametrize("name", ["a\x00b", "a/b", "a\\b", ".hidden", "", "x" * 101, "tab\there"])
def test_sweep_names_must_be_plain_folder_names(name):
    data = {"name": name, "model": {"preset": str(HOLLAND)}, "run": {"duration": 1.0, "warmup": 0.5}}
    with pytest.raises(ConfigError) as info:
        sweep_from_dict(data, ROOT)
    assert info.value.key == "name"


# -- the run window ------------------------------------------------------------------------------------

def window_sweep(run: dict, axes=()) -> dict:
    return {"name": "w", "model": {"preset": str(HOLLAND)}, "run": {"n": 6, **run}, "axes": list(axes)}


@pytest.mark.parametrize("run, key", [
    ({"duration": 2.0, "warmup": 2.0}, "run.warmup"),
    ({"duration": 2.0, "warmup": 3.0}, "run.warmup"),
    ({"duration": 2.0, "record_interval": 3.0, "warmup": 0.5}, "run.record_interval"),
    ({"duration": 4.0, "record_interval": 3.0, "warmup": 3.5}, "run.warmup"),   # no record at or after 3.5 s
])
def test_a_sweep_whose_runs_record_nothing_to_summarise_is_refused(run, key):
    with pytest.raises(ConfigError) as info:
        expand(sweep_from_dict(window_sweep(run), ROOT))
    assert info.value.key == key


def test_a_swept_duration_is_checked_at_every_design_point():
    data = window_sweep({"duration": 4.0, "warmup": 1.0, "record_interval": 0.5},
                        [{"key": "run.duration", "values": [4.0, 0.5]}])
    with pytest.raises(ConfigError, match=r"run.warmup: .*at design point run.duration=0.5"):
        expand(sweep_from_dict(data, ROOT))
    ok = expand(sweep_from_dict(window_sweep({"duration": 4.0, "warmup": 1.0},
                                             [{"key": "run.duration", "values": [4.0, 2.0]}]), ROOT))
    assert [s.preset.run.duration for s in ok] == [4.0, 2.0]


# -- model.set merges ----------------------------------------------------------------------------------

def test_model_set_and_set_model_change_one_key_and_keep_the_preset_table():
    smoke = ROOT / "configs" / "sweeps" / "smoke.toml"
    plain = expand(load_sweep(smoke))[0].preset
    spelled = [["model.set.perception.range=30"], ["model.perception.range=30"], ['model.set={"perception.range"=30}']]
    for overrides in spelled:
        preset = expand(load_sweep(smoke, overrides))[0].preset
        assert preset.model.perception.range == 30
        assert preset.model.perception.kind == "binocular"                     # the rest of the table stays
        assert preset.model.perception.occlusion == plain.model.perception.occlusion
        assert preset.replace({"perception.range": plain.model.perception.range}) == plain
    steering = expand(load_sweep(smoke, ["model.steering.cohesion_weight=3.5"]))[0].preset.model.steering
    assert (steering.cohesion_weight, steering.separation_weight) == (3.5, plain.model.steering.separation_weight)


def test_a_nested_model_set_table_in_a_file_merges_too():
    data = {"name": "m", "model": {"preset": str(HOLLAND), "set": {"perception": {"field_deg": 90}}},
            "run": {"n": 6, "duration": 1.0, "warmup": 0.5}}
    preset = expand(sweep_from_dict(data, ROOT))[0].preset
    assert preset.model.perception.field_deg == 90 and preset.model.perception.kind == "binocular"
    assert preset.model.perception.direction_deg == load_preset(HOLLAND).model.perception.direction_deg


# -- size and memory, before anything is built -----------------------------------------------------------

def big_design(levels: int, axes: int, replicates: int = 1) -> dict:
    keys = ["perception.field_deg", "perception.range", "steering.cohesion_weight", "steering.alignment_weight"]
    axes_list = [{"key": keys[k], "values": [1 + j for j in range(levels)]} for k in range(axes)]
    return {"name": "big", "replicates": replicates, "model": {"preset": str(HOLLAND)},
            "run": {"n": 6, "duration": 1.0, "warmup": 0.5}, "axes": axes_list}


def test_a_huge_design_is_counted_and_refused_without_building_a_run():
    config = sweep_from_dict(big_design(300, 4), ROOT)   # 300^4 = 8.1e9 runs: building them would take hours
    start = time.perf_counter()
    assert budget.count_runs(config) == 300 ** 4
    with pytest.raises(budget.BudgetError, match="8,100,000,000 runs"):
        budget.check_sweep(config, workers=1)
    assert time.perf_counter() - start < 1.0


def test_a_large_design_needs_yes_and_yes_lets_it_through():
    config = sweep_from_dict(big_design(20, 4), ROOT)     # 160,000 runs
    with pytest.raises(budget.BudgetError, match="--yes"):
        budget.check_sweep(config, workers=1)
    assert budget.check_sweep(config, workers=1, yes=True) == 160_000


def test_memory_is_checked_for_the_largest_flock_any_axis_gives():
    data = big_design(2, 1)
    data["axes"].append({"key": "init.n", "values": [10, 10 ** 12]})
    config = sweep_from_dict(data, ROOT)
    worst = budget.worst_run(config)
    assert worst.n == 1e12 and worst.origin["n"] == "init.n (axes[1])"
    with pytest.raises(budget.BudgetError) as info:
        budget.check_sweep(config, workers=1)
    assert info.value.key == "init.n (axes[1])" and "EiB of memory" in str(info.value)
    small = sweep_from_dict(big_design(2, 1), ROOT)
    worst = budget.worst_run(small)
    one = budget.run_bytes(worst.n, worst.n_steps, worst.record_every)
    with pytest.raises(budget.BudgetError, match="--workers 3 or fewer"):
        budget.check_sweep(small, workers=8, available=int(3.5 * one))
    assert budget.check_sweep(small, workers=3, available=int(3.5 * one)) == 2


def test_the_memory_estimate_is_above_what_a_run_allocates():
    preset = load_preset(HOLLAND, ["init.n=40", "run.duration=2.0"])
    obs = simulate(preset.model, preset.init, 1, preset.run.duration, preset.run.dt, preset.run.record_every)
    arrays = sum(a.nbytes for a in (obs.pos, obs.vel, obs.visible, obs.binocular, obs.leader))
    estimate = budget.run_bytes(40, preset.run.n_steps, preset.run.record_every)
    assert arrays + 4 * 40 ** 2 < estimate < 20 * (arrays + 4 * 40 ** 2)
    assert np.isfinite(budget.run_bytes(1e18, 1e6, 1))   # no overflow for absurd inputs
