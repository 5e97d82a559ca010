"""The tests behind claims, vectorised over rows: one call tests k samples at once (a claim's data is
k = 1; a power simulation's is k = hundreds). Every p-value is two-sided.

Each function takes ``Y`` (k, n) float (one sample per row, no NaN) and returns ``(statistic, p,
sign)`` arrays of shape (k,), ``sign`` the direction the row's data go (+1 up, -1 down, 0 none):

* ``spearman(x, Y)``: Spearman's rho between the fixed ``x`` (n,) and each row, p from Student's t with
  n - 2 degrees of freedom (the formula of ``scipy.stats.spearmanr``); sign = sign(rho);
* ``mann_whitney(Y, higher)``: U of the ``higher`` columns (bool mask) against the others, as
  ``scipy.stats.mannwhitneyu(Y[:, higher], Y[:, ~higher], axis=1)``: the normal approximation with tie
  and continuity corrections once both groups exceed 8 values (scipy's "asymptotic", computed here
  without its overhead), the exact distribution (scipy's "exact", approximate with ties) below that;
  sign = sign(U - n_h n_l / 2);
* ``welch(Y, higher)``: Welch's t of the higher group minus the other (``scipy.stats.ttest_ind``,
  ``equal_var=False``);
* ``wilcoxon(D)``: the signed-rank test of D against 0, as ``scipy.stats.wilcoxon(D, axis=1)`` (zeros
  dropped): the normal approximation with tie correction beyond 50 values (scipy's "asymptotic",
  computed here), the exact distribution up to 50 (scipy's "exact", conservative with ties);
  statistic = the sum of the positive ranks, sign = sign(W+ - m(m+1)/4);
* ``sign_test(D)``: the binomial test of P(D > 0) = 1/2 over the non-zero values (two-sided p = twice
  the smaller tail, at most 1, which is ``scipy.stats.binomtest``'s for p = 1/2); statistic = the share
  of positives;
* ``one_sample_t(D)``: Student's t of the mean of D against 0 (``scipy.stats.ttest_1samp``).

These choices depend on the sample size only, never on the data, so a data set and its simulated
copies are always tested the same way. A row that cannot be tested (too few values, no variation) gets
statistic and p NaN and sign 0, except that a constant sample of a rank test has p = 1. ``average_ranks(Y)`` ranks each row (ties get their
average rank) and returns the tie-group sizes' sum of t^3 - t per row.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy import stats

EXACT_LIMIT_MWU = 8      # scipy's "auto": exact Mann-Whitney when both groups are at most this large
EXACT_LIMIT_WILCOXON = 50


def average_ranks(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ranks 1..n with ties averaged, sum over tie groups of t^3 - t), each row of Y (k, n).

    One argsort per row; the tie groups are then found on the flattened sorted rows (a group starts
    where a value differs from the one before it, or a row begins), so the work past the sort is a few
    passes over k x n values (the power simulations rank hundreds of rows of 10^5 values)."""
    k, n = Y.shape
    order = np.argsort(Y, axis=1)
    ordered = np.take_along_axis(Y, order, axis=1)
    starts = np.ones((k, n), dtype=bool)
    np.not_equal(ordered[:, 1:], ordered[:, :-1], out=starts[:, 1:])
    ranks = np.empty((k, n))
    rows = np.arange(k)[:, None]
    if starts.all():                        # no ties: the positions in sorted order
        ranks.reshape(-1)[(order + rows * n).ravel()] = np.tile(np.arange(1.0, n + 1.0), k)
        return ranks, np.zeros(k)
    first = np.flatnonzero(starts)          # flat index of each tie group's first value
    size = np.diff(first, append=k * n)     # its length (a row's first value always starts a group)
    row_first = np.searchsorted(first, np.arange(k) * n)   # each row's first group (every row starts one)
    row_start = np.repeat(np.arange(0, k * n, n), np.diff(row_first, append=first.size))
    average = (first - row_start) + (size + 1) / 2.0       # (first rank + last rank) / 2, ranks from 1
    ranks.reshape(-1)[(order + rows * n).ravel()] = np.repeat(average, size)
    size = size.astype(float)
    return ranks, np.add.reduceat(size * size * size - size, row_first)


def _nan(k: int):
    return np.full(k, np.nan), np.full(k, np.nan), np.zeros(k, dtype=int)


def spearman(x: np.ndarray, Y: np.ndarray):
    k, n = Y.shape
    if n < 3 or np.all(x == x[0]):
        return _nan(k)
    rx = stats.rankdata(x)
    rx = rx - rx.mean()
    ry, _ = average_ranks(Y)
    ry -= ry.mean(axis=1, keepdims=True)
    norm = np.sqrt((ry * ry).sum(axis=1) * (rx @ rx))
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.clip((ry @ rx) / norm, -1.0, 1.0)
        t = rho * np.sqrt((n - 2) / ((rho + 1.0) * (1.0 - rho)))
    p = 2.0 * stats.t.sf(np.abs(t), n - 2)
    p = np.where(np.abs(rho) == 1.0, 0.0, p)
    constant = norm == 0
    rho, p = np.where(constant, np.nan, rho), np.where(constant, np.nan, p)
    return rho, p, np.where(constant, 0, np.sign(np.nan_to_num(rho))).astype(int)


def mann_whitney(Y: np.ndarray, higher: np.ndarray):
    k, n = Y.shape
    n_h, n_l = int(higher.sum()), int((~higher).sum())
    if n_h == 0 or n_l == 0:
        return _nan(k)
    if n_h <= EXACT_LIMIT_MWU or n_l <= EXACT_LIMIT_MWU:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = stats.mannwhitneyu(Y[:, higher], Y[:, ~higher], axis=1, method="exact")
        u, p = np.asarray(result.statistic, dtype=float), np.asarray(result.pvalue, dtype=float)
    else:
        ranks, ties = average_ranks(Y)
        u = ranks[:, higher].sum(axis=1) - n_h * (n_h + 1) / 2.0
        mu = n_h * n_l / 2.0
        big = np.maximum(u, n_h * n_l - u)
        s = np.sqrt(n_h * n_l / 12.0 * ((n + 1) - ties / (n * (n - 1))))
        with np.errstate(invalid="ignore", divide="ignore"):
            z = (big - mu - 0.5) / s
        p = np.clip(2.0 * stats.norm.sf(z), 0.0, 1.0)
    constant = np.all(Y == Y[:, :1], axis=1)
    p = np.where(constant, 1.0, p)
    return u, p, np.sign(u - n_h * n_l / 2.0).astype(int)


def welch(Y: np.ndarray, higher: np.ndarray):
    k = Y.shape[0]
    if higher.sum() < 2 or (~higher).sum() < 2:
        return _nan(k)
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = stats.ttest_ind(Y[:, higher], Y[:, ~higher], axis=1, equal_var=False)
    t = np.asarray(result.statistic, dtype=float)
    return t, np.asarray(result.pvalue, dtype=float), np.sign(np.nan_to_num(t)).astype(int)


def wilcoxon(D: np.ndarray):
    k, n = D.shape
    nonzero = D != 0
    m = nonzero.sum(axis=1).astype(float)
    if n <= EXACT_LIMIT_WILCOXON:
        with warnings.catch_warnings(), np.errstate(invalid="ignore"):
            warnings.simplefilter("ignore")
            result = stats.wilcoxon(D, axis=1, method="exact")
        p = np.where(m == 0, 1.0, np.asarray(result.pvalue, dtype=float))
        ranks, _ = average_ranks(np.abs(D))
        zeros = (n - m)[:, None]
        w = np.where(D > 0, ranks - zeros, 0.0).sum(axis=1)
        sign = np.sign(w - m * (m + 1) / 4.0).astype(int)
        return w, p, np.where(m == 0, 0, sign)
    magnitude = np.abs(D)
    ranks, _ = average_ranks(magnitude)
    zeros = (n - m)[:, None]
    ranks = np.where(nonzero, ranks - zeros, 0.0)      # zeros hold the lowest ranks: drop them
    _, ties = average_ranks(np.where(nonzero, magnitude, -1.0 - np.arange(n)))  # ties among non-zeros only
    w = np.where(D > 0, ranks, 0.0).sum(axis=1)
    mean = m * (m + 1) / 4.0
    se = np.sqrt((m * (m + 1) * (2 * m + 1) - ties / 2.0) / 24.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (w - mean) / se
    p = np.where(m == 0, 1.0, np.clip(2.0 * stats.norm.sf(np.abs(z)), 0.0, 1.0))
    return w, p, np.where(m == 0, 0, np.sign(w - mean)).astype(int)


def sign_test(D: np.ndarray):
    positive = (D > 0).sum(axis=1)
    m = (D != 0).sum(axis=1)
    tail = np.minimum(stats.binom.cdf(positive, m, 0.5), stats.binom.sf(positive - 1, m, 0.5))
    p = np.where(m == 0, 1.0, np.minimum(1.0, 2.0 * tail))
    with np.errstate(invalid="ignore", divide="ignore"):
        share = positive / m
    return share, p, np.where(m == 0, 0, np.sign(2 * positive - m)).astype(int)


def one_sample_t(D: np.ndarray):
    k, n = D.shape
    if n < 2:
        return _nan(k)
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = stats.ttest_1samp(D, 0.0, axis=1)
    t = np.asarray(result.statistic, dtype=float)
    return t, np.asarray(result.pvalue, dtype=float), np.sign(np.nan_to_num(t)).astype(int)


TWO_GROUP = {"mann-whitney": mann_whitney, "welch": welch}
ONE_SAMPLE = {"wilcoxon": wilcoxon, "sign": sign_test, "t": one_sample_t}
STATISTIC_NAMES = {"spearman": "Spearman rho", "mann-whitney": "Mann-Whitney U", "welch": "Welch t",
                   "wilcoxon": "Wilcoxon W+", "sign": "share above", "t": "Student t"}
