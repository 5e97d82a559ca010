"""Estimator folders sealed like results (issue 42; analysis.calibration.estimator_folder): the malformed-input
battery's posterior section (tests/malformed.py ESTIMATOR_FOLDERS and TARGET_TABLES: damaged, edited,
manifest-less and forged estimator folders, bad --targets tables and --tracks files), each one message and
exit 2 with nothing written; the seal's rules; and posterior on an intact folder."""
from __future__ import annotations

import json

import pytest

pytest.importorskip("flowjax", reason="the sbi extra (pip install -e '.[sbi]')")

from malformed import ESTIMATOR_FOLDERS, FLOCKS, TARGET_TABLES, attempt  # noqa: E402
from npe_tiny import fake_estimator  # noqa: E402
from flocksweep.analysis.calibration.estimator_folder import DamagedEstimator, seal, verify  # noqa: E402
from flocksweep.cli import main  # noqa: E402


@pytest.mark.parametrize("case", ESTIMATOR_FOLDERS + TARGET_TABLES, ids=[c.name for c in ESTIMATOR_FOLDERS + TARGET_TABLES])
def test_each_damaged_estimator_or_bad_target_is_one_message_and_exit_2(case, tmp_path):
    refusal = attempt(case, tmp_path)
    assert refusal.crash == "", refusal.crash
    assert refusal.code == case.code, refusal.stderr
    assert case.expect.lower() in refusal.stderr.lower(), refusal.stderr
    assert refusal.stderr.strip().startswith("flocksweep: ") and "Traceback" not in refusal.stderr
    if case in ESTIMATOR_FOLDERS:
        assert refusal.stderr.strip().count("\n") == 0, refusal.stderr
    assert refusal.written == set(), refusal.written


def test_an_intact_estimator_gives_its_posteriors(tmp_path, capsys):
    fake_estimator(tmp_path / "est")
    (tmp_path / "flocks.csv").write_text(FLOCKS)
    assert main(["posterior", str(tmp_path / "est"), "--targets", str(tmp_path / "flocks.csv"), "--draws", "50",
                 "--out", str(tmp_path / "post.csv")]) == 0
    assert "coverage: passed" in capsys.readouterr().out
    verify(tmp_path / "est")
    # the same command again writes the table again (it was refused: "a file; expected a folder"); a folder
    # given as the table is refused, naming --out, and nothing is written
    first = (tmp_path / "post.csv").read_bytes()
    assert main(["posterior", str(tmp_path / "est"), "--targets", str(tmp_path / "flocks.csv"), "--draws", "50",
                 "--out", str(tmp_path / "post.csv")]) == 0
    assert (tmp_path / "post.csv").read_bytes() == first
    capsys.readouterr()
    (tmp_path / "folder").mkdir()
    assert main(["posterior", str(tmp_path / "est"), "--targets", str(tmp_path / "flocks.csv"),
                 "--out", str(tmp_path / "folder")]) == 2
    assert "--out" in capsys.readouterr().err and not any((tmp_path / "folder").iterdir())


def test_seal_records_only_what_its_writer_names_and_keeps_what_still_holds(tmp_path):
    where = fake_estimator(tmp_path / "est")
    manifest = json.loads((where / "manifest.json").read_text())
    assert sorted(manifest["checksums"]) == ["coverage.json", "flow.eqx", "flow.json", "identity.json"]
    assert manifest["calibration"] == "c.toml"
    (where / "identity.json").write_text("{}")                   # edited behind the seal ...
    (where / "coverage.json").write_text('{"passed": true, "messages": ["x"]}')
    seal(where, ["coverage.json"])                               # ... a writer recording its own file
    assert sorted(json.loads((where / "manifest.json").read_text())["checksums"]) == [
        "coverage.json", "flow.eqx", "flow.json"]                # never vouches for the edited identity.json
    with pytest.raises(DamagedEstimator, match="identity.json cannot be verified"):
        verify(where)
