"""External simulators as commands (sweeps.external): configuration refused before anything runs, the
command built without a shell from checked values, and sweeps of the example simulator with faults
injected (tests/sweeps/faulty_sim.py): failures recorded with their reasons, the rest complete, resume,
the stored sweep, and the same rows from the serial and the local executor."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pandas.testing import assert_frame_equal

from flocksweep.cli import main
from flocksweep.observables.measured import measure_tracks, track_settings
from flocksweep.observables.resample import RECORDED
from flocksweep.observables.summary import summary_columns
from flocksweep.observables.tracks import TrackSource, load_tracks
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.external import TAIL_BYTES, CommandFailed, Tail, run_command
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT, TESTS

FAULTY = TESTS / "sweeps" / "faulty_sim.py"
DAEMON = "faulty-sim-daemon"   # faulty_sim.py's background child
EXAMPLE = ROOT / "configs" / "external" / "vicsek_sim.py"
TIMING = ["wall_s", "sim_s", "part"]

PARAMETERS = """
[model.parameters]
n_agents = { default = 12, bounds = [2, 100], integer = true }
noise = { default = 0.3, bounds = [0.0, 3.0] }
duration = { default = 4.0, bounds = [1.0, 60.0] }
fault = { default = "none", choices = ["none", "hang", "malformed", "crash"] }

[model.tracks]
units = { length = "bl" }

[run]
group_radius = 5.0
warmup = 1.0
"""

FAULTS_AXIS = """
[[axes]]
name = "case"
keys = ["noise", "fault"]
values = [[0.1, "none"], [0.5, "none"], [1.0, "none"], [0.3, "hang"], [0.3, "malformed"], [0.3, "crash"]]
"""


def command(*extra) -> str:
    args = [sys.executable, str(FAULTY), "--seed", "{seed}", "--out", "{out}", "{params}", *extra]
    return json.dumps(args)


def write_sweep(folder: Path, body: str = FAULTS_AXIS, model_lines: str = "", cmd: str | None = None,
                parameters: str = PARAMETERS) -> Path:
    path = folder / "external.toml"
    path.write_text(f'name = "external"\nseed = 5\n\n[model]\ncommand = {cmd or command()}\ntimeout_s = 4\n'
                    f"{model_lines}{parameters}{body}")
    return path


def processes_with(marker: str) -> dict[int, str]:
    """{pid: command line} of the running processes whose command line holds ``marker``."""
    found = {}
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            text = cmdline.read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if marker in text:
            found[int(cmdline.parent.name)] = text
    return found


def rows(out: Path) -> pd.DataFrame:
    return pd.read_parquet(out / "runs.parquet").drop(columns=TIMING)


# ------------------------------------------------------------------------------ refused before any run

@pytest.mark.parametrize("cmd, key, words", [
    (command("--typo", "{sed}"), "model.command[8]", "unknown placeholder {sed} (did you mean 'seed'?)"),
    (command("--x={seed:>5}"), "model.command", "without conversions or format specs"),
    (json.dumps(["no-such-simulator-anywhere", "--out", "{out}"]), "model.command[0]", "program not found"),
    (json.dumps(["./missing_sim", "--out", "{out}"]), "model.command[0]", "program not found: './missing_sim'"),
    (json.dumps([sys.executable, str(FAULTY), "--seed", "{seed}"]), "model.command", "never names {out}"),
    (json.dumps([sys.executable, str(FAULTY), "--out", "{out}", "--all={params}"]), "model.command[4]",
     "must be a whole argument"),
    (json.dumps([]), "model.command", "expected a non-empty list"),
])
def test_bad_commands_are_refused_before_anything_is_written(tmp_path, capsys, cmd, key, words):
    sweep = write_sweep(tmp_path, cmd=cmd)
    with pytest.raises(ConfigError) as err:
        load_sweep(sweep)
    assert err.value.key == key and words in str(err.value)
    out = tmp_path / "results"
    assert main(["run", str(sweep), "--out", str(out), "--executor", "serial", "--no-progress"]) == 2
    assert words in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("body, model_lines, key, words", [
    ('[[axes]]\nkey = "nosie"\nvalues = [0.1, 0.2]\n', "", "axes[0].key",
     "not a parameter of the command (did you mean 'noise'?)"),
    ('[[axes]]\nkey = "noise"\nvalues = [0.1, 7.5]\n', "", "noise", "allowed: 0 to 3 (bounds) (at design point noise=7.5)"),
    ('[[axes]]\nkey = "noise"\nvalues = [0.1, nan]\n', "", "noise", "expected a finite number"),
    ('[[axes]]\nkey = "fault"\nvalues = ["none", "rm -rf"]\n', "", "fault", "allowed: 'none', 'hang'"),
    ('[[axes]]\nkey = "n_agents"\nvalues = [10, 10.5]\n', "", "n_agents", "expected a whole number"),
    ("", 'preset = "../models/holland.toml"\n', "model.preset", "either a preset"),
    ("", "timeout_s = 0\n", "model.timeout_s", "expected seconds > 0"),
    ("", 'output = "../tracks.csv"\n', "model.output", "a file name (no folder)"),
])
def test_bad_parameters_and_values_are_refused(tmp_path, body, model_lines, key, words):
    sweep = write_sweep(tmp_path, body, model_lines.replace("timeout_s = 0\n", ""))
    if "timeout_s = 0" in model_lines:
        sweep.write_text(sweep.read_text().replace("timeout_s = 4", "timeout_s = 0"))
    with pytest.raises(ConfigError) as err:
        expand(load_sweep(sweep))
    assert err.value.key == key and words in str(err.value), str(err.value)


@pytest.mark.parametrize("change, key, words", [
    (("[run]\n", "[run]\nn = 30\n"), "run.n", "declare the simulator's own settings"),
    (("group_radius = 5.0", 'group_radius = "auto"'), "run.group_radius", "no perception range"),
    (("[run]\n", '[run]\nkeep = "trajectories"\n'), "run.keep", "metrics only"),
    (("n_agents = {", "n = {"), "model.parameters.n", "a column of the results"),
    (("n_agents = {", "seed = {"), "model.parameters.seed", "none of seed, out"),
    (("bounds = [0.0, 3.0]", "bounds = [3.0, 0.0]"), "model.parameters.noise.bounds", "low < high"),
    (('default = "none"', 'default = "boom"'), "model.parameters.fault.default", "allowed: 'none'"),
])
def test_bad_run_and_parameter_tables_are_refused(tmp_path, change, key, words):
    sweep = write_sweep(tmp_path, "", parameters=PARAMETERS.replace(*change))
    with pytest.raises(ConfigError) as err:
        load_sweep(sweep)
    assert err.value.key == key and words in str(err.value), str(err.value)


# ------------------------------------------------------------------------------------- the command

def test_arguments_are_a_list_with_checked_values_never_a_shell(tmp_path):
    sweep = write_sweep(tmp_path, '[[axes]]\nkey = "noise"\nvalues = [0.1, 2.5]\n',
                        cmd=json.dumps(f"{sys.executable} {FAULTY} --seed={{seed}} --out {{out}} {{params}} "
                                       "'; touch pwned' --n {n_agents}"))
    config = load_sweep(sweep)
    spec = expand(config)[1]
    argv = config.command.arguments(dict(spec.command.values), spec.seed, tmp_path / "o.csv", tmp_path)
    assert argv == [sys.executable, str(FAULTY), f"--seed={spec.seed}", "--out", str(tmp_path / "o.csv"),
                    "--n_agents", "12", "--noise", "2.5", "--duration", "4.0", "--fault", "none",
                    "; touch pwned", "--n", "12"]
    assert dict(spec.columns) == {"noise": 2.5}
    assert [s.seed for s in expand(config)] == [s.seed for s in expand(load_sweep(sweep))]


def test_parameter_files_hold_the_values(tmp_path):
    program = ("import json, shutil, sys, tomllib; p = json.load(open(sys.argv[1])); "
               "t = tomllib.load(open(sys.argv[2], 'rb')); assert p == t, (p, t); shutil.copy(sys.argv[1], sys.argv[3])")
    sweep = write_sweep(tmp_path, "", cmd=json.dumps([sys.executable, "-c", program, "{params_json}",
                                                      "{params_toml}", "{out}"]),
                        model_lines='output = "p.csv"\n')
    config = load_sweep(sweep)
    spec = expand(config)[0]
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    out = run_command(config.command, dict(spec.command.values), spec.seed, scratch)
    assert json.loads(out.read_text()) == {"n_agents": 12, "noise": 0.3, "duration": 4.0, "fault": "none"}


def test_run_ids_follow_the_script_and_the_values(tmp_path):
    script = tmp_path / "sim.py"
    script.write_text(EXAMPLE.read_text())
    text = f'[[axes]]\nkey = "noise"\nvalues = [0.1, 0.2]\n'
    sweep = write_sweep(tmp_path, text, cmd=json.dumps([sys.executable, "sim.py", "--out", "{out}", "{params}"]))
    first = [s.run_id for s in expand(load_sweep(sweep))]
    assert len(set(first)) == 2 and first == [s.run_id for s in expand(load_sweep(sweep))]
    script.write_text(EXAMPLE.read_text() + "\n# changed\n")
    assert set(first).isdisjoint(s.run_id for s in expand(load_sweep(sweep)))


def test_a_crash_keeps_the_end_of_stderr(tmp_path):
    config = load_sweep(write_sweep(tmp_path, ""))
    values = dict(expand(config)[0].command.values) | {"fault": "crash"}
    (tmp_path / "s").mkdir()
    with pytest.raises(CommandFailed, match=r"faulty_sim.py failed: exit status 3; stderr ends:\n"
                                            r"faulty_sim: injected crash\nTraceback: none, on purpose"):
        run_command(config.command, values, 1, tmp_path / "s")


def test_a_flood_on_stderr_is_read_through_a_bounded_tail(tmp_path):
    """64 MiB on stderr: the reason keeps its last lines, and reading it costs no more than a bounded
    buffer (the whole stream was read into memory before: 200 MiB took a run to 798 MB)."""
    import tracemalloc

    config = load_sweep(write_sweep(tmp_path, ""))
    values = dict(expand(config)[0].command.values) | {"fault": "flood"}
    (tmp_path / "s").mkdir()
    tracemalloc.start()
    try:
        with pytest.raises(CommandFailed) as err:
            run_command(config.command, values, 1, tmp_path / "s")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2 * TAIL_BYTES + (2 << 20), f"{peak:,} bytes held while reading the flood"
    assert str(err.value).startswith("faulty_sim.py failed: exit status 1; stderr ends (of 67,108,903 bytes):\n")
    assert str(err.value).endswith("\nfaulty_sim: the last line of the flood")
    assert len(str(err.value)) < 2200
    assert os.listdir(tmp_path / "s") == []   # nor written to disk


def test_a_command_that_exits_0_takes_its_background_children_with_it(tmp_path):
    """The whole process group ends with the run, whatever the command's exit status."""
    config = load_sweep(write_sweep(tmp_path, ""))
    values = dict(expand(config)[0].command.values) | {"fault": "daemon"}
    (tmp_path / "s").mkdir()
    assert run_command(config.command, values, 1, tmp_path / "s").is_file()
    deadline = time.monotonic() + 10   # SIGKILL has been sent: wait only for the kernel to finish the job
    while processes_with(DAEMON) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not processes_with(DAEMON), "the command's background child outlived the run"


def test_the_tail_keeps_the_last_bytes_of_any_stream():
    tail = Tail(limit=12)
    for k in range(1000):
        tail.add(f"line {k}\n".encode())
        assert len(tail.data) <= 2 * 12 + 9
    assert tail.total == sum(len(f"line {k}\n") for k in range(1000))
    assert tail.lines() == "line 999" and "stderr ends (of 8,890 bytes):\nline 999" in tail.said("stderr")
    tail.add(b"no newline")    # kept: "9\\nno newline", which starts inside a line: that piece is left out
    assert tail.lines() == "no newline"
    assert Tail().said("stderr") == ""


# ------------------------------------------------------------------------------------ whole sweeps

@pytest.mark.slow
def test_a_sweep_with_faults_records_them_and_completes_the_rest(tmp_path):
    sweep = write_sweep(tmp_path)
    out = tmp_path / "serial"
    result = run_sweep(load_sweep(sweep), None, out, executor="serial", progress=False)
    table = result.table.set_index(result.table["fault"].where(result.table["fault"] != "none",
                                                               "ok" + result.table["noise"].astype(str)))
    assert list(table["status"]) == ["ok", "ok", "ok", "failed", "failed", "failed"]
    assert table.loc["hang", "error"].startswith("flocksweep.sweeps.external.CommandFailed: timed out after 4 s "
                                                 "(model.timeout_s); killed; stderr ends:\nfaulty_sim: hanging")
    assert "MalformedOutput: the output tracks.csv is not tracks that can be measured: TrackError" in \
        table.loc["malformed", "error"]
    assert "no column for role 'id'" in table.loc["malformed", "error"]
    assert table.loc["crash", "error"] == ("flocksweep.sweeps.external.CommandFailed: faulty_sim.py failed: exit status 3; "
                                           "stderr ends:\nfaulty_sim: injected crash\nTraceback: none, on purpose")
    metrics = list(summary_columns(leadership=False))
    ok = table[table["status"] == "ok"]
    assert ok[metrics].columns.tolist() == metrics
    assert ok["polarization_mean"].between(0, 1).all() and ok["polarization_mean"].is_monotonic_decreasing
    assert ok["visible_mean_mean"].isna().all()   # nobody measures perception from tracks
    assert table.loc["crash", metrics].isna().all()
    assert not processes_with("faulty-sim-grandchild"), "the timed-out command's own child was left running"

    # each ok row is what `flocksweep measure` makes of that run's output: rerun the command by hand
    spec = [s for s in expand(load_sweep(sweep)) if dict(s.command.values)["noise"] == 0.5][0]
    (tmp_path / "by_hand").mkdir()
    path = run_command(spec.command.model, dict(spec.command.values), spec.seed, tmp_path / "by_hand")
    measured = measure_tracks(load_tracks(path, TrackSource(units={"length": "bl"})),
                              track_settings(5.0, warmup=1.0), velocity_interval=RECORDED)
    row = result.table.set_index("run_id").loc[spec.run_id]
    assert np.array_equal(row[metrics].to_numpy(float), measured.runs.iloc[0][metrics].to_numpy(float),
                          equal_nan=True)

    # resume: every run is found, ok or failed (kept), nothing is computed again
    again = run_sweep(load_sweep(sweep), None, out, executor="serial", progress=False)
    assert (len(again.plan.done), len(again.plan.failed), len(again.plan.todo)) == (3, 3, 0)
    assert_frame_equal(pd.read_parquet(out / "runs.parquet"), result.table)

    # the stored sweep names the folder the command runs in relative to the results: same runs, all found
    stored = load_sweep(out / "sweep.toml")
    assert [s.run_id for s in expand(stored)] == list(result.table["run_id"])
    assert json.loads((out / "model.json").read_text())["command"]["parameters"]["fault"]["choices"][1] == "hang"

    # the local executor (2 workers) gives the same rows, failures and reasons included
    local = tmp_path / "local"
    run_sweep(load_sweep(sweep), None, local, executor="local", workers=2, progress=False)
    assert_frame_equal(rows(local), rows(out), check_exact=True)
    series = [pd.read_parquet(p).sort_values(["run_id", "t"]).drop(columns="part", errors="ignore")
              .reset_index(drop=True) for p in (out / "timeseries", local / "timeseries")]
    assert_frame_equal(series[0], series[1], check_exact=True)


@pytest.mark.slow
def test_a_dask_cluster_gives_the_serial_rows(tmp_path):
    pytest.importorskip("dask.distributed")
    config = load_sweep(ROOT / "configs" / "external" / "vicsek.toml",
                        ["replicates=1", "model.parameters.duration.default=3.0"])
    run_sweep(config, None, tmp_path / "serial", executor="serial", progress=False)
    run_sweep(config, None, tmp_path / "dask", executor="dask", workers=2, progress=False)
    assert (rows(tmp_path / "dask")["status"] == "ok").all() and len(rows(tmp_path / "dask")) == 6
    assert_frame_equal(rows(tmp_path / "dask"), rows(tmp_path / "serial"), check_exact=True)


@pytest.mark.slow
def test_the_shipped_example_sweep_runs_from_the_command_line(tmp_path, capsys):
    sweep = ROOT / "configs" / "external" / "vicsek.toml"
    out = tmp_path / "vicsek"
    assert main(["run", str(sweep), "--out", str(out), "--executor", "serial", "--no-progress",
                 "--set", "replicates=1", "--set", "model.parameters.duration.default=4.0"]) == 0
    assert "6 runs, 6 ok, 0 failed" in capsys.readouterr().out
    table = pd.read_parquet(out / "runs.parquet")
    # more noise, less order, at either radius (3 levels, fixed seeds)
    for _, group in table.groupby("radius"):
        assert group.sort_values("noise")["polarization_mean"].is_monotonic_decreasing


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_a_command_dies_with_the_worker_that_started_it(tmp_path):
    """A worker killed outright (as the pool kills its workers on Ctrl-C) takes its command along (Linux)."""
    marker = f"external-orphan-{tmp_path.name}"
    sweep = write_sweep(tmp_path, "", cmd=json.dumps([sys.executable, "-c", "import time; time.sleep(600)",
                                                      "{out}", marker]))
    script = ("import sys; from pathlib import Path; from flocksweep.sweeps.config import load_sweep; "
              "from flocksweep.sweeps.external import run_command; c = load_sweep(sys.argv[1]).command; "
              "s = Path(sys.argv[2]); s.mkdir(); run_command(c, c.values({}), 1, s)")
    worker = subprocess.Popen([sys.executable, "-c", script, str(sweep), str(tmp_path / "scratch")],
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
    deadline = time.monotonic() + 60
    while not processes_with(marker) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert processes_with(marker), "the command never started"
    worker.kill()
    worker.wait()
    deadline = time.monotonic() + 10
    while processes_with(marker) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = processes_with(marker)
    for pid in left:   # this test's own orphans, so that a failure leaves nothing running
        os.kill(pid, signal.SIGKILL)
    assert not left


@pytest.mark.slow
def test_the_netlogo_wrapper_pattern(tmp_path):
    """configs/external/netlogo_flock.py drives a stand-in for netlogo-headless.sh (tests/sweeps/fake_netlogo.py:
    turtles marching one patch per tick, slowed by 0.1 x vision's fraction, across the edges of a wrapping
    world): the tracks come out unwrapped (no impossible speeds), and NetLogo's failure is the run's."""
    cmd = [sys.executable, str(ROOT / "configs" / "external" / "netlogo_flock.py"), "--netlogo",
           str(TESTS / "sweeps" / "fake_netlogo.py"), "--model", "Flocking.nlogo", "--seed", "{seed}",
           "--out", "{out}", "--scratch", "{scratch}", "--ticks", "40", "{params}"]
    parameters = ('\n[model.parameters]\npopulation = { default = 5, bounds = [1, 100], integer = true }\n'
                  'vision = { default = 3.0, bounds = [0.0, 10.0] }\n[run]\ngroup_radius = 3.0\nwarmup = 0.0\n')
    body = '[[axes]]\nkey = "vision"\nvalues = [1.0, 1.5]\n[[axes]]\nkey = "population"\nvalues = [6, 60]\n'
    sweep = write_sweep(tmp_path, body, cmd=json.dumps(cmd), parameters=parameters)
    table = run_sweep(load_sweep(sweep), None, tmp_path / "out", executor="serial", progress=False).table
    ok = table[table["population"] == 6].set_index("vision")
    assert list(ok["status"]) == ["ok", "ok"]
    assert ok["speed_mean_mean"].to_numpy() == pytest.approx([1.0, 0.95], abs=1e-9)
    assert ok["polarization_mean"].to_numpy() == pytest.approx([1.0, 1.0], abs=1e-12)
    failed = table[table["population"] == 60]
    assert (failed["status"] == "failed").all()
    assert failed["error"].str.endswith("netlogo_flock.py failed: exit status 1; stderr ends:\nfake netlogo: "
                                        "population too large\nnetlogo-headless failed with exit status 1").all()


def test_a_value_is_one_of_the_declared_choices():
    from flocksweep.sweeps.external import Parameter

    choice = Parameter(default=2, choices=(1, 2, "a", True))
    assert [repr(choice.check(v, "k")) for v in (2.0, True, 1, "a")] == ["2", "True", "1", "'a'"]
    for bad in (1.5, "A", False, None):
        with pytest.raises(ConfigError, match=r"k: got .*; allowed: 1, 2, 'a', True"):
            choice.check(bad, "k")


def test_reading_settings_added_later_leave_earlier_run_ids_as_they_were():
    """[model.tracks] hashes into a run's id; the track settings added with exact clocks, padding, trims
    and the burst rule enter it only when set, and where settings came from (origins) never does."""
    from flocksweep.sweeps.external import OutputTracks, _tracks_record
    record = _tracks_record(OutputTracks())
    assert sorted(record) == sorted(["columns", "units", "body_length", "max_speed", "bad_speeds", "format", "fps",
                                     "body_length_px", "layout", "interval", "velocity_interval", "max_gap"])
    assert _tracks_record(OutputTracks(trim="1:"))["trim"] == "1:"
