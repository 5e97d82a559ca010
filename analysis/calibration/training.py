"""The emulator's training set: an existing sweep's runs, checked against a calibration and grouped by
parameter point.

Shapes: d free parameters, k statistics, P distinct parameter points in the sweep, N runs.

Contract
--------
``training_set(results_path, config) -> TrainingSet``
    Reads the sweep results folder (``runs.parquet``, ``model.json``), keeps the runs with status
    ``ok`` and finite values of every target column, and groups them by the free-parameter point.
    Checks, each a :class:`~simcore.schema.ConfigError` naming the calibration key:

    * ``method.results``: folder missing, no ``runs.parquet`` / ``model.json``; the sweep's fixed
      settings differ from the calibration's (every resolved preset value that neither design varies
      is compared: model name, dynamics, run duration, dt, record interval, ``init.n``, steering, ...;
      for an external command model its command, the SHA-256 of its files, its output and how it is read,
      and the defaults of the parameters neither design varies;
      plus the warmup, an automatic group radius, the fragmentation threshold when a fragmentation
      column is a target, and ``dcd_max_delay`` when a directional correlation delay is); a swept
      factor that is not a free parameter has no run at the
      calibration's value (only the runs at that value are kept; the values available are listed);
      fewer than ``d + 2`` points with >= 2 replicates, or no replicates at all; points that do not
      vary the free parameters independently (e.g. a zipped axis moving two of them together);
    * ``parameters.<name>.key``: a free parameter the sweep did not vary (the swept keys are listed);
    * ``parameters.<name>.prior``: the prior's support does not overlap the swept range;
    * ``targets.stats``: a target column missing from the runs table (the available ones are listed).

    A free parameter's column is its key (the runs table holds every swept key's resolved value); a
    table without it may still hold the values under the axis' ``name`` (used when numeric).
    Points with a single usable replicate are dropped and recorded in ``TrainingSet.notes``.

    With an ``[observation]`` block (targets from tracks) every kept run is measured anew through it
    (:func:`observed_summaries`): its stored trajectory (the sweep must keep them, ``keep =
    "trajectories"``, recorded at an interval dividing the observation's) seen by the observer (projection,
    missed detections, position noise from the run's seed) and summarised with the calibration's metric
    settings, exactly as the calibration's own runs are; the sweep's record interval and metric settings
    then do not matter.

``group_replicates(points (N, d), summaries (N, k), names, columns, keys=None) -> TrainingSet``
    The same grouping for arrays (synthetic simulators, tests); raises ValueError.

:class:`TrainingSet`: ``points`` (P, d), ``mean`` (P, k), ``var`` (P, k) (ddof = 1, floored at
1e-12 x the stat's variance over all runs, at least 1e-300, so a point whose replicates agree keeps a
finite log variance), ``count`` (P,), ``correlation`` (k, k) (pooled within-point correlation of the
standardised residuals, shrunk towards the identity only if not positive definite), ``lower`` /
``upper`` (d,) (the training box), ``names``, ``keys``, ``columns``, ``fixed`` (non-free swept key ->
the value kept), ``notes``, ``source``.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import numbers
from pathlib import Path

import numpy as np

from flocksweep.observables.directional_correlation import DCD_METRIC_NAMES
from flocksweep.observables.metrics import FRAGMENTATION_COHESION
from flocksweep.observables.summary import MOTION_SETTINGS
from flocksweep.simcore.params import canonical_key, preset_from_dict
from flocksweep.simcore.schema import ConfigError, get_dotted
from flocksweep.sweeps.results import load_results
from flocksweep.sweeps.store import ResultsStore

FRAGMENTATION_COLUMNS = ("time_to_fragmentation", "fragmented")
IGNORED_PRESET_KEYS = ("description",)


@dataclasses.dataclass(frozen=True, eq=False)
class TrainingSet:
    """Per-point replicate statistics of a sweep (see the module docstring for the shapes)."""

    names: tuple[str, ...]
    keys: tuple[str, ...]
    columns: tuple[str, ...]
    points: np.ndarray        # (P, d)
    mean: np.ndarray          # (P, k)
    var: np.ndarray           # (P, k), ddof = 1, floored
    count: np.ndarray         # (P,)
    correlation: np.ndarray   # (k, k)
    fixed: dict = dataclasses.field(default_factory=dict)
    notes: tuple[str, ...] = ()
    source: Path | None = None

    @property
    def d(self) -> int:
        return self.points.shape[1]

    @property
    def k(self) -> int:
        return self.mean.shape[1]

    @property
    def lower(self) -> np.ndarray:
        return self.points.min(axis=0)

    @property
    def upper(self) -> np.ndarray:
        return self.points.max(axis=0)


def _variance_floor(summaries: np.ndarray) -> np.ndarray:
    """(k,) smallest per-point variance kept: 1e-12 x the stat's variance over all runs (>= 1e-300)."""
    total = summaries.var(axis=0) if len(summaries) > 1 else np.zeros(summaries.shape[1])
    return np.maximum(1e-12 * total, 1e-300)


def _pooled_correlation(summaries: np.ndarray, group: np.ndarray, mean: np.ndarray,
                        var: np.ndarray) -> np.ndarray:
    """(k, k) correlation of the within-point residuals, each standardised by its point's sd."""
    residuals = (summaries - mean[group]) / np.sqrt(var[group])
    dof = len(summaries) - len(mean)
    pooled = residuals.T @ residuals / max(dof, 1)
    scale = np.sqrt(np.diag(pooled))
    constant = scale <= 0
    scale[constant] = 1.0
    correlation = pooled / np.outer(scale, scale)
    correlation[constant, :] = 0.0
    correlation[:, constant] = 0.0
    np.fill_diagonal(correlation, 1.0)
    return _positive_definite(correlation)


def _positive_definite(correlation: np.ndarray) -> np.ndarray:
    """The correlation, shrunk towards the identity just enough to be positive definite."""
    k = len(correlation)
    for weight in (0.0, 1e-6, 1e-4, 1e-2, 0.1, 0.5, 1.0):
        candidate = (1.0 - weight) * correlation + weight * np.eye(k)
        if np.linalg.eigvalsh(candidate).min() > 1e-10:
            return candidate
    return np.eye(k)


def _check_independent(points: np.ndarray, names) -> None:
    """The points (P, d) must span d dimensions (not, e.g., a zipped axis moving two free parameters
    together), or the emulator cannot tell the parameters' effects apart."""
    unit = (points - points.min(axis=0)) / (points.max(axis=0) - points.min(axis=0))
    design = np.column_stack([np.ones(len(points)), unit])
    if np.linalg.matrix_rank(design, tol=1e-8) < design.shape[1]:
        raise ValueError(f"the training points do not vary the parameters {list(names)} independently (they lie "
                         "in a lower-dimensional subspace, e.g. a zipped axis moves them together)")


def group_replicates(points, summaries, names, columns, keys=None, *, fixed=None, source=None) -> TrainingSet:
    """Rows (N, d) of parameter values and (N, k) of summaries -> per-point statistics; rows with a
    non-finite summary are left out, points with one usable replicate are dropped (noted)."""
    points = np.asarray(points, dtype=float)
    summaries = np.asarray(summaries, dtype=float)
    names, columns = tuple(names), tuple(columns)
    if points.ndim != 2 or summaries.ndim != 2 or len(points) != len(summaries):
        raise ValueError(f"points must be (N, d) and summaries (N, k) with the same N, got {points.shape} "
                         f"and {summaries.shape}")
    if points.shape[1] != len(names) or summaries.shape[1] != len(columns):
        raise ValueError(f"{len(names)} names for {points.shape[1]} parameters or {len(columns)} columns for "
                         f"{summaries.shape[1]} statistics")
    usable = np.isfinite(summaries).all(axis=1) & np.isfinite(points).all(axis=1)
    notes = []
    if not usable.all():
        notes.append(f"{int((~usable).sum())} run(s) with a non-finite statistic left out")
    points, summaries = points[usable], summaries[usable]
    unique, group, count = np.unique(points, axis=0, return_inverse=True, return_counts=True)
    group = np.ravel(group)
    if count.size == 0 or count.max() < 2:
        raise ValueError("the emulator needs replicates: every parameter point has at most one usable run; "
                         "run the sweep with replicates >= 2 (e.g. 3 or more)")
    single = count < 2
    if single.any():
        notes.append(f"{int(single.sum())} point(s) with a single usable replicate dropped")
        keep = ~single[group]
        remap = np.cumsum(~single) - 1
        points, summaries, group = points[keep], summaries[keep], remap[group[keep]]
        unique, count = unique[~single], count[~single]
    d = points.shape[1]
    if len(unique) < d + 2:
        raise ValueError(f"the emulator needs at least d + 2 = {d + 2} parameter points with >= 2 replicates, "
                         f"got {len(unique)}")
    for j, name in enumerate(names):
        if np.unique(unique[:, j]).size < 2:
            raise ValueError(f"parameter {name!r} takes a single value in the training points; it must vary")
    _check_independent(unique, names)
    mean = np.zeros((len(unique), summaries.shape[1]))
    np.add.at(mean, group, summaries)
    mean /= count[:, None]
    squares = np.zeros_like(mean)
    np.add.at(squares, group, (summaries - mean[group]) ** 2)
    var = np.maximum(squares / (count[:, None] - 1), _variance_floor(summaries))
    correlation = _pooled_correlation(summaries, group, mean, var)
    return TrainingSet(names=names, keys=tuple(keys) if keys is not None else names, columns=columns,
                       points=unique, mean=mean, var=var, count=count.astype(int), correlation=correlation,
                       fixed=dict(fixed or {}), notes=tuple(notes), source=source)


def _load_sweep(path: Path):
    """(Results, model record) of a sweep folder, or ConfigError method.results."""
    if not path.is_dir():
        raise ConfigError("method.results", f"results folder not found: {path} (run the sweep first with "
                                            "`flocksweep run SWEEP.toml`)")
    if not (path / "runs.parquet").is_file():
        raise ConfigError("method.results", f"{path} has no runs.parquet: not a finished sweep results folder "
                                            "(run or resume the sweep with `flocksweep run`)")
    model = ResultsStore(path).model()
    if not model.get("preset") and not model.get("command"):
        raise ConfigError("method.results", f"{path} has no model.json: cannot check the sweep's fixed settings")
    try:
        results = load_results(path)
    except FileNotFoundError as err:
        raise ConfigError("method.results", str(err)) from None
    return results, model


def _flatten(data: dict, prefix: str = "") -> dict:
    flat = {}
    for key, value in data.items():
        dotted = f"{prefix}.{key}" if prefix else key
        if isinstance(value, dict):
            flat.update(_flatten(value, dotted))
        else:
            flat[dotted] = value
    return flat


def _is_number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _same(a, b) -> bool:
    """Equal settings: numbers within a relative 1e-9 (a dt of 1/60 written two ways), else ==."""
    if _is_number(a) and _is_number(b):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def _resolved(preset_data: dict) -> dict:
    return preset_from_dict(copy.deepcopy(preset_data)).full_dict()


def _preset_differences(config, model: dict, neutral_keys) -> list[str]:
    """Resolved preset values that differ between the sweep's base and the calibration's preset, with
    the keys either design varies set to the sweep's base values in both (so derived values agree)."""
    try:
        sweep_full = _resolved(model["preset"])
    except ConfigError as err:
        raise ConfigError("method.results", f"the sweep's stored preset (model.json) is not valid for this "
                                            f"version of the model: {err}") from None
    try:
        calibration_full = config.preset.replace({key: get_dotted(sweep_full, key) for key in neutral_keys}).full_dict()
    except ConfigError as err:
        raise ConfigError("method.results", f"the calibration's preset with the sweep's values of the swept keys "
                                            f"is not valid ({err}); the sweep does not match this model") from None
    sweep_flat, calibration_flat = _flatten(sweep_full), _flatten(calibration_full)
    skip = set(neutral_keys) | set(IGNORED_PRESET_KEYS)
    out = []
    for key in sorted(set(sweep_flat) | set(calibration_flat)):
        if key in skip:
            continue
        a, b = sweep_flat.get(key), calibration_flat.get(key)
        if not _same(a, b):
            out.append(f"{key}: sweep {a!r}, calibration {b!r}")
    return out


def _radius_text(radius) -> str:
    return "\"auto\" (the model's perception range)" if radius is None else repr(radius)


def _analysis_differences(config, model: dict) -> list[str]:
    """The metric settings that differ between the sweep and the calibration (model.json's analysis)."""
    analysis = model.get("analysis", {})
    mine = config.metrics
    out = []
    warmup = analysis.get("warmup")
    if warmup is None or not _same(warmup, mine.warmup):
        out.append(f"warmup: sweep {warmup!r}, calibration {mine.warmup!r}")
    radius = analysis.get("group_radius")
    if not _same(radius, mine.group_radius):
        out.append(f"group_radius: sweep {_radius_text(radius)}, calibration {_radius_text(mine.group_radius)}")
    if any(c in FRAGMENTATION_COLUMNS for c in config.targets.columns):
        threshold = analysis.get("fragmentation_cohesion", FRAGMENTATION_COHESION)
        if not _same(threshold, mine.fragmentation_cohesion):
            out.append(f"fragmentation_cohesion: sweep {threshold!r}, calibration {mine.fragmentation_cohesion!r}")
    if any(c in DCD_METRIC_NAMES for c in config.targets.columns):
        delay = analysis.get("dcd_max_delay")
        if delay is not None and not _same(delay, mine.dcd_max_delay):
            out.append(f"dcd_max_delay: sweep {delay!r}, calibration {mine.dcd_max_delay!r}")
    for key, default in MOTION_SETTINGS.items():   # the observables of collective motion (absent: the default)
        theirs = analysis.get(key, default)
        if theirs != getattr(mine, key):
            out.append(f"{key}: sweep {theirs!r}, calibration {getattr(mine, key)!r}")
    return out


def _command_differences(config, model: dict, neutral_keys) -> list[str]:
    """What differs between the sweep's command model (model.json) and the calibration's: the command, its
    files' contents, the output and how it is read, and the defaults of the parameters neither design
    varies (a command sweep against a preset calibration, or the reverse, differs in everything)."""
    if (config.command is None) != (model.get("command") is None):
        mine = "a command model" if config.command is not None else "a model preset"
        theirs = "a command model" if model.get("command") is not None else "a model preset"
        return [f"model: the sweep ran {theirs}, the calibration has {mine}"]
    out = []
    identity = config.command.identity
    record = model["command"]          # model.json: {"command": the command's record, "swept_keys": ...}
    for key in ("command", "files", "output", "tracks"):
        if record.get(key) != identity.get(key):
            out.append(f"model.{key}: sweep {record.get(key)!r}, calibration {identity.get(key)!r}")
    theirs = {name: spec.get("default") for name, spec in record.get("parameters", {}).items()}
    mine = config.command.values({})
    for name in sorted(set(theirs) | set(mine)):
        if name not in neutral_keys and not _same(theirs.get(name), mine.get(name)):
            out.append(f"model.parameters.{name}: sweep default {theirs.get(name)!r}, calibration {mine.get(name)!r}")
    return out


def _check_fixed_settings(config, model: dict, path: Path) -> None:
    swept = [str(k) for k in model.get("swept_keys", [])]
    neutral = sorted(set(swept) | set(config.keys))
    if config.command is not None or model.get("command") is not None:
        differences = _command_differences(config, model, neutral)
    else:   # with an [observation] block the runs are measured anew at its interval: their records do not matter
        neutral += ["run.record_interval"] if config.observation is not None else []
        differences = _preset_differences(config, model, neutral)
    if config.observation is None:   # with one, the runs are measured anew with the calibration's settings
        differences += _analysis_differences(config, model)
    if differences:
        raise ConfigError("method.results", f"the sweep in {path} was run with other fixed settings than this "
                                            f"calibration: {'; '.join(differences)}. Make the calibration's "
                                            "[model]/[run] match, or use a sweep run with these settings")


def _swept_description(model: dict, sweep: dict) -> str:
    names = {}
    for axis in sweep.get("axes", []):
        keys = [axis["key"]] if "key" in axis else list(axis.get("keys", []))
        for key in keys:
            if "name" in axis and axis["name"] != key:
                names[canonical_key(key)] = axis["name"]
    swept = [str(k) for k in model.get("swept_keys", [])]
    return ", ".join(f"{k} (axis {names[k]!r})" if k in names else k for k in swept) or "nothing"


def _factor_column(key: str, runs, model: dict, sweep: dict) -> str | None:
    """The runs-table column holding a free parameter's values: its key, else a numeric axis name."""
    if key not in [str(k) for k in model.get("swept_keys", [])]:
        return None
    if key in runs.columns:
        return key
    for axis in sweep.get("axes", []):
        keys = [canonical_key(k) for k in ([axis["key"]] if "key" in axis else [])]
        name = axis.get("name")
        if keys == [key] and name in runs.columns and np.issubdtype(runs[name].dtype, np.number):
            return name
    return None


def _free_columns(config, runs, model: dict, sweep: dict) -> list[str]:
    columns = []
    for parameter in config.parameters:
        column = _factor_column(parameter.key, runs, model, sweep)
        if column is None:
            raise ConfigError(f"parameters.{parameter.name}.key",
                              f"{parameter.key!r} was not varied by the sweep, so the emulator cannot learn its "
                              f"effect; the sweep varied: {_swept_description(model, sweep)}")
        columns.append(column)
    return columns


def _check_stat_columns(config, runs, metrics) -> None:
    for column in config.targets.columns:
        if column not in runs.columns:
            available = ", ".join(metrics) or "none"
            raise ConfigError("targets.stats", f"the sweep's runs table has no column {column!r}; available "
                                               f"statistics: {available}")


def _matches(values, target) -> np.ndarray:
    """(N,) whether each table value equals the calibration's value (numbers compared with tolerance)."""
    return np.array([_same(value, target) for value in values], dtype=bool)


def _level_order(value):
    return (0, float(value), "") if _is_number(value) else (1, 0.0, repr(value))


def _filter_fixed_factors(config, runs, model: dict):
    """Keep the runs whose non-free swept keys equal the calibration preset's values (a command's
    parameter defaults)."""
    if config.command is not None:
        calibration_full = config.command.values({})
        get_dotted_value = (lambda data, key: data[key])
    else:
        calibration_full = _resolved(config.preset_data)
        get_dotted_value = get_dotted
    fixed = {}
    for key in [str(k) for k in model.get("swept_keys", [])]:
        if key in config.keys or key not in runs.columns:
            continue
        target = get_dotted_value(calibration_full, key)
        keep = _matches(runs[key].tolist(), target)
        if not keep.any():
            levels = sorted(set(runs[key].tolist()), key=_level_order)
            raise ConfigError("method.results", f"the sweep varies {key} (values {levels}) but it is not a free "
                                                f"parameter and the calibration fixes it at {target!r}, which no "
                                                f"run has; set it to one of the swept values (model.set) or make "
                                                "it a free parameter")
        runs = runs[keep]
        fixed[key] = target
    return runs, fixed


def _check_prior_overlap(config, training: TrainingSet) -> None:
    for parameter, (prior_low, prior_high), low, high in zip(config.parameters, config.prior.bounds,
                                                             training.lower, training.upper):
        if prior_high < low or prior_low > high:
            raise ConfigError(f"parameters.{parameter.name}.prior",
                              f"support [{prior_low}, {prior_high}] does not overlap the swept range "
                              f"[{low}, {high}] of {parameter.key}; the emulator cannot go outside it")


def _trajectory_run(path: Path):
    """A stored trajectory as the observation model reads a run: times, positions, velocities, patterns and
    its record interval (one record per step of that length)."""
    from types import SimpleNamespace

    from flocksweep.sweeps.trajectory import read_trajectory

    data = read_trajectory(path)
    times = np.asarray(data["times"], dtype=float)
    interval = float(times[1] - times[0]) if len(times) > 1 else 1.0
    pattern = data["pattern"] if data["pattern"] is not None else np.zeros(data["pos"].shape[1], dtype=np.int64)
    return SimpleNamespace(times=times, pos=data["pos"], vel=data["vel"], pattern=pattern, dt=interval,
                           record_every=1)


def observed_summaries(config, runs, columns, path: Path) -> np.ndarray:
    """(N, k): every run of the sweep measured through the calibration's ``[observation]`` block, from its
    stored trajectory (the sweep must keep them, every ``trajectory_every`` steps dividing the observation's
    interval), the observation noise drawn from the run's seed as for a calibration's own runs; a run whose
    statistics are not finite is a NaN row."""
    from flocksweep.observables.observation import observe_run
    from flocksweep.observables.summary import summarize_run

    from .simulator import summary_simulator

    folder = path / "trajectories"
    if not folder.is_dir():
        raise ConfigError("method.results", f"{path} kept no trajectories; the emulator measures the sweep's runs "
                                            "through the [observation] block from them: run the sweep with "
                                            '[run] keep = "trajectories" (trajectory_every dividing the '
                                            "observation's interval)")
    simulator = summary_simulator(config, n_sim=1)
    out = np.full((len(runs), len(config.targets.columns)), np.nan)
    for i, (run_id, seed, theta) in enumerate(zip(runs["run_id"], runs["seed"], runs[columns].to_numpy(dtype=float))):
        trajectory = folder / f"{run_id}.npz"
        if not trajectory.is_file():
            raise ConfigError("method.results", f"{path}: run {run_id} has no trajectory file; the emulator needs "
                                                "every run's trajectory to measure it through the [observation] block")
        try:
            flock = observe_run(_trajectory_run(trajectory), config.observation, int(seed))
        except ValueError as err:
            raise ConfigError("observation.interval", f"the sweep's trajectories cannot be seen through the "
                                                      f"observation block: {err}") from None
        settings = simulator.metrics.resolve(simulator.preset(theta).model)
        row = summarize_run(flock, settings)
        out[i] = [row.get(c, np.nan) for c in config.targets.columns]
    return out


def training_set(results_path, config) -> TrainingSet:
    """Per-point training statistics from a sweep results folder; see the module docstring."""
    path = Path(results_path if results_path is not None else config.method.results)
    results, model = _load_sweep(path)
    runs = results.ok
    columns = _free_columns(config, runs, model, results.sweep)
    _check_fixed_settings(config, model, path)
    if config.observation is None:
        _check_stat_columns(config, runs, results.metrics)
    runs, fixed = _filter_fixed_factors(config, runs, model)
    points = runs[columns].to_numpy(dtype=float)
    if config.observation is not None:
        summaries = observed_summaries(config, runs, columns, path)
    else:
        summaries = runs[list(config.targets.columns)].to_numpy(dtype=float)
    try:
        training = group_replicates(points, summaries, config.names, config.targets.columns, config.keys,
                                    fixed=fixed, source=path)
    except ValueError as err:
        raise ConfigError("method.results", f"{path}: {err}") from None
    _check_prior_overlap(config, training)
    return training
