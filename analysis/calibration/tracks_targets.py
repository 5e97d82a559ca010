"""Calibration targets straight from measured tracks, and the checks of a calibration's ``[observation]``.

A calibration file may take its targets from a track file instead of typed numbers::

    [observation]                 # how the real flocks were measured; simulated runs are measured alike
    interval = 0.2                # seconds between samples (the records of every simulated run)
    velocity_interval = 0.4       # positions differenced over 0.4 s (or "recorded")
    detection_probability = 0.95
    position_sd = 0.1             # body lengths
    projection = "none"           # or "xz" (the simulator's horizontal plane) for 2-D tracks

    [targets]
    summary = "mean"
    stats = ["polarization", "nn_distance", "speed_cv"]
    from_tracks = "../tracks/synthetic_holland.csv.gz"
    aggregate = "samples"         # each measured flock is one sample of the statistics (default), or
                                  # "mean": the flocks' mean with the covariance of that mean
    sd = [0.02, 0.3, 0.05]        # optional, with "samples": the measurement sd of one flock's statistics

    [targets.tracks]              # how to read them (defaults from the file's sidecar JSON)
    columns = { flock = "event" }
    units = { length = "m", time = "s" }
    body_length = 0.3             # metres: lengths in body lengths, the model's units
    warmup = 0.0                  # seconds skipped at the start of each measured flock

The tracks are measured by :func:`observables.measured.measure_tracks` with the observation's
interval, gap limit and velocity interval, the calibration's fragmentation threshold, its
``run.dcd_max_delay`` (the directional correlation delays ``dcd_*`` need only velocities: they are
measured on tracks and observed runs alike), the settings of the observables of collective motion
(``run.k_nearest``, ``pairwise_metrics``, ``state_high``, ``state_low``) and a fixed group radius
(:func:`fixed_group_radius`), giving one row of ``targets.columns`` per flock. Checks (each a
:class:`~simcore.schema.ConfigError` naming the key): the tracks must be in body lengths (tracks in
metres need ``body_length``), 2-D tracks need a ``projection`` and 3-D tracks must not have one, every
flock must be measured and every target statistic finite; ``aggregate = "mean"`` needs more flocks than
statistics. ``targets.sd`` (with ``aggregate = "samples"`` only: with "mean" the flocks' spread already holds
their measurement error) is a known measurement error of one flock's statistics: the targets' covariance is
then diag(sd^2), which the calibration adds to every simulated summary as Gaussian noise, so the synthetic
likelihood's Gaussian has the replicate covariance plus diag(sd^2), as for typed mean/sd targets.

:func:`check_observation` checks an ``[observation]`` block against the model and the rest of the file:
an open world (differences and gap bridging need continuous tracks), a sampling interval that is a whole
number of steps and fits the run, no ``run.record_interval`` beside it (the samples are the records),
statistics an observer can measure (not ``visible_mean``, ``visible_sd``, ``binocular_share`` or the leadership
statistics). Whether the method takes the block is the method's check (:mod:`analysis.calibration.methods`).

**A tank the tracks declare** (their ``arena``, :meth:`observables.tracks.TrackSource.tank`, docs/measured.md) is the
model's tank (:func:`shared_tank`, before the parameters are checked): the tracks are read once
(:func:`read_target_tracks`), their tank converted to body lengths, and

* a preset without an ``[arena]`` gets the tracks' (its kind, radius or size, height) centred on the origin, where
  the simulated flock starts (statistics do not depend on where the tank sits; the preset's wall term, or the
  arena defaults, are kept), written into the preset data every simulation is built from, so its runs start inside
  (the start region is checked against it) and stay in it;
* a preset with one must have the same geometry (kind; radius or the sides the tracks see; a 3-D cylinder's
  height) within ``TANK_TOLERANCE`` (0.1%, relative): otherwise a ConfigError names both tanks; its centre may differ;
* 2-D tracks see the tank in their x-y plane, and the model's cylinder stands along z: its runs must be seen
  along z, ``projection = "xy"`` (refused otherwise);
* the tank's geometry is no free parameter (a ``[parameters.*]`` key ``arena.radius`` etc. is refused); its wall
  term (``arena.wall_weight``, ``arena.wall_range``) may be.

Every sample of the tracks is checked to lie inside their tank when they are read (the ``outside the tank``
check of :mod:`observables.validation`).
"""
from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from flocksweep.observables.columns import PERCEPTION_SERIES
from flocksweep.observables.leadership import LEADERSHIP_METRIC_NAMES
from flocksweep.observables.measured import Measurement, measure_tracks, track_settings
from flocksweep.observables.observation import Observation, check_projection
from flocksweep.observables.summary import MetricSettings, default_group_radius, motion_settings
from flocksweep.observables.tracks import TrackSource, TrackTable, load_tracks, track_source
from flocksweep.observables.validation import TrackError
from flocksweep.simcore.params import preset_from_dict
from flocksweep.simcore.schema import ConfigError, check_non_negative, get_dotted, resolve_path

UNOBSERVABLE = PERCEPTION_SERIES + tuple(LEADERSHIP_METRIC_NAMES)
TANK_TOLERANCE = 1e-3     # relative: a preset's tank and the tracks' are the same within this
TANK_GEOMETRY = ("arena.kind", "arena.centre", "arena.radius", "arena.size", "arena.height")


@dataclass(frozen=True)
class TracksTable(TrackSource):
    """``[targets.tracks]``: how to read the track file, and the warm-up skipped in each measured flock."""

    warmup: float = 0.0

    def __post_init__(self):
        super().__post_init__()
        check_non_negative("warmup", self.warmup)


class TrackTargets(NamedTuple):
    observed: np.ndarray          # (m, k), or (1, k) with aggregate = "mean"
    cov: np.ndarray | None        # (k, k) with aggregate = "mean"
    path: Path
    flocks: tuple[str, ...]
    per_flock: np.ndarray         # (m, k) always
    measurement: Measurement


def check_observation(observation: Observation, preset, run_table, stats) -> None:
    """ConfigError when the block does not fit the model or the file (see the module docstring); ``preset``
    None: a command model (its tracks are put on the observation's grid whatever their own sampling)."""
    if preset is not None:
        check_projection(observation, preset.model.world.dimensions)
        boundary = preset.model.world.boundary
        if boundary != "open":
            raise ConfigError("observation", f"the model's world.boundary is {boundary!r}; observed tracks are "
                                             "differenced and bridged over time, which needs the continuous tracks "
                                             "of an open world")
        try:
            observation.record_every(preset.run.dt)
        except ConfigError as err:
            raise ConfigError("observation.interval", err.detail) from None
        if observation.interval > preset.run.duration:
            raise ConfigError("observation.interval", f"got {observation.interval!r}; longer than the run "
                                                      f"({preset.run.duration!r} s)")
    if run_table.record_interval is not None:
        raise ConfigError("run.record_interval", "with an [observation] block the records are its samples "
                                                 "(observation.interval); remove run.record_interval")
    hidden = [s for s in stats if s in UNOBSERVABLE]
    if hidden:
        raise ConfigError("targets.stats", f"{hidden[0]!r} cannot be measured by an observer; with an [observation] "
                                           "block use statistics of positions and velocities")


def fixed_group_radius(metrics: MetricSettings, preset, parameters) -> float:
    """The group radius measured tracks and simulations share: run.group_radius, or with "auto" the model's
    perception range, which then must not depend on a free parameter."""
    if metrics.group_radius is not None:
        return float(metrics.group_radius)
    radius = default_group_radius(preset.model)
    full = preset.full_dict()
    for parameter in parameters:
        for value in parameter.bounds:
            if isinstance(get_dotted(full, parameter.key), int):
                value = int(round(value))
            try:
                moved = default_group_radius(preset.replace({parameter.key: value}).model)
            except ConfigError:
                continue
            if moved != radius:
                raise ConfigError("run.group_radius", f'"auto" is the perception range, which parameter '
                                                      f"{parameter.name!r} ({parameter.key}) changes; measured "
                                                      "tracks need one fixed radius: give a number (body lengths)")
    return float(radius)


def _given_with_tracks(targets) -> None:
    for key in ("mean", "cov", "samples"):
        if getattr(targets, key) is not None:
            raise ConfigError(f"targets.{key}", "not with from_tracks: the tracks give the targets")


def measurement_sd(targets, k: int) -> np.ndarray | None:
    """``targets.sd`` with from_tracks: (k,) measurement sd of one flock's statistics (> 0), or None."""
    if targets.sd is None:
        return None
    if (targets.aggregate or "samples") != "samples":
        raise ConfigError("targets.sd", 'only with aggregate = "samples": the flocks\' spread around their mean '
                                        "already holds their measurement error")
    values = targets.sd if isinstance(targets.sd, (list, tuple)) else [targets.sd]
    try:
        sd = np.array([float(v) for v in values if not isinstance(v, bool)], dtype=np.float64)
    except (TypeError, ValueError):
        sd = np.empty(0)
    if sd.shape != (k,) or not (np.isfinite(sd).all() and (sd > 0).all()):
        raise ConfigError("targets.sd", f"got {targets.sd!r}; expected {k} numbers > 0, one per stat (the "
                                        "measurement sd of one flock's statistic)")
    return sd


def read_target_tracks(targets, base: Path) -> TrackTable:
    """The track file of ``[targets] from_tracks``, read with ``[targets.tracks]`` (and its sidecar); lengths
    must be in body lengths, the model's units."""
    path = resolve_path(targets.from_tracks, base, "targets.from_tracks", "track file")
    source = track_source(path, targets.tracks or {}, "targets.tracks", cls=TracksTable)
    try:
        table = load_tracks(path, source)
    except TrackError as err:
        raise ConfigError("targets.from_tracks", str(err)) from None
    if table.unit_label != "BL":
        raise ConfigError("targets.tracks.body_length", f"{path.name} is in metres; give the body length (metres) "
                                                        "so that lengths are in body lengths, the model's units")
    return table


def _check_planes(table: TrackTable, observation: Observation) -> None:
    name = table.path.name
    if table.dims == 2 and observation.projection == "none":
        raise ConfigError("observation.projection", f"{name} holds 2-D tracks: project the simulated runs "
                                                    'too, e.g. projection = "xz" (the horizontal plane)')
    if table.dims == 3 and observation.projection != "none":
        raise ConfigError("observation.projection", f"{name} holds 3-D tracks; a projection is for 2-D ones")


def describe_tank(tank, dims: int = 3) -> str:
    """'cylinder of radius 10 about (0, 0)' / 'box of sides 20 x 10 about (1, 2)' (body lengths)."""
    about = "(" + ", ".join(f"{c:.6g}" for c in tank.centre[:dims]) + ")"
    if tank.kind == "cylinder":
        height = f", height {tank.height:.6g}" if dims == 3 and tank.height is not None else ""
        return f"{'circle' if dims == 2 else 'cylinder'} of radius {tank.radius:.6g}{height} about {about}"
    return f"{'rectangle' if dims == 2 else 'box'} of sides {' x '.join(f'{v:.6g}' for v in tank.size[:dims])} about {about}"


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return math.isclose(a, b, rel_tol=TANK_TOLERANCE)


def same_tank(model_tank, tracks_tank, dims: int) -> bool:
    """Whether the model's tank has the geometry the tracks see (their ``dims``; the centre aside)."""
    if model_tank.kind != tracks_tank.kind:
        return False
    if model_tank.kind == "cylinder":
        return _same(model_tank.radius, tracks_tank.radius) and (
            dims == 2 or _same(model_tank.height, tracks_tank.height))
    return all(_same(a, b) for a, b in zip(model_tank.size[:dims], tracks_tank.size[:dims]))


def shared_tank(preset, preset_data: dict, table: TrackTable, observation: Observation) -> tuple:
    """(preset, preset data) in the tank the tracks declare (see the module docstring); unchanged when they
    declare none. ConfigError: a preset tank of another geometry, a projection other than "xy" for 2-D
    tracks, a start region that does not fit the tracks' tank."""
    tank = table.source.tank()
    if tank is None:
        return preset, preset_data
    _check_planes(table, observation)
    name, dims = table.path.name, table.dims
    said = f"the tank {name} declares ({describe_tank(tank, dims)} body lengths)"
    if dims == 2 and observation.projection != "xy":
        raise ConfigError("observation.projection", f"got {observation.projection!r}; {said} lies in the tracks' "
                                                    "x-y plane and the model's tank stands along z, so its runs are "
                                                    'seen along z: use projection = "xy"')
    if preset.model.arena.enabled:
        if not same_tank(preset.model.arena, tank, dims):
            raise ConfigError("arena", f"the model's tank ({describe_tank(preset.model.arena, dims)} body lengths) is "
                                       f"not {said}: give the preset that geometry (its centre may differ), or leave "
                                       "its [arena] out and the calibration takes the tracks' tank")
        return preset, preset_data
    scale = preset.units.body_length_m if preset.units.length == "m" else 1.0   # the preset file's length unit
    geometry = {"kind": tank.kind, "centre": [0.0, 0.0, 0.0]}
    if tank.kind == "cylinder":
        geometry["radius"] = tank.radius * scale
        if tank.height is not None:
            geometry["height"] = tank.height * scale
    else:
        geometry["size"] = [side * scale for side in tank.size]
    data = copy.deepcopy(preset_data)
    data["arena"] = {**(data.get("arena") or {}), **geometry}
    try:
        placed = preset_from_dict(copy.deepcopy(data))
    except ConfigError as err:
        raise ConfigError(err.key, f"{err.detail} (the model is put in {said})") from None
    return placed, data


def check_tank_parameters(parameters, table: TrackTable | None) -> None:
    """ConfigError for a free parameter that moves the tank the tracks declare (its wall term may be free)."""
    if table is None or table.source.tank() is None:
        return
    for parameter in parameters:
        if parameter.key in TANK_GEOMETRY:
            raise ConfigError(f"parameters.{parameter.name}.key", f"{parameter.key} is fixed by the tank "
                                                                 f"{table.path.name} declares; fit the wall term "
                                                                 "(arena.wall_weight, arena.wall_range) instead")


def _measure(table: TrackTable, targets, observation: Observation, metrics: MetricSettings) -> Measurement:
    source = table.source
    _check_planes(table, observation)
    settings = dataclasses.replace(track_settings(metrics.group_radius, source.warmup, metrics.fragmentation_cohesion,
                                                  metrics.dcd_max_delay), **motion_settings(metrics))
    try:
        return measure_tracks(table, settings, observation.interval, observation.max_gap, observation.velocity_interval)
    except TrackError as err:
        raise ConfigError("targets.from_tracks", str(err)) from None


def tracks_targets(targets, observation: Observation | None, metrics: MetricSettings, columns,
                   base: Path, table: TrackTable | None = None) -> TrackTargets:
    """The targets of ``[targets] from_tracks`` (see the module docstring); ``metrics``: the calibration's,
    its group radius fixed (:func:`fixed_group_radius`); ``table``: the tracks already read
    (:func:`read_target_tracks`)."""
    path = resolve_path(targets.from_tracks, base, "targets.from_tracks", "track file")
    if observation is None:
        raise ConfigError("targets.from_tracks", "needs an [observation] block (at least interval = seconds between "
                                                 "samples) so that simulated runs are measured as the tracks were")
    _given_with_tracks(targets)
    measurement_sd(targets, len(columns))          # checked before the tracks are measured
    measurement = _measure(table if table is not None else read_target_tracks(targets, base), targets, observation,
                           metrics)
    runs = measurement.runs
    failed = runs[runs["status"] != "ok"]
    if len(failed):
        raise ConfigError("targets.from_tracks", f"flock {failed['flock'].iloc[0]!r} could not be measured: "
                                                 f"{failed['error'].iloc[0]}")
    unmeasured = [c for c in columns if c not in runs]
    if unmeasured:   # the wall statistics: measured only on tracks that declare their tank
        raise ConfigError("targets.stats", f"{unmeasured[0]!r} is not measured on these tracks: it needs the tank "
                                           "they were filmed in; declare it with the tracks (arena = { kind, "
                                           "centre, radius or size }, docs/measured.md) or remove the statistic")
    per_flock = runs[list(columns)].to_numpy(dtype=np.float64)
    bad = ~np.isfinite(per_flock)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ConfigError("targets.stats", f"{columns[c]} is undefined (nan) for flock {runs['flock'].iloc[r]!r}; "
                                           "choose statistics every flock has")
    flocks = tuple(runs["flock"])
    sd = measurement_sd(targets, per_flock.shape[1])
    if (targets.aggregate or "samples") == "samples":
        cov = None if sd is None else np.diag(sd ** 2)
        return TrackTargets(per_flock, cov, path, flocks, per_flock, measurement)
    m, k = per_flock.shape
    if m < k + 1:
        raise ConfigError("targets.aggregate", f'"mean" needs more flocks than statistics for a covariance ({m} '
                                               f"flocks, {k} stats); use \"samples\"")
    cov = np.atleast_2d(np.cov(per_flock, rowvar=False, ddof=1)) / m
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ConfigError("targets.aggregate", "the flocks' covariance is singular; use \"samples\"") from None
    return TrackTargets(per_flock.mean(axis=0)[None, :], cov, path, flocks, per_flock, measurement)


def tracks_block(config) -> str:
    """The ``[targets]`` block of a calibration whose targets come from tracks, with every flock's values."""
    t = config.targets
    rows, stats = t.per_flock, t.stats
    width = max(12, *(len(s) + 2 for s in stats))
    name_width = max(8, *(len(f) + 2 for f in t.flocks))
    lines = [f"# targets from {t.tracks_path} ({len(t.flocks)} flocks), {t.summary} of each flock's records",
             f"# observation: {config.observation.describe()}",
             "# " + "flock".ljust(name_width) + "".join(s.rjust(width) for s in stats)]
    lines += ["# " + f.ljust(name_width) + "".join(f"{v:.6g}".rjust(width) for v in row) for f, row in zip(t.flocks, rows)]
    mean = rows.mean(axis=0)
    lines += ["[targets]", f'summary = "{t.summary}"', "stats = [" + ", ".join(f'"{s}"' for s in stats) + "]",
              f'from_tracks = "{t.tracks_path}"      # each flock one sample']
    if t.cov is not None and len(t.observed) > 1:
        lines.append("sd = [" + ", ".join(f"{v:.6g}" for v in np.sqrt(np.diag(t.cov))) + "]      # measurement sd")
    if len(rows) > 1:
        cov = np.atleast_2d(np.cov(rows, rowvar=False, ddof=1)) / len(rows)
        lines += ['# or aggregate = "mean": the flocks\' mean and the covariance of that mean',
                  "# mean = [" + ", ".join(f"{v:.6g}" for v in mean) + "]",
                  "# cov = [" + ", ".join("[" + ", ".join(f"{v:.6g}" for v in r) + "]" for r in cov) + "]"]
    return "\n".join(lines) + "\n"


def tracks_record(found: TrackTargets) -> dict:
    """What a calibration records of the tracks its targets came from: the file (its name, not the
    machine's path), format, flocks, every unit and scale used with where it came from (file, sidecar, given,
    default: :meth:`~observables.tracks.TrackSource.scales`), and how many warnings and errors the checks
    found (``flocksweep measure`` lists them)."""
    table = found.measurement.table
    levels = [getattr(issue, "level", "") for issue in found.measurement.issues]
    return {"file": Path(found.path).name, "format": table.source.format, "flocks": list(found.flocks),
            "dims": int(table.dims), "scales": table.source.scales(),
            "checks": {"warnings": levels.count("warning"), "errors": levels.count("error")}}
