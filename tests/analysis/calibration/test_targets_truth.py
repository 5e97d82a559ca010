"""``targets.truth`` of a calibration file (recovery studies): a value for every free parameter inside its
bounds, refused with the key otherwise; absent, nothing changes."""
from __future__ import annotations

import pytest

from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.simcore import ConfigError
from paths import ROOT


def data(truth=None) -> dict:
    targets = {"stats": ["polarization"], "mean": [0.9], "sd": [0.05]}
    if truth is not None:
        targets["truth"] = truth
    return {"name": "t", "model": {"preset": str(ROOT / "configs/models/holland.toml")},
            "parameters": {"field": {"key": "perception.field_deg", "prior": {"dist": "uniform", "low": 60, "high": 300}},
                           "range": {"key": "perception.range", "prior": {"dist": "uniform", "low": 5, "high": 40}}},
            "targets": targets, "method": {"kind": "emcee", "n_sim": 8}}


def test_truth_is_read_in_parameter_order():
    config = calibration_from_dict(data({"range": 20, "field": 150}), ROOT)
    assert config.targets.truth == {"field": 150.0, "range": 20.0}
    assert calibration_from_dict(data(), ROOT).targets.truth is None


@pytest.mark.parametrize("truth, key, words", [
    ({"field": 150, "rnage": 20}, "targets.truth.rnage", "did you mean 'range'"),
    ({"field": 150}, "targets.truth", "missing 'range'"),
    ({"field": 400, "range": 20}, "targets.truth.field", "outside the bounds"),
    ({"field": "wide", "range": 20}, "targets.truth.field", "finite number"),
])
def test_bad_truths_are_refused_with_their_key(truth, key, words):
    with pytest.raises(ConfigError, match=words) as err:
        calibration_from_dict(data(truth), ROOT)
    assert err.value.key == key


def test_targets_samples_writes_each_run_as_a_flock_and_the_block_reads_them_back(tmp_path, capsys):
    """``flocksweep targets --replicates 3 --samples F.csv``: F holds the 3 runs' statistics (not their mean),
    the printed block names F relative to the calibration file, and that block, pasted, gives the calibration
    those 3 rows bit for bit as its observed data; --sd with --samples is refused, naming --sd."""
    import tomllib

    import numpy as np

    from flocksweep.analysis.calibration.config import load_calibration
    from flocksweep.analysis.calibration.synthetic import synthetic_observation
    from flocksweep.cli import main
    from malformed import calibration_text

    HOLLAND = str(ROOT / "configs/models/holland.toml")
    config = tmp_path / "c.toml"
    config.write_text(calibration_text().replace("{holland}", HOLLAND))
    argv = ["targets", str(config), "--truth", "field=150", "--replicates", "3", "--seed", "5"]
    assert main(argv + ["--samples", str(tmp_path / "obs" / "flocks.csv")]) == 0
    block = tomllib.loads(capsys.readouterr().out)["targets"]
    assert block["samples"] == "obs/flocks.csv" and "mean" not in block and "sd" not in block
    rows = synthetic_observation(load_calibration(config), {"field": 150}, 5, 3)
    assert rows.shape[0] == 3 and not np.all(rows[0] == rows[1])        # three flocks, not one mean
    text = config.read_text()
    start = text.index("[targets]")
    end = text.index("\n[", start + 1)
    config.write_text(text[:start] + "[targets]\n" + "\n".join(f"{k} = {v!r}".replace("'", '"') for k, v in block.items()
                                                              if k in ("stats", "samples")) + text[end:])
    loaded = load_calibration(config)
    np.testing.assert_array_equal(loaded.targets.observed, rows)
    assert main(argv + ["--samples", str(tmp_path / "f.csv"), "--sd", "0.1"]) == 2
    assert "--sd" in capsys.readouterr().err


@pytest.mark.parametrize("name, says", [("flocks.txt", "expected a .csv file"), ("obs", "is a folder")])
def test_a_bad_samples_path_is_refused_before_any_run(tmp_path, capsys, monkeypatch, name, says):
    from flocksweep.analysis.calibration import synthetic
    from flocksweep.cli import main
    from malformed import calibration_text

    def no_run(*args, **kwargs):
        raise AssertionError("simulated before the --samples path was checked")
    monkeypatch.setattr(synthetic, "synthetic_observation", no_run)
    config = tmp_path / "c.toml"
    config.write_text(calibration_text().replace("{holland}", str(ROOT / "configs/models/holland.toml")))
    (tmp_path / "obs").mkdir()
    assert main(["targets", str(config), "--truth", "field=150", "--replicates", "3",
                 "--samples", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert "--samples" in err and says in err
