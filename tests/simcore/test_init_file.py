"""Initial state from a file: ``init.from_file`` and ``flocksweep simulate --init-state`` (simcore/initfile.py).

A run from a file starts from exactly the file's state, the file's content is part of the run's identity,
the boid count comes from the file, bad files are clear config errors, and presets without the key keep
their resolved form (so no existing run id changed).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import unit_vectors
from paths import ROOT
from flocksweep.simcore import ConfigError, advance, load_preset, simulate_preset
from flocksweep.simcore.params import preset_from_dict
from flocksweep.simcore.rng import run_streams
from flocksweep.simcore.state import State
from flocksweep.cli import main

OPENSTEER = ROOT / "configs" / "models" / "opensteer.toml"
PATTERN = ROOT / "configs" / "models" / "holland_pattern.toml"


def write_state(path, n=30, seed=0, **extra):
    rng = np.random.default_rng(seed)
    fwd = unit_vectors(rng, n)
    arrays = dict(pos=rng.normal(scale=4.0, size=(n, 3)), fwd=fwd, speed=rng.uniform(0.0, 6.0, n))
    arrays.update(extra)
    np.savez(path, **arrays)
    return arrays


def preset_with(path, *overrides):
    return load_preset(OPENSTEER, [f"init.from_file={json.dumps(str(path))}", *overrides])


def test_run_starts_from_the_file_state_exactly(tmp_path):
    arrays = write_state(tmp_path / "s.npz")
    preset = preset_with(tmp_path / "s.npz", "init.n=30", "run.duration=0.5")
    obs = simulate_preset(preset, seed=3, record_every=1)
    assert np.array_equal(obs.pos[0], arrays["pos"])
    assert np.array_equal(obs.vel[0], arrays["fwd"] * arrays["speed"][:, None])
    # the same as advancing that state by hand (frame from the heading, as a random start builds it)
    from flocksweep.simcore.state import frame_from_forward
    up, side = frame_from_forward(arrays["fwd"])
    state = State(pos=arrays["pos"], vel=arrays["fwd"] * arrays["speed"][:, None], fwd=arrays["fwd"], up=up,
                  side=side, acc=np.zeros((30, 3)), pattern=np.zeros(30, np.uint32))
    by_hand = advance(preset.model, state, preset.run.n_steps, preset.run.dt, 1, run_streams(3)[1])
    assert np.array_equal(obs.final.pos, by_hand.final.pos)
    assert np.array_equal(obs.final.up, by_hand.final.up)


def test_up_and_acceleration_are_used_as_given(tmp_path):
    rng = np.random.default_rng(1)
    fwd = unit_vectors(rng, 10)
    up = np.cross(fwd, unit_vectors(rng, 10))
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    acc = rng.normal(size=(10, 3))
    write_state(tmp_path / "s.npz", n=10, fwd=fwd, up=up, acc=acc)
    preset = preset_with(tmp_path / "s.npz", "init.n=10", "run.duration=0.016666666666666666")
    from flocksweep.simcore.state import initial_state
    state = initial_state(preset.init, preset.model.patterns, np.random.default_rng(0))
    assert np.array_equal(state.up, up) and np.array_equal(state.acc, acc) and np.array_equal(state.fwd, fwd)
    np.testing.assert_allclose(state.side, np.cross(fwd, up) / np.linalg.norm(np.cross(fwd, up), axis=1)[:, None])


def test_boid_count_comes_from_the_file_and_must_agree(tmp_path):
    write_state(tmp_path / "s.npz", n=30)
    preset = preset_from_dict({"init": {"from_file": str(tmp_path / "s.npz")}})
    assert preset.init.n == 30
    with pytest.raises(ConfigError, match=r"init.n: got 100.*holds 30 boids"):
        preset_with(tmp_path / "s.npz")  # the preset file says n = 100


def test_file_content_is_part_of_the_identity(tmp_path):
    path = tmp_path / "s.npz"
    write_state(path, seed=0)
    first = preset_with(path, "init.n=30").to_dict()
    assert first["init"]["from_file_sha256"] and "radius" not in first["init"]
    write_state(path, seed=1)
    second = preset_with(path, "init.n=30").to_dict()
    assert first != second
    with pytest.raises(ConfigError, match="changed since"):
        preset_from_dict(first)  # a stored spec whose file changed
    assert preset_from_dict(second).to_dict() == second


def test_presets_without_the_key_keep_their_resolved_init():
    for name in ("opensteer", "holland", "hartman_benes", "holland_pattern", "topological", "opensteer_plugin"):
        init = load_preset(ROOT / "configs" / "models" / f"{name}.toml").to_dict()["init"]
        assert set(init) == {"n", "radius", "speed", "scale_with_n"}, name


def test_patterns_come_from_the_file_in_pattern_mode(tmp_path):
    pattern = np.arange(30) % 256
    write_state(tmp_path / "s.npz", pattern=pattern)
    preset = load_preset(PATTERN, [f"init.from_file={json.dumps(str(tmp_path / 's.npz'))}", "init.n=30",
                                   "run.duration=0.1"])
    assert np.array_equal(simulate_preset(preset, 0).pattern, pattern)
    write_state(tmp_path / "wide.npz", pattern=np.full(30, 1 << 9))
    wide = load_preset(PATTERN, [f"init.from_file={json.dumps(str(tmp_path / 'wide.npz'))}", "init.n=30",
                                 "run.duration=0.1"])
    with pytest.raises(ConfigError, match="8 bits"):
        simulate_preset(wide, 0)


@pytest.mark.parametrize("arrays, message", [
    (dict(pos=np.zeros((5, 2)), vel=np.ones((5, 3))), r"'pos' has shape \(5, 2\); expected \(N, 3\)"),
    (dict(vel=np.ones((5, 3))), "no 'pos' array"),
    (dict(pos=np.zeros((5, 3))), "no velocities"),
    (dict(pos=np.zeros((5, 3)), vel=np.ones((4, 3))), r"'vel' has shape \(4, 3\); expected \(5, 3\)"),
    (dict(pos=np.zeros((5, 3)), vel=np.ones((5, 3)), fwd=np.ones((5, 3))), "either 'vel' or 'fwd'"),
    (dict(pos=np.zeros((5, 3)), vel=np.zeros((5, 3))), "zero velocity"),
    (dict(pos=np.zeros((5, 3)), fwd=np.ones((5, 3)), speed=np.ones(5)), "expected unit vectors"),
    (dict(pos=np.full((5, 3), np.nan), vel=np.ones((5, 3))), "non-finite"),
    (dict(pos=np.zeros((5, 3)), vel=np.ones((5, 3)), colour=np.ones(5)), "unknown arrays"),
    (dict(pos=np.zeros((5, 3)), fwd=np.tile([1.0, 0, 0], (5, 1)), speed=np.ones(5), up=np.tile([1.0, 0, 0], (5, 1))),
     "not orthogonal"),
])
def test_bad_files_are_config_errors_naming_the_problem(tmp_path, arrays, message):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(ConfigError, match=message) as err:
        preset_from_dict({"init": {"from_file": str(path)}})
    assert err.value.key == "init.from_file"


def test_missing_or_unreadable_file(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        preset_from_dict({"init": {"from_file": str(tmp_path / "nope.npz")}})
    (tmp_path / "text.npz").write_text("not an archive")
    with pytest.raises(ConfigError, match="not a readable .npz"):
        preset_from_dict({"init": {"from_file": str(tmp_path / "text.npz")}})


def test_cli_continues_a_run_from_its_trajectory(tmp_path, capsys):
    first = tmp_path / "first"
    assert main(["simulate", str(OPENSTEER), "--n", "12", "--duration", "0.5", "--record-every", "5",
                 "--out", str(first)]) == 0
    second = tmp_path / "second"
    assert main(["simulate", str(OPENSTEER), "--init-state", str(first / "trajectory.npz"), "--duration", "0.1",
                 "--out", str(second)]) == 0
    a, b = np.load(first / "trajectory.npz"), np.load(second / "trajectory.npz")
    assert b["pos"].shape[1] == 12                      # init.n taken from the file
    assert np.array_equal(b["pos"][0], a["pos"][-1])     # the last record is the new start
    assert np.array_equal(b["vel"][0], a["vel"][-1])
    params = json.loads((second / "params.json").read_text())
    assert params["preset"]["init"]["from_file"].endswith("trajectory.npz")


def test_cli_reports_a_bad_init_state(tmp_path, capsys):
    assert main(["simulate", str(OPENSTEER), "--init-state", str(tmp_path / "missing.npz")]) == 2
    assert "init.from_file" in capsys.readouterr().err
