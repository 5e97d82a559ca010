"""Where a flock sits relative to its tank's side walls: how close individuals keep to them and how they
head near them (a fish group turning along the wall of a tank), for a run in an arena and for tracks that
declare theirs.

``tank_walls(arena) -> Walls | None``: the side walls of an arena (anything with ``kind``, ``centre``,
``radius`` and ``size``: a preset's :class:`simcore.arena.Arena`, or the tank a tracks file declares,
in the analysis unit), or None for ``kind = "none"``. Only the side walls count, seen in the x-y plane
(the plane of 2-D tracks and 2-D models; a 3-D cylinder stands along z): a cylinder's circle of radius
R about (cx, cy), a box's rectangle of sides sx x sy; a 3-D tank's floor and ceiling are left out, so a
3-D run seen from above (``projection = "xy"``) and the same run seen whole measure the same.

``wall_metrics(pos, vel, times, warmup, walls) -> dict`` of :data:`WALL_METRIC_NAMES`, over every
individual seen (finite position) at a record with ``times >= warmup``, pooled over individuals and
records:

* d, the distance to the nearest side wall (length): R - |p - c| in a circle, min(sx/2 - |x - cx|,
  sy/2 - |y - cy|) in a rectangle; negative outside (a tracker's error, a boid the wall term did not hold);
* ``wall_distance_mean``, ``wall_distance_q10``, ``wall_distance_q50``: the mean and the 10 and 50 %
  quantiles of d (``numpy.quantile``'s linear rule);
* ``wall_facing_near`` (1): over the samples in the quarter nearest a wall (d at or below the 25 %
  quantile of d) that move in the plane (|v_xy| > 1e-12), the mean of |u . n|, u = v_xy / |v_xy| the
  heading in the plane and n the outward normal of the nearest wall ((p - c) / |p - c| in a circle; the
  nearest face's axis in a rectangle, x on a tie): 0 when individuals near the wall swim along it, 1 when
  they head straight at it or away; about 2/pi (0.64) for headings uniform in angle.

Each is nan when it has no term (no sample in the window; no moving sample near the wall for the last).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .columns import WALL_METRIC_NAMES

NEAR_QUANTILE = 0.25   # wall_facing_near: the samples at or below this quantile of the wall distance
TINY = 1e-12


class Walls(NamedTuple):
    """A tank's side walls in the x-y plane (module docstring); hashable, so metric settings stay frozen."""

    kind: str                       # "cylinder" (a circle) or "box" (a rectangle)
    centre: tuple[float, float]
    radius: float                   # the circle's
    size: tuple[float, float]       # the rectangle's sides along x and y


def tank_walls(arena) -> Walls | None:
    """The side walls of ``arena`` (module docstring), None when it has none."""
    if arena is None or arena.kind == "none":
        return None
    return Walls(str(arena.kind), (float(arena.centre[0]), float(arena.centre[1])), float(arena.radius),
                 (float(arena.size[0]), float(arena.size[1])))


def wall_distance(walls: Walls, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(d, nx, ny): the distance of each point to the nearest side wall (negative outside) and that wall's
    outward unit normal (zero at a circle's centre, where no wall is nearest)."""
    dx, dy = x - walls.centre[0], y - walls.centre[1]
    if walls.kind == "cylinder":
        r = np.hypot(dx, dy)
        safe = np.where(r > 0.0, r, 1.0)
        return walls.radius - r, np.where(r > 0.0, dx / safe, 0.0), np.where(r > 0.0, dy / safe, 0.0)
    gap_x = walls.size[0] / 2.0 - np.abs(dx)
    gap_y = walls.size[1] / 2.0 - np.abs(dy)
    along_x = gap_x <= gap_y
    nx = np.where(along_x, np.where(dx >= 0.0, 1.0, -1.0), 0.0)
    ny = np.where(along_x, 0.0, np.where(dy >= 0.0, 1.0, -1.0))
    return np.minimum(gap_x, gap_y), nx, ny


def wall_metrics(pos: np.ndarray, vel: np.ndarray, times: np.ndarray, warmup: float, walls: Walls) -> dict:
    """The scalars of :data:`WALL_METRIC_NAMES` of one run (module docstring); ``pos`` and ``vel`` (R, N, 3),
    nan where an individual is not seen."""
    window = np.asarray(times, dtype=np.float64) >= warmup
    p = np.asarray(pos, dtype=np.float64)[window].reshape(-1, 3)
    v = np.asarray(vel, dtype=np.float64)[window].reshape(-1, 3)
    seen = np.isfinite(p[:, 0]) & np.isfinite(p[:, 1])
    p, v = p[seen], v[seen]
    if p.shape[0] == 0:
        return {name: math.nan for name in WALL_METRIC_NAMES}
    d, nx, ny = wall_distance(walls, p[:, 0], p[:, 1])
    q10, q25, q50 = np.quantile(d, [0.10, NEAR_QUANTILE, 0.50])
    speed = np.hypot(v[:, 0], v[:, 1])
    near = (d <= q25) & (speed > TINY) & np.isfinite(speed) & ((nx != 0.0) | (ny != 0.0))
    facing = math.nan
    if near.any():
        facing = float(np.mean(np.abs(v[near, 0] * nx[near] + v[near, 1] * ny[near]) / speed[near]))
    return {"wall_distance_mean": float(np.mean(d)), "wall_distance_q10": float(q10),
            "wall_distance_q50": float(q50), "wall_facing_near": facing}
