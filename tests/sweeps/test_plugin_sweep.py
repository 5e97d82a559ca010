"""A sweep of a plug-in dynamics (examples/couzin_like.py, docs/plugins.md) is as deterministic as a built-in
one: serial, a local pool of one worker and of two, and a Dask cluster of two (spawned processes, which import the plug-in module from
the path they inherit) store bit-identical rows and time series; the rows carry the swept plug-in keys."""
from __future__ import annotations

import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from paths import ROOT
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.runner import run_sweep
from flocksweep.sweeps.store import ResultsStore

SWEEP = ROOT / "examples" / "couzin_like_sweep.toml"
SMALL = ["run.n=12", "run.duration=4.0", "run.warmup=1.0", "replicates=1"]
TIMING = ["wall_s", "sim_s", "part"]   # the only columns allowed to differ between equal computations


def run(out, **options):
    return run_sweep(load_sweep(SWEEP, SMALL), SWEEP.read_text(), out, progress=False, **options)


def rows(out) -> pd.DataFrame:
    return pd.read_parquet(out / "runs.parquet").drop(columns=TIMING).sort_values("run_id").reset_index(drop=True)


def series(out) -> pd.DataFrame:
    return ResultsStore(out).timeseries().sort_values(["run_id", "t"]).reset_index(drop=True)


@pytest.mark.slow
def test_a_plugin_sweep_is_bit_identical_across_executors_and_worker_counts(tmp_path):
    run(tmp_path / "serial", executor="serial")
    reference = rows(tmp_path / "serial")
    assert len(reference) == 6 and (reference["status"] == "ok").all()
    assert sorted(reference["plugin.zor"].unique()) == [1.0, 2.0, 3.0]
    assert sorted(reference["plugin.gain"].unique()) == [2.0, 6.0]
    assert reference["nn_distance_mean"].nunique() == 6      # the parameters act
    for workers in (1, 2):
        out = tmp_path / f"local{workers}"
        run(out, executor="local", workers=workers, batch_size=1)
        assert_frame_equal(rows(out), reference, check_exact=True)
        assert_frame_equal(series(out), series(tmp_path / "serial"), check_exact=True)
    pytest.importorskip("dask.distributed")
    run(tmp_path / "dask", executor="dask", workers=2)   # dask's workers find the module on the path too
    assert_frame_equal(rows(tmp_path / "dask"), reference, check_exact=True)
