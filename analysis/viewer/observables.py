"""Per-frame numbers the viewer shows: the one module of the viewer that imports the flock metrics.

``frame_observables(track)`` returns, for every frame of a :class:`~analysis.viewer.track.Track`:

* ``metrics``: {name: float64 (F,)} for :data:`PANEL_METRICS` (polarization, number of groups, mean
  nearest-neighbour distance, cohesion = largest group's share), computed by
  ``analysis.metrics.frame_metrics`` with the track's group radius and periodic box, so they are the
  same numbers as a sweep's time series at the same record;
* ``labels``: int32 (F, N), each boid's group rank at that frame (0 = the largest group, 1 the next;
  ``analysis.groups.neighbour_graph``);
* ``speed``: float64 (F, N), |v|;
* ``group_radius`` used and whether it was ``assumed`` (the track did not say).

``record_metrics(obs, every, group_radius, model)`` gives the metric series of a sweep's record frames
(for the re-simulation check of :mod:`analysis.viewer.resimulate`); ``flock_polarization(vel)``.

When analysis/metrics.py moves, only the imports below change.
"""
from __future__ import annotations

import numpy as np

from analysis.groups import neighbour_graph
from analysis.metrics import frame_metrics, polarization, world_box

from .track import DEFAULT_GROUP_RADIUS, Track

PANEL_METRICS = ("polarization", "n_groups", "nn_distance", "cohesion")


def frame_observables(track: Track) -> dict:
    assumed = track.group_radius is None
    radius = DEFAULT_GROUP_RADIUS if assumed else float(track.group_radius)
    series = frame_metrics(track.pos, track.vel, track.visible, track.binocular, track.pattern, radius, track.box)
    graph = neighbour_graph(track.pos, radius, track.box)
    return {"metrics": {name: np.asarray(series[name], dtype=np.float64) for name in PANEL_METRICS},
            "labels": graph.labels, "speed": np.linalg.norm(track.vel, axis=-1),
            "group_radius": radius, "assumed": assumed}


def flock_polarization(vel: np.ndarray) -> np.ndarray:
    """Polarization of (..., N, 3) velocities (for the animation's time stamp)."""
    return polarization(vel)


def record_metrics(obs, every: int, group_radius: float, model) -> dict:
    """``frame_metrics`` of every ``every``-th record of simulator observations, as a sweep's worker
    computes them (same arrays, radius and box): used to check a re-simulated run's trajectory."""
    pick = slice(None, None, every)
    return frame_metrics(obs.pos[pick], obs.vel[pick], obs.visible[pick], obs.binocular[pick], obs.pattern,
                         group_radius, world_box(model))
