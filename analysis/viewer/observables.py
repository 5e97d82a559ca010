"""Per-frame numbers the viewer shows, from the flock metrics of the observables layer.

``frame_observables(track)`` returns, for every frame of a :class:`~analysis.viewer.track.Track`:

* ``metrics``: {name: float64 (F,)} for :data:`PANEL_METRICS` (polarization, number of groups, mean
  nearest-neighbour distance, cohesion = largest group's share), with the definitions of
  docs/metrics.md, from one pass of ``observables.groups.neighbour_graph`` (the graph the sweep's metrics
  use) with the track's group radius and periodic box: a sweep's time series at the same record agree
  to rounding (summation order);
* ``labels``: int32 (F, N), each boid's group rank at that frame (0 = the largest group, 1 the next);
* ``speed``: float64 (F, N), |v|;
* ``group_radius`` used and whether it was ``assumed`` (the track did not say).

``group_labels(track)`` gives the
labels alone; ``record_metrics(obs, every, group_radius, model)`` the metric series of a sweep's record
frames (for the re-simulation check of :mod:`analysis.viewer.resimulate`).
"""
from __future__ import annotations

import numpy as np

from flocksweep.observables.groups import neighbour_graph
from flocksweep.observables.metrics import frame_metrics, polarization
from flocksweep.observables.summary import world_box

from .track import DEFAULT_GROUP_RADIUS, Track, metric_settings

PANEL_METRICS = ("polarization", "n_groups", "nn_distance", "cohesion")


def _radius(track: Track) -> tuple[float, bool]:
    assumed = track.group_radius is None
    return (DEFAULT_GROUP_RADIUS if assumed else float(track.group_radius)), assumed


def frame_observables(track: Track) -> dict:
    radius, assumed = _radius(track)
    graph = neighbour_graph(track.pos, radius, track.box)
    n = track.n
    nn = np.full(track.frames, np.nan) if n < 2 else graph.nn.mean(axis=1)
    metrics = {"polarization": np.asarray(polarization(track.vel), dtype=np.float64),
               "n_groups": graph.n_groups.astype(np.float64), "nn_distance": nn,
               "cohesion": (graph.labels == 0).sum(axis=1) / n}
    return {"metrics": metrics, "labels": graph.labels, "speed": np.linalg.norm(track.vel, axis=-1),
            "group_radius": radius, "assumed": assumed}


def group_labels(track: Track) -> np.ndarray:
    """Group ranks (F, N) alone (for page size estimates)."""
    return neighbour_graph(track.pos, _radius(track)[0], track.box).labels


def record_metrics(obs, every: int, group_radius: float, model) -> dict:
    """``frame_metrics`` of every ``every``-th record of simulator observations, as a sweep's worker
    computes them (same arrays, radius and box): used to check a re-simulated run's trajectory."""
    pick = slice(None, None, every)
    interval = int(obs.record_every) * int(every) * float(obs.dt)  # as summary.record_interval of the picks
    return frame_metrics(obs.pos[pick], obs.vel[pick], obs.visible[pick], obs.binocular[pick], obs.pattern,
                         group_radius, world_box(model), interval)
