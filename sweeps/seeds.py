"""The one registry of random streams derived from a sweep's or a calibration's seed.

Every generator outside the compiled loop comes from a ``numpy.random.SeedSequence`` whose entropy is
``[seed, tag, ...]``: the user's seed, then a :class:`Tag` saying what the numbers are for, then the
position inside that use. A new use takes a new tag, so it never shifts the numbers of an existing one.
The values are part of every stored result: changing one changes results.

=====================  ===========================  =================================================
tag                    entropy                      seeds
=====================  ===========================  =================================================
``WALKERS`` (0)        [seed, 0]                    emcee's initial walkers (BSL, emulator)
``MOVES`` (1)          [seed, 1]                    emcee's move random state (MT19937)
``EVALUATION`` (2)     [seed, 2, phase, step, i]    the simulations of one BSL log-posterior evaluation
``CONFIRM`` (3)        [seed, 3]; [seed, 3, r]      the emulator's confirmation runs; refinement round r >= 1
``RECHECK`` (7)        [seed, 7]                    the optimum's fresh-seed re-check (optimize)
``PREDICTIVE``         [seed, 0x5050]; [.., i]      which posterior draws are checked; draw i's run
``SBC``                [seed, 0x5BC, j, stream]     SBC dataset j (:class:`SBCStream`); [seed, 0x5BC,
                                                    0xECDF] the ECDF band
``DESIGN_SAMPLE``      [sweep seed, 0x5A3D1E]       the sampled block of a sweep design
``DESIGN_SENSITIVITY`` [sweep seed, 0x5E45]         a sweep's ``[design]`` block (SALib's sample)
``PRIOR``              [seed, 0x9A10]               the prior draws stored in a calibration's posterior.nc
``NPE``                [seed, 0x4E5E, stream(, r)]  neural posterior estimation (:class:`NPEStream`; r: a sequential round)
``COMPARE``            [seed, 0xC0DE, stream, m]    model comparison, model m (:class:`CompareStream`)
``CLAIM_POWER``        [seed, 0xC1A1, sha256(test)]  the power simulation of a claim's test (``test`` its
                                                    path, e.g. "d.faster"; :func:`named_generator`)
=====================  ===========================  =================================================

A stream's ``numpy.random.SeedSequence`` is :func:`simcore.rng.seed_sequence` of its entropy words
(``seed_sequence((seed, Tag.MOVES))``), the same function that turns a run's seed into its sequence.

Other seeds: a sweep run's seed is :func:`run_seed` (``[sweep seed, sha256(point) words, replicate]``,
the top 63 bits); :func:`common_seeds` gives fixed seeds from one integer (``SeedSequence(seed)``) and
:func:`seeds_for` fresh ones from a generator. Inside the simulator, counter-based draws use the run's
key and the ``STREAM_*`` numbers of ``simcore.rng``.
"""
from __future__ import annotations

import hashlib
from enum import IntEnum, unique

import numpy as np

from flocksweep.simcore.rng import seed_sequence

SEED_BITS = 63


@unique
class Tag(IntEnum):
    WALKERS = 0
    MOVES = 1
    EVALUATION = 2
    CONFIRM = 3
    RECHECK = 7
    PREDICTIVE = 0x5050
    SBC = 0x5BC
    DESIGN_SAMPLE = 0x5A3D1E
    DESIGN_SENSITIVITY = 0x5E45
    PRIOR = 0x9A10
    CLAIM_POWER = 0xC1A1
    NPE = 0x4E5E
    COMPARE = 0xC0DE


@unique
class NPEStream(IntEnum):
    """The streams of the npe method: [seed, Tag.NPE, stream]."""
    DESIGN = 0      # the prior draws of the training and held-out simulations (one design)
    NOISE = 1       # the targets' measurement noise added to those simulations
    TRAIN = 2       # the flow's initial weights, batches and validation split (a JAX key)
    POSTERIOR = 3   # the posterior draws at the targets (a JAX key)
    COVERAGE = 4    # the posterior draws and rank ties of the held-out coverage check
    ROUND_REGION = 5   # [seed, Tag.NPE, 5, r]: the posterior draws that set round r's truncation region (r >= 2)
    ROUND_DESIGN = 6   # [seed, Tag.NPE, 6, r]: round r's draws from the truncated prior (rejection)
    ROUND_NOISE = 7    # [seed, Tag.NPE, 7, r]: the targets' measurement noise added to round r's simulations
    ROUND_TRAIN = 8    # [seed, Tag.NPE, 8, r]: the flows of round r (a JAX key)
    RUNS = 9           # [seed, Tag.NPE, 9, i]: the run seed of design row i (round 1 and the one-round design)
    ROUND_RUNS = 10    # [seed, Tag.NPE, 10, r, i]: the run seed of round r's design row i (r >= 2)


@unique
class CompareStream(IntEnum):
    """The streams of a model comparison: [seed, Tag.COMPARE, stream, model index] (CLASSIFIER: no model)."""
    DESIGN = 0      # model m's prior draws (its training and held-out simulations, one sweep design)
    NOISE = 1       # the targets' measurement noise added to those simulations
    CLASSIFIER = 2  # the classifier's random state


@unique
class SBCStream(IntEnum):
    """The streams of one SBC dataset: [seed, Tag.SBC, j, stream]."""

    THETA = 0       # the parameters drawn from the prior
    OBSERVED = 1    # the observed data simulated at them
    BSL = 2         # the integer seed of the dataset's BSL run (npe: the JAX seed of its estimator draws)
    SELECT = 3      # which thinned posterior draws are kept
    TIES = 4        # tie-breaking in the ranks


ECDF_BAND = 0xECDF  # [seed, Tag.SBC, ECDF_BAND]: the simulated uniform ranks of SBC's ECDF band


def generator(*words) -> np.random.Generator:
    """``Generator(PCG64(SeedSequence([w0, w1, ...])))`` of integer words >= 0 (``[seed, tag, ...]``;
    the sequence is :func:`simcore.rng.seed_sequence` of ``words``)."""
    return np.random.Generator(np.random.PCG64(seed_sequence(words)))


def _count(n, name: str) -> int:
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"{name}: got {n!r}; must be an integer >= 0")
    return int(n)


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


def _words(text: str, count: int = 4) -> list[int]:
    digest = hashlib.sha256(text.encode()).digest()
    return [int.from_bytes(digest[4 * k:4 * k + 4], "little") for k in range(count)]


def named_generator(seed: int, tag: Tag, name: str) -> np.random.Generator:
    """The generator of [seed, tag, 4 words of sha256(name)]: one stream per name, so adding a name never
    shifts another's numbers."""
    return generator(seed, tag, *_words(name))


def run_seed(sweep_seed: int, point: str | None, replicate: int) -> int:
    """A sweep run's 63-bit seed from ``SeedSequence([sweep_seed, *sha256(point) words, replicate])``;
    ``point=None`` (common random numbers) leaves the point out, so replicate r has the same seed at
    every design point."""
    entropy = [int(sweep_seed)] + (_words(point) if point is not None else []) + [int(replicate)]
    return int(np.random.SeedSequence(entropy).generate_state(1, np.uint64)[0] >> np.uint64(1))
