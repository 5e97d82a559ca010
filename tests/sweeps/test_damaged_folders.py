"""Damaged results folders, full and read-only disks, file permissions (docs/errors.md).

* A part that cannot be read (garbage, truncated, a foreign table, a broken time series) is skipped with
  a warning by ``status`` (which moves nothing) and moved to ``quarantine/`` by ``run``, which then
  computes its runs again: the final table is bit for bit the uninterrupted one, with no foreign column.
* A garbage manifest is set aside and rewritten; a garbage design is a clear error for readers.
* A write that fails stops the sweep at once with one message naming the file and the errno (exit 4);
  what was saved before is kept and the same command resumes. A full disk while saving trajectories is
  not a run failure.
* Results files get the permissions the umask gives, not 0600.
* ``status`` during a run says a runner is working there, not that the run "did not finish".
"""
from __future__ import annotations

import contextlib
import errno
import os
import stat
from pathlib import Path

import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from paths import ROOT
from flocksweep.sweeps import files, runner, store as store_module, trajectory, worker
from flocksweep.cli import main
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.files import WriteFailed
from flocksweep.sweeps.runner import run_sweep, status
from flocksweep.sweeps.store import ResultsStore

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
TIMING = ["wall_s", "sim_s", "part"]
SWEEP = f"""name = "damaged"
seed = 4
replicates = 2
[model]
preset = "{HOLLAND}"
[run]
n = 7
duration = 1.0
record_interval = 0.5
warmup = 0.5
{{extra}}
[[axes]]
key = "perception.field_deg"
values = [60, 120, 180]
"""


def write_sweep(folder, extra=""):
    path = folder / "damaged.toml"
    path.write_text(SWEEP.format(extra=extra))
    return path


def run(path, out, **options):
    options.setdefault("executor", "serial")
    return run_sweep(load_sweep(path), path.read_text(), out, progress=False, batch_size=1, **options)


@pytest.fixture
def one_part_per_run(monkeypatch):
    """Every finished run is written at once as its own part (PartWriter.max_runs = 1)."""
    init = runner.PartWriter.__init__

    def patched(self, store, max_runs=64, max_seconds=None):
        init(self, store, 1, max_seconds)
    monkeypatch.setattr(runner.PartWriter, "__init__", patched)


def results(out):
    return pd.read_parquet(out / "runs.parquet").drop(columns=TIMING)


def series(out):
    return ResultsStore(out).timeseries().sort_values(["run_id", "t"]).reset_index(drop=True)


@pytest.fixture
def reference(tmp_path_factory):
    folder = tmp_path_factory.mktemp("reference")
    out = folder / "out"
    run(write_sweep(folder), out)
    return out


# -- damaged parts -------------------------------------------------------------------------------------

@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_damaged_parts_are_skipped_by_status_quarantined_by_run_and_recomputed(tmp_path, reference, capsys,
                                                                               one_part_per_run):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    run(sweep, out)
    parts = sorted((out / "runs").glob("part-*.parquet"))
    assert len(parts) == 6
    parts[0].write_bytes(parts[0].read_bytes()[:40])                         # truncated
    parts[1].write_bytes(b"not a parquet file at all")                        # garbage
    (out / "timeseries" / parts[2].name).write_bytes(b"PAR1 broken")          # its time series broken
    pd.DataFrame({"foreign": [1, 2], "run_id": ["x", "y"]}).to_parquet(out / "runs" / "part-000099.parquet")
    before = sorted(p.relative_to(out) for p in out.rglob("*"))

    assert main(["status", str(out)]) == 0
    captured = capsys.readouterr()
    assert "6 runs: 4 done, 0 failed, 2 missing" in captured.out
    for name in ("part-000001", "part-000002", "part-000099"):
        assert name in captured.err
    assert "records no checksum of it" in captured.err   # part 99, which flocksweep never wrote
    assert "Traceback" not in captured.err
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before   # status moves nothing
    runs = pd.read_parquet(out / "runs.parquet")
    series_now = ResultsStore(out).timeseries()                 # as the report reads them: part 3 skipped
    assert set(series_now["run_id"]) == set(runs.loc[runs["part"] != 3, "run_id"])
    assert "timeseries/part-000003.parquet changed since it was written" in capsys.readouterr().err

    assert main(["run", str(sweep), "--out", str(out), "--executor", "serial", "--no-progress"]) == 0
    captured = capsys.readouterr()
    assert "computed 3 now, 3 already done" in captured.out
    moved = sorted(p.name.split(".parquet")[0] for p in (out / "quarantine").rglob("part-*"))
    assert moved == ["part-000001", "part-000001", "part-000002", "part-000002", "part-000003", "part-000003",
                     "part-000099"]
    assert "moved to quarantine/" in captured.err and "runs/part-000002.parquet cannot be read" in captured.err
    # the partner of a damaged part is named as such, in words that read as a sentence
    assert ("timeseries/part-000002.parquet goes with runs/part-000002.parquet, which was damaged; moved to "
            "quarantine/") in captured.err
    assert min(int(p.stem[5:]) for p in (out / "runs").glob("part-*.parquet")) >= 4
    assert_frame_equal(results(out), results(reference), check_exact=True)   # no foreign column either
    assert_frame_equal(series(out), series(reference), check_exact=True)
    assert status(out)["missing"] == 0


def _edit_part(out, kind, edit, name="part-000002.parquet"):
    path = out / kind / name
    edit(pd.read_parquet(path)).to_parquet(path, index=False)


def _rename(frame):
    return frame.rename(columns={"polarization_mean": "polarisation_mean"})


def _nan(frame):
    return frame.assign(cohesion_mean=float("nan"))


def _strings(frame):
    return frame.assign(cohesion_mean=frame["cohesion_mean"].astype(str))


def _series_shifted(frame):
    return frame.assign(**{c: frame[c] + 0.125 for c in frame.columns if c not in ("run_id", "t")})


# (what is done to a finished sweep, the file a reader must name, the file the next run quarantines)
DAMAGES = {
    "a renamed metric column": (lambda out: _edit_part(out, "runs", _rename), "runs/part-000002", "runs/part-000002"),
    "metric values overwritten with NaN": (lambda out: _edit_part(out, "runs", _nan), "runs/part-000002",
                                           "runs/part-000002"),
    "strings in a metric column": (lambda out: _edit_part(out, "runs", _strings), "runs/part-000002",
                                   "runs/part-000002"),
    "a part with zero rows": (lambda out: _edit_part(out, "runs", lambda f: f.iloc[:0]), "runs/part-000002",
                              "runs/part-000002"),
    "a time series part with other values": (lambda out: _edit_part(out, "timeseries", _series_shifted),
                                             "timeseries/part-000002", "timeseries/part-000002"),
    "runs.parquet overwritten with NaN": (lambda out: _nan(pd.read_parquet(out / "runs.parquet")).to_parquet(
        out / "runs.parquet", index=False), "runs.parquet", None),
}


@pytest.mark.slow
@pytest.mark.parametrize("damage", list(DAMAGES))
def test_a_changed_stored_file_is_detected_named_set_aside_and_recomputed(damage, tmp_path, reference, capsys,
                                                                         one_part_per_run):
    """Every stored file kind (runs part, time series part, runs table, manifest): status, load_results
    and report name the changed file and never merge it; run quarantines it and recomputes what it held,
    giving the uninterrupted result bit for bit."""
    from flocksweep.sweeps.results import load_results

    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    run(sweep, out)
    reference_runs = pd.read_parquet(reference / "runs.parquet")
    apply, named, moved = DAMAGES[damage]
    apply(out)
    assert main(["status", str(out)]) == 0
    loaded = load_results(out, timeseries=True)
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err
    assert "polarisation_mean" not in loaded.runs and not loaded.runs["cohesion_mean"].isna().any()
    assert loaded.runs["cohesion_mean"].dtype.kind == "f"
    shown = set(loaded.series()["run_id"])
    assert shown <= set(reference_runs["run_id"])
    if "time series" in damage:   # the changed series are left out, never shown
        changed = pd.read_parquet(out / "runs" / "part-000002.parquet")["run_id"]
        assert not shown & set(changed)
    assert main(["run", str(sweep), "--out", str(out), "--executor", "serial", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if moved:
        assert f"{moved}" in err and "moved to quarantine/" in err
        assert list((out / "quarantine").rglob(Path(moved).name + "*"))
    assert_frame_equal(results(out), results(reference), check_exact=True)
    assert_frame_equal(series(out), series(reference), check_exact=True)
    assert status(out)["missing"] == 0
    assert main(["status", str(out)]) == 0 and capsys.readouterr().err == ""   # nothing damaged is left


def test_checksums_are_recorded_as_parts_are_written_and_a_changed_part_is_skipped(tmp_path, caplog):
    store = ResultsStore(tmp_path)
    rows = [{"run_id": "a", "status": "ok", "error": "", "cohesion_mean": 0.5}]
    store.write_part(1, rows, pd.DataFrame({"run_id": ["a"], "t": [0.0], "cohesion": [0.5]}))
    store.write_part(2, [{**rows[0], "run_id": "b"}], pd.DataFrame({"run_id": ["b"], "t": [0.0], "cohesion": [0.5]}))
    manifest = ResultsStore(tmp_path).manifest()
    assert set(manifest["checksums"]) == {"runs/part-000001.parquet", "runs/part-000002.parquet",
                                          "timeseries/part-000001.parquet", "timeseries/part-000002.parquet"}
    assert list(ResultsStore(tmp_path).latest()["run_id"]) == ["a", "b"]
    path = tmp_path / "runs" / "part-000002.parquet"
    pd.read_parquet(path).assign(cohesion_mean=0.75).to_parquet(path, index=False)   # a valid, wrong value
    assert list(ResultsStore(tmp_path).latest()["run_id"]) == ["a"]
    assert "runs/part-000002.parquet changed since it was written" in caplog.text
    store = ResultsStore(tmp_path)
    assert store.repair()     # moved aside, and its checksum forgotten
    assert not path.exists() and "runs/part-000002.parquet" not in store.checksums()


def test_part_numbers_are_never_reused_after_quarantine(tmp_path, one_part_per_run):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    run(sweep, out)
    last = sorted((out / "runs").glob("part-*.parquet"))[-1]
    last.write_bytes(b"garbage")
    run(sweep, out)
    assert ResultsStore(out).next_part() == 8          # 6 written, 6 moved aside, 7 its recomputation


def test_a_garbage_design_is_a_clear_error_for_readers_and_run_rewrites_it(tmp_path, reference, capsys):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    run(sweep, out)
    (out / "design.parquet").write_bytes(b"\x00" * 100)
    for command in (["status", str(out)], ["report", str(out)]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert "design.parquet cannot be read" in err and "flocksweep run" in err and "Traceback" not in err
    run(sweep, out)
    assert status(out)["ok"] == 6
    assert_frame_equal(results(out), results(reference), check_exact=True)


def test_a_garbage_runs_table_is_rebuilt_from_the_parts(tmp_path, reference, capsys):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    run(sweep, out)
    (out / "runs.parquet").write_bytes(b"junk")
    runs = ResultsStore(out).runs()
    assert len(runs) == 6
    run(sweep, out)
    assert_frame_equal(results(out), results(reference), check_exact=True)


def test_stale_temporary_files_of_a_killed_writer_are_removed(tmp_path):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    run(sweep, out)
    debris = [out / "runs" / ".part-000009.ab12cd34.tmp.parquet", out / ".manifest.zz99yy88.tmp.json"]
    for path in debris:
        path.write_bytes(b"half")
    keep = out / "runs" / "notes.txt"
    keep.write_text("mine")
    run(sweep, out)
    assert not any(p.exists() for p in debris) and keep.read_text() == "mine"


# -- full and read-only disks ------------------------------------------------------------------------

def failing_on(name_part: str, code: int = errno.ENOSPC):
    """The store's atomic_path, failing (as a full disk would) for paths containing ``name_part``."""
    real = files.atomic_path

    @contextlib.contextmanager
    def patched(path):
        with real(path) as tmp:
            if name_part in str(path):
                raise OSError(code, os.strerror(code))
            yield tmp
    return patched


def test_a_full_disk_stops_the_sweep_with_one_message_and_the_same_command_resumes(tmp_path, reference, capsys,
                                                                                   monkeypatch, one_part_per_run):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    computed = []
    real_batch = worker.execute_batch
    monkeypatch.setattr(worker, "execute_batch", lambda specs, out_dir=None: computed.append(1) or
                        real_batch(specs, out_dir))
    monkeypatch.setattr(store_module, "atomic_path", failing_on("runs/part-000003"))
    argv = ["run", str(sweep), "--out", str(out), "--executor", "serial", "--no-progress", "--batch-size", "1"]
    assert main(argv) == 4
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "cannot write" in err and "runs/part-000003.parquet" in err and "ENOSPC, errno 28" in err
    assert len(computed) == 3                               # stopped at the first failed write
    assert sorted(p.name for p in (out / "runs").glob("part-*")) == ["part-000001.parquet", "part-000002.parquet"]
    assert not list(out.rglob("*.tmp*"))
    monkeypatch.setattr(store_module, "atomic_path", files.atomic_path)   # space freed
    assert main(argv) == 0
    assert "computed 4 now, 2 already done" in capsys.readouterr().out
    assert_frame_equal(results(out), results(reference), check_exact=True)
    assert_frame_equal(series(out), series(reference), check_exact=True)


def test_a_read_only_folder_is_exit_4_naming_the_file(tmp_path, capsys, monkeypatch):
    sweep = write_sweep(tmp_path)
    real = files.tempfile.mkstemp

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))
    monkeypatch.setattr(files.tempfile, "mkstemp", read_only)
    assert main(["run", str(sweep), "--out", str(tmp_path / "out"), "--executor", "serial", "--no-progress"]) == 4
    err = capsys.readouterr().err
    assert "sweep.toml: Read-only file system (EROFS, errno 30)" in err and "Traceback" not in err
    monkeypatch.setattr(files.tempfile, "mkstemp", real)


def test_a_full_disk_while_saving_trajectories_is_not_a_run_failure(tmp_path, monkeypatch):
    sweep = write_sweep(tmp_path, extra='keep = "trajectories"')
    out = tmp_path / "out"

    def full(handle, **arrays):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(trajectory.np, "savez_compressed", full)
    with pytest.raises(WriteFailed) as info:
        run(sweep, out)
    assert info.value.errno == errno.ENOSPC and "/trajectories/" in info.value.filename
    assert ResultsStore(out).all_rows().empty or (ResultsStore(out).all_rows()["status"] == "ok").all()


# -- permissions and status ------------------------------------------------------------------------

@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_results_files_follow_the_umask(mask, mode, tmp_path):
    before = os.umask(mask)
    try:
        out = tmp_path / "out"
        run(write_sweep(tmp_path), out)
    finally:
        os.umask(before)
    written = [out / "runs.parquet", out / "manifest.json", out / "design.parquet",
               next((out / "runs").glob("part-*.parquet")), next((out / "timeseries").glob("part-*.parquet"))]
    assert {stat.S_IMODE(p.stat().st_mode) for p in written} == {mode}


def test_status_during_an_active_run_says_a_runner_is_working(tmp_path, capsys):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "out"
    run(sweep, out)
    manifest = ResultsStore(out).manifest()
    ResultsStore(out).write_manifest({**manifest, "finished": None})
    with ResultsStore(out).lock():
        assert main(["status", str(out)]) == 0
        printed = capsys.readouterr().out
        assert f"a runner is working here now (pid {os.getpid()}" in printed and "did not finish" not in printed
    assert main(["status", str(out)]) == 0
    assert "did not finish (resume with flocksweep run)" in capsys.readouterr().out
