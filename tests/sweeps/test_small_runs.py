"""Small runs in bulk (sweeps.worker's groups, sweeps.runner's batches and parts): which runs are simulated
together, how a sweep is cut into batches, and that none of it changes a result: the same rows, series and
trajectories whatever the batching (alone, grouped, serial or a local pool), a failure inside a group the
failing run's own. Runs of 6-8 boids for 1.5 s."""
from __future__ import annotations

import dataclasses
import json
import sys

import numpy as np
import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from faults import FAULTY_PRESET, FAULTY_SWEEP
from flocksweep.simcore.simulate import THREADED_MIN_N
from flocksweep.sweeps import runner, worker
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.runner import PartWriter, make_batches, run_sweep
from flocksweep.sweeps.store import ResultsStore
from paths import ROOT, TESTS

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
TIMING = ["wall_s", "sim_s", "part"]   # the only columns that may differ between equal computations


def write_sweep(folder, *, name="small", n=8, replicates=4, run_extra="", axes=None):
    """Two design points (field 60 and 180) x ``replicates`` of holland, ``n`` boids for 1.5 s."""
    axes = axes or '[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 180]\n'
    path = folder / f"{name}.toml"
    path.write_text(f'name = "{name}"\nseed = 11\nreplicates = {replicates}\n\n[model]\npreset = "{HOLLAND}"\n\n'
                    f"[run]\nn = {n}\nduration = 1.5\nrecord_interval = 0.5\nwarmup = 0.5\n{run_extra}\n{axes}")
    return path


def run(path, out, **options):
    options.setdefault("executor", "serial")
    return run_sweep(load_sweep(path), path.read_text(), out, progress=False, **options)


def results(out):
    return pd.read_parquet(out / "runs.parquet").drop(columns=TIMING)


def series(out):
    return ResultsStore(out).timeseries().sort_values(["run_id", "t"]).reset_index(drop=True)


def shapes(groups):
    return [[(s.point_index, s.replicate) for s in group] for group in groups]


# -- which runs are simulated together -------------------------------------------------------------------

def test_a_points_consecutive_replicates_group_and_different_points_do_not(tmp_path):
    specs = expand(load_sweep(write_sweep(tmp_path, replicates=3)))
    assert shapes(worker.replicate_groups(specs)) == [[(0, 0), (0, 1), (0, 2)], [(1, 0), (1, 1), (1, 2)]]
    # only neighbours group: a batch that interleaves points keeps each run apart
    mixed = [specs[0], specs[3], specs[1], specs[4]]
    assert shapes(worker.replicate_groups(mixed)) == [[(0, 0)], [(1, 0)], [(0, 1)], [(1, 1)]]
    # a batch's cut: the replicates it holds group, whatever precedes them elsewhere
    assert shapes(worker.replicate_groups(specs[2:5])) == [[(0, 2)], [(1, 0), (1, 1)]]


def test_runs_of_large_flocks_command_models_and_contained_runs_are_never_grouped(tmp_path):
    large = expand(load_sweep(write_sweep(tmp_path, name="large", n=THREADED_MIN_N, replicates=2)))
    below = expand(load_sweep(write_sweep(tmp_path, name="below", n=THREADED_MIN_N - 1, replicates=2)))
    limited = expand(load_sweep(write_sweep(tmp_path, name="limited", run_extra="timeout_s = 30", replicates=2)))
    (tmp_path / "faulty.toml").write_text(FAULTY_PRESET.format(module="faulty_plugin"))
    (tmp_path / "plugin.toml").write_text("replicates = 2\n" + FAULTY_SWEEP.format(values="[0]", run="",
                                                                                   key="plugin.fault"))
    plugin = expand(load_sweep(tmp_path / "plugin.toml"))
    command = json.dumps([sys.executable, str(TESTS / "sweeps" / "faulty_sim.py"), "--seed", "{seed}",
                          "--out", "{out}", "{params}"])
    (tmp_path / "command.toml").write_text(
        f'name = "command"\nseed = 5\nreplicates = 2\n[model]\ncommand = {command}\n[model.parameters]\n'
        'noise = { default = 0.3, bounds = [0.0, 3.0] }\n[model.tracks]\nunits = { length = "bl" }\n'
        "[run]\ngroup_radius = 5.0\n")
    commands = expand(load_sweep(tmp_path / "command.toml"))
    assert shapes(worker.replicate_groups(below)) == [[(0, 0), (0, 1)], [(1, 0), (1, 1)]]
    for specs, why in [(large, "threaded"), (limited, "timeout_s"), (plugin, "plug-in"), (commands, "command")]:
        assert len(specs) >= 2 and all(s.point_index == specs[0].point_index for s in specs[:2]), why
        assert [len(g) for g in worker.replicate_groups(specs)] == [1] * len(specs), why
        assert not any(worker.groupable(s) for s in specs), why


def test_kept_trajectories_group_within_the_groups_memory_bound(tmp_path, monkeypatch):
    specs = expand(load_sweep(write_sweep(tmp_path, replicates=4, run_extra='keep = "trajectories"')))
    assert [len(g) for g in worker.replicate_groups(specs)] == [4, 4]
    one = worker._group_bytes(specs[0])
    monkeypatch.setattr(worker, "GROUP_BYTES", 2.5 * one)
    assert [len(g) for g in worker.replicate_groups(specs)] == [2, 2, 2, 2]
    monkeypatch.setattr(worker, "GROUP_BYTES", 0.5 * one)   # a run larger than the bound still runs, alone
    assert [len(g) for g in worker.replicate_groups(specs)] == [1] * 8
    # specs that differ in anything but the seed never share a group
    other = dataclasses.replace(specs[1], storage=dataclasses.replace(specs[1].storage, trajectory_every=3))
    monkeypatch.setattr(worker, "GROUP_BYTES", 64 * 2 ** 20)
    assert [len(g) for g in worker.replicate_groups([specs[0], other, specs[2]])] == [1, 1, 1]


# -- how a sweep is cut into batches ------------------------------------------------------------------------

def test_batches_hold_a_share_of_the_cost_dearest_first_every_run_once(tmp_path, monkeypatch):
    axes = '[[axes]]\nkey = "init.n"\nvalues = [6, 12, 24]\n'
    specs = expand(load_sweep(write_sweep(tmp_path, replicates=20, axes=axes)))   # costs 1 : 4 : 16 (x n_steps 36)
    batches = make_batches(specs, workers=2)
    assert sorted(s.index for b in batches for s in b) == list(range(60))
    share = sum(s.cost for s in specs) / (2 * runner.BATCHES_PER_WORKER)
    assert all(sum(s.cost for s in b) <= share * (1 + 1e-9) or len(b) == 1 for b in batches)
    costs = [s.cost for b in batches for s in b]
    assert costs == sorted(costs, reverse=True)
    # the dear runs travel alone or in few, the cheap ones many to a batch, each batch one cost share at most
    assert max(len(b) for b in batches if b[0].preset.init.n == 24) < max(len(b) for b in batches
                                                                         if b[0].preset.init.n == 6)
    assert len(batches) <= 2 * runner.BATCHES_PER_WORKER + 3
    # a design point's replicates stay next to each other (they are simulated together)
    for batch in batches:
        points = [s.point_index for s in batch]
        assert points == sorted(points, key=points.index)   # each point's runs together ...
        assert all(b.index == a.index + 1 for a, b in zip(batch, batch[1:]) if a.point_index == b.point_index)
    assert [len(b) for b in make_batches(specs, 2, batch_size=7)] == [7] * 8 + [4]
    monkeypatch.setattr(runner, "MAX_BATCH_RUNS", 3)
    assert max(len(b) for b in make_batches(specs, workers=1)) == 3
    monkeypatch.setattr(runner, "MAX_BATCH_RUNS", 4096)
    monkeypatch.setattr(runner, "MAX_BATCH_COST", 2.5 * specs[0].cost)   # seconds of work at most, any sweep size
    small = make_batches([s for s in specs if s.preset.init.n == 6] * 10, workers=1)   # a share of 6.25 runs
    assert [len(b) for b in small] == [2] * 100


def test_command_runs_travel_at_most_max_command_batch_to_a_batch(tmp_path):
    command = json.dumps([sys.executable, str(TESTS / "sweeps" / "faulty_sim.py"), "--seed", "{seed}",
                          "--out", "{out}", "{params}"])
    (tmp_path / "command.toml").write_text(
        f'name = "command"\nseed = 5\nreplicates = 800\n[model]\ncommand = {command}\n[model.parameters]\n'
        'noise = { default = 0.3, bounds = [0.0, 3.0] }\n[model.tracks]\nunits = { length = "bl" }\n'
        "[run]\ngroup_radius = 5.0\n")
    specs = expand(load_sweep(tmp_path / "command.toml"))
    batches = make_batches(specs, workers=1)
    assert max(map(len, batches)) == runner.MAX_COMMAND_BATCH and sum(map(len, batches)) == 800


def test_part_writer_writes_a_part_once_its_series_rows_reach_the_bound(tmp_path):
    class Store:
        def __init__(self):
            self.parts = []

        def next_part(self):
            return len(self.parts)

        def write_part(self, number, rows, ts):
            self.parts.append((len(rows), None if ts is None else len(ts)))

    store = Store()
    frame = pd.DataFrame({"run_id": ["a"] * 10, "t": np.arange(10.0)})
    with PartWriter(store, max_runs=100, max_seconds=3600, max_series_rows=25) as writer:
        for _ in range(5):
            writer.add([{"run_id": "a"}], frame)
        assert store.parts == [(3, 30)]
    assert store.parts == [(3, 30), (2, 20)]   # the rest on exit
    assert runner.PART_RUNS >= 10_000   # a sweep of small runs: few parts, each one of many runs


# -- nothing changes a result -----------------------------------------------------------------------------

def test_results_are_bit_identical_alone_grouped_and_cut_anywhere(tmp_path, monkeypatch):
    sweep = write_sweep(tmp_path, replicates=4, run_extra='keep = "trajectories"\ntrajectory_every = 3')
    calls = []
    real = worker.simulate_batch
    monkeypatch.setattr(worker, "simulate_batch", lambda *a, **k: calls.append(len(a[2])) or real(*a, **k))
    run(sweep, tmp_path / "alone", batch_size=1)
    assert calls == []
    run(sweep, tmp_path / "grouped", batch_size=8)   # one batch: each point's 4 replicates simulated together
    assert sorted(calls) == [4, 4]
    run(sweep, tmp_path / "cut", batch_size=3)   # batches of 3: groups of 3, 1 + 2, 2 + 1 ... runs
    assert len(calls) > 2
    reference = results(tmp_path / "alone")
    assert (reference["status"] == "ok").all() and len(reference) == 8
    for name in ("grouped", "cut"):
        assert_frame_equal(results(tmp_path / name), reference, check_exact=True)
        assert_frame_equal(series(tmp_path / name), series(tmp_path / "alone"), check_exact=True)
        for spec in expand(load_sweep(sweep)):
            with np.load(tmp_path / name / "trajectories" / f"{spec.run_id}.npz") as got, \
                    np.load(tmp_path / "alone" / "trajectories" / f"{spec.run_id}.npz") as want:
                assert sorted(got.files) == sorted(want.files)
                for key in want.files:
                    np.testing.assert_array_equal(got[key], want[key])
    grouped = pd.read_parquet(tmp_path / "grouped" / "runs.parquet")
    assert (grouped["sim_s"] > 0).all() and (grouped["wall_s"] >= grouped["sim_s"]).all()


@pytest.mark.slow
def test_a_local_pool_of_two_gives_the_serial_results(tmp_path):
    sweep = write_sweep(tmp_path, replicates=6)
    run(sweep, tmp_path / "serial", batch_size=1)
    run(sweep, tmp_path / "local", executor="local", workers=2, batch_size=5)   # groups cut across batches
    assert_frame_equal(results(tmp_path / "local"), results(tmp_path / "serial"), check_exact=True)
    assert_frame_equal(series(tmp_path / "local"), series(tmp_path / "serial"), check_exact=True)


def test_a_run_failing_inside_a_group_is_its_own_failure_and_the_others_are_kept(tmp_path, monkeypatch):
    sweep = write_sweep(tmp_path, replicates=4)
    run(sweep, tmp_path / "clean")
    bad_seed = expand(load_sweep(sweep))[2].seed
    real = worker.measure_run

    def measure(obs, settings):   # the third run's records fail to measure
        if obs.final is BAD[0]:
            raise RuntimeError("boom: cannot measure")
        return real(obs, settings)

    real_batch = worker.simulate_batch
    BAD = [None]

    def simulate_batch(model, init, seeds, *args):
        out = real_batch(model, init, seeds, *args)
        for seed, obs in zip(seeds, out):
            if seed == bad_seed:
                BAD[0] = obs.final
        return out

    monkeypatch.setattr(worker, "measure_run", measure)
    monkeypatch.setattr(worker, "simulate_batch", simulate_batch)
    run(sweep, tmp_path / "out", batch_size=8)
    got = pd.read_parquet(tmp_path / "out" / "runs.parquet")
    assert list(got["status"]) == ["ok", "ok", "failed", "ok"] + ["ok"] * 4
    assert got.loc[2, "error"] == "RuntimeError: boom: cannot measure" and got.loc[2, "seed"] == bad_seed
    assert np.isnan(got.loc[2, "cohesion_mean"]) and got.loc[2, "sim_s"] > 0
    keep = [0, 1, 3, 4, 5, 6, 7]
    assert_frame_equal(got.drop(columns=TIMING).loc[keep], results(tmp_path / "clean").loc[keep], check_exact=True)
    assert set(ResultsStore(tmp_path / "out").timeseries()["run_id"]) == set(got.loc[keep, "run_id"])


def test_a_group_whose_simulation_raises_runs_each_alone(tmp_path, monkeypatch):
    sweep = write_sweep(tmp_path, replicates=3)
    run(sweep, tmp_path / "clean")
    bad_seed = expand(load_sweep(sweep))[1].seed
    real = worker.simulate

    def simulate(model, init, seed, *args, **kwargs):
        if seed == bad_seed:
            raise RuntimeError("boom: this seed")
        return real(model, init, seed, *args, **kwargs)

    def simulate_batch(model, init, seeds, *args):
        if bad_seed in seeds:
            raise RuntimeError("boom: a seed of the batch")
        return worker.simcore_batch(model, init, seeds, *args)

    monkeypatch.setattr(worker, "simcore_batch", worker.simulate_batch, raising=False)
    monkeypatch.setattr(worker, "simulate_batch", simulate_batch)
    monkeypatch.setattr(worker, "simulate", simulate)
    run(sweep, tmp_path / "out", batch_size=6)
    got = pd.read_parquet(tmp_path / "out" / "runs.parquet")
    assert list(got["status"]) == ["ok", "failed", "ok", "ok", "ok", "ok"]
    assert got.loc[1, "error"] == "RuntimeError: boom: this seed"
    keep = [0, 2, 3, 4, 5]
    assert_frame_equal(got.drop(columns=TIMING).loc[keep], results(tmp_path / "clean").loc[keep], check_exact=True)


def test_runs_starting_from_a_state_file_group_and_match_their_runs_alone(monkeypatch):
    """couzin2002_hysteresis's replicates start from a stored state (init.from_file), 100 boids, 1 s here."""
    monkeypatch.chdir(ROOT)   # its states are named relative to the repository root
    config = load_sweep(ROOT / "configs" / "sweeps" / "couzin2002_hysteresis.toml", ["run.duration=1.0",
                                                                                      "run.warmup=0.2"], 3)
    specs = [s for s in expand(config) if s.point_index == 0]
    assert specs[0].preset.init.from_file and [len(g) for g in worker.replicate_groups(specs)] == [3]
    rows, timeseries = worker.execute_batch(specs)
    alone = [worker.execute_run(spec) for spec in specs]
    assert [r["status"] for r in rows] == ["ok"] * 3
    assert_frame_equal(pd.DataFrame(rows).drop(columns=["sim_s", "wall_s"]),
                       pd.DataFrame([row for row, _ in alone]).drop(columns=["sim_s", "wall_s"]), check_exact=True)
    assert_frame_equal(timeseries, pd.concat([ts for _, ts in alone], ignore_index=True), check_exact=True)
