"""What keeps a sweep of 100,000 runs quick to resume and to read (docs/sweeps.md, "Large sweeps"): a rerun
with nothing to compute reads the stored design instead of building it (sweeps.design_key) and each stored
part once, keeps runs.parquet when nothing it is built from changed, and finds the same runs, ids and
results as building the design would; anything that could change the design (the sweep, the code, the
manifest's record) builds it again. Plus the faster design pieces (ResolvedValues, simcore.schema.to_dict)
against their plain twins. Runs of 6 boids for 1.5 s, serial."""
from __future__ import annotations

import dataclasses
import json

import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from flocksweep.simcore.params import load_preset
from flocksweep.simcore.schema import get_dotted, to_dict
from flocksweep.sweeps import design_key as design_key_module, runner
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import ResolvedValues, StoredRun, expand
from flocksweep.sweeps.design_key import design_key
from flocksweep.sweeps.runner import run_sweep
from flocksweep.sweeps.store import ResultsStore
from paths import ROOT

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
TIMING = ["wall_s", "sim_s", "part"]


def write_sweep(folder, replicates=2, extra=""):
    path = folder / "tiny.toml"
    path.write_text(f'name = "tiny"\nseed = 5\nreplicates = {replicates}\n\n[model]\npreset = "{HOLLAND}"\n\n'
                    "[run]\nn = 6\nduration = 1.5\nrecord_interval = 0.5\nwarmup = 0.5\n\n"
                    '[[axes]]\nkey = "perception.field_deg"\nvalues = [90, 270]\n' + extra)
    return path


def run(path, out, overrides=(), **options):
    return run_sweep(load_sweep(path, overrides), path.read_text(), out, executor="serial", progress=False, **options)


def no_expand(monkeypatch):
    def refuse(config):
        raise AssertionError("the design was built")
    monkeypatch.setattr(runner, "expand", refuse)


@pytest.fixture
def finished(tmp_path):
    path = write_sweep(tmp_path)
    first = run(path, tmp_path / "out")
    assert len(first.plan.todo) == 4
    return path, tmp_path / "out", first


def test_a_rerun_with_nothing_to_compute_reads_the_stored_design_and_each_part_once(finished, monkeypatch):
    path, out, first = finished
    table_bytes = (out / "runs.parquet").read_bytes()
    no_expand(monkeypatch)
    reads = []
    original = ResultsStore._checked_runs_part
    monkeypatch.setattr(ResultsStore, "_checked_runs_part",
                        lambda self, part, *args: reads.append(part.name) or original(self, part, *args))
    again = run(path, out)
    assert not again.plan.todo and all(isinstance(r, StoredRun) for r in again.plan.specs)
    assert [r.run_id for r in again.plan.done] == [s.run_id for s in first.plan.specs]
    assert [(r.index, r.point_index, r.replicate, r.seed) for r in again.plan.done] == \
        [(s.index, s.point_index, s.replicate, s.seed) for s in first.plan.specs]
    assert sorted(reads) == sorted(set(reads)) and reads   # every part read, none twice
    assert (out / "runs.parquet").read_bytes() == table_bytes   # kept, not rebuilt
    assert_frame_equal(again.table, first.table)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["design_key"] == design_key(load_sweep(path))
    assert manifest["computed_this_invocation"] == 0 and manifest["counts"]["ok"] == 4


@pytest.mark.parametrize("change", ["replicates", "code", "manifest", "force"])
def test_anything_that_could_change_the_design_builds_it_again(finished, monkeypatch, change):
    path, out, first = finished
    built = []
    monkeypatch.setattr(runner, "expand", lambda config: built.append(1) or expand(config))
    overrides, options = (), {}
    if change == "replicates":
        overrides = ["replicates=3"]
    elif change == "code":
        design_key_module.code_digest.cache_clear()
        monkeypatch.setattr(design_key_module, "code_digest", lambda: "another checkout")
    elif change == "manifest":   # a manifest that records another key (a folder of an older flocksweep: none)
        store = ResultsStore(out)
        data = {k: v for k, v in store.manifest().items() if k != "design_key"}
        store.write_manifest(data)
    else:
        options = {"force": True}
    again = run(path, out, overrides, **options)
    assert built == [1]
    assert len(again.plan.todo) == {"replicates": 2, "force": 4}.get(change, 0)
    assert_frame_equal(again.table.drop(columns=TIMING).head(2), first.table.drop(columns=TIMING).head(2))


def test_a_damaged_part_is_recomputed_to_the_same_results_through_the_stored_design(finished):
    path, out, first = finished
    part = sorted((out / "runs").iterdir())[0]
    data = bytearray(part.read_bytes())
    data[len(data) // 2] ^= 0xFF
    part.write_bytes(bytes(data))
    again = run(path, out)
    assert len(again.plan.todo) == 4 and again.quarantined   # the one part held all four runs
    assert_frame_equal(again.table.drop(columns=TIMING), first.table.drop(columns=TIMING))


def test_a_missing_or_changed_runs_table_is_rebuilt_from_the_parts(finished, monkeypatch):
    path, out, first = finished
    no_expand(monkeypatch)
    for damage in ("remove", "change"):
        table = out / "runs.parquet"
        if damage == "remove":
            table.unlink()
        else:
            first.table.assign(polarization_mean=0.0).to_parquet(table, index=False)
        again = run(path, out)
        assert_frame_equal(again.table.drop(columns=TIMING), first.table.drop(columns=TIMING))
        assert_frame_equal(pd.read_parquet(table), again.table)


def test_retry_failed_with_no_failure_and_a_dry_run_use_the_stored_design(finished, monkeypatch):
    path, out, first = finished
    no_expand(monkeypatch)
    assert not run(path, out, retry_failed=True).plan.todo
    dry = run(path, out, dry_run=True)
    assert len(dry.plan.done) == 4 and not dry.plan.todo


def test_the_design_key_follows_the_sweep_and_is_none_where_files_outside_it_matter(tmp_path):
    path = write_sweep(tmp_path)
    key = design_key(load_sweep(path))
    assert key == design_key(load_sweep(path))
    assert key != design_key(load_sweep(path, ["replicates=3"]))
    assert key != design_key(load_sweep(path, ["run.duration=2.0"]))
    assert key != design_key(load_sweep(path, ["seed=6"]))
    swept = write_sweep(tmp_path, extra='\n[[axes]]\nkey = "dynamics"\nvalues = ["opensteer"]\n')
    assert design_key(load_sweep(swept)) is None


# -- the faster design pieces against their plain twins ------------------------------------------------------

def plain_to_dict(obj):
    """simcore.schema.to_dict as it was: dataclasses looked up on every call."""
    if dataclasses.is_dataclass(obj):
        return {f.name: plain_to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple):
        return [plain_to_dict(v) for v in obj]
    if isinstance(obj, dict):
        return {k: plain_to_dict(v) for k, v in obj.items()}
    if isinstance(obj, type(ROOT)):
        return str(obj)
    return obj


def leaves(data, prefix=""):
    for key, value in data.items():
        dotted = f"{prefix}{key}"
        yield dotted
        if isinstance(value, dict):
            yield from leaves(value, dotted + ".")


@pytest.mark.parametrize("name", ["holland", "boidspp_predator", "couzin2002_torus_2d", "vicsek", "hartman_benes",
                                  "reynolds87_obstacles", "topological", "holland_pattern"])
def test_resolved_values_and_to_dict_equal_their_plain_twins_on_every_key(name):
    preset = load_preset(ROOT / "configs" / "models" / f"{name}.toml")
    for part in (preset.model, preset.init, preset.run):
        assert to_dict(part) == plain_to_dict(part)
    full = preset.full_dict()
    values = ResolvedValues(preset)
    for key in [*leaves(full), "no_such_table", "perception.no_such_key", "init.n.deeper"]:
        assert values(key) == get_dotted(full, key), key


# -- status reads what it counts ------------------------------------------------------------------------------

def test_status_reads_only_ids_statuses_and_errors_and_still_checks_every_part(finished, monkeypatch):
    from flocksweep.sweeps.status import status

    path, out, first = finished
    reads = []
    original = pd.read_parquet
    monkeypatch.setattr(pd, "read_parquet", lambda file, *a, **k: reads.append((file, k.get("columns"))) or
                        original(file, *a, **k))
    info = status(out)
    assert (info["runs"], info["ok"], info["failed"], info["missing"]) == (4, 4, 0, 0)
    assert not any("timeseries" in str(file) for file, _ in reads)
    assert reads and all(columns is not None and "polarization_mean" not in columns for _, columns in reads)
    # a part written through the store (its checksum recorded) holding text in a metric column is damaged
    store = ResultsStore(out)
    store.write_part(store.next_part(), [{"run_id": first.plan.specs[0].run_id, "status": "ok", "error": "",
                                          "polarization_mean": "high"}], None)
    info = status(out)
    assert info["ok"] == 4   # the bad part skipped (with a warning), the counts those of the good ones
    with pytest.raises(Exception, match="non-numbers in its metric column 'polarization_mean'"):
        ResultsStore(out)._runs_part(sorted((out / "runs").iterdir())[-1], None, ("run_id", "status"))
