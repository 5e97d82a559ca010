"""SBC of the npe method (analysis.calibration.sbc_npe): the tiny npe calibration end to end through
``flocksweep sbc`` (the estimator trained once, then reused), identical ranks for the same file and seed
whatever the order, a resume that redoes only the missing datasets, and the refusals (a method without
SBC, a chain's options, sequential rounds) naming what is allowed."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")

from flocksweep.analysis.calibration import methods, sbc  # noqa: E402
from flocksweep.analysis.calibration.config import load_calibration  # noqa: E402
from flocksweep.analysis.calibration.sbc_npe import draw_seed  # noqa: E402
from flocksweep.cli import main  # noqa: E402
from flocksweep.sweeps.seeds import SBCStream  # noqa: E402
from npe_tiny import CALIBRATION  # noqa: E402

DATASETS, DRAWS = 10, 9


def records(out) -> dict:
    """Per-dataset records without their wall time (the only field allowed to differ between runs)."""
    found = {}
    for path in sorted((out / "datasets").glob("*.json")):
        record = json.loads(path.read_text())
        record.pop("wall_s")
        found[path.name] = record
    return found


@pytest.mark.slow    # trains the tiny estimator twice (about 10 s each after the kernels are compiled)
def test_npe_sbc_trains_once_ranks_deterministically_and_resumes(tmp_path, capsys):
    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION)
    out = tmp_path / "sbc"
    args = ["sbc", str(path), "--datasets", str(DATASETS), "--draws", str(DRAWS), "--out", str(out), "--no-progress"]
    assert main(args) == 0
    said = capsys.readouterr().out
    assert "field" in said and "miscalibration" in said and "wrote" in said
    for name in ("ranks.csv", "uniformity.csv", "uniformity.md", "rank_histogram.png", "ecdf_diff.png", "summary.json",
                 "estimator/identity.json"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["datasets"] == DATASETS and summary["draws"] == DRAWS
    assert summary["simulations"] == {"observed": DATASETS, "total": DATASETS}   # one flock per dataset, no chain
    assert "tau_max_median" not in summary and summary["outside_support_datasets"] >= 0
    ranks = pd.read_csv(out / "ranks.csv", index_col=0)
    assert ranks["rank_field"].between(0, DRAWS).all() and ranks["theta_field"].between(60, 300).all()

    # each dataset: theta and y from the SBC streams (as BSL's), DRAWS draws inside the prior, its rank among them
    config = load_calibration(path)
    first = json.loads((out / "datasets" / "000003.json").read_text())
    theta = config.prior.sample(sbc.generator(config.seed, 3, SBCStream.THETA), 1)[0]
    assert np.array_equal(first["theta"], theta) and first["draw_seed"] == draw_seed(config.seed, 3)
    draws = np.asarray(first["draws"])
    assert draws.shape == (DRAWS, 1) and ((draws >= 60) & (draws <= 300)).all()
    below = int((draws[:, 0] < theta[0]).sum())
    assert first["ranks"] == [below]                                 # no ties among continuous draws

    # the same file and seed, another folder, datasets in reverse order: identical records (training again)
    again = methods.run_sbc(config, datasets=DATASETS, draws=DRAWS, out_dir=tmp_path / "again", progress=False,
                        order=list(range(DATASETS))[::-1])
    assert not again["estimator"]["reused"] and again["estimator"]["simulations"]["training"] == 60
    assert records(out) == records(tmp_path / "again")

    # a resume redoes only the missing dataset, with the estimator found again by its identity
    kept = records(out)
    (out / "datasets" / "000005.json").unlink()
    shutil.rmtree(out / "training")                                  # the reused estimator needs no training run
    resumed = methods.run_sbc(config, datasets=DATASETS, draws=DRAWS, out_dir=out, progress=False)
    assert resumed["estimator"]["reused"] and "training" not in resumed["estimator"]["simulations"]
    assert records(out) == kept
    pd.testing.assert_frame_equal(ranks.drop(columns="wall_s"),
                                  pd.read_csv(out / "ranks.csv", index_col=0).drop(columns="wall_s"))

    # more datasets extend the study; another seed is another study, refused in the same folder
    assert main(args[:3] + ["12"] + args[4:]) == 0
    assert len(list((out / "datasets").glob("*.json"))) == 12
    capsys.readouterr()
    assert main(args + ["--set", "seed=4"]) == 2
    assert "other settings" in capsys.readouterr().err


def test_methods_without_sbc_and_a_chains_options_are_refused_naming_what_is_allowed(tmp_path, capsys):
    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION)
    optimize = tmp_path / "optimize.toml"
    optimize.write_text(CALIBRATION.split("[method]")[0] + '[method]\nkind = "optimize"\n')
    assert main(["sbc", str(optimize), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "method.kind" in err and "'optimize'" in err and "allowed: emcee, npe, emulator" in err
    assert main(["sbc", str(path), "--steps", "10", "--out", str(tmp_path / "y")]) == 2
    assert "--steps" in capsys.readouterr().err
    assert main(["sbc", str(path), "--set", "method.rounds=2", "--out", str(tmp_path / "z")]) == 2
    assert "method.rounds" in capsys.readouterr().err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists() and not (tmp_path / "z").exists()
