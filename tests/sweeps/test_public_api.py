"""The sweeps' Python API (sweeps/__init__.py): a sweep built from a dict runs with run_sweep(sweep, out)
and stores a sweep.toml that reads back as the same sweep; load_results adds every fixed setting as a
column and opens the time series lazily, each run once; flocksweep export writes tables that read back
equal to the store."""
from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pandas as pd
import pyarrow.dataset as ds
import pytest

from flocksweep.simcore import load_preset
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps import ResultsStore, Sweep, load_results, run_sweep
from flocksweep.cli import main
from flocksweep.sweeps.design import expand
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")


def tiny(**tables) -> dict:
    data = {"name": "api", "seed": 5, "replicates": 2, "model": {"preset": HOLLAND, "set": {"perception.range": 18}},
            "run": {"n": 6, "duration": 1.0, "record_interval": 0.5, "warmup": 0.25},
            "axes": [{"name": "mode", "key": "patterns.enabled", "values": [False, True],
                      "labels": ["normal", "pattern"]},
                     {"key": "perception.field_deg", "values": [60, 180]}]}
    data.update(tables)
    return data


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    sweep = Sweep.from_dict(tiny(), ROOT)
    out = tmp_path_factory.mktemp("api") / "results"
    result = run_sweep(sweep, out, executor="serial", progress=False)
    assert (result.table["status"] == "ok").all() and len(result.table) == 8
    return sweep, out


def test_a_dict_built_sweep_stores_a_sweep_toml_that_reads_back_as_the_same_sweep(stored, tmp_path):
    sweep, out = stored
    text = (out / "sweep.toml").read_text()
    assert text.strip() and 'field_deg' in text
    again = Sweep.from_toml(out / "sweep.toml")
    assert [s.run_id for s in expand(again)] == [s.run_id for s in expand(sweep)]
    assert again.text == text
    # ... where it is stored (the preset path is relative to the results folder), finding every run done
    assert f'preset = "{os.path.relpath(HOLLAND, out)}"' in text
    rerun = run_sweep(Sweep.from_toml(out / "sweep.toml"), out, executor="serial", progress=False)
    assert not rerun.plan.todo and len(rerun.plan.done) == 8


def test_a_file_built_sweep_stores_its_own_text(tmp_path):
    path = ROOT / "configs/sweeps/smoke.toml"
    sweep = Sweep.from_toml(path, ["run.duration=1.0", "run.warmup=0.25", "replicates=1"])
    assert sweep.text == path.read_text() and sweep.replicates == 1
    result = run_sweep(sweep, tmp_path / "out", executor="serial", dry_run=True)
    assert len(result.plan.todo) == 4


def test_to_toml_names_a_value_toml_cannot_hold():
    sweep = Sweep.from_dict(tiny(report={"title": None}), ROOT)
    with pytest.raises(ConfigError, match="report.title"):
        sweep.to_toml()


def test_load_results_with_fixed_has_every_fixed_setting_as_a_column(stored):
    sweep, out = stored
    plain = load_results(out)
    results = load_results(out, with_fixed=True)
    assert plain.fixed == [] and list(results.runs.columns[:plain.runs.shape[1]]) == list(plain.runs.columns)
    pd.testing.assert_frame_equal(results.runs[plain.runs.columns], plain.runs)
    preset = load_preset(HOLLAND, ["perception.range=18", "init.n=6", "run.duration=1.0", "run.record_interval=0.5"])
    expected = {"perception.range": 18.0, "init.n": 6, "run.duration": 1.0, "run.dt": preset.run.dt,
                "steering.separation_weight": preset.model.steering.separation_weight,
                "perception.kind": "binocular", "analysis.warmup": 0.25,
                "patterns.set": json.dumps(preset.to_dict()["patterns"]["set"])}
    for column, value in expected.items():
        assert column in results.fixed, column
        assert (results.runs[column] == value).all(), column
    assert "perception.field_deg" not in results.fixed and "patterns.enabled" not in results.fixed
    assert not any(c.startswith("patterns.enabled") for c in results.fixed)
    assert sorted(results.runs["perception.field_deg"].unique()) == [60.0, 180.0]   # the swept column is untouched


def test_time_series_are_a_lazy_dataset_of_the_ok_runs(stored):
    sweep, out = stored
    results = load_results(out, timeseries=True)
    assert isinstance(results.timeseries, ds.Dataset)
    lazy = results.timeseries.to_table().to_pandas().drop(columns="part")
    eager = ResultsStore(out).timeseries()
    key = ["run_id", "t"]
    pd.testing.assert_frame_equal(lazy.sort_values(key).reset_index(drop=True)[eager.columns],
                                  eager.sort_values(key).reset_index(drop=True))
    some = list(results.runs["run_id"][:3])
    picked = results.series(some, columns=["run_id", "t", "polarization"])
    assert set(picked["run_id"]) == set(some) and list(picked.columns) == ["run_id", "t", "polarization"]
    assert len(picked) == 3 * 3   # records at 0, 0.5 and 1.0 s


def test_a_run_computed_again_appears_once_from_its_latest_part(tmp_path):
    sweep = Sweep.from_dict(tiny(), ROOT)
    out = tmp_path / "results"
    run_sweep(sweep, out, executor="serial", progress=False, batch_size=8)
    again = expand(sweep)[:3]
    from flocksweep.sweeps.runner import run_sweep as run_specs   # the subset form the --until rounds use

    run_specs(sweep, None, out, executor="serial", progress=False, force=True, specs=again)
    assert not run_sweep(sweep, out, executor="serial", progress=False).plan.todo   # the whole design again
    results = load_results(out, timeseries=True)
    assert sorted(results.runs["part"].unique()) == [1, 2]
    assert results.runs.set_index("run_id").loc[[s.run_id for s in again], "part"].eq(2).all()
    series = results.timeseries.to_table().to_pandas()
    assert not series.duplicated(["run_id", "t"]).any() and series["run_id"].nunique() == 8
    assert (series.groupby("run_id")["part"].first()[[s.run_id for s in again]] == 2).all()
    # the old part still holds the recomputed runs' rows (deterministic, so equal values) but only once is read
    old = pd.read_parquet(out / "timeseries" / "part-000001.parquet")
    assert set(s.run_id for s in again) <= set(old["run_id"])


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_export_reads_back_equal_to_the_store(stored, tmp_path, fmt, capsys):
    sweep, out = stored
    target = tmp_path / fmt
    assert main(["export", str(out), f"--{fmt}", "--with-fixed", "--timeseries", "--out", str(target)]) == 0
    assert "runs." + fmt in capsys.readouterr().out
    read = pd.read_csv if fmt == "csv" else pd.read_parquet
    runs = read(target / f"runs.{fmt}")
    results = load_results(out, with_fixed=True, timeseries=True)
    expected = results.runs.drop(columns="part")
    assert list(runs.columns) == list(expected.columns) and list(runs["run_id"]) == list(expected["run_id"])
    for column in results.metrics + ["perception.field_deg", "seed", "perception.range", "init.n", "analysis.warmup"]:
        np.testing.assert_array_equal(runs[column].to_numpy(dtype=float), expected[column].to_numpy(dtype=float),
                                      err_msg=column)   # CSV floats round-trip exactly (shortest repr)
    assert list(runs["mode"]) == list(expected["mode"]) and list(runs["patterns.set"]) == list(expected["patterns.set"])
    series = read(target / f"timeseries.{fmt}")
    stored_series = results.series()
    order = {r: k for k, r in enumerate(expected["run_id"])}
    assert list(series["run_id"].map(order)) == sorted(series["run_id"].map(order))   # design order, then time
    merged = series.merge(stored_series, on=["run_id", "t"], suffixes=("", "_store"))
    assert len(merged) == len(series) == len(stored_series)
    for column in [c for c in series.columns if c not in ("run_id", "t")]:
        np.testing.assert_array_equal(merged[column].to_numpy(dtype=float), merged[f"{column}_store"].to_numpy(dtype=float))


def test_export_without_a_results_directory_or_a_format_is_an_input_error(tmp_path, capsys):
    assert main(["export", str(tmp_path / "missing"), "--csv"]) == 2
    assert "not a sweep results directory" in capsys.readouterr().err
    with pytest.raises(SystemExit) as raised:
        main(["export", str(tmp_path)])
    assert raised.value.code == 2


def test_fixed_columns_of_a_preset_that_no_longer_validates_are_its_stored_keys(stored, tmp_path):
    """A stored preset whose init file has moved since still gives its fixed settings (as stored)."""
    import shutil

    sweep, out = stored
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    record = json.loads((copy / "model.json").read_text())
    record["preset"]["init"]["from_file"] = str(tmp_path / "moved.npz")
    (copy / "model.json").write_text(json.dumps(record))
    results = load_results(copy, with_fixed=True)
    assert (results.runs["init.from_file"] == str(tmp_path / "moved.npz")).all()
    assert (results.runs["perception.range"] == 18).all() and "perception.field_deg" not in results.fixed


def test_a_results_folder_moved_with_its_repository_runs_again_from_its_sweep_toml(tmp_path):
    """Stored paths are relative to the results folder: sweep.toml and model.json of a file sweep and of
    a command line (--model/--axis) work after the repository (configs and results) has moved."""
    repo = tmp_path / "repo"
    (repo / "configs/models").mkdir(parents=True)
    (repo / "configs/sweeps").mkdir()
    shutil.copy(HOLLAND, repo / "configs/models/holland.toml")
    sweep_file = repo / "configs/sweeps/tiny.toml"
    sweep_file.write_text(Sweep.from_dict(tiny(replicates=1), ROOT).to_toml().replace(HOLLAND, "../models/holland.toml"))
    assert main(["run", str(sweep_file), "--out", str(repo / "results/tiny"), "--executor", "serial",
                 "--no-progress"]) == 0
    assert main(["run", "--model", str(repo / "configs/models/holland.toml"), "--axis", "perception.field_deg=60,90",
                 "--set", "run.n=6", "--set", "run.duration=1.0", "--set", "run.record_interval=0.5",
                 "--set", "run.warmup=0.25", "--out", str(repo / "results/axis"), "--executor", "serial",
                 "--no-progress"]) == 0
    moved = tmp_path / "elsewhere" / "moved"
    shutil.move(repo, moved)
    for name, runs in (("tiny", 4), ("axis", 2)):
        folder = moved / "results" / name
        assert json.loads((folder / "model.json").read_text())["preset_path"] == "../../configs/models/holland.toml"
        assert 'preset = "../../configs/models/holland.toml"' in (folder / "sweep.toml").read_text()
        again = run_sweep(Sweep.from_toml(folder / "sweep.toml"), folder, executor="serial", progress=False)
        assert not again.plan.todo and len(again.plan.done) == runs
