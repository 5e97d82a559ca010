"""Running sweeps end to end on tiny designs: the results store, resume, executors, failures, locking.

Every sweep here is a few runs of 6-12 boids for 1.5 s (one resume test uses bigger runs so that a
runner can be killed halfway). The sweep files are written into ``tmp_path`` at test time.
"""
from __future__ import annotations

import re

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from flocksweep.observables.metrics import METRIC_NAMES
from flocksweep.simcore import simulate
from flocksweep.sweeps import worker
from flocksweep.cli import main
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.runner import run_sweep, status
from flocksweep.sweeps.store import ResultsStore, StoreLocked
from paths import ROOT

HOLLAND = ROOT / "configs" / "models" / "holland.toml"

TIMING = ["wall_s", "sim_s", "part"]  # the only columns allowed to differ between equal computations
METRICS = [f"{name}_{stat}" for name in METRIC_NAMES for stat in ("mean", "final")] + \
          ["time_to_fragmentation", "fragmented"]

MODE_AXIS = """
[[axes]]
name = "mode"
key = "patterns.enabled"
values = [false, true]
labels = ["normal", "pattern"]
"""

FIELD_AXIS = """
[[axes]]
key = "perception.field_deg"
values = [60, 180]
"""

SMOKE_AXES = MODE_AXIS + FIELD_AXIS  # the shipped smoke sweep's design

N_AXIS = """
[[axes]]
key = "init.n"
values = [6, 7, 8]
"""


def write_sweep(folder: Path, axes: str, *, name="tiny", n=8, duration=1.5, replicates=1, seed=3,
                run_extra="") -> Path:
    """A sweep file with the holland model, a short run and the given axes."""
    path = folder / f"{name}.toml"
    path.write_text(f"""# written by a test
name = "{name}"
seed = {seed}
replicates = {replicates}

[model]
preset = "{HOLLAND}"

[run]
n = {n}
duration = {duration}
record_interval = 0.5
warmup = 0.5
{run_extra}
{axes}
""")
    return path


def run(path: Path, out: Path, **options):
    """run_sweep on a sweep file, without progress bar (serial unless told otherwise)."""
    options.setdefault("executor", "serial")
    return run_sweep(load_sweep(path), path.read_text(), out, progress=False, **options)


def table(out: Path) -> pd.DataFrame:
    return pd.read_parquet(out / "runs.parquet")


def results(out: Path) -> pd.DataFrame:
    """runs.parquet without the timing and part columns."""
    return table(out).drop(columns=TIMING)


def series(out: Path) -> pd.DataFrame:
    return ResultsStore(out).timeseries().sort_values(["run_id", "t"]).reset_index(drop=True)


def part_files(out: Path) -> list[str]:
    folder = out / "runs"
    return sorted(p.name for p in folder.glob("part-*.parquet")) if folder.is_dir() else []


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` with its bytes (to show nothing was written)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def fail_when_n_is_7(make_failure):
    """A stand-in for sweeps.worker.simulate that fails (as ``make_failure`` says) for init.n == 7."""
    real = worker.simulate

    def patched(model, init, seed, *args, **kwargs):
        obs = real(model, init, seed, *args, **kwargs)
        return make_failure(obs) if init.n == 7 else obs

    return patched


def raise_boom(obs):
    raise RuntimeError("boom: seven boids")


def batches_simulating_with(simulate_fn):
    """A stand-in for sweeps.worker.execute_batch that runs its batch with ``simulate_fn`` as the worker's
    simulate. The runner ships the batch function with every task, so this reaches worker processes too
    (they are spawned: a patch of the parent's module would not)."""
    real = worker.execute_batch

    def patched(specs, out_dir=None):
        original = worker.simulate
        worker.simulate = simulate_fn
        try:
            return real(specs, out_dir)
        finally:
            worker.simulate = original

    return patched


# -- end to end through the CLI --------------------------------------------------------------------

@pytest.mark.slow
def test_cli_run_writes_the_store_and_a_second_run_computes_nothing(tmp_path, capsys):
    sweep = write_sweep(tmp_path, SMOKE_AXES, name="smokeish", replicates=2)
    out = tmp_path / "results"
    argv = ["run", str(sweep), "--out", str(out), "--workers", "2", "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "smokeish: 8 runs, 8 ok, 0 failed; computed 8 now, 0 already done" in printed

    runs = table(out)
    assert len(runs) == 8 and runs["run_id"].is_unique
    for column in ["run_id", "replicate", "seed", "mode", "patterns.enabled", "perception.field_deg", "status",
                   "error", "wall_s", "cohesion_mean", "polarization_final", "time_to_fragmentation"]:
        assert column in runs.columns, column
    assert set(METRICS) <= set(runs.columns)
    assert (runs["status"] == "ok").all() and (runs["error"] == "").all()
    assert (runs["wall_s"] > 0).all()
    assert list(runs["index"]) == list(range(8))
    assert sorted(runs["replicate"]) == [0, 0, 0, 0, 1, 1, 1, 1]
    assert set(runs["mode"]) == {"normal", "pattern"} and set(runs["perception.field_deg"]) == {60.0, 180.0}
    assert runs["polarization_final"].between(0, 1).all()

    design = pd.read_parquet(out / "design.parquet")
    assert list(design["run_id"]) == list(runs["run_id"])
    assert list(design["seed"]) == list(runs["seed"])
    # the file's text as written, but for the preset, named relative to the results folder (portable)
    preset_line = next(line for line in sweep.read_text().splitlines() if line.startswith("preset = "))
    relative = os.path.relpath(preset_line.split('"')[1], out)
    assert (out / "sweep.toml").read_text() == sweep.read_text().replace(preset_line, f'preset = "{relative}"')
    assert json.loads((out / "sweep.effective.json").read_text())["replicates"] == 2

    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["sweep"] == "smokeish"
    assert manifest["packages"]["numpy"] == np.__version__ and manifest["packages"]["flocksweep"]
    assert "git_revision" in manifest
    assert manifest["machine"]["cpus"] and manifest["machine"]["python"]
    assert manifest["started"] and manifest["finished"] and manifest["started"] <= manifest["finished"]
    assert manifest["counts"] == {"runs": 8, "ok": 8, "failed": 0, "missing": 0}
    assert manifest["computed_this_invocation"] == 8

    ts = ResultsStore(out).timeseries()
    assert set(ts["run_id"]) == set(runs["run_id"])
    assert sorted(set(ts["t"])) == pytest.approx([0.0, 0.5, 1.0, 1.5])
    assert len(ts) == 8 * 4

    assert main(["status", str(out)]) == 0
    assert "smokeish: 8 runs: 8 done, 0 failed, 0 missing" in capsys.readouterr().out

    parts = part_files(out)
    assert main(argv) == 0
    assert "computed 0 now, 8 already done" in capsys.readouterr().out
    assert_frame_equal(table(out), runs)
    assert part_files(out) == parts
    assert json.loads((out / "manifest.json").read_text())["computed_this_invocation"] == 0


def test_cli_status_of_a_directory_without_a_sweep_is_exit_2(tmp_path, capsys):
    assert main(["status", str(tmp_path / "nothing")]) == 2
    assert "no sweep stored here" in capsys.readouterr().err


# -- executors ----------------------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("executor", ["local", "dask"])
def test_executors_give_bit_identical_results(executor, tmp_path):
    if executor == "dask":
        pytest.importorskip("dask.distributed")
    import dask

    scheduler = dask.config.get("scheduler", None)
    sweep = write_sweep(tmp_path, N_AXIS + FIELD_AXIS, replicates=2)
    serial, other = tmp_path / "serial", tmp_path / executor
    reference = run(sweep, serial, executor="serial")
    result = run(sweep, other, executor=executor, workers=2, batch_size=1)
    assert len(reference.plan.todo) == len(result.plan.todo) == 3 * 2 * 2
    assert (table(other)["status"] == "ok").all()
    assert_frame_equal(results(other), results(serial), check_exact=True)
    assert_frame_equal(series(other), series(serial), check_exact=True)
    assert ResultsStore(other).manifest()["executor"] == executor
    # dask's global scheduler is left as it was: set to our closed client, xarray's to_netcdf (a calibration's
    # posterior.nc, later in the same process) failed with "Requested dask.distributed scheduler but no Client"
    assert dask.config.get("scheduler", None) == scheduler


# -- resume --------------------------------------------------------------------------------------------

# The runner killed by SIGKILL at a known point: a part written after every run (FLUSH_SECONDS = 0, one run a
# batch), and the process killing itself right after its KILL_AFTER-th part is on disk. A real runner process
# and a real SIGKILL, at the same point whatever the machine's speed (racing a timer against the runs'
# speed, as before, sometimes found every run done at the kill on a busy machine).
KILL_AFTER = 10
KILLED_RUNNER = """
import os, signal, sys
from flocksweep.cli import main
from flocksweep.sweeps import runner, store

runner.FLUSH_SECONDS = 0.0
write_part, written = store.ResultsStore.write_part, []

def write_part_then_die(self, *args, **kwargs):
    write_part(self, *args, **kwargs)
    written.append(1)
    if len(written) == {kill_after}:
        os.kill(os.getpid(), signal.SIGKILL)

store.ResultsStore.write_part = write_part_then_die
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_resume_after_sigkill_finishes_without_recomputing_or_duplicating(tmp_path, capsys):
    axes = '[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 90, 120, 150, 180, 210, 240, 270]\n'
    sweep = write_sweep(tmp_path, axes, name="killed", n=12, duration=2.0, replicates=4)
    total = 32
    out = tmp_path / "killed"
    script = tmp_path / "killed_runner.py"
    script.write_text(KILLED_RUNNER.format(kill_after=KILL_AFTER))
    with open(tmp_path / "runner.log", "w") as log:
        proc = subprocess.run([sys.executable, str(script), "run", str(sweep), "--out", str(out),
                               "--executor", "serial", "--batch-size", "1", "--no-progress"],
                              cwd=tmp_path, stdout=log, stderr=subprocess.STDOUT, timeout=600)
    assert proc.returncode == -signal.SIGKILL, (tmp_path / "runner.log").read_text()[-2000:]
    assert not (out / "runs.parquet").exists()

    before = pd.concat([pd.read_parquet(out / "runs" / name) for name in part_files(out)], ignore_index=True)
    assert len(part_files(out)) == KILL_AFTER and len(before) == KILL_AFTER
    done = len(before)

    assert main(["run", str(sweep), "--out", str(out), "--executor", "local", "--workers", "2",
                 "--no-progress"]) == 0
    assert f"computed {total - done} now, {done} already done" in capsys.readouterr().out

    resumed = table(out)
    design_ids = [s.run_id for s in expand(load_sweep(sweep))]
    assert resumed["run_id"].is_unique
    assert list(resumed["run_id"]) == design_ids
    assert (resumed["status"] == "ok").all()
    kept = resumed.set_index("run_id").loc[before["run_id"], "part"]
    assert list(kept) == list(before["part"])  # finished before the kill: not recomputed

    fresh = tmp_path / "uninterrupted"
    run(sweep, fresh, executor="local", workers=2)
    assert_frame_equal(results(out), results(fresh), check_exact=True)
    assert_frame_equal(series(out), series(fresh), check_exact=True)


# -- failures --------------------------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("executor", ["serial", "local"])
def test_failing_run_is_recorded_the_rest_finish_and_retry_fixes_it(executor, tmp_path, monkeypatch, capsys):
    sweep = write_sweep(tmp_path, N_AXIS)
    out = tmp_path / "results"
    real_batch = worker.execute_batch
    monkeypatch.setattr(worker, "execute_batch", batches_simulating_with(fail_when_n_is_7(raise_boom)))
    result = run(sweep, out, executor=executor, workers=2, batch_size=1)
    runs = table(out)
    assert list(runs["init.n"]) == [6, 7, 8]
    assert list(runs["status"]) == ["ok", "failed", "ok"]
    assert runs.loc[1, "error"] == "RuntimeError: boom: seven boids"
    assert list(runs.loc[[0, 2], "error"]) == ["", ""]
    assert np.isnan(runs.loc[1, "cohesion_mean"]) and np.isfinite(runs.loc[[0, 2], "cohesion_mean"]).all()
    failed_id = runs.loc[1, "run_id"]
    assert set(ResultsStore(out).timeseries()["run_id"]) == set(runs.loc[[0, 2], "run_id"])

    info = status(out)
    assert (info["runs"], info["ok"], info["failed"], info["missing"]) == (3, 2, 1, 0)
    assert info["failures"] == [(failed_id, "RuntimeError: boom: seven boids")]
    assert info["manifest"]["counts"] == {"runs": 3, "ok": 2, "failed": 1, "missing": 0}
    assert main(["status", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "3 runs: 2 done, 1 failed, 0 missing" in printed
    assert f"failed {failed_id}: RuntimeError: boom: seven boids" in printed
    assert len(result.plan.todo) == 3

    monkeypatch.setattr(worker, "execute_batch", real_batch)  # the cause is fixed
    again = run(sweep, out, executor=executor, workers=2)
    assert again.plan.todo == [] and [s.run_id for s in again.plan.failed] == [failed_id]
    assert_frame_equal(table(out), runs)  # still failed: failures are kept without --retry-failed

    retried = run(sweep, out, executor=executor, workers=2, retry_failed=True)
    assert [s.run_id for s in retried.plan.todo] == [failed_id]
    fixed = table(out)
    assert list(fixed["status"]) == ["ok", "ok", "ok"] and (fixed["error"] == "").all()
    assert list(fixed.loc[[0, 2], "part"]) == list(runs.loc[[0, 2], "part"])
    assert fixed.loc[1, "part"] > runs["part"].max()
    assert status(out)["failures"] == []


def test_non_finite_state_is_a_failed_run(tmp_path, monkeypatch):
    def poison(obs):
        obs.pos[2, 0, 1] = np.nan  # the third record: t = 1 s
        return obs

    sweep = write_sweep(tmp_path, N_AXIS)
    out = tmp_path / "results"
    monkeypatch.setattr(worker, "simulate", fail_when_n_is_7(poison))
    run(sweep, out)
    runs = table(out)
    assert list(runs["status"]) == ["ok", "failed", "ok"]
    # the reason names the boid and the steps its records bracket (here the poison is in the records only,
    # so the run recorded again at every step does not show it: tests/sweeps/test_containment.py has a
    # real NaN, found at its step)
    assert runs.loc[1, "error"].endswith("NonFiniteState: non-finite state: boid 0's position became NaN between "
                                         "steps 30 and 59 (t = 0.5 to 1 s); forces so large that the motion "
                                         "overflowed")
    assert np.isfinite(runs.loc[1, "sim_s"]) and runs.loc[1, "wall_s"] >= runs.loc[1, "sim_s"]   # its accounting
    assert status(out)["failed"] == 1


def test_sweep_whose_every_run_raises_records_them_all_as_failed(tmp_path, monkeypatch):
    def always_raise(*args, **kwargs):
        raise RuntimeError("kernel exploded")

    sweep = write_sweep(tmp_path, N_AXIS)
    out = tmp_path / "results"
    monkeypatch.setattr(worker, "simulate", always_raise)
    run(sweep, out)
    assert list(table(out)["status"]) == ["failed"] * 3


# -- force, lock, dry run --------------------------------------------------------------------------------

def test_force_recomputes_every_run_into_new_parts_with_equal_results(tmp_path):
    sweep = write_sweep(tmp_path, N_AXIS)
    out = tmp_path / "results"
    run(sweep, out)
    first = table(out)
    forced = run(sweep, out, force=True)
    assert len(forced.plan.todo) == 3 and forced.plan.done == []
    second = table(out)
    assert (second["part"] > first["part"].max()).all()
    assert_frame_equal(second.drop(columns=TIMING), first.drop(columns=TIMING), check_exact=True)
    assert len(ResultsStore(out).all_rows()) == 6  # old parts are kept, the latest row wins


@pytest.mark.slow
def test_second_runner_on_a_locked_directory_is_refused(tmp_path, capsys):
    sweep = write_sweep(tmp_path, N_AXIS)
    out = tmp_path / "results"
    with ResultsStore(out).lock():
        with pytest.raises(StoreLocked) as info:
            run(sweep, out)
        message = str(info.value)
        assert "in use by another flocksweep runner" in message and f"pid {os.getpid()}" in message
        assert main(["run", str(sweep), "--out", str(out), "--executor", "serial", "--no-progress"]) == 3
        assert "in use by another flocksweep runner" in capsys.readouterr().err
        assert [p.name for p in out.iterdir()] == [".lock"]  # nothing else was written
    run(sweep, out)  # released: the next runner proceeds
    assert (table(out)["status"] == "ok").all()


def test_dry_run_counts_runs_and_cost_and_writes_nothing(tmp_path, capsys):
    sweep = write_sweep(tmp_path, SMOKE_AXES, replicates=2)
    out = tmp_path / "results"
    dry = ["run", str(sweep), "--out", str(out), "--dry-run", "--executor", "serial"]
    assert main(dry) == 0
    printed = capsys.readouterr().out
    assert "tiny: 8 runs; 0 done, 0 failed" in printed and "8 to run" in printed
    assert "(5,760 boid-steps;" in printed  # 8 runs x 8 boids x 90 steps
    wall = re.search(r"estimated wall time: about (\d+) s = start-up ([\d.]+) s \+ simulation ([\d.]+) s \+ "
                     r"per-run overhead ([\d.]+) ms x 8 runs, on 1 worker", printed)
    assert wall, printed   # what the user waits for: start-up and per-run overhead, not the simulation alone
    total, startup, simulation, per_run = (float(g) for g in wall.groups())
    assert startup > 0 and per_run > 0
    assert abs(total - (startup + simulation + per_run / 1000 * 8)) <= 1.0
    assert not out.exists()

    run(sweep, out)
    before = snapshot(out)
    assert main(dry + ["--replicates", "3"]) == 0
    printed = capsys.readouterr().out
    assert "tiny: 12 runs; 8 done, 0 failed" in printed and "4 to run" in printed
    assert "(2,880 boid-steps;" in printed and "x 4 runs" in printed
    assert main(dry + ["--set", "seed=4"]) == 0
    assert "tiny: 8 runs; 0 done" in capsys.readouterr().out
    assert snapshot(out) == before


# -- trajectories ----------------------------------------------------------------------------------------

def test_keep_trajectories_writes_positions_and_leaves_metrics_unchanged(tmp_path):
    keep = write_sweep(tmp_path, N_AXIS, name="keep", run_extra='keep = "trajectories"\ntrajectory_every = 6')
    plain = write_sweep(tmp_path, N_AXIS, name="plain")
    run(keep, tmp_path / "keep")
    run(plain, tmp_path / "plain")
    kept, metrics = table(tmp_path / "keep"), table(tmp_path / "plain")
    assert not set(kept["run_id"]) & set(metrics["run_id"])  # keep is part of a run's identity
    assert list(kept["seed"]) == list(metrics["seed"])
    assert_frame_equal(kept[METRICS], metrics[METRICS], check_exact=True)
    assert not (tmp_path / "plain" / "trajectories").exists()

    specs = {s.run_id: s for s in expand(load_sweep(keep))}
    files = sorted(p.name for p in (tmp_path / "keep" / "trajectories").iterdir())
    assert files == sorted(f"{rid}.npz" for rid in kept["run_id"])
    for row in kept.itertuples():
        spec = specs[row.run_id]
        saved = np.load(tmp_path / "keep" / "trajectories" / f"{row.run_id}.npz")
        n, dt = spec.preset.init.n, spec.preset.run.dt
        assert saved["pos"].shape == saved["vel"].shape == (90 // 6 + 1, n, 3)
        assert np.allclose(np.diff(saved["times"]), 6 * dt)
        assert int(saved["seed"]) == row.seed
        direct = simulate(spec.preset.model, spec.preset.init, row.seed, spec.preset.run.duration, dt, 6)
        assert np.array_equal(saved["pos"], direct.pos) and np.array_equal(saved["vel"], direct.vel)


@pytest.mark.parametrize("every", [4, 60])
def test_trajectory_frames_are_trajectory_every_steps_apart(every, tmp_path):
    sweep = write_sweep(tmp_path, N_AXIS, run_extra=f'keep = "trajectories"\ntrajectory_every = {every}')
    out = tmp_path / "results"
    run(sweep, out)
    rid = table(out)["run_id"][0]
    saved = np.load(out / "trajectories" / f"{rid}.npz")
    steps = np.diff(saved["times"]) / (1 / 60)  # the holland preset's dt
    assert np.allclose(steps, every)


# -- reusing a directory with a changed design ------------------------------------------------------------

GRID_CHANGES = {
    # (axes and replicates of the first run, of the second run, runs computed by the second)
    "grid reordered and grown": (('[[axes]]\nkey = "init.n"\nvalues = [8, 6]\n', 1),
                                 ('[[axes]]\nkey = "init.n"\nvalues = [6, 7, 8]\n', 1), 1),
    "replicates raised": ((N_AXIS, 2), (N_AXIS, 3), 3),
}


@pytest.mark.parametrize("change", list(GRID_CHANGES))
def test_changed_design_in_the_same_directory_is_consolidated_in_design_order(change, tmp_path):
    (axes_before, replicates_before), (axes_after, replicates_after), new_runs = GRID_CHANGES[change]
    out = tmp_path / "results"
    run(write_sweep(tmp_path, axes_before, name="grid", replicates=replicates_before), out)
    result = run(write_sweep(tmp_path, axes_after, name="grid", replicates=replicates_after), out)
    assert len(result.plan.todo) == new_runs  # the earlier runs are reused, as the identity promises
    runs, design = table(out), pd.read_parquet(out / "design.parquet")
    assert list(runs["run_id"]) == list(design["run_id"])
    assert list(runs["index"]) == list(design["index"])


def test_manifest_keeps_every_invocation_that_computed_runs(tmp_path):
    path = write_sweep(tmp_path, '[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 180]\n', duration=1.0)
    out = tmp_path / "out"
    run(path, out)
    run_sweep(load_sweep(path, replicates=2), path.read_text(), out, executor="serial", progress=False)
    run(path, out)                                              # computes nothing
    manifest = json.loads((out / "manifest.json").read_text())
    assert [h["computed"] for h in manifest["invocations"]] == [2, 2]
    assert manifest["computed_this_invocation"] == 0
    assert all(h["git_revision"] == manifest["git_revision"] for h in manifest["invocations"])
    assert manifest["invocations"][0]["started"] <= manifest["invocations"][1]["started"]
