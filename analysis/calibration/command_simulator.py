"""The simulator side of calibration for an external simulator run as a command (``[model] command``,
:mod:`sweeps.external`): theta -> the statistics of the tracks it writes, measured as measured tracks are.

Contract
--------
:class:`CommandSimulator` has the interface of :class:`~analysis.calibration.simulator.SummarySimulator`
(``simulate(theta, seeds) -> (n_sim, k)``, ``sim(theta, rng)``, ``run(theta, seed)``, ``with_replicates``,
``identity()``, ``keys``, ``columns``, ``integer_keys``, ``n_sim``, ``observation``, ``metrics``), so every
calibration method runs it unchanged:

    sim = CommandSimulator(command, keys, columns, n_sim, metrics, observation=None)

* ``command``: the validated :class:`~sweeps.external.CommandModel`; ``keys``: the free parameters, each a
  numeric parameter of its ``[model.parameters]`` (an ``integer = true`` one takes ``round(theta_j)``); the
  others keep their defaults. A value the declaration does not allow is a ConfigError naming the key.
* A run: the command with the run's seed (an int; a tuple or SeedSequence seed becomes its first 63-bit
  word) in a scratch folder (:func:`sweeps.external.run_command`: timeout, stderr kept), its output read as
  tracks (``[model.tracks]``), then, with an ``observation`` block, seen through it
  (:func:`observables.observation.observe_tracks`: the observation's sampling grid, projection, missed
  detections and position noise from the seed's observation stream, then resampled), else resampled as
  ``[model.tracks]`` says (interval, velocity interval, gap limit); measured by
  :func:`observables.summary.measure_run` with ``metrics`` (a fixed group radius). The row holds ``columns``.
* A run that fails (time-out, non-zero exit, output that is not one flock's tracks) or whose statistics are
  not finite is a NaN row, as the preset simulator's non-finite runs (``strict``: as there); :meth:`rows_and_reasons` gives the
  reasons too (the npe training runs record them).
* ``run(theta, seed) -> (flock, row)``: the run's flock as measured (an
  :class:`~observables.observed.ObservedFlock`, for the viewer pages) and its row; raises the run's failure.
"""
from __future__ import annotations

import dataclasses
import math
import tempfile
from pathlib import Path

import numpy as np

from flocksweep.observables.observation import observe_tracks
from flocksweep.observables.resample import RECORDED, resample
from flocksweep.observables.summary import measure_run
from flocksweep.observables.tracks import load_tracks, raw_flocks
from flocksweep.simcore.rng import seed_sequence
from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.external import CommandFailed, CommandModel, MalformedOutput, run_command
from flocksweep.sweeps.seeds import seeds_for


def command_seed(seed) -> int:
    """The integer a command gets for a run seed (an int as it is; else the seed's first 63-bit word)."""
    if isinstance(seed, (int, np.integer)) and int(seed) >= 0:
        return int(seed)
    return int(seed_sequence(seed).generate_state(1, np.uint64)[0] >> np.uint64(1))


class CommandSimulator:
    """theta -> (n_sim, k) statistics of an external command's tracks (module docstring)."""

    def __init__(self, command: CommandModel, keys, columns, n_sim: int, metrics, observation=None,
                 strict: int | None = None):
        self.command, self.strict = command, strict
        self.keys, self.columns, self.n_sim = tuple(keys), tuple(columns), int(n_sim)
        self.metrics, self.observation = metrics, observation
        declared = dict(command.parameters)
        for key in self.keys:
            if key not in declared:
                raise ConfigError(key, f"not a parameter of the command; declared: {', '.join(declared)}")
        self.integer_keys = tuple(bool(declared[key].integer) for key in self.keys)

    @property
    def warmup(self) -> float:
        return self.metrics.warmup

    def identity(self) -> dict:
        from flocksweep.sweeps.files import json_ready

        return json_ready({"command": self.command.identity, "defaults": self.command.values({}),
                           "keys": list(self.keys), "columns": list(self.columns), "n_sim": self.n_sim,
                           "metrics": self.metrics.identity(),
                           "observation": None if self.observation is None else dataclasses.asdict(self.observation)})

    def with_replicates(self, n_sim: int) -> "CommandSimulator":
        if n_sim == self.n_sim:
            return self
        return CommandSimulator(self.command, self.keys, self.columns, n_sim, self.metrics, self.observation,
                                self.strict)

    def values(self, theta) -> dict:
        """Every parameter's value at ``theta`` (the free ones set, integer ones rounded), checked."""
        theta = np.asarray(theta, dtype=np.float64)
        if theta.shape != (len(self.keys),):
            raise ValueError(f"theta: expected shape ({len(self.keys)},) for keys {self.keys}, got {theta.shape}")
        given = {}
        for key, whole, value in zip(self.keys, self.integer_keys, theta):
            if not math.isfinite(value):
                raise ConfigError(key, f"got {value!r}; must be finite")
            given[key] = int(round(value)) if whole else float(value)
        return self.command.values(given)

    def _flock(self, values: dict, seed):
        """The measured flock of one run (module docstring); raises the run's failure."""
        with tempfile.TemporaryDirectory(prefix="flocksweep-calibration-") as folder:
            scratch = Path(folder)
            try:
                out = run_command(self.command, values, command_seed(seed), scratch)
                table = load_tracks(out, self.command.tracks)
                flocks, _ = raw_flocks(table)
                if len(flocks) != 1:
                    raise MalformedOutput(f"the output holds {len(flocks)} flocks; a run writes one")
                raw = flocks[0]
                if self.observation is not None:
                    return observe_tracks(raw, self.observation, seed)
                tracks = self.command.tracks
                interval = tracks.interval or float(np.median(np.diff(np.unique(raw.t))))
                velocity = tracks.velocity_interval
                if velocity is None:
                    velocity = RECORDED if raw.vel is not None else None
                return resample(raw, interval, tracks.max_gap, velocity)
            except (CommandFailed, MalformedOutput) as err:
                raise type(err)(str(err).replace(str(scratch), "{scratch}")) from None
            except Exception as err:  # noqa: BLE001 - whatever the reader makes of the output is the output's fault
                raise MalformedOutput(f"the output {self.command.output} is not tracks that can be measured: "
                                      f"{type(err).__name__}: {err}") from None

    def _row(self, flock) -> np.ndarray:
        _, summary = measure_run(flock, self.metrics)
        row = np.array([summary.get(c, np.nan) for c in self.columns], dtype=np.float64)
        strict = len(row) if self.strict is None else self.strict
        if not np.isfinite(row[:strict]).all():
            raise ValueError("statistics not finite: " + ", ".join(c for c, v in zip(self.columns[:strict], row)
                                                                      if not np.isfinite(v)))
        return np.where(np.isfinite(row), row, np.nan)

    def rows_and_reasons(self, theta, seeds) -> tuple[np.ndarray, list[str]]:
        """((n_sim, k) rows, a reason per row: '' for a good one, why it is NaN otherwise)."""
        seeds = list(seeds)
        if len(seeds) != self.n_sim:
            raise ValueError(f"seeds: expected {self.n_sim} seeds (n_sim), got {len(seeds)}")
        values = self.values(theta)
        out, reasons = np.full((self.n_sim, len(self.columns)), np.nan), []
        for i, seed in enumerate(seeds):
            try:
                out[i] = self._row(self._flock(values, seed))
                reasons.append("")
            except (CommandFailed, MalformedOutput, ValueError) as err:
                reasons.append(f"{type(err).__name__}: {err}")
        return out, reasons

    def simulate(self, theta, seeds) -> np.ndarray:
        return self.rows_and_reasons(theta, seeds)[0]

    def __call__(self, theta, rng: np.random.Generator) -> np.ndarray:
        return self.simulate(theta, seeds_for(rng, self.n_sim))

    def run(self, theta, seed):
        """(the run's measured flock, its row), the row ``simulate`` gives that seed."""
        flock = self._flock(self.values(theta), seed)
        try:
            row = self._row(flock)
        except ValueError:
            row = np.full(len(self.columns), np.nan)
        return flock, row
