"""Sequential rounds of the ``npe`` method: truncated sequential neural posterior estimation (TSNPE,
Deistler, Goncalves & Macke 2022). Round 1 trains on prior draws; every later round draws its training
simulations from the prior truncated to the current estimator's highest-probability region at the
observed targets, and the estimator is retrained on all rounds' simulations.

Shapes: d parameters, k statistics, S draws.

Contract
--------
``Region(estimator, observed (k,), threshold, inside_prior)``: the truncation region {theta inside the
prior's bounds with log q(theta | observed) >= threshold}; ``contains(theta (S, d)) -> (S,) bool``.

``truncation_region(estimator, observed, inside_prior, seed, quantile=QUANTILE, draws=REGION_DRAWS) ->
Region``: the threshold is the ``quantile`` (1e-4, Deistler et al.'s choice) of log q over ``draws``
posterior draws at ``observed`` (JAX seed ``seed``), so the region holds all but about that share of the
estimator's posterior mass.

``truncated_prior_draws(prior, region, count, rng) -> ((count, d), accepted share)``: draws of the
prior restricted to the region by rejection: batches of prior draws from ``rng``, the accepted ones in
order, until ``count``; the share of prior draws accepted estimates the region's prior mass. A deterministic function of the region and ``rng``. A ConfigError ``method.rounds`` when
fewer than one in ``MAX_REJECTIONS`` prior draws is accepted (a region too small to sample).

Why the posterior stays right: inside the region the truncated prior is proportional to the prior, so
the mixture of all rounds' proposals is too, and maximum likelihood on all simulations fits the true
posterior there (Deistler et al. 2022, section 3); outside it the estimator saw only round 1's draws.
The ``npe`` method therefore restricts the final posterior and its held-out coverage check to the last
round's region (docs/calibration.md, "Sequential rounds").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flocksweep.simcore.schema import ConfigError

QUANTILE = 1e-4
REGION_DRAWS = 20_000
MAX_REJECTIONS = 10_000   # at most this many prior draws per accepted one


@dataclass(frozen=True, eq=False)
class Region:
    """The truncation region of one round (module docstring)."""

    estimator: object
    observed: np.ndarray
    threshold: float
    inside_prior: object

    def contains(self, theta) -> np.ndarray:
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        inside = np.asarray(self.inside_prior(theta), dtype=bool)
        if inside.any():
            inside[inside] = self.estimator.log_prob(theta[inside], self.observed) >= self.threshold
        return inside


def truncation_region(estimator, observed, inside_prior, seed: int, quantile: float = QUANTILE,
                      draws: int = REGION_DRAWS) -> Region:
    """The region holding all but ``quantile`` of the estimator's posterior mass at ``observed``."""
    observed = np.asarray(observed, dtype=float)
    samples = estimator.sample(observed, draws, seed, inside_prior)
    threshold = float(np.quantile(estimator.log_prob(samples, observed), quantile))
    return Region(estimator, observed, threshold, inside_prior)


def truncated_prior_draws(prior, region: Region, count: int, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """``count`` prior draws inside ``region`` by rejection, and the share of prior draws accepted (the
    region's prior mass; module docstring)."""
    accepted, proposed, found = [], 0, 0
    batch = max(1000, 4 * count)
    while found < count:
        if proposed >= MAX_REJECTIONS * count:
            raise ConfigError("method.rounds", f"the truncated prior accepted {found} of {proposed} prior draws: the "
                                               "estimator's region at the targets is too small to sample; use "
                                               "rounds = 1 or more simulations per round")
        theta = np.asarray(prior.sample(rng, batch), dtype=float).reshape(batch, -1)
        keep = theta[region.contains(theta)]
        accepted.append(keep)
        proposed, found = proposed + batch, found + len(keep)
    return np.concatenate(accepted)[:count], found / proposed

