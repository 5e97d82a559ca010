"""The simulator side of calibration: parameter vector theta -> a table of summary statistics.

Contract
--------
:class:`SummarySimulator` is configured once and called many times:

    sim = SummarySimulator(base_preset_data, keys, columns, n_sim, warmup, group_radius=None)
    rows = sim.simulate(theta, seeds)      # float64 (n_sim, k), k = len(columns)
    rows = sim(theta, rng)                 # = sim.simulate(theta, seeds_for(rng, n_sim))

* ``base_preset_data`` is a preset dict (parsed TOML, fixed settings already applied); it is deep-copied
  and validated once at construction and never modified.
* ``keys`` (p,) are dotted preset keys of the free parameters (``"perception.field_deg"``,
  ``"init.n"``, ...). ``theta`` has shape (p,), one value per key in that order. A key whose field is an
  integer (e.g. ``init.n``) takes ``round(theta_j)`` (Python rounding, half to even); every other key
  takes ``float(theta_j)``. Boolean and string fields cannot be free parameters.
* At each ``theta`` the preset is rebuilt with :func:`simcore.schema.set_dotted` and
  :func:`simcore.params.preset_from_dict`, so a ``theta`` outside what the model allows raises
  :class:`~simcore.schema.ConfigError` naming the key (so does a non-finite ``theta_j``). The run
  settings (duration, dt, record interval) are the preset's ``[run]`` table.
* ``columns`` (k,) are per-run summary statistics, in the output's column order, any of
  ``<metric>_mean`` / ``<metric>_final`` for a metric of :data:`analysis.metrics.METRIC_NAMES`,
  ``time_to_fragmentation``, ``fragmented`` (all from :func:`analysis.metrics.summarize` with ``warmup``)
  and the leadership scalars :data:`analysis.leadership.LEADERSHIP_METRIC_NAMES` (escape duration =
  the model's ``leadership.duration``; with ``leadership.x = 0`` there are no events, so
  ``trigger_rate`` is 0). Unknown columns raise ValueError at construction.
* ``group_radius`` links boids into groups for the metrics; None (default) uses the perception range
  of the model *at theta* (:func:`analysis.metrics.default_group_radius`, as the sweeps do), so a free
  perception radius also moves the group radius. Pass a number to keep it fixed. Periodic worlds use
  minimum-image metrics (:func:`analysis.metrics.world_box`).
* ``seeds`` (n_sim,) are run seeds: ints >= 0, tuples of them, or ``numpy.random.SeedSequence``
  objects (copied before use, so the caller's objects are never advanced and the same seeds always give
  the same rows). All seeds run in ONE :func:`simcore.simulate.simulate_batch` call (threaded, compiled);
  row i is bit-identical to ``simulate`` + ``frame_metrics`` + ``summarize`` (+ ``leadership_metrics``)
  of seed i alone, whatever the other seeds are.

Non-finite results (decision): a row is either all finite or all NaN. When a run's trajectory has a
non-finite value, or any of its requested summaries is nan or +-inf (e.g. ``time_to_fragmentation``
of a flock that never fragments, ``follow_corr_lag0`` without a trigger event), its whole row is NaN.
Nothing is dropped or replaced here; the caller decides (e.g. ``rows[np.isfinite(rows).all(axis=1)]``,
or treating the NaN share as a failure rate). Choose columns that are finite by design for likelihoods.

Seeds: :func:`seeds_for` draws fresh 63-bit seeds from a ``numpy.random.Generator`` (independent
replicates per evaluation); :func:`common_seeds` derives fixed 63-bit seeds from one integer with
``SeedSequence(seed).generate_state`` (common random numbers across theta).

Cost (measured on the 2-core development machine, numba kernels cached on disk): the holland preset
with n = 30 boids, 10 s at dt = 1/60 (600 steps), records every 1 s, n_sim = 20 takes about 0.1 s per
evaluation (medians 0.11-0.14 s over 10 evaluations at varied theta, range 0.09-0.17 s; about 5-7 ms
per run). The threaded simulate_batch dominates; the metrics add a few ms. The first call in a fresh
process costs about 0.5 s more (loading the compiled kernels).
"""
from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np

from simcore.params import Preset, preset_from_dict
from simcore.schema import ConfigError, set_dotted, suggest
from simcore.simulate import Observations, simulate_batch

from ..leadership import LEADERSHIP_METRIC_NAMES, leadership_metrics
from ..metrics import METRIC_NAMES, default_group_radius, frame_metrics, summarize, world_box

SUMMARY_COLUMNS = tuple(f"{name}_{kind}" for name in METRIC_NAMES for kind in ("mean", "final")) + (
    "time_to_fragmentation", "fragmented")
ALL_COLUMNS = SUMMARY_COLUMNS + tuple(LEADERSHIP_METRIC_NAMES)
SEED_BITS = 63


def seeds_for(rng: np.random.Generator, n: int) -> list[int]:
    """``n`` fresh seeds, ints in [0, 2**63), drawn from ``rng`` (which advances)."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    n = _count(n, "n")
    return [int(s) for s in rng.integers(0, 2 ** SEED_BITS, size=n, dtype=np.int64)]


def common_seeds(seed: int, n: int) -> list[int]:
    """``n`` fixed seeds, ints in [0, 2**63), from ``SeedSequence(seed).generate_state`` (the top 63
    bits of each 64-bit word): the same list for the same ``seed`` (common random numbers)."""
    n = _count(n, "n")
    words = np.random.SeedSequence(seed).generate_state(n, np.uint64)
    return [int(w >> np.uint64(64 - SEED_BITS)) for w in words]


def _count(n, name: str, minimum: int = 0) -> int:
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < minimum:
        raise ValueError(f"{name}: got {n!r}; must be an integer >= {minimum}")
    return int(n)


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
                 warmup: float, group_radius: float | None = None):
        self.base = copy.deepcopy(dict(base_preset_data))
        base_preset = preset_from_dict(self.base)
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
        self.n_sim = _count(n_sim, "n_sim", 1)
        if not (isinstance(warmup, (int, float)) and math.isfinite(warmup) and warmup >= 0):
            raise ValueError(f"warmup: got {warmup!r}; must be a finite number >= 0")
        self.warmup = float(warmup)
        if group_radius is not None and not (math.isfinite(group_radius) and group_radius > 0):
            raise ValueError(f"group_radius: got {group_radius!r}; must be a finite number > 0 or None")
        self.group_radius = None if group_radius is None else float(group_radius)
        full = base_preset.full_dict()
        integer = []
        for key in self.keys:
            value = _lookup(full, key)
            if isinstance(value, (bool, str, list)):
                raise ConfigError(key, f"a free parameter must be numeric, this key holds {value!r}")
            integer.append(isinstance(value, int))
        self.integer_keys = tuple(integer)
        self._need_summary = any(c in SUMMARY_COLUMNS for c in self.columns)
        self._need_leadership = any(c in LEADERSHIP_METRIC_NAMES for c in self.columns)

    # ------------------------------------------------------------------ building

    def preset_data(self, theta) -> dict:
        """The preset dict at ``theta`` (integer keys rounded); not yet validated."""
        values = np.asarray(theta, dtype=np.float64)
        if values.shape != (len(self.keys),):
            raise ValueError(f"theta: expected shape ({len(self.keys)},) for keys {self.keys}, "
                             f"got {np.shape(theta)}")
        data = copy.deepcopy(self.base)
        for key, is_int, value in zip(self.keys, self.integer_keys, values):
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError(key, f"got {value!r}; must be finite")
            set_dotted(data, key, int(round(value)) if is_int else value)
        return data

    def preset(self, theta) -> Preset:
        """The validated preset at ``theta`` (ConfigError naming the key when invalid)."""
        return preset_from_dict(self.preset_data(theta))

    # ------------------------------------------------------------------ running

    def simulate(self, theta, seeds) -> np.ndarray:
        """float64 (n_sim, k): row i holds the summary columns of the run with ``seeds[i]``."""
        seeds = list(seeds)
        if len(seeds) != self.n_sim:
            raise ValueError(f"seeds: expected {self.n_sim} seeds (n_sim), got {len(seeds)}")
        preset = self.preset(theta)
        model, run = preset.model, preset.run
        runs = simulate_batch(model, preset.init, [_fresh_seed(s) for s in seeds], run.duration, run.dt,
                              run.record_every)
        radius = default_group_radius(model) if self.group_radius is None else self.group_radius
        out = np.empty((self.n_sim, len(self.columns)))
        for i, obs in enumerate(runs):
            out[i] = self._row(obs, model, radius)
        return out

    def __call__(self, theta, rng: np.random.Generator) -> np.ndarray:
        """``simulate(theta, seeds_for(rng, n_sim))``: fresh replicates at every call."""
        return self.simulate(theta, seeds_for(rng, self.n_sim))

    seeds_for = staticmethod(seeds_for)
    common_seeds = staticmethod(common_seeds)

    def _row(self, obs: Observations, model, radius: float) -> np.ndarray:
        nan_row = np.full(len(self.columns), np.nan)
        if not (np.isfinite(obs.pos).all() and np.isfinite(obs.vel).all()):
            return nan_row
        box = world_box(model)
        values: dict[str, float] = {}
        if self._need_summary:
            series = frame_metrics(obs.pos, obs.vel, obs.visible, obs.binocular, obs.pattern, radius, box)
            values.update(summarize(series, obs.times, self.warmup))
        if self._need_leadership:
            values.update(leadership_metrics(obs, radius, model.leadership.duration, box))
        row = np.array([values[c] for c in self.columns], dtype=np.float64)
        return row if np.isfinite(row).all() else nan_row
