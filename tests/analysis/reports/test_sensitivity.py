"""Sensitivity analysis of continuous factors (analysis.reports.sensitivity and its report section).

* Ishigami through a toy simulator: a Saltelli ``[design]`` expanded by the sweep machinery, each run's
  output the Ishigami function of its parameters, stored in a results folder: the Sobol' indices match
  their analytic values within their CIs, and ``flocksweep report`` ranks the factors by total index;
* Morris mu* ranks a known function's factors and finds an inert one; rank correlations and PRCC on known
  linear models; the smoother and partial dependence recover known shapes; the noise share of known noise;
* a small Saltelli sweep of the real holland model ends in a report that ranks factors by total index
  with CIs.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from flocksweep.observables.summary import summary_columns
from flocksweep.analysis.reports.report import build_report
from flocksweep.analysis.reports.sensitivity import (ContinuousDesign, continuous_design, correlations, morris_indices,
                                          noise_share, partial_dependence, subsample, sample_outputs, smoother, sobol_indices)
from flocksweep.sweeps.config import load_sweep, sweep_from_dict
from flocksweep.sweeps.design import expand
from flocksweep.sweeps.runner import design_table, model_record, run_sweep
from flocksweep.sweeps.sensitivity import SensitivityDesign
from flocksweep.sweeps.store import ResultsStore
from flocksweep.sweeps.worker import base_row
from paths import ROOT

HOLLAND = str(ROOT / "configs/models/holland.toml")
# Ishigami (a = 7, b = 0.1) on [-pi, pi]^3: analytic first-order and total indices
ISHIGAMI_S1 = {"perception.field_deg": 0.3139, "perception.direction_deg": 0.4424, "perception.range": 0.0}
ISHIGAMI_ST = {"perception.field_deg": 0.5576, "perception.direction_deg": 0.4424, "perception.range": 0.2437}
BOUNDS = {"perception.field_deg": [10, 350], "perception.direction_deg": [0, 90], "perception.range": [5, 25]}


def ishigami_sweep(n: int, seed: int = 11, replicates: int = 1):
    data = {"name": "ishigami", "seed": seed, "replicates": replicates, "model": {"preset": HOLLAND},
            "run": {"duration": 1.0, "n": 5, "warmup": 0.0},
            "design": {"kind": "saltelli", "n": n, "bounds": BOUNDS}}
    return sweep_from_dict(data, ROOT)


def ishigami(values) -> float:
    """Ishigami of (field, direction, range), each mapped linearly onto [-pi, pi]."""
    x = [(v - lo) / (hi - lo) * 2 * math.pi - math.pi for v, (lo, hi) in zip(values, BOUNDS.values())]
    return math.sin(x[0]) + 7.0 * math.sin(x[1]) ** 2 + 0.1 * x[2] ** 4 * math.sin(x[0])


def toy_simulator(spec) -> float:
    """The toy simulator: Ishigami of the run's resolved field, direction and range of vision."""
    p = spec.preset.model.perception
    return ishigami([p.field_deg, p.direction_deg, p.range])


def store_toy_results(config, out, noise_sd: float = 0.0):
    """The sweep's design run through the toy simulator (every statistic of a run is its Ishigami value),
    written to a results folder as real runs are."""
    specs = expand(config)
    rng = np.random.default_rng(0)
    rows, series = [], []
    per_record = [c[:-5] for c in summary_columns(leadership=False) if c.endswith("_mean")]
    for spec in specs:
        row = base_row(spec)
        value = toy_simulator(spec) + noise_sd * rng.standard_normal()
        row.update(status="ok", **{column: value for column in summary_columns(leadership=False)})
        rows.append(row)
        series.append(pd.DataFrame({"run_id": spec.run_id, "t": [0.0, 1.0], **{c: value for c in per_record}}))
    store = ResultsStore(out)
    design = design_table(specs)
    store.write_inputs("# toy\n", {**config.source, "replicates": config.replicates}, model_record(config), design)
    store.write_part(1, rows, pd.concat(series, ignore_index=True))
    store.consolidate(design)
    store.write_manifest({"sweep": config.name, "seed": config.seed, "replicates": config.replicates})
    return specs


def ishigami_design(n: int) -> tuple[ContinuousDesign, pd.DataFrame]:
    """The design's rows and a runs table of the toy outputs at its points (the full path through
    ``expand`` and the store is the slow test below)."""
    config = ishigami_sweep(n)
    rows = np.array(config.design.rows(config.seed, [False] * 3))
    design = ContinuousDesign("saltelli", list(config.design.keys), config.design, rows)
    runs = pd.DataFrame(rows, columns=list(BOUNDS)).assign(y=[ishigami(r) for r in rows])
    return design, runs


def assert_ishigami(table: pd.DataFrame) -> None:
    for row in table.itertuples():
        assert row.S1_low <= ISHIGAMI_S1[row.factor] <= row.S1_high, (row.factor, row.S1, row.S1_conf)
        assert row.ST_low <= ISHIGAMI_ST[row.factor] <= row.ST_high, (row.factor, row.ST, row.ST_conf)
    assert list(table["factor"]) == ["perception.field_deg", "perception.direction_deg", "perception.range"]


def test_ishigami_sobol_indices_match_their_analytic_values_within_their_cis():
    design, runs = ishigami_design(256)
    X, Y = sample_outputs(design, runs, "y")
    assert X.shape == (256 * 5, 3) and np.isfinite(Y).all()
    table, note = sobol_indices(design, Y, seed=0)
    assert note == ""
    assert_ishigami(table)
    assert (table["ST_conf"] < 0.2).all()    # informative intervals at N = 256 (SALib's bootstrap)
    assert table["rank"].tolist() == [1, 2, 3]


def test_sobol_drops_incomplete_blocks_and_says_so():
    design, runs = ishigami_design(256)
    X, Y = sample_outputs(design, runs, "y")
    Y[[0, 7, 8]] = np.nan      # rows of base rows 0 and 1 (blocks of d + 2 = 5 rows)
    table, note = sobol_indices(design, Y, seed=0)
    assert "2 of 256 Saltelli base rows" in note and table["n_base"].eq(254).all()
    assert_ishigami(table)


@pytest.mark.slow
def test_ishigami_through_the_sweep_store_and_the_report(tmp_path):
    config = ishigami_sweep(1024)
    store_toy_results(config, tmp_path / "results")
    result = build_report(tmp_path / "results", tmp_path / "report", metrics=["polarization"], formats=("md",))
    table = result["tables"]["sobol_indices"]
    assert_ishigami(table)
    md = result["paths"]["md"].read_text()
    assert "Sobol' indices" in md and "field of vision phi (deg)" in md
    assert "factor_tests" not in result["tables"]          # no grid factor: no Kruskal-Wallis on 1024 levels
    corr = result["tables"]["rank_correlations"].set_index("factor")
    assert corr.loc["perception.field_deg", "prcc_low"] > 0.3      # sin(x1) rises over the middle of the range
    assert corr.loc["perception.range", "prcc_low"] < 0 < corr.loc["perception.range", "prcc_high"]


def test_continuous_design_is_rebuilt_from_the_stored_sweep(tmp_path):
    config = ishigami_sweep(8)
    store_toy_results(config, tmp_path / "results")
    from flocksweep.sweeps.results import load_results

    results = load_results(tmp_path / "results")
    design = continuous_design(results)
    assert design.kind == "saltelli" and design.keys == list(BOUNDS)
    assert np.array_equal(design.rows, np.array(config.design.rows(config.seed, [False] * 3)))
    assert set(results.factors) == set(BOUNDS)


def test_morris_ranks_factors_and_finds_the_inert_one():
    spec = SensitivityDesign(kind="morris", bounds=(("a", 0.0, 1.0), ("b", 0.0, 1.0), ("c", 0.0, 1.0)),
                             trajectories=40, levels=4)
    rows = spec.sample(seed=3)
    design = ContinuousDesign("morris", ["a", "b", "c"], spec, rows)
    Y = 4.0 * rows[:, 0] + np.sin(3.0 * rows[:, 1]) + 0.0 * rows[:, 2]
    table, note = morris_indices(design, rows, Y, seed=0)
    by = table.set_index("factor")
    assert note == "" and list(table["factor"][:2]) == ["a", "b"]
    assert by.loc["a", "mu_star"] == pytest.approx(4.0, rel=1e-9)     # a linear effect: every step's slope
    assert by.loc["a", "sigma"] == pytest.approx(0.0, abs=1e-9)
    assert by.loc["c", "mu_star"] == 0.0 and by.loc["b", "sigma"] > 0  # inert; non-linear


def test_rank_correlations_and_prcc_on_known_models():
    rng = np.random.default_rng(1)
    X = rng.uniform(0, 1, (400, 3))
    Y = X[:, 0] + 0.3 * X[:, 1] + 0.05 * rng.standard_normal(400)
    table = correlations(X, Y, ["a", "b", "c"]).set_index("factor")
    assert table.loc["a", "prcc"] > table.loc["b", "prcc"] > 0.5
    assert table.loc["c", "prcc_low"] < 0 < table.loc["c", "prcc_high"] and table.loc["c", "prcc_p"] > 0.01
    assert table.loc["a", "spearman_p"] < 1e-10
    monotone = correlations(X[:, :1], np.exp(X[:, 0]), ["a"]).iloc[0]
    assert monotone["spearman"] == pytest.approx(1.0) and monotone["n"] == 400


def test_smoother_and_partial_dependence_recover_known_shapes():
    rng = np.random.default_rng(2)
    X = rng.uniform(0, 1, (300, 2))
    Y = np.sin(2 * np.pi * X[:, 0]) + X[:, 1] + 0.05 * rng.standard_normal(300)
    x, fitted = smoother(X[:, 0], Y)
    assert np.max(np.abs(fitted - (np.sin(2 * np.pi * x) + 0.5))) < 0.15   # E[Y | x1] = sin + E[x2]
    curves, r2 = partial_dependence(X, Y, ["a", "b"], seed=0)
    assert r2 > 0.9
    a = curves[curves["factor"] == "a"]
    assert np.corrcoef(a["average"], np.sin(2 * np.pi * a["value"]))[0, 1] > 0.97
    b = curves[curves["factor"] == "b"]
    assert np.corrcoef(b["average"], b["value"])[0, 1] > 0.97
    assert smoother([1, 2, 3], [1, 2, 3]) is None


def test_partial_dependence_of_many_points_is_fitted_to_a_seeded_subsample_of_them():
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 1, (260, 2))
    Y = X[:, 0] ** 2 + 0.5 * X[:, 1] + 0.02 * rng.standard_normal(260)
    Y[7] = np.nan   # a point without a value is left out before the draw
    keep = np.isfinite(Y)
    chosen = subsample(int(keep.sum()), 120, seed=5)
    assert len(chosen) == 120 and len(set(chosen)) == 120 and np.all(np.diff(chosen) > 0)
    assert np.array_equal(subsample(100, 120, seed=5), np.arange(100))   # all of them when few
    curves, r2 = partial_dependence(X, Y, ["a", "b"], seed=5, most=120)
    alone, r2_alone = partial_dependence(X[keep][chosen], Y[keep][chosen], ["a", "b"], seed=5)
    pd.testing.assert_frame_equal(curves, alone)   # exactly the fit to those points
    assert r2 == r2_alone > 0.8
    full, _ = partial_dependence(X, Y, ["a", "b"], seed=5)   # under the bound: every point, as before
    assert not full.equals(curves)


def test_noise_share_of_known_noise():
    rng = np.random.default_rng(4)
    x = np.repeat(np.linspace(0, 1, 50), 4)
    runs = pd.DataFrame({"x": x, "y": 2 * x + 0.2 * rng.standard_normal(len(x))})
    # variance of the point means: var(2x) ~ 4/12 * 50/49 = 0.340 plus noise 0.04/4 = 0.01
    assert noise_share(runs, ["x"], "y") == pytest.approx(0.01 / 0.35, rel=0.35)
    assert math.isnan(noise_share(runs.drop_duplicates("x"), ["x"], "y"))


@pytest.mark.slow
def test_a_small_saltelli_sweep_of_holland_ranks_factors_by_total_index(tmp_path):
    path = ROOT / "configs/sweeps/holland_saltelli.toml"
    config = load_sweep(path, ["design.n=16", "run.duration=6.0", "run.n=20", "replicates=1"])
    run_sweep(config, path.read_text(), tmp_path / "results", executor="serial", progress=False)
    result = build_report(tmp_path / "results", tmp_path / "report", metrics=["polarization", "cohesion"])
    table = result["tables"]["sobol_indices"]
    assert set(table["metric"]) == {"polarization_mean", "cohesion_mean"}
    for _, block in table.groupby("metric"):
        assert block["rank"].tolist() == list(range(1, len(config.design.keys) + 1))
        assert np.all(np.diff(block["ST"].to_numpy()) <= 0)          # ranked by total index
        assert (block["ST_low"] <= block["ST"]).all() and (block["ST"] <= block["ST_high"]).all()
    html = result["paths"]["html"].read_text()
    assert "Sobol&#x27; indices" in html or "Sobol' indices" in html
