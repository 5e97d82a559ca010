"""A user's own hypothesis, declared in a tiny sweep file, end to end through the command line: `flocksweep
run` validates and stores it, `flocksweep report` judges it with its evidence, `--until-claims` adds
replicates only to the design points of the tests that are still undecided."""
from __future__ import annotations

import pandas as pd
import pytest

from flocksweep.cli import main
from paths import ROOT

SWEEP = f"""
name = "mine"
seed = 4
replicates = 2

[model]
preset = "{ROOT / 'configs/models/holland.toml'}"

[run]
n = 10
duration = 3.0
record_interval = 0.5
warmup = 0.5

[[axes]]
name = "mode"
key = "patterns.enabled"
values = [false, true]
labels = ["normal", "pattern"]

[[axes]]
key = "perception.field_deg"
values = [40, 360]

[[claims]]
id = "full-vision"
statement = "Boids that see all around form more aligned flocks than boids with a 40 degree field."
source = {{ paper = "our notebook", section = "idea 3" }}
condition = 'mode == "normal"'
test = "compare"
metric = "polarization_mean"
lower = "perception.field_deg == 40"
higher = "perception.field_deg == 360"
effect = 0.2
"""


@pytest.fixture()
def sweep_file(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(SWEEP)
    return path


@pytest.mark.slow
def test_a_declared_claim_runs_and_is_reported_through_the_cli(sweep_file, tmp_path, capsys):
    out = tmp_path / "results"
    assert main(["run", str(sweep_file), "--out", str(out), "--executor", "serial", "--no-progress"]) == 0
    assert main(["report", str(out), "--out", str(tmp_path / "report"), "--format", "md"]) == 0
    printed = capsys.readouterr().out
    claims = pd.read_csv(tmp_path / "report" / "tables" / "claims.csv")
    tests = pd.read_csv(tmp_path / "report" / "tables" / "claim_tests.csv")
    assert list(claims["claim"]) == ["full-vision"]
    verdict = claims["verdict"].iloc[0]
    assert f"claim (full-vision): {verdict}: Boids that see all around" in printed
    # 2 replicates of 2 design points in normal mode: the exact Mann-Whitney test cannot reach p < 0.05
    assert tests["n"].iloc[0] == 4 and verdict == "inconclusive" and tests["power"].iloc[0] == 0.0
    md = (tmp_path / "report" / "report.md").read_text()
    assert "Tested where `mode == \"normal\"`" in md and "Source: our notebook, idea 3." in md
    assert (tmp_path / "report" / "figures" / "claim_full-vision.png").stat().st_size > 5000


@pytest.mark.slow
def test_until_claims_adds_replicates_only_where_a_claim_is_undecided(sweep_file, tmp_path, capsys):
    out = tmp_path / "results"
    assert main(["run", str(sweep_file), "--out", str(out), "--executor", "serial", "--no-progress",
                 "--until-claims", "--max-replicates", "6"]) == 0
    log = capsys.readouterr().out
    assert "claims (full-vision)" in log and "round 2" in log
    runs = pd.read_parquet(out / "runs.parquet")
    per_point = runs.groupby(["mode", "perception.field_deg"]).size()
    assert (per_point.loc["pattern"] == 2).all()                   # outside the claim's condition: untouched
    assert (per_point.loc["normal"] > 2).all() and (per_point.loc["normal"] <= 6).all()
    assert runs["run_id"].is_unique and (runs["status"] == "ok").all()


def test_until_claims_needs_claims_and_excludes_until_ci(tmp_path, capsys):
    bare = tmp_path / "bare.toml"
    bare.write_text(SWEEP.split("[[claims]]")[0])
    assert main(["run", str(bare), "--out", str(tmp_path / "r"), "--until-claims"]) == 2
    assert "declares no claims" in capsys.readouterr().err
    sweep = tmp_path / "s.toml"
    sweep.write_text(SWEEP)
    assert main(["run", str(sweep), "--out", str(tmp_path / "r"), "--until-claims",
                 "--until-ci", "cohesion=0.1"]) == 2
    assert "not both" in capsys.readouterr().err
    broken = tmp_path / "broken.toml"
    broken.write_text(SWEEP.replace('metric = "polarization_mean"', 'metric = "polarisation_mean"'))
    assert main(["run", str(broken), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "claims[0].metric" in err and "did you mean 'polarization_mean'" in err
    assert not (tmp_path / "r").exists()                            # nothing ran, nothing was written


@pytest.mark.slow
def test_stored_claims_that_no_longer_fit_the_results_are_listed_not_fatal(sweep_file, tmp_path):
    """Results computed before a metric existed keep their old columns (their runs are done): a stored
    claim on that metric is skipped with the reason, the others are tested; a --claims file that does
    not fit is an error."""
    import json

    from flocksweep.analysis.reports.claims.load import claims_of
    from flocksweep.simcore.schema import ConfigError
    from flocksweep.sweeps.results import load_results

    out = tmp_path / "results"
    assert main(["run", str(sweep_file), "--out", str(out), "--executor", "serial", "--no-progress"]) == 0
    effective = json.loads((out / "sweep.effective.json").read_text())
    effective["claims"].append({**effective["claims"][0], "id": "newer", "metric": "newer_metric_mean"})
    (out / "sweep.effective.json").write_text(json.dumps(effective))
    claims, columns, skipped = claims_of(load_results(out))
    assert [c.id for c in claims] == ["full-vision"]
    assert skipped[0][0] == "newer" and "'newer_metric_mean' is not a metric" in skipped[0][1]
    bad = tmp_path / "bad.toml"
    bad.write_text('[[claims]]\nid = "x"\nstatement = "s"\ntest = "sign"\nmetric = "newer_metric_mean"\n'
                   'direction = "positive"\n')
    with pytest.raises(ConfigError, match="bad.toml: claims\\[0\\].metric"):
        claims_of(load_results(out), [bad])
