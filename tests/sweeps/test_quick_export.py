"""``flocksweep export`` without pandas (sweeps/quick_export.py) writes runs.csv and runs.parquet byte for
byte as the pandas path (sweeps.export.export_with_pandas, its slow twin) does, with and without
--with-fixed, for a finished sweep with failed rows, NaN and infinite values, booleans, integers with a
gap (floats in pandas), text that needs quoting, a fixed setting that is also a stored column, and (CSV)
a runs table out of design order; Arrow column types pandas never stores (booleans and integers with
gaps, all-null) are checked cell by cell. It steps aside (the pandas path verifies and warns as before)
whenever a file is not as flocksweep wrote it. The stores are written with ResultsStore directly (no
simulation)."""
from __future__ import annotations

import csv
import io
import json
import math
import subprocess
import sys

import pandas as pd
import pyarrow as pa
import pytest

from paths import ROOT
from flocksweep.simcore import load_preset
from flocksweep.sweeps.export import export_results, export_with_pandas
from flocksweep.sweeps.files import write_parquet
from flocksweep.sweeps.quick_export import _cells, _constant, _large_text, _pandas_metadata, runs_csv, runs_parquet, stored_runs
from flocksweep.sweeps.store import ResultsStore

RUNS = ["a1b2c3d4e5f6", "b2c3d4e5f6a1", "c3d4e5f6a1b2", "d4e5f6a1b2c3", "e5f6a1b2c3d4"]
HOLLAND = ROOT / "configs/models/holland.toml"


def finished_store(root):
    """A finished 5-run sweep in two parts, consolidated: ok and failed rows, NaN, inf, -0.0, booleans and
    integers with gaps, text with commas, quotes and line breaks."""
    store = ResultsStore(root)
    design = pd.DataFrame({"run_id": RUNS, "index": range(5), "point_index": [0, 0, 1, 1, 2],
                           "replicate": [0, 1, 0, 1, 0], "seed": [11, 2**62, 13, 14, 15],
                           "mode": ["normal", "pattern, wide", 'say "hi"', "", "two\nlines"],
                           "patterns.enabled": [False, True, False, True, False],
                           "perception.field_deg": [60.0, 60.0, 180.0, 180.0, 1e-5]})
    # field_deg is not among the swept keys here: a fixed setting that is also a stored column
    model = {"preset": load_preset(HOLLAND).to_dict(), "swept_keys": ["patterns.enabled"],
             "analysis": {"warmup": 1.0, "group_radius": None, "keep": "metrics", "leadership": False,
                          "trajectory_every": 6}}
    store.write_inputs("# test\n", {}, model, design)

    def rows(k):
        ok = k != 3
        return {**design.iloc[k].to_dict(), "status": "ok" if ok else "failed",
                "error": None if ok else 'ValueError: bad "n", see\nthe log', "n": 12 if ok else None,
                "steps": [240, 240, 240, None, 240][k], "sim_s": 0.25 * k,
                "polarization_mean": [0.1, float("nan"), 1e16, None, -0.0][k],
                "polarization_final": [1 / 3, math.inf, -math.inf, None, 123456789.0][k],
                "fragmented": [1.0, 0.0, 0.0, None, 1.0][k]}
    store.write_part(1, [rows(k) for k in (0, 1, 2)], None)
    store.write_part(2, [rows(k) for k in (3, 4)], None)
    store.consolidate(design)
    store.write_manifest({"sweep": "tiny", "started": "2026-12-03T07:00:00", "finished": "2026-12-03T07:01:00"})
    return store


def both_paths(root, tmp_path, with_fixed, fmt="csv"):
    quick = (runs_csv if fmt == "csv" else runs_parquet)(root, tmp_path / "quick" / f"runs.{fmt}", with_fixed)
    slow = export_with_pandas(root, fmt, tmp_path / "slow", with_fixed, timeseries=False)["runs"]
    return quick, slow


@pytest.mark.parametrize("with_fixed", [False, True])
@pytest.mark.parametrize("shuffled", [False, True])
def test_the_quick_csv_is_byte_for_byte_the_pandas_csv(tmp_path, with_fixed, shuffled):
    store = finished_store(tmp_path / "tiny")
    if shuffled:   # a runs table out of design order, recorded as written: both paths sort it by index
        table = pd.read_parquet(store.root / "runs.parquet").iloc[[4, 1, 3, 0, 2]]
        write_parquet(store.root / "runs.parquet", table)
        store._record(store.root / "runs.parquet")
        store._save_checksums()
    quick, slow = both_paths(store.root, tmp_path, with_fixed)
    assert quick is not None, "the quick path stepped aside on an intact folder"
    assert quick[1:] == slow[1:] and quick[1] == 5
    text = quick[0].read_bytes()
    assert text == slow[0].read_bytes()
    # the cases the folder was built to hold are really in the file
    assert b'"pattern, wide"' in text and b'"say ""hi"""' in text and b'"two\nlines"' in text
    assert b",inf," in text and b",-inf," in text and b"1e+16" in text and b"-0.0" in text and b",1e-05," in text
    assert b"True" in text and b"4611686018427387904" in text and b",12.0," in text   # n with a gap: floats
    assert (b"perception.range" in text) == with_fixed and (b"analysis.group_radius" in text) == with_fixed
    assert text.split(b"\n")[0].split(b",").count(b"perception.field_deg") == 1   # the stored column, once


@pytest.mark.parametrize("with_fixed", [False, True])
def test_the_quick_parquet_is_byte_for_byte_the_pandas_parquet(tmp_path, with_fixed):
    store = finished_store(tmp_path / "tiny")
    quick, slow = both_paths(store.root, tmp_path, with_fixed, "parquet")
    assert quick is not None, "the quick path stepped aside on an intact folder"
    assert quick[1:] == slow[1:] and quick[1] == 5
    assert quick[0].read_bytes() == slow[0].read_bytes()
    stored = stored_runs(store.root)   # a table another pandas or pyarrow wrote: the pandas path
    assert _pandas_metadata(stored, pa.__version__, pd.__version__) is not None
    assert _pandas_metadata(stored, pa.__version__, "2.0.0") is None
    assert _pandas_metadata(stored, "1.0", pd.__version__) is None
    back = pd.read_parquet(quick[0])
    assert "part" not in back and back["polarization_final"].iloc[1] == math.inf
    assert ("analysis.group_radius" in back) == with_fixed


def test_the_quick_parquet_steps_aside_for_a_table_it_cannot_vouch_for(tmp_path):
    store = finished_store(tmp_path / "tiny")
    table = pd.read_parquet(store.root / "runs.parquet")
    for changed in (table.iloc[[4, 1, 3, 0, 2]],                                 # out of design order
                    table.assign(flag=pd.array([True, None, False, True, True], dtype=object))):  # bools with a gap
        write_parquet(store.root / "runs.parquet", changed)
        store._record(store.root / "runs.parquet")
        store._save_checksums()
        assert runs_parquet(store.root, tmp_path / "quick" / "runs.parquet") is None
        slow = export_with_pandas(store.root, "parquet", tmp_path / "slow", False, False)["runs"]
        quick = export_results(store.root, "parquet", tmp_path / "out")["runs"]
        assert quick[0].read_bytes() == slow[0].read_bytes()


def test_each_arrow_column_gets_the_cells_pandas_writes_for_it():
    """Column types pandas itself never writes to a part (integers and booleans with gaps, all-null) as
    pyarrow.parquet reads them: the text of each cell is what to_pandas().to_csv() writes."""
    table = pa.table({"count": pa.array([3, None, -7, 2**60], pa.int64()),
                      "small": pa.array([1, 2, 3, 4], pa.int32()),
                      "flag": pa.array([True, None, False, True]),
                      "nothing": pa.array([None] * 4, pa.null()),
                      "x": pa.array([0.5, None, float("nan"), 1e-7]),
                      "label": pa.array(["a", None, "", "b,c"], pa.large_string())})
    expected = table.to_pandas().to_csv(index=False, header=False).splitlines()
    handle = io.StringIO()
    csv.writer(handle, lineterminator="\n").writerows(zip(*(_cells(table.column(c)) for c in table.column_names)))
    assert handle.getvalue().splitlines() == expected
    assert _cells(table.column("count"))[:2] == ["3.0", ""] and _cells(table.column("flag"))[1] == ""
    assert _cells(pa.chunked_array([pa.array([1.5], pa.float32())])) is None   # a type it does not know


def test_arrays_built_from_buffers_equal_those_pyarrow_builds():
    """The quick Parquet path builds its columns from buffers (pa.array would import pandas); they equal
    what pa.array and a cast give, sliced chunks and empty text included."""
    text = pa.chunked_array([pa.array(["ab", None, "", "cdé", "x"])[1:], pa.array([None, "q"])])
    wide = _large_text(pa, text)
    wide.validate(full=True)
    assert wide.equals(text.cast(pa.large_string()))
    for value, kind in [(1.5, "float64"), (-7, "int64"), (True, "bool_"), (False, "bool_"), ("a,b", "large_string"),
                        ("", "large_string"), (None, "null")]:
        built = _constant(pa, value, kind, 11)
        built.validate(full=True)
        assert built.equals(pa.array([value] * 11, getattr(pa, kind)())), (value, kind)


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_export_of_an_intact_folder_imports_no_pandas(tmp_path, fmt):
    store = finished_store(tmp_path / "tiny")
    code = ("import sys; from flocksweep.cli import main; "
            f"assert main(['export', {str(store.root)!r}, '--{fmt}', '--with-fixed']) == 0; "
            "print(sorted(m for m in ('pandas', 'pyarrow.dataset', 'pyarrow.compute', 'numba') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert done.stdout.strip().endswith("[]"), done.stdout + done.stderr
    assert (store.root / "export" / f"runs.{fmt}").exists()


def change_a_byte(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def edit_manifest(store):
    text = (store.root / "manifest.json").read_text().replace('"tiny"', '"edited"')
    (store.root / "manifest.json").write_text(text)


def forget_checksums(store):   # a folder from before checksums
    data = json.loads((store.root / "manifest.json").read_text())
    data.pop("checksums"), data.pop("manifest_checksum")
    (store.root / "manifest.json").write_text(json.dumps(data))


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("damage", [
    lambda s: change_a_byte(s.root / "runs.parquet"),
    lambda s: (s.root / "runs.parquet").unlink(),          # interrupted before consolidating
    lambda s: change_a_byte(s.root / "design.parquet"),
    edit_manifest,
    forget_checksums,
], ids=["runs-changed", "runs-missing", "design-changed", "manifest-edited", "no-checksums"])
def test_the_quick_path_steps_aside_for_anything_not_as_written(tmp_path, damage, fmt):
    store = finished_store(tmp_path / "tiny")
    damage(store)
    quick_path = runs_csv if fmt == "csv" else runs_parquet
    assert quick_path(store.root, tmp_path / "quick" / f"runs.{fmt}", with_fixed=True) is None
    assert not (tmp_path / "quick").exists()   # nothing written
    # export_results then takes the pandas path, with what it says and does about the damage
    try:
        quick = export_results(store.root, fmt, tmp_path / "out")
    except ValueError as err:   # design.parquet changed: Unreadable, as before
        assert "design.parquet" in str(err)
        return
    slow = export_with_pandas(store.root, fmt, tmp_path / "slow", False, False)
    assert quick["runs"][0].read_bytes() == slow["runs"][0].read_bytes()


def test_a_changed_runs_table_is_reported_and_the_parts_exported(tmp_path, caplog):
    store = finished_store(tmp_path / "tiny")
    change_a_byte(store.root / "runs.parquet")
    written = export_results(store.root, "csv", tmp_path / "out")
    assert "runs.parquet changed since it was written" in caplog.text
    assert written["runs"][1] == 5


def test_a_missing_folder_is_still_not_a_sweep(tmp_path):
    with pytest.raises(FileNotFoundError, match="not a sweep results directory"):
        export_results(tmp_path / "missing", "csv")
