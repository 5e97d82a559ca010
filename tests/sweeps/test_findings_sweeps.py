"""The shipped sweeps of the Reynolds 1987 and Boids++ findings (configs/sweeps/reynolds87_allocation.toml,
boidspp_avoidance.toml, boidspp_predator.toml, boidspp_random_force.toml) and their claims files
(configs/claims/reynolds87.toml, boidspp.toml) load and validate without running: each sweep carries
the findings it can test, every claim names metrics and factors of its sweep (sweeps.claims checks that
at load). An axis over a list-valued key (``world.obstacles``) is stored as JSON text in the tables and
rebuilt from it exactly."""
from __future__ import annotations

import json
import tomllib

import pandas as pd
import pytest

from flocksweep.sweeps.config import load_sweep, sweep_from_dict
from flocksweep.sweeps.design import expand, rebuild
from flocksweep.sweeps.runner import design_table, model_record, run_sweep
from paths import ROOT

SWEEPS = ROOT / "configs" / "sweeps"
CLAIMS = ROOT / "configs" / "claims"

FINDINGS = {                       # sweep -> (claims it tests, their family, runs in the design)
    "reynolds87_allocation": (["a", "b"], "reynolds87", 90),
    "boidspp_avoidance": (["c"], "boidspp", 20),
    "boidspp_predator": (["d"], "boidspp", 32),
    "boidspp_random_force": (["e"], "boidspp", 75),
}


@pytest.mark.parametrize("name", sorted(FINDINGS))
def test_finding_sweeps_load_with_their_claims(name):
    ids, family, runs = FINDINGS[name]
    config = load_sweep(SWEEPS / f"{name}.toml")
    assert [c.id for c in config.claims] == ids
    assert all(c.family == family and c.origin.endswith(f"{family}.toml") for c in config.claims)
    assert all(c.source is not None and c.statement for c in config.claims)
    assert len(config.points or ()) == 0 and len(expand(config)) == runs


def test_claims_files_declare_every_finding_once():
    for name, ids in (("reynolds87", ["a", "b"]), ("boidspp", ["c", "d", "e"])):
        data = tomllib.loads((CLAIMS / f"{name}.toml").read_text())
        assert [c["id"] for c in data["claims"]] == ids
        assert "BEFORE the sweep" in (CLAIMS / f"{name}.toml").read_text()   # effects declared up front


def test_paired_findings_have_common_random_numbers():
    # a paired comparison matches runs of the same replicate: only meaningful when they start alike
    for name in ("reynolds87_allocation", "boidspp_avoidance"):
        config = load_sweep(SWEEPS / f"{name}.toml")
        assert config.common_random_numbers
        specs = expand(config)
        by_replicate = {}
        for spec in specs:
            by_replicate.setdefault(spec.replicate, set()).add(spec.seed)
        assert all(len(seeds) == 1 for seeds in by_replicate.values())


OBSTACLE_AXIS = [[], [{"kind": "sphere", "centre": [20.0, 0.0, 0.0], "radius": 3.0}],
                 [{"kind": "sphere", "centre": [20.0, 0.0, 0.0], "radius": 3.0},
                  {"kind": "box", "centre": [40.0, 0.0, 0.0], "half_extents": [1.0, 2.0, 3.0]}]]


def obstacle_sweep() -> dict:
    return {"name": "obstacles", "seed": 3, "replicates": 2, "common_random_numbers": True,
            "model": {"preset": str(ROOT / "configs/models/reynolds87.toml")},
            "run": {"n": 6, "duration": 1.0, "record_interval": 0.5, "warmup": 0.5},
            "axes": [{"name": "obstacles", "key": "world.obstacles", "values": OBSTACLE_AXIS,
                      "labels": ["none", "one", "two"]}]}


def test_a_list_valued_axis_is_json_text_in_the_tables_and_rebuilds_exactly():
    config = sweep_from_dict(obstacle_sweep(), ROOT)
    specs = expand(config)
    table = design_table(specs)
    assert table["obstacles"].tolist() == ["none"] * 2 + ["one"] * 2 + ["two"] * 2
    cells = table["world.obstacles"]
    assert all(isinstance(c, str) for c in cells) and cells.nunique() == 3       # hashable, one per level
    assert len(table[["obstacles", "world.obstacles"]].drop_duplicates()) == 3   # groups like any factor
    assert [len(json.loads(c)) for c in cells[::2]] == [0, 1, 2]
    record = model_record(config)
    for spec, row in zip(specs, table.to_dict("records")):
        preset, _ = rebuild(record, row)
        assert preset.model.world.obstacles == spec.preset.model.world.obstacles
        assert preset.to_dict() == spec.preset.to_dict()
    assert json.loads(cells[4])[1]["kind"] == "box"


def test_a_list_valued_axis_survives_the_stored_sweep_text():
    config = sweep_from_dict(obstacle_sweep(), ROOT)
    again = sweep_from_dict(tomllib.loads(config.to_toml()), ROOT)
    assert [s.run_id for s in expand(again)] == [s.run_id for s in expand(config)]
    assert pd.Series([s.run_id for s in expand(config)]).nunique() == 6


@pytest.mark.slow
def test_a_shrunken_allocation_sweep_runs_and_its_claims_are_judged_from_the_stored_tables(tmp_path):
    """reynolds87_allocation shrunk (N = 12, 8 s, 2 paired replicates, one budget): runs, its stored
    tables give the claims their factors back (the obstacle list as text, the label as the level), both
    claims reach a verdict, and a stored run rebuilt from its row resimulates to the same collisions."""
    from flocksweep.observables.summary import summarize_run
    from flocksweep.analysis.reports.claims.evaluate import evaluate
    from flocksweep.analysis.reports.claims.load import claims_of
    from flocksweep.simcore import simulate
    from flocksweep.sweeps.results import load_results
    from flocksweep.sweeps.store import ResultsStore

    data = tomllib.loads((SWEEPS / "reynolds87_allocation.toml").read_text())
    data["run"].update(n=12, duration=8.0)
    data["replicates"] = 2
    data["axes"][1]["values"] = [16.0]
    config = sweep_from_dict(data, SWEEPS)
    out = tmp_path / "alloc"
    run_sweep(config, config.to_toml(), out, executor="serial", progress=False)
    results = load_results(out)
    assert len(results.ok) == 12 and set(results.ok["obstacles"]) == {"none", "sparse", "dense"}
    claims, columns, skipped = claims_of(results)
    assert [c.id for c in claims] == ["a", "b"] and not skipped
    outcomes = evaluate(claims, results.ok, columns.factors, with_power=False)
    verdicts = {o.claim.id: o.outcome.verdict for o in outcomes}
    assert set(verdicts) == {"a", "b"}
    assert all(v in ("supported", "not supported", "inconclusive", "partly supported") for v in verdicts.values())
    row = results.ok[results.ok["obstacles"] == "dense"].iloc[0].to_dict()
    preset, metrics = rebuild(ResultsStore(out).model(), row)
    assert len(preset.model.world.obstacles) == 15
    run = preset.run
    obs = simulate(preset.model, preset.init, int(row["seed"]), run.duration, run.dt, run.record_every)
    again = summarize_run(obs, metrics)
    assert again["collided_boids"] == row["collided_boids"] and again["polarization_final"] == row["polarization_final"]
