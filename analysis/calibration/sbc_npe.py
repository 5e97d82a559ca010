"""Simulation-based calibration (Talts et al. 2018) of the ``npe`` method's amortised estimator.

What it checks: the trained estimator q(theta | x) across the whole prior, not one posterior. One
estimator serves every dataset, so a dataset costs one simulation of its observed data and S draws of the
flow, no chain: far cheaper than BSL's SBC (:mod:`analysis.calibration.sbc`), which runs a chain per
dataset.

Contract
--------
``run_npe_sbc(config, datasets=50, draws=49, out_dir=None, progress=True, *, bins=None, workers=1,
order=None, resume=True, alpha=0.05) -> dict`` (the same return value as
:func:`analysis.calibration.sbc.run_sbc`), through :func:`analysis.calibration.methods.run_sbc`.

* ``config``: a calibration of method ``npe`` with one round (``rounds > 1`` truncates the prior to the
  targets' region, so its estimator is not meant to hold across the prior: a ConfigError at
  ``method.rounds``).
* The estimator is trained once into ``<out>/estimator`` (its runs in ``<out>/training``) or reused when
  that folder's identity matches, exactly as ``flocksweep calibrate`` does
  (:func:`analysis.calibration.npe.trained_estimator`; ``method.estimator`` names one kept elsewhere).
* Dataset ``j`` uses the BSL path's streams (``[seed, Tag.SBC, j, stream]``, :class:`sweeps.seeds.SBCStream`):
  ``theta_j`` from stream THETA, the observed rows ``y_j`` (m, k) from stream OBSERVED through the
  calibration's own simulator, ``[observation]`` block and measurement noise (what BSL's SBC observes),
  the rank ties from stream TIES. The estimator is conditioned on the transformed mean of the m rows, as
  at the targets (a learned summary, ``[method.npe.summary] kind = "learned"``: the m runs are its own
  simulator's, :func:`analysis.calibration.npe.npe_simulator`, the same runs and statistics, each with its
  raw inputs, and the estimator is conditioned on their mean statistics and every run's raw inputs, as at
  the observed flocks; the dataset records keep the statistics); its S draws are restricted to the prior's support and use the JAX seed drawn from
  stream BSL with row number j, so a dataset's draws depend on the file, j and S only (not on the order,
  the other datasets, the workers or a resume). A dataset the estimator puts almost no mass inside the
  prior at is ranked among the unrestricted draws and flagged ``outside_support`` (counted in
  ``summary.json``).
* Storage as the BSL path: ``settings.json`` (with the estimator's identity digest: a resume with another
  estimator is refused), ``datasets/<j>.json`` written as each dataset is done (resumable), then the
  report of :func:`analysis.calibration.sbc_report.write_report`.
* ``workers > 1`` simulates the datasets' observed data on a local process pool; draws are taken here.
"""
from __future__ import annotations

import dataclasses
import functools
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.files import json_ready
from flocksweep.sweeps.progress import Phases
from flocksweep.sweeps.seeds import SBCStream
from flocksweep.sweeps.store import OutputFolder

from .accounting import Accounting
from .checks import integer
from .data_model import simulate_fn
from .diagnostics import sbc_ranks
from .sbc import _bar, _check_settings, _digest, _prepare_out, draw_observed, draw_theta, generator, stream
from .sbc_report import dataset_path, write_report


@dataclasses.dataclass(frozen=True)
class NpeData:
    """What a dataset's observed data needs (picklable to worker processes): the prior, the observation
    model ``observe_fn(theta, rng) -> (m, k)`` and the seed."""

    prior: object
    observe_fn: Callable
    seed: int


def _observed(data: NpeData, j: int) -> dict:
    """theta_j and y_j (the simulation part of dataset j)."""
    started = time.time()
    theta = draw_theta(data, j)
    y = draw_observed(data, theta, j)
    return {"theta": theta, "y": y, "wall_s": time.time() - started}


def draw_seed(seed: int, j: int) -> int:
    """The JAX seed of dataset j's draws, in [0, 2**31 - 1)."""
    return int(np.random.Generator(np.random.PCG64(stream(seed, j, SBCStream.BSL))).integers(0, 2 ** 31 - 1))


def npe_dataset(config, estimator, support, j: int, theta, y, draws: int, wall_s: float = 0.0) -> dict:
    """The record of dataset j: the estimator's ``draws`` posterior draws at y_j and the ranks of theta_j."""
    started = time.time()
    y = np.asarray(y, dtype=float)
    k = len(config.targets.columns)
    x = config.transforms.apply(y[:, :k].mean(axis=0)[None, :], clip=True)
    if y.shape[1] > k:          # a learned summary: every run's raw inputs after the mean statistics
        x = np.concatenate([x, y[:, k:].reshape(1, -1)], axis=1)
    y = y[:, :k]
    seed = draw_seed(config.seed, j)
    outside = not np.isfinite(x).all()
    sample = np.full((draws, len(theta)), np.nan)
    if not outside:
        sample = estimator.sample_many(x, draws, seed, support, short="nan", rows=[j])[0]
        if np.isnan(sample).any():
            outside = True
            sample = estimator.sample_many(x, draws, seed, None, rows=[j])[0]
    ranks = (sbc_ranks(np.asarray(theta)[None, :], [sample], rng=generator(config.seed, j, SBCStream.TIES))[0]
             if np.isfinite(sample).all() else np.zeros(len(theta), dtype=int))
    return {"dataset": int(j), "theta": np.asarray(theta).tolist(), "observed": np.asarray(y).tolist(),
            "ranks": np.asarray(ranks).tolist(), "draws": sample.tolist(), "post_mean": sample.mean(axis=0).tolist(),
            "post_sd": sample.std(axis=0, ddof=1).tolist(), "draw_seed": seed, "outside_support": bool(outside),
            "wall_s": wall_s + time.time() - started, "simulations": {"observed": len(y), "total": len(y)}}


def settings_record(config, draws: int, identity: str) -> dict:
    return json_ready({"method": "sbc", "kind": config.method.kind, "seed": int(config.seed), "draws": int(draws),
                       "names": list(config.names), "columns": list(config.targets.columns),
                       "estimator_identity": identity,
                       "problem": {"name": config.name, "config": json_ready(config.source),
                                   "preset_sha256": _digest(config.preset_data)}})


def run_npe_sbc(config, datasets: int = 50, draws: int = 49, out_dir=None, progress: bool = True, *,
                bins: int | None = None, workers: int = 1, order: Sequence[int] | None = None,
                resume: bool = True, alpha: float = 0.05) -> dict:
    """SBC of the config's npe estimator; see the module docstring."""
    from .npe import digest, estimator_identity, npe_simulator, trained_estimator
    from .npe_flow import support_of

    if config.method.rounds > 1:
        raise ConfigError("method.rounds", f"got {config.method.rounds}; SBC checks an amortised estimator across "
                                           "the prior, and sequential rounds truncate it to the targets' region: "
                                           "run it with --set method.rounds=1")
    datasets, draws = integer(datasets, "datasets", 1), integer(draws, "draws", 1)
    workers = integer(workers, "workers", 1)
    out_dir = Path("results") / "calibration" / config.name / "sbc" if out_dir is None else Path(out_dir)
    order = list(range(datasets)) if order is None else [int(j) for j in order]
    if sorted(order) != list(range(datasets)):
        raise ValueError(f"order must be a permutation of 0..{datasets - 1}")
    folder = OutputFolder(out_dir)
    settings = settings_record(config, draws, digest(estimator_identity(config)))
    _check_settings(folder, settings)                      # before the lock: refused without a write
    started = time.time()
    with folder.lock():
        _prepare_out(folder, settings, resume)
        phases = Phases("sbc", 3, progress)
        cost = Accounting()
        with Executor("serial", 1) as pool:
            estimator, _, info, where = trained_estimator(config, folder, pool, ("local", workers, None), phases,
                                                          cost)
        todo = [j for j in order if not dataset_path(folder.root, j).exists()]
        phases.start(f"{len(todo)} of {datasets} datasets: one simulated flock and {draws} draws of the estimator "
                     f"each ({datasets - len(todo)} stored)")
        data = NpeData(config.prior, simulate_fn(config, npe_simulator(config)), int(config.seed))
        support = support_of(config.prior)
        bar = _bar(datasets, datasets - len(todo), config.name, progress)
        try:
            with Executor("local" if workers > 1 else "serial", workers) as pool:
                for outcome in pool.as_completed(functools.partial(_observed, data), todo):
                    if outcome.error is not None:
                        raise outcome.error
                    j, part = outcome.item, outcome.value
                    record = npe_dataset(config, estimator, support, j, part["theta"], part["y"], draws,
                                         part["wall_s"])
                    folder.write_json(str(dataset_path(folder.root, j).relative_to(folder.root)), record)
                    if bar is not None:
                        bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        phases.start("the rank statistics, figures and report")
        result = write_report(folder.root, config.names, datasets, draws, bins=bins, alpha=alpha, seed=config.seed,
                              columns=config.targets.columns)
        phases.done(f": {folder.root}")
    result["wall_s"] = time.time() - started
    result["estimator"] = {"path": str(where), "reused": bool(info["reused"]),
                           "simulations": cost.block()["simulations"]}
    return result
