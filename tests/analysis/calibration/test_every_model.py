"""Every model calibrates with every method: a plug-in dynamics (examples/couzin_like.py) and an external
simulator run as a command (the shipped Vicsek-like configs/external/vicsek_sim.py), whose tracks are seen
through the calibration's [observation] block, as measured tracks are (a calibration file could not name a
command before)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.run import run_calibration
from flocksweep.analysis.calibration.simulator import summary_simulator
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT

SIMULATOR = ROOT / "configs" / "external" / "vicsek_sim.py"
PLUGIN = str(ROOT / "examples" / "couzin_like.toml")
METHODS = {"emcee": {"kind": "emcee", "n_sim": 4, "walkers": 4, "steps": 2},
           "optimize": {"kind": "optimize", "n_sim": 4, "popsize": 1, "maxiter": 1, "recheck": 4},
           "npe": {"kind": "npe", "simulations": 20, "heldout": 10, "draws": 200,
                   "flow": {"width": 8, "layers": 1, "max_epochs": 5, "patience": 2}}}
COMMAND = {"command": ["python", str(SIMULATOR), "--seed", "{seed}", "--out", "{out}", "{params}"],
           "output": "tracks.csv", "timeout_s": 60,
           "parameters": {"n_agents": {"default": 8, "bounds": [2, 200], "integer": True},
                          "noise": {"default": 0.3, "bounds": [0.0, 5.0]},
                          "duration": {"default": 2.0, "bounds": [1.0, 120.0]}},
           "tracks": {"units": {"length": "bl", "time": "s"}}}


def command_calibration(method: dict) -> dict:
    return {"name": "command", "seed": 2, "model": COMMAND, "run": {"group_radius": 5.0, "warmup": 0.5},
            "observation": {"interval": 0.2, "velocity_interval": 0.4, "detection_probability": 0.9,
                            "position_sd": 0.05},
            "parameters": {"noise": {"key": "noise", "prior": {"dist": "uniform", "low": 0.05, "high": 1.5}}},
            "targets": {"stats": ["polarization", "speed_mean"], "mean": [0.9, 1.9], "sd": [0.05, 0.1]},
            "method": method}


def plugin_calibration(method: dict) -> dict:
    return {"name": "plugin", "seed": 4, "model": {"preset": PLUGIN},
            "run": {"n": 8, "duration": 1.5, "record_interval": 0.5, "warmup": 0.5},
            "parameters": {"cruise": {"key": "plugin.cruise_speed", "prior": {"dist": "uniform", "low": 1.5,
                                                                               "high": 6.0}}},
            "targets": {"stats": ["speed_mean", "nn_distance"], "mean": [3.0, 1.5], "sd": [0.1, 0.2]},
            "method": method}


def test_a_command_model_is_validated_like_a_preset(tmp_path):
    config = calibration_from_dict(command_calibration(METHODS["emcee"]), ROOT)
    assert config.command is not None and config.preset is None and config.keys == ("noise",)
    bad = command_calibration(METHODS["emcee"])
    bad["parameters"]["noise"]["key"] = "noize"
    with pytest.raises(ConfigError, match=r"parameters.noise.key: 'noize' is not a parameter of the command"):
        calibration_from_dict(bad, ROOT)
    wide = command_calibration(METHODS["emcee"])
    wide["parameters"]["noise"]["prior"]["high"] = 9.0
    with pytest.raises(ConfigError, match=r"parameters.noise.prior: the prior's support \[0.05, 9\] reaches 9.0"):
        calibration_from_dict(wide, ROOT)
    preset_key = command_calibration(METHODS["emcee"])
    preset_key["run"]["n"] = 10
    with pytest.raises(ConfigError, match="run.n: sets a key of a model preset"):
        calibration_from_dict(preset_key, ROOT)


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_a_command_run_is_seen_through_the_observation_block_and_repeats_with_its_seed():
    config = calibration_from_dict(command_calibration(METHODS["emcee"]), ROOT)
    simulator = summary_simulator(config, n_sim=2)
    rows = simulator.simulate(np.array([0.3]), [11, 12])
    assert np.isfinite(rows).all() and rows.shape == (2, 2)
    assert np.array_equal(simulator.simulate(np.array([0.3]), [11, 12]), rows)          # a function of the seeds
    bare = calibration_from_dict({**command_calibration(METHODS["emcee"]), "observation": None}, ROOT)
    assert not np.array_equal(summary_simulator(bare, n_sim=2).simulate(np.array([0.3]), [11, 12]), rows)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["emcee", "optimize", "npe", "emulator"])
def test_a_command_model_calibrates_with_every_method(method, tmp_path):
    if method == "npe":
        pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    settings = METHODS.get(method)
    if method == "emulator":
        sweep = tmp_path / "sweep.toml"
        sweep.write_text(f'''name = "command_sweep"
seed = 3
replicates = 2
[model]
command = ["python", "{SIMULATOR}", "--seed", "{{seed}}", "--out", "{{out}}", "{{params}}"]
output = "tracks.csv"
[model.parameters]
n_agents = {{ default = 8, bounds = [2, 200], integer = true }}
noise = {{ default = 0.3, bounds = [0.0, 5.0] }}
duration = {{ default = 2.0, bounds = [1.0, 120.0] }}
[model.tracks]
units = {{ length = "bl", time = "s" }}
[run]
group_radius = 5.0
warmup = 0.5
[[axes]]
key = "noise"
values = [0.05, 0.5, 1.0, 1.5]
''')
        run_sweep(load_sweep(sweep), sweep.read_text(), tmp_path / "sweep", executor="serial", progress=False)
        settings = {"kind": "emulator", "results": str(tmp_path / "sweep"), "n_sim": 4, "walkers": 4, "steps": 20,
                    "confirm": 2}
        data = {**command_calibration(settings), "observation": None}
    else:
        data = command_calibration(settings)
    result = run_calibration(calibration_from_dict(data, ROOT), tmp_path / "out", progress=False, predictive_draws=3)
    report = json.loads((tmp_path / "out" / ("optimum.json" if method == "optimize" else "convergence.json")).read_text())
    assert report["verdict"] and report["accounting"]["simulations"]["total"] > 0
    assert (tmp_path / "out" / "report.html").is_file() and (tmp_path / "out" / "viewer_posterior_median.html").is_file()
    assert result.flock is not None


@pytest.mark.slow
@pytest.mark.parametrize("method", ["optimize", "npe"])
def test_a_plugin_dynamics_calibrates_with_the_other_methods(method, tmp_path):
    if method == "npe":
        pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")
    result = run_calibration(calibration_from_dict(plugin_calibration(METHODS[method]), ROOT), tmp_path / "out",
                             progress=False, predictive_draws=3)
    assert result.report["verdict"] and (tmp_path / "out" / "report.html").is_file()
