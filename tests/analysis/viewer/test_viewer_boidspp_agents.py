"""Boids++ agents travel with a run: ``flocksweep simulate`` stores the predator's and the prey's
recorded positions in trajectory.npz, and the viewer's reader turns them into agents."""
from __future__ import annotations

import numpy as np

from flocksweep.analysis.viewer.track import from_npz, from_observations, recorded_agents
from flocksweep.simcore import load_preset, simulate_preset
from flocksweep.cli import main
from paths import ROOT

PREDATOR = str(ROOT / "configs/models/boidspp_predator.toml")
PREY = ROOT / "configs/models/boidspp.toml"


def test_simulate_stores_the_predator_and_the_viewer_reads_it(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["simulate", PREDATOR, "--n", "20", "--duration", "1", "--seed", "3", "--record-every", "6",
                 "--set", "boidspp.predator.start_s=0.5", "--set", "boidspp.predator.leave_s=0.8", "--out", str(out)])
    assert code == 0
    data = np.load(out / "trajectory.npz")
    assert "prey" not in data.files
    predator = data["predator"]
    assert predator.shape == (11, 3)                  # 60 steps recorded every 6
    assert np.isnan(predator[:5]).all() and np.isfinite(predator[5:]).all()   # appears at step 30 = record 5
    track = from_npz(out / "trajectory.npz")
    (agent,) = track.agents
    assert agent["kind"] == "predator" and agent["label"] == "predator (ghosted until t = 0.5 s)"
    assert agent["appears_s"] == data["times"][5]     # drawn ghosted before it, where it first appears
    assert agent["pos"].shape == (11, 1, 3)           # (frames, agents of this kind, 3), as the encoder takes
    path = agent["pos"][:, 0]
    assert np.array_equal(path[5:], predator[5:]) and np.array_equal(path[:5], predator[[5] * 5])


def test_observations_with_a_prey_give_a_prey_agent_and_plain_runs_none():
    preset = load_preset(PREY, ["init.n=12", "run.duration=0.5"])
    obs = simulate_preset(preset, seed=1, record_every=5)
    assert obs.predator is None and obs.prey.shape == (7, 3) and np.isfinite(obs.prey).all()
    kinds = [a["kind"] for a in from_observations(obs, preset).agents]
    assert kinds == ["prey"]
    assert recorded_agents(np.full((4, 3), np.nan), None) == ()
