"""Typed settings of each calibration method: the ``[method]`` table of a calibration file, read by the
schema engine (:func:`simcore.schema.build`) into :class:`EmceeSettings`, :class:`OptimizeSettings`
or :class:`EmulatorSettings` or :class:`NpeSettings` by its ``kind`` (each the ``settings`` of a registered
method, :mod:`analysis.calibration.methods`). Each checks its own ranges; :mod:`analysis.calibration.method_table`
adds the checks that need the rest of the file (``n_sim`` against the number of statistics, then the
method's ``resolve``: ``walkers`` against the number of parameters, ``results`` resolved against the file's
folder). A method of one's own subclasses :class:`MethodSettings` with its ``kind``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Literal

from flocksweep.simcore.schema import ConfigError, check_at_least

from .learned_inputs import SummarySettings
from .npe_flow import FlowSettings


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
    until_converged: bool = False   # steps is then a cap: stop at >= 50 tau, R-hat <= 1.01, ESS >= 400
    check_every: int = 50           # ... judged after every this many steps

    def __post_init__(self):
        super().__post_init__()
        check_at_least("reevaluate_every", self.reevaluate_every, 0)
        check_at_least("check_every", self.check_every, 2)


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
class RefineSettings:
    """The emulator's sequential design (analysis.calibration.refine): at most ``rounds`` rounds of
    ``runs_per_round`` new sweep runs (``runs_per_round / replicates`` new points of the sweep's
    replicates each); 0 rounds: none. The rounds stop once the confirmation passes and the emulator's
    variance is at most ``max_emulator_share`` of the likelihood's over the posterior."""

    rounds: int = 0
    runs_per_round: int = 50
    max_emulator_share: float = 0.1

    def __post_init__(self):
        check_at_least("rounds", self.rounds, 0)
        check_at_least("runs_per_round", self.runs_per_round, 1)
        if not self.max_emulator_share > 0:
            raise ConfigError("max_emulator_share", f"got {self.max_emulator_share}; expected a share > 0 "
                                                    "(e.g. 0.1: the emulator adds at most 10 % to the variance)")


@dataclass(frozen=True, kw_only=True)
class EmulatorSettings(ChainSettings):
    """Emcee on a surrogate fitted to a sweep's results (analysis.calibration.training, .surrogates,
    .emulated); ``results`` is resolved against the calibration file's folder."""

    kind: ClassVar[str] = "emulator"
    results: Path = field(metadata={"expected": 'a path to a sweep results folder: results = "<folder>"'})
    surrogate: Literal["gp", "rbf"] = "gp"
    confirm: int = 100
    steps: int = 5000
    refine: RefineSettings = field(default_factory=RefineSettings)

    def __post_init__(self):
        super().__post_init__()
        check_at_least("confirm", self.confirm, 0)
        if self.confirm == 1:
            raise ConfigError("confirm", "got 1; use 0 (no confirmation) or >= 2 replicates")
        if self.refine.rounds and not self.confirm:
            raise ConfigError("refine.rounds", "refinement stops when the confirmation at the posterior median "
                                               "passes: set confirm >= 2 (e.g. 50) or rounds = 0")


@dataclass(frozen=True, kw_only=True)
class NpeSettings(MethodSettings):
    """Neural posterior estimation (analysis.calibration.npe): ``simulations`` prior draws run as a sweep
    train a conditional flow, ``heldout`` more check its coverage; ``draws`` posterior draws at the
    targets. ``ensemble``: the estimator is a mixture of this many flows trained with different seeds
    (analysis.calibration.npe_flow.train_ensemble; less over-confident than one flow). ``rounds``: R > 1
    runs R truncated sequential rounds of ``simulations`` each (analysis.calibration.npe_rounds), each
    later round's region leaving out ``truncation`` of the estimator's posterior mass. ``estimator``: a
    folder holding a trained estimator to reuse (resolved against the file's folder); by default the output
    folder's ``estimator/``. ``summary``: ``[method.npe.summary]``, the flow conditioned on the
    statistics alone (default) or also on a summary it learns (analysis.calibration.learned_inputs). ``n_sim`` and
    ``likelihood`` are unused."""

    kind: ClassVar[str] = "npe"
    simulations: int = 1000
    heldout: int = 200
    draws: int = 4000
    coverage_tolerance: float = 0.05
    flow: FlowSettings = field(default_factory=FlowSettings)   # [method.npe] flow = {width = 50, ...}
    summary: SummarySettings = field(default_factory=SummarySettings)   # [method.npe.summary]: learned or not
    ensemble: int = 1
    rounds: int = 1
    truncation: float = 1e-4   # rounds > 1: the share of the estimator's posterior mass left outside each region
    estimator: Path | None = None

    def __post_init__(self):
        super().__post_init__()
        check_at_least("simulations", self.simulations, 20)
        check_at_least("heldout", self.heldout, 10)
        check_at_least("draws", self.draws, 100)
        check_at_least("ensemble", self.ensemble, 1)
        check_at_least("rounds", self.rounds, 1)
        if self.rounds > 1 and self.estimator is not None:
            raise ConfigError("estimator", f"got {str(self.estimator)!r} with rounds = {self.rounds}: an estimator of "
                                           "sequential rounds is trained for one flock's targets and is not reused "
                                           "elsewhere; remove estimator or use rounds = 1")
        if not 0 < self.coverage_tolerance < 0.5:
            raise ConfigError("coverage_tolerance", f"got {self.coverage_tolerance}; expected a share in (0, 0.5)")
        if not 0 < self.truncation <= 0.1:
            raise ConfigError("truncation", f"got {self.truncation}; expected the share of posterior mass each round's "
                                            "region leaves out, in (0, 0.1] (default 1e-4)")

