"""One run's observations -> its summary row: the one place sweeps, calibration and users turn a
simulation into numbers.

:class:`MetricSettings` says how records become a row: the warm-up excluded from window means, the
group radius linking boids (None: the model's perception range), the cohesion below which the flock
counts as fragmented, whether the leadership metrics and the directional correlation delays (with
their largest delay) are computed, the capture radius, predator "near"
distance and prey reach of the encounter metrics (:mod:`observables.encounters`), and the values
a model fixes: the periodic box side, the escape duration, the obstacles and the body radius.
:meth:`MetricSettings.resolve` fills those in from a model; a configuration file sets the others (its
``[run]`` table).

``summarize_run(obs, settings) -> dict`` is the row: for every per-record metric of
:data:`~observables.metrics.METRIC_NAMES` its ``<name>_mean`` and ``<name>_final``, then
``time_to_fragmentation`` and ``fragmented`` (:func:`~observables.metrics.summarize`), then,
with ``settings.leadership``, the leadership scalars
(:data:`~observables.leadership.LEADERSHIP_METRIC_NAMES`), then, with ``settings.dcd``, the directional
correlation delays of Nagy et al. 2010 (:data:`~observables.directional_correlation.DCD_METRIC_NAMES`, of
:func:`run_directional_correlation`: over the records at or after the warm-up, delays up to
``settings.dcd_max_delay``; they need only velocities, so measured flocks and observed runs have them
too), then, when the model has a migratory
urge (``settings.migration``, its direction), the migration scalars
(:data:`~observables.migration.MIGRATION_METRIC_NAMES`), then, when the run has a tank (``settings.walls``:
the model's arena, or the tank a tracks file declares), its wall scalars
(:data:`~observables.columns.WALL_METRIC_NAMES`, :mod:`~observables.walls`), then the obstacle, predator and prey
columns of the families the run has (obstacles in the model, ``predator`` / ``prey`` positions in the
observations); :func:`summary_columns` lists them in that order. ``measure_run(obs, settings)`` gives the
row together with the per-record series (plus ``leaders``, the number of leaders per record, with
leadership on). ``settings`` must be resolved. The row is a pure function of the observations and the settings. Observations with a ``present`` mask
(an :class:`~observables.observed.ObservedFlock`: measured tracks, or a run seen through an
observation model) are measured record by record over the individuals present
(:func:`~observables.observed.present_metrics`), and their series and row add ``tracked``
(individuals present per record; ``tracked_mean``, ``tracked_final``).

``record_interval(obs)`` is the seconds between records (``overtake_rate`` needs it).
``check_finite(obs)`` raises :class:`NonFiniteState` when a position or velocity is not finite;
``every_nth(obs, k)`` keeps every k-th record (records at the record interval of a run recorded more
finely, e.g. for stored trajectories). ``default_group_radius(model)``, ``world_box(model)``,
``observation_metrics(obs, model)`` and ``observation_leadership(obs, model)`` tie single metrics to a
model for users.
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from flocksweep.simcore.registry import describe
from flocksweep.simcore.schema import ConfigError, check_finite as _finite, check_non_negative, check_positive, check_within

from .columns import RUN_COLUMNS, summary_columns  # noqa: F401 - declared there, part of this module's face
from .directional_correlation import (DCD_MAX_DELAY, DCD_METRIC_NAMES, DirectionalCorrelation, dcd_scalars,
                                      directional_correlation)
from .encounters import (CAPTURE_RADIUS, FAMILIES, PREDATOR_NEAR, PREY_REACH, agent_positions, encounter_columns,
                         encounter_metrics)
from .leadership import LEADERSHIP_METRIC_NAMES, leadership_metrics
from .migration import MIGRATION_METRIC_NAMES, migration_metrics
from .metrics import FRAGMENTATION_COHESION, K_NEAREST, METRIC_NAMES, WARMUP_S, frame_metrics, summarize
from .motion import STATE_HIGH, STATE_LOW, motion_metrics
from .observed import present_metrics
from .walls import Walls, tank_walls, wall_metrics

ENCOUNTER_FAMILIES = tuple(FAMILIES)  # "obstacles", "predator", "prey"
# the settings of the obstacle, predator and prey metrics (keys of [run]), with their defaults
ENCOUNTER_SETTINGS = {"capture_radius": CAPTURE_RADIUS, "predator_near": PREDATOR_NEAR, "prey_reach": PREY_REACH}
# the settings of the observables of collective motion (keys of [run]), with their defaults
MOTION_SETTINGS = {"k_nearest": K_NEAREST, "pairwise_metrics": True, "state_high": STATE_HIGH, "state_low": STATE_LOW}


class NonFiniteState(RuntimeError):
    """A run's trajectory holds a non-finite position or velocity."""


@dataclasses.dataclass(frozen=True)
class MetricSettings:
    """How a run's records become its row (see the module docstring)."""

    warmup: float = WARMUP_S
    group_radius: float | None = None          # None: the model's perception range
    fragmentation_cohesion: float = FRAGMENTATION_COHESION
    leadership: bool = False
    box: float | None = None                   # periodic box side; None: no periodic box
    escape_duration: float | None = None       # the model's leadership.duration (set by resolve)
    capture_radius: float = CAPTURE_RADIUS     # predator captures: boids this close to it
    predator_near: float = PREDATOR_NEAR       # the predator is near: this close to the flock centre
    prey_reach: float = PREY_REACH             # the prey is reached: the flock centre this close
    obstacles: tuple = ()                      # the model's world.obstacles (set by resolve)
    body_radius: float | None = None           # the model's perception.body_radius (set by resolve)
    migration: tuple[float, float, float] | None = None  # the model's migration direction (set by resolve)
    dcd: bool = False                          # the directional correlation delays (DCD_METRIC_NAMES)
    dcd_max_delay: float = DCD_MAX_DELAY       # s: their largest delay
    k_nearest: int = K_NEAREST                 # the k of the knn_* series
    pairwise_metrics: bool = True              # False: the PAIRWISE_SERIES (knn_*, corr_length) are nan
    state_high: float = STATE_HIGH             # Tunstrom et al. 2013's thresholds of the state fractions
    state_low: float = STATE_LOW
    walls: Walls | None = None                 # the tank's side walls (set by resolve; tracks: their own tank)

    def __post_init__(self):
        for key in ENCOUNTER_SETTINGS:
            check_positive(key, getattr(self, key))
        if isinstance(self.k_nearest, bool) or not isinstance(self.k_nearest, (int, np.integer)) or self.k_nearest < 1:
            raise ConfigError("k_nearest", f"got {self.k_nearest!r}; expected a whole number >= 1")
        if not isinstance(self.pairwise_metrics, (bool, np.bool_)):
            raise ConfigError("pairwise_metrics", f"got {self.pairwise_metrics!r}; expected true or false")
        check_within("state_high", self.state_high, 0.0, 1.0)
        check_within("state_low", self.state_low, 0.0, 1.0)
        if self.state_low > self.state_high:
            raise ConfigError("state_low", f"got {self.state_low!r}, above state_high = {self.state_high!r}; a low "
                                           "order parameter must lie below a high one")
        check_non_negative("warmup", self.warmup)
        check_non_negative("dcd_max_delay", self.dcd_max_delay)
        if self.group_radius is not None:
            _finite("group_radius", self.group_radius)
            if self.group_radius <= 0:
                raise ConfigError("group_radius", f"got {self.group_radius!r}; expected \"auto\" or a number > 0")
        check_within("fragmentation_cohesion", self.fragmentation_cohesion, 0.0, 1.0, lo_open=True)

    def resolve(self, model) -> "MetricSettings":
        """These settings for ``model``: the group radius (when None), box, escape duration, obstacles and
        body radius filled in."""
        radius = default_group_radius(model) if self.group_radius is None else self.group_radius
        return dataclasses.replace(self, group_radius=radius, box=world_box(model),
                                   escape_duration=float(model.leadership.duration),
                                   obstacles=tuple(model.world.obstacles),
                                   body_radius=model_body_radius(model),
                                   migration=migration_direction(model),
                                   walls=tank_walls(model.arena))

    def identity(self) -> dict:
        """These settings as data for an identity (a calibration's training runs): every field, but
        ``walls`` only when set, so identities recorded before the wall scalars existed stay valid."""
        record = dataclasses.asdict(self)
        if record["walls"] is None:
            del record["walls"]
        return record

    @property
    def resolved(self) -> bool:
        return self.group_radius is not None and self.escape_duration is not None


def encounter_settings(settings: MetricSettings) -> dict:
    """The encounter settings (``ENCOUNTER_SETTINGS``) that differ from their defaults: what run
    identity and a sweep's ``model.json`` record, so run ids of earlier sweeps stay valid."""
    return {key: getattr(settings, key) for key, default in ENCOUNTER_SETTINGS.items()
            if getattr(settings, key) != default}


def motion_settings(settings: MetricSettings) -> dict:
    """The settings of the observables of collective motion (``MOTION_SETTINGS``) that differ from their
    defaults: what run identity and a sweep's ``model.json`` record, so run ids of earlier sweeps stay
    valid."""
    return {key: getattr(settings, key) for key, default in MOTION_SETTINGS.items()
            if getattr(settings, key) != default}


def model_body_radius(model) -> float:
    """The body radius obstacle collisions are measured with: the dynamics' own (its descriptor's
    ``body_radius``, :mod:`simcore.registry`: reynolds87's ``reynolds.body_radius``), else
    ``perception.body_radius``."""
    return float(describe(model.dynamics).body_radius(model))


def migration_direction(model) -> tuple[float, float, float] | None:
    """The migratory urge's unit direction when the model has one (its dynamics' descriptor's
    ``migration``: reynolds87 with migration_weight > 0 in an open world), else None (then no migration
    metrics)."""
    return describe(model.dynamics).migration(model)


class RunMetrics(NamedTuple):
    series: dict   # name -> (R,) float64 per-record values
    row: dict      # column -> float, see summary_columns


def measure_run(obs, settings: MetricSettings) -> RunMetrics:
    """The per-record series and the summary row of one run (see the module docstring)."""
    if not settings.resolved:
        raise ValueError("metric settings: resolve them for the run's model first (MetricSettings.resolve)")
    if getattr(obs, "present", None) is not None:  # an observed flock: who is seen varies by record
        if settings.leadership:
            raise ValueError("metric settings: leadership metrics need the simulator's leader records, "
                             "an observed flock has none")
        series = present_metrics(obs, settings.group_radius, settings.box, settings.k_nearest,
                                 settings.pairwise_metrics)
        series["tracked"] = obs.tracked
    else:
        series = frame_metrics(obs.pos, obs.vel, obs.visible, obs.binocular, obs.pattern, settings.group_radius,
                               settings.box, record_interval(obs), settings.k_nearest, settings.pairwise_metrics)
    row = summarize(series, obs.times, settings.warmup, settings.fragmentation_cohesion)
    fragmentation = {name: row.pop(name) for name in RUN_COLUMNS}   # the motion scalars come before them
    row.update(run_motion_metrics(obs, settings, series))
    row.update(fragmentation)
    if settings.leadership:
        row.update(leadership_metrics(obs, settings.group_radius, settings.escape_duration, settings.box))
        series["leaders"] = obs.leader.sum(axis=1).astype(np.float64)
    if settings.dcd:
        row.update(dcd_scalars(run_directional_correlation(obs, settings)))
    if settings.migration is not None:
        row.update(migration_metrics(obs.pos, obs.vel, obs.times, settings.migration, settings.warmup))
    if settings.walls is not None:
        row.update(run_wall_metrics(obs, settings))
    if getattr(obs, "present", None) is None:
        extra_series, extra_row = encounter_metrics(obs, settings, series)
        series.update(extra_series)
        row.update(extra_row)
    return RunMetrics(series, row)


def run_motion_metrics(obs, settings: MetricSettings, series: dict) -> dict:
    """The scalars of collective motion (:mod:`~observables.motion`) of a run or an observed flock: its
    velocities (nan where an individual is not present), the window at or after ``settings.warmup``, and
    the run's ``polarization`` and ``milling`` series for the state fractions."""
    present = getattr(obs, "present", None)
    vel = obs.vel if present is None else np.where(present[..., None], obs.vel, np.nan)
    return motion_metrics(vel, obs.times, observed_interval(obs), settings.warmup, series["polarization"],
                          series["milling"], settings.state_high, settings.state_low)


def run_wall_metrics(obs, settings: MetricSettings) -> dict:
    """The tank's wall scalars (:mod:`~observables.walls`) of a run or an observed flock (positions and
    velocities nan where an individual is not present), over the records at or after ``settings.warmup``."""
    present = getattr(obs, "present", None)
    pos = obs.pos if present is None else np.where(present[..., None], obs.pos, np.nan)
    vel = obs.vel if present is None else np.where(present[..., None], obs.vel, np.nan)
    return wall_metrics(pos, vel, obs.times, settings.warmup, settings.walls)


def observed_interval(obs) -> float:
    """Seconds between the records of a simulator ``Observations`` (:func:`record_interval`) or of an
    observed flock (its grid's ``interval``; else the median spacing of its times, 1.0 for one record)."""
    if getattr(obs, "present", None) is None:
        return record_interval(obs)
    if obs.interval is not None:
        return float(obs.interval)
    steps = np.diff(np.asarray(obs.times, dtype=np.float64))
    return float(np.median(steps)) if steps.size and np.median(steps) > 0 else 1.0


def run_directional_correlation(obs, settings: MetricSettings) -> DirectionalCorrelation:
    """The directional correlation delays of a run or an observed flock: its velocities (nan where an
    individual is not present) over the records at or after ``settings.warmup``, delays up to
    ``settings.dcd_max_delay``."""
    present = getattr(obs, "present", None)
    vel = obs.vel if present is None else np.where(present[..., None], obs.vel, np.nan)
    interval = record_interval(obs) if present is None else obs.interval
    window = np.asarray(obs.times) >= settings.warmup
    return directional_correlation(vel[window], interval, settings.dcd_max_delay)


def summarize_run(obs, settings: MetricSettings) -> dict:
    """The summary row of one run: :func:`measure_run` without the series."""
    return measure_run(obs, settings).row


def check_finite(obs) -> None:
    """NonFiniteState naming the first record time with a non-finite position or velocity."""
    bad = ~(np.isfinite(obs.pos).all(axis=(1, 2)) & np.isfinite(obs.vel).all(axis=(1, 2)))
    if bad.any():
        raise NonFiniteState(f"non-finite position or velocity at t = {obs.times[np.argmax(bad)]:g} s")


def every_nth(obs, k: int):
    """The observations with every ``k``-th record kept (the record interval grows k times)."""
    if k == 1:
        return obs
    pick = slice(None, None, k)
    return dataclasses.replace(obs, times=obs.times[pick], pos=obs.pos[pick], vel=obs.vel[pick],
                               visible=obs.visible[pick], binocular=obs.binocular[pick], leader=obs.leader[pick],
                               record_every=obs.record_every * k, **agent_positions(obs, pick))


def default_group_radius(model) -> float:
    """The model's perception range: ``perception.range`` (binocular), the perception sphere's radius
    (``perception.radius``, or the one the dynamics sets: the outer zone of ``couzin2002``, the alignment
    radius of ``vicsek``), or the largest of the separation, alignment and cohesion radii (opensteer)."""
    p = model.perception
    if p.kind == "binocular":
        return float(p.range)
    if p.kind == "sphere":
        return float(model.sphere_radius)
    if p.kind == "opensteer":
        return float(max(p.separation_radius, p.alignment_radius, p.cohesion_radius))
    raise ValueError(f"perception.kind: no group radius for {p.kind!r}")


def world_box(model) -> float | None:
    """Side of the periodic box for minimum-image metrics, None for other worlds."""
    world = model.world
    return float(world.box_size) if world.boundary == "periodic_box" else None


def observation_metrics(obs, model, group_radius: float | None = None) -> dict[str, np.ndarray]:
    """:func:`~observables.metrics.frame_metrics` of a simulator ``Observations`` with the
    model's perception range (or ``group_radius``) and periodic box."""
    s = MetricSettings(group_radius=group_radius).resolve(model)
    return frame_metrics(obs.pos, obs.vel, obs.visible, obs.binocular, obs.pattern, s.group_radius, s.box,
                         record_interval(obs))


def record_interval(obs) -> float:
    """Seconds between an ``Observations``' records: ``record_every`` steps of ``dt`` (computed as that
    integer times dt, so records picked from a finer recording give the same bits)."""
    return int(obs.record_every) * float(obs.dt)


def observation_leadership(obs, model, group_radius: float | None = None, max_lag: float = 2.0) -> dict[str, float]:
    """:func:`~observables.leadership.leadership_metrics` of a simulator ``Observations`` with
    the model's perception range as the group radius, its periodic box and its ``leadership.duration``
    as the escape length."""
    s = MetricSettings(group_radius=group_radius).resolve(model)
    return leadership_metrics(obs, s.group_radius, s.escape_duration, s.box, max_lag)

