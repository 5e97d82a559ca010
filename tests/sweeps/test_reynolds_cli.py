"""`flocksweep simulate` runs the reynolds87 obstacle-course preset end to end (tiny run)."""
from __future__ import annotations

import numpy as np

from paths import ROOT
from flocksweep.cli import main

COURSE = str(ROOT / "configs/models/reynolds87_obstacles.toml")


def test_simulate_the_obstacle_course(tmp_path, capsys):
    code = main(["simulate", COURSE, "--n", "20", "--duration", "1", "--seed", "3", "--record-every", "6",
                 "--out", str(tmp_path)])
    assert code == 0
    assert "reynolds87_obstacles: N=20" in capsys.readouterr().out
    with np.load(tmp_path / "trajectory.npz") as data:
        assert data["pos"].shape == (11, 20, 3) and np.isfinite(data["pos"]).all()
