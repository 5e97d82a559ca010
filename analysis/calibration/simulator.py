"""The simulator side of calibration: parameter vector theta -> a table of summary statistics.

Contract
--------
:class:`SummarySimulator` is configured once and called many times:

    sim = SummarySimulator(base_preset_data, keys, columns, n_sim, warmup, group_radius=None,
                           fragmentation_cohesion=0.5, observation=None, dcd_max_delay=2.0, motion=None,
                           strict=None)
    rows = sim.simulate(theta, seeds)      # float64 (n_sim, k), k = len(columns)
    rows = sim(theta, rng)                 # = sim.simulate(theta, seeds_for(rng, n_sim))
    obs, row = sim.run(theta, seed)        # one run's observations (bare) and its row, as simulate gives it
    sim.identity()                         # what a row depends on besides theta and the seed (a dict)

* ``base_preset_data`` is a preset dict (parsed TOML, fixed settings already applied); it is deep-copied
  and validated once at construction and never modified.
* ``keys`` (p,) are dotted preset keys of the free parameters (``"perception.field_deg"``,
  ``"init.n"``, ...). ``theta`` has shape (p,), one value per key in that order. A key whose field is an
  integer (e.g. ``init.n``) takes ``round(theta_j)`` (Python rounding, half to even); every other key
  takes ``float(theta_j)``. Boolean and string fields cannot be free parameters.
* At each ``theta`` the preset is the base preset with the keys set by :meth:`simcore.Preset.replace`,
  so a ``theta`` outside what the model allows raises :class:`~simcore.schema.ConfigError` naming the
  key (so does a non-finite ``theta_j``). The run settings (duration, dt, record interval) are the
  preset's ``[run]`` table.
* ``columns`` (k,) are per-run summary columns, in the output's column order: any of
  :func:`observables.summary.summary_columns` (``<metric>_mean`` / ``<metric>_final``,
  ``time_to_fragmentation``, ``fragmented``, the leadership scalars and the directional correlation
  delays ``dcd_*``). A row is :func:`observables.summary.summarize_run` of the run with the metric
  settings ``warmup``, ``group_radius`` and ``fragmentation_cohesion`` (leadership metrics when a
  leadership column is asked for; with ``leadership.x = 0`` there are no events, so ``trigger_rate`` is
  0; the directional correlation delays, up to ``dcd_max_delay`` s, when a ``dcd_*`` column is) and
  ``motion``, the settings of the observables of collective motion that differ from their defaults
  (``k_nearest``, ``pairwise_metrics``, ``state_high``, ``state_low``: :data:`observables.summary.MOTION_SETTINGS`;
  None: the defaults). Unknown columns raise ValueError at construction.
* ``group_radius`` None (default) uses the perception range of the model *at theta*, as the sweeps do,
  so a free perception radius also moves the group radius. Pass a number to keep it fixed.
* ``observation`` (an :class:`observables.observation.Observation`, default None): each run is
  recorded at the observation's sampling interval and measured as an observer measured the targets
  (:func:`~observables.observation.observe_run`: projection, missed detections, position noise
  drawn from the run seed's observation stream, resampling, velocities by differencing) before
  ``summarize_run``. Without it nothing changes: rows are those of the bare runs, bit for bit.
* ``seeds`` (n_sim,) are run seeds: ints >= 0, tuples of them, or ``numpy.random.SeedSequence``
  objects (copied before use, so the caller's objects are never advanced and the same seeds always give
  the same rows). All seeds run in ONE :func:`simcore.simulate.simulate_batch` call (threaded, compiled);
  row i is bit-identical to ``simulate`` + ``summarize_run`` of seed i alone, whatever the other seeds are.

Non-finite results (decision): a row is either all finite or all NaN; with ``strict = j`` only its first j
columns decide (the targets of a predictive run: a flock statistic that is undefined, as the elongation of
a group of two, is NaN alone and the run still counts). When a run's trajectory has a
non-finite value, or any of its requested summaries is nan or +-inf (e.g. ``time_to_fragmentation``
of a flock that never fragments, ``follow_corr_lag0`` without a trigger event), its whole row is NaN.
Nothing is dropped or replaced here; the caller decides (e.g. ``rows[np.isfinite(rows).all(axis=1)]``,
or treating the NaN share as a failure rate). Choose columns that are finite by design for likelihoods.

Seeds: :func:`sweeps.seeds.seeds_for` draws fresh seeds from a generator (independent replicates per
evaluation); :func:`sweeps.seeds.common_seeds` derives fixed seeds from one integer (common random
numbers across theta).
"""
from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np

from flocksweep.observables.directional_correlation import DCD_MAX_DELAY, DCD_METRIC_NAMES
from flocksweep.observables.leadership import LEADERSHIP_METRIC_NAMES
from flocksweep.observables.metrics import FRAGMENTATION_COHESION
from flocksweep.observables.observation import observe_run
from flocksweep.observables.summary import (MetricSettings, NonFiniteState, check_finite, motion_settings, summarize_run,
                                            summary_columns)
from flocksweep.simcore.params import Preset, preset_from_dict
from flocksweep.simcore.schema import ConfigError, suggest
from flocksweep.simcore.simulate import simulate_batch
from flocksweep.sweeps.seeds import seeds_for

from .checks import integer

ALL_COLUMNS = summary_columns(leadership=True, dcd=True, walls=True)


def _fresh_seed(seed):
    """A SeedSequence copied to its initial state (simulate spawns children, which advances it)."""
    if isinstance(seed, np.random.SeedSequence):
        return np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key, pool_size=seed.pool_size)
    return seed


def _lookup(full: dict, key: str):
    """Resolved value of dotted ``key`` in a preset's ``full_dict``; ConfigError for an unknown key."""
    node = full
    parts = key.split(".")
    for i, part in enumerate(parts):
        if not isinstance(node, dict) or part not in node:
            known = list(node) if isinstance(node, dict) else []
            where = ".".join(parts[:i]) or "the preset"
            raise ConfigError(key, f"not a key of {where}" + suggest(part, known))
        node = node[part]
    if isinstance(node, dict):
        raise ConfigError(key, "is a table, not a value")
    return node


class SummarySimulator:
    """theta -> (n_sim, k) summary table; see the module docstring for the contract."""

    def __init__(self, base_preset_data: dict, keys: Sequence[str], columns: Sequence[str], n_sim: int,
                 warmup: float, group_radius: float | None = None,
                 fragmentation_cohesion: float = FRAGMENTATION_COHESION, observation=None,
                 dcd_max_delay: float = DCD_MAX_DELAY, motion: dict | None = None, strict: int | None = None):
        self.base = copy.deepcopy(dict(base_preset_data))
        self.strict = None if strict is None else int(strict)
        self.observation = observation
        self.base_preset = preset_from_dict(self.base)
        self.keys = tuple(keys)
        self.columns = tuple(columns)
        if not self.keys:
            raise ValueError("keys: need at least one free parameter")
        if len(set(self.keys)) != len(self.keys):
            raise ValueError(f"keys: duplicates in {self.keys}")
        if not self.columns:
            raise ValueError("columns: need at least one summary column")
        for col in self.columns:
            if col not in ALL_COLUMNS:
                raise ValueError(f"columns: unknown column {col!r}" + suggest(col, ALL_COLUMNS))
        self.n_sim = integer(n_sim, "n_sim", 1)
        if not (isinstance(warmup, (int, float)) and math.isfinite(warmup) and warmup >= 0):
            raise ValueError(f"warmup: got {warmup!r}; must be a finite number >= 0")
        if group_radius is not None and not (math.isfinite(group_radius) and group_radius > 0):
            raise ValueError(f"group_radius: got {group_radius!r}; must be a finite number > 0 or None")
        self.metrics = MetricSettings(warmup=float(warmup), group_radius=None if group_radius is None
                                      else float(group_radius), fragmentation_cohesion=fragmentation_cohesion,
                                      leadership=any(c in LEADERSHIP_METRIC_NAMES for c in self.columns),
                                      dcd=any(c in DCD_METRIC_NAMES for c in self.columns),
                                      dcd_max_delay=float(dcd_max_delay), **dict(motion or {}))
        full = self.base_preset.full_dict()
        integer_keys = []
        for key in self.keys:
            value = _lookup(full, key)
            if isinstance(value, (bool, str, list)):
                raise ConfigError(key, f"a free parameter must be numeric, this key holds {value!r}")
            integer_keys.append(isinstance(value, int))
        self.integer_keys = tuple(integer_keys)

    @property
    def row_width(self) -> int:
        """Numbers in a row: the columns (a subclass may add more after them)."""
        return len(self.columns)

    @property
    def run_width(self) -> int:
        """Numbers in one run's row of :meth:`simulate` (a subclass may pool several runs into a wider row)."""
        return self.row_width

    @property
    def warmup(self) -> float:
        return self.metrics.warmup

    @property
    def group_radius(self) -> float | None:
        return self.metrics.group_radius

    def with_replicates(self, n_sim: int) -> "SummarySimulator":
        """The same simulator running ``n_sim`` replicates per call."""
        if n_sim == self.n_sim:
            return self
        return SummarySimulator(self.base, self.keys, self.columns, n_sim, self.warmup, self.group_radius,
                                self.metrics.fragmentation_cohesion, self.observation, self.metrics.dcd_max_delay,
                                motion_settings(self.metrics), self.strict)

    def identity(self) -> dict:
        """What a row depends on besides theta and the seed: the model (its preset with the fixed settings,
        the model version), the free keys, the columns, replicates, metric settings and observation block."""
        import dataclasses

        from flocksweep.simcore import MODEL_VERSION
        from flocksweep.sweeps.files import json_ready

        return json_ready({"preset": self.base_preset.to_dict(), "model_version": MODEL_VERSION,
                           "keys": list(self.keys), "columns": list(self.columns), "n_sim": int(self.n_sim),
                           "metrics": self.metrics.identity(),
                           "observation": None if self.observation is None else dataclasses.asdict(self.observation)})

    def preset(self, theta) -> Preset:
        """The validated preset at ``theta`` (integer keys rounded; ConfigError naming the key when invalid)."""
        values = np.asarray(theta, dtype=np.float64)
        if values.shape != (len(self.keys),):
            raise ValueError(f"theta: expected shape ({len(self.keys)},) for keys {self.keys}, "
                             f"got {np.shape(theta)}")
        changes = {}
        for key, is_int, value in zip(self.keys, self.integer_keys, values):
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError(key, f"got {value!r}; must be finite")
            changes[key] = int(round(value)) if is_int else value
        return self.base_preset.replace(changes)

    def simulate(self, theta, seeds) -> np.ndarray:
        """float64 (n_sim, k): row i holds the summary columns of the run with ``seeds[i]``."""
        seeds = list(seeds)
        if len(seeds) != self.n_sim:
            raise ValueError(f"seeds: expected {self.n_sim} seeds (n_sim), got {len(seeds)}")
        runs, settings = self._runs(theta, seeds)
        out = np.empty((self.n_sim, self.run_width))
        for i, obs in enumerate(runs):
            out[i] = self._row(obs, settings, seeds[i])
        return out

    def run(self, theta, seed):
        """(observations, row) of the one run with ``seed``: the bare run as recorded (every step of the
        observation's interval, or the preset's record interval) and its row, the row ``simulate`` gives
        that seed (bit for bit)."""
        (obs,), settings = self._runs(theta, [seed])
        return obs, self._row(obs, settings, seed)

    def _runs(self, theta, seeds):
        preset = self.preset(theta)
        run = preset.run
        every = run.record_every if self.observation is None else self.observation.record_every(run.dt)
        runs = simulate_batch(preset.model, preset.init, [_fresh_seed(s) for s in seeds], run.duration, run.dt,
                              every)
        return runs, self.metrics.resolve(preset.model)

    def __call__(self, theta, rng: np.random.Generator) -> np.ndarray:
        """``simulate(theta, seeds_for(rng, n_sim))``: fresh replicates at every call."""
        return self.simulate(theta, seeds_for(rng, self.n_sim))

    def _observed(self, obs, seed):
        """The run as the statistics see it (through the ``[observation]`` block when there is one), or
        None when its state went non-finite (its row is then all nan)."""
        try:
            check_finite(obs)
        except NonFiniteState:
            return None
        return obs if self.observation is None else observe_run(obs, self.observation, _fresh_seed(seed))

    def _row(self, obs, settings: MetricSettings, seed) -> np.ndarray:
        nan_row = np.full(len(self.columns), np.nan)
        obs = self._observed(obs, seed)
        if obs is None:
            return nan_row
        values = summarize_run(obs, settings)
        row = np.array([values[c] for c in self.columns], dtype=np.float64)
        strict = len(row) if self.strict is None else self.strict
        if not np.isfinite(row[:strict]).all():
            return nan_row
        return np.where(np.isfinite(row), row, np.nan)


def summary_simulator(config, n_sim: int | None = None, extra_columns=()) -> SummarySimulator:
    """The simulator of a calibration ``config`` (its fixed preset, free keys, target columns and metric
    settings) with ``n_sim`` replicates per call (default: ``config.method.n_sim``); ``extra_columns``
    are reported after the targets' (the predictive runs' flock statistics). A command model's is a
    :class:`~analysis.calibration.command_simulator.CommandSimulator` (the same interface)."""
    n_sim = config.method.n_sim if n_sim is None else n_sim
    m = config.metrics
    columns = tuple(config.targets.columns) + tuple(extra_columns)
    if getattr(config, "command", None) is not None:     # an external simulator: its tracks measured
        from .command_simulator import CommandSimulator

        return CommandSimulator(config.command, config.keys, columns, n_sim, m, config.observation,
                                len(config.targets.columns) if extra_columns else None)
    return SummarySimulator(config.preset_data, config.keys, columns, n_sim, m.warmup,
                            m.group_radius, m.fragmentation_cohesion, config.observation, m.dcd_max_delay,
                            motion_settings(m), len(config.targets.columns) if extra_columns else None)
