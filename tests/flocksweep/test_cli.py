"""End-to-end tests of `flocksweep simulate` on tiny runs."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from flocksweep.cli import main
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
PATTERN = str(ROOT / "configs/models/holland_pattern.toml")


def test_simulate_writes_trajectory_params_and_plot(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["simulate", PATTERN, "--n", "12", "--duration", "1", "--seed", "4", "--record-every", "6",
                 "--set", "perception.field_deg=200", "--out", str(out), "--plot"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "final polarization" in printed and "mean visible neighbours" in printed
    data = np.load(out / "trajectory.npz")
    assert data["pos"].shape == (11, 12, 3)          # 60 steps recorded every 6 -> 11 records
    assert data["vel"].shape == (11, 12, 3)
    assert data["visible"].shape == (11, 12)
    assert len(np.unique(data["pattern"])) > 1        # pattern mode assigns Table 1 patterns
    params = json.loads((out / "params.json").read_text())
    assert params["seed"] == 4
    assert params["preset"]["perception"]["field_deg"] == 200.0
    assert params["preset"]["init"]["n"] == 12
    assert params["provenance"]["model_version"]
    png = out / "traces.png"
    assert png.stat().st_size > 10_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob(".*tmp"))                # atomic writes leave no temporaries


def test_simulate_is_reproducible_through_the_cli(tmp_path):
    for name in ("a", "b"):
        assert main(["simulate", HOLLAND, "--n", "10", "--duration", "0.5", "--seed", "9",
                     "--out", str(tmp_path / name)]) == 0
    a, b = (np.load(tmp_path / name / "trajectory.npz") for name in ("a", "b"))
    for key in ("pos", "vel", "visible", "binocular"):
        assert np.array_equal(a[key], b[key])


def test_bad_key_is_a_clear_error_with_exit_status_2(capsys):
    code = main(["simulate", HOLLAND, "--set", "perception.feild_deg=90", "--duration", "0.1"])
    err = capsys.readouterr().err
    assert code == 2
    assert "perception.feild_deg" in err and "did you mean 'field_deg'" in err


def test_bad_value_names_key_value_and_allowed_range(capsys):
    assert main(["simulate", HOLLAND, "--set", "perception.field_deg=400"]) == 2
    err = capsys.readouterr().err
    assert "perception.field_deg" in err and "400" in err and "(0.0, 360.0]" in err


def test_missing_model_file_is_reported(capsys, tmp_path):
    assert main(["simulate", str(tmp_path / "nope.toml")]) == 2
    assert "not found" in capsys.readouterr().err


@pytest.mark.slow
def test_console_script_runs_in_a_fresh_process(tmp_path):
    exe = shutil.which("flocksweep")
    cmd = [exe] if exe else [sys.executable, "-m", "flocksweep.cli"]
    done = subprocess.run(cmd + ["simulate", HOLLAND, "--n", "8", "--duration", "0.5", "--plot"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    png = tmp_path / "results" / "simulate" / "holland-seed0" / "traces.png"
    assert png.stat().st_size > 10_000
    assert str(Path("results/simulate/holland-seed0/traces.png")) in done.stdout


HEAVY = ("pandas", "matplotlib", "pyarrow", "jinja2", "tqdm", "emcee", "SALib", "scipy.stats", "scipy.optimize",
         "scipy.spatial", "scipy.sparse", "flocksweep.analysis.viewer", "flocksweep.analysis.reports", "flocksweep.analysis.calibration",
         "multiprocessing", "flocksweep.sweeps.executors")


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_simulate_loads_only_what_it_needs(tmp_path):
    """`flocksweep simulate` (no --plot, no --tracks) imports none of the table, plotting, report, viewer or
    calibration libraries, nor the executors' process pools: a fresh process runs the command, then lists
    what it loaded. (numba itself
    imports scipy.linalg for its BLAS bindings, so scipy's other subpackages are what is checked.)"""
    code = ("import json, sys\nfrom flocksweep.cli import main\n"
            f"code = main(['simulate', {HOLLAND!r}, '--n', '3', '--duration', '0.016666666666666666'])\n"
            "print(json.dumps([code, sorted(sys.modules)]))\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    status, modules = json.loads(done.stdout.strip().splitlines()[-1])
    assert status == 0
    assert "flocksweep.simcore.kernel" in modules                       # it did simulate
    loaded = [m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY)]
    assert loaded == []


def test_help_lists_every_command_and_each_command_declares_its_arguments(capsys):
    from flocksweep.commands import ORDER as COMMANDS

    with pytest.raises(SystemExit):
        main(["--help"])
    listed = capsys.readouterr().out
    assert all(name in listed for name in COMMANDS)
    for name, option in (("view", "--animate"), ("measure", "--group-radius"), ("simulate", "--init-state")):
        with pytest.raises(SystemExit):
            main([name, "--help"])
        assert option in capsys.readouterr().out
