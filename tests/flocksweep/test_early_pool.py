"""flocksweep/cli.py: a plain local run starts its pool first thing, so its workers import the simulator
while the sweep is read and designed; anything else starts no early pool."""
from __future__ import annotations

import multiprocessing
from contextlib import contextmanager, nullcontext

import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from flocksweep import cli
from flocksweep.commands import run as run_command
from paths import ROOT
from flocksweep.sweeps import executors, runner

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
TIMING = ["wall_s", "sim_s", "part"]


def args_of(*flags, sweep="s.toml"):
    argv = ["run", sweep, *flags]
    return cli.build_parser(cli._command_of(argv)).parse_args(argv)


def write_sweep(folder):
    path = folder / "tiny.toml"
    path.write_text(f"""name = "tiny"
seed = 5
[model]
preset = "{HOLLAND}"
[run]
n = 8
duration = 1.0
record_interval = 0.5
warmup = 0.25
[[axes]]
key = "perception.field_deg"
values = [60, 120, 180]
""")
    return path


@pytest.mark.parametrize("flags", [("--workers", "2"), ("--workers", "2", "--force"), ("--workers", "3", "--retry-failed")])
def test_a_plain_local_run_gets_an_early_pool(flags):
    pool = run_command._early_pool(args_of(*flags))
    assert isinstance(pool, executors.Executor)   # not started yet: entered by cmd_run
    assert (pool.kind, pool.workers, pool.preload) == ("local", int(flags[1]), ("flocksweep.sweeps.worker:prepare",))


@pytest.mark.parametrize("flags", [("--executor", "serial"), ("--executor", "dask"), ("--workers", "1"),
                                   ("--workers", "2", "--dry-run"), ("--workers", "2", "--until-claims"),
                                   ("--workers", "2", "--until-ci", "polarization_mean=0.1"),
                                   ("--workers", "0"), ("--workers", "100000")])
def test_other_runs_and_refused_flags_get_none(flags):
    assert isinstance(run_command._early_pool(args_of(*flags)), nullcontext)


def test_a_refused_worker_count_is_still_named(tmp_path, capsys):
    assert cli.main(["run", str(write_sweep(tmp_path)), "--workers", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--workers" in capsys.readouterr().err


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_the_run_computes_on_the_early_pool_with_the_serial_results(tmp_path, monkeypatch, capsys):
    sweep = write_sweep(tmp_path)
    assert cli.main(["run", str(sweep), "--executor", "serial", "--out", str(tmp_path / "serial"),
                     "--no-progress"]) == 0

    def no_second_pool(*args, **kwargs):
        raise AssertionError("the sweep started a pool of its own")

    monkeypatch.setattr(runner, "Executor", no_second_pool)
    assert cli.main(["run", str(sweep), "--workers", "2", "--batch-size", "1", "--out", str(tmp_path / "pool"),
                     "--no-progress"]) == 0
    assert "3 runs, 3 ok, 0 failed" in capsys.readouterr().out
    serial, pool = (pd.read_parquet(tmp_path / d / "runs.parquet").drop(columns=TIMING) for d in ("serial", "pool"))
    assert_frame_equal(serial, pool, check_exact=True)
    assert not multiprocessing.active_children()


def test_a_pool_with_nothing_to_do_is_stopped_without_waiting(tmp_path, monkeypatch):
    sweep, out = write_sweep(tmp_path), tmp_path / "out"
    assert cli.main(["run", str(sweep), "--executor", "serial", "--out", str(out), "--no-progress"]) == 0
    (out / "runs.parquet").unlink()   # as if interrupted before its table: the pool starts early
    closed = []
    close = executors.Executor.close

    def recorded(self, wait=True):
        closed.append((self._pool is not None, wait))
        close(self, wait)

    monkeypatch.setattr(executors.Executor, "close", recorded)
    assert cli.main(["run", str(sweep), "--workers", "2", "--out", str(out), "--no-progress"]) == 0
    assert closed[0] == (True, False)   # every run was done: its workers were stopped, not waited for
    assert not multiprocessing.active_children()


def test_a_bad_sweep_stops_the_early_pool(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(write_sweep(tmp_path).read_text().replace("n = 8", "n = -8"))
    assert cli.main(["run", str(bad), "--workers", "2", "--out", str(tmp_path / "o")]) == 2
    assert "init.n: got -8" in capsys.readouterr().err
    assert not multiprocessing.active_children() and not (tmp_path / "o").exists()


def test_a_finished_sweep_run_again_gets_no_early_pool(tmp_path, monkeypatch):
    """Its results table is there: most likely nothing to compute, so no workers import for nothing; with
    --force or --retry-failed (work to do) the pool starts early again."""
    sweep, out = write_sweep(tmp_path), tmp_path / "out"
    assert isinstance(run_command._early_pool(args_of("--workers", "2", "--out", str(out))), executors.Executor)
    assert cli.main(["run", str(sweep), "--executor", "serial", "--out", str(out), "--no-progress"]) == 0
    assert isinstance(run_command._early_pool(args_of("--workers", "2", "--out", str(out))), nullcontext)
    for flag in ("--force", "--retry-failed"):
        assert isinstance(run_command._early_pool(args_of("--workers", "2", "--out", str(out), flag)), executors.Executor)
    monkeypatch.chdir(tmp_path)   # without --out: the sweep file's name under results/
    (tmp_path / "results").mkdir()
    out.rename(tmp_path / "results" / "tiny")
    argv = ["run", str(sweep), "--workers", "2"]
    assert isinstance(run_command._early_pool(cli.build_parser(cli._command_of(argv)).parse_args(argv)), nullcontext)
    renamed = argv + ["--set", "name=other"]   # another folder: told only once the sweep is read
    assert isinstance(run_command._early_pool(cli.build_parser(cli._command_of(renamed)).parse_args(renamed)),
                      executors.Executor)


def test_an_interrupted_sweep_stops_the_early_pool_before_it_lets_go_of_the_store(tmp_path, monkeypatch):
    """As with the sweep's own pool: no worker is left to write into the folder once its lock is released."""
    from flocksweep.sweeps import store as stores

    sweep, out = write_sweep(tmp_path), tmp_path / "out"
    alive_at_release = []
    lock = stores.ResultsStore.lock

    @contextmanager
    def watched(self):
        try:
            with lock(self) as store:
                yield store
        finally:
            alive_at_release.append(len(multiprocessing.active_children()))

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(stores.ResultsStore, "lock", watched)
    monkeypatch.setattr(runner, "_run_batches", interrupted)
    assert cli.main(["run", str(sweep), "--workers", "2", "--out", str(out), "--no-progress"]) != 0
    assert alive_at_release == [0]
