"""The one trajectory file: what ``flocksweep simulate --out`` and a sweep's ``keep = "trajectories"`` write
(the same fields, by one function), read back by one function, files of the earlier writers included."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.viewer.track import from_npz
from flocksweep.observables.summary import every_nth
from flocksweep.simcore.simulate import Observations
from flocksweep.sweeps.trajectory import OPTIONAL, REQUIRED, read_trajectory, write_trajectory


def observations(records: int = 5, n: int = 3, agents: bool = True) -> Observations:
    rng = np.random.default_rng(7)
    pos = rng.normal(size=(records, n, 3))
    visible = rng.integers(0, n, size=(records, n)).astype(np.int32)
    leader = np.zeros((records, n), bool)
    leader[2, 1] = True
    predator = rng.normal(size=(records, 3)) if agents else None
    if agents:
        predator[0] = np.nan   # not there yet
    return Observations(times=np.arange(records) * 0.5, pos=pos, vel=rng.normal(size=(records, n, 3)),
                        visible=visible, binocular=visible // 2, leader=leader, triggers=np.zeros((0, 2), np.int64),
                        pattern=np.arange(n, dtype=np.uint32), final=None, dt=0.25, record_every=2,
                        predator=predator, prey=None)


def test_a_trajectory_reads_back_exactly_every_field_it_was_written_with(tmp_path):
    obs = observations()
    data = read_trajectory(write_trajectory(tmp_path / "t.npz", obs, 2 ** 63 - 1))
    assert set(data) == set(REQUIRED + OPTIONAL)
    for name in ("times", "pos", "vel", "visible", "binocular", "leader", "pattern", "predator"):
        np.testing.assert_array_equal(data[name], getattr(obs, name))
        assert data[name].dtype == getattr(obs, name).dtype
    assert int(data["seed"]) == 2 ** 63 - 1 and data["prey"] is None


def test_every_kth_record_thins_every_per_record_field_alike(tmp_path):
    obs = observations(records=7)
    data = read_trajectory(write_trajectory(tmp_path / "t.npz", every_nth(obs, 3), 5))
    assert data["times"].tolist() == [0.0, 1.5, 3.0]
    for name in ("pos", "vel", "visible", "binocular", "leader", "predator"):
        np.testing.assert_array_equal(data[name], getattr(obs, name)[::3])


def test_a_seed_that_is_not_a_64_bit_integer_is_left_out(tmp_path):
    assert read_trajectory(write_trajectory(tmp_path / "big.npz", observations(), 2 ** 70))["seed"] is None
    assert read_trajectory(write_trajectory(tmp_path / "tuple.npz", observations(), (3, 4)))["seed"].tolist() == [3, 4]


def test_files_of_the_earlier_writers_are_read_with_the_fields_they_have(tmp_path):
    """The sweep worker wrote times, pos, vel, pattern, seed (+ agents); ``flocksweep simulate`` wrote times,
    pos, vel, visible, binocular, pattern (+ agents)."""
    obs = observations(agents=True)
    sweep_file, simulate_file = tmp_path / "sweep.npz", tmp_path / "simulate.npz"
    np.savez_compressed(sweep_file, times=obs.times, pos=obs.pos, vel=obs.vel, pattern=obs.pattern, seed=9,
                        predator=obs.predator)
    np.savez_compressed(simulate_file, times=obs.times, pos=obs.pos, vel=obs.vel, visible=obs.visible,
                        binocular=obs.binocular, pattern=obs.pattern, predator=obs.predator)
    old_sweep, old_simulate = read_trajectory(sweep_file), read_trajectory(simulate_file)
    assert old_sweep["visible"] is None and old_sweep["leader"] is None and int(old_sweep["seed"]) == 9
    assert old_simulate["seed"] is None and old_simulate["leader"] is None
    np.testing.assert_array_equal(old_simulate["binocular"], obs.binocular)
    for path in (sweep_file, simulate_file):
        track = from_npz(path)
        np.testing.assert_array_equal(track.pos, obs.pos)
        assert [a["kind"] for a in track.agents] == ["predator"] and track.leader is None
    assert from_npz(sweep_file).info["seed"] == 9 and from_npz(sweep_file).visible is None
    new = from_npz(write_trajectory(tmp_path / "new.npz", obs, 9))
    np.testing.assert_array_equal(new.visible, obs.visible)
    np.testing.assert_array_equal(new.leader, obs.leader)


def test_a_file_without_the_required_arrays_is_refused_naming_them(tmp_path):
    np.savez(tmp_path / "x.npz", times=np.zeros(2))
    with pytest.raises(ValueError, match="missing pos, vel"):
        read_trajectory(tmp_path / "x.npz")
    with pytest.raises(FileNotFoundError, match="no such trajectory file"):
        read_trajectory(tmp_path / "none.npz")
