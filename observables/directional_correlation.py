"""Directional correlation delays (Nagy, Akos, Biro & Vicsek 2010, Nature 464: 890): who follows whom.

Input: velocities ``vel`` (R, N, 3) on a regular record grid of spacing ``interval`` (s), nan where an
individual is not seen (a measured flock's :class:`~observables.observed.ObservedFlock`, or a
simulator's ``Observations``: the same function for both). v_hat = v / |v| is the unit heading; a
stopped or unseen individual has none at that record and is left out of every term.

* **Directional correlation** of the ordered pair (i, j) at the delay tau = m x interval,
  m = -M .. M, M = floor(max_delay / interval), at most R - 1 for R records (a longer delay has no pair of
  records, so its C would be nan: not allocated, however fine the interval):

      C_ij(tau) = mean over records t (both t and t + m in the run, both headings known)
                  of v_hat_i(t) . v_hat_j(t + m)

  so C_ij(tau) near 1 at tau > 0 means j flies, tau later, as i flew: i leads j. C_ji(-tau) = C_ij(tau)
  exactly (the same terms). A pair with fewer than ``min_terms`` terms at a delay has nan there.
* **Delay** tau*_ij = the delay of the largest C_ij (the smallest |tau| on ties, then the earlier), and
  C*_ij = C_ij(tau*_ij): tau*_ji = -tau*_ij.
* **Leader-follower network**: a directed edge i -> j when C*_ij >= ``min_corr`` (0.5 by default,
  Nagy et al.'s threshold for a meaningful relation) and tau*_ij > 0.
* **Hierarchy**: score_i = mean of tau*_ij over the j with C*_ij >= ``min_corr``; rank 1 is the highest
  score (leads the most, by the longest delays), nan scores rank last.

Scalars per flock (``DCD_METRIC_NAMES``, :func:`dcd_scalars` of a :class:`DirectionalCorrelation`): ``dcd_corr_mean`` (mean C* over pairs i < j with a value),
``dcd_delay_mean`` (mean |tau*| over pairs with C* >= min_corr, s), ``dcd_edges`` (edges of the network
per individual) and ``dcd_leader_delay`` (the highest score, s). nan without any pair.

Delays go up to ``max_delay`` (``DCD_MAX_DELAY`` = 2 s by default, the range of Nagy et al.'s delays).
:func:`observables.summary.run_directional_correlation` applies this to a run or a measured flock with
its metric settings (the records at or after the warm-up, ``MetricSettings.dcd_max_delay``): the one
path of ``flocksweep measure``, the sweeps (``run.dcd_metrics``) and calibration statistics.

Cost: one (R, N, N) product per delay, O((2M + 1) R N^2), numpy: about 5 ms for 30 boids over 31
records (1 s apart, M = 2) but 0.3 s over 301 records (0.1 s apart, M = 20), three times the 30 s
simulation itself, which is why sweeps compute it only when asked (docs/metrics.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .columns import DCD_METRIC_NAMES  # noqa: F401 - declared there, part of this module's face

MIN_CORR = 0.5
DCD_MAX_DELAY = 2.0    # s: the largest delay by default


@dataclass(frozen=True, eq=False)
class DirectionalCorrelation:
    delays: np.ndarray     # (2M + 1,) s
    corr: np.ndarray       # (N, N, 2M + 1) C_ij(tau), nan without enough terms
    corr_max: np.ndarray   # (N, N) C*_ij (nan on the diagonal and without a value)
    delay: np.ndarray      # (N, N) tau*_ij, s
    edges: np.ndarray      # (N, N) bool: i leads j
    score: np.ndarray      # (N,) mean delay of i over its meaningful pairs, s
    rank: np.ndarray       # (N,) 1 = the top of the hierarchy


def unit_velocity_headings(vel: np.ndarray) -> np.ndarray:
    """(R, N, 3) unit headings, nan where the velocity is unknown or zero."""
    vel = np.asarray(vel, dtype=np.float64)
    speed = np.linalg.norm(vel, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(speed > 0, vel / speed, np.nan)


def correlation_curves(vel: np.ndarray, interval: float, max_delay: float, min_terms: int = 1):
    """(delays (2M+1,), C (N, N, 2M+1)) of the module docstring."""
    if not (np.isfinite(interval) and interval > 0):
        raise ValueError(f"interval: got {interval!r}; expected seconds > 0")
    if not (np.isfinite(max_delay) and max_delay >= 0):
        raise ValueError(f"max_delay: got {max_delay!r}; expected seconds >= 0")
    head = unit_velocity_headings(vel)
    known = np.isfinite(head).all(axis=-1)
    head = np.where(known[..., None], head, 0.0)
    n_rec, n = known.shape
    steps = int(min(np.floor(max_delay / interval + 1e-9), max(n_rec - 1, 0)))
    shifts = np.arange(-steps, steps + 1)
    corr = np.full((n, n, shifts.size), np.nan)
    for k, m in enumerate(shifts):
        lead = slice(max(0, -m), n_rec - max(0, m))       # records t with t + m in the run
        follow = slice(max(0, m), n_rec - max(0, -m))
        if lead.stop - lead.start <= 0:
            continue
        total = np.einsum("tid,tjd->ij", head[lead], head[follow])
        terms = np.einsum("ti,tj->ij", known[lead].astype(np.float64), known[follow].astype(np.float64))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr[:, :, k] = np.where(terms >= max(min_terms, 1), total / terms, np.nan)
    return shifts * interval, np.clip(corr, -1.0, 1.0)


def directional_correlation(vel: np.ndarray, interval: float, max_delay: float, min_corr: float = MIN_CORR,
                            min_terms: int = 1) -> DirectionalCorrelation:
    """Correlations, delays, network and hierarchy of a flock (see the module docstring)."""
    delays, corr = correlation_curves(vel, interval, max_delay, min_terms)
    n = corr.shape[0]
    order = np.argsort(np.abs(delays), kind="stable")      # ties: the smallest |tau|, then the earlier one
    ranked = corr[:, :, order]
    filled = np.where(np.isfinite(ranked), ranked, -np.inf)
    best = np.argmax(filled, axis=2)
    corr_max = np.take_along_axis(ranked, best[..., None], axis=2)[..., 0]
    delay = np.where(np.isfinite(corr_max), delays[order][best], np.nan)
    off = ~np.eye(n, dtype=bool)
    corr_max = np.where(off, corr_max, np.nan)
    delay = np.where(off, delay, np.nan)
    meaningful = off & (corr_max >= min_corr)
    edges = meaningful & (delay > 0)
    counts = meaningful.sum(axis=1)
    with np.errstate(invalid="ignore"):
        score = np.where(counts > 0, np.where(meaningful, delay, 0.0).sum(axis=1) / np.maximum(counts, 1), np.nan)
    sort_key = np.where(np.isfinite(score), -score, np.inf)
    rank = np.empty(n, dtype=np.int64)
    rank[np.argsort(sort_key, kind="stable")] = np.arange(1, n + 1)
    return DirectionalCorrelation(delays, corr, corr_max, delay, edges, score, rank)


def dcd_scalars(dc: DirectionalCorrelation, min_corr: float = MIN_CORR) -> dict:
    """The per-flock scalars of ``DCD_METRIC_NAMES`` of computed correlations (``min_corr`` as computed)."""
    n = dc.corr_max.shape[0]
    upper = dc.corr_max[np.triu_indices(n, 1)]
    strong = np.abs(dc.delay[np.triu_indices(n, 1)])[upper >= min_corr]
    upper = upper[np.isfinite(upper)]
    scores = dc.score[np.isfinite(dc.score)]
    return {"dcd_corr_mean": float(upper.mean()) if upper.size else float("nan"),
            "dcd_delay_mean": float(strong.mean()) if strong.size else float("nan"),
            "dcd_edges": float(dc.edges.sum() / n) if upper.size else float("nan"),
            "dcd_leader_delay": float(scores.max()) if scores.size else float("nan")}


def dcd_metrics(vel: np.ndarray, interval: float, max_delay: float, min_corr: float = MIN_CORR) -> dict:
    """The per-flock scalars of ``DCD_METRIC_NAMES`` of velocities (R, N, 3)."""
    return dcd_scalars(directional_correlation(vel, interval, max_delay, min_corr), min_corr)
