"""Simulation-based calibration of the ``emulator`` method: the emcee chain on its surrogate, checked on
many simulated datasets (``flocksweep sbc`` on an emulator file).

``emulator_problem(config, steps=None, walkers=None) -> SBCProblem``: the surrogate is fitted once, on the
config's sweep (``method.results``, as :mod:`analysis.calibration.methods.emulator` fits it, without
refinement rounds); then, as for BSL (:mod:`analysis.calibration.sbc`), dataset j draws theta_j from the
prior and y_j from the real simulator through the data model (:func:`analysis.calibration.data_model.simulate_fn`:
the targets' observation noise, their rows), and the posterior given y_j is the emulator's own chain
(:func:`analysis.calibration.emulated.run_emulator_mcmc`: the surrogate's mean and variance, the targets'
covariance, the config's walkers, steps and moves) seeded by dataset j's stream 2. Burn-in, thinning,
ranks, storage, resume and the uniformity tests are :func:`analysis.calibration.sbc.run_sbc`'s. No
simulation beyond the observed datasets: the check costs chains, not runs.

What it checks: the whole emulated inference (the surrogate's accuracy over the prior, its variance, the
chain), against the real simulator. Ranks that are not uniform say the surrogate misleads the posterior
somewhere the prior reaches (e.g. outside the sweep's box, or where the sweep is too sparse); refining
the sweep (``method.emulator.refine``) changes the surrogate, so SBC checks the unrefined one.
``meta`` records the method, the surrogate kind and fingerprint (its training data) and the config, so a
resume against another sweep or surrogate is refused.
"""
from __future__ import annotations

import functools

import numpy as np

from flocksweep.sweeps.files import json_ready

from .data_model import simulate_fn
from .sbc import SBCProblem, _digest
from .simulator import summary_simulator


def _emulated_chain(surrogate, obs_cov, prior, walkers: int, steps: int, moves: str, observed, seed: int):
    from .emulated import run_emulator_mcmc

    return run_emulator_mcmc(surrogate, observed, obs_cov, prior, walkers=walkers, steps=steps, seed=seed,
                             moves=moves)


def emulator_problem(config, steps: int | None = None, walkers: int | None = None) -> SBCProblem:
    """The SBC problem of an emulator calibration (module docstring)."""
    from .emulated import observation_covariance
    from .surrogates import build_surrogate
    from .training import training_set

    settings = config.method
    surrogate = build_surrogate(training_set(settings.results, config), settings.surrogate)
    walkers = int(walkers if walkers is not None else settings.walkers)
    steps = int(steps if steps is not None else settings.steps)
    rows = int(np.asarray(config.targets.observed).shape[0])
    posterior = functools.partial(_emulated_chain, surrogate, observation_covariance(config), config.prior,
                                  walkers, steps, settings.moves)
    meta = {"name": config.name, "method": "emulator", "surrogate": settings.surrogate,
            "surrogate_fingerprint": surrogate.fingerprint, "observed_rows": rows,
            "config": json_ready(config.source), "preset_sha256": _digest(config.preset_data)}
    return SBCProblem(prior=config.prior, simulate_fn=None,
                      observe_fn=simulate_fn(config, summary_simulator(config, n_sim=rows)),
                      names=tuple(config.names), columns=tuple(config.targets.columns), seed=int(config.seed),
                      walkers=walkers, steps=steps, likelihood="emulated", moves=settings.moves, meta=meta,
                      posterior_fn=posterior)
