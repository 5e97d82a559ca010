"""The tables of claims (what a ``[[claims]]`` table may hold, read by the schema engine) and the
resolved, validated tree the statistics work on (:class:`Test`, :class:`Claim`). Data only: reading,
validating and storing claims is :mod:`sweeps.claims`, which documents the keys.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pandas as pd

from flocksweep.simcore.schema import ConfigError, check_at_least, check_within

from .expressions import Expression

KINDS = ("trend", "compare", "sign", "all_of", "any_of")
KEYS = {"trend": ("metric", "factor", "direction", "method", "effect"),
        "compare": ("metric", "lower", "higher", "paired", "method", "effect"),
        "sign": ("metric", "direction", "value", "tolerance", "method", "effect"),
        "all_of": ("parts",), "any_of": ("parts",)}
REQUIRED = {"trend": ("metric", "factor", "direction"), "compare": ("metric", "lower", "higher"),
            "sign": ("metric", "direction"), "all_of": ("parts",), "any_of": ("parts",)}
DIRECTIONS = {"trend": ("increasing", "decreasing"), "sign": ("positive", "negative", "zero")}
METHODS = {"trend": ("spearman",), "compare": ("mann-whitney", "welch"), "sign": ("wilcoxon", "sign", "t")}
COMMON = ("test", "id", "label", "condition")
ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


# ------------------------------------------------------------------------------------------ the tables

@dataclass(frozen=True)
class Source:
    """Where a claim is stated."""

    paper: str = field(metadata={"expected": "a string naming the paper, e.g. \"Holland & Semwal\""})
    section: str = ""
    quote: str = ""


@dataclass(frozen=True)
class PowerTable:
    """The power analysis of a claim's tests (analysis/reports/claims/power.py)."""

    target: float = 0.8
    simulations: int = 200
    max_replicates: int = 200

    def __post_init__(self):
        check_within("target", self.target, 0.0, 1.0, lo_open=True)
        if self.target >= 1.0:
            raise ConfigError("target", f"got {self.target!r}; must be < 1")
        check_at_least("simulations", self.simulations, 20)
        check_at_least("max_replicates", self.max_replicates, 2)


@dataclass(frozen=True)
class TestTable:
    """One test as written: a leaf (trend, compare, sign) or a composition of parts (see the module
    docstring for which keys each kind takes)."""

    __test__ = False  # not a pytest test class

    test: Literal["trend", "compare", "sign", "all_of", "any_of"] = field(
        default=None, metadata={"expected": "one of trend, compare, sign, all_of, any_of"})
    id: str | None = None
    label: str = ""
    condition: str | None = None
    metric: str | None = None
    factor: str | None = None
    direction: str | None = None
    lower: str | None = None
    higher: str | None = None
    paired: bool = False
    value: float = 0.0
    tolerance: float = 0.0
    method: str | None = None
    effect: float | None = None
    parts: tuple[TestTable, ...] = field(default=(), metadata={"expected": "an array of tests: [[claims.parts]]"})


@dataclass(frozen=True, kw_only=True)
class ClaimTable(TestTable):
    """One ``[[claims]]`` table: a test plus what the claim is, where it is stated and how it is judged."""

    statement: str = field(default=None, metadata={"expected": "the claim as one sentence"})
    source: Source | None = None
    family: str = "default"
    alpha: float = 0.05
    power: PowerTable = field(default_factory=PowerTable)


@dataclass(frozen=True)
class IncludeTable:
    file: str = field(metadata={"expected": "a path to a claims file"})
    only: tuple[str, ...] | None = None


@dataclass(frozen=True)
class ClaimsFile:
    """A shared claims file: a description and ``[[claims]]``."""

    claims: tuple[ClaimTable, ...] = field(metadata={"expected": "an array of tables: [[claims]]"})
    description: str = ""


# ------------------------------------------------------------------------------------- the resolved tree

@dataclass(frozen=True)
class Test:
    """A validated test: ``conditions`` are its own and its parents' (all must hold); ``path`` is
    ``claim id`` or ``claim id.part id...``; ``key`` the config key it was declared at."""

    __test__ = False

    kind: str
    path: str
    label: str
    key: str
    conditions: tuple[Expression, ...] = ()
    metric: Expression | None = None
    factor: str | None = None
    direction: str | None = None
    lower: Expression | None = None
    higher: Expression | None = None
    paired: bool = False
    value: float = 0.0
    tolerance: float = 0.0
    method: str | None = None
    effect: float | None = None
    parts: tuple[Test, ...] = ()

    @property
    def composite(self) -> bool:
        return self.kind in ("all_of", "any_of")

    def leaves(self) -> list[Test]:
        return [leaf for part in self.parts for leaf in part.leaves()] if self.composite else [self]

    def select(self, frame: pd.DataFrame) -> np.ndarray:
        """Rows of ``frame`` meeting every condition."""
        mask = np.ones(len(frame), dtype=bool)
        for condition in self.conditions:
            mask &= condition.evaluate(frame)
        return mask

    @property
    def claimed_sign(self) -> int:
        """+1 when the claim says the metric rises (increasing, positive, higher group), -1 falls, 0 zero."""
        return {"decreasing": -1, "negative": -1, "zero": 0}.get(self.direction, 1)


@dataclass(frozen=True)
class Claim:
    id: str
    statement: str
    source: Source | None
    family: str
    alpha: float
    power: PowerTable
    test: Test
    table: ClaimTable = field(repr=False)
    origin: str = ""     # the claims file it came from ("" for the sweep file itself)
