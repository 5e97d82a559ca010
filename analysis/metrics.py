"""Flock metrics computed from recorded observations (never inside the simulator).

Shapes: ``vel`` float64 (..., N, 3); results drop the last two axes, so a whole run's records
(R, N, 3) give a time series (R,).

* ``polarization(vel)`` = |mean_i v_i/|v_i||, in [0, 1]: 1 for a perfectly aligned flock, about
  sqrt(8 / (3 pi N)) for N independent headings uniform on the sphere. Stopped boids (|v| = 0) are
  left out of the mean.
* ``mean_speed(vel)`` = mean_i |v_i|.
"""
from __future__ import annotations

import numpy as np


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
