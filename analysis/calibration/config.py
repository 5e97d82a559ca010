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
    stats = ["cohesion", "polarization", "nn_distance"]   # per-record metric names (analysis.metrics) or
                                                          # leadership metric names (analysis.leadership)
    mean = [0.9, 0.8, 2.5]          # observed values ...
    sd = [0.05, 0.05, 0.3]          # ... with their uncertainty (sd > 0), or cov = [[...], ...] (k x k,
                                    # symmetric positive definite); OR instead of mean/sd/cov:
    # samples = "observed.csv"      # CSV, one column per stat (named by the stat), one row per dataset

    [method]
    kind = "emcee"                  # "emcee" | "optimize" | "emulator"
    n_sim = 50                      # replicates per likelihood evaluation (all kinds)
    likelihood = "gaussian"         # "gaussian" (n_sim >= k + 2) or "unbiased" (n_sim >= k + 4)
    # emcee:    walkers (even, >= 2 x parameters), steps (>= 1), reevaluate_every (0: never),
    #           moves = "stretch" (emcee's default) | "de" (differential evolution + snooker)
    # optimize: algorithm = "differential_evolution" | "nelder_mead", objective = "loglik" (negative
    #           synthetic log posterior) | "distance" (standardised distance), maxiter, popsize, recheck
    # emulator: results = "../../results/holland648_r5" (required: a sweep's results folder),
    #           surrogate = "gp" | "rbf", confirm (real runs at the posterior median, 0: none; >= 2),
    #           walkers, steps, moves (emcee on the surrogate: cheap, default 5000 steps)

Summary columns: a per-record metric ``x`` is compared through the run summary column ``x_mean`` or
``x_final`` (``targets.summary``); a leadership metric is a per-run scalar and keeps its own name.

Parameter keys are checked by building the preset with each parameter set to its prior mean (integer
keys rounded); the fixed preset (model.set and run settings applied) is built once with
``preset_from_dict``. Errors are :class:`ConfigError` whose ``key`` is the dotted key in this file.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.calibration.priors import JointPrior, Normal, prior_from_dict
from analysis.leadership import LEADERSHIP_METRIC_NAMES
from analysis.metrics import METRIC_NAMES, WARMUP_S
from simcore.params import preset_from_dict, read_toml
from simcore.schema import ConfigError, get_dotted, read_config, set_dotted, suggest

TOP_KEYS = ("name", "description", "seed", "model", "run", "parameters", "targets", "method")
MODEL_KEYS = ("preset", "set")
RUN_KEYS = ("n", "duration", "dt", "record_interval", "warmup")
PARAMETER_KEYS = ("key", "prior", "bounds")
TARGET_KEYS = ("summary", "stats", "mean", "sd", "cov", "samples")
SUMMARIES = ("mean", "final")
STAT_NAMES = tuple(METRIC_NAMES) + tuple(LEADERSHIP_METRIC_NAMES)
KEY_ALIASES = {"n": "init.n"}
RUN_TARGETS = {"n": "init.n", "duration": "run.duration", "dt": "run.dt", "record_interval": "run.record_interval"}

METHOD_KINDS = ("emcee", "optimize", "emulator")
LIKELIHOODS = ("gaussian", "unbiased")
ALGORITHMS = ("differential_evolution", "nelder_mead")
SURROGATES = ("gp", "rbf")
OBJECTIVES = ("loglik", "distance")
MOVES = ("stretch", "de")
COMMON_METHOD_DEFAULTS = {"n_sim": 50, "likelihood": "gaussian"}
METHOD_DEFAULTS = {
    "emcee": {"walkers": None, "steps": 2000, "reevaluate_every": 0, "moves": "stretch"},  # walkers None: max(16, 2 d), even
    "optimize": {"algorithm": "differential_evolution", "objective": "loglik", "maxiter": 100, "popsize": 15,
                 "recheck": 200},
    "emulator": {"results": None, "surrogate": "gp", "confirm": 100, "walkers": None, "steps": 5000,
                 "moves": "stretch"},
}


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

    @property
    def k(self) -> int:
        return len(self.stats)


@dataclass(frozen=True)
class Method:
    """Fitting method ``kind`` with its validated settings (defaults filled in)."""

    kind: str
    settings: dict = field(compare=False, hash=False)


@dataclass(frozen=True)
class CalibrationConfig:
    name: str
    description: str
    seed: int
    preset_path: Path
    preset_data: dict = field(repr=False, compare=False, hash=False)  # preset with model.set and [run] applied
    warmup: float = WARMUP_S
    parameters: tuple[Parameter, ...] = ()
    prior: JointPrior | None = field(default=None, repr=False, compare=False, hash=False)
    targets: Targets | None = field(default=None, compare=False, hash=False)
    method: Method | None = None
    source: dict = field(default_factory=dict, repr=False, compare=False, hash=False)  # file as given (+ overrides)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.parameters)

    @property
    def dim(self) -> int:
        return len(self.parameters)


# ----------------------------------------------------------------------------------------------- helpers

def _check_keys(table, allowed, where: str) -> None:
    if not isinstance(table, dict):
        raise ConfigError(where, f"expected a table, got {table!r}")
    for key in table:
        if key not in allowed:
            raise ConfigError(f"{where}.{key}" if where else key,
                              "unknown key" + suggest(key, allowed) + f"; allowed keys: {', '.join(allowed)}")


def _string(value, key: str, allowed: str) -> str:
    if not isinstance(value, str):
        raise ConfigError(key, f"got {value!r}; expected {allowed}")
    return value


def _int(value, key: str, minimum: int) -> int:
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ConfigError(key, f"got {value!r}; expected an integer >= {minimum}")
    return value


def _float(value, key: str, allowed: str = "a finite number") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(key, f"got {value!r}; expected {allowed}")
    return float(value)


def _choice(value, key: str, allowed) -> str:
    if not isinstance(value, str) or value not in allowed:
        hint = suggest(value, allowed) if isinstance(value, str) else ""
        raise ConfigError(key, f"got {value!r}{hint}; allowed: {', '.join(allowed)}")
    return value


def _resolve_path(text: str, base: Path, key: str, what: str, must_exist: bool = True) -> Path:
    candidates = [Path(text)] if Path(text).is_absolute() else [base / text, Path.cwd() / text]
    for path in candidates:
        if path.exists():
            return path.resolve()
    if not must_exist:
        return candidates[0]
    tried = ", ".join(str(p) for p in candidates)
    raise ConfigError(key, f"{what} not found: {text!r} (looked at {tried})")


def _vector(value, key: str, k: int, stats) -> np.ndarray:
    if not isinstance(value, list) or len(value) != k:
        raise ConfigError(key, f"got {value!r}; expected a list of {k} numbers, one per stat {list(stats)}")
    return np.array([_float(v, f"{key}[{i}]") for i, v in enumerate(value)])


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


# ------------------------------------------------------------------------------------------------ tables

def _parse_model_and_run(data: dict, base: Path) -> tuple[Path, dict, float, Any]:
    model = data.get("model")
    if model is None:
        raise ConfigError("model", "missing table: name a preset with [model] preset = \"...\"")
    _check_keys(model, MODEL_KEYS, "model")
    preset_text = _string(model.get("preset"), "model.preset", "a path to a model preset TOML")
    preset_path = _resolve_path(preset_text, base, "model.preset", "model file")
    if not preset_path.is_file():
        raise ConfigError("model.preset", f"not a file: {preset_path}")
    model_set = model.get("set", {})
    _check_keys(model_set, tuple(model_set), "model.set")
    run = data.get("run", {})
    _check_keys(run, RUN_KEYS, "run")
    preset_data = read_toml(preset_path)
    origin = {}  # preset key -> key in this file, for error messages
    for key, value in model_set.items():
        target = KEY_ALIASES.get(key, key)
        set_dotted(preset_data, target, value)
        origin[target] = f"model.set.{key}"
    for key, target in RUN_TARGETS.items():
        if key in run:
            set_dotted(preset_data, target, run[key])
            origin[target] = f"run.{key}"
    try:
        preset = preset_from_dict(preset_data)
    except ConfigError as err:
        raise ConfigError(origin.get(err.key, err.key), str(err).split(": ", 1)[-1]) from None
    warmup = _float(run.get("warmup", WARMUP_S), "run.warmup", "a number >= 0")
    if warmup < 0 or warmup >= preset.run.duration:
        raise ConfigError("run.warmup", f"got {warmup}; expected a number >= 0 and below the run duration "
                                        f"{preset.run.duration}")
    return preset_path, preset_data, warmup, preset


def _rekey_prior_error(err: ConfigError, name: str) -> ConfigError:
    message = str(err).split(": ", 1)[-1]
    if err.key.startswith("bounds."):
        return ConfigError(f"parameters.{name}.bounds", message)
    return ConfigError(f"parameters.{name}.prior", message)


def _parse_parameters(data: dict, preset_data: dict, preset) -> tuple[tuple[Parameter, ...], JointPrior]:
    table = data.get("parameters")
    if not isinstance(table, dict) or not table:
        raise ConfigError("parameters", "missing: give at least one [parameters.<name>] table with key and prior")
    base_values = preset.full_dict()
    names, keys, priors, bounds = [], [], [], {}
    for name, spec in table.items():
        where = f"parameters.{name}"
        _check_keys(spec, PARAMETER_KEYS, where)
        if "key" not in spec:
            raise ConfigError(f"{where}.key", "missing required key: the dotted preset key, e.g. "
                                              "'perception.field_deg'")
        key = _string(spec["key"], f"{where}.key", "a dotted preset key such as 'perception.field_deg'")
        key = KEY_ALIASES.get(key, key)
        if key in keys:
            other = names[keys.index(key)]
            raise ConfigError(f"{where}.key", f"{key!r} is already set by parameter {other!r}; each key once")
        if "prior" not in spec:
            raise ConfigError(f"{where}.prior", "missing required key: a table such as "
                                                "{ dist = \"uniform\", low = 0, high = 1 }")
        prior = prior_from_dict(spec["prior"], f"{where}.prior")
        if "bounds" in spec:
            pair = spec["bounds"]
            if not isinstance(pair, list) or len(pair) != 2:
                raise ConfigError(f"{where}.bounds", f"got {pair!r}; expected [low, high] (finite numbers)")
            low, high = (_float(v, f"{where}.bounds", "finite numbers [low, high]") for v in pair)
            if not low < high:
                raise ConfigError(f"{where}.bounds", f"got {pair!r}; low must be < high")
        else:
            low, high = prior.bounds
            if not (math.isfinite(low) and math.isfinite(high)):
                family = "normal" if isinstance(prior, Normal) else "this"
                raise ConfigError(f"{where}.bounds", f"{family} prior has unbounded support [{low}, {high}]; "
                                                     "give finite bounds = [low, high]")
        names.append(name)
        keys.append(key)
        priors.append(prior)
        bounds[name] = (low, high)
    try:
        joint = JointPrior(names, priors, bounds)
    except ConfigError as err:
        name = err.key.split(".", 1)[-1]
        if name in names:
            raise _rekey_prior_error(err, name) from None
        raise
    for name, key, marginal in zip(names, keys, joint.marginals):
        _check_parameter_key(name, key, marginal.moments[0], preset_data, base_values)
    params = tuple(Parameter(name=n, key=k, prior=p, bounds=bounds[n])
                   for n, k, p in zip(names, keys, joint.marginals))
    return params, joint


def _check_parameter_key(name: str, key: str, value: float, preset_data: dict, base_values: dict) -> None:
    where = f"parameters.{name}.key"
    current = get_dotted(base_values, key)
    if isinstance(current, (bool, str, dict)):
        kind = "a table" if isinstance(current, dict) else f"not numeric (currently {current!r})"
        raise ConfigError(where, f"{key!r} is {kind}; a free parameter must be a numeric preset key")
    if isinstance(current, int):
        value = int(round(value))
    trial = copy.deepcopy(preset_data)
    try:
        set_dotted(trial, key, value)
        preset_from_dict(trial)
    except ConfigError as err:
        raise ConfigError(where, f"{key!r} is not a valid preset key for this model "
                                 f"(setting it to {value!r}: {err})") from None


def _parse_targets(data: dict, base: Path) -> Targets:
    table = data.get("targets")
    if table is None:
        raise ConfigError("targets", "missing table: give [targets] stats and mean/sd (or cov) or samples")
    _check_keys(table, TARGET_KEYS, "targets")
    summary = _choice(table.get("summary", "mean"), "targets.summary", SUMMARIES)
    stats = table.get("stats")
    if not isinstance(stats, list) or not stats:
        raise ConfigError("targets.stats", f"got {stats!r}; expected a non-empty list of metric names")
    for i, stat in enumerate(stats):
        if not isinstance(stat, str) or stat not in STAT_NAMES:
            hint = suggest(stat, STAT_NAMES) if isinstance(stat, str) else ""
            raise ConfigError("targets.stats", f"unknown metric {stat!r}{hint}; allowed: {', '.join(STAT_NAMES)}")
    dupes = sorted({s for s in stats if stats.count(s) > 1})
    if dupes:
        raise ConfigError("targets.stats", f"{dupes[0]!r} is listed twice")
    stats = tuple(stats)
    k = len(stats)
    columns = tuple(s if s in LEADERSHIP_METRIC_NAMES else f"{s}_{summary}" for s in stats)
    has_mean, has_samples = "mean" in table, "samples" in table
    if has_mean and has_samples:
        raise ConfigError("targets.samples", "give either mean (with sd or cov) or samples, not both")
    if not has_mean and not has_samples:
        raise ConfigError("targets.mean", "missing: give mean (with sd or cov), or samples = \"file.csv\"")
    if has_samples:
        for key in ("sd", "cov"):
            if key in table:
                raise ConfigError(f"targets.{key}", "only with mean; samples carry their own spread")
        path = _resolve_path(_string(table["samples"], "targets.samples", "a path to a CSV file"), base,
                             "targets.samples", "samples file")
        observed = _read_samples(path, stats, columns)
        return Targets(summary=summary, stats=stats, columns=columns, observed=_readonly(observed), cov=None,
                       samples_path=path)
    mean = _vector(table["mean"], "targets.mean", k, stats)
    if ("sd" in table) == ("cov" in table):
        raise ConfigError("targets.sd", "give exactly one of sd (per stat) or cov (k x k) with mean")
    if "sd" in table:
        sd = _vector(table["sd"], "targets.sd", k, stats)
        if np.any(sd <= 0):
            raise ConfigError("targets.sd", f"got {table['sd']!r}; every sd must be > 0")
        cov = np.diag(sd ** 2)
    else:
        raw = table["cov"]
        if not isinstance(raw, list) or len(raw) != k or not all(isinstance(r, list) and len(r) == k for r in raw):
            raise ConfigError("targets.cov", f"expected a {k} x {k} list of lists (one row per stat)")
        cov = np.array([[_float(v, f"targets.cov[{i}][{j}]") for j, v in enumerate(row)]
                        for i, row in enumerate(raw)])
        if not np.allclose(cov, cov.T, rtol=1e-10, atol=1e-12):
            raise ConfigError("targets.cov", "must be symmetric")
        try:
            np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            raise ConfigError("targets.cov", "must be positive definite") from None
    return Targets(summary=summary, stats=stats, columns=columns, observed=_readonly(mean[None, :]),
                   cov=_readonly(cov))


def _read_samples(path: Path, stats, columns) -> np.ndarray:
    import pandas as pd

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


def _parse_method(data: dict, base: Path, dim: int, k: int) -> Method:
    table = data.get("method")
    if table is None:
        raise ConfigError("method", f"missing table: give [method] kind = one of {', '.join(METHOD_KINDS)}")
    if not isinstance(table, dict):
        raise ConfigError("method", f"expected a table, got {table!r}")
    if "kind" not in table:
        raise ConfigError("method.kind", f"missing required key; allowed: {', '.join(METHOD_KINDS)}")
    kind = _choice(table["kind"], "method.kind", METHOD_KINDS)
    allowed = ("kind", *COMMON_METHOD_DEFAULTS, *METHOD_DEFAULTS[kind])
    _check_keys(table, allowed, "method")
    settings = {**COMMON_METHOD_DEFAULTS, **METHOD_DEFAULTS[kind]}
    settings.update({key: value for key, value in table.items() if key != "kind"})
    likelihood = _choice(settings["likelihood"], "method.likelihood", LIKELIHOODS)
    need = k + 2 if likelihood == "gaussian" else k + 4
    n_sim = settings["n_sim"] = _int(settings["n_sim"], "method.n_sim", 2)
    if n_sim < need:
        raise ConfigError("method.n_sim", f"got {n_sim}; the {likelihood} synthetic likelihood needs at least "
                                          f"{need} replicates for {k} stats (n_sim >= k + {need - k})")
    if kind in ("emcee", "emulator"):
        walkers = settings["walkers"]
        if walkers is None:
            walkers = max(16, 2 * dim)
        walkers = settings["walkers"] = _int(walkers, "method.walkers", 2)
        if walkers < 2 * dim:
            raise ConfigError("method.walkers", f"got {walkers}; need at least 2 x {dim} parameters = {2 * dim}")
        if walkers % 2:
            raise ConfigError("method.walkers", f"got {walkers}; must be even")
        settings["steps"] = _int(settings["steps"], "method.steps", 1)
        settings["moves"] = _choice(settings["moves"], "method.moves", MOVES)
    if kind == "emcee":
        settings["reevaluate_every"] = _int(settings["reevaluate_every"], "method.reevaluate_every", 0)
    elif kind == "optimize":
        settings["algorithm"] = _choice(settings["algorithm"], "method.algorithm", ALGORITHMS)
        settings["objective"] = _choice(settings["objective"], "method.objective", OBJECTIVES)
        settings["maxiter"] = _int(settings["maxiter"], "method.maxiter", 1)
        settings["popsize"] = _int(settings["popsize"], "method.popsize", 1)
        settings["recheck"] = _int(settings["recheck"], "method.recheck", 0)
    else:
        if settings["results"] is None:
            raise ConfigError("method.results", "missing: the emulator needs results = \"<sweep results folder>\"")
        text = _string(settings["results"], "method.results", "a path to a sweep results folder")
        settings["results"] = _resolve_path(text, base, "method.results", "results folder", must_exist=False)
        settings["surrogate"] = _choice(settings["surrogate"], "method.surrogate", SURROGATES)
        settings["confirm"] = _int(settings["confirm"], "method.confirm", 0)
        if settings["confirm"] == 1:
            raise ConfigError("method.confirm", "got 1; use 0 (no confirmation) or >= 2 replicates")
    return Method(kind=kind, settings=settings)


# ------------------------------------------------------------------------------------------------ public

def calibration_from_dict(data: dict, base: Path) -> CalibrationConfig:
    """Validated calibration from a parsed TOML dict; ``base`` is the folder relative paths start from."""
    _check_keys(data, TOP_KEYS, "")
    name = _string(data.get("name"), "name", "a non-empty string naming the calibration")
    if not name or "/" in name or name.startswith("."):
        raise ConfigError("name", f"got {name!r}; expected a plain folder name")
    description = _string(data.get("description", ""), "description", "a string")
    seed = _int(data.get("seed", 0), "seed", 0)
    base = Path(base)
    preset_path, preset_data, warmup, preset = _parse_model_and_run(data, base)
    parameters, joint = _parse_parameters(data, preset_data, preset)
    targets = _parse_targets(data, base)
    method = _parse_method(data, base, len(parameters), targets.k)
    return CalibrationConfig(name=name, description=description, seed=seed, preset_path=preset_path,
                             preset_data=preset_data, warmup=warmup, parameters=parameters, prior=joint,
                             targets=targets, method=method, source=data)


def load_calibration(path, overrides=()) -> CalibrationConfig:
    """Read a calibration TOML, apply ``key=value`` overrides (of this file's own keys), validate."""
    path = Path(path)
    return calibration_from_dict(read_config(path, "calibration file", overrides), path.resolve().parent)
