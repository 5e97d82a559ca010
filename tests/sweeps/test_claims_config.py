"""Claims in sweep files (sweeps/claims.py, sweeps/expressions.py): declared inline or included from
claims files, validated through the schema engine before anything runs, with errors that name the key;
conditions and metric expressions are a safe whitelist; the resolved claims are stored with the results."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.claims import claims_from_records, read_claims_file, table_columns, with_claims
from flocksweep.sweeps.config import RESERVED_COLUMNS, load_sweep, sweep_from_dict
from flocksweep.sweeps.expressions import ExpressionError, parse
from flocksweep.sweeps.runner import run_sweep
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
CLAIMS = ROOT / "configs" / "claims"


def sweep(*claims, include=None, **extra) -> dict:
    data = {"name": "claims", "seed": 1, "replicates": 2, "model": {"preset": HOLLAND},
            "run": {"n": 8, "duration": 2.0, "record_interval": 0.5, "warmup": 0.5},
            "axes": [{"name": "mode", "key": "patterns.enabled", "values": [False, True],
                      "labels": ["normal", "pattern"]},
                     {"key": "perception.field_deg", "values": [60, 180]}],
            "claims": list(claims), **extra}
    if include is not None:
        data["include_claims"] = include
    return data


TREND = {"id": "wide", "statement": "A wider field aligns the flock.", "test": "trend",
         "metric": "polarization_mean", "factor": "perception.field_deg", "direction": "increasing"}


def error_of(*claims, **extra) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        sweep_from_dict(sweep(*claims, **extra), ROOT)
    return info.value


def test_inline_and_included_claims_resolve():
    config = sweep_from_dict(sweep(TREND, include=[{"file": str(CLAIMS / "holland.toml"), "only": ["a", "b"]}]), ROOT)
    assert [c.id for c in config.claims] == ["wide", "a", "b"]
    a = config.claims[1]
    assert a.family == "holland_semwal" and a.source.paper == "Holland & Semwal" and a.origin.endswith("holland.toml")
    assert [leaf.path for leaf in a.test.leaves()] == ["a.cohesion", "a.alignment"]
    disperses = config.claims[2].test.parts[1]
    assert [c.text for c in disperses.conditions] == ["perception.field_deg < 90"] and disperses.method == "sign"
    for name in ("holland648", "holland648_r5", "leadership", "leadership_vision", "smoke"):
        assert load_sweep(ROOT / "configs" / "sweeps" / f"{name}.toml").claims      # every shipped sweep has claims


@pytest.mark.parametrize("change, key, words", [
    ({"metirc": "x"}, "claims[0].metirc", "did you mean 'metric'"),
    ({"metric": "polarisation_mean"}, "claims[0].metric", "did you mean 'polarization_mean'"),
    ({"metric": "polarization_mean - cohesin_mean"}, "claims[0].metric", "did you mean 'cohesion_mean'"),
    ({"factor": "perception.range"}, "claims[0].factor", "not a factor of this sweep"),
    ({"factor": "mode"}, "claims[0].factor", "not numeric"),
    ({"direction": "upward"}, "claims[0].direction", "increasing, decreasing"),
    ({"method": "pearson"}, "claims[0].method", "spearman"),
    ({"test": "tend"}, "claims[0].test", "did you mean 'trend'"),
    ({"lower": "perception.field_deg < 90"}, "claims[0].lower", "not a key of a trend test"),
    ({"condition": "perception.field_deg > 200"}, "claims[0].condition", "selects no design point"),
    ({"condition": "perception.field_deg == 60"}, "claims[0].condition", "fewer than two levels"),
    ({"condition": 'perception.field_deg == "wide"'}, "claims[0].condition", "compares text with a number"),
    ({"condition": "mode.upper() == 1"}, "claims[0].condition", "is not allowed here"),
    ({"condition": "__import__('os')"}, "claims[0].condition", "is not allowed here"),
    ({"condition": "perception.field_deg <"}, "claims[0].condition", "not a valid condition"),
    ({"metric": "trigger_rate"}, "claims[0].metric", "leadership metrics are computed only"),
    ({"effect": -1.0}, "claims[0].effect", "a number > 0"),
    ({"alpha": 1.5}, "claims[0].alpha", "(0, 1)"),
    ({"power": {"target": 1.2}}, "claims[0].power.target", "allowed range"),
    ({"statement": None}, "claims[0].statement", "missing required key"),
])
def test_claim_errors_name_the_key(change, key, words):
    claim = {**TREND, **change}
    claim = {k: v for k, v in claim.items() if v is not None}
    err = error_of(claim)
    assert err.key == key and words in str(err), str(err)


def test_composite_and_compare_errors():
    leaf = {k: v for k, v in TREND.items() if k != "statement"}
    parts = {"id": "p", "statement": "s", "test": "all_of", "parts": [leaf | {"id": "x"}, leaf | {"id": "x"}]}
    assert error_of(parts).key == "claims[0].parts[1].id"
    assert error_of({**parts, "parts": [TREND]}).key == "claims[0].parts[0].statement"   # parts have no statement
    assert error_of({"id": "p", "statement": "s", "test": "any_of"}).key == "claims[0].parts"
    compare = {"id": "c", "statement": "s", "test": "compare", "metric": "cohesion_mean",
               "lower": 'mode == "normal"', "higher": "perception.field_deg == 180"}
    assert "disjoint" in str(error_of(compare))
    assert error_of({**compare, "higher": 'mode == "patern"'}).key == "claims[0].higher"
    assert error_of({**compare, "higher": 'mode == "pattern"', "paired": True, "method": "welch"}).key == \
        "claims[0].method"
    assert "unique" in str(error_of(TREND, TREND))


def test_include_errors_name_the_file_and_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[claims]]\nid = "q"\nstatement = "s"\ntest = "sign"\nmetric = "cohesion_mean"\ndirektion = "positive"\n')
    err = error_of(include=[str(bad)])
    assert err.key.startswith("include_claims[0]") and "direktion" in err.key and "did you mean 'direction'" in str(err)
    missing = error_of(include=[str(tmp_path / "none.toml")])
    assert missing.key == "include_claims[0]" and "claims file not found" in str(missing)
    only = error_of(include=[{"file": str(CLAIMS / "holland.toml"), "only": ["z"]}])
    assert only.key == "include_claims[0].only" and "its claims: a, b, c, d, e" in str(only)
    # claim (c) of Holland's needs a direction of vision, which this sweep does not vary
    needs = error_of(include=[str(CLAIMS / "holland.toml")])
    assert "claims[2].parts[0].factor" in needs.key and "perception.direction_deg" in str(needs)


def test_an_included_claims_file_reached_through_a_symbolic_link_is_named_with_its_real_file(tmp_path):
    """docs/errors.md, 'What a config file can make flocksweep read': links are followed, the real file is
    named in messages and its claims are copied into the results (which never depend on the link)."""
    (tmp_path / "sweep").mkdir()
    (tmp_path / "elsewhere").mkdir()
    real = tmp_path / "elsewhere" / "claims.toml"
    real.write_text((CLAIMS / "holland.toml").read_text())
    (tmp_path / "sweep" / "link.toml").symlink_to(real)
    data = sweep(include=[{"file": "link.toml", "only": ["a"]}])
    config = sweep_from_dict(data, tmp_path / "sweep")
    assert [c.id for c in config.claims] == ["a"]
    stored = with_claims(config.source, config.claims)               # as the results store it: written out
    assert [c["id"] for c in stored["claims"]] == ["a"] and "include_claims" not in stored
    real.write_text(real.read_text().replace('id = "a"', 'id = "a"\nstatment = "typo"', 1))
    with pytest.raises(ConfigError) as info:
        sweep_from_dict(data, tmp_path / "sweep")
    assert f"include_claims[0] (link.toml -> {real.resolve()})" in info.value.key
    plain = error_of(include=[str(real)])                          # no link: no arrow
    assert "->" not in plain.key and "did you mean 'statement'" in str(plain)
    (tmp_path / "sweep" / "dangling.toml").symlink_to(tmp_path / "nowhere.toml")
    with pytest.raises(ConfigError, match="claims file not found: 'dangling.toml'"):
        sweep_from_dict(sweep(include=["dangling.toml"]), tmp_path / "sweep")


@pytest.mark.parametrize("text, expected", [
    ("f <= 20", [True, True, False, False]),
    ("f > 10 and g == 'b'", [False, False, True, True]),
    ("not (f in [0, 30])", [False, True, False, True]),
    ("g not in ['a']", [False, False, True, True]),
    ("0 < f <= 30", [False, True, True, False]),
    ("flag", [True, False, True, False]),
    ("flag == false or f == 40", [False, True, False, True]),
    ("abs(f - 25) < 10 or f / 2 == 0", [True, True, True, False]),
])
def test_conditions_evaluate_on_a_table(text, expected):
    table = pd.DataFrame({"f": [0.0, 20.0, 30.0, 40.0], "g": ["a", "a", "b", "b"], "flag": [True, False, True, False]})
    assert parse(text, "k", "condition").evaluate(table).tolist() == expected


def test_metric_expressions_and_their_limits():
    table = pd.DataFrame({"a": [1.0, 2.0, np.nan], "b": [0.5, 0.5, 0.5], "init.n": [10, 20, 30]})
    assert np.allclose(parse("a - b", "k", "metric").evaluate(table)[:2], [0.5, 1.5])
    assert np.isnan(parse("a * 2", "k", "metric").evaluate(table)[2])
    assert parse("n / 10", "k", "metric").evaluate(table).tolist() == [1.0, 2.0, 3.0]     # n means init.n
    assert parse("sqrt(a) + log(b) - exp(0)", "k", "metric").names == ("a", "b")
    for bad in ("a < b", "a if b else 0", "'text'", "a[0]", "lambda: 1", "min(a, b)"):
        with pytest.raises(ConfigError, match="not allowed here"):
            parse(bad, "claims[0].metric", "metric")
    with pytest.raises(ExpressionError, match="no column 'c'"):
        parse("a + c", "k", "metric").evaluate(table)


def test_claims_are_stored_with_the_results_and_read_back(tmp_path):
    data = sweep(TREND, include=[{"file": str(CLAIMS / "holland.toml"), "only": ["e"]}])
    config = sweep_from_dict(data, ROOT)
    result = run_sweep(config, "# claims\n", tmp_path / "out", executor="serial", progress=False)
    stored = json.loads((tmp_path / "out" / "sweep.effective.json").read_text())
    assert "include_claims" not in stored and [c["id"] for c in stored["claims"]] == ["wide", "e"]
    design = pd.read_parquet(tmp_path / "out" / "design.parquet")
    columns = table_columns(design, [c for c in result.table.columns if c.endswith(("_mean", "_final"))],
                            RESERVED_COLUMNS)
    again = claims_from_records(stored["claims"], columns)
    assert [c.table for c in again] == [c.table for c in config.claims]
    assert with_claims(stored, again) == stored                         # writing them again changes nothing
    # the stored file is a sweep in its own right (includes expanded): it loads to the same claims
    assert [c.table for c in sweep_from_dict({**stored, "model": data["model"]}, ROOT).claims] == \
        [c.table for c in config.claims]
    assert read_claims_file(CLAIMS / "hartman_benes.toml", table_columns(
        pd.DataFrame({"leadership.x": [0.0, 1.0]}), ["trigger_rate", "leaders_mean", "follow_corr_max",
                                                     "follow_corr_before", "n_groups_mean", "cohesion_mean"], ()))


# -- expressions are data: hostile inputs (docs/errors.md, sweeps.expressions) -----------------------

@pytest.mark.parametrize("text, kind, said", [
    ("__import__('os').system('touch pwned')", "condition", "is not allowed here"),
    ("open('/etc/passwd')", "metric", "is not allowed here"),
    ("abs(cohesion_mean).__class__", "metric", "is not allowed here"),
    ("(lambda: 1)()", "metric", "is not allowed here"),
    ("cohesion_mean ** 10 ** 10", "metric", "is not allowed here"),
    ("[x for x in ()]", "metric", "is not allowed here"),
    ("cohesion_mean[0]", "metric", "is not allowed here"),
    ("not " * 3000 + "fragmented", "condition", "at most 4,000"),
    ("+".join(["cohesion_mean"] * 20000), "metric", "at most 4,000"),
    ("not " * 200 + "fragmented", "condition", "nested more than 60 levels"),
    ("+".join(["cohesion_mean"] * 100), "metric", "nested more than 60 levels"),
    ("(" * 1000 + "cohesion_mean" + ")" * 1000, "metric", "cohesion_mean"),
])
def test_hostile_expressions_are_refused_as_config_errors(text, kind, said):
    with pytest.raises(ConfigError) as info:
        parse(text, "claims[0].condition", kind)
    assert info.value.key == "claims[0].condition" and said in str(info.value)


def test_a_dunder_column_name_is_only_a_name_that_no_table_has():
    expression = parse("x.__class__ == 1", "k", "condition")
    assert expression.names == ("x.__class__",)
    with pytest.raises(ExpressionError, match="no column 'x.__class__'"):
        expression.evaluate(pd.DataFrame({"x": [1.0]}))
