"""Flock metrics computed from recorded observations (never inside the simulator).

Shapes: ``pos``, ``vel`` float64 (..., N, 3); results drop the last two axes, so a whole run's records
(R, N, 3) give a time series (R,). docs/metrics.md gives every formula, range and nan rule.

* ``polarization(vel)`` = |mean_i v_i/|v_i||, in [0, 1]: 1 for a perfectly aligned flock, about
  sqrt(8 / (3 pi N)) for N independent headings uniform on the sphere. Stopped boids (|v| = 0) are
  left out of the mean.
* ``mean_speed(vel)`` = mean_i |v_i|.
* ``frame_metrics(pos, vel, visible, binocular, pattern, group_radius, box=None, record_interval=None)``:
  every per-record metric of :data:`METRIC_NAMES` at once, as a dict of arrays (``overtake_rate``, the
  one metric of a pair of consecutive records, needs the records' spacing ``record_interval`` in
  seconds and a single leading axis of records; it is nan otherwise).
* ``summarize(series, times, warmup=3.0, fragmentation_cohesion=0.5)``: one run's series reduced to
  ``<name>_mean`` (over records at t >= warmup), ``<name>_final``, ``time_to_fragmentation`` and
  ``fragmented``.
Tying the metrics to a model (group radius, periodic box) and a run to its summary row is
:mod:`observables.summary`'s job.

Groups (:mod:`observables.groups`) are the connected components of the graph linking boids closer than the
group radius; in a periodic box every distance is a minimum image and a group's centroid and shape are
taken from its unwrapped layout.
"""
from __future__ import annotations

import numpy as np

from . import kernels
from .groups import check_radius, kernel_box, neighbour_graph, pattern_codes

METRIC_NAMES = kernels.COLUMNS  # every series of frame_metrics, in this order
WARMUP_S = 3.0               # Holland & Semwal: snapshots start 3 s in, once the initial flock formed
FRAGMENTATION_COHESION = 0.5  # fragmented once the largest group holds less than half the flock
K_NEAREST = 6                # the k of the knn_* series (Ballerini et al. 2008: a starling heeds 6-7 neighbours)


def unit_headings(vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit headings, moving mask): v/|v| where |v| > 0, zeros elsewhere."""
    speed = np.linalg.norm(vel, axis=-1)
    moving = speed > 0
    heading = np.divide(vel, speed[..., None], out=np.zeros_like(vel), where=moving[..., None])
    return heading, moving


def polarization(vel: np.ndarray) -> np.ndarray:
    """|mean unit heading| over the moving boids (nan when none moves)."""
    heading, moving = unit_headings(vel)
    count = moving.sum(axis=-1)
    total = heading.sum(axis=-2)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.linalg.norm(total, axis=-1) / np.where(count > 0, count, np.nan)


def mean_speed(vel: np.ndarray) -> np.ndarray:
    return np.linalg.norm(vel, axis=-1).mean(axis=-1)


# ---------------------------------------------------------------------------------------------------
# helpers: one metric each, over any leading shape (the compiled per-record code is in kernels.py)


def _frames(*arrays):
    """Arrays (..., N, k) flattened to (B, N, k) float64, and the leading shape."""
    lead = np.shape(arrays[0])[:-2]
    n = np.shape(arrays[0])[-2]
    return lead, [np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape((-1, n) + np.shape(a)[-1:]))
                  for a in arrays]


def milling(pos: np.ndarray, vel: np.ndarray, box: float | None = None) -> np.ndarray:
    """|mean_i r_hat_i x v_hat_i| with r_i = p_i - flock centroid, in [0, 1]: 1 for a rigid rotation
    about the centroid, 0 for a translating or disordered flock. In a periodic box the flock is
    unwrapped around boid 0 by minimum image first. Boids at the centroid or stopped are left out of
    the mean (nan when none is left)."""
    box_arg = kernel_box(box)
    lead, (p, v) = _frames(pos, vel)
    return np.array([kernels.milling_frame(p[f], v[f], box_arg) for f in range(len(p))]).reshape(lead)


def speed_cv(vel: np.ndarray) -> np.ndarray:
    """Coefficient of variation of the speeds, sd/mean (population sd; nan when all are stopped)."""
    lead, (v,) = _frames(vel)
    return np.array([kernels.speed_frame(v[f])[1] for f in range(len(v))]).reshape(lead)


def visible_mean(visible: np.ndarray) -> np.ndarray:
    """Mean number of perceived neighbours per boid."""
    return np.asarray(visible, dtype=np.float64).mean(axis=-1)


def visible_sd(visible: np.ndarray) -> np.ndarray:
    """Standard deviation across boids (population sd) of the number of perceived neighbours: 0 when every
    boid perceives as many (topological perception of k neighbours, no boid short of k), > 0 when a metric
    range or field lets the counts vary."""
    return np.asarray(visible, dtype=np.float64).std(axis=-1)


def binocular_share(visible: np.ndarray, binocular: np.ndarray) -> np.ndarray:
    """sum binocular / sum visible over the flock, in [0, 1]; 0 when nothing is visible."""
    seen = np.asarray(visible, dtype=np.float64).sum(axis=-1)
    both = np.asarray(binocular, dtype=np.float64).sum(axis=-1)
    return np.divide(both, seen, out=np.zeros_like(seen), where=seen > 0)


def expected_same_share(pattern: np.ndarray) -> np.ndarray:
    """(n_p - 1)/(N - 1) per boid: the same-pattern share of a random other boid (0 when N = 1)."""
    pattern = np.asarray(pattern)
    n = pattern.shape[0]
    _, inverse, counts = np.unique(pattern, return_inverse=True, return_counts=True)
    return (counts[inverse.reshape(-1)] - 1) / max(n - 1, 1)


def segregation(pos: np.ndarray, pattern: np.ndarray, radius: float, box: float | None = None) -> np.ndarray:
    """Mean over boids with a neighbour closer than ``radius`` of (share of those neighbours with the
    boid's pattern - (n_p - 1)/(N - 1)); 0 in expectation under random mixing, > 0 when patterns
    cluster, nan when no boid has a neighbour. ``pos`` (..., N, 3), ``pattern`` (N,)."""
    lead, (p,) = _frames(pos)
    graph = neighbour_graph(p, radius, box, pattern)
    expected = expected_same_share(pattern)
    return np.array([kernels.segregation_frame(graph.degree[f], graph.same[f], expected)
                     for f in range(len(p))]).reshape(lead)


def group_shape(points: np.ndarray, vel: np.ndarray, mask: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Gyration radius, elongation and heading aspect of the boids selected by ``mask`` (..., N).

    ``points`` (..., N, 3) must be contiguous (unwrapped) positions; ``mask`` None selects all. With
    c the centroid of the selected boids, x_i = p_i - c and G = mean_i x_i x_i^T (the gyration tensor,
    eigenvalues l1 >= l2 >= l3):

    * ``gyration_radius`` = sqrt(trace G) = sqrt(mean_i |x_i|^2), the RMS distance from the centroid;
    * ``elongation`` = sqrt(l1 / l2): 1 for an isotropic group, about the ratio of the two largest
      standard deviations otherwise; nan for fewer than 3 boids or l2 = 0 (to rounding: l2 <= 1e-12 l1);
    * ``aspect_heading`` = extent / width. h = normalised sum of the unit headings of the selected
      moving boids; extent = max_i x_i.h - min_i x_i.h; e = the principal axis (top eigenvector) of the
      gyration tensor of the positions projected onto the plane perpendicular to h,
      (I - hh^T) G (I - hh^T), i.e. the major axis of G restricted to that plane (found in an
      orthonormal basis of the plane, so e is exactly perpendicular to h);
      width = max_i x_i.e - min_i x_i.e. So > 1 for a group drawn out along its
      heading (single file), < 1 for a line abreast. nan when no selected boid moves, the headings
      cancel (|sum| <= 1e-12 x count) or the width is zero (to rounding: width <= 1e-12 extent).
    * ``elongation_heading`` = sqrt(h^T G h / m), m the top eigenvalue of (I - hh^T) G (I - hh^T): the
      RMS extent along the heading over the largest RMS extent across it: a second-moment (not a range)
      version of the aspect, so one straggler at distance d moves it by about d^2 / n, not by d. nan
      for fewer than 3 boids, without
      a heading (as the aspect), or when m = 0 (to rounding: m <= 1e-12 h^T G h).

    All nan when nothing is selected.
    """
    lead, (p, v) = _frames(points, vel)
    mask = np.ones(p.shape[:2], dtype=bool) if mask is None else \
        np.ascontiguousarray(np.broadcast_to(mask, np.shape(points)[:-1]).reshape(p.shape[:2]))
    rows = np.array([kernels.shape_frame(p[f], v[f], mask[f]) for f in range(len(p))]).reshape(-1, 4)
    return {name: rows[:, c].reshape(lead)
            for c, name in enumerate(("gyration_radius", "elongation", "aspect_heading", "elongation_heading"))}


def gyration_radius(points: np.ndarray) -> np.ndarray:
    """RMS distance of contiguous points (..., M, 3) from their centroid (see :func:`group_shape`)."""
    return group_shape(points, np.zeros_like(points))["gyration_radius"]


def elongation(points: np.ndarray) -> np.ndarray:
    """sqrt(l1/l2) of the gyration tensor of points (..., M, 3) (see :func:`group_shape`)."""
    return group_shape(points, np.zeros_like(points))["elongation"]


def aspect_heading(points: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Extent along the mean heading / width across it (see :func:`group_shape`)."""
    return group_shape(points, vel)["aspect_heading"]


def elongation_heading(points: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """RMS extent along the mean heading / largest RMS extent across it (see :func:`group_shape`)."""
    return group_shape(points, vel)["elongation_heading"]


def overtake_rate(pos: np.ndarray, vel: np.ndarray, group_radius: float, record_interval: float,
                  box: float | None = None) -> np.ndarray:
    """Overtakes per boid per second between consecutive records of (R, N, 3) positions and
    velocities, record r counting the swaps since record r - 1 (nan at r = 0). An overtake is a pair
    closer than ``group_radius`` at both records whose order along its group's mean heading swaps (the
    heading of the group, a connected component, at each record; see docs/metrics.md)."""
    if np.ndim(pos) != 3:
        raise ValueError(f"pos: expected (R, N, 3) consecutive records, got shape {np.shape(pos)}")
    return frame_metrics(pos, vel, None, None, None, group_radius, box, record_interval)["overtake_rate"]


# ---------------------------------------------------------------------------------------------------
# all metrics of a run


def frame_metrics(pos: np.ndarray, vel: np.ndarray, visible: np.ndarray | None, binocular: np.ndarray | None,
                  pattern: np.ndarray | None, group_radius: float, box: float | None = None,
                  record_interval: float | None = None, k_nearest: int = K_NEAREST,
                  pairwise: bool = True) -> dict[str, np.ndarray]:
    """Every metric of :data:`METRIC_NAMES` for every record, as float64 arrays of shape ``pos.shape[:-2]``.

    ``pos``, ``vel`` (R, N, 3) (or (N, 3) for one record, or any leading shape); ``visible``,
    ``binocular`` int (R, N) as recorded (None: ``visible_mean``, ``visible_sd`` and ``binocular_share`` are nan);
    ``pattern`` (N,) (None: one pattern for all); ``group_radius`` links boids closer than it;
    ``box`` the side of a periodic box (None: open world); ``record_interval`` the seconds between
    consecutive records of (R, N, 3) input (None, or another leading shape: ``overtake_rate`` is nan);
    ``k_nearest`` the k of the ``knn_*`` series; ``pairwise`` False leaves the series that rank every pair
    (``PAIRWISE_SERIES``: ``knn_*``, ``corr_length``) nan. Definitions in docs/metrics.md.
    """
    if np.shape(pos) != np.shape(vel) or np.ndim(pos) < 2 or np.shape(pos)[-1] != 3 or np.shape(pos)[-2] < 1:
        raise ValueError(f"pos and vel: expected equal shapes (..., N, 3), N >= 1, got {np.shape(pos)} "
                         f"and {np.shape(vel)}")
    radius, box_arg = check_radius(group_radius), kernel_box(box)
    lead, (p, v) = _frames(pos, vel)
    n_frames, n = p.shape[:2]
    have_visible = visible is not None and binocular is not None
    if have_visible:
        visible = np.ascontiguousarray(np.asarray(visible, dtype=np.float64).reshape(n_frames, n))
        binocular = np.ascontiguousarray(np.asarray(binocular, dtype=np.float64).reshape(n_frames, n))
    else:
        visible = binocular = np.zeros((n_frames, n))
    codes = pattern_codes(pattern, n)
    interval = -1.0  # the kernel's "no spacing": overtake_rate nan
    if record_interval is not None and len(lead) == 1:
        interval = float(record_interval)
        if not (np.isfinite(interval) and interval > 0):
            raise ValueError(f"record_interval: got {record_interval!r}; expected seconds > 0")
    k_nearest = check_k_nearest(k_nearest)
    table = np.empty((n_frames, len(kernels.COLUMNS)))
    kernels.frame_kernel(p, v, visible, binocular, have_visible, codes, expected_same_share(codes),
                         radius, box_arg, interval, k_nearest, bool(pairwise), table)
    return {name: table[:, kernels.COLUMNS.index(name)].reshape(lead) for name in METRIC_NAMES}


def check_k_nearest(k) -> int:
    """``k`` as an int >= 1, or ValueError."""
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"k_nearest: got {k!r}; expected a whole number >= 1")
    return int(k)


def _nanmean(values: np.ndarray) -> float:
    """The mean of the values that are not nan (nan when none is): ``values.mean()``'s own sum and division
    (numpy's mean is ``add.reduce`` divided by the count), without its per-call overhead (a sweep of small
    runs calls this 27 times a run)."""
    values = values[~np.isnan(values)]
    return float(np.add.reduce(values) / values.size) if values.size else float("nan")


def summarize(series: dict, times: np.ndarray, warmup: float = WARMUP_S,
              fragmentation_cohesion: float = FRAGMENTATION_COHESION) -> dict[str, float]:
    """One run's metric series (name -> (R,)) reduced to floats.

    * ``<name>_mean``: mean over the records with time >= ``warmup``, nan records left out (nan when
      none is left);
    * ``<name>_final``: the last record;
    * ``time_to_fragmentation``: the first recorded time >= ``warmup`` with cohesion <
      ``fragmentation_cohesion`` (nan when that never happens), and ``fragmented`` 1.0 / 0.0.

    Defaults: warmup 3 s (Holland & Semwal's first snapshot), fragmentation below cohesion 0.5. The
    record interval (1 s in the presets) is the caller's.
    """
    times = np.asarray(times, dtype=np.float64)
    if times.ndim != 1 or times.size == 0:
        raise ValueError(f"times: expected a non-empty 1-D array, got shape {times.shape}")
    window = times >= warmup
    out: dict[str, float] = {}
    for name, values in series.items():
        values = np.asarray(values, dtype=np.float64)
        if values.shape != times.shape:
            raise ValueError(f"series {name!r}: shape {values.shape} does not match times {times.shape}")
        out[f"{name}_mean"] = _nanmean(values[window])
        out[f"{name}_final"] = float(values[-1])
    if "cohesion" not in series:
        raise ValueError("summarize: the series need 'cohesion' for time_to_fragmentation")
    broken = window & (np.asarray(series["cohesion"], dtype=np.float64) < fragmentation_cohesion)
    hit = np.flatnonzero(broken)
    out["time_to_fragmentation"] = float(times[hit[0]]) if hit.size else float("nan")
    out["fragmented"] = 1.0 if hit.size else 0.0
    return out
