"""The calibration's data model as every method sees it: theta -> simulated statistics, with the targets'
measurement noise; and the posterior predictive runs.

Contract
--------
``simulate_fn(config, simulator) -> fn(theta, rng) -> (n_sim, k)``: the simulator's rows (fresh seeds from
``rng``), with the observation noise N(0, cov) of mean/sd (or covariance) targets added on the target
columns, drawn from the same generator after the seeds (BSL, SBC, the public ``summary_simulator``).

``seeded_fn(config, simulator) -> fn(theta, seeds) -> (n_sim, k)``: a deterministic function of the seeds,
the noise drawn from a generator seeded by the same seeds (common random numbers: the optimiser).

``predictive_runs(config, draws (P, d), pool=None, tick=None) -> ((P, k), (P, f))``: one simulated run per
posterior draw, its target statistics (observation noise included) and its flock statistics
(:func:`~analysis.calibration.flock_check.flock_columns`, bare); draw i uses the seed key
``(config.seed, Tag.PREDICTIVE, i)``; ``tick()`` after each. ``posterior_predictive`` is its first part.
"""
from __future__ import annotations

import functools

import numpy as np

from flocksweep.sweeps.executors import Executor
from flocksweep.sweeps.seeds import Tag, generator

from .bsl import simulate_keyed
from .emulated import observation_covariance
from .flock_check import flock_columns
from .simulator import summary_simulator


def simulate_fn(config, simulator):
    """theta, rng -> (n_sim, k) summaries, with the observation noise of mean/sd targets added."""
    cov = observation_covariance(config)

    def fn(theta, rng):
        sims = simulator(np.asarray(theta, dtype=float), rng)
        if cov is not None:   # the targets' noise, on the target columns (the first k; extra ones stay bare)
            sims = sims.copy()
            sims[:, :len(cov)] += rng.multivariate_normal(np.zeros(len(cov)), cov, size=len(sims))
        return sims
    return fn


def seeded_fn(config, simulator):
    """theta, seeds -> (n_sim, k): a deterministic function of the seeds (observation noise included,
    drawn from a generator seeded by the same seeds), as common random numbers need."""
    cov = observation_covariance(config)

    def fn(theta, seeds):
        sims = simulator.simulate(np.asarray(theta, dtype=float), seeds)
        if cov is not None:
            rng = generator(*seeds)
            sims = sims + rng.multivariate_normal(np.zeros(len(cov)), cov, size=len(sims))
        return sims
    return fn


def predictive_runs(config, draws: np.ndarray, pool: Executor | None = None, tick=None):
    """((P, k), (P, f)): one run per posterior draw (see the module docstring)."""
    simulator = summary_simulator(config, n_sim=1, extra_columns=flock_columns(config))
    fn = functools.partial(simulate_keyed, simulate_fn(config, simulator))
    tasks = [(theta, (config.seed, Tag.PREDICTIVE, i)) for i, theta in enumerate(draws)]
    rows = np.vstack((pool or Executor("serial")).map(fn, tasks, tick))
    k = len(config.targets.columns)
    return rows[:, :k], rows[:, k:]


def posterior_predictive(config, draws: np.ndarray, pool: Executor | None = None, tick=None) -> np.ndarray:
    """(P, k): the target statistics of :func:`predictive_runs`."""
    return predictive_runs(config, draws, pool, tick)[0]
