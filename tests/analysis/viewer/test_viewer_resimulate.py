"""`flocksweep view` of sweep runs: a run is found by id, by parameter point and replicate, or by its
showcase name; re-simulated from its stored spec and seed it reproduces every stored metric bit for bit;
a run whose stored results differ is refused with the differing column named; and the CLI writes pages
from a model preset, a sweep run and a trajectory, refusing flags that do not apply."""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flocksweep.observables.summary import every_nth
from flocksweep.analysis.viewer.encode import decode_stream
from flocksweep.analysis.viewer.resimulate import (NotReproduced, RunNotFound, parse_where, record_step_for, reproduce,
                                        select_run)
from flocksweep.cli import main
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.runner import run_sweep
from flocksweep.sweeps.store import ResultsStore
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")


def page_json(path: Path) -> dict:
    html = Path(path).read_text()
    return json.loads(re.search(r'id="flock-data">(.*?)</script>', html, re.S).group(1))


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """2 modes x 2 fields x 2 replicates, 10 boids for 2 s, with a showcase entry."""
    data = {"name": "tiny", "seed": 7, "replicates": 2, "model": {"preset": HOLLAND},
            "run": {"n": 10, "duration": 2.0, "record_interval": 0.5, "warmup": 0.5},
            "axes": [{"name": "mode", "key": "patterns.enabled", "values": [False, True],
                      "labels": ["normal", "pattern"]},
                     {"key": "perception.field_deg", "values": [60, 180]}],
            "report": {"showcase": {"wide": {"mode": "pattern", "perception.field_deg": 180}}}}
    out = tmp_path_factory.mktemp("tiny") / "results"
    run_sweep(sweep_from_dict(data, ROOT), "# test\n", out, executor="serial", progress=False)
    return out


def test_parse_where():
    assert parse_where("perception.field_deg=60, n=100 ,mode=normal, patterns.enabled=true") == {
        "perception.field_deg": 60, "init.n": 100, "mode": "normal", "patterns.enabled": True}
    with pytest.raises(RunNotFound, match="expected key=value"):
        parse_where("perception.field_deg")
    with pytest.raises(RunNotFound, match="no key=value"):
        parse_where(" , ")


@pytest.mark.parametrize("where", [
    "__import__('os').system('touch pwned')=1",              # a call as a key
    "mode=__import__('os').system('touch pwned')",           # a call as a value: only a string
    "mode.__class__=1", "mode=x.__class__.__bases__",        # attribute access, dunder names
    "perception.field_deg=10**10**10",                       # a huge exponent: a string, never computed
    "mode=" + "(" * 500 + "1" + ")" * 500,                   # deep nesting: a string
])
def test_hostile_where_filters_are_data_never_code(sweep, where, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    parsed = parse_where(where)
    assert all(isinstance(k, str) for k in parsed) and all(isinstance(v, (str, int, float, bool)) for v in parsed.values())
    with pytest.raises(RunNotFound, match="--where"):
        select_run(sweep, where=parsed)
    assert not (tmp_path / "pwned").exists()
    assert parse_where("perception.field_deg=10**10**10") == {"perception.field_deg": "10**10**10"}


def test_select_run_by_id_prefix_point_and_showcase(sweep):
    runs = pd.read_parquet(sweep / "runs.parquet")
    target = runs[(runs["mode"] == "pattern") & (runs["perception.field_deg"] == 180) & (runs["replicate"] == 1)]
    rid = target["run_id"].iloc[0]
    assert select_run(sweep, run_id=rid)["run_id"] == rid
    assert select_run(sweep, run_id=rid[:8])["run_id"] == rid
    assert select_run(sweep, where={"mode": "pattern", "perception.field_deg": 180.0}, replicate=1)["run_id"] == rid
    wide = select_run(sweep, showcase="wide")
    assert wide["mode"] == "pattern" and wide["perception.field_deg"] == 180 and wide["replicate"] == 0


def test_select_run_says_what_is_wrong(sweep):
    with pytest.raises(RunNotFound, match="matches 0 runs"):
        select_run(sweep, run_id="ffffffffff")
    with pytest.raises(RunNotFound, match=r"perception.field_deg takes: 180(\.0)?, 60"):
        select_run(sweep, where={"perception.field_deg": 90})
    with pytest.raises(RunNotFound, match="not a column"):
        select_run(sweep, where={"perception.range": 20})
    with pytest.raises(RunNotFound, match="differ in perception.field_deg"):
        select_run(sweep, where={"mode": "normal"})
    with pytest.raises(RunNotFound, match="no replicate 5"):
        select_run(sweep, where={"mode": "normal", "perception.field_deg": 60}, replicate=5)
    with pytest.raises(RunNotFound, match="entries: wide"):
        select_run(sweep, showcase="narrow")
    with pytest.raises(RunNotFound, match="exactly one of"):
        select_run(sweep)
    with pytest.raises(RunNotFound, match="not a sweep results directory"):
        select_run(sweep / "runs")


def test_every_run_reproduces_its_stored_metrics_bit_for_bit(sweep):
    runs = pd.read_parquet(sweep / "runs.parquet")
    for row in runs.to_dict("records"):
        result = reproduce(sweep, row, record_step=1)
        assert result.checks["identical"].all()
        metrics = result.checks[~result.checks["column"].str.startswith("series:")]
        assert len(metrics) >= 30
        assert {"polarization_mean", "cohesion_final", "nn_distance_mean"} <= set(metrics["column"])
        assert (result.checks["column"].str.startswith("series:")).sum() >= 10
        assert result.obs.pos.shape == (121, 10, 3)  # every step of 2 s at dt = 1/60
        # the viewed trajectory's 0.5 s records give the stored polarization_final exactly
        final = result.checks.set_index("column").loc["polarization_final"]
        assert final["stored"] == final["resimulated"]


def test_a_run_that_does_not_reproduce_is_refused(sweep, tmp_path):
    copy = tmp_path / "tampered"
    shutil.copytree(sweep, copy)
    runs = pd.read_parquet(copy / "runs.parquet")
    row = runs.iloc[3].to_dict()
    runs.loc[3, "cohesion_mean"] = np.nextafter(runs.loc[3, "cohesion_mean"], 2.0)  # one ulp off
    runs.to_parquet(copy / "runs.parquet", index=False)
    # a forger who records the changed file's checksum in the manifest: the value is read, not quarantined
    store = ResultsStore(copy)
    store._record(copy / "runs.parquet")
    store._save_checksums()
    tampered = select_run(copy, run_id=row["run_id"])
    with pytest.raises(NotReproduced, match="cohesion_mean: stored"):
        reproduce(copy, tampered)
    code = main(["view", str(copy), "--run", row["run_id"]])
    assert code == 2
    assert not (copy / "viewer").exists()


def test_a_changed_spec_is_refused(sweep, tmp_path):
    copy = tmp_path / "respec"
    shutil.copytree(sweep, copy)
    record = json.loads((copy / "model.json").read_text())
    record["preset"]["steering"]["cohesion_weight"] = 9.0
    (copy / "model.json").write_text(json.dumps(record))
    row = select_run(copy, where={"mode": "normal", "perception.field_deg": 60})
    with pytest.raises(NotReproduced, match="hashes to"):
        reproduce(copy, row)


def test_thinning_keeps_every_kth_record(sweep):
    row = select_run(sweep, showcase="wide")
    obs = reproduce(sweep, row, record_step=1).obs
    thin = every_nth(obs, 6)
    np.testing.assert_array_equal(thin.pos, obs.pos[::6])
    assert thin.record_every == 6 and len(thin.times) == 21
    assert record_step_for(1800, 100) == 1 and record_step_for(18000, 1000, max_bytes=400e6) == 3


def test_cli_views_a_sweep_run(sweep, capsys):
    assert main(["view", str(sweep), "--where", "mode=pattern, perception.field_deg=180", "--replicate", "1"]) == 0
    out = capsys.readouterr().out
    assert "bit for bit" in out
    rid = select_run(sweep, where={"mode": "pattern", "perception.field_deg": 180}, replicate=1)["run_id"]
    data = page_json(sweep / "viewer" / f"{rid}.html")
    assert data["info"]["run id"] == rid and data["info"]["replicate"] == 1
    assert data["params"]["patterns.enabled"] is True and data["defaults"]["color_by"] == "pattern"
    assert main(["view", str(sweep), "--showcase", "wide", "--out", str(sweep / "w.html")]) == 0
    assert page_json(sweep / "w.html")["info"]["showcase"] == "wide"
    assert main(["view", str(sweep)]) == 2
    assert "name the run" in capsys.readouterr().err


def test_cli_views_a_model_preset_and_a_trajectory(tmp_path, capsys):
    page = tmp_path / "h.html"
    assert main(["view", HOLLAND, "--n", "12", "--duration", "1", "--seed", "3", "--set", "perception.field_deg=200",
                 "--out", str(page)]) == 0
    data = page_json(page)
    assert data["n"] == 12 and data["frames"] == 61 and data["info"]["seed"] == 3
    assert data["params"]["perception.field_deg"] == 200.0
    # the page shows the simulation itself: same seed, same positions (to the quantum)
    from flocksweep.simcore import load_preset, simulate_preset

    preset = load_preset(HOLLAND, ["perception.field_deg=200", "init.n=12", "run.duration=1.0"])
    obs = simulate_preset(preset, 3, record_every=1)
    np.testing.assert_allclose(decode_stream(data["pos"]), obs.pos, atol=max(data["encoding"]["position_quantum"]))
    traj = tmp_path / "t.npz"
    np.savez(traj, times=obs.times, pos=obs.pos, vel=obs.vel, pattern=obs.pattern)
    assert main(["view", str(traj)]) == 0
    assert (tmp_path / "t.html").exists()
    assert "wrote" in capsys.readouterr().out


def test_cli_refuses_flags_that_do_not_apply(sweep, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["view", HOLLAND, "--run", "abc"]) == 2
    assert "--run: only applies when SOURCE is a sweep results directory" in capsys.readouterr().err
    assert main(["view", str(sweep), "--seed", "3", "--run", "abc"]) == 2
    assert "--seed" in capsys.readouterr().err
    assert main(["view", str(ROOT / "configs/sweeps/smoke.toml")]) == 2
    assert "is a sweep file" in capsys.readouterr().err
    assert main(["view", str(tmp_path / "missing.npz")]) == 2
    assert main(["view", HOLLAND, "--no-page"]) == 2
    assert main(["view", HOLLAND, "--n", "5", "--duration", "0.5", "--animate", str(tmp_path / "a.avi")]) == 2
    assert ".gif or .mp4" in capsys.readouterr().err
    assert main(["view", HOLLAND, "--animate", str(tmp_path / "a.mp4"), "--size", "641x480"]) == 2
    assert "even width and height" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()  # nothing was simulated or written


@pytest.mark.slow
def test_several_runs_make_one_page_with_a_block_per_run(sweep, tmp_path, capsys):
    ids = list(pd.read_parquet(sweep / "runs.parquet")["run_id"][:3])
    page = tmp_path / "three.html"
    assert main(["view", str(sweep), "--run", ids[0], ids[1][:8], ids[2], "--out", str(page), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert out.count("reproduces its stored results bit for bit") == 3 and "3 runs" in out
    html = page.read_text()
    assert re.findall(r'id="flock-data[-0-9]*" data-run="([^"]+)"', html) == ids
    blocks = re.findall(r'data-run="[^"]+" data-label="[^"]+">(.*?)</script>', html, re.S)
    assert [json.loads(b)["info"]["run id"] for b in blocks] == ids
    assert main(["view", str(sweep), "--run", ids[0], ids[1], "--animate", str(tmp_path / "a.gif")]) == 2
    assert "--animate: animates one run" in capsys.readouterr().err
    assert main(["view", str(sweep), "--run", ids[0], ids[0][:8], "--out", str(tmp_path / "twice.html")]) == 2
    assert "names a run twice" in capsys.readouterr().err
