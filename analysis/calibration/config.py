"""Calibration definitions: a TOML file -> a frozen, validated :class:`CalibrationConfig`.

A calibration file names a model preset (plus fixed overrides), the fixed run settings, the free
parameters with their priors, the observed summary statistics and the fitting method. Every key is
checked (unknown keys get a did-you-mean) and every value is validated before anything runs::

    name = "recover_holland"        # plain folder name
    description = "..."
    seed = 7                        # integer >= 0 (default 0)

    [model]
    preset = "../models/holland.toml"      # relative to this file, absolute, or relative to the cwd
    set = { "perception.range" = 20 }      # fixed preset overrides, dotted keys

    [run]                           # fixed settings, all optional (defaults from the preset)
    n = 30                          # init.n
    duration = 10.0                 # run.duration (seconds)
    dt = 0.016666666666666666       # run.dt
    record_interval = 1.0           # run.record_interval
    warmup = 3.0                    # seconds excluded from window means (default 3.0; < duration)
    group_radius = "auto"           # "auto" = the model's perception range (at each theta), or a number
    fragmentation_cohesion = 0.5    # cohesion below this counts as fragmented

    [parameters.field]              # one table per free parameter; the table name is its name
    key = "perception.field_deg"    # the preset key it sets ("n" means init.n)
    prior = { dist = "uniform", low = 30, high = 360 }
    bounds = [30, 360]              # optional hard bounds (default: the prior's support); must be finite

    [parameters.direction]
    key = "perception.direction_deg"
    prior = { dist = "truncnormal", mean = 45, sd = 30, low = 0, high = 90 }

    [targets]                       # observed summary statistics
    summary = "mean"                # each simulated run summarised by "mean" (window mean after warmup)
                                    # or "final" (last record)
    stats = ["cohesion", "polarization", "nn_distance"]   # per-record metric names, leadership metric
                                                          # names or directional correlation delays
                                                          # (dcd_*, up to run.dcd_max_delay = 2 s)
    mean = [0.9, 0.8, 2.5]          # observed values ...
    sd = [0.05, 0.05, 0.3]          # ... with their uncertainty (sd > 0), or cov = [[...], ...] (k x k,
                                    # symmetric positive definite); OR instead of mean/sd/cov:
    # samples = "observed.csv"      # CSV, one column per stat (named by the stat), one row per dataset
    truth = { field = 135, direction = 45 }   # optional: the parameters the targets were simulated at
                                    # (a recovery study): drawn as truth lines, checked in the report
    transform = "auto"              # optional: how the statistics are transformed for the npe learner and
                                    # BSL's Gaussian: "auto" (from each statistic's range: logit of
                                    # polarization, log of nn_distance, ...), "none", or a table
                                    # { polarization = "logit", nn_distance = "none" } (analysis/calibration/transforms.py)
    flock = { n_groups = 1 }        # optional: the observed flock's other statistics, not fitted: the
                                    # predictive runs are checked against them (analysis/calibration/flock_check.py)
    # from_tracks = "tracks.csv.gz" # OR measured tracks: each flock one sample (aggregate = "mean": their
                                    # mean and its covariance); [targets.tracks] says how to read them and
                                    # [observation] how they were measured (analysis/calibration/tracks_targets.py)

    [observation]                   # optional: how the targets were measured; every simulated run is then
    interval = 0.2                  # measured alike (observables.observation: velocity_interval,
                                    # max_gap, detection_probability, position_sd, projection)

    [method]
    kind = "emcee"                  # "emcee" | "optimize" | "emulator" | "npe" (docs/calibration.md)
    n_sim = 50                      # replicates per likelihood evaluation (all kinds)
    likelihood = "gaussian"         # "gaussian" (n_sim >= k + 2) or "unbiased" (n_sim >= k + 4)
    # emcee:    walkers (even, >= 2 x parameters), steps (>= 1), reevaluate_every (0: never),
    #           moves = "stretch" (emcee's default) | "de" (differential evolution + snooker)
    # optimize: algorithm = "differential_evolution" | "nelder_mead", objective = "loglik" (negative
    #           synthetic log posterior) | "distance" (standardised distance), maxiter, popsize, recheck
    # emcee:    ... until_converged = true (steps a cap: stop when 50 tau, R-hat, ESS hold; check_every = 50)
    # emulator: results = "../../results/holland648_r5" (required: a sweep's results folder),
    #           surrogate = "gp" | "rbf", confirm (real runs at the posterior median, 0: none; >= 2),
    #           walkers, steps, moves (emcee on the surrogate: cheap, default 5000 steps),
    #           refine = { rounds, runs_per_round, max_emulator_share = 0.1 } (new sweep points until the
    #           confirmation passes and the emulator's variance is <= that share of the likelihood's)
    # [method.emcee], [method.optimize], [method.emulator]: settings for several methods in one file;
    # kind picks the default, --method another (analysis/calibration/method_table.py)

Summary columns: a per-record metric ``x`` is compared through the run summary column ``x_mean`` or
``x_final`` (``targets.summary``); a leadership metric or a directional correlation delay (``dcd_*``,
:mod:`observables.directional_correlation`) is a per-run scalar and keeps its own name (``RUN_SCALARS``).
The ``dcd_*`` statistics need only velocities: simulated targets, ``from_tracks`` and the ``[observation]``
block all take them.

``[model]`` may instead name an external simulator run as a command (``command``, ``[model.parameters]``,
``[model.tracks]``, as a sweep's: :mod:`sweeps.external`): a free parameter's ``key`` is then one of its
numeric parameters (its declared bounds must hold the prior's support), ``[run]`` gives a numeric
``group_radius``, the warm-up and the metric settings but no preset keys, and every run is the command's
tracks measured (:mod:`analysis.calibration.command_simulator`); ``config.command`` holds it,
``config.preset`` is None.

Tracks that declare their tank (``from_tracks`` with an ``arena``) put the model in it: a preset without an
``[arena]`` gets the tracks' (in ``preset_data`` too, so every simulation has it), one with a tank of another
geometry is refused naming both (:func:`analysis.calibration.tracks_targets.shared_tank`).

The file is read by the schema engine (:mod:`simcore.schema`); ``[model]`` and ``[run]`` are the tables
of sweep files (:class:`sweeps.config.ModelTable`, :class:`sweeps.config.RunTable`), applied to the
preset the same way. ``[method]`` (:mod:`analysis.calibration.method_table`) becomes typed settings per kind (:mod:`analysis.calibration.settings`:
``EmceeSettings``, ``OptimizeSettings``, ``EmulatorSettings`` or ``NpeSettings``; ``config.method.kind`` names it).

Parameter keys are checked by setting each parameter to its prior mean (integer keys rounded) with
:meth:`simcore.Preset.replace` on the fixed preset (model.set and run settings applied), which is
built once; then the whole support the chain may explore (the prior's, cut to ``bounds``) is checked
against the key's allowed range at both ends, and ``n_sim`` runs of the largest flock the parameters
allow must fit in memory (:mod:`analysis.calibration.feasibility`), so a prior reaching outside the
model's range is refused before anything is written, naming ``parameters.<name>.prior`` (or
``.bounds``). ``run.warmup`` and ``run.record_interval`` must leave a record to summarise
(:func:`sweeps.config.check_window`); the obstacle, predator and prey metric settings of ``[run]``
(``capture_radius``, ``predator_near``, ``prey_reach``) are refused, as those metrics are no targets
(:func:`check_no_encounter_settings`). Errors are :class:`ConfigError` whose ``key`` is the dotted key in
this file.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd

from flocksweep.observables.columns import MOTION_METRIC_NAMES, PAIRWISE_SERIES, WALL_METRIC_NAMES
from flocksweep.observables.directional_correlation import DCD_METRIC_NAMES
from flocksweep.observables.leadership import LEADERSHIP_METRIC_NAMES
from flocksweep.observables.metrics import METRIC_NAMES
from flocksweep.observables.observation import Observation
from flocksweep.observables.summary import MetricSettings, encounter_settings, motion_settings
from flocksweep.simcore.params import Preset, canonical_key, preset_from_dict
from flocksweep.simcore.schema import (ConfigError, FileConfig, build, check_at_least, get_dotted, input_file, read_config,
                            resolve_path, suggest)
from flocksweep.observables.measured import track_settings
from flocksweep.sweeps.config import RunTable, check_name, check_window, model_data, model_table
from flocksweep.sweeps.external import CommandModel, CommandTable, command_model
from flocksweep.sweeps.model_set import model_overrides

from .feasibility import check_memory, check_support
from .flock_check import check_flock_table
from .priors import JointPrior, Normal, prior_from_dict
from .method_table import chosen_kind, method_settings
from .methods import method_of
from .settings import MethodSettings
from .tracks_targets import (check_observation, check_tank_parameters, fixed_group_radius, read_target_tracks,
                             shared_tank, tracks_record, tracks_targets)
from .transforms import Transforms, transforms_from

RUN_SCALARS = (tuple(LEADERSHIP_METRIC_NAMES) + DCD_METRIC_NAMES + MOTION_METRIC_NAMES
               + WALL_METRIC_NAMES)   # per-run: no _mean / _final
STAT_NAMES = tuple(METRIC_NAMES) + RUN_SCALARS


def stat_columns(stats, summary: str) -> tuple[str, ...]:
    """The summary column of each statistic: ``<metric>_<summary>``, or a per-run scalar's own name."""
    return tuple(s if s in RUN_SCALARS else f"{s}_{summary}" for s in stats)


# ---------------------------------------------------------------------------------------- the file

@dataclass(frozen=True)
class ParameterTable:
    key: str = field(metadata={"expected": "the dotted preset key, e.g. 'perception.field_deg'"})
    prior: dict = field(metadata={"expected": 'a table such as { dist = "uniform", low = 0, high = 1 }'})
    bounds: Any = None


@dataclass(frozen=True)
class TargetsTable:
    summary: Literal["mean", "final"] = "mean"
    stats: Any = None
    mean: Any = None
    sd: Any = None
    cov: Any = None
    samples: str | None = None
    truth: dict | None = None
    from_tracks: str | None = None
    aggregate: Literal["samples", "mean"] | None = None
    tracks: dict | None = None
    flock: dict | None = None
    transform: Any = None


@dataclass(frozen=True)
class CalibrationFile:
    """A calibration file's tables, type-checked (see the module docstring)."""

    name: str = field(metadata={"expected": "a non-empty string naming the calibration"})
    model: Any = field(metadata={"expected": 'a table naming a preset ([model] preset = "...") or a command '
                                             '([model] command = [...], an external simulator)'})
    parameters: dict[str, ParameterTable] = field(
        metadata={"expected": "at least one [parameters.<name>] table with key and prior"})
    targets: TargetsTable = field(
        metadata={"expected": "a table: [targets] stats and mean/sd (or cov) or samples"})
    method: dict = field(metadata={"expected": "a table: [method] kind = \"emcee\", \"optimize\" or \"emulator\" "
                                               "(and/or [method.emcee], [method.optimize], ... tables)"})
    description: str = ""
    seed: int = 0
    run: RunTable = field(default_factory=RunTable)
    observation: Observation | None = None

    def __post_init__(self):
        check_name(self.name, "the calibration")
        check_at_least("seed", self.seed, 0)
        object.__setattr__(self, "model", model_table(self.model))


# ---------------------------------------------------------------------------------------- the config

@dataclass(frozen=True)
class Parameter:
    """A free parameter: its name, the preset key it sets, its prior and finite hard bounds."""

    name: str
    key: str
    prior: Any
    bounds: tuple[float, float]


@dataclass(frozen=True, eq=False)
class Targets:
    """Observed statistics. ``observed`` is (m, k); ``cov`` is (k, k), or None when ``samples`` gave them."""

    summary: str
    stats: tuple[str, ...]
    columns: tuple[str, ...]
    observed: np.ndarray
    cov: np.ndarray | None
    samples_path: Path | None = None
    truth: dict | None = None      # parameter name -> value the targets were simulated at (recovery studies)
    tracks_path: Path | None = None     # from_tracks: the track file, its flocks and their values (m, k)
    flocks: tuple[str, ...] = ()
    per_flock: np.ndarray | None = None
    flock: dict = field(default_factory=dict)   # [targets] flock: the observed flock's other statistics (column -> value)
    flock_runs: Any = None              # from_tracks: every measured flock's row (all metrics), for the flock check
    flock_tracks: tuple = field(default=(), repr=False)   # from_tracks: the measured flocks (ObservedFlock), for the viewer
    tracks_warmup: float = 0.0          # from_tracks: seconds skipped at the start of each measured flock
    tank: Any = None                    # from_tracks: the tank the tracks declare (simcore.arena.Arena, their coordinates)
    tracks_record: dict | None = None   # from_tracks: the file, its format, every unit and scale used with its
                                        # source, and what the checks found (convergence.json's "tracks")

    @property
    def k(self) -> int:
        return len(self.stats)


@dataclass(frozen=True)
class CalibrationConfig(FileConfig, loader="load_calibration"):
    """A calibration file, validated (module docstring); ``CalibrationConfig.from_toml(path, overrides)`` reads one."""

    name: str
    description: str
    seed: int
    preset_path: Path
    preset_data: dict = field(repr=False, compare=False, hash=False)  # preset with model.set and [run] applied
    preset: Preset | None = field(default=None, repr=False, compare=False, hash=False)  # the same, validated
    metrics: MetricSettings = field(default_factory=MetricSettings)
    parameters: tuple[Parameter, ...] = ()
    prior: JointPrior | None = field(default=None, repr=False, compare=False, hash=False)
    targets: Targets | None = field(default=None, compare=False, hash=False)
    method: MethodSettings | None = None
    source: dict = field(default_factory=dict, repr=False, compare=False, hash=False)  # file as given (+ overrides)
    observation: Observation | None = None   # how the targets were measured; simulated runs are measured alike
    folder_name: str = ""    # results/calibration/<folder_name>: the name, with -<kind> for another method than the file's
    methods: tuple[str, ...] = ()   # the methods the file holds settings for
    transforms: Transforms | None = field(default=None, repr=False, compare=False, hash=False)  # [targets] transform
    source_path: Path | None = field(default=None, compare=False, hash=False)   # the file read (load_calibration)
    command: CommandModel | None = field(default=None, repr=False, compare=False, hash=False)  # an external simulator

    @property
    def warmup(self) -> float:
        return self.metrics.warmup

    @property
    def record_interval(self) -> float | None:
        """Seconds between the records a run is summarised over (the observation's interval with one; a
        command's ``[model.tracks] interval``, None when its output's own)."""
        if self.observation is not None:
            return float(self.observation.interval)
        if self.command is not None:
            return self.command.tracks.interval
        return float(self.preset.run.dt * self.preset.run.record_every)

    @property
    def dims(self) -> int | None:
        """2 for a run seen in 2-D (an observation's projection, or a planar model), else 3 (None: a command's
        output, as it writes it)."""
        if self.observation is not None:
            return self.observation.dims
        if self.command is not None:
            return None
        return int(self.preset.model.world.dimensions)

    @property
    def model_label(self) -> str:
        """The model in words: its preset file, or the command."""
        if self.command is not None:
            return "command: " + " ".join(self.command.template)
        return str(self.preset_path)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.parameters)

    @property
    def dim(self) -> int:
        return len(self.parameters)


# ------------------------------------------------------------------------------------------- helpers

def _float(value, key: str, allowed: str = "a finite number") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(key, f"got {value!r}; expected {allowed}")
    return float(value)


def _vector(value, key: str, k: int, stats) -> np.ndarray:
    if not isinstance(value, list) or len(value) != k:
        raise ConfigError(key, f"got {value!r}; expected a list of {k} numbers, one per stat {list(stats)}")
    return np.array([_float(v, f"{key}[{i}]") for i, v in enumerate(value)])


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


# -------------------------------------------------------------------------------------------- tables

def _command_and_run(table: CalibrationFile, base: Path):
    """An external simulator's model (:mod:`sweeps.external`) and the checks of ``[run]`` it needs."""
    command = command_model(table.model, base)
    run = table.run
    for short in ("n", "duration", "dt", "record_interval"):
        if getattr(run, short) is not None:
            raise ConfigError(f"run.{short}", "sets a key of a model preset; a command model has none: declare the "
                                              "simulator's own settings in [model.parameters]")
    if not isinstance(run.group_radius, (int, float)) or isinstance(run.group_radius, bool):
        raise ConfigError("run.group_radius", f"got {run.group_radius!r}; a command model has no perception range "
                                              "to default to: give the linking radius in body lengths")
    check_no_encounter_settings(run)
    return command


def _model_and_run(table: CalibrationFile, base: Path) -> tuple[Path, dict, Preset]:
    preset_path, preset_data, origin = model_data(table.model, table.run, base)
    try:
        preset = preset_from_dict(preset_data)
    except ConfigError as err:
        raise ConfigError(origin.get(err.key, err.key), err.detail) from None
    check_window(table.run.warmup, preset.run)
    check_no_encounter_settings(table.run)
    return preset_path, preset_data, preset


def check_no_encounter_settings(run: RunTable) -> None:
    """ConfigError for a calibration file's ``[run]`` that sets an obstacle, predator or prey metric
    setting: those metrics are not calibration targets, so the setting would do nothing."""
    for key in encounter_settings(run.metrics(leadership=False)):
        raise ConfigError(f"run.{key}", "sets an obstacle, predator or prey metric, and those are not calibration "
                                        "targets: leave it out of a calibration file")


def _rekey_prior_error(err: ConfigError, name: str) -> ConfigError:
    if err.key.startswith("bounds."):
        return ConfigError(f"parameters.{name}.bounds", err.detail)
    return ConfigError(f"parameters.{name}.prior", err.detail)


def _bounds(spec: ParameterTable, prior, where: str) -> tuple[float, float]:
    if spec.bounds is not None:
        pair = spec.bounds
        if not isinstance(pair, list) or len(pair) != 2:
            raise ConfigError(f"{where}.bounds", f"got {pair!r}; expected [low, high] (finite numbers)")
        low, high = (_float(v, f"{where}.bounds", "finite numbers [low, high]") for v in pair)
        if not low < high:
            raise ConfigError(f"{where}.bounds", f"got {pair!r}; low must be < high")
        return low, high
    low, high = prior.bounds
    if not (math.isfinite(low) and math.isfinite(high)):
        family = "normal" if isinstance(prior, Normal) else "this"
        raise ConfigError(f"{where}.bounds", f"{family} prior has unbounded support [{low}, {high}]; "
                                             "give finite bounds = [low, high]")
    return low, high


def _command_parameter(name: str, key: str, marginal, bounds, command) -> None:
    """A command model's free parameter: a numeric parameter of ``[model.parameters]`` whose declared bounds
    hold the prior's support (both ends)."""
    declared = dict(command.parameters)
    where = f"parameters.{name}"
    if key not in declared:
        raise ConfigError(f"{where}.key", f"{key!r} is not a parameter of the command{suggest(key, list(declared))}; "
                                          f"declared in [model.parameters]: {', '.join(declared) or 'none'}")
    spec = declared[key]
    if spec.choices is not None:
        raise ConfigError(f"{where}.key", f"{key!r} takes one of {list(spec.choices)}; a free parameter must be a "
                                          "number")
    for end in bounds:
        value = int(round(end)) if spec.integer else float(end)
        try:
            spec.check(value, key)
        except ConfigError as err:
            raise ConfigError(f"{where}.prior", f"the prior's support [{bounds[0]:g}, {bounds[1]:g}] reaches "
                                                f"{value!r}, where {err.detail}; keep it inside the parameter's "
                                                "bounds (e.g. with bounds = [low, high])") from None


def _parameters(table: CalibrationFile, preset: Preset, command=None) -> tuple[tuple[Parameter, ...], JointPrior]:
    if not table.parameters:
        raise ConfigError("parameters", "missing: give at least one [parameters.<name>] table with key and prior")
    names, keys, priors, bounds = [], [], [], {}
    for name, spec in table.parameters.items():
        where = f"parameters.{name}"
        key = canonical_key(spec.key) if command is None else spec.key
        if key in keys:
            other = names[keys.index(key)]
            raise ConfigError(f"{where}.key", f"{key!r} is already set by parameter {other!r}; each key once")
        prior = prior_from_dict(spec.prior, f"{where}.prior")
        bounds[name] = _bounds(spec, prior, where)
        names.append(name)
        keys.append(key)
        priors.append(prior)
    try:
        joint = JointPrior(names, priors, bounds)
    except ConfigError as err:
        name = err.key.split(".", 1)[-1]
        if name in names:
            raise _rekey_prior_error(err, name) from None
        raise
    if command is not None:
        for name, key, marginal in zip(names, keys, joint.marginals):
            _command_parameter(name, key, marginal, bounds[name], command)
        return tuple(Parameter(name=n, key=k, prior=p, bounds=bounds[n])
                     for n, k, p in zip(names, keys, joint.marginals)), joint
    base_values = preset.full_dict()
    for name, key, marginal in zip(names, keys, joint.marginals):
        _check_parameter_key(name, key, marginal.moments[0], preset, base_values)
        where = f"parameters.{name}." + ("bounds" if table.parameters[name].bounds is not None else "prior")
        check_support(where, key, marginal.bounds, preset, isinstance(get_dotted(base_values, key), int))
    params = tuple(Parameter(name=n, key=k, prior=p, bounds=bounds[n])
                   for n, k, p in zip(names, keys, joint.marginals))
    return params, joint


def _check_parameter_key(name: str, key: str, value: float, preset: Preset, base_values: dict) -> None:
    where = f"parameters.{name}.key"
    current = get_dotted(base_values, key)
    if isinstance(current, (bool, str, dict)):
        kind = "a table" if isinstance(current, dict) else f"not numeric (currently {current!r})"
        raise ConfigError(where, f"{key!r} is {kind}; a free parameter must be a numeric preset key")
    if isinstance(current, int):
        value = int(round(value))
    try:
        preset.replace({key: value})
    except ConfigError as err:
        raise ConfigError(where, f"{key!r} is not a valid preset key for this model "
                                 f"(setting it to {value!r}: {err})") from None


def _stats(targets: TargetsTable) -> tuple[str, ...]:
    stats = targets.stats
    if not isinstance(stats, list) or not stats:
        raise ConfigError("targets.stats", f"got {stats!r}; expected a non-empty list of metric names")
    for stat in stats:
        if not isinstance(stat, str) or stat not in STAT_NAMES:
            hint = suggest(stat, STAT_NAMES) if isinstance(stat, str) else ""
            raise ConfigError("targets.stats", f"unknown metric {stat!r}{hint}; allowed: {', '.join(STAT_NAMES)}")
    dupes = sorted({s for s in stats if stats.count(s) > 1})
    if dupes:
        raise ConfigError("targets.stats", f"{dupes[0]!r} is listed twice")
    return tuple(stats)


def _covariance(targets: TargetsTable, k: int, stats) -> np.ndarray:
    if (targets.sd is None) == (targets.cov is None):
        raise ConfigError("targets.sd", "give exactly one of sd (per stat) or cov (k x k) with mean")
    if targets.sd is not None:
        sd = _vector(targets.sd, "targets.sd", k, stats)
        if np.any(sd <= 0):
            raise ConfigError("targets.sd", f"got {targets.sd!r}; every sd must be > 0")
        return np.diag(sd ** 2)
    raw = targets.cov
    if not isinstance(raw, list) or len(raw) != k or not all(isinstance(r, list) and len(r) == k for r in raw):
        raise ConfigError("targets.cov", f"expected a {k} x {k} list of lists (one row per stat)")
    cov = np.array([[_float(v, f"targets.cov[{i}][{j}]") for j, v in enumerate(row)] for i, row in enumerate(raw)])
    if not np.allclose(cov, cov.T, rtol=1e-10, atol=1e-12):
        raise ConfigError("targets.cov", "must be symmetric")
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ConfigError("targets.cov", "must be positive definite") from None
    return cov


def _targets(targets: TargetsTable, base: Path) -> Targets:
    stats = _stats(targets)
    k = len(stats)
    columns = stat_columns(stats, targets.summary)
    for key in ("aggregate", "tracks"):
        if getattr(targets, key) is not None:
            raise ConfigError(f"targets.{key}", "only with from_tracks = \"tracks file\"")
    has_mean, has_samples = targets.mean is not None, targets.samples is not None
    if has_mean and has_samples:
        raise ConfigError("targets.samples", "give either mean (with sd or cov) or samples, not both")
    if not has_mean and not has_samples:
        raise ConfigError("targets.mean", "missing: give mean (with sd or cov), or samples = \"file.csv\"")
    if has_samples:
        for key in ("sd", "cov"):
            if getattr(targets, key) is not None:
                raise ConfigError(f"targets.{key}", "only with mean; samples carry their own spread")
        path = resolve_path(targets.samples, base, "targets.samples", "samples file")
        observed = _read_samples(path, stats, columns)
        return Targets(summary=targets.summary, stats=stats, columns=columns, observed=_readonly(observed),
                       cov=None, samples_path=path)
    mean = _vector(targets.mean, "targets.mean", k, stats)
    cov = _covariance(targets, k, stats)
    return Targets(summary=targets.summary, stats=stats, columns=columns, observed=_readonly(mean[None, :]),
                   cov=_readonly(cov))


def _truth(truth: dict | None, parameters: tuple[Parameter, ...]) -> dict | None:
    """``targets.truth``: a value for every free parameter, inside its bounds, or None."""
    if truth is None:
        return None
    names = [p.name for p in parameters]
    for name in truth:
        if name not in names:
            raise ConfigError(f"targets.truth.{name}", f"not a free parameter{suggest(name, names)}; free "
                                                      f"parameters: {', '.join(names)}")
    out = {}
    for parameter in parameters:
        if parameter.name not in truth:
            raise ConfigError("targets.truth", f"missing {parameter.name!r}; give the value of every free parameter "
                                               f"({', '.join(names)}) the targets were simulated at")
        value = _float(truth[parameter.name], f"targets.truth.{parameter.name}")
        low, high = parameter.bounds
        if not low <= value <= high:
            raise ConfigError(f"targets.truth.{parameter.name}", f"got {value:g}; outside the bounds [{low:g}, "
                                                                 f"{high:g}] of {parameter.name}")
        out[parameter.name] = value
    return out


SAMPLES_LIMIT = 256 << 20   # bytes: a table of observed datasets


def _read_samples(path: Path, stats, columns) -> np.ndarray:
    input_file(path, "targets.samples", "samples file", SAMPLES_LIMIT)   # no folder, FIFO, device; bounded
    try:
        frame = pd.read_csv(path)
    except Exception as err:  # noqa: BLE001 - any unreadable file is a config problem
        raise ConfigError("targets.samples", f"cannot read {path} as CSV: {err}") from None
    out = []
    for stat, column in zip(stats, columns):
        name = stat if stat in frame.columns else column if column in frame.columns else None
        if name is None:
            raise ConfigError("targets.samples", f"{path.name} has no column {stat!r}"
                                                 f"{suggest(stat, [str(c) for c in frame.columns])}; "
                                                 f"columns: {', '.join(map(str, frame.columns))}")
        values = pd.to_numeric(frame[name], errors="coerce").to_numpy(dtype=float)
        if not np.all(np.isfinite(values)):
            raise ConfigError("targets.samples", f"column {name!r} of {path.name} has missing or non-numeric values")
        out.append(values)
    observed = np.column_stack(out)
    if observed.shape[0] < 1:
        raise ConfigError("targets.samples", f"{path.name} has no rows; need one row per observed dataset")
    return observed


# -------------------------------------------------------------------------------------------- public

def _observed_targets(table: CalibrationFile, preset: Preset | None, parameters, base: Path, tracks=None
                      ) -> tuple[Targets, MetricSettings]:
    """The targets and metric settings, with the [observation] block checked and from_tracks measured
    (``preset`` None: a command model, whose runs are measured as tracks)."""
    stats = _stats(table.targets)
    dcd = any(s in DCD_METRIC_NAMES for s in stats)
    if preset is None:
        run = table.run
        metrics = dataclasses.replace(track_settings(run.group_radius, run.warmup, run.fragmentation_cohesion,
                                                     run.dcd_max_delay), dcd=dcd,
                                      **motion_settings(run.metrics(leadership=False, dcd=dcd)))
    else:
        metrics = table.run.metrics(leadership=False, dcd=dcd)
    off = [s for s in stats if s in PAIRWISE_SERIES] if not metrics.pairwise_metrics else []
    if off:
        raise ConfigError("targets.stats", f"{off[0]!r} is computed only with run.pairwise_metrics = true (it ranks "
                                           "every pair of every record): remove it or the setting")
    walls = [s for s in stats if s in WALL_METRIC_NAMES]
    if walls and preset is not None and preset.model.arena.kind == "none":
        raise ConfigError("targets.stats", f"{walls[0]!r} measures where the flock keeps from its tank's walls, and "
                                           "the model has no tank: give the preset an [arena] (or model.set "
                                           "arena.kind = ...), or remove the statistic")
    if table.observation is not None:
        check_observation(table.observation, preset, table.run, stats)
    if table.targets.from_tracks is None:
        targets = _targets(table.targets, base)
    else:
        columns = stat_columns(stats, table.targets.summary)
        if preset is not None:
            metrics = dataclasses.replace(metrics, group_radius=fixed_group_radius(metrics, preset, parameters))
        found = tracks_targets(table.targets, table.observation, metrics, columns, base, tracks)
        targets = Targets(summary=table.targets.summary, stats=stats, columns=columns,
                          observed=_readonly(found.observed), cov=None if found.cov is None else _readonly(found.cov),
                          samples_path=found.path if found.cov is None else None, tracks_path=found.path,
                          flocks=found.flocks, per_flock=_readonly(found.per_flock),
                          flock_runs=found.measurement.runs, flock_tracks=tuple(found.measurement.flocks),
                          tracks_warmup=float(found.measurement.table.source.warmup),
                          tank=found.measurement.table.source.tank(), tracks_record=tracks_record(found))
    targets = dataclasses.replace(targets, flock=check_flock_table(table.targets.flock, targets.summary,
                                                                    targets.columns))
    return targets, metrics


def calibration_from_dict(data: dict, base: Path, method: str | None = None) -> CalibrationConfig:
    """Validated calibration from a parsed TOML dict; ``base`` is the folder relative paths start from;
    ``method`` picks one of the methods the file holds settings for (default: its ``method.kind``)."""
    table = build(CalibrationFile, data)
    base = Path(base)
    if isinstance(table.model, CommandTable):
        command = _command_and_run(table, base)
        preset_path, preset_data, preset = None, {}, None
    else:
        command = None
        preset_path, preset_data, preset = _model_and_run(table, base)
    tracks = None
    if table.targets.from_tracks is not None and preset is not None and table.observation is not None:
        tracks = read_target_tracks(table.targets, base)     # read once: its tank is the model's (shared_tank)
        preset, preset_data = shared_tank(preset, preset_data, tracks, table.observation)
    parameters, joint = _parameters(table, preset, command)
    check_tank_parameters(parameters, tracks)
    chosen_kind(table.method, method)      # an unknown method is named before the targets are measured
    targets, metrics = _observed_targets(table, preset, parameters, base, tracks)
    targets = dataclasses.replace(targets, truth=_truth(table.targets.truth, parameters))
    choice = method_settings(table.method, base, len(parameters), targets.k, method)
    if preset is not None:
        check_memory(preset, parameters, choice.settings.n_sim)
    transforms = transforms_from(table.targets.transform, targets.stats, targets.columns)
    config = CalibrationConfig(name=table.name, description=table.description, seed=table.seed,
                             preset_path=preset_path, preset_data=preset_data, preset=preset,
                             metrics=metrics, parameters=parameters, prior=joint,
                             targets=targets, method=choice.settings, source=data, observation=table.observation,
                             folder_name=table.name if choice.own else f"{table.name}-{choice.kind}",
                             methods=choice.available, transforms=transforms, command=command)
    method_of(choice.kind).check(config)   # the method's own checks of the whole file
    return config


def load_calibration(path, overrides=(), method: str | None = None) -> CalibrationConfig:
    """Read a calibration TOML, apply ``key=value`` overrides (of this file's own keys; ``model.<preset
    key>`` is short for ``model.set.<preset key>``), pick ``method`` (default: the file's kind), validate."""
    path = Path(path)
    config = calibration_from_dict(read_config(path, "calibration file", model_overrides(overrides)),
                                   path.resolve().parent, method)
    return dataclasses.replace(config, source_path=path)
