"""``flocksweep report --out`` never deletes a file it did not write (docs/errors.md): a non-empty folder it
did not write is refused before anything is written; a rebuild removes only what the previous build
recorded; the default report folder keeps the user's own files."""
from __future__ import annotations

import json

import pytest

from flocksweep.analysis.reports.report import REPORT_RECORD, build_report
from paths import ROOT
from flocksweep.simcore import ConfigError
from flocksweep.cli import main
from flocksweep.sweeps.config import sweep_from_dict
from flocksweep.sweeps.runner import run_sweep

HOLLAND = str(ROOT / "configs" / "models" / "holland.toml")


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "results"
    data = {"name": "folder", "seed": 3, "replicates": 2, "model": {"preset": HOLLAND},
            "run": {"n": 6, "duration": 1.0, "record_interval": 0.5, "warmup": 0.5},
            "axes": [{"key": "perception.field_deg", "values": [60, 180]}]}
    run_sweep(sweep_from_dict(data, ROOT), "# test\n", out, executor="serial", progress=False)
    return out


def files(folder) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.slow
def test_a_foreign_folder_is_refused_and_left_as_it_was(results, tmp_path, capsys):
    mine = tmp_path / "thesis"
    (mine / "figures").mkdir(parents=True)
    (mine / "figures" / "plot.png").write_bytes(b"my figure")
    (mine / "report.md").write_text("my notes")
    before = files(mine)
    assert main(["report", str(results), "--out", str(mine), "--format", "md"]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "not empty and was not written by flocksweep" in err
    assert files(mine) == before


@pytest.mark.slow
def test_a_rebuild_removes_only_what_the_previous_build_wrote(results, tmp_path):
    out = tmp_path / "report"
    first = build_report(results, out, formats=("md",))
    recorded = set(json.loads((out / REPORT_RECORD).read_text())["files"])
    assert "report.md" in recorded and any(name.startswith("tables/") for name in recorded)
    (out / "figures" / "mine.png").write_bytes(b"added by the user")      # not ours: must stay
    (out / "tables" / "stale.csv").write_text("x\n1\n")                     # ours from an older build
    (out / REPORT_RECORD).write_text(json.dumps({"files": sorted(recorded | {"tables/stale.csv"})}))
    build_report(results, out, formats=("md",))
    assert (out / "figures" / "mine.png").read_bytes() == b"added by the user"
    assert not (out / "tables" / "stale.csv").exists()
    assert set(json.loads((out / REPORT_RECORD).read_text())["files"]) == recorded
    assert first["paths"]["md"].exists()


@pytest.mark.slow
def test_the_default_folder_is_adopted_without_deleting_what_is_there(results):
    default = results / "report"
    default.mkdir(exist_ok=True)
    (default / "notes.txt").write_text("keep me")
    build_report(results, formats=("md",))
    assert (default / "notes.txt").read_text() == "keep me"
    assert "notes.txt" not in json.loads((default / REPORT_RECORD).read_text())["files"]


def test_an_output_path_that_is_a_file_is_a_config_error(results, tmp_path):
    target = tmp_path / "file.txt"
    target.write_text("x")
    with pytest.raises(ConfigError) as info:
        build_report(results, target, formats=("md",))
    assert info.value.key == "--out" and target.read_text() == "x"


@pytest.mark.slow
def test_an_interrupted_build_is_rerun_by_the_same_command(results, tmp_path, monkeypatch, capsys):
    from flocksweep.analysis.reports import report

    out = tmp_path / "rep"
    argv = ["report", str(results), "--out", str(out), "--format", "md"]

    def stopped(ctx, cells):
        raise KeyboardInterrupt
    monkeypatch.setattr(report, "_timeseries", stopped)
    assert main(argv) == 130
    assert any((out / "tables").iterdir())            # the stopped build had written some files
    monkeypatch.undo()
    assert main(argv) == 0, capsys.readouterr().err
    recorded = set(json.loads((out / REPORT_RECORD).read_text())["files"])
    assert "report.md" in recorded and "tables/design.csv" in recorded


@pytest.mark.slow
def test_a_bad_claims_file_is_refused_before_the_folder_is_written(results, tmp_path, capsys):
    claims = tmp_path / "claims.toml"
    claims.write_text("root:x:0:0:root:/root:/bin/bash\n")
    out = tmp_path / "rep"
    assert main(["report", str(results), "--claims", str(claims), "--out", str(out)]) == 2
    assert "claims.toml" in capsys.readouterr().err
    assert not out.exists()
