"""Migratory progress: how far a flock with a migratory urge travels along the urge's direction.

``migration_metrics(pos, vel, times, direction, warmup) -> {"migratory_progress", "migratory_efficiency"}``
(docs/metrics.md, "Migratory progress"), from the records with time >= ``warmup`` (records t_a .. t_b, the
first and last of them; pos, vel float64 (R, N, 3), times (R,), direction a unit 3-vector g):

* ``migratory_progress`` = (c(t_b) - c(t_a)) . g / (t_b - t_a), c the flock centre (mean position):
  the displacement of the centre along g per second (units/s);
* ``migratory_efficiency`` = migratory_progress / mean speed over the same records (each record's mean
  boid speed, averaged): the share of the flock's speed that carries it along g (1 for a flock flying
  straight along g, 0 for one that does not travel that way, negative against it).

Both are nan when fewer than two records lie in the window (or the mean speed is 0 for the efficiency).
Only defined in an open world (a wrapped or periodic centre is no displacement): the summary adds them
when the model has a migratory urge and an open boundary (:meth:`summary.MetricSettings.resolve`).
"""
from __future__ import annotations

import numpy as np

from .columns import MIGRATION_METRIC_NAMES  # declared there, part of this module's face



def migration_metrics(pos, vel, times, direction, warmup: float) -> dict[str, float]:
    """The two migration scalars of one run (module docstring)."""
    times = np.asarray(times, dtype=np.float64)
    window = np.flatnonzero(times >= warmup)
    if window.size < 2:
        return {name: float("nan") for name in MIGRATION_METRIC_NAMES}
    a, b = window[0], window[-1]
    g = np.asarray(direction, dtype=np.float64)
    shift = np.asarray(pos[b]).mean(axis=0) - np.asarray(pos[a]).mean(axis=0)
    progress = float(shift @ g / (times[b] - times[a]))
    speed = float(np.linalg.norm(np.asarray(vel)[window], axis=2).mean(axis=1).mean())
    efficiency = progress / speed if speed > 0.0 else float("nan")
    return {"migratory_progress": progress, "migratory_efficiency": efficiency}
