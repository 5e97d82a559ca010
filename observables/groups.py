"""The neighbour graph of a flock: groups, nearest neighbours and pattern-matched neighbour counts.

Two boids are linked when their distance is strictly less than the group radius (minimum image in a
periodic box of side L: ``d - L floor(d/L + 0.5)``, as the simulator does). Groups are the connected
components of that graph; a boid with no link is a stray and a group of its own.

``neighbour_graph(pos, radius, box=None, pattern=None)`` does every record of a run in one compiled
pass (O(N^2) pairs per record, analysis/kernels.py) and returns a :class:`Graph`;
``groups(pos_frame, radius, box=None)`` gives the labels of one record.

Labels rank the groups: 0 is the largest group, 1 the next, ...; groups of equal size are ranked by their
lowest boid index. ``Graph.unwrapped`` holds positions with every group laid out contiguously: in an open
world they are the positions themselves; in a periodic box each group is unwrapped from its lowest-index
boid along the links of a breadth-first tree, each boid placed at its parent plus the minimum-image
offset between them. That equals unwrapping around one member by minimum image whenever the group spans
less than half the box, and stays right for long, chain-like groups (every link is shorter than the
group radius); a group that wraps all the way round the box has no unwrapped layout and gets an
arbitrary one.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .kernels import graph_run


def check_radius(radius: float) -> float:
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"group radius: got {radius!r}; must be a finite number > 0")
    return float(radius)


def kernel_box(box: float | None) -> float:
    """The box as the kernels take it: its side, or -1.0 for an open world (None)."""
    if box is None:
        return -1.0
    if not (np.isfinite(box) and box > 0):
        raise ValueError(f"box: got {box!r}; must be None or a finite number > 0")
    return float(box)


def pattern_codes(pattern: np.ndarray | None, n: int) -> np.ndarray:
    """Patterns (N,) as int64 for the kernels; None means one pattern (0) for all."""
    if pattern is None:
        return np.zeros(n, np.int64)
    codes = np.ascontiguousarray(pattern, dtype=np.int64)
    if codes.shape != (n,):
        raise ValueError(f"pattern: expected shape ({n},), got {codes.shape}")
    return codes


class Graph(NamedTuple):
    """Neighbour graph of every record: (R, N) arrays unless noted."""

    labels: np.ndarray     # int32 group rank of each boid, 0 = largest group
    n_groups: np.ndarray   # int64 (R,) number of groups (strays included)
    unwrapped: np.ndarray  # float64 (R, N, 3) positions with each group laid out contiguously
    nn: np.ndarray         # float64 nearest-neighbour distance (nan when N = 1)
    degree: np.ndarray     # int32 links of each boid (neighbours closer than the radius)
    same: np.ndarray       # int32 of those, neighbours with the same pattern


def neighbour_graph(pos: np.ndarray, radius: float, box: float | None = None,
                    pattern: np.ndarray | None = None) -> Graph:
    """Graph of every record of ``pos`` (R, N, 3); ``pattern`` (N,) feeds ``Graph.same`` (None: all 0)."""
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[-1] != 3 or pos.shape[1] < 1:
        raise ValueError(f"pos: expected shape (R, N, 3) with N >= 1, got {pos.shape}")
    n_frames, n = pos.shape[:2]
    pattern = pattern_codes(pattern, n)
    labels = np.empty((n_frames, n), np.int32)
    unwrapped = np.empty((n_frames, n, 3))
    nn = np.empty((n_frames, n))
    degree = np.empty((n_frames, n), np.int32)
    same = np.empty((n_frames, n), np.int32)
    n_groups = np.empty(n_frames, np.int64)
    graph_run(pos, pattern, check_radius(radius), kernel_box(box), labels, unwrapped, nn, degree, same, n_groups)
    return Graph(labels, n_groups, unwrapped, nn, degree, same)


def groups(pos_frame: np.ndarray, radius: float, box: float | None = None) -> np.ndarray:
    """Group label of each boid of one record (N, 3): 0 = largest group (see module docstring)."""
    return neighbour_graph(np.asarray(pos_frame)[None], radius, box).labels[0]
