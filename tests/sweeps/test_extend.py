"""Adding points to a stored sweep (sweeps.extend): the stored sweep is rebuilt with its run ids checked,
new points run through the sweep machinery into the same store with the usual identities, finished runs
are never recomputed, and a sampled block's bounds keep their order although the stored JSON sorts them."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.extend import add_points, stored_sweep
from flocksweep.sweeps.results import load_results
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")


def tiny(**tables) -> dict:
    data = {"name": "ext", "seed": 3, "replicates": 2, "model": {"preset": HOLLAND},
            "run": {"n": 6, "duration": 1.0, "record_interval": 0.5, "warmup": 0.25},
            "axes": [{"name": "mode", "key": "patterns.enabled", "values": [False, True],
                      "labels": ["normal", "pattern"]},
                     {"key": "perception.field_deg", "values": [60, 180]}]}
    data.update(tables)
    return data


@pytest.fixture()
def stored(tmp_path):
    config = sweep_from_dict(tiny(), ROOT)
    out = tmp_path / "results"
    run_sweep(config, "# tiny\n", out, executor="serial", progress=False)
    return config, out


def test_stored_sweep_rebuilds_the_design_with_its_run_ids(stored):
    config, out = stored
    rebuilt, text = stored_sweep(out)
    assert [s.run_id for s in expand(rebuilt)] == [s.run_id for s in expand(config)]
    assert text == "# tiny\n"


def test_added_points_run_in_the_same_store_with_the_usual_identities(stored):
    config, out = stored
    before = load_results(out).runs
    result, added = add_points(out, [{"patterns.enabled": False, "perception.field_deg": 100.5},
                                     {"patterns.enabled": True, "perception.field_deg": 120}],
                               executor="serial", progress=False)
    assert len(added) == 4 and len(result.plan.todo) == 4 and len(result.plan.done) == 8   # nothing recomputed
    runs = load_results(out).runs
    assert len(runs) == 12 and set(before["run_id"]) < set(runs["run_id"])
    new = runs[runs["run_id"].isin([s.run_id for s in added])]
    assert sorted(new["perception.field_deg"].unique()) == [100.5, 120.0] and (new["status"] == "ok").all()
    assert list(new["mode"].unique()) == ["normal", "pattern"]
    # the same points written into the sweep file give the same runs
    extended = sweep_from_dict(tiny(points=[{"patterns.enabled": False, "perception.field_deg": 100.5},
                                            {"patterns.enabled": True, "perception.field_deg": 120}]), ROOT)
    assert [s.run_id for s in expand(extended)][-4:] == [s.run_id for s in added]
    effective = json.loads((out / "sweep.effective.json").read_text())
    assert len(effective["points"]) == 2
    again, nothing = add_points(out, [{"patterns.enabled": False, "perception.field_deg": 100.5}],
                                executor="serial", progress=False)
    assert nothing == [] and not again.plan.todo and len(load_results(out).runs) == 12


@pytest.mark.slow
def test_a_sampled_blocks_bounds_keep_their_order(tmp_path):
    data = tiny(axes=[], design={"kind": "saltelli", "n": 4, "bounds": {"perception.range": [10, 20],
                                                                          "perception.field_deg": [60, 180]}},
                replicates=1)
    config = sweep_from_dict(data, ROOT)
    run_sweep(config, "", tmp_path / "r", executor="serial", progress=False)
    rebuilt, _ = stored_sweep(tmp_path / "r")
    assert rebuilt.design.keys == ("perception.range", "perception.field_deg")
    assert [s.run_id for s in expand(rebuilt)] == [s.run_id for s in expand(config)]


def test_a_changed_design_is_refused(stored, tmp_path):
    _, out = stored
    effective = json.loads((out / "sweep.effective.json").read_text())
    effective["seed"] = 4                                   # the stored design no longer follows from it
    (out / "sweep.effective.json").write_text(json.dumps(effective))
    with pytest.raises(ValueError, match="not in the stored design"):
        stored_sweep(out)
    with pytest.raises(FileNotFoundError, match="not a sweep results folder"):
        stored_sweep(tmp_path / "nothing")
    assert isinstance(pd.read_parquet(out / "runs.parquet"), pd.DataFrame)
