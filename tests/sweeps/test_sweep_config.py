"""Sweep definitions: parsing and validation, design expansion, and run identity (seeds and run ids).

Nothing here simulates. Configs are built as dicts (``sweep_from_dict``) or written as TOML into
``tmp_path`` and expanded with ``sweeps.design.expand``; the CLI is driven in-process with the runner
replaced where a test only checks how arguments reach the config.
"""
from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import pytest

from flocksweep.simcore import ConfigError
from flocksweep.sweeps import runner
from flocksweep.cli import main
from flocksweep.sweeps.config import load_sweep, sweep_from_dict
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.runner import Plan, SweepResult, design_table, run_sweep
from paths import ROOT

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
SHIPPED = ROOT / "configs" / "sweeps"

FIELD = "perception.field_deg"
RANGE = "perception.range"


# -- builders ------------------------------------------------------------------------------------

def sweep(**changes) -> dict:
    """A small valid sweep as a dict; keyword arguments replace whole top-level entries."""
    data = {"name": "tiny", "seed": 7, "model": {"preset": str(HOLLAND)},
            "run": {"n": 8, "duration": 1.0, "record_interval": 0.5, "warmup": 0.25}, "axes": []}
    data.update(changes)
    return data


def axis(key, values, **extra) -> dict:
    return {"key": key, "values": values, **extra}


def build(data: dict):
    """Validated run specs of a sweep dict (relative paths start at the repository root)."""
    return expand(sweep_from_dict(data, ROOT))


def by_point(specs) -> dict:
    """{(swept parameters, replicate): (seed, run id)}, independent of design order."""
    return {(frozenset(s.columns), s.replicate): (s.seed, s.run_id) for s in specs}


def toml_sweep(body: str) -> str:
    """A small sweep file with the given axes (or other trailing tables)."""
    return (f'name = "tiny"\nseed = 7\n\n[model]\npreset = "{HOLLAND}"\n\n'
            f'[run]\nn = 8\nduration = 1.0\nrecord_interval = 0.5\nwarmup = 0.25\n\n{body}\n')


# -- expansion counts ------------------------------------------------------------------------------

def test_holland648_expands_to_the_full_grid_with_distinct_ids_and_seeds():
    specs = expand(load_sweep(SHIPPED / "holland648.toml"))
    assert len(specs) == 648 == 2 * 3 * 6 * 6 * 3
    assert len({s.run_id for s in specs}) == 648
    assert len({s.seed for s in specs}) == 648
    assert [s.index for s in specs] == list(range(648))
    columns = [dict(s.columns) for s in specs]
    assert {c["mode"] for c in columns} == {"normal", "pattern"}
    assert {c["init.n"] for c in columns} == {20, 50, 100}
    assert {c["perception.direction_deg"] for c in columns} == {0, 20, 40, 60, 80, 90}
    assert {c[FIELD] for c in columns} == {30, 60, 90, 120, 150, 180}
    assert {c[RANGE] for c in columns} == {10, 20, 40}
    assert len({tuple(sorted(c.items())) for c in columns}) == 648
    # the label follows the swept value, and the preset holds what the columns say
    for spec, c in zip(specs, columns):
        assert c["mode"] == ("pattern" if c["patterns.enabled"] else "normal")
        assert spec.preset.model.patterns.enabled == c["patterns.enabled"]
        assert spec.preset.init.n == c["init.n"]
        assert spec.preset.model.perception.field_deg == c[FIELD]
        assert spec.metrics.group_radius == c[RANGE]  # group_radius = "auto": the perception range


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_holland648_r5_has_five_replicates_per_cell_and_contains_holland648():
    single = expand(load_sweep(SHIPPED / "holland648.toml"))
    specs = expand(load_sweep(SHIPPED / "holland648_r5.toml"))
    assert len(specs) == 3240 == 648 * 5
    assert len({s.run_id for s in specs}) == 3240
    assert len({s.seed for s in specs}) == 3240
    assert sorted({s.replicate for s in specs}) == [0, 1, 2, 3, 4]
    # same seed and same points: replicate 0 of the 5-replicate grid is exactly the 648-run grid
    first = {s.run_id: s.seed for s in specs if s.replicate == 0}
    assert first == {s.run_id: s.seed for s in single}


def test_smoke_sweep_expands_to_its_count():
    specs = expand(load_sweep(SHIPPED / "smoke.toml"))
    assert len(specs) == 2 * 2 * 2
    assert len({s.run_id for s in specs}) == 8
    assert all(s.preset.init.n == 12 and s.preset.run.duration == 4.0 for s in specs)


def test_zipped_axis_contributes_its_number_of_points_not_a_product():
    data = sweep(axes=[
        {"name": "vision", "keys": ["perception.direction_deg", FIELD], "values": [[20, 60], [90, 60], [40, 120]]},
        axis("init.n", [6, 8]),
    ])
    specs = build(data)
    assert len(specs) == 3 * 2
    pairs = {(s.preset.model.perception.direction_deg, s.preset.model.perception.field_deg) for s in specs}
    assert pairs == {(20.0, 60.0), (90.0, 60.0), (40.0, 120.0)}
    assert {dict(s.columns)["vision"] for s in specs} == {"20|60", "90|60", "40|120"}


def test_linspace_and_range_axes_give_the_right_values():
    data = sweep(axes=[
        {"key": RANGE, "linspace": {"start": 10, "stop": 40, "num": 4}},
        {"key": "init.n", "range": {"start": 6, "stop": 12, "step": 3}},
        {"key": "init.speed", "range": {"start": 0.5, "stop": 1.5, "step": 0.25}},
        {"key": "steering.alignment_weight", "linspace": {"start": 3, "stop": 9, "num": 1}},
    ])
    config = sweep_from_dict(data, ROOT)
    values = [[p[0] for p in a.points] for a in config.axes]
    assert values[0] == pytest.approx([10, 20, 30, 40])
    assert values[1] == pytest.approx([6, 9, 12])
    assert values[2] == pytest.approx([0.5, 0.75, 1.0, 1.25, 1.5])
    assert values[3] == pytest.approx([3])
    specs = expand(config)
    assert len(specs) == 4 * 3 * 5 * 1
    assert sorted({s.preset.init.n for s in specs}) == [6, 9, 12]
    assert all(isinstance(s.preset.init.n, int) for s in specs)


SAMPLE_BOUNDS = {FIELD: [30, 330], "init.n": [6, 12]}


@pytest.mark.parametrize("method", ["random", "lhs", "sobol"])
def test_sampled_design_points_are_in_bounds_rounded_and_reproducible(method):
    data = sweep(sample={"method": method, "n": 16, "bounds": SAMPLE_BOUNDS})
    specs = build(data)
    assert len(specs) == 16
    fields = [dict(s.columns)[FIELD] for s in specs]
    sizes = [dict(s.columns)["init.n"] for s in specs]
    assert all(30 <= f <= 330 for f in fields)
    assert all(type(n) is int and 6 <= n <= 12 for n in sizes)  # integer key: rounded to an int
    assert len(set(fields)) == 16 and len(set(sizes)) > 1
    assert [s.preset.model.perception.field_deg for s in specs] == fields
    assert [s.preset.init.n for s in specs] == sizes

    again = build(data)
    assert [s.columns for s in again] == [s.columns for s in specs]
    assert [(s.seed, s.run_id) for s in again] == [(s.seed, s.run_id) for s in specs]

    other = build({**data, "seed": data["seed"] + 1})
    assert [dict(s.columns)[FIELD] for s in other] != fields


def test_lhs_hits_each_stratum_once_per_dimension():
    n = 10
    bounds = {FIELD: [30.0, 330.0], RANGE: [5.0, 45.0]}
    specs = build(sweep(sample={"method": "lhs", "n": n, "bounds": bounds}))
    for key, (low, high) in bounds.items():
        values = np.array([dict(s.columns)[key] for s in specs])
        strata = np.floor((values - low) / (high - low) * n).astype(int)
        assert sorted(strata) == list(range(n)), key


def test_sampled_block_is_one_more_factor_of_the_product():
    data = sweep(axes=[axis("patterns.enabled", [False, True])],
                 sample={"method": "random", "n": 4, "bounds": {FIELD: [30, 330]}})
    specs = build(data)
    assert len(specs) == 2 * 4
    normal = [dict(s.columns)[FIELD] for s in specs if not s.preset.model.patterns.enabled]
    pattern = [dict(s.columns)[FIELD] for s in specs if s.preset.model.patterns.enabled]
    assert normal == pattern and len(set(normal)) == 4


# -- identity: seeds and run ids -----------------------------------------------------------------

BASE_AXES = [axis(FIELD, [60, 120, 180]), axis("init.n", [6, 8])]
CHANGED_GRIDS = {
    "values reordered": ([axis(FIELD, [180, 60, 120]), axis("init.n", [8, 6])], 6),
    "axes reordered": ([axis("init.n", [6, 8]), axis(FIELD, [60, 120, 180])], 6),
    "grid grown": ([axis(FIELD, [30, 60, 90, 120, 180, 240]), axis("init.n", [6, 7, 8])], 6),
    "grid shrunk": ([axis(FIELD, [120]), axis("init.n", [8])], 1),
    "values given as floats": ([axis(FIELD, [60.0, 120.0, 180.0]), axis("init.n", [6, 8])], 6),
}


@pytest.mark.parametrize("change", list(CHANGED_GRIDS))
def test_seed_and_run_id_of_a_point_do_not_depend_on_the_rest_of_the_grid(change):
    axes, common_points = CHANGED_GRIDS[change]
    before = by_point(build(sweep(replicates=2, axes=BASE_AXES)))
    after = by_point(build(sweep(replicates=2, axes=axes)))
    common = before.keys() & after.keys()
    assert len(common) == common_points * 2
    for key in common:
        assert after[key] == before[key], key


def test_sweep_seed_changes_every_seed_and_run_id():
    one = build(sweep(axes=BASE_AXES, replicates=2))
    two = build(sweep(axes=BASE_AXES, replicates=2, seed=8))
    assert [s.columns for s in one] == [s.columns for s in two]
    assert all(a.seed != b.seed and a.run_id != b.run_id for a, b in zip(one, two))


def test_replicates_of_a_point_have_different_seeds_and_ids():
    specs = build(sweep(axes=BASE_AXES, replicates=3))
    assert len(specs) == 6 * 3
    assert len({s.seed for s in specs}) == 18
    assert len({s.run_id for s in specs}) == 18
    assert [(s.point_index, s.replicate) for s in specs[:4]] == [(0, 0), (0, 1), (0, 2), (1, 0)]


def test_common_random_numbers_share_the_replicate_seed_across_points():
    specs = build(sweep(axes=BASE_AXES, replicates=3, common_random_numbers=True))
    seeds = {r: {s.seed for s in specs if s.replicate == r} for r in range(3)}
    assert all(len(v) == 1 for v in seeds.values())
    assert len(set.union(*seeds.values())) == 3  # replicates still differ from each other
    assert len({s.run_id for s in specs}) == len(specs) == 18
    independent = build(sweep(axes=BASE_AXES, replicates=3))
    assert {s.seed for s in independent} != {s.seed for s in specs}


NON_SWEPT_CHANGES = {
    "model.set steering weight": {"model": {"preset": str(HOLLAND), "set": {"steering.cohesion_weight": 4.0}}},
    "run duration": {"run": {"n": 8, "duration": 1.5, "record_interval": 0.5, "warmup": 0.25}},
    "analysis warmup": {"run": {"n": 8, "duration": 1.0, "record_interval": 0.5, "warmup": 0.5}},
    "keep trajectories": {"run": {"n": 8, "duration": 1.0, "record_interval": 0.5, "warmup": 0.25,
                                  "keep": "trajectories"}},
}


@pytest.mark.parametrize("change", list(NON_SWEPT_CHANGES))
def test_non_swept_settings_change_the_run_id_but_not_the_seed(change):
    before = build(sweep(axes=BASE_AXES))
    after = build(sweep(axes=BASE_AXES, **NON_SWEPT_CHANGES[change]))
    assert [s.columns for s in before] == [s.columns for s in after]
    assert [s.seed for s in before] == [s.seed for s in after]
    assert all(a.run_id != b.run_id for a, b in zip(before, after))


# -- bad configs -----------------------------------------------------------------------------------

BAD_CONFIGS = {
    "unknown top-level key": (sweep(replicate=2), "replicate", "did you mean 'replicates'"),
    "unknown run key": (sweep(run={"n": 8, "duraton": 1.0}), "run.duraton", "did you mean 'duration'"),
    "unknown model key": (sweep(model={"presets": str(HOLLAND)}), "model.presets", "did you mean 'preset'"),
    "unknown axis key": (sweep(axes=[{"key": FIELD, "value": [60]}]), "axes[0].value", "did you mean 'values'"),
    "replicates as a string": (sweep(replicates="3"), "replicates", "'3'"),
    "seed not an integer": (sweep(seed=1.5), "seed", "1.5"),
    "zero replicates": (sweep(replicates=0), "replicates", ">= 1"),
    "flag not a boolean": (sweep(common_random_numbers="yes"), "common_random_numbers", "true or false"),
    "bad keep": (sweep(run={"keep": "trajectory"}), "run.keep", "did you mean 'trajectories'"),
    "empty axis values": (sweep(axes=[axis(FIELD, [])]), "axes[0].values", "non-empty"),
    "repeated axis values": (sweep(axes=[axis(FIELD, [60, 90, 60])]), "axes[0].values", "repeat"),
    "zip value of wrong length": (
        sweep(axes=[{"keys": ["perception.direction_deg", FIELD], "values": [[20, 60], [90]]}]),
        "axes[0].values[1]", "2 values"),
    "both key and keys": (
        sweep(axes=[{"key": FIELD, "keys": [FIELD, RANGE], "values": [[60, 10]]}]), "axes[0]", "exactly one"),
    "neither key nor keys": (sweep(axes=[{"values": [60]}]), "axes[0]", "exactly one"),
    "values and linspace": (
        sweep(axes=[{"key": FIELD, "values": [60], "linspace": {"start": 1, "stop": 2, "num": 2}}]),
        "axes[0]", "exactly one of 'values'"),
    "unknown model file": (sweep(model={"preset": "no/such/model.toml"}), "model.preset", "not found"),
    "out-of-range axis value": (
        sweep(axes=[axis(FIELD, [60, 400])]), FIELD, "design point perception.field_deg=400"),
    "axis key not a preset key": (
        sweep(axes=[axis("perception.feild_deg", [60])]), "perception.feild_deg", "did you mean 'field_deg'"),
    "bad model.set key": (
        sweep(model={"preset": str(HOLLAND), "set": {"steering.cohesion_wieght": 1.0}}),
        "steering.cohesion_wieght", "did you mean 'cohesion_weight'"),
    "key swept twice (alias n)": (sweep(axes=[axis("init.n", [6]), axis("n", [8])]), "axes", "'init.n' is swept twice"),
    "key swept by an axis and the sample": (
        sweep(axes=[axis(FIELD, [60])], sample={"n": 2, "bounds": {FIELD: [30, 90]}}), "axes", "swept twice"),
    "bad sample method": (
        sweep(sample={"method": "lhc", "n": 4, "bounds": {FIELD: [30, 90]}}), "sample.method", "did you mean 'lhs'"),
    "empty sample bounds": (sweep(sample={"n": 4, "bounds": {}}), "sample.bounds", "low, high"),
    "sample bounds reversed": (
        sweep(sample={"n": 4, "bounds": {FIELD: [90, 30]}}), f"sample.bounds.{FIELD}", "low must be < high"),
    "labels count mismatch": (
        sweep(axes=[axis("patterns.enabled", [False, True], labels=["normal"])]), "axes[0].labels", "2 strings"),
    "linspace num zero": (
        sweep(axes=[{"key": FIELD, "linspace": {"start": 30, "stop": 90, "num": 0}}]), "axes[0].linspace.num", ">= 1"),
    "missing name": ({k: v for k, v in sweep().items() if k != "name"}, "name", "non-empty string"),
}


@pytest.mark.parametrize("case", list(BAD_CONFIGS))
def test_bad_config_is_a_config_error_naming_the_key(case):
    data, key, hint = BAD_CONFIGS[case]
    with pytest.raises(ConfigError) as info:
        build(data)
    assert info.value.key == key
    assert hint in str(info.value)


def test_out_of_range_value_names_key_allowed_range_and_design_point():
    data = sweep(axes=[axis("init.n", [6, 8]), axis(FIELD, [60, 400])])
    with pytest.raises(ConfigError) as info:
        build(data)
    message = str(info.value)
    assert message.startswith("perception.field_deg:")
    assert "400" in message and "(0.0, 360.0]" in message
    assert "design point init.n=6, perception.field_deg=400" in message


@pytest.mark.parametrize("case", ["out-of-range axis value", "axis key not a preset key", "bad model.set key"])
def test_run_sweep_validates_the_whole_design_before_writing_anything(case, tmp_path):
    data, key, _ = BAD_CONFIGS[case]
    config = sweep_from_dict(data, ROOT)  # these pass parsing; the design expansion rejects them
    out = tmp_path / "results"
    with pytest.raises(ConfigError) as info:
        run_sweep(config, "", out, executor="serial", progress=False)
    assert info.value.key == key
    assert not out.exists()


CLI_BAD_FILES = {
    "unknown axis key": ('[[axes]]\nkey = "perception.field_deg"\nvales = [60]\n', "axes[0].vales"),
    "out-of-range axis value": ('[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 400]\n',
                                "perception.field_deg=400"),
    "wrong type": ('[sample]\nmethod = "lhs"\nn = "eight"\nbounds = { "init.n" = [6, 12] }\n', "sample.n"),
    "bad labels": ('[[axes]]\nkey = "init.n"\nvalues = [6, 8]\nlabels = ["a", "b", "c"]\n', "axes[0].labels"),
}


@pytest.mark.parametrize("dry_run", [False, True], ids=["run", "dry-run"])
@pytest.mark.parametrize("case", list(CLI_BAD_FILES))
def test_cli_reports_config_errors_with_exit_status_2_and_writes_nothing(case, dry_run, tmp_path, capsys):
    body, needle = CLI_BAD_FILES[case]
    path = tmp_path / "bad.toml"
    path.write_text(toml_sweep(body))
    out = tmp_path / "results"
    argv = ["run", str(path), "--out", str(out), "--no-progress", "--executor", "serial"]
    assert main(argv + (["--dry-run"] if dry_run else [])) == 2
    err = capsys.readouterr().err
    assert "config error" in err and needle in err
    assert not out.exists()


def test_cli_bad_toml_and_missing_file_are_config_errors(tmp_path, capsys):
    broken = tmp_path / "broken.toml"
    broken.write_text('name = "x"\n[model\n')
    assert main(["run", str(broken), "--out", str(tmp_path / "a")]) == 2
    assert "not valid TOML" in capsys.readouterr().err
    assert main(["run", str(tmp_path / "absent.toml"), "--out", str(tmp_path / "b")]) == 2
    assert "sweep file not found" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


# -- overrides -------------------------------------------------------------------------------------

def test_load_sweep_applies_set_overrides_and_replicates():
    plain = load_sweep(SHIPPED / "smoke.toml")
    config = load_sweep(SHIPPED / "smoke.toml", ["run.duration=2.0", "seed=9", "run.keep=trajectories",
                                                  "model.set.steering.cohesion_weight=3.5"], replicates=3)
    assert (plain.replicates, plain.seed, plain.preset_data["run"]["duration"]) == (2, 1, 4.0)
    assert config.replicates == 3 and config.seed == 9
    assert config.storage.keep == "trajectories"
    specs = expand(config)
    assert len(specs) == 2 * 2 * 3
    assert all(s.preset.run.duration == 2.0 for s in specs)
    assert all(s.preset.model.steering.cohesion_weight == 3.5 for s in specs)
    assert config.source["run"]["duration"] == 2.0  # recorded as run (sweep.effective.json)


def test_bad_override_is_a_config_error_naming_the_overridden_key():
    with pytest.raises(ConfigError) as info:
        load_sweep(SHIPPED / "smoke.toml", ["run.duraton=2"])
    assert info.value.key == "run.duraton" and "did you mean 'duration'" in str(info.value)
    with pytest.raises(ConfigError) as info:
        load_sweep(SHIPPED / "smoke.toml", replicates=0)
    assert info.value.key == "replicates"


def test_cli_set_and_replicates_reach_the_runner(monkeypatch, tmp_path, capsys):
    seen = {}
    signature = inspect.signature(runner.run_sweep)

    def fake_run_sweep(*args, **kwargs):  # records its arguments by name, runs nothing
        seen.update(signature.bind(*args, **kwargs).arguments)
        plan = Plan(specs=expand(seen["config"]))
        plan.todo = list(plan.specs)
        return SweepResult(Path(seen["out_dir"]), plan, None, 0.0, {"boid_steps": 0, "seconds": 0.0, "compile_s": 0.0,
                                                                   "startup_s": 0.0, "per_run_s": 0.0, "total_s": 0.0})

    monkeypatch.setattr(runner, "run_sweep", fake_run_sweep)
    out = tmp_path / "results"
    code = main(["run", str(SHIPPED / "smoke.toml"), "--set", "run.duration=2.0", "--set", "seed=11",
                 "--replicates", "3", "--out", str(out), "--dry-run", "--executor", "serial", "--workers", "1"])
    assert code == 0
    config = seen["config"]
    assert config.replicates == 3 and config.seed == 11
    assert config.preset_data["run"]["duration"] == 2.0
    assert (seen["executor"], seen["workers"], seen["dry_run"], seen["out_dir"]) == ("serial", 1, True, out)
    assert "smoke: 12 runs; 0 done" in capsys.readouterr().out


@pytest.mark.parametrize("argv, needle", [
    (["--replicates", "0"], "--replicates"),
    (["--set", "replicates=0"], "replicates"),
    (["--set", "run.duraton=2"], "run.duraton"),
    (["--workers", "0"], "--workers"),
    (["--scheduler", "tcp://127.0.0.1:1"], "--scheduler"),
])
def test_cli_bad_overrides_exit_2(argv, needle, tmp_path, capsys):
    out = tmp_path / "results"
    assert main(["run", str(SHIPPED / "smoke.toml"), "--out", str(out), "--no-progress"] + argv) == 2
    assert needle in capsys.readouterr().err
    assert not out.exists()


# -- known bugs ------------------------------------------------------------------------------------

def test_axis_name_cannot_clobber_the_seed_column():
    data = sweep(axes=[axis(FIELD, [60, 90], name="seed")])
    try:
        specs = build(data)
    except ConfigError:
        return  # rejecting a reserved column name is a fine fix
    table = design_table(specs)
    assert list(table["seed"]) == [s.seed for s in specs]


def test_values_equal_after_resolution_do_not_give_duplicate_run_ids():
    data = sweep(axes=[axis(FIELD, [60, 60.0])])
    try:
        specs = build(data)
    except ConfigError:
        return  # "values repeat" is the expected error
    assert len({s.run_id for s in specs}) == len(specs)


def test_leadership_metrics_are_switched_on_when_leadership_is_swept_or_on():
    from flocksweep.sweeps.config import load_sweep as load

    configs = ROOT / "configs" / "sweeps"
    assert load(configs / "leadership.toml").metrics.leadership
    assert load(configs / "leadership_vision.toml").metrics.leadership
    assert not load(configs / "holland648.toml").metrics.leadership
    assert load(configs / "smoke.toml", ["model.set.leadership.x=1"]).metrics.leadership
    assert not load(configs / "smoke.toml", ["run.leadership_metrics=false", "model.set.leadership.x=1"]).metrics.leadership
    with pytest.raises(ConfigError) as info:
        load(configs / "smoke.toml", ["run.leadership_metrics=sometimes"])
    assert info.value.key == "run.leadership_metrics"


def test_boidspp_random_force_sweep_expands_with_its_claim_and_a_plain_flock():
    config = load_sweep(SHIPPED / "boidspp_random_force.toml")
    specs = expand(config)
    assert len(specs) == 75 == 5 * 3 * 5
    assert len({s.run_id for s in specs}) == 75
    table = specs[-1].preset.model.boidspp
    assert specs[-1].preset.model.dynamics == "boidspp" and not table.predator.enabled and not table.prey.enabled
    assert {(s.preset.model.boidspp.random_force.magnitude, s.preset.model.boidspp.random_force.every)
            for s in specs} == {(m, e) for m in (0, 1, 2, 4, 8) for e in (5, 20, 60)}
    assert [c.id for c in config.claims] == ["e"]
