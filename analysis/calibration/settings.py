"""Typed settings of each calibration method: the ``[method]`` table of a calibration file, read by the
schema engine (:func:`simcore.schema.build`) into :class:`EmceeSettings`, :class:`OptimizeSettings`
or :class:`EmulatorSettings` by its ``kind`` (:data:`METHODS`). Each checks its own ranges;
:mod:`analysis.calibration.config` adds the checks that need the rest of the file (``n_sim`` against the
number of statistics, ``walkers`` against the number of parameters, ``results`` resolved against the
file's folder).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Literal

from simcore.schema import ConfigError, check_at_least


@dataclass(frozen=True, kw_only=True)
class MethodSettings:
    """Settings every method has: replicates per evaluation and the synthetic likelihood."""

    kind: ClassVar[str] = ""
    n_sim: int = 50
    likelihood: Literal["gaussian", "unbiased"] = "gaussian"

    def __post_init__(self):
        check_at_least("n_sim", self.n_sim, 2)


@dataclass(frozen=True, kw_only=True)
class ChainSettings(MethodSettings):
    """Settings of the methods that run an emcee chain; ``walkers`` None: max(16, 2 d)."""

    walkers: int | None = None
    steps: int = 2000
    moves: Literal["stretch", "de"] = "stretch"

    def __post_init__(self):
        super().__post_init__()
        check_at_least("steps", self.steps, 1)


@dataclass(frozen=True, kw_only=True)
class EmceeSettings(ChainSettings):
    """BSL-MCMC (analysis.calibration.bsl)."""

    kind: ClassVar[str] = "emcee"
    reevaluate_every: int = 0

    def __post_init__(self):
        super().__post_init__()
        check_at_least("reevaluate_every", self.reevaluate_every, 0)


@dataclass(frozen=True, kw_only=True)
class OptimizeSettings(MethodSettings):
    """Point calibration with common random numbers (analysis.calibration.optimize)."""

    kind: ClassVar[str] = "optimize"
    algorithm: Literal["differential_evolution", "nelder_mead"] = "differential_evolution"
    objective: Literal["loglik", "distance"] = "loglik"
    maxiter: int = 100
    popsize: int = 15
    recheck: int = 200

    def __post_init__(self):
        super().__post_init__()
        check_at_least("maxiter", self.maxiter, 1)
        check_at_least("popsize", self.popsize, 1)
        check_at_least("recheck", self.recheck, 0)


@dataclass(frozen=True, kw_only=True)
class EmulatorSettings(ChainSettings):
    """Emcee on a surrogate fitted to a sweep's results (analysis.calibration.training, .surrogates,
    .emulated); ``results`` is resolved against the calibration file's folder."""

    kind: ClassVar[str] = "emulator"
    results: Path = field(metadata={"expected": 'a path to a sweep results folder: results = "<folder>"'})
    surrogate: Literal["gp", "rbf"] = "gp"
    confirm: int = 100
    steps: int = 5000

    def __post_init__(self):
        super().__post_init__()
        check_at_least("confirm", self.confirm, 0)
        if self.confirm == 1:
            raise ConfigError("confirm", "got 1; use 0 (no confirmation) or >= 2 replicates")


METHODS = {cls.kind: cls for cls in (EmceeSettings, OptimizeSettings, EmulatorSettings)}
