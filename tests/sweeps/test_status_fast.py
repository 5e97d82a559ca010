"""``flocksweep status`` of an unchanged folder reuses its last full check (sweeps/status.py), and is never
fooled by it: a part rewritten, rewritten with its old times put back, removed or added, an edited
manifest, or a damaged folder (never remembered) means a full check that reports the damage. The
stores here are written with ResultsStore directly (no simulation)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pandas as pd
import pytest

from paths import ROOT
from flocksweep.sweeps.status import cache_path, status
from flocksweep.sweeps.store import ResultsStore

RUNS = ["a1b2c3d4e5f6", "b2c3d4e5f6a1", "c3d4e5f6a1b2", "d4e5f6a1b2c3"]


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("FLOCKSWEEP_CACHE_DIR", str(tmp_path / "cache"))


def finished_store(root):
    """A finished 4-run sweep in two parts: three runs ok, one failed."""
    store = ResultsStore(root)
    design = pd.DataFrame({"run_id": RUNS, "index": range(4), "point_index": [0, 0, 1, 1],
                           "replicate": [0, 1, 0, 1], "seed": [11, 12, 13, 14], "perception.field_deg": [60, 60, 180, 180]})
    store.write_inputs("# test\n", {}, {}, design)
    rows = lambda ids, states: [{"run_id": r, "status": s, "error": "boom" if s == "failed" else None,
                                 "polarization_mean": 0.5} for r, s in zip(ids, states)]
    store.write_part(1, rows(RUNS[:2], ["ok", "ok"]), None)
    store.write_part(2, rows(RUNS[2:], ["ok", "failed"]), None)
    store.write_manifest({"sweep": "tiny", "started": "2026-12-03T07:00:00", "finished": "2026-12-03T07:01:00"})
    return root


def counts(info):
    return info["runs"], info["ok"], info["failed"], info["missing"], info["failures"]


def test_an_unchanged_folder_is_counted_from_its_last_full_check(tmp_path):
    root = finished_store(tmp_path / "tiny")
    first = status(root, remember=True)
    assert first["checked"] == "full" and cache_path(root).exists()
    second = status(root, remember=True)
    assert second["checked"].startswith("unchanged since the full check")
    assert counts(second) == counts(first) == (4, 3, 1, 0, [(RUNS[3], "boom")])
    assert second["manifest"]["sweep"] == "tiny"
    assert status(root)["checked"] == "full"          # the default (and --verify) checks in full


def damage_in_place(path):
    """Overwrite one byte in the middle of the file and put its size and modification time back."""
    before = path.stat()
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns))
    assert path.stat().st_size == before.st_size and path.stat().st_mtime_ns == before.st_mtime_ns


@pytest.mark.parametrize("change", ["rewrite", "remove", "manifest"])
def test_a_changed_folder_is_checked_in_full_and_its_damage_reported(tmp_path, change, caplog):
    root = finished_store(tmp_path / "tiny")
    status(root, remember=True)
    part = root / "runs" / "part-000002.parquet"
    if change == "rewrite":
        damage_in_place(part)   # same size and mtime: the change time still differs
    elif change == "remove":
        part.unlink()
    else:
        manifest = json.loads((root / "manifest.json").read_text())
        manifest["finished"] = "edited"
        (root / "manifest.json").write_text(json.dumps(manifest))
    info = status(root, remember=True)
    assert info["checked"] == "full"
    if change == "manifest":   # its checksum no longer matches: ignored with a warning
        assert info["manifest"] == {} and "manifest.json" in caplog.text
    else:
        assert counts(info) == (4, 2, 0, 2, [])
    if change == "rewrite":
        assert "part-000002.parquet" in caplog.text
    caplog.clear()
    again = status(root, remember=True)   # a damaged folder is never remembered: reported every time
    assert counts(again) == counts(info)
    if change == "remove":   # nothing damaged, two runs missing: remembered as such
        assert again["checked"].startswith("unchanged since")
    else:
        assert again["checked"] == "full" and caplog.text


def test_a_new_part_is_counted(tmp_path):
    root = finished_store(tmp_path / "tiny")
    status(root, remember=True)
    store = ResultsStore(root)
    store.write_part(3, [{"run_id": RUNS[3], "status": "ok", "error": None, "polarization_mean": 0.4}], None)
    info = status(root, remember=True)
    assert info["checked"] == "full" and counts(info) == (4, 4, 0, 0, [])


def test_the_fast_path_imports_neither_pandas_nor_pyarrow(tmp_path):
    root = finished_store(tmp_path / "tiny")
    status(root, remember=True)
    code = ("import json, sys\nfrom flocksweep.cli import main\nmain(['status', %r])\n"
            "print(json.dumps(sorted(sys.modules)))\n" % str(root))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    lines = done.stdout.strip().splitlines()
    assert lines[0].startswith("tiny: 4 runs: 3 done, 1 failed, 0 missing"), done.stdout + done.stderr
    assert "unchanged since the full check" in done.stdout
    modules = json.loads(lines[-1])
    assert not [m for m in modules if m.split(".")[0] in ("pandas", "pyarrow", "numpy", "numba")]


def test_new_checking_code_means_a_full_check(tmp_path, monkeypatch):
    import flocksweep.sweeps.status as status_module
    code = tmp_path / "store.py"
    code.write_text("# the checks\n")
    monkeypatch.setattr(status_module, "CODE", (code,))
    root = finished_store(tmp_path / "tiny")
    status(root, remember=True)
    assert status(root, remember=True)["checked"].startswith("unchanged since")
    code.write_text("# the checks, edited\n")
    assert status(root, remember=True)["checked"] == "full"
