"""Tests of analysis/reports/stats.py on synthetic run tables with a known structure.

Every random table is drawn from a fixed seed; tolerances are stated next to each assertion.
"""
from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from flocksweep.analysis.reports import stats as S


def level_table(rng, n_per_level, shifts, levels=None, sd=1.0):
    """One row per run: factor 'f' with len(shifts) levels, metric 'm' ~ Normal(shift, sd)."""
    levels = list(range(len(shifts))) if levels is None else list(levels)
    f = np.repeat(np.asarray(levels, dtype=float), n_per_level)
    m = rng.normal(0.0, sd, f.size) + np.repeat(np.asarray(shifts, dtype=float), n_per_level)
    return pd.DataFrame({"f": f, "m": m})


def grid_table(rng, reps, interaction, a_effect=0.5):
    """3 x 3 design, ``reps`` runs per cell; A numeric, B text; a diagonal interaction of size
    ``interaction`` (no marginal effect of its own: each row and column holds one diagonal cell)."""
    a, b = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    a, b = np.repeat(a.ravel(), reps), np.repeat(b.ravel(), reps)
    m = rng.normal(size=a.size) + a_effect * a + interaction * (a == b)
    return pd.DataFrame({"A": a.astype(float), "B": np.array(["u", "v", "w"])[b], "m": m})


# ---------------------------------------------------------------------------------------- factor_test

def test_factor_test_null_rejection_rate_is_nominal():
    # 300 null data sets (4 levels x 20 runs, no effect): the rate of p < 0.05 must be near 0.05;
    # [0.02, 0.09] is about +-2.5 binomial sd around 0.05 (sd = 0.0126)
    pvalues = [S.factor_test(level_table(np.random.default_rng(1000 + s), 20, [0, 0, 0, 0]), "f", "m")["p"]
               for s in range(300)]
    rate = np.mean(np.asarray(pvalues) < 0.05)
    assert 0.02 <= rate <= 0.09


def expected_epsilon2(shifts):
    """Large-sample eta^2 of the ranks for equal groups of Normal(shift_i, 1):
    12 sum_i w_i (E[F(X_i)] - 1/2)^2, with E[F(X_i)] = sum_j w_j Phi((mu_i - mu_j) / sqrt 2)."""
    mu = np.asarray(shifts, dtype=float)
    w = 1.0 / mu.size
    mean_cdf = (w * sps.norm.cdf((mu[:, None] - mu[None, :]) / np.sqrt(2))).sum(axis=1)
    return 12 * w * ((mean_cdf - 0.5) ** 2).sum()


def test_factor_test_finds_planted_effect_with_expected_epsilon2():
    # three levels 1 sd apart (means 0, 1, 2), 30 runs per level
    target = expected_epsilon2([0, 1, 2])
    assert target == pytest.approx(0.413, abs=1e-3)
    results = [S.factor_test(level_table(np.random.default_rng(s), 30, [0, 1, 2]), "f", "m") for s in range(50)]
    for r in results:
        assert r["p"] < 1e-3
        assert r["df"] == 2 and r["n"] == 90 and r["n_levels"] == 3
        assert 0.15 <= r["epsilon2"] <= 0.75                 # one data set: sd about 0.08
        assert r["epsilon2"] == pytest.approx(r["H"] * 91 / (90 ** 2 - 1))
    # mean over 50 data sets: sd of the mean about 0.011; allow 0.05 (small-sample bias included)
    assert np.mean([r["epsilon2"] for r in results]) == pytest.approx(target, abs=0.05)


def test_factor_test_matches_scipy_kruskal():
    rng = np.random.default_rng(7)
    a, b, c = rng.normal(size=10), rng.normal(0.5, 1, 12), rng.normal(1, 1, 9)
    table = pd.DataFrame({"f": ["a"] * 10 + ["b"] * 12 + ["c"] * 9, "m": np.concatenate([a, b, c])})
    h, p = sps.kruskal(a, b, c)
    r = S.factor_test(table, "f", "m")
    assert r["H"] == pytest.approx(h, rel=1e-12) and r["p"] == pytest.approx(p, rel=1e-12)
    assert r["epsilon2"] == pytest.approx(h / 30, rel=1e-12)


# ---------------------------------------------------------------------------------------- main_effect

@pytest.mark.slow
def test_main_effect_ci_coverage_is_about_nominal():
    # 200 draws x 2 levels = 400 BCa intervals around the true means 0 and 2 (n = 30 each):
    # coverage within [0.9, 0.99] (nominal 0.95; binomial sd 0.011)
    hits = []
    for s in range(200):
        table = level_table(np.random.default_rng(5000 + s), 30, [0.0, 2.0])
        effect = S.main_effect(table, "f", "m", n_resamples=1000, seed=s)
        truth = np.array([0.0, 2.0])
        hits.extend((effect["ci_low"] <= truth) & (truth <= effect["ci_high"]))
        assert set(effect["ci_method"]) == {"BCa"}
    coverage = np.mean(hits)
    assert 0.9 <= coverage <= 0.99


def test_main_effect_columns_order_and_values():
    table = level_table(np.random.default_rng(3), 15, [1.0, 2.0, 3.0], levels=[10, 2, 1.5])
    table.loc[0, "m"] = np.nan                                  # a run at level 10 with no value
    effect = S.main_effect(table, "f", "m", n_resamples=500, seed=1)
    assert list(effect.columns) == S.MAIN_EFFECT_COLUMNS
    assert effect["level"].tolist() == [1.5, 2.0, 10.0]         # numeric, not lexicographic
    assert effect["n"].tolist() == [15, 15, 14] and effect["n_missing"].tolist() == [0, 0, 1]
    for _, row in effect.iterrows():
        values = table.loc[table["f"] == row["level"], "m"].dropna()
        assert row["mean"] == pytest.approx(values.mean(), rel=1e-12)
        assert row["sd"] == pytest.approx(values.std(ddof=1), rel=1e-12)
        assert row["ci_low"] < row["mean"] < row["ci_high"]


def test_main_effect_text_levels_sorted_and_reproducible():
    rng = np.random.default_rng(4)
    table = pd.DataFrame({"mode": rng.choice(["pattern", "normal", "lazy"], 90), "m": rng.normal(size=90)})
    first = S.main_effect(table, "mode", "m", n_resamples=500, seed=11)
    again = S.main_effect(table, "mode", "m", n_resamples=500, seed=11)
    other = S.main_effect(table, "mode", "m", n_resamples=500, seed=12)
    assert first["level"].tolist() == ["lazy", "normal", "pattern"]
    pd.testing.assert_frame_equal(first, again)
    assert not np.allclose(first["ci_low"], other["ci_low"])
    via_generator = S.main_effect(table, "mode", "m", n_resamples=500, seed=np.random.default_rng(11))
    pd.testing.assert_frame_equal(first, via_generator)


def test_main_effect_constant_and_tiny_samples():
    table = pd.DataFrame({"f": [1, 1, 1, 2, 3, 3], "m": [5.0, 5.0, 5.0, 7.0, np.nan, np.nan]})
    effect = S.main_effect(table, "f", "m", n_resamples=200)
    const, single, empty = effect.iloc[0], effect.iloc[1], effect.iloc[2]
    assert (const["ci_low"], const["ci_high"], const["ci_method"]) == (5.0, 5.0, "constant")
    assert const["sd"] == 0.0
    assert single["n"] == 1 and np.isnan(single["ci_low"]) and single["ci_method"] == "none"
    assert empty["n"] == 0 and empty["n_missing"] == 2 and np.isnan(empty["mean"])


def test_bootstrap_falls_back_to_percentile_when_bca_fails(monkeypatch):
    real = sps.bootstrap

    def failing_bca(*args, method="BCa", **kwargs):
        if method == "BCa":
            raise ValueError("BCa failed")
        return real(*args, method=method, **kwargs)

    monkeypatch.setattr(S.stats, "bootstrap", failing_bca)
    x = np.random.default_rng(0).normal(size=40)
    low, high, method = S.bootstrap_mean_ci(x, n_resamples=500, seed=3)
    assert method == "percentile" and low < x.mean() < high
    expected = real((x,), np.mean, n_resamples=500, method="percentile", rng=np.random.default_rng(3))
    assert low == pytest.approx(expected.confidence_interval.low, rel=1e-12)


# --------------------------------------------------------------------------------------------- holm

def test_holm_hand_computed_example():
    # sorted: 0.005*4 = 0.02, 0.01*3 = 0.03, 0.03*2 = 0.06, max(0.04*1, 0.06) = 0.06
    adjusted = S.holm([0.01, np.nan, 0.04, 0.03, 0.005])
    np.testing.assert_allclose(adjusted, [0.03, np.nan, 0.06, 0.06, 0.02], rtol=1e-12)
    np.testing.assert_allclose(S.holm([0.5, 0.6]), [1.0, 1.0])       # capped at 1
    assert S.holm([]).size == 0 and np.isnan(S.holm([np.nan])).all()


def test_holm_is_monotone_and_not_below_raw():
    p = np.random.default_rng(2).uniform(0, 0.2, 40)
    adjusted = S.holm(p)
    order = np.argsort(p)
    assert np.all(np.diff(adjusted[order]) >= 0)
    assert np.all(adjusted >= p) and np.all(adjusted <= 1)


# -------------------------------------------------------------------------------------- two_way_test

def test_two_way_finds_planted_interaction():
    result = S.two_way_test(grid_table(np.random.default_rng(21), 10, 2.0), "A", "B", "m")
    assert result["source"].tolist() == ["A", "B", "A:B"]
    assert (result["model"] == "full").all() and (result["note"] == "").all()
    row = result.set_index("source").loc["A:B"]
    assert row["df"] == 4 and row["df_resid"] == 81
    assert row["p"] < 1e-3 and row["partial_eta2"] > 0.2


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_two_way_null_interaction_rejection_rate():
    # 200 data sets with a main effect of A (0.5 sd per level) and no interaction: the interaction's
    # p < 0.05 at about the nominal rate ([0.01, 0.10]); the planted main effect of A is found
    pvalues = np.array([S.two_way_test(grid_table(np.random.default_rng(s), 8, 0.0), "A", "B", "m")["p"]
                        .to_numpy() for s in range(200)])
    rate = np.mean(pvalues[:, 2] < 0.05)
    assert 0.01 <= rate <= 0.10
    assert np.mean(pvalues[:, 0] < 0.05) > 0.7


def test_two_way_matches_statsmodels_type2_on_unbalanced_data():
    # reference: statsmodels 0.15 anova_lm(ols('r ~ C(A) * C(B)'), typ=2) on r = rankdata(m)
    table = pd.DataFrame({
        "A": ["p"] * 7 + ["q"] * 9 + ["p"] * 5 + ["q"] * 4,
        "B": [1.0] * 3 + [2.0] * 4 + [1.0] * 5 + [2.0] * 4 + [3.0] * 5 + [3.0] * 4,
        "m": [3.1, 4.7, 2.2, 8.0, 6.5, 7.7, 5.0, 1.2, 0.4, 2.9, 1.9, 3.3, 9.1, 6.9, 7.2, 8.8, 4.1, 5.5,
              4.4, 6.1, 3.9, 9.9, 10.5, 12.0, 2.0],
    })
    result = S.two_way_test(table, "A", "B", "m").set_index("source")
    np.testing.assert_allclose(result["SS"], [29.890660592255, 732.384250335845, 127.809339407745],
                               rtol=1e-10)
    np.testing.assert_allclose(result["F"], [1.303172444362, 15.965237214756, 2.786114557994], rtol=1e-10)
    np.testing.assert_allclose(result["p"], [0.267818402757, 0.000085481248, 0.086883223599], rtol=1e-8)
    assert result["df"].tolist() == [1, 2, 2] and (result["df_resid"] == 19).all()
    np.testing.assert_allclose(result["partial_eta2"], result["SS"] / (result["SS"] + 435.8), rtol=1e-10)


def test_two_way_balanced_ss_equals_classical_formula():
    table = grid_table(np.random.default_rng(8), 6, 1.0)
    result = S.two_way_test(table, "A", "B", "m").set_index("source")
    r = sps.rankdata(table["m"])
    for factor in ("A", "B"):
        means = pd.Series(r).groupby(table[factor].to_numpy()).mean()
        classical = (18 * (means - r.mean()) ** 2).sum()      # 18 runs per level
        assert result.loc[factor, "SS"] == pytest.approx(classical, rel=1e-9)


def test_two_way_without_replication_drops_interaction():
    rng = np.random.default_rng(9)
    table = pd.DataFrame([(a, b) for a in range(4) for b in ("x", "y", "z")], columns=["A", "B"])
    table["m"] = rng.normal(size=len(table)) + 2.0 * table["A"]
    result = S.two_way_test(table, "A", "B", "m")
    assert result["source"].tolist() == ["A", "B"]
    assert (result["model"] == "additive").all()
    assert result["note"].str.contains("no replication").all()
    assert result["df"].tolist() == [3, 2] and (result["df_resid"] == 6).all()


# ------------------------------------------------------------------------------ adjacent comparisons

def test_cliffs_delta_separated_and_brute_force():
    assert S.cliffs_delta([5, 6, 7], [1, 2]) == 1.0
    assert S.cliffs_delta([1, 2], [5, 6, 7]) == -1.0
    rng = np.random.default_rng(1)
    x, y = rng.integers(0, 5, 23).astype(float), rng.integers(0, 5, 17).astype(float)   # with ties
    brute = np.sign(x[:, None] - y[None, :]).mean()
    assert S.cliffs_delta(x, y) == pytest.approx(brute, abs=1e-12)
    assert np.isnan(S.cliffs_delta([], [1.0]))


def test_adjacent_comparisons_find_the_single_shifted_step():
    # five levels, only the step from level 2 to 3 shifts the metric (+1.5 sd), 40 runs per level
    table = level_table(np.random.default_rng(31), 40, [0, 0, 0, 1.5, 1.5], levels=[0, 5, 10, 20, 40])
    result = S.adjacent_comparisons(table, "f", "m")
    assert list(result.columns) == S.ADJACENT_COLUMNS
    assert list(zip(result["level_a"], result["level_b"])) == [(0, 5), (5, 10), (10, 20), (20, 40)]
    shifted = result["level_a"] == 10
    assert result.loc[shifted, "p_holm"].item() < 1e-3
    assert result.loc[shifted, "cliffs_delta"].item() > 0.4
    assert result.loc[shifted, "median_diff"].item() > 0.8
    assert (result.loc[~shifted, "p_holm"] > 0.05).all()
    np.testing.assert_allclose(result["p_holm"], S.holm(result["p"]))


def test_adjacent_comparisons_fully_separated_levels():
    table = pd.DataFrame({"f": ["a"] * 5 + ["b"] * 6, "m": [1, 2, 3, 4, 5, 10, 11, 12, 13, 14, 15.0]})
    row = S.adjacent_comparisons(table, "f", "m").iloc[0]
    assert row["cliffs_delta"] == 1.0 and row["U"] == 30 and row["median_diff"] == 9.5
    reverse = table.assign(m=-table["m"])
    assert S.adjacent_comparisons(reverse, "f", "m").iloc[0]["cliffs_delta"] == -1.0


# -------------------------------------------------------------------------------------- cell_summary

def test_cell_summary_matches_hand_computation():
    table = pd.DataFrame({
        "a": [1, 1, 1, 1, 2, 2, 2],
        "b": ["x", "x", "x", "y", "x", "x", "x"],
        "m": [1.0, 2.0, 4.0, 3.0, 2.0, np.nan, 6.0],
    })
    cells = S.cell_summary(table, ["a", "b"], "m", confidence=0.9)
    assert cells[["a", "b"]].values.tolist() == [[1, "x"], [1, "y"], [2, "x"]]
    assert cells["n"].tolist() == [3, 1, 2] and cells["n_missing"].tolist() == [0, 0, 1]
    sd = np.std([1.0, 2.0, 4.0], ddof=1)
    assert cells["ci_halfwidth"].iloc[0] == pytest.approx(sps.t.ppf(0.95, 2) * sd / np.sqrt(3), rel=1e-12)
    assert cells["ci_halfwidth"].iloc[2] == pytest.approx(sps.t.ppf(0.95, 1) * np.sqrt(8) / np.sqrt(2),
                                                          rel=1e-12)
    assert cells["ci_halfwidth"].iloc[1] == np.inf and np.isnan(cells["sd"].iloc[1])   # n = 1: no finite bound
    assert cells["mean"].tolist() == pytest.approx([7 / 3, 3.0, 4.0])


def test_cell_summary_single_factor_name():
    table = level_table(np.random.default_rng(0), 5, [0, 1], levels=[10, 2])
    cells = S.cell_summary(table, "f", "m")
    assert cells["f"].tolist() == [2.0, 10.0] and cells["n"].tolist() == [5, 5]


def test_cell_summary_takes_factors_named_like_pandas_aggregations():
    """An axis may be called size, count or std (pandas' own aggregation names); n, mean and sd are refused
    when the sweep file is read (sweeps.config.REPORT_COLUMNS, RESERVED_COLUMNS)."""
    table = pd.DataFrame({"size": [1, 1, 2, 2], "count": ["a", "a", "a", "a"], "m": [1.0, 3.0, 5.0, 9.0]})
    cells = S.cell_summary(table, ["size", "count"], "m")
    assert cells["size"].tolist() == [1, 2] and cells["mean"].tolist() == [2.0, 7.0]
    assert cells["n"].tolist() == [2, 2] and cells["sd"].tolist() == pytest.approx([np.sqrt(2), np.sqrt(8)])


# ------------------------------------------------------------------------------------- monotone_trend

def test_monotone_trend_direction_and_significance():
    up = level_table(np.random.default_rng(12), 20, [0, 0.5, 1.0, 1.5], levels=[30, 60, 90, 120])
    r = S.monotone_trend(up, "f", "m")
    assert r["direction"] == 1 and r["rho"] > 0.3 and r["p"] < 1e-4 and r["n"] == 80 and r["n_levels"] == 4
    rho, p = sps.spearmanr(up["f"], up["m"])
    assert r["rho"] == pytest.approx(rho) and r["p"] == pytest.approx(p)
    down = up.assign(m=-up["m"])
    assert S.monotone_trend(down, "f", "m")["direction"] == -1
    one_sided = S.monotone_trend(down, "f", "m", alternative="greater")
    assert one_sided["p"] > 0.99                                  # the claim "increasing" is not supported


def test_monotone_trend_rejects_text_factor():
    with pytest.raises(ValueError):
        S.monotone_trend(pd.DataFrame({"mode": ["a", "b", "c"], "m": [1.0, 2, 3]}), "mode", "m")


# ------------------------------------------------------------------------------------ factor_report

def report_table(n_rep, rng):
    """A synthetic sweep: 5 factors (one text) fully crossed, ``n_rep`` replicates, 6 metrics."""
    grids = np.meshgrid(["normal", "pattern"], [20, 50, 100], [0.0, 30, 60, 90, 120, 150],
                        [30.0, 60, 90, 120, 150, 180], [5.0, 10, 20], indexing="ij")
    design = pd.DataFrame({name: g.ravel() for name, g in zip(
        ["mode", "init.n", "perception.direction_deg", "perception.field_deg", "perception.range"], grids)})
    runs = design.loc[design.index.repeat(n_rep)].reset_index(drop=True)
    runs["replicate"] = np.tile(np.arange(n_rep), len(design))
    n = len(runs)
    runs["cohesion_mean"] = 0.002 * runs["perception.field_deg"] + rng.normal(0, 0.3, n)
    runs["polarization_mean"] = rng.uniform(0, 1, n)
    runs["stray_fraction_mean"] = rng.beta(1, 5, n)
    runs["n_groups_mean"] = 1 + rng.poisson(runs["perception.range"] / 5)
    runs["elongation_mean"] = rng.lognormal(0, 0.5, n)
    runs["speed_mean_mean"] = np.where(rng.uniform(size=n) < 0.1, np.nan, rng.normal(1, 0.1, n))
    return runs


FACTORS = ["mode", "init.n", "perception.direction_deg", "perception.field_deg", "perception.range"]
METRICS = ["cohesion_mean", "polarization_mean", "stray_fraction_mean", "n_groups_mean", "elongation_mean",
           "speed_mean_mean"]


def test_factor_report_structure_and_consistency():
    runs = report_table(1, np.random.default_rng(0))
    report = S.factor_report(runs, FACTORS, METRICS, seed=5, n_resamples=300)
    tests = report["tests"]
    assert len(tests) == 30
    np.testing.assert_allclose(tests["p_holm"], S.holm(tests["p"]))
    field = tests.set_index(["metric", "factor"]).loc[("cohesion_mean", "perception.field_deg")]
    assert field["p_holm"] < 0.01                                  # the planted effect survives Holm
    direct = S.main_effect(runs, "perception.field_deg", "cohesion_mean", n_resamples=300, seed=5)
    effects = report["main_effects"]
    block = effects[(effects["metric"] == "cohesion_mean") & (effects["factor"] == "perception.field_deg")]
    np.testing.assert_allclose(block[["mean", "ci_low", "ci_high"]].to_numpy(dtype=float),
                               direct[["mean", "ci_low", "ci_high"]].to_numpy(dtype=float))
    assert len(effects) == 6 * (2 + 3 + 6 + 6 + 3)
    assert len(report["adjacent"]) == 6 * (1 + 2 + 5 + 5 + 2)
    speed = tests[tests["metric"] == "speed_mean_mean"]
    assert (speed["n"] + speed["n_missing"] == len(runs)).all() and (speed["n_missing"] > 0).all()


@pytest.mark.slow
def test_factor_report_on_a_full_size_table_has_every_interval():
    # 3240 runs x 5 factors x 6 metrics, as for holland648_r5 (its speed is measured in bench/, not here)
    runs = report_table(5, np.random.default_rng(1))
    assert len(runs) == 3240
    report = S.factor_report(runs, FACTORS, METRICS, seed=0)
    assert report["main_effects"]["ci_low"].notna().all()
    assert (report["main_effects"]["ci_low"] <= report["main_effects"]["ci_high"]).all()


# ------------------------------------------------------------------------------------ degenerate inputs

def test_degenerate_inputs_do_not_raise():
    constant = pd.DataFrame({"f": [1.0, 1, 2, 2, 3, 3], "g": list("ababab"), "m": [4.0] * 6})
    single = pd.DataFrame({"f": [1.0] * 5, "g": list("abcab"), "m": [1.0, 2, 3, 4, 5]})
    nans = pd.DataFrame({"f": [1.0, 1, 2, 2], "g": list("abab"), "m": [np.nan] * 4})
    empty = pd.DataFrame({"f": pd.Series([], dtype=float), "g": pd.Series([], dtype=object),
                          "m": pd.Series([], dtype=float)})
    with warnings.catch_warnings():
        warnings.simplefilter("error")                         # no stray warnings either
        r = S.factor_test(constant, "f", "m")
        assert (r["H"], r["p"], r["epsilon2"]) == (0.0, 1.0, 0.0)
        r = S.factor_test(single, "f", "m")
        assert np.isnan(r["p"]) and r["df"] == 0 and r["n"] == 5
        assert np.isnan(S.factor_test(nans, "f", "m")["p"]) and S.factor_test(nans, "f", "m")["n_missing"] == 4
        assert np.isnan(S.factor_test(empty, "f", "m")["p"])

        two = S.two_way_test(constant, "f", "g", "m")
        assert (two["p"] == 1.0).all()
        assert np.isnan(S.two_way_test(single, "f", "g", "m").set_index("source").loc["f", "p"])
        assert S.two_way_test(nans, "f", "g", "m")["p"].isna().all()
        assert S.two_way_test(empty, "f", "g", "m")["p"].isna().all()

        adj = S.adjacent_comparisons(constant, "f", "m")
        assert (adj["p"] == 1.0).all() and (adj["cliffs_delta"] == 0.0).all()
        assert S.adjacent_comparisons(single, "f", "m").empty
        assert S.adjacent_comparisons(nans, "f", "m")["p"].isna().all()

        for table in (constant, single, nans, empty):
            S.main_effect(table, "f", "m", n_resamples=100)
            S.cell_summary(table, ["f", "g"], "m")
            trend = S.monotone_trend(table, "f", "m")
            assert trend["direction"] == 0 and np.isnan(trend["rho"])
        assert S.main_effect(empty, "f", "m").empty
        report = S.factor_report(nans, ["f", "g"], ["m"], n_resamples=100)
        assert report["tests"]["p_holm"].isna().all()
