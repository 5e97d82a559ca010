"""The leader-follower network and hierarchy of one flock (directional correlation delays, Nagy et al. 2010).

``hierarchy_figure(dc, ids, path, title="") -> Path`` draws a
:class:`~observables.directional_correlation.DirectionalCorrelation` in two panels:

* **network** (left): the individuals in a column ordered by hierarchy rank (rank 1, the one that leads
  the most by the longest delays, at the top), each labelled ``id (score s)``; every edge i -> j of the
  network (C*_ij >= min_corr and tau*_ij > 0: j flies as i flew tau* earlier) is an arc from i to j,
  its colour the delay tau*_ij; every arc bows to the right of the column, by a height in proportion to
  the ranks it spans, so the arcs nest (an arc diagram) instead of crossing the labels and each other;
  an edge another path already implies (i leads k, k leads j) is left out (:func:`reduced`; the matrix
  panel has every pair). Only the top ``NETWORK_MAX`` individuals are drawn (the title
  says so): more would not be readable at the figure's size;
* **delays** (right): the matrix of tau*_ij over the meaningful pairs (C*_ij >= min_corr; blank
  otherwise), rows and columns in rank order: a leader's row is positive (red), its column negative.

The colour scale is symmetric, +- the largest |tau*| shown. The figure is 11 x 5 inches with text of at
least 7 points, so it reads at a report's width.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flocksweep.observables.directional_correlation import MIN_CORR, DirectionalCorrelation

from .plotting import pyplot, save

NETWORK_MAX = 20        # individuals drawn in the network panel
ARC_RAD = 0.9           # the edges' bow, as a share of the distance between the two individuals
LABELS_MAX = 40         # individuals labelled on the delay matrix


def _delay_scale(dc: DirectionalCorrelation, min_corr: float) -> float:
    meaningful = np.isfinite(dc.corr_max) & (dc.corr_max >= min_corr)
    values = np.abs(dc.delay[meaningful])
    return float(values.max()) if values.size and values.max() > 0 else 1.0


def _network(ax, dc: DirectionalCorrelation, labels: list, order: np.ndarray, norm, cmap) -> None:
    from matplotlib.patches import FancyArrowPatch
    shown = order[:NETWORK_MAX]
    level = {int(i): k for k, i in enumerate(shown)}
    for k, i in enumerate(shown):
        score = dc.score[i]
        text = f"{labels[i]} ({score:+.2f} s)" if np.isfinite(score) else f"{labels[i]} (no pair)"
        ax.plot(0, -k, "o", color="0.2", markersize=5, zorder=3)
        ax.text(-0.08, -k, text, ha="right", va="center", fontsize=7.5)
    edges = {(level[int(i)], level[int(j)]): dc.delay[i, j] for i, j in zip(*np.nonzero(dc.edges))
             if int(i) in level and int(j) in level}
    kept = reduced(list(edges))
    # an arc diagram: every edge bows to the right of the column (away from the labels), by a height in
    # proportion to the ranks it spans, so arcs nest rather than tangle; the long ones drawn first, under
    for a, b in sorted(kept, key=lambda e: -abs(e[0] - e[1])):
        delay = edges[(a, b)]
        rad = -ARC_RAD if a < b else ARC_RAD   # arc3 bows to the right of travel for rad < 0: +x going down
        ax.add_patch(FancyArrowPatch((0, -a), (0, -b), connectionstyle=f"arc3,rad={rad}",
                                     arrowstyle="-|>", mutation_scale=8, linewidth=0.9, alpha=0.8,
                                     color=cmap(norm(delay)), zorder=2, shrinkA=3, shrinkB=3))
    ax.set_xlim(-1.1, 1.0)
    ax.set_ylim(-len(shown) + 0.4, 0.8)
    ax.axis("off")
    more = f" (top {len(shown)} of {len(order)})" if len(order) > len(shown) else ""
    implied = len(edges) - len(kept)
    note = f"\n{implied} edges implied by the others not drawn (every pair: the matrix)" if implied else ""
    ax.set_title(f"leader -> follower edges{more}, rank 1 on top{note}", fontsize=9)


def reduced(edges: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """The edges left when each one that another path already implies is dropped (a leads c, c leads b:
    "a leads b" is implied), one at a time against what is left, so what leads to what is unchanged."""
    kept = set(edges)

    def reaches(start, goal, without) -> bool:
        seen, todo = {start}, [start]
        while todo:
            node = todo.pop()
            for a, b in kept:
                if a == node and (a, b) != without and b not in seen:
                    if b == goal:
                        return True
                    seen.add(b)
                    todo.append(b)
        return False

    for edge in sorted(edges, key=lambda e: -abs(e[0] - e[1])):   # the longest first: they are the implied ones
        if reaches(edge[0], edge[1], edge):
            kept.discard(edge)
    return sorted(kept)


def _matrix(ax, dc: DirectionalCorrelation, labels: list, order: np.ndarray, norm, cmap, min_corr: float):
    meaningful = np.isfinite(dc.corr_max) & (dc.corr_max >= min_corr)
    delays = np.where(meaningful, dc.delay, np.nan)[np.ix_(order, order)]
    image = ax.imshow(np.ma.masked_invalid(delays), cmap=cmap, norm=norm, interpolation="nearest")
    n = len(order)
    if n <= LABELS_MAX:
        ticks = np.arange(n)
        names = [str(labels[i]) for i in order]
        size = 7 if n <= 20 else 5.5
        ax.set_xticks(ticks, names, rotation=90, fontsize=size)
        ax.set_yticks(ticks, names, fontsize=size)
    else:
        ax.set_xticks([])
        ax.set_yticks([])
    ax.set_xlabel("j (rank order)", fontsize=8)
    ax.set_ylabel("i (rank order)", fontsize=8)
    ax.set_title(f"delay tau*_ij of pairs with C* >= {min_corr:g}", fontsize=9)
    return image


def hierarchy_figure(dc: DirectionalCorrelation, ids, path, title: str = "", min_corr: float = MIN_CORR) -> Path:
    """The network and delay-matrix panels of one flock (see the module docstring); ``ids`` (N,) names the
    individuals; ``min_corr`` is the threshold ``dc`` was computed with."""
    plt = pyplot()
    from matplotlib.colors import Normalize
    labels = [str(i) for i in ids]
    order = np.argsort(dc.rank, kind="stable")
    scale = _delay_scale(dc, min_corr)
    norm, cmap = Normalize(-scale, scale), plt.get_cmap("coolwarm")
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [1.1, 1]})
    _network(left, dc, labels, order, norm, cmap)
    image = _matrix(right, dc, labels, order, norm, cmap, min_corr)
    bar = fig.colorbar(image, ax=right, fraction=0.046, pad=0.04)
    bar.set_label("delay tau* (s): > 0, i leads j", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    fig.suptitle(title, fontsize=10)
    return save(fig, path)
