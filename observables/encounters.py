"""What a flock does around obstacles, a predator and prey, measured from a run's records.

Three families of metrics, each computed only when the run has the thing it measures (so runs of models
without obstacles, predator or prey keep exactly their rows): obstacles when the model has
``world.obstacles``, predator metrics when the observations carry ``predator`` positions (R, 3), prey
metrics when they carry ``prey`` positions (R, 3). Every family gives per-record series (their
``<name>_mean`` over the records at t >= warm-up and ``<name>_final`` go into the row, the series into
the per-run series files) and run scalars. docs/metrics.md ("Obstacles, predator and prey") gives every
definition and nan rule; in short:

* obstacles (body radius b, signed clearance sd from :func:`simcore.obstacles.clearances`): a boid
  *collides* at a record when min_k sd_k(p_i) < b (its body overlaps an obstacle); series
  ``collisions``, ``collision_fraction``, ``clearance`` (min_i min_k sd - b); scalars over the records
  at t >= warm-up: ``collided_boids``, ``collision_events`` (onsets), ``clearance_min``.
* predator (flock centre c = mean position; "near" = |c - predator| <= ``predator_near``): series
  ``predator_distance`` (nearest boid), ``predator_near`` (0/1), ``predator_in_capture`` (boids within
  ``capture_radius``), ``flock_gyration_radius`` (whole flock); scalars ``predator_captures`` (distinct
  boids ever within the capture radius), ``predator_distance_min``, the flash expansion
  ``flash_nn_ratio`` and ``flash_gyration_ratio`` (mean while near / mean before the predator first
  came near), ``groups_before_predator``, ``groups_near_predator``, ``groups_near_predator_max`` and
  ``remerge_time`` (from the predator's first departure to the flock being one group again).
* prey: series ``prey_distance`` (flock centre to prey), ``prey_within_fraction`` (boids within
  ``prey_reach``); scalars ``prey_reach_time`` (first time the centre is within ``prey_reach``) and
  ``prey_first_reach_time`` (first time any boid is), measured from the start of the run.

In a periodic box of side L every offset is a minimum image and the flock is unwrapped around boid 0
(as ``milling`` does) for its centre and gyration radius.

``encounter_metrics(obs, settings, series) -> (series, scalars)`` is what
:func:`observables.summary.measure_run` calls (``series``: the run's per-record metrics, for
``nn_distance`` and ``n_groups``); :func:`encounter_columns` lists the row columns of each family.
``agent_positions(obs, pick)`` is the one way to take a run's recorded agents (``AGENTS``: the
predator's and the prey's (R, 3) positions, those the run has), e.g. to keep every k-th record or to
write them to a trajectory file.
"""
from __future__ import annotations

import numpy as np

from flocksweep.simcore.obstacle_spec import pack_obstacles
from flocksweep.simcore.obstacles import clearances

from .columns import (FAMILIES, OBSTACLE_SCALARS, OBSTACLE_SERIES, PREDATOR_SCALARS,  # noqa: F401 - declared there
                      PREDATOR_SERIES, PREY_SCALARS, PREY_SERIES, encounter_columns)


AGENTS = ("predator", "prey")  # the agents a run may record besides the boids: Observations attributes

CAPTURE_RADIUS = 1.0   # a boid's and the predator's bodies (radius 0.5 each) touch
PREDATOR_NEAR = 10.0   # the predator is near when this close to the flock centre
PREY_REACH = 5.0       # the flock has reached the prey when its centre is this close


def _fold(d: np.ndarray, box: float | None) -> np.ndarray:
    return d if box is None else d - box * np.floor(d / box + 0.5)


def _unwrapped(pos: np.ndarray, box: float | None) -> np.ndarray:
    """Positions (R, N, 3) unwrapped around boid 0 by minimum image (unchanged in an open world)."""
    if box is None:
        return pos
    return pos[:, :1, :] + _fold(pos - pos[:, :1, :], box)


def flock_centre(pos: np.ndarray, box: float | None = None) -> np.ndarray:
    """(R, 3) mean position of every record (in a periodic box, of the flock unwrapped around boid 0)."""
    return _unwrapped(np.asarray(pos, dtype=np.float64), box).mean(axis=1)


def flock_gyration_radius(pos: np.ndarray, box: float | None = None) -> np.ndarray:
    """(R,) RMS distance of every boid from the flock centre (the whole flock, not its largest group)."""
    points = _unwrapped(np.asarray(pos, dtype=np.float64), box)
    offsets = points - points.mean(axis=1, keepdims=True)
    return np.sqrt((offsets * offsets).sum(axis=2).mean(axis=1))


def agent_distances(pos: np.ndarray, agent: np.ndarray, box: float | None = None) -> np.ndarray:
    """(R, N) distance of every boid to an agent's position (R, 3) at each record."""
    return np.linalg.norm(_fold(np.asarray(pos) - np.asarray(agent)[:, None, :], box), axis=2)


def _ratio(top: float, bottom: float) -> float:
    """top / bottom, nan when either is nan or bottom is 0."""
    return top / bottom if bottom != 0.0 and not (np.isnan(top) or np.isnan(bottom)) else float("nan")


def _window_mean(values: np.ndarray, mask: np.ndarray) -> float:
    picked = values[mask & ~np.isnan(values)]
    return float(picked.mean()) if picked.size else float("nan")


def series_summary(series: dict, times: np.ndarray, warmup: float) -> dict[str, float]:
    """``<name>_mean`` (records at t >= warmup, nan left out) and ``<name>_final`` of every series."""
    window = np.asarray(times) >= warmup
    out = {}
    for name, values in series.items():
        out[f"{name}_mean"] = _window_mean(np.asarray(values, dtype=np.float64), window)
        out[f"{name}_final"] = float(values[-1])
    return out


# ---------------------------------------------------------------------------------------------------
# obstacles


def obstacle_clearance(pos: np.ndarray, obstacles) -> np.ndarray:
    """(R, N) signed clearance min_k sd_k(p_i) of every boid centre to the nearest obstacle surface
    (negative inside), from the compiled geometry."""
    table, kinds = pack_obstacles(obstacles)
    pos = np.asarray(pos, dtype=np.float64)
    out = np.empty(pos.shape[:2])
    for r in range(pos.shape[0]):
        out[r] = clearances(table, kinds, np.ascontiguousarray(pos[r])).min(axis=1)
    return out


def obstacle_metrics(pos: np.ndarray, times: np.ndarray, obstacles, body_radius: float,
                     warmup: float) -> tuple[dict, dict]:
    """(series, scalars) of the obstacle family (see the module docstring)."""
    gap = obstacle_clearance(pos, obstacles) - body_radius   # < 0: the body overlaps an obstacle
    hit = gap < 0.0
    series = {"collisions": hit.sum(axis=1).astype(np.float64), "collision_fraction": hit.mean(axis=1),
              "clearance": gap.min(axis=1)}
    window = np.asarray(times) >= warmup
    hits = hit[window]
    onsets = hits.copy()
    onsets[1:] &= ~hits[:-1]
    scalars = {"collided_boids": float(hits.any(axis=0).sum()), "collision_events": float(onsets.sum()),
               "clearance_min": float(gap[window].min()) if window.any() else float("nan")}
    return series, scalars


# ---------------------------------------------------------------------------------------------------
# predator and prey


def _first_time(times: np.ndarray, mask: np.ndarray) -> float:
    hit = np.flatnonzero(mask)
    return float(times[hit[0]]) if hit.size else float("nan")


def remerge_time(times: np.ndarray, near: np.ndarray, n_groups: np.ndarray) -> float:
    """Seconds from the predator's first departure (the first record not near after the first near
    record) to the first record from then on with one group; nan when it never comes near, never
    leaves or the flock never is one group again after it left. 0 when the flock is one group as it leaves."""
    came = np.flatnonzero(near)
    if not came.size:
        return float("nan")
    left = np.flatnonzero(~near[came[0]:])
    if not left.size:
        return float("nan")
    leave = came[0] + left[0]
    whole = np.flatnonzero(n_groups[leave:] == 1)
    return float(times[leave + whole[0]] - times[leave]) if whole.size else float("nan")


def predator_metrics(pos: np.ndarray, predator: np.ndarray, times: np.ndarray, nn_distance: np.ndarray,
                     n_groups: np.ndarray, capture_radius: float, near_distance: float, warmup: float,
                     box: float | None = None) -> tuple[dict, dict]:
    """(series, scalars) of the predator family; ``nn_distance`` and ``n_groups`` are the run's
    per-record series of those metrics (see the module docstring and docs/metrics.md)."""
    times = np.asarray(times, dtype=np.float64)
    distance = agent_distances(pos, predator, box)
    centre_gap = np.linalg.norm(_fold(flock_centre(pos, box) - predator, box), axis=1)
    near = centre_gap <= near_distance
    caught = distance <= capture_radius
    gyration = flock_gyration_radius(pos, box)
    series = {"predator_distance": distance.min(axis=1), "predator_near": near.astype(np.float64),
              "predator_in_capture": caught.sum(axis=1).astype(np.float64), "flock_gyration_radius": gyration}
    window = times >= warmup
    near_w = near & window
    first = np.flatnonzero(near_w)
    before = window & (np.arange(len(times)) < (first[0] if first.size else len(times)))
    groups = np.asarray(n_groups, dtype=np.float64)
    nn = np.asarray(nn_distance, dtype=np.float64)
    scalars = {
        "predator_captures": float(caught[window].any(axis=0).sum()),
        "predator_distance_min": _present_min(series["predator_distance"][window]),
        "flash_nn_ratio": _ratio(_window_mean(nn, near_w), _window_mean(nn, before)),
        "flash_gyration_ratio": _ratio(_window_mean(gyration, near_w), _window_mean(gyration, before)),
        "groups_before_predator": _window_mean(groups, before),
        "groups_near_predator": _window_mean(groups, near_w),
        "groups_near_predator_max": float(groups[near_w].max()) if near_w.any() else float("nan"),
        "remerge_time": remerge_time(times[window], near[window], groups[window]),
    }
    return series, scalars


def _present_min(values: np.ndarray) -> float:
    """The smallest value over the records where the agent is present (not NaN); NaN if it never is."""
    present = values[np.isfinite(values)]
    return float(present.min()) if present.size else float("nan")


def prey_metrics(pos: np.ndarray, prey: np.ndarray, times: np.ndarray, reach: float,
                 box: float | None = None) -> tuple[dict, dict]:
    """(series, scalars) of the prey family (see the module docstring)."""
    times = np.asarray(times, dtype=np.float64)
    centre_gap = np.linalg.norm(_fold(flock_centre(pos, box) - prey, box), axis=1)
    within = agent_distances(pos, prey, box) <= reach
    series = {"prey_distance": centre_gap, "prey_within_fraction": within.mean(axis=1)}
    scalars = {"prey_reach_time": _first_time(times, centre_gap <= reach),
               "prey_first_reach_time": _first_time(times, within.any(axis=1))}
    return series, scalars


# ---------------------------------------------------------------------------------------------------
# one run


def agent_positions(obs, pick=slice(None)) -> dict:
    """{name: positions[pick]} of the :data:`AGENTS` the observations record (those not None)."""
    return {name: getattr(obs, name)[pick] for name in AGENTS if getattr(obs, name, None) is not None}


def _agent(obs, name: str, n_records: int):
    agent = getattr(obs, name, None)
    if agent is None:
        return None
    agent = np.asarray(agent, dtype=np.float64)
    if agent.shape != (n_records, 3):
        raise ValueError(f"observations.{name}: expected shape ({n_records}, 3) (one position per record), "
                         f"got {agent.shape}")
    return agent


def encounter_metrics(obs, settings, series: dict) -> tuple[dict, dict]:
    """(series, row columns) of every family the run has; empty dicts for a run with none.

    ``settings`` is a resolved :class:`~observables.summary.MetricSettings` (obstacles, body
    radius, capture radius, near distance, prey reach, warm-up, box); ``series`` the run's per-record
    metrics (``nn_distance`` and ``n_groups`` are read)."""
    pos, times = obs.pos, np.asarray(obs.times, dtype=np.float64)
    out_series, row = {}, {}
    families = []
    if settings.obstacles:
        families.append(obstacle_metrics(pos, times, settings.obstacles, settings.body_radius, settings.warmup))
    predator = _agent(obs, "predator", len(times))
    if predator is not None:
        families.append(predator_metrics(pos, predator, times, series["nn_distance"], series["n_groups"],
                                         settings.capture_radius, settings.predator_near, settings.warmup,
                                         settings.box))
    prey = _agent(obs, "prey", len(times))
    if prey is not None:
        families.append(prey_metrics(pos, prey, times, settings.prey_reach, settings.box))
    for family_series, scalars in families:
        out_series.update(family_series)
        row.update(series_summary(family_series, times, settings.warmup))
        row.update(scalars)
    return out_series, row
