"""Integrity that cannot be switched off (docs/errors.md, "Disks and folders"): a part is verified only when
an intact manifest.json records the checksum its bytes have. Deleting the manifest, replacing it with
garbage, stripping its checksums, or dropping in a part it does not record makes the parts unverified:
every command after it says so (status, load_results, export, report), and ``run`` moves them aside and
computes their runs again, so an edited value is never vouched for by a fresh manifest."""
from __future__ import annotations

import json

import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from paths import ROOT
from flocksweep.cli import main
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.results import load_results
from flocksweep.sweeps.runner import run_sweep, status
from flocksweep.sweeps.store import ResultsStore

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
TIMING = ["wall_s", "sim_s", "part"]
SWEEP = f"""name = "vouched"
seed = 8
[model]
preset = "{HOLLAND}"
[run]
n = 6
duration = 1.0
record_interval = 0.5
warmup = 0.5
[[axes]]
key = "perception.field_deg"
values = [90, 270]
"""
FORGED = 0.123456789   # a value no run computes


def run(folder):
    sweep = folder.parent / "vouched.toml"
    sweep.write_text(SWEEP)
    return run_sweep(load_sweep(sweep), None, folder, executor="serial", progress=False, batch_size=1)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference") / "out"
    run(out)
    return out


def copy_of(reference, tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(reference, out)
    (tmp_path / "vouched.toml").write_text(SWEEP)
    return out


def forge_a_value(out):
    """Overwrite a metric of the first part with a valid-looking number (as a user's edit would)."""
    path = sorted((out / "runs").glob("part-*.parquet"))[0]
    pd.read_parquet(path).assign(cohesion_mean=FORGED).to_parquet(path, index=False)


def delete_manifest(out):
    (out / "manifest.json").unlink()


def garbage_manifest(out):
    (out / "manifest.json").write_text("{ not json")


def strip_checksums(out):
    data = json.loads((out / "manifest.json").read_text())
    data.pop("checksums"), data.pop("manifest_checksum")
    (out / "manifest.json").write_text(json.dumps(data))


def edit_manifest(out):
    (out / "manifest.json").write_text((out / "manifest.json").read_text().replace('"seed": 8', '"seed": 9'))


HOW = {"deleted": (delete_manifest, "manifest.json is missing"),
       "garbage": (garbage_manifest, "manifest.json is not valid JSON"),
       "checksums stripped": (strip_checksums, "manifest.json records no checksums"),
       "edited": (edit_manifest, "manifest.json changed since it was written (its checksum differs from the one it "
                                 "records)")}


def rows(out):
    return pd.read_parquet(out / "runs.parquet").drop(columns=TIMING)


@pytest.mark.parametrize("how", list(HOW))
def test_an_edited_part_is_never_vouched_for_by_a_new_manifest(how, reference, tmp_path, capsys):
    """The probe's case: a value overwritten, then the manifest deleted (or made useless) so that nothing
    would check it. status says so and counts nothing it cannot verify; run recomputes every run, the
    forged value is gone, and status --verify is clean afterwards."""
    damage, words = HOW[how]
    out = copy_of(reference, tmp_path)
    assert main(["status", str(out)]) == 0 and capsys.readouterr().err == ""   # clean: its counts remembered
    forge_a_value(out)
    damage(out)
    assert main(["status", str(out)]) == 0
    captured = capsys.readouterr()
    assert f"{words}, so the 1 stored part of runs/ cannot be verified: skipped as damaged" in captured.err
    assert "2 runs: 0 done, 0 failed, 2 missing" in captured.out and "Traceback" not in captured.err
    assert main(["run", str(out.parent / "vouched.toml"), "--out", str(out), "--executor", "serial",
                 "--no-progress"]) == 0
    captured = capsys.readouterr()
    assert f"{words}, so the 1 stored part of runs/ cannot be verified: moved to quarantine/" in captured.err
    assert "computed 2 now" in captured.out
    assert FORGED not in set(pd.read_parquet(out / "runs.parquet")["cohesion_mean"])
    assert_frame_equal(rows(out), rows(reference), check_exact=True)
    assert len(list((out / "quarantine").rglob("part-*"))) == 2   # the part, with its series
    assert main(["status", "--verify", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "2 runs: 2 done, 0 failed, 0 missing" in captured.out


def test_every_reader_says_so_the_first_time(reference, tmp_path, capsys):
    """load_results, export and report after the manifest was deleted: one warning naming it, nothing
    unverified used (no rows, no series), and nothing moved."""
    out = copy_of(reference, tmp_path)
    delete_manifest(out)
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    loaded = load_results(out, timeseries=True)
    assert len(loaded.runs) == 0 and len(loaded.series()) == 0
    assert "manifest.json is missing, so the 1 stored part of runs/ cannot be verified" in capsys.readouterr().err
    assert main(["export", str(out), "--csv", "--out", str(tmp_path / "exported")]) == 0
    err = capsys.readouterr().err
    assert "manifest.json is missing, so the 1 stored part of runs/ cannot be verified" in err and "Traceback" not in err
    assert len(pd.read_csv(tmp_path / "exported" / "runs.csv")) == 0
    code = main(["report", str(out), "--out", str(tmp_path / "report"), "--no-progress"])
    err = capsys.readouterr().err
    assert "manifest.json is missing, so the 1 stored part of runs/ cannot be verified" in err and "Traceback" not in err
    assert code == 2 and "no finished runs to report on" in err and "runs.parquet" not in err
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before


def test_a_part_the_manifest_does_not_record_is_not_adopted(reference, tmp_path, capsys):
    """A part under a new number (a copy of a stored one, edited) that the intact manifest does not
    record is skipped by readers and moved aside by run, never recorded (before: run adopted it)."""
    out = copy_of(reference, tmp_path)
    first = sorted((out / "runs").glob("part-*.parquet"))[0]
    extra = out / "runs" / "part-000009.parquet"
    pd.read_parquet(first).assign(part=9, cohesion_mean=FORGED).to_parquet(extra, index=False)
    series = out / "timeseries"
    (series / "part-000009.parquet").write_bytes((series / first.name).read_bytes())
    info = status(out)
    assert "runs/part-000009.parquet cannot be verified (manifest.json records no checksum of it" in \
        capsys.readouterr().err
    assert info["ok"] == 2
    run(out)
    assert "part-000009" in capsys.readouterr().err
    assert not extra.exists() and "runs/part-000009.parquet" not in ResultsStore(out).checksums()
    assert FORGED not in set(pd.read_parquet(out / "runs.parquet")["cohesion_mean"])
    assert_frame_equal(rows(out), rows(reference), check_exact=True)


def test_a_part_is_recorded_in_the_manifest_before_it_has_its_name(tmp_path, monkeypatch):
    """So that a part a killed runner left without a recorded checksum cannot exist, and one without a
    checksum is never flocksweep's: at the moment the manifest is written, neither file of the part
    exists yet, and the manifest already holds both checksums."""
    store = ResultsStore(tmp_path)
    seen = []
    write_manifest = ResultsStore.write_manifest

    def spy(self, data):
        seen.append(((tmp_path / "runs" / "part-000001.parquet").exists(),
                     (tmp_path / "timeseries" / "part-000001.parquet").exists(), dict(self.checksums())))
        write_manifest(self, data)
    monkeypatch.setattr(ResultsStore, "write_manifest", spy)
    rows_ = [{"run_id": "a", "status": "ok", "error": "", "cohesion_mean": 0.5}]
    store.write_part(1, rows_, pd.DataFrame({"run_id": ["a"], "t": [0.0], "cohesion": [0.5]}))
    assert len(seen) == 1
    runs_exists, series_exists, sums = seen[0]
    assert not runs_exists and not series_exists
    assert {"runs/part-000001.parquet", "timeseries/part-000001.parquet"} <= set(sums)
    fresh = ResultsStore(tmp_path)
    assert fresh.unverified(tmp_path / "runs" / "part-000001.parquet") is None
    assert fresh.unverified(tmp_path / "timeseries" / "part-000001.parquet") is None


def test_a_reader_meets_a_part_written_after_it_read_the_manifest(tmp_path, caplog):
    """status while a runner works: a part that got its name after the reader loaded the manifest is
    recorded in the manifest now (before its rename), so the reader reads it again and finds it; likewise
    a runs.parquet rewritten meanwhile. No warning, nothing skipped."""
    def part(run_id):
        return ([{"run_id": run_id, "status": "ok", "error": "", "cohesion_mean": 0.5}],
                pd.DataFrame({"run_id": [run_id], "t": [0.0], "cohesion": [0.5]}))

    ResultsStore(tmp_path).write_part(1, *part("a"))
    reader = ResultsStore(tmp_path)
    assert list(reader.latest()["run_id"]) == ["a"]          # it has read the manifest
    runner = ResultsStore(tmp_path)
    runner.write_part(2, *part("b"))
    runner.consolidate(pd.DataFrame({"run_id": ["a", "b"], "index": [0, 1]}))
    assert list(reader.latest()["run_id"]) == ["a", "b"]
    assert list(reader.runs()["run_id"]) == ["a", "b"]
    assert "cannot be verified" not in caplog.text and "changed since" not in caplog.text
