"""The ``emulator`` calibration method: a cheap surrogate of the summary statistics, fitted to an existing
sweep's results, sampled with emcee, and confirmed with real simulations at the posterior's centre.

Shapes: d free parameters, k statistics, P distinct parameter points in the sweep, N runs, m observed
datasets, n points evaluated at once.

Contract
--------
``training_set(results_path, config) -> TrainingSet``
    Reads the sweep results folder (``runs.parquet``, ``model.json``), keeps the runs with status
    ``ok`` and finite values of every target column, and groups them by the free-parameter point.
    Checks, each a :class:`~simcore.schema.ConfigError` naming the calibration key:

    * ``method.results``: folder missing, no ``runs.parquet`` / ``model.json``; the sweep's fixed
      settings differ from the calibration's (every resolved preset value that neither design varies
      is compared: model name, dynamics, run duration, dt, record interval, ``init.n``, steering, ...;
      plus the warmup, an automatic group radius, and the fragmentation threshold when a
      fragmentation column is a target); a swept factor that is not a free parameter has no run at the
      calibration's value (only the runs at that value are kept; the values available are listed);
      fewer than ``d + 2`` points with >= 2 replicates, or no replicates at all; points that do not
      vary the free parameters independently (e.g. a zipped axis moving two of them together);
    * ``parameters.<name>.key``: a free parameter the sweep did not vary (the swept keys are listed);
    * ``parameters.<name>.prior``: the prior's support does not overlap the swept range;
    * ``targets.stats``: a target column missing from the runs table (the available ones are listed).

    A free parameter's column is its key (the runs table holds every swept key's resolved value); a
    table without it may still hold the values under the axis' ``name`` (used when numeric).
    Points with a single usable replicate are dropped and recorded in ``TrainingSet.notes``.

``group_replicates(points (N, d), summaries (N, k), names, columns, keys=None) -> TrainingSet``
    The same grouping for arrays (synthetic simulators, tests); raises ValueError.

:class:`TrainingSet`: ``points`` (P, d), ``mean`` (P, k), ``var`` (P, k) (ddof = 1, floored at
1e-12 x the stat's variance over all runs, at least 1e-300, so a point whose replicates agree keeps a
finite log variance), ``count`` (P,), ``correlation`` (k, k) (pooled within-point correlation of the
standardised residuals, shrunk towards the identity only if not positive definite), ``lower`` /
``upper`` (d,) (the training box), ``names``, ``keys``, ``columns``, ``fixed`` (non-free swept key ->
the value kept), ``notes``, ``source``.

Surrogates (``build_surrogate(training, kind)``, kind ``"gp"`` or ``"rbf"``) are fitted on inputs scaled
to [0, 1] by the training box and outputs standardised (mean 0, sd 1 per output). Two outputs per
stat: the point means and the log variances. A log sample variance of n Gaussian replicates is biased
by ``digamma((n-1)/2) - log((n-1)/2)`` (removed) and has variance ``trigamma((n-1)/2)``; a point mean
has variance ``var / n``. These are each point's known noise.

* :class:`GPSurrogate`: per output an exact GP, kernel = ARD squared exponential + a linear trend
  (intercept and slopes with fixed prior variance 1, centred on the box), noise = known noise
  (heteroscedastic) + a fitted white nugget; hyperparameters (signal variance, length
  scales, nugget; log scale, bounded) maximise the log marginal likelihood (L-BFGS-B with its analytic
  gradient, three fixed starting points, best kept). Emulator variance of the mean: the GP's
  predictive variance of the latent function (no noise); it grows away from the data.
* :class:`RBFSurrogate`: per output a :class:`scipy.interpolate.RBFInterpolator` (thin-plate spline,
  linear polynomial) with per-point smoothing ``lam x known noise / mean known noise`` (floored at
  1e-3 of the mean). ``lam`` (fixed log grid 1e-6..1e3) minimises Stein's unbiased risk estimate
  ``|y - H y|^2 + 2 sum_i H_ii noise_i - sum_i noise_i`` of the smoother with hat matrix ``H`` (exact,
  from fitting the identity); with the noise known this was steadier than leave-one-out in trials.
  Emulator variance of the mean: constant per stat, ``max(0, mean(LOO residual^2 - known noise))``
  (exact LOO residuals ``e_i / (1 - H_ii)``: what the held-out error has beyond the noise of the
  held-out point means).

``surrogate.predict(theta)`` with theta (n, d) or (d,) -> :class:`EmulatorPrediction` of (n, k)
arrays: ``mean``, ``mean_var`` (emulator variance of the mean) and ``var`` (per-replicate variance =
``exp`` of the predicted log variance). It predicts anywhere; the box is enforced by the likelihood.

``emulated_loglik(theta (d,), observed (m, k) or (k,), surrogate, obs_cov (k, k) or None) -> float``
    ``sum_i log N(observed_i; mu(theta), D C D + obs_cov + diag(mean_var(theta)))`` with ``D`` the
    diagonal of emulated per-replicate sds and ``C`` the pooled correlation. ``obs_cov`` is the
    targets' covariance (mean with sd or cov; the same observation noise run.py adds to simulated
    summaries) or None (samples targets). ``-inf`` outside the training box (bounds included): the
    emulator must not extrapolate, so the posterior is the prior truncated to the box times this
    likelihood. :func:`prior_outside_box` lists the parameters whose prior reaches beyond the box.
    ``emulated_logliks(thetas (n, d), ...) -> (n,)`` is the same for many points at once.

Cost: fitting is O(P^3) per likelihood evaluation (GP) or per smoothing candidate (RBF). Measured
on the 2-core development machine (while loaded) for P = 324 points, d = 4, k = 3: GP 15 s, RBF 2 s;
predicting 8 points takes milliseconds, so the chain costs seconds.

``run_emulator_mcmc(surrogate, observed, obs_cov, prior, *, walkers, steps, seed, path=None,
resume=False, progress=None, progress_every=None, moves="stretch") -> BSLResult`` (as
:func:`~.bsl.run_bsl`, ``moves`` as there)
    emcee, vectorised (each half-ensemble's proposals evaluated at once). Log posterior =
    ``prior.logpdf + emulated_loglik`` (no randomness). Seeds as in bsl: initial walkers from
    ``prior.sample(Generator(PCG64(SeedSequence([seed, 0]))), walkers)``; walkers outside the box (or
    with a -inf log posterior) are replaced, in walker order, by the next acceptable draws of the same
    generator, drawn ``max(64, 4 x walkers)`` at a time, for at most 1000 rounds (then RuntimeError
    with the share accepted: the prior has too little mass in the box). Moves from
    ``RandomState(MT19937(SeedSequence([seed, 1])))``. With ``path``: HDF5 backend group ``"mcmc"``;
    an existing file needs ``resume=True`` (FileExistsError otherwise) and must carry this run's
    ``emulator_seed`` and ``emulator_fingerprint`` (surrogate, training data, targets, prior;
    ValueError otherwise); resume continues bit for bit. ``progress(step, acceptance, tau)`` after
    every ``progress_every`` rows (default ``max(1, steps // 10)``) and after the last.

``confirm(config, simulator, surrogate, theta, *, count, seed) -> dict``
    ``count`` (>= 2) fresh replicates at theta with ``SummarySimulator.simulate(theta,
    seeds_for(rng, count))``, ``rng = Generator(PCG64(SeedSequence([seed, 3])))``. Returns
    ``theta`` (name -> value), ``comparison`` (DataFrame indexed by stat column: emulated_mean,
    emulated_mean_sd, emulated_sd, real_mean, real_sd, n_real, se, z with ``se = sqrt(real_sd^2 /
    n_real + emulated_mean_sd^2)`` and ``z = (real_mean - emulated_mean) / se``, sd_ratio = real_sd /
    emulated_sd), ``predictive`` (:func:`~.diagnostics.predictive_check` of the observed targets
    against the real summaries, with the targets' observation noise added from the same rng when
    mean/sd targets are given), ``summaries`` (count, k) (raw, non-finite rows kept) and ``seeds``.
    It writes no file.

Helpers: ``posterior_median(chain, burn=0) -> (d,)`` (the centre to confirm at);
``observation_covariance(config) -> (k, k) | None`` (the ``obs_cov`` argument for a config).
"""
from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
import numbers
import os
from pathlib import Path
from typing import Callable

import numpy as np
from scipy import optimize, special

from simcore.schema import ConfigError, get_dotted, set_dotted

from .bsl import BSLResult
from .chainfile import emcee_moves, ensemble_sampler, open_chain, progress_tau

SURROGATE_KINDS = ("gp", "rbf")
FRAGMENTATION_COLUMNS = ("time_to_fragmentation", "fragmented")
IGNORED_PRESET_KEYS = ("description",)
_TAG_INIT, _TAG_MOVES, _TAG_CONFIRM = 0, 1, 3
MAX_INITIAL_ROUNDS = 1000
_LOG_2PI = math.log(2.0 * math.pi)


# ------------------------------------------------------------------------------------- training set

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
    from analysis.results import load_results
    from sweeps.store import ResultsStore

    if not path.is_dir():
        raise ConfigError("method.results", f"results folder not found: {path} (run the sweep first with "
                                            "`flocksweep run SWEEP.toml`)")
    if not (path / "runs.parquet").is_file():
        raise ConfigError("method.results", f"{path} has no runs.parquet: not a finished sweep results folder "
                                            "(run or resume the sweep with `flocksweep run`)")
    model = ResultsStore(path).model()
    if not model.get("preset"):
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
    from simcore.params import preset_from_dict

    return preset_from_dict(copy.deepcopy(preset_data)).full_dict()


def _preset_differences(config, model: dict, neutral_keys) -> list[str]:
    """Resolved preset values that differ between the sweep's base and the calibration's preset, with
    the keys either design varies set to the sweep's base values in both (so derived values agree)."""
    try:
        sweep_full = _resolved(model["preset"])
    except ConfigError as err:
        raise ConfigError("method.results", f"the sweep's stored preset (model.json) is not valid for this "
                                            f"version of the model: {err}") from None
    calibration = copy.deepcopy(config.preset_data)
    for key in neutral_keys:
        set_dotted(calibration, key, get_dotted(sweep_full, key))
    try:
        calibration_full = _resolved(calibration)
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


def _analysis_differences(config, model: dict) -> list[str]:
    from analysis.metrics import FRAGMENTATION_COHESION

    analysis = model.get("analysis", {})
    out = []
    warmup = analysis.get("warmup")
    if warmup is None or not _same(warmup, config.warmup):
        out.append(f"warmup: sweep {warmup!r}, calibration {config.warmup!r}")
    if analysis.get("group_radius") is not None:
        out.append(f"group_radius: sweep {analysis['group_radius']!r}, calibration \"auto\" (the model's "
                   "perception range)")
    if any(c in FRAGMENTATION_COLUMNS for c in config.targets.columns):
        threshold = analysis.get("fragmentation_cohesion", FRAGMENTATION_COHESION)
        if not _same(threshold, FRAGMENTATION_COHESION):
            out.append(f"fragmentation_cohesion: sweep {threshold!r}, calibration {FRAGMENTATION_COHESION!r}")
    return out


def _check_fixed_settings(config, model: dict, path: Path) -> None:
    swept = [str(k) for k in model.get("swept_keys", [])]
    differences = _preset_differences(config, model, sorted(set(swept) | set(config.keys)))
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
                names["init.n" if key == "n" else key] = axis["name"]
    swept = [str(k) for k in model.get("swept_keys", [])]
    return ", ".join(f"{k} (axis {names[k]!r})" if k in names else k for k in swept) or "nothing"


def _factor_column(key: str, runs, model: dict, sweep: dict) -> str | None:
    """The runs-table column holding a free parameter's values: its key, else a numeric axis name."""
    if key not in [str(k) for k in model.get("swept_keys", [])]:
        return None
    if key in runs.columns:
        return key
    for axis in sweep.get("axes", []):
        keys = ["init.n" if k == "n" else k for k in ([axis["key"]] if "key" in axis else [])]
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
    """Keep the runs whose non-free swept keys equal the calibration preset's values."""
    calibration_full = _resolved(config.preset_data)
    fixed = {}
    for key in [str(k) for k in model.get("swept_keys", [])]:
        if key in config.keys or key not in runs.columns:
            continue
        target = get_dotted(calibration_full, key)
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


def training_set(results_path, config) -> TrainingSet:
    """Per-point training statistics from a sweep results folder; see the module docstring."""
    path = Path(results_path if results_path is not None else config.method.settings["results"])
    results, model = _load_sweep(path)
    runs = results.ok
    columns = _free_columns(config, runs, model, results.sweep)
    _check_fixed_settings(config, model, path)
    _check_stat_columns(config, runs, results.metrics)
    runs, fixed = _filter_fixed_factors(config, runs, model)
    points = runs[columns].to_numpy(dtype=float)
    summaries = runs[list(config.targets.columns)].to_numpy(dtype=float)
    try:
        training = group_replicates(points, summaries, config.names, config.targets.columns, config.keys,
                                    fixed=fixed, source=path)
    except ValueError as err:
        raise ConfigError("method.results", f"{path}: {err}") from None
    _check_prior_overlap(config, training)
    return training


# ------------------------------------------------------------------------------------------ surrogates

@dataclasses.dataclass(frozen=True)
class EmulatorPrediction:
    """Arrays (n, k): emulated mean, emulator variance of that mean, per-replicate variance."""

    mean: np.ndarray
    mean_var: np.ndarray
    var: np.ndarray


def _rows(values, width: int, what: str) -> np.ndarray:
    """``values`` as a (n, width) float array (a (width,) vector is one row); ValueError otherwise."""
    values = np.asarray(values, dtype=float)
    values = values[None, :] if values.ndim == 1 else values
    if values.ndim != 2 or values.shape[1] != width:
        raise ValueError(f"{what} must have shape (n, {width}) or ({width},), got {np.shape(values)}")
    return values


def _as_points(theta, d: int) -> np.ndarray:
    return _rows(theta, d, "theta")


def _log_variance_targets(var: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bias-corrected log sample variances (P, k) and their sampling variances (P, k) (Gaussian theory)."""
    half_dof = (count[:, None] - 1) / 2.0
    bias = special.digamma(half_dof) - np.log(half_dof)
    noise = special.polygamma(1, half_dof)
    return np.log(var) - bias, np.broadcast_to(noise, var.shape).copy()


@dataclasses.dataclass(frozen=True)
class _Standardised:
    """One output standardised: y = (value - centre) / scale; noise in standardised units."""

    values: np.ndarray
    noise: np.ndarray
    centre: float
    scale: float

    @classmethod
    def of(cls, values, noise) -> "_Standardised":
        centre = float(np.mean(values))
        scale = float(np.std(values))
        scale = scale if scale > 0 else 1.0
        return cls((values - centre) / scale, np.asarray(noise) / scale ** 2, centre, scale)


class Surrogate:
    """Common part: the training set, its box, the unit scaling and prediction. Subclasses fit
    ``mean_models`` and ``log_var_models`` (one per stat), or override ``_predict_unit(unit (n, d)) ->
    (mean, mean_var, log_var)`` (each (n, k), original units), e.g. a test stub with known functions."""

    kind = "base"

    def __init__(self, training: TrainingSet):
        self.training = training
        self.lower = np.array(training.lower, dtype=float)
        self.upper = np.array(training.upper, dtype=float)
        self.correlation = np.array(training.correlation, dtype=float)
        self.names = training.names
        self.columns = training.columns

    @property
    def d(self) -> int:
        return len(self.lower)

    @property
    def k(self) -> int:
        return len(self.columns)

    def to_unit(self, theta) -> np.ndarray:
        return (_as_points(theta, self.d) - self.lower) / (self.upper - self.lower)

    def inside(self, theta) -> np.ndarray:
        """(n,) whether each point lies in the training box (bounds included)."""
        theta = _as_points(theta, self.d)
        return np.all((theta >= self.lower) & (theta <= self.upper), axis=1)

    def fit(self, output_model) -> None:
        """One ``output_model(unit points, standardised output)`` per stat for the means and for the
        log variances."""
        unit = self.to_unit(self.training.points)
        means, logs = self.outputs()
        self.mean_models = [output_model(unit, out) for out in means]
        self.log_var_models = [output_model(unit, out) for out in logs]

    def outputs(self) -> tuple[list[_Standardised], list[_Standardised]]:
        """Standardised training outputs: per stat the point means, then the log variances."""
        t = self.training
        log_var, log_noise = _log_variance_targets(t.var, t.count)
        means = [_Standardised.of(t.mean[:, j], t.var[:, j] / t.count) for j in range(t.k)]
        logs = [_Standardised.of(log_var[:, j], log_noise[:, j]) for j in range(t.k)]
        return means, logs

    def predict(self, theta) -> EmulatorPrediction:
        """Emulated mean, its emulator variance and the per-replicate variance, each (n, k)."""
        mean, mean_var, log_var = self._predict_unit(self.to_unit(theta))
        return EmulatorPrediction(mean=mean, mean_var=mean_var, var=np.exp(log_var))

    def _predict_unit(self, unit):
        """From the fitted per-stat models (``mean_models``, ``log_var_models``: ``predict(unit) ->
        (mean, var)`` in standardised units, ``output`` their scaling), back in original units."""
        mean, mean_var, log_var = (np.empty((len(unit), self.k)) for _ in range(3))
        for j, model in enumerate(self.mean_models):
            m, v = model.predict(unit)
            out = model.output
            mean[:, j], mean_var[:, j] = out.centre + out.scale * m, out.scale ** 2 * v
        for j, model in enumerate(self.log_var_models):
            m, _ = model.predict(unit)
            log_var[:, j] = model.output.centre + model.output.scale * m
        return mean, mean_var, log_var

    @property
    def fingerprint(self) -> str:
        """Hash of the kind and the training data (what a stored chain must have been run with)."""
        t = self.training
        digest = hashlib.sha256(self.kind.encode())
        for array in (t.points, t.mean, t.var, t.count, t.correlation):
            digest.update(np.ascontiguousarray(array, dtype=float).tobytes())
        digest.update(repr((t.names, t.columns)).encode())
        return digest.hexdigest()[:32]


class _ExactGP:
    """One output: GP on unit inputs with an ARD squared-exponential plus a linear-trend kernel, known
    per-point noise plus a fitted nugget. Hyperparameters h = log [signal variance, length scales (d),
    nugget]. Factorisations use numpy.linalg (on the loaded development machine scipy.linalg's triangular
solves cost milliseconds even for 12 x 12 matrices)."""

    STARTS = ((0.25, 1e-3), (0.6, 1e-2), (1.5, 1e-1))  # (length scale, nugget); signal variance 1
    LOG_BOUNDS_SIGNAL = (math.log(1e-3), math.log(1e2))
    LOG_BOUNDS_LENGTH = (math.log(0.03), math.log(30.0))
    LOG_BOUNDS_NUGGET = (math.log(1e-8), math.log(10.0))
    LINEAR_VARIANCE = 1.0
    JITTER = 1e-10

    def __init__(self, x: np.ndarray, output: _Standardised):
        self.x = x
        self.output = output
        self.sq_diff = (x[:, None, :] - x[None, :, :]) ** 2          # (P, P, d)
        self.linear = self._linear(x, x)
        self.h = self._fit()
        _, total = self._covariances(self.h)
        self.inverse_factor = _inverse_cholesky(total)                 # L^-1, (P, P)
        self.alpha = self.inverse_factor.T @ (self.inverse_factor @ output.values)

    def _linear(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Linear-trend kernel (intercept and slopes with prior variance ``LINEAR_VARIANCE``), centred on
        the box so its prior variance is smallest in the middle."""
        return self.LINEAR_VARIANCE * (1.0 + (a - 0.5) @ (b - 0.5).T)

    def _covariances(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(squared-exponential part, total covariance incl. the linear part and noise), each (P, P)."""
        signal, length = math.exp(h[0]), np.exp(h[1:-1])
        kernel = signal * np.exp(-0.5 * np.sum(self.sq_diff / length ** 2, axis=-1))
        noise = self.output.noise + math.exp(h[-1]) + self.JITTER
        return kernel, kernel + self.linear + np.diag(noise)

    def _objective(self, h: np.ndarray) -> tuple[float, np.ndarray]:
        """Negative log marginal likelihood and its gradient in h."""
        kernel, total = self._covariances(h)
        try:
            inverse_factor = _inverse_cholesky(total)
        except np.linalg.LinAlgError:
            return 1e25, np.zeros_like(h)
        y = self.output.values
        inverse = inverse_factor.T @ inverse_factor
        alpha = inverse @ y
        log_det = -2.0 * np.sum(np.log(np.diag(inverse_factor)))
        value = 0.5 * y @ alpha + 0.5 * log_det + 0.5 * len(y) * _LOG_2PI
        inner = np.outer(alpha, alpha) - inverse          # d value / d total = -inner / 2
        weighted = inner * kernel
        grad = np.empty_like(h)
        grad[0] = -0.5 * np.sum(weighted)
        grad[1:-1] = -0.5 * np.einsum("ij,ijd->d", weighted, self.sq_diff) / np.exp(2.0 * h[1:-1])
        grad[-1] = -0.5 * math.exp(h[-1]) * np.trace(inner)
        return float(value), grad

    def _fit(self) -> np.ndarray:
        d = self.x.shape[1]
        bounds = [self.LOG_BOUNDS_SIGNAL] + [self.LOG_BOUNDS_LENGTH] * d + [self.LOG_BOUNDS_NUGGET]
        best = None
        for length, nugget in self.STARTS:
            start = np.array([0.0] + [math.log(length)] * d + [math.log(nugget)])
            result = optimize.minimize(self._objective, start, jac=True, method="L-BFGS-B", bounds=bounds)
            if best is None or result.fun < best.fun:
                best = result
        return np.asarray(best.x, dtype=float)

    def predict(self, unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Latent mean and variance (n,) at unit points (n, d), in standardised units."""
        signal, length = math.exp(self.h[0]), np.exp(self.h[1:-1])
        sq = (unit[:, None, :] - self.x[None, :, :]) ** 2
        cross = signal * np.exp(-0.5 * np.sum(sq / length ** 2, axis=-1)) + self._linear(unit, self.x)  # (n, P)
        mean = cross @ self.alpha
        v = self.inverse_factor @ cross.T
        prior = signal + self.LINEAR_VARIANCE * (1.0 + np.sum((unit - 0.5) ** 2, axis=1))
        var = np.maximum(prior - np.sum(v * v, axis=0), 1e-12 * prior)
        return mean, var


def _inverse_cholesky(matrix: np.ndarray) -> np.ndarray:
    """L^-1 for the lower Cholesky factor L of a positive definite matrix (LinAlgError otherwise)."""
    factor = np.linalg.cholesky(matrix)
    return np.linalg.solve(factor, np.eye(len(matrix)))


class GPSurrogate(Surrogate):
    """Exact GPs (see the module docstring): one per stat for the mean, one per stat for log variance."""

    kind = "gp"

    def __init__(self, training: TrainingSet):
        super().__init__(training)
        self.fit(_ExactGP)


class _SmoothedRBF:
    """One output: thin-plate spline RBF with per-point smoothing ``lam x relative known noise``; ``lam``
    minimises the unbiased risk estimate (Mallows' Cp / SURE) over a fixed log grid."""

    LAMBDAS = 10.0 ** np.arange(-6.0, 3.01, 0.75)

    def __init__(self, x: np.ndarray, output: _Standardised):
        self.x = x
        self.output = output
        noise = np.asarray(output.noise, dtype=float)
        typical = float(np.mean(noise)) if np.mean(noise) > 0 else 1.0
        self.weights = np.maximum(noise / typical, 1e-3)
        fits = [self._risk(lam) for lam in self.LAMBDAS]
        best = int(np.argmin([risk for risk, _ in fits]))
        self.smoothing = float(self.LAMBDAS[best])
        self.loo_residuals = fits[best][1]
        self.model = self._interpolator(self.output.values, self.smoothing)
        self.emulator_var = max(0.0, float(np.mean(self.loo_residuals ** 2 - noise)))  # standardised units

    def _interpolator(self, values, lam: float):
        from scipy.interpolate import RBFInterpolator

        return RBFInterpolator(self.x, values, kernel="thin_plate_spline", degree=1,
                               smoothing=lam * self.weights)

    def _risk(self, lam: float) -> tuple[float, np.ndarray]:
        """(SURE = |y - H y|^2 + 2 sum H_ii noise_i - sum noise_i, leave-one-out residuals
        e_i / (1 - H_ii)) of the linear smoother with hat matrix H (fitted values = H y)."""
        size = len(self.x)
        hat = self._interpolator(np.eye(size), lam)(self.x)
        y, noise = self.output.values, self.output.noise
        residuals = y - hat @ y
        leverage = np.diag(hat)
        risk = float(np.sum(residuals ** 2) + 2.0 * np.sum(leverage * noise) - np.sum(noise))
        return risk, residuals / (1.0 - np.minimum(leverage, 1.0 - 1e-8))

    def predict(self, unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.model(unit), np.full(len(unit), self.emulator_var)


class RBFSurrogate(Surrogate):
    """Thin-plate spline RBF regression (see the module docstring) for means and log variances."""

    kind = "rbf"

    def __init__(self, training: TrainingSet):
        super().__init__(training)
        self.fit(_SmoothedRBF)


def build_surrogate(training: TrainingSet, kind: str = "gp") -> Surrogate:
    """Fit the surrogate ``kind`` ("gp" or "rbf") to ``training``."""
    if kind == "gp":
        return GPSurrogate(training)
    if kind == "rbf":
        return RBFSurrogate(training)
    raise ValueError(f"kind: unknown surrogate {kind!r}; allowed: {', '.join(SURROGATE_KINDS)}")


def prior_outside_box(prior, surrogate: Surrogate) -> list[str]:
    """Plain warnings for the parameters whose prior support reaches beyond the training box (the
    posterior is truncated there)."""
    out = []
    for name, (low, high), box_low, box_high in zip(prior.names, prior.bounds, surrogate.lower, surrogate.upper):
        if low < box_low or high > box_high:
            out.append(f"{name}: prior support [{low:g}, {high:g}] reaches beyond the swept range "
                       f"[{box_low:g}, {box_high:g}]; the posterior is truncated to the swept range")
    return out


# ------------------------------------------------------------------------------------------ likelihood

def _observed_rows(observed, k: int) -> np.ndarray:
    return _rows(observed, k, "observed")


def _obs_cov_matrix(obs_cov, k: int) -> np.ndarray:
    if obs_cov is None:
        return np.zeros((k, k))
    obs_cov = np.asarray(obs_cov, dtype=float)
    if obs_cov.shape != (k, k):
        raise ValueError(f"obs_cov must be ({k}, {k}) or None, got {obs_cov.shape}")
    return obs_cov


def _gaussian_logpdf_rows(observed: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(n,) sum over the m observed rows (m, k) of log N(row; mean_i (k,), cov_i (k, k)); -inf where
    cov_i is not positive definite."""
    n, k = mean.shape
    m = observed.shape[0]
    try:
        factors = np.linalg.cholesky(cov)                                   # (n, k, k)
    except np.linalg.LinAlgError:
        return np.array([_gaussian_logpdf_rows(observed, mean[i:i + 1], cov[i:i + 1])[0] if _is_pd(cov[i])
                         else -np.inf for i in range(n)])
    residuals = observed[None, :, :] - mean[:, None, :]                     # (n, m, k)
    z = np.linalg.solve(factors, np.swapaxes(residuals, 1, 2))              # (n, k, m)
    log_det = 2.0 * np.sum(np.log(np.diagonal(factors, axis1=1, axis2=2)), axis=1)
    return -0.5 * np.sum(z * z, axis=(1, 2)) - 0.5 * m * log_det - 0.5 * m * k * _LOG_2PI


def _is_pd(matrix: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        return False
    return True


def emulated_logliks(thetas, observed, surrogate: Surrogate, obs_cov=None) -> np.ndarray:
    """(n,) :func:`emulated_loglik` at each row of ``thetas`` (n, d)."""
    thetas = _as_points(thetas, surrogate.d)
    observed = _observed_rows(observed, surrogate.k)
    extra = _obs_cov_matrix(obs_cov, surrogate.k)
    out = np.full(len(thetas), -np.inf)
    inside = surrogate.inside(thetas) & np.isfinite(thetas).all(axis=1)
    if not inside.any():
        return out
    prediction = surrogate.predict(thetas[inside])
    sd = np.sqrt(prediction.var)
    cov = sd[:, :, None] * surrogate.correlation[None] * sd[:, None, :] + extra[None]
    cov = cov + np.einsum("nk,kl->nkl", prediction.mean_var, np.eye(surrogate.k))
    values = _gaussian_logpdf_rows(observed, prediction.mean, cov)
    out[inside] = np.where(np.isfinite(values), values, -np.inf)
    return out


def emulated_loglik(theta, observed, surrogate: Surrogate, obs_cov=None) -> float:
    """Gaussian log likelihood of ``observed`` under the emulator at ``theta`` (d,); -inf outside the
    training box (see the module docstring)."""
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (surrogate.d,):
        raise ValueError(f"theta must have shape ({surrogate.d},), got {theta.shape}")
    return float(emulated_logliks(theta[None, :], observed, surrogate, obs_cov)[0])


# ----------------------------------------------------------------------------------------------- MCMC

class _EmulatedPosterior:
    """Vectorised log posterior: prior log density + emulated log likelihood, -inf where either is."""

    def __init__(self, surrogate, observed, obs_cov, prior):
        self.surrogate, self.observed, self.obs_cov, self.prior = surrogate, observed, obs_cov, prior

    def __call__(self, thetas) -> np.ndarray:
        thetas = np.asarray(thetas, dtype=float)
        log_prior = np.atleast_1d(np.asarray(self.prior.logpdf(thetas), dtype=float))
        out = np.full(len(thetas), -np.inf)
        finite = np.isfinite(log_prior)
        if finite.any():
            out[finite] = log_prior[finite] + emulated_logliks(thetas[finite], self.observed, self.surrogate,
                                                               self.obs_cov)
        return np.where(np.isnan(out), -np.inf, out)


def _count(value, name: str, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name}: got {value!r}; must be an integer >= {minimum}")
    return int(value)


def _initial_walkers(logpost: _EmulatedPosterior, prior, walkers: int, seed: int):
    """Seeded draws from the prior inside the box: (coords (walkers, d), log_prob (walkers,))."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, _TAG_INIT])))
    d = int(prior.dim)
    coords = np.asarray(prior.sample(rng, walkers), dtype=float).reshape(walkers, d)
    log_prob = logpost(coords)
    drawn, accepted = walkers, int(np.isfinite(log_prob).sum())
    batch = max(64, 4 * walkers)
    for _ in range(MAX_INITIAL_ROUNDS):
        bad = np.flatnonzero(~np.isfinite(log_prob))
        if bad.size == 0:
            return coords, log_prob
        fresh = np.asarray(prior.sample(rng, batch), dtype=float).reshape(batch, d)
        fresh_lp = logpost(fresh)
        good = np.flatnonzero(np.isfinite(fresh_lp))[:bad.size]
        drawn, accepted = drawn + batch, accepted + int(np.isfinite(fresh_lp).sum())
        coords[bad[:good.size]] = fresh[good]
        log_prob[bad[:good.size]] = fresh_lp[good]
    raise RuntimeError(f"could not place {int((~np.isfinite(log_prob)).sum())} initial walkers inside the "
                       f"training box: only {accepted} of {drawn} prior draws had a finite emulated log "
                       "posterior; narrow the prior to the swept range")


def _fingerprint(surrogate: Surrogate, observed, obs_cov, prior) -> str:
    digest = hashlib.sha256(surrogate.fingerprint.encode())
    digest.update(np.ascontiguousarray(observed, dtype=float).tobytes())
    digest.update(_obs_cov_matrix(obs_cov, surrogate.k).tobytes())
    digest.update(repr(prior).encode())
    return digest.hexdigest()[:32]


def run_emulator_mcmc(surrogate: Surrogate, observed, obs_cov, prior, *, walkers: int, steps: int, seed: int,
                      path=None, resume: bool = False, progress: Callable | None = None,
                      progress_every: int | None = None, moves: str = "stretch") -> BSLResult:
    """emcee on the emulated posterior; see the module docstring for the full contract."""
    emcee_moves(moves)   # validates
    import emcee

    steps, seed = _count(steps, "steps", 1), _count(seed, "seed", 0)
    d = int(prior.dim)
    if d != surrogate.d:
        raise ValueError(f"the prior has {d} parameters, the surrogate {surrogate.d}")
    walkers = _count(walkers, "walkers", max(2, 2 * d))
    every = max(1, steps // 10) if progress_every is None else _count(progress_every, "progress_every", 1)
    if resume and path is None:
        raise ValueError("resume=True needs a path")
    observed = _observed_rows(observed, surrogate.k)
    logpost = _EmulatedPosterior(surrogate, observed, obs_cov, prior)
    meta = {"emulator_seed": seed, "emulator_fingerprint": _fingerprint(surrogate, observed, obs_cov, prior),
            "emulator_moves": moves}
    backend = None
    if path is not None:
        backend = open_chain(path, resume, meta, defaults={"emulator_moves": "stretch"},
                             needs="the same seed, surrogate, training data, targets, prior and moves")
    sampler = ensemble_sampler(logpost, walkers, d, backend, meta, moves)
    start = int(sampler.backend.iteration)
    if start == 0:
        coords, log_prob = _initial_walkers(logpost, prior, walkers, seed)
        move_rs = np.random.RandomState(np.random.MT19937(np.random.SeedSequence([seed, _TAG_MOVES])))
        state = emcee.State(coords, log_prob=log_prob, random_state=move_rs.get_state())
    else:
        state = sampler.backend.get_last_sample()
    if start < steps:
        generator = sampler.sample(state, iterations=steps - start, skip_initial_state_check=start > 0)
        for t, _ in enumerate(generator, start=start + 1):
            if progress is not None and (t % every == 0 or t == steps):
                acceptance = float(np.mean(sampler.backend.accepted / float(t)))
                progress(t, acceptance, progress_tau(sampler.backend.get_chain()[t // 2:]))
    stored = sampler.backend
    n = int(stored.iteration)
    names = getattr(prior, "names", None)
    return BSLResult(chain=np.asarray(stored.get_chain()), log_prob=np.asarray(stored.get_log_prob()),
                     acceptance_fraction=np.asarray(stored.accepted, dtype=float) / float(n),
                     names=tuple(names) if names is not None else None,
                     path=os.fspath(path) if path is not None else None, seed=seed)


def posterior_median(chain: np.ndarray, burn: int = 0) -> np.ndarray:
    """(d,) median over walkers and the rows after ``burn`` of a chain (steps, walkers, d)."""
    chain = np.asarray(chain, dtype=float)
    return np.median(chain[burn:].reshape(-1, chain.shape[-1]), axis=0)


# ---------------------------------------------------------------------------------------- confirmation

def observation_covariance(config) -> np.ndarray | None:
    """The targets' (k, k) covariance for mean/sd (or cov) targets, None for samples targets."""
    return None if config.targets.samples_path is not None else np.asarray(config.targets.cov, dtype=float)


def _simulator_with(simulator, count: int):
    """The same simulator running ``count`` replicates per call."""
    from .simulator import SummarySimulator

    if simulator.n_sim == count:
        return simulator
    return SummarySimulator(simulator.base, simulator.keys, simulator.columns, count, simulator.warmup,
                            simulator.group_radius)


def _comparison_table(columns, prediction: EmulatorPrediction, finite: np.ndarray):
    import pandas as pd

    n_real = len(finite)
    real_mean = finite.mean(axis=0) if n_real else np.full(len(columns), np.nan)
    real_sd = finite.std(axis=0, ddof=1) if n_real > 1 else np.full(len(columns), np.nan)
    emulated_mean, emulated_mean_sd = prediction.mean[0], np.sqrt(prediction.mean_var[0])
    emulated_sd = np.sqrt(prediction.var[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        se = np.sqrt(real_sd ** 2 / max(n_real, 1) + emulated_mean_sd ** 2)
        z = (real_mean - emulated_mean) / se
        ratio = real_sd / emulated_sd
    return pd.DataFrame({"emulated_mean": emulated_mean, "emulated_mean_sd": emulated_mean_sd,
                         "emulated_sd": emulated_sd, "real_mean": real_mean, "real_sd": real_sd,
                         "n_real": n_real, "se": se, "z": z, "sd_ratio": ratio},
                        index=pd.Index(list(columns), name="statistic"))


def confirm(config, simulator, surrogate: Surrogate, theta, *, count: int, seed: int) -> dict:
    """Real simulations at ``theta`` against the emulator and the targets; see the module docstring."""
    from .diagnostics import predictive_check
    from .simulator import seeds_for

    count, seed = _count(count, "count", 2), _count(seed, "seed", 0)
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (surrogate.d,):
        raise ValueError(f"theta must have shape ({surrogate.d},), got {theta.shape}")
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, _TAG_CONFIRM])))
    seeds = seeds_for(rng, count)
    summaries = _simulator_with(simulator, count).simulate(theta, seeds)
    finite = summaries[np.isfinite(summaries).all(axis=1)]
    comparison = _comparison_table(config.targets.columns, surrogate.predict(theta), finite)
    cov = observation_covariance(config)
    noisy = finite if cov is None else finite + rng.multivariate_normal(np.zeros(len(cov)), cov, size=len(finite))
    predictive = predictive_check(config.targets.observed, noisy, config.targets.columns)
    return {"theta": dict(zip(config.names, map(float, theta))), "comparison": comparison,
            "predictive": predictive, "summaries": summaries, "seeds": seeds}
