"""Simulation-based calibration of the emulator (analysis.calibration.sbc_emulator, `flocksweep sbc` on an
emulator file): the chain on the surrogate per dataset, the observed data from the real simulator, ranks
and report as BSL's; the same records with workers or in another order; a resume against another surrogate
refused; optimize still refused."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.cli import main
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")

SWEEP = f"""
name = "emu_sweep"
seed = 5
replicates = 3
[model]
preset = "{HOLLAND}"
[run]
n = 10
duration = 2.0
record_interval = 0.5
warmup = 0.5
[[axes]]
key = "perception.range"
values = [5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0]
"""

CALIBRATION = """
name = "emu_sbc"
seed = 4
[model]
preset = "{preset}"
[run]
n = 10
duration = 2.0
record_interval = 0.5
warmup = 0.5
[parameters.range]
key = "perception.range"
prior = {{ dist = "uniform", low = 5, high = 40 }}
[targets]
stats = ["cohesion", "polarization"]
mean = [0.95, 0.5]
sd = [0.05, 0.1]
[method]
kind = "emulator"
results = "{results}"
walkers = 8
steps = 120
"""


@pytest.fixture(scope="module")
def emulator_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("emu_sbc")
    (folder / "sweep.toml").write_text(SWEEP)
    assert main(["run", str(folder / "sweep.toml"), "--out", str(folder / "results"), "--executor", "serial",
                 "--no-progress"]) == 0
    path = folder / "cal.toml"
    path.write_text(CALIBRATION.format(preset=HOLLAND, results=folder / "results"))
    return path


def _records(out) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((out / "datasets").glob("*.json"))]


@pytest.mark.slow
def test_sbc_of_the_emulator_runs_its_chain_per_dataset_and_holds_whatever_the_workers(emulator_file, tmp_path, capsys):
    args = ["sbc", str(emulator_file), "--datasets", "6", "--draws", "19", "--no-progress"]
    assert main(args + ["--out", str(tmp_path / "one")]) == 0
    assert "rank_histogram.png" in capsys.readouterr().out        # the next step names the figures
    ranks = pd.read_csv(tmp_path / "one" / "ranks.csv")
    assert len(ranks) == 6 and ranks["rank_range"].between(0, 19).all()
    records = _records(tmp_path / "one")
    assert all(r["simulations"] == {"observed": 1, "total": 1} and r["walkers"] == 8 and r["steps"] == 120 for r in records)  # only y_j is run
    assert all(5.0 <= t[0] <= 40.0 for r in records for t in r["draws"])
    # the posterior follows the data: its mean tracks the truth across datasets (the surrogate is informative)
    truths = np.array([r["theta"][0] for r in records])
    means = np.array([r["post_mean"][0] for r in records])
    assert np.corrcoef(truths, means)[0, 1] > 0.5
    settings = json.loads((tmp_path / "one" / "settings.json").read_text())
    assert settings["likelihood"] == "emulated" and settings["problem"]["method"] == "emulator"
    assert main(args + ["--out", str(tmp_path / "two"), "--workers", "2"]) == 0
    assert _records(tmp_path / "two") == [{**r, "wall_s": s["wall_s"]} for r, s in
                                          zip(records, _records(tmp_path / "two"))]   # bit for bit but the clock
    capsys.readouterr()
    assert main(args + ["--out", str(tmp_path / "one"), "--set", 'method.surrogate="rbf"']) == 2
    assert "other settings" in capsys.readouterr().err           # another surrogate: not mixed into these ranks


def test_optimize_has_no_sbc_and_the_refusal_names_the_emulator(tmp_path, capsys):
    optimize = tmp_path / "optimize.toml"
    optimize.write_text(CALIBRATION.format(preset=HOLLAND, results=tmp_path).split("[method]")[0]
                        + '[method]\nkind = "optimize"\n')
    assert main(["sbc", str(optimize), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "'optimize'" in err and "emulator" in err and not (tmp_path / "x").exists()
