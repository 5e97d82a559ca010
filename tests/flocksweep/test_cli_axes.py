"""Sweeps from the command line: ``flocksweep run --model M --axis KEY=VALUES ...`` (flocksweep/command_line.py)
builds the sweep a file would, stores it resolved as RESULTS/sweep.toml, and that file reproduces it."""
from __future__ import annotations

import pandas as pd
import pytest

from flocksweep.simcore.schema import ConfigError
from flocksweep.cli import main
from flocksweep.command_line import parse_axis_flag
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
TINY = ["--set", "run.duration=1.0", "--set", "run.warmup=0.5", "--executor", "serial", "--no-progress"]
FILE = f'''
name = "by_hand"
seed = 0
replicates = 2
[model]
preset = "{HOLLAND}"
set = {{ "perception.range" = 20 }}
[run]
duration = 1.0
warmup = 0.5
[[axes]]
key = "perception.field_deg"
values = [30, 90, 180]
[[axes]]
key = "n"
values = [4, 6]
'''


def test_axis_flags_take_the_forms_of_axes_tables():
    assert parse_axis_flag("perception.field_deg=30,90,180") == {"key": "perception.field_deg", "values": [30, 90, 180]}
    assert parse_axis_flag("patterns.enabled=false,true") == {"key": "patterns.enabled", "values": [False, True]}
    assert parse_axis_flag("perception.kind=binocular") == {"key": "perception.kind", "values": ["binocular"]}
    assert parse_axis_flag("perception.range=linspace(10, 40, 4)") == \
        {"key": "perception.range", "linspace": {"start": 10, "stop": 40, "num": 4}}
    assert parse_axis_flag("init.n=range(10,30,10)") == {"key": "init.n", "range": {"start": 10, "stop": 30, "step": 10}}
    for bad in ("perception.field_deg", "=1,2", "perception.field_deg=", "perception.field_deg=1,,2",
                "perception.range=linspace(1,2)", "perception.range=range(1,a,2)"):
        with pytest.raises(ConfigError) as info:
            parse_axis_flag(bad)
        assert info.value.key == "--axis" and repr(bad) in str(info.value)


@pytest.mark.slow
def test_command_line_sweep_equals_the_file_sweep_and_its_stored_file_reproduces_it(tmp_path, capsys):
    flags = ["run", "--model", HOLLAND, "--axis", "perception.field_deg=30,90,180", "--axis", "init.n=4,6",
             "--replicates", "2", "--set", "model.perception.range=20"]
    assert main(flags + ["--out", str(tmp_path / "cli")] + TINY) == 0
    stored = tmp_path / "cli" / "sweep.toml"
    text = stored.read_text()
    assert "flocksweep run --model" in text and "replicates = 2" in text and "range = 20" in text
    assert main(["run", str(stored), "--out", str(tmp_path / "again")] + TINY[4:]) == 0
    by_hand = tmp_path / "by_hand.toml"
    by_hand.write_text(FILE)
    assert main(["run", str(by_hand), "--out", str(tmp_path / "file")] + TINY[4:]) == 0
    tables = {name: pd.read_parquet(tmp_path / name / "runs.parquet").sort_values("run_id").reset_index(drop=True)
              for name in ("cli", "again", "file")}
    assert len(tables["cli"]) == 12 and (tables["cli"]["status"] == "ok").all()
    metrics = [c for c in tables["cli"].columns if c.endswith(("_mean", "_final"))]
    for other in ("again", "file"):   # same run ids, bit-identical metrics
        assert tables[other]["run_id"].tolist() == tables["cli"]["run_id"].tolist()
        pd.testing.assert_frame_equal(tables[other][metrics], tables["cli"][metrics])
    assert sorted(set(tables["cli"]["perception.field_deg"])) == [30, 90, 180]


@pytest.mark.parametrize("argv, flag, words", [
    (["--model", HOLLAND, "--axis", "perception.feild_deg=30,90"], "--axis", ["perception.feild_deg=30,90",
                                                                                "did you mean 'field_deg'"]),
    (["--model", HOLLAND, "--axis", "perception.field_deg=30,400"], "--axis", ["allowed range", "400"]),
    (["--model", HOLLAND, "--axis", "perception.field_deg=linspace(1,2)"], "--axis", ["3 numbers"]),
    (["--model", HOLLAND], "--axis", ["missing"]),
    (["--axis", "perception.field_deg=30"], "sweep", ["--model"]),
    (["--model", "nope.toml", "--axis", "perception.field_deg=30"], "--model", ["no such file"]),
    ([str(ROOT / "configs/sweeps/smoke.toml"), "--model", HOLLAND], "--model", ["only without a sweep file"]),
    ([str(ROOT / "configs/sweeps/smoke.toml"), "--name", "x"], "--name", ["only without a sweep file"]),
    (["--model", HOLLAND, "--axis", "perception.field_deg=30", "--name", "a/b"], "name", ["plain folder name"]),
])
def test_bad_flags_are_named_before_anything_runs(tmp_path, capsys, argv, flag, words):
    out = tmp_path / "out"
    assert main(["run", *argv, "--out", str(out), "--executor", "serial", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert f"{flag}:" in err and all(word in err for word in words), err
    assert not out.exists()


def test_help_documents_axis_and_set_forms(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--axis KEY=VALUES" in text and "linspace(START,STOP,NUM)" in text and "model.<preset key>=VALUE" in text
