"""The worked plug-in example (examples/couzin_like*.toml, docs/plugins.md) through the command line: a grid
over two of its parameters runs, resumes without recomputing, is reported with its claims file (the claim
reaches its verdict from the data), and a stored run is viewed (re-simulated bit for bit from its stored
spec), but refused once the module's source hash differs from the one its run id was made with."""
from __future__ import annotations

import dataclasses
import json
import re

import pandas as pd
import pytest

from flocksweep.cli import main
from paths import ROOT
from flocksweep.simcore import plugin as plugins

SWEEP = ROOT / "examples" / "couzin_like_sweep.toml"
SMALL = ["--set", "run.n=12"]   # 20 s runs (400 steps): the flock settles at its spacing


def page_json(path) -> dict:
    return json.loads(re.search(r'id="flock-data">(.*?)</script>', path.read_text(), re.S).group(1))


@pytest.mark.slow
def test_the_example_plugin_is_swept_reported_and_viewed(tmp_path, capsys, monkeypatch):
    out = tmp_path / "results"
    argv = ["run", str(SWEEP), *SMALL, "--out", str(out), "--executor", "serial", "--no-progress"]
    assert main(argv) == 0
    runs = pd.read_parquet(out / "runs.parquet")
    assert len(runs) == 12 and (runs["status"] == "ok").all()
    assert set(runs["plugin.zor"]) == {1.0, 2.0, 3.0} and set(runs["plugin.gain"]) == {2.0, 6.0}
    assert json.loads((out / "model.json").read_text())["preset"]["dynamics"] == "examples.couzin_like"

    capsys.readouterr()
    assert main(argv) == 0                                  # resume: nothing recomputed
    assert "computed 0 now, 12 already done" in capsys.readouterr().out

    assert main(["report", str(out), "--out", str(tmp_path / "report"), "--format", "md", "--no-progress"]) == 0
    claims = pd.read_csv(tmp_path / "report" / "tables" / "claims.csv")
    assert list(claims["claim"]) == ["repulsion-spaces"]
    assert claims["verdict"].iloc[0] == "supported"        # neighbours further apart with a wider zor
    assert (tmp_path / "report" / "figures" / "claim_repulsion-spaces.png").stat().st_size > 5000

    run_id = runs.sort_values("run_id")["run_id"].iloc[0]
    page = tmp_path / "run.html"
    assert main(["view", str(out), "--run", run_id, "--out", str(page)]) == 0
    assert "bit for bit" in capsys.readouterr().out
    data = page_json(page)
    assert data["n"] == 12 and data["info"]["run id"] == run_id
    assert data["params"]["plugin.zor"] in (1.0, 2.0, 3.0)

    # the module edited since (its source hash differs): the stored run no longer hashes to its id, refused
    edited = dataclasses.replace(plugins.load("examples.couzin_like"), sha256="0" * 64)
    monkeypatch.setitem(plugins.LOADED, "examples.couzin_like", edited)
    capsys.readouterr()
    assert main(["view", str(out), "--run", run_id, "--out", str(tmp_path / "edited.html")]) == 2
    assert "hashes to" in capsys.readouterr().err
    assert not (tmp_path / "edited.html").exists()
