"""The raw inputs of npe's learned summary: what a run (or a measured flock) gives the embedding that is
trained jointly with the flow (:mod:`analysis.calibration.learned_summary`), declared in the calibration
file's ``[method.npe.summary]`` table, and computed by one function for simulations and tracks alike.

Shapes: M individuals at most (``max_individuals``), F per-individual features, L bins of S series, k
hand-picked statistics (the targets' columns).

Contract
--------
:class:`SummarySettings` (``[method.npe.summary]``): ``kind`` "statistics" (the default: the flow is
conditioned on the targets' statistics alone, exactly as before the table existed) or "learned";
``features`` (of :data:`observables.individuals.INDIVIDUAL_FEATURES`), ``series`` (per-record series a
tracker measures: :data:`SERIES_ALLOWED`), ``series_length`` L (bins of the window), ``max_individuals`` M
(None: the preset's ``init.n``), ``width`` (hidden units of the embedding's networks), ``size`` (numbers the
embedding gives the flow), ``observed_seed`` (targets not measured from tracks: the observed raw inputs are
those of one run at ``[targets] truth`` with the seed ``flocksweep targets --truth ... --seed observed_seed``
gives it, a recovery study's device). Each bad value is a
ConfigError naming the key, the value and what is allowed.

:class:`Layout` (``layout(settings, max_individuals)``): how the raw inputs pack into one flat row of
``length = M (F + 1) + L S`` numbers, after the k statistics: an (M, F + 1) block, row i individual i's
features and a last column 1 (present) or 0 (a padding row: features 0), then the (L, S) series. An
individual counts when it has every feature (it was seen moving at two consecutive records with a neighbour
present); the counted ones fill the first rows in index order (ids never or barely seen in the window, e.g. a
tracker's short tracklets, take no slot), the rest is padding. ``layout.split(rows (m, k + length))`` gives the statistics, the
(m, M, F + 1) individuals and the (m, L, S) series; ``layout.split(rows (m, k + f length), k, flocks=f)`` with
f > 1 flocks per row the (m, f, M, F + 1) individuals and the (m, f, L, S) series.

``raw_row(obs, settings (resolved MetricSettings), layout, series=None) -> (length,)``: the raw inputs of one
run or flock (``obs``: a simulator's observations or an :class:`~observables.observed.ObservedFlock`), from
:func:`observables.individuals.individual_features` and :func:`observables.individuals.window_series` of its
:func:`observables.summary.measure_run` series (``series``: already measured). The window is the
``settings.warmup`` one of the statistics. A flock with more than M counted individuals raises ValueError (as
does a window shorter than L records); a flock whose individuals all lack a feature gives a row of NaN.

:class:`LearnedSimulator`: the calibration's :class:`~analysis.calibration.simulator.SummarySimulator` whose
``simulate`` gives each of its ``n_sim`` = f runs' k statistics followed by :func:`raw_row` of the same run
(``run_width = k + length``); ``pool(runs (f, run_width)) -> (row_width,)`` makes one training simulation's
row of them: the f runs' mean statistics (as the statistics path's mean of f runs), then each run's raw inputs
in seed order (``row_width = k + f length``; with f = 1 the one run's row, bit for bit). Its identity adds the
layout. ``learned_simulator(config)`` builds it with f = :func:`flocks` runs per training simulation.

``flocks(config) -> f``: the observed flocks a learned summary is conditioned on at once: the ``from_tracks``
flocks (each a sample: ``aggregate = "samples"``), or the rows of ``samples`` / mean targets.

``check_learned(config)``: the calibration may use a learned summary: a built-in or plug-in model (not an
external command), ``rounds = 1``, and not ``aggregate = "mean"`` over several tracked flocks (one mean row
with the flocks' individuals would mix two designs); ConfigError naming the key otherwise.

``observed_raw(config) -> (f length,)``: the observed flocks' raw inputs, flock after flock: the ``from_tracks``
flocks measured with the tracks' metric settings, or f runs at ``[targets] truth`` with the run seeds of
``common_seeds(observed_seed, f)`` (the runs ``flocksweep targets --seed observed_seed --replicates f`` simulates
the targets with, one row each from :func:`analysis.calibration.synthetic.synthetic_observation`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

import numpy as np

from flocksweep.observables.columns import PERCEPTION_SERIES, SERIES
from flocksweep.observables.individuals import INDIVIDUAL_FEATURES, individual_features, window_series
from flocksweep.observables.summary import measure_run, record_interval
from flocksweep.simcore.schema import ConfigError, suggest
from flocksweep.sweeps.seeds import common_seeds

from .simulator import SummarySimulator

SERIES_ALLOWED = tuple(s for s in SERIES if s not in PERCEPTION_SERIES and s != "overtake_rate") + ("tracked",)
DEFAULT_SERIES = ("polarization", "milling", "speed_mean", "nn_distance")
KEY = "method.npe.summary"


def _choices(key: str, values, allowed) -> None:
    if not values:
        raise ConfigError(key, f"got an empty list; expected one or more of {', '.join(allowed)}")
    for value in values:
        if value not in allowed:
            raise ConfigError(key, f"got {value!r}; expected one or more of {', '.join(allowed)}"
                              + suggest(str(value), allowed))
    if len(set(values)) != len(values):
        raise ConfigError(key, f"got {list(values)}: a name twice")


@dataclass(frozen=True, kw_only=True)
class SummarySettings:
    """``[method.npe.summary]`` (module docstring)."""

    kind: Literal["statistics", "learned"] = "statistics"
    features: tuple[str, ...] = INDIVIDUAL_FEATURES
    series: tuple[str, ...] = DEFAULT_SERIES
    series_length: int = 10
    max_individuals: int | None = None
    width: int = 32
    size: int = 8
    observed_seed: int | None = None

    def __post_init__(self):
        _choices("features", self.features, INDIVIDUAL_FEATURES)
        _choices("series", self.series, SERIES_ALLOWED)
        for name, low, high in (("series_length", 1, 200), ("width", 1, 1024), ("size", 1, 256),
                                ("max_individuals", 2, 100_000)):
            value = getattr(self, name)
            if value is not None and not low <= value <= high:
                raise ConfigError(name, f"got {value!r}; expected an integer from {low} to {high}")
        if self.observed_seed is not None and self.observed_seed < 0:
            raise ConfigError("observed_seed", f"got {self.observed_seed!r}; expected an integer >= 0")

    @property
    def learned(self) -> bool:
        return self.kind == "learned"


@dataclass(frozen=True)
class Layout:
    """How the raw inputs pack into a row (module docstring)."""

    features: tuple
    series: tuple
    series_length: int
    max_individuals: int

    @property
    def block(self) -> int:
        return self.max_individuals * (len(self.features) + 1)

    @property
    def length(self) -> int:
        return self.block + self.series_length * len(self.series)

    def record(self) -> dict:
        return {"features": list(self.features), "series": list(self.series), "series_length": self.series_length,
                "max_individuals": self.max_individuals}

    def split(self, rows: np.ndarray, k: int, flocks: int = 1):
        """(statistics (m, k), individuals (m, M, F + 1), series (m, L, S)) of rows (m, k + length); with
        ``flocks`` = f > 1, rows (m, k + f length) give individuals (m, f, M, F + 1) and series (m, f, L, S)."""
        rows = np.atleast_2d(rows)
        if rows.shape[-1] != k + flocks * self.length:
            raise ValueError(f"rows need {k} statistics and {flocks} x {self.length} raw inputs, got shape "
                             f"{rows.shape}")
        if flocks == 1:
            individuals = rows[:, k:k + self.block].reshape(len(rows), self.max_individuals, len(self.features) + 1)
            series = rows[:, k + self.block:].reshape(len(rows), self.series_length, len(self.series))
            return rows[:, :k], individuals, series
        raw = rows[:, k:].reshape(len(rows), flocks, self.length)
        individuals = raw[:, :, :self.block].reshape(len(rows), flocks, self.max_individuals, len(self.features) + 1)
        series = raw[:, :, self.block:].reshape(len(rows), flocks, self.series_length, len(self.series))
        return rows[:, :k], individuals, series


def layout_from_record(record: dict) -> Layout:
    return Layout(tuple(record["features"]), tuple(record["series"]), int(record["series_length"]),
                  int(record["max_individuals"]))


def layout(settings: SummarySettings, max_individuals: int) -> Layout:
    return Layout(tuple(settings.features), tuple(settings.series), int(settings.series_length), int(max_individuals))


def _interval(obs) -> float:
    interval = getattr(obs, "interval", None)
    return float(interval) if interval is not None else float(record_interval(obs))


def raw_row(obs, settings, plan: Layout, series: dict | None = None) -> np.ndarray:
    """(length,) the raw inputs of one run or flock (module docstring)."""
    if series is None:
        series = measure_run(obs, settings).series
    features = individual_features(obs, settings.warmup, _interval(obs), settings.box)
    picked = features[:, [INDIVIDUAL_FEATURES.index(f) for f in plan.features]]
    counted = picked[np.isfinite(picked).all(axis=1)]          # in index order; the others are not packed
    if len(counted) > plan.max_individuals:
        raise ValueError(f"{len(counted)} individuals have every feature, more than max_individuals = "
                         f"{plan.max_individuals} of the learned summary (method.npe.summary.max_individuals)")
    block = np.zeros((plan.max_individuals, len(plan.features) + 1))
    block[:len(counted), :-1] = counted
    block[:len(counted), -1] = 1.0
    binned = window_series(series, plan.series, obs.times, settings.warmup, plan.series_length)
    if not len(counted):
        return np.full(plan.length, np.nan)
    return np.concatenate([block.ravel(), binned.ravel()])


class LearnedSimulator(SummarySimulator):
    """The statistics of each run followed by its raw inputs (module docstring)."""

    def __init__(self, *args, plan: Layout, **kwargs):
        super().__init__(*args, **kwargs)
        self.plan = plan

    @property
    def run_width(self) -> int:
        """Numbers of one run's row: its statistics and raw inputs."""
        return len(self.columns) + self.plan.length

    @property
    def row_width(self) -> int:
        """Numbers of one training simulation's row (:meth:`pool`)."""
        return len(self.columns) + self.n_sim * self.plan.length

    def with_replicates(self, n_sim: int):
        if n_sim != self.n_sim:
            raise ValueError(f"a learned summary takes {self.n_sim} run(s) per training simulation (the observed "
                             "flocks)")
        return self

    def pool(self, runs: np.ndarray) -> np.ndarray:
        """(row_width,) one training simulation's row of its runs (module docstring)."""
        runs = np.asarray(runs, dtype=float).reshape(self.n_sim, self.run_width)
        if self.n_sim == 1:
            return runs[0]
        k = len(self.columns)
        return np.concatenate([runs[:, :k].mean(axis=0), runs[:, k:].ravel()])

    def identity(self) -> dict:
        return {**super().identity(), "learned_inputs": self.plan.record()}

    def _row(self, obs, settings, seed) -> np.ndarray:
        nan_row = np.full(self.run_width, np.nan)
        obs = self._observed(obs, seed)
        if obs is None:
            return nan_row
        measured = measure_run(obs, settings)
        stats = np.array([measured.row[c] for c in self.columns], dtype=np.float64)
        try:
            raw = raw_row(obs, settings, self.plan, measured.series)
        except ValueError:
            return nan_row
        row = np.concatenate([stats, raw])
        return row if np.isfinite(row).all() else nan_row


def max_individuals(config) -> int:
    summary = config.method.summary
    if summary.max_individuals is not None:
        return int(summary.max_individuals)
    if "init.n" in config.keys:
        raise ConfigError(f"{KEY}.max_individuals", "not given while init.n is a free parameter: give the largest "
                                                    "flock the embedding must take (e.g. the prior's upper bound)")
    return int(config.preset.init.n)


def flocks(config) -> int:
    """The observed flocks a learned summary is conditioned on at once (module docstring)."""
    return int(len(config.targets.observed))


def check_learned(config) -> None:
    """The calibration may use a learned summary (module docstring)."""
    if getattr(config, "command", None) is not None:
        raise ConfigError(f"{KEY}.kind", 'got "learned" with an external command model; a learned summary needs the '
                                         "runs' trajectories in this process: a built-in or plug-in model")
    tracked = len(config.targets.flock_tracks)
    if tracked and tracked != flocks(config):
        raise ConfigError("targets.aggregate", f'got "mean" over {tracked} tracked flocks with a learned summary, '
                                               "which embeds each flock's individuals and series: use aggregate = "
                                               '"samples" (the default: the posterior given all the flocks), or '
                                               'kind = "statistics"')
    if config.method.rounds != 1:
        raise ConfigError(f"{KEY}.kind", f'got "learned" with rounds = {config.method.rounds}; learned summaries '
                                         "are trained in one round: rounds = 1")
    if not config.targets.flock_tracks:
        if config.targets.truth is None:
            raise ConfigError(f"{KEY}.kind", 'got "learned" with targets that are not measured from tracks and no '
                                             "[targets] truth: the observed individuals and series come from "
                                             "from_tracks, or (a recovery study) from one run at the truth")
        if config.method.summary.observed_seed is None:
            raise ConfigError(f"{KEY}.observed_seed", "missing: targets not measured from tracks take their observed "
                                                      "raw inputs from one run at [targets] truth with this seed "
                                                      "(e.g. the seed the targets were simulated with)")
    max_individuals(config)


def learned_simulator(config) -> LearnedSimulator:
    from flocksweep.observables.summary import motion_settings

    m = config.metrics
    plan = layout(config.method.summary, max_individuals(config))
    return LearnedSimulator(config.preset_data, config.keys, tuple(config.targets.columns), flocks(config), m.warmup,
                            m.group_radius, m.fragmentation_cohesion, config.observation, m.dcd_max_delay,
                            motion_settings(m), plan=plan)


def _track_settings(config):
    from flocksweep.observables.measured import track_settings
    from flocksweep.observables.summary import motion_settings

    m = config.metrics
    return dataclasses.replace(track_settings(m.group_radius, float(config.targets.tracks_warmup),
                                              m.fragmentation_cohesion, m.dcd_max_delay), **motion_settings(m))


def observed_raw(config) -> np.ndarray:
    """(f length,) the observed flocks' raw inputs, flock after flock (module docstring)."""
    check_learned(config)
    simulator = learned_simulator(config)
    if config.targets.flock_tracks:
        rows = []
        for flock in config.targets.flock_tracks:
            try:
                rows.append(raw_row(flock, _track_settings(config), simulator.plan))
            except ValueError as err:
                raise ConfigError(f"{KEY}", f"the raw inputs of the tracks' flock {flock.name!r} cannot be measured: "
                                            f"{err}") from None
        row = np.concatenate(rows)
    else:
        truth = np.array([config.targets.truth[name] for name in config.names], dtype=float)
        seeds = common_seeds(int(config.method.summary.observed_seed), simulator.n_sim)  # as `flocksweep targets --seed`
        row = simulator.simulate(truth, seeds)[:, len(config.targets.columns):].ravel()
    if not np.isfinite(row).all():
        raise ConfigError(f"{KEY}", "the observed flocks' raw inputs are not finite (a flock with no individual with "
                                    "every feature, or a series with an empty bin): choose other features or series")
    return row


def measured_raw(flocks, identity: dict) -> np.ndarray:
    """(m, length) raw inputs of measured flocks (``flocksweep posterior --tracks``), with the metric settings
    the estimator's identity records."""
    from flocksweep.observables.measured import track_settings

    plan = layout_from_record(identity["simulator"]["learned_inputs"])
    wanted, metrics = identity["measurement"], identity["simulator"]["metrics"]
    motion = {key: metrics[key] for key in ("k_nearest", "pairwise_metrics", "state_high", "state_low")
              if key in metrics}
    settings = dataclasses.replace(track_settings(wanted["group_radius"], wanted.get("warmup", 0.0),
                                                  wanted["fragmentation_cohesion"], wanted["dcd_max_delay"]), **motion)
    rows = []
    for flock in flocks:
        try:
            rows.append(raw_row(flock, settings, plan))
        except ValueError as err:
            raise ConfigError("--tracks", f"flock {flock.name!r}: {err}") from None
    return np.array(rows, dtype=float).reshape(len(rows), plan.length)

