"""Sweeps on a batch-scheduled cluster (sweeps.cluster, ``flocksweep run --executor cluster``) and on a Dask
scheduler started from the ``dask`` command line.

The cluster is this machine behind stand-in ``sbatch``/``scancel`` (and ``qsub``/``qdel``) commands that
run the job script dask-jobqueue generates, each job in its own process group, as a batch scheduler
would; the results are bit for bit those of a serial run, and no job outlives the sweep."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from flocksweep.cli import main
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.cluster import ClusterSettings, cluster_settings, job_script
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from paths import ROOT

HOLLAND = ROOT / "configs" / "models" / "holland.toml"
TIMING = ["wall_s", "sim_s", "part"]

SWEEP = f"""name = "tiny_cluster"
seed = 11
[model]
preset = "{HOLLAND}"
[run]
n = 8
duration = 1.0
warmup = 0.5
record_interval = 0.25
[[axes]]
key = "perception.field_deg"
values = [60, 180, 300]
"""

CLUSTER = """
[cluster]
kind = "slurm"
queue = "short"
account = "flock42"
jobs = 2
cores = 2
memory = "2GB"
walltime = "00:20:00"
directives = ["--constraint=cpu"]
prologue = ["export FLOCKSWEEP_JOB=1"]
"""

# A batch scheduler on this machine: submission copies the job script (dask-jobqueue deletes its file
# once submitted), starts it in a process group of its own and prints the job id as the real one does;
# cancelling ends that group. Every job id is logged so the test can check none is left running.
SUBMIT = """#!/usr/bin/env bash
set -e
dir="{jobs}"
script="$dir/job-$$-$RANDOM.sh"
cp "${{@: -1}}" "$script"
setsid bash "$script" > "$script.log" 2>&1 < /dev/null &
echo "$!" >> "$dir/ids"
echo "{answer}"
"""
CANCEL = """#!/usr/bin/env bash
for id in "$@"; do kill -TERM -- "-$id" 2>/dev/null || true; done
"""
SCHEDULERS = {"slurm": ("sbatch", "scancel", "Submitted batch job $!"), "pbs": ("qsub", "qdel", "$!.server")}


def write_sweep(folder: Path, cluster: str = "") -> Path:
    path = folder / "sweep.toml"
    path.write_text(SWEEP + cluster)
    return path


def fake_scheduler(folder: Path, kind: str) -> Path:
    """A bin/ folder with the scheduler's submit and cancel commands; job ids logged in jobs/ids."""
    submit, cancel, answer = SCHEDULERS[kind]
    bin_dir, jobs = folder / "bin", folder / "jobs"
    bin_dir.mkdir()
    jobs.mkdir()
    (bin_dir / submit).write_text(SUBMIT.format(jobs=jobs, answer=answer))
    (bin_dir / cancel).write_text(CANCEL)
    for name in (submit, cancel):
        (bin_dir / name).chmod(0o755)
    return bin_dir


def alive(pid: int) -> bool:
    try:
        os.killpg(pid, 0)
    except ProcessLookupError:
        return False
    return True


def table(folder: Path) -> pd.DataFrame:
    return pd.read_parquet(folder / "runs.parquet").drop(columns=TIMING).set_index("run_id").sort_index()


# ------------------------------------------------------------------------------------------- settings

@pytest.mark.parametrize("key, value, expected", [
    ("kind", "slurmm", "cluster.kind"), ("jobs", 0, "cluster.jobs"), ("cores", -2, "cluster.cores"),
    ("processes", 3, "cluster.processes"), ("memory", "lots", "cluster.memory"),
    ("walltime", "2 hours", "cluster.walltime"), ("directives", ["a\nb"], "cluster.directives"),
    ("queu", "short", "cluster.queu"),
])
def test_a_bad_cluster_table_names_its_key_before_anything_runs(key, value, expected):
    table = {"kind": "slurm", "cores": 2, key: value}
    with pytest.raises(ConfigError) as err:
        cluster_settings(table)
    assert err.value.key == expected


def test_the_cluster_is_execution_only_and_never_changes_a_run_id(tmp_path):
    plain = load_sweep(write_sweep(tmp_path))
    declared = load_sweep(write_sweep(tmp_path, CLUSTER))
    overridden = load_sweep(write_sweep(tmp_path), ["cluster.kind=pbs", "cluster.jobs=3"])
    assert plain.cluster is None and declared.cluster.workers == 4
    assert overridden.cluster == ClusterSettings(kind="pbs", jobs=3)
    ids = [[spec.run_id for spec in expand(config)] for config in (plain, declared, overridden)]
    assert ids[0] == ids[1] == ids[2]


def test_the_job_script_carries_every_setting(tmp_path):
    settings = load_sweep(write_sweep(tmp_path, CLUSTER)).cluster
    script = job_script(settings)
    for line in ("#SBATCH -p short", "#SBATCH -A flock42", "#SBATCH -t 00:20:00", "#SBATCH --constraint=cpu",
                 "#SBATCH --cpus-per-task=2", "export FLOCKSWEEP_JOB=1", f"{sys.executable} -m distributed"):
        assert line in script, line
    pbs = job_script(ClusterSettings(kind="pbs", queue="long", walltime="01:00:00", memory="3GB"))
    assert "#PBS -q long" in pbs and "#PBS -l walltime=01:00:00" in pbs


def test_without_a_cluster_table_the_cluster_executor_is_refused_naming_the_fix(tmp_path, capsys):
    assert main(["run", str(write_sweep(tmp_path)), "--executor", "cluster", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "no [cluster] table" in err and "--set cluster.kind=slurm" in err
    assert not (tmp_path / "o").exists()
    assert main(["run", str(write_sweep(tmp_path, CLUSTER)), "--executor", "cluster", "--workers", "3"]) == 2
    assert "cluster.jobs x cluster.processes" in capsys.readouterr().err


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_a_dry_run_prints_the_job_script_and_submits_nothing(tmp_path, capsys, monkeypatch):
    bin_dir = fake_scheduler(tmp_path, "slurm")
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    code = main(["run", str(write_sweep(tmp_path, CLUSTER)), "--executor", "cluster", "--dry-run",
                 "--out", str(tmp_path / "o")])
    out = capsys.readouterr().out
    assert code == 0 and "slurm cluster: 2 job(s) x 2 worker(s)" in out and "#SBATCH -p short" in out
    assert not (tmp_path / "jobs" / "ids").exists()


# ------------------------------------------------------------------------------------------ end to end

@pytest.mark.slow
@pytest.mark.parametrize("kind", ["slurm", "pbs"])
def test_a_sweep_on_batch_jobs_gives_the_serial_results_and_leaves_no_job_behind(tmp_path, monkeypatch, capsys,
                                                                                 kind):
    bin_dir = fake_scheduler(tmp_path, kind)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    sweep = write_sweep(tmp_path, CLUSTER.replace('"slurm"', f'"{kind}"'))
    assert main(["run", str(sweep), "--executor", "serial", "--out", str(tmp_path / "serial"), "--no-progress"]) == 0
    code = main(["run", str(sweep), "--executor", "cluster", "--set", "cluster.interface=lo",
                 "--out", str(tmp_path / "cluster"), "--no-progress"])
    assert code == 0, capsys.readouterr().err
    assert_frame_equal(table(tmp_path / "serial"), table(tmp_path / "cluster"))
    ids = [int(line) for line in (tmp_path / "jobs" / "ids").read_text().split()]
    assert len(ids) == 2   # cluster.jobs
    deadline = time.monotonic() + 60   # cancelled jobs get their process group's SIGTERM; let them exit
    while any(alive(pid) for pid in ids) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [pid for pid in ids if alive(pid)]


@pytest.mark.slow
def test_a_sweep_on_a_scheduler_and_workers_started_from_the_dask_command_line(tmp_path, capsys):
    dask = [sys.executable, "-m", "dask"]   # the `dask` command of this interpreter, which has flocksweep
    scheduler_file = tmp_path / "scheduler.json"
    started = []
    try:
        started.append(subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", "0",
                                         "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                        start_new_session=True))
        deadline = time.monotonic() + 120
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        import json
        address = json.loads(scheduler_file.read_text())["address"]
        started.append(subprocess.Popen([*dask, "worker", "--scheduler-file", str(scheduler_file), "--nworkers", "2",
                                         "--nthreads", "1", "--no-dashboard"],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                        start_new_session=True))
        sweep = write_sweep(tmp_path)
        assert main(["run", str(sweep), "--executor", "serial", "--out", str(tmp_path / "serial"),
                     "--no-progress"]) == 0
        code = main(["run", str(sweep), "--executor", "dask", "--scheduler", address, "--out",
                     str(tmp_path / "dask"), "--no-progress"])
        assert code == 0, capsys.readouterr().err
        assert_frame_equal(table(tmp_path / "serial"), table(tmp_path / "dask"))
    finally:
        for process in reversed(started):
            os.killpg(process.pid, signal.SIGTERM)
            process.wait(timeout=60)


def test_loading_dask_jobqueue_keeps_the_processs_ctrl_c():
    """dask_jobqueue's runner module sets SIGINT to a bare sys.exit() on import; ours is put back."""
    import signal

    import importlib.util

    assert importlib.util.find_spec("dask_jobqueue") is not None   # the test extra installs it (flocksweep[hpc])
    from flocksweep.sweeps.cluster import _jobqueue_class

    before = signal.getsignal(signal.SIGINT)
    _jobqueue_class("slurm")
    assert signal.getsignal(signal.SIGINT) is before
