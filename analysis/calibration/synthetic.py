"""Synthetic observations for parameter-recovery studies: simulate a calibration's statistics at a
known truth.

``synthetic_observation(config, truth, seed, replicates=1) -> (replicates, k)`` runs the calibration's
fixed model with its free parameters set to ``truth`` (a dict name -> value covering every free
parameter, or a (d,) array in ``config.names`` order) and returns the target summary columns
(``config.targets.columns``) of ``replicates`` runs whose seeds are ``common_seeds(seed, replicates)``:
the same arguments always give the same numbers. A row is one flock's observed statistics, exactly
what the likelihood models (observation noise is NOT added: the targets' sd is the measurement error
the user states).

``targets_block(config, rows, sd, truth=None)`` formats them as a ``[targets]`` TOML block for the
calibration file (one replicate: its values; several: their means, with the replicate sd in a comment, or
with ``samples`` the path of the CSV of the rows, one observed flock each: ``flocksweep targets --samples``;
with ``truth``, the ``truth = { ... }`` line that draws it in the corner plot and checks it in the report;
with ``flock``, the ``flock = { ... }`` line of the same runs' other statistics, which the predictive runs
are checked against: :mod:`~analysis.calibration.flock_check`).

``measured_targets_block(path, tracks=None, overrides=())`` is ``flocksweep targets --from-tracks``: the calibration
file's targets measured from its ``from_tracks`` file (or from ``tracks`` instead of the file's own
targets), one row per flock, as :func:`~analysis.calibration.tracks_targets.tracks_block` prints them.
"""
from __future__ import annotations

import json

import numpy as np

from pathlib import Path

from flocksweep.simcore.schema import ConfigError, read_config

from flocksweep.sweeps.model_set import model_overrides
from flocksweep.sweeps.seeds import common_seeds

from .config import CalibrationConfig, calibration_from_dict
from .flock_check import flock_columns
from .simulator import summary_simulator
from .tracks_targets import tracks_block


def truth_vector(config: CalibrationConfig, truth) -> np.ndarray:
    """(d,) truth in ``config.names`` order; ConfigError naming a missing, unknown or out-of-prior value."""
    if isinstance(truth, dict):
        unknown = sorted(set(truth) - set(config.names))
        if unknown:
            raise ConfigError("--truth", f"unknown parameter(s) {unknown}; free parameters: {list(config.names)}")
        missing = [n for n in config.names if n not in truth]
        if missing:
            raise ConfigError("--truth", f"missing value(s) for {missing}; give every free parameter "
                                         f"{list(config.names)}")
        truth = [truth[n] for n in config.names]
    vector = np.asarray(truth, dtype=float)
    if vector.shape != (config.dim,):
        raise ConfigError("--truth", f"expected {config.dim} values for {list(config.names)}, got {vector.shape}")
    if not np.isfinite(config.prior.logpdf(vector)):
        raise ConfigError("--truth", f"{dict(zip(config.names, vector.tolist()))} is outside the prior's support")
    return vector


def synthetic_observation(config: CalibrationConfig, truth, seed: int, replicates: int = 1, flock: bool = False):
    """(replicates, k) target statistics of runs at ``truth``; with ``flock``, also the same runs' (replicates,
    f) flock statistics (:func:`~analysis.calibration.flock_check.flock_columns`); see the module docstring."""
    theta = truth_vector(config, truth)
    columns = flock_columns(config) if flock else ()
    rows = summary_simulator(config, n_sim=replicates, extra_columns=columns).simulate(
        theta, common_seeds(seed, replicates))
    k = config.targets.k
    return (rows[:, :k], rows[:, k:]) if flock else rows


def targets_block(config: CalibrationConfig, rows: np.ndarray, sd, truth=None, flock=None, samples=None) -> str:
    """A ``[targets]`` TOML block: observed = the rows' mean, with ``sd`` (k,) as measurement error (or,
    with ``samples``, the path of a CSV holding the rows, one observed flock each), the ``truth`` (a dict or
    (d,) vector) they were simulated at as ``truth = { name = value, ... }``, and the same runs' ``flock``
    statistics (replicates, f) as ``flock = { stat = mean, ... }``."""
    rows = np.atleast_2d(rows)
    mean = rows.mean(axis=0)
    lines = ["[targets]", f'summary = "{config.targets.summary}"',
             "stats = [" + ", ".join(f'"{s}"' for s in config.targets.stats) + "]"]
    if samples is not None:
        lines.append(f"samples = {json.dumps(str(samples))}   # {len(rows)} rows: one observed flock each")
    else:
        lines += ["mean = [" + ", ".join(f"{v:.6g}" for v in mean) + "]",
                  "sd = [" + ", ".join(f"{v:.6g}" for v in np.broadcast_to(sd, mean.shape)) + "]"]
    if truth is not None:
        values = truth_vector(config, truth)
        lines.append("truth = { " + ", ".join(f"{n} = {v:.6g}" for n, v in zip(config.names, values)) + " }")
    if flock is not None:
        means = np.atleast_2d(flock).mean(axis=0)
        stats = [c.removesuffix(f"_{config.targets.summary}") for c in flock_columns(config)]
        lines.append("flock = { " + ", ".join(f"{n} = {v:.6g}" for n, v in zip(stats, means)) + " }"
                     "   # the same runs' other statistics: checked, not fitted")
    if len(rows) > 1:
        spread = rows.std(axis=0, ddof=1)
        what = f"{len(rows)} runs" if samples is not None else f"means of {len(rows)} runs"
        lines.append(f"# {what}; run-to-run sd " + ", ".join(f"{v:.4g}" for v in spread))
    return "\n".join(lines) + "\n"


def measured_targets_block(path, tracks=None, overrides=()) -> str:
    """The targets of calibration file ``path`` (with ``key=value`` ``overrides``) measured from tracks (see
    the module docstring); the file's ``targets.sd`` stays, as the flocks' measurement error."""
    path = Path(path)
    data = read_config(path, "calibration file", model_overrides(overrides))
    if tracks:
        targets = data.setdefault("targets", {})
        for key in ("mean", "cov", "samples"):
            targets.pop(key, None)
        targets["from_tracks"] = str(Path(tracks).resolve())
    config = calibration_from_dict(data, path.resolve().parent)
    if config.targets.tracks_path is None:
        raise ConfigError("--from-tracks", f"{path} has no targets.from_tracks; name the track file: --from-tracks TRACKS")
    return tracks_block(config)
