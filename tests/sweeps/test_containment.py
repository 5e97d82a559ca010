"""Plug-ins and runs contained (docs/errors.md, "Runs that fail"; sweeps.sandbox, sweeps.worker,
sweeps.plugin_check): a plug-in whose steer does not compile is one message naming its file and line
before anything is written or compiled; a NaN force is a failed run naming the step and boid; an
out-of-bounds write (SIGSEGV) and an endless loop are failed runs under --workers 1 and serial (the
runner lives on, the sweep completes, exit 0); ``run.timeout_s`` limits every run (built-in ones too) and
is not part of any run id. ``flocksweep simulate`` of the same plug-ins: one message, exit 6.
The plug-ins are tests/faulty_plugin.py (the fault a parameter) and tests/broken_plugin.py."""
from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest

from faults import FAULTY_PRESET, FAULTY_SWEEP   # the fault battery's plug-in files (tests/faults.py)
from paths import ROOT
from flocksweep.cli import main
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.design import expand

HOLLAND = ROOT / "configs" / "models" / "holland.toml"


def write(folder, module="faulty_plugin", faults="[0, 1, 2, 3]", run="timeout_s = 3", key="plugin.fault"):
    (folder / "faulty.toml").write_text(FAULTY_PRESET.format(module=module))
    path = folder / "contained.toml"
    path.write_text(FAULTY_SWEEP.format(values=faults, run=run, key=key))
    return path


def rows(out) -> pd.DataFrame:
    return pd.read_parquet(out / "runs.parquet").set_index("plugin.fault")


def test_a_plugin_that_does_not_compile_is_one_message_naming_its_line(tmp_path, capsys):
    """Before: numba's traceback, after the first compile of the whole run loop (40-50 s)."""
    sweep = write(tmp_path, module="broken_plugin", faults="[5.0, 6.0]", run="", key="init.radius")
    out = tmp_path / "out"
    assert main(["run", str(sweep), "--out", str(out), "--workers", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "dynamics: plug-in 'broken_plugin' does not compile: " in err and "broken_plugin.py, line 15 " \
           "(return (nbrs.nonexistent[0], 0.0, 0.0)): Unknown attribute 'nonexistent' of type Neighbours(...)" in err
    assert "compiling the simulation kernels" not in err   # refused before the run loop's compile
    assert not out.exists()
    (tmp_path / "one.toml").write_text(FAULTY_PRESET.format(module="broken_plugin"))
    assert main(["simulate", str(tmp_path / "one.toml")]) == 2
    assert "broken_plugin.py, line 15" in capsys.readouterr().err


@pytest.mark.slow
def test_every_plugin_fault_is_a_failed_run_and_the_sweep_completes(tmp_path, capsys):
    """--workers 1 (the runner's own process before: SIGSEGV killed it, the loop hung it for ever)."""
    sweep = write(tmp_path)
    out = tmp_path / "out"
    started = time.monotonic()
    assert main(["run", str(sweep), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    elapsed = time.monotonic() - started
    captured = capsys.readouterr()
    assert "4 runs, 1 ok, 3 failed" in captured.out and "Traceback" not in captured.err
    table = rows(out)
    assert table.loc[0, "status"] == "ok" and np.isfinite(table.loc[0, "cohesion_mean"])
    assert table.loc[1, "error"] == (
        "flocksweep.observables.summary.NonFiniteState: non-finite state: boid 2's velocity became NaN in step 3 "
        "(t = 0.15 to 0.2 s); a steering force that is not finite: the plug-in's steer returned NaN or inf, or a "
        "force so large that the motion overflowed")
    assert table.loc[2, "error"].startswith("flocksweep.sweeps.sandbox.TaskCrashed: the run crashed: its process "
                                            "died (killed by SIGSEGV) in compiled code: for a plug-in")
    assert table.loc[3, "error"].startswith("flocksweep.sweeps.sandbox.TaskTimedOut: the run was still going after "
                                            "3 s (run.timeout_s): stopped")
    assert table.loc[3, "wall_s"] >= 3.0 and elapsed < 600   # its accounting: the time it was given
    assert np.isfinite(table.loc[1, "sim_s"])   # it failed after its simulation: that time is kept
    assert main(["status", str(out)]) == 0 and "4 runs: 1 done, 3 failed, 0 missing" in capsys.readouterr().out

    # the same faults from flocksweep simulate: one message each, exit 6, nothing written
    for fault, words in ((1, "boid 2's velocity became NaN in step 3"), (2, "killed by SIGSEGV")):
        assert main(["simulate", str(tmp_path / "faulty.toml"), "--set", f"plugin.fault={fault}",
                     "--record-every", "4", "--out", str(tmp_path / f"single{fault}")]) == 6
        err = capsys.readouterr().err
        assert err.startswith("flocksweep: the simulation failed: ") and words in err and err.count("\n") == 1
        assert not (tmp_path / f"single{fault}").exists()
    # a dry run times its pilots in the sandbox too: the crash is reported, the runner lives on
    (tmp_path / "dry").mkdir()
    dry = write(tmp_path / "dry", faults="[2]")
    assert main(["run", str(dry), "--out", str(tmp_path / "dry" / "out"), "--dry-run"]) == 0
    out_text = capsys.readouterr().out
    assert "estimated wall time: unknown: a pilot run failed (TaskCrashed: its process died (killed by SIGSEGV))" \
        in out_text


def test_run_timeout_s_is_not_part_of_any_run_id(tmp_path):
    """Determinism and identity: a limit changes nothing a run computes, so no id changes with it."""
    base = tmp_path / "s.toml"
    text = (f'name = "ids"\nseed = 1\n[model]\npreset = "{HOLLAND}"\n[run]\nn = 5\nduration = 1.0\n'
            f'record_interval = 0.5\nwarmup = 0.5\n{{limit}}[[axes]]\nkey = "perception.field_deg"\n'
            f'values = [90, 180]\n')
    base.write_text(text.format(limit=""))
    limited = tmp_path / "limited.toml"
    limited.write_text(text.format(limit="timeout_s = 30\n"))
    plain, timed = expand(load_sweep(base)), expand(load_sweep(limited))
    assert [s.run_id for s in plain] == [s.run_id for s in timed]
    assert {s.timeout_s for s in plain} == {None} and {s.timeout_s for s in timed} == {30.0}


@pytest.mark.parametrize("value, words", [(0, "must be a finite number > 0"), (-1, "must be a finite number > 0"),
                                          ("inf", "must be a finite number > 0"), ('"soon"', "timeout_s")])
def test_a_bad_timeout_is_refused_naming_the_key(tmp_path, capsys, value, words):
    path = tmp_path / "s.toml"
    path.write_text(f'name = "t"\n[model]\npreset = "{HOLLAND}"\n[run]\ntimeout_s = {value}\n')
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "run.timeout_s" in err and words in err and not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_built_in_run_over_its_limit_is_stopped_and_the_rest_are_bit_identical(tmp_path, capsys):
    """run.timeout_s holds for every run, not only plug-ins': a run of minutes is stopped at 2 s, and the
    runs that finish in the child process equal those computed in the runner itself, bit for bit."""
    text = (f'name = "limited"\nseed = 3\n[model]\npreset = "{HOLLAND}"\n[run]\nrecord_interval = 0.5\n'
            'warmup = 0.5\n{limit}[[axes]]\nkeys = ["init.n", "run.duration"]\nvalues = {values}\n')
    short = "[[6, 2.0], [8, 2.0]"
    (tmp_path / "plain.toml").write_text(text.format(limit="", values=short + "]"))
    (tmp_path / "limited.toml").write_text(text.format(limit="timeout_s = 2\n", values=short + ", [400, 600.0]]"))
    for name in ("plain", "limited"):
        assert main(["run", str(tmp_path / f"{name}.toml"), "--out", str(tmp_path / name), "--executor", "serial",
                     "--no-progress"]) == 0
    capsys.readouterr()
    limited = pd.read_parquet(tmp_path / "limited" / "runs.parquet")
    long_run = limited[limited["index"] == limited["index"].max()].iloc[0]
    assert long_run["status"] == "failed" and "TaskTimedOut: the run was still going after 2 s" in long_run["error"]
    plain = pd.read_parquet(tmp_path / "plain" / "runs.parquet")
    finished = limited[limited["status"] == "ok"].drop(columns=["wall_s", "sim_s", "part"]).reset_index(drop=True)
    pd.testing.assert_frame_equal(finished, plain.drop(columns=["wall_s", "sim_s", "part"]), check_exact=True)
