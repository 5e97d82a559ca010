"""The vectorised tests behind claims (analysis/reports/claims/statistics.py) give scipy's statistics and
p-values row by row, with ties, zeros, small and large samples; ranks average ties."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from flocksweep.analysis.reports.claims import statistics as S

RTOL = 1e-9


def samples(seed: int, k: int, n: int, shift: float = 0.2, decimals: int = 1) -> np.ndarray:
    """k rows of n values rounded to ``decimals`` (so ties occur)."""
    return np.round(np.random.default_rng(seed).normal(shift, 1.0, (k, n)), decimals)


def test_average_ranks_match_scipy_with_and_without_ties():
    for decimals in (0, 1, 12):
        Y = samples(1, 5, 300, decimals=decimals)
        ranks, ties = S.average_ranks(Y)
        assert np.array_equal(ranks, stats.rankdata(Y, axis=1))
        for row, y in zip(ties, Y):
            _, counts = np.unique(y, return_counts=True)
            assert row == pytest.approx(float((counts ** 3 - counts).sum()))


def test_average_ranks_flat_tie_groups_match_scipy_row_by_row():
    """The tie groups are found on the flattened rows: a group never runs across rows, even when a
    row ends and the next begins with the same value; rows with and without ties, constant rows, n = 1."""
    rng = np.random.default_rng(3)
    Y = rng.integers(0, 4, (6, 50)).astype(float)
    Y[1] = 2.0                                  # constant row
    Y[2] = rng.normal(size=50)                  # no ties in this row
    Y[3, :] = np.sort(Y[3])[::-1]               # ends low, the next row starts low
    Y[4, 0] = Y[3, -1]
    for block in (Y, Y[:1], Y[:, :1], Y[:, :2], np.vstack([Y[2], Y[2]])):
        ranks, ties = S.average_ranks(block)
        assert np.array_equal(ranks, stats.rankdata(block, axis=1))
        for row, y in zip(ties, block):
            _, counts = np.unique(y, return_counts=True)
            assert row == float((counts ** 3 - counts).sum())


@pytest.mark.parametrize("n", [5, 30, 400])
def test_spearman_matches_scipy(n):
    rng = np.random.default_rng(n)
    x = rng.integers(0, 6, n).astype(float)
    Y = np.round(rng.normal(0.2 * x, 1.0, (4, n)), 1)
    rho, p, sign = S.spearman(x, Y)
    for k, y in enumerate(Y):
        ref = stats.spearmanr(x, y)
        assert rho[k] == pytest.approx(ref.statistic, rel=RTOL) and p[k] == pytest.approx(ref.pvalue, rel=RTOL)
        assert sign[k] == np.sign(ref.statistic)


@pytest.mark.parametrize("n", [11, 40, 400])
def test_mann_whitney_and_welch_match_scipy(n):
    Y = samples(n, 4, n)
    higher = np.random.default_rng(n + 1).random(n) < 0.45
    u, p, sign = S.mann_whitney(Y, higher)
    t, pt, _ = S.welch(Y, higher)
    method = "exact" if min(higher.sum(), (~higher).sum()) <= S.EXACT_LIMIT_MWU else "asymptotic"
    for k, y in enumerate(Y):
        ref = stats.mannwhitneyu(y[higher], y[~higher], method=method)
        assert u[k] == ref.statistic and p[k] == pytest.approx(ref.pvalue, rel=RTOL)
        assert sign[k] == np.sign(u[k] - higher.sum() * (~higher).sum() / 2)
        ref_t = stats.ttest_ind(y[higher], y[~higher], equal_var=False)
        assert t[k] == pytest.approx(ref_t.statistic, rel=RTOL) and pt[k] == pytest.approx(ref_t.pvalue, rel=RTOL)


@pytest.mark.parametrize("n", [12, 45, 300])
def test_one_sample_tests_match_scipy_with_zeros(n):
    D = samples(n, 4, n, shift=0.15)
    D[:, :3] = 0.0                                     # zeros are dropped by the signed-rank and sign tests
    w, p, sign = S.wilcoxon(D)
    share, p_sign, _ = S.sign_test(D)
    t, p_t, _ = S.one_sample_t(D)
    method = "exact" if n <= S.EXACT_LIMIT_WILCOXON else "asymptotic"
    for k, d in enumerate(D):
        nonzero = d[d != 0]
        assert p[k] == pytest.approx(stats.wilcoxon(d, method=method).pvalue, rel=RTOL)
        assert w[k] == pytest.approx(stats.rankdata(np.abs(nonzero))[nonzero > 0].sum())
        assert p_sign[k] == pytest.approx(stats.binomtest(int((d > 0).sum()), nonzero.size).pvalue, rel=RTOL)
        assert share[k] == pytest.approx((d > 0).sum() / nonzero.size)
        ref = stats.ttest_1samp(d, 0.0)
        assert t[k] == pytest.approx(ref.statistic, rel=RTOL) and p_t[k] == pytest.approx(ref.pvalue, rel=RTOL)


def test_degenerate_rows_do_not_raise():
    flat = np.ones((2, 20))
    assert np.isnan(S.spearman(np.arange(20.0), flat)[1]).all()           # constant metric
    assert np.isnan(S.spearman(np.ones(20), samples(0, 2, 20))[0]).all()  # one level of the factor
    assert (S.mann_whitney(flat, np.arange(20) < 10)[1] == 1.0).all()
    assert (S.wilcoxon(np.zeros((2, 60)))[1] == 1.0).all() and (S.sign_test(np.zeros((2, 5)))[1] == 1.0).all()
    assert np.isnan(S.welch(samples(0, 2, 3), np.array([True, False, False]))[1]).all()
