"""The emulator takes targets measured by an observer too: it measures its sweep's kept trajectories through
the calibration's [observation] block, exactly as the calibration's own runs are measured (the emulator
refused the block before)."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.run import run_calibration
from flocksweep.analysis.calibration.simulator import summary_simulator
from flocksweep.analysis.calibration.training import observed_summaries, training_set
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.config import load_sweep
from flocksweep.sweeps.results import load_results
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT

HOLLAND = str(ROOT / "configs" / "models" / "holland.toml")
SWEEP = f'''name = "kept"
seed = 5
replicates = 2
[model]
preset = "{HOLLAND}"
set = {{ "init.radius" = 6.0 }}
[run]
n = 8
duration = 2.0
record_interval = 0.5
warmup = 0.5
keep = "{{keep}}"
trajectory_every = 6
[[axes]]
key = "perception.field_deg"
values = [120.0, 200.0, 280.0]
'''


def sweep(folder, keep: str):
    path = folder / f"{keep}.toml"
    path.write_text(SWEEP.replace("{keep}", keep))
    run_sweep(load_sweep(path), path.read_text(), folder / keep, executor="serial", progress=False)
    return folder / keep


def calibration(results) -> dict:
    return {"name": "emu_obs", "seed": 4, "model": {"preset": HOLLAND, "set": {"init.radius": 6.0}},
            "run": {"n": 8, "duration": 2.0, "warmup": 0.5, "group_radius": 20.0},
            "observation": {"interval": 0.2, "velocity_interval": 0.4, "detection_probability": 0.9,
                            "position_sd": 0.05},
            "parameters": {"field": {"key": "perception.field_deg", "prior": {"dist": "uniform", "low": 120,
                                                                               "high": 280}}},
            "targets": {"stats": ["polarization", "nn_distance"], "mean": [0.7, 4.0], "sd": [0.1, 0.5]},
            "method": {"kind": "emulator", "results": str(results), "n_sim": 4, "walkers": 4, "steps": 20,
                       "confirm": 2}}


@pytest.mark.slow
def test_the_emulator_measures_the_sweeps_trajectories_as_the_calibration_measures_its_runs(tmp_path):
    results = sweep(tmp_path, "trajectories")
    config = calibration_from_dict(calibration(results), ROOT)
    runs = load_results(results).ok.head(3)
    rows = observed_summaries(config, runs, ["perception.field_deg"], results)
    simulator = summary_simulator(config, n_sim=1)
    for i, (theta, seed) in enumerate(zip(runs["perception.field_deg"], runs["seed"])):
        assert np.array_equal(rows[i], simulator.simulate(np.array([theta]), [int(seed)])[0])
    assert not np.array_equal(rows[:, 0], runs["polarization_mean"].to_numpy())     # not the sweep's own measure
    assert training_set(results, config).count.sum() == 6
    outcome = run_calibration(config, tmp_path / "out", progress=False, predictive_draws=4)
    assert outcome.report["verdict"] and outcome.report["transforms"] is None        # the emulator's own scale


@pytest.mark.slow
def test_a_sweep_without_trajectories_is_refused_saying_how_to_keep_them(tmp_path):
    results = sweep(tmp_path, "metrics")
    with pytest.raises(ConfigError, match='kept no trajectories.*keep = "trajectories"'):
        training_set(results, calibration_from_dict(calibration(results), ROOT))
