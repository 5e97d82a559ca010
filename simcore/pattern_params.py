"""Holland and Semwal's pattern recognition parameters: the ``[patterns]`` table of a model preset
(docs/model.md, patterns), re-exported by :mod:`simcore.params`."""
from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import ConfigError, check_choice as _choice, check_within as _within

SEPARATION_WEIGHTS = ("similarity", "dissimilarity", "uniform")


@dataclass(frozen=True)
class PatternEntry:
    """One pattern of the set: a bit string (most significant bit first) and its share of the flock."""

    bits: str
    fraction: float

    def __post_init__(self):
        if not (1 <= len(self.bits) <= 32) or set(self.bits) - {"0", "1"}:
            raise ConfigError("bits", f"got {self.bits!r}; must be a string of 1 to 32 characters 0/1")
        _within("fraction", self.fraction, 0.0, 1.0)

    @property
    def value(self) -> int:
        return int(self.bits, 2)


HOLLAND_TABLE_1 = (
    PatternEntry("00000000", 0.35),
    PatternEntry("00111010", 0.35),
    PatternEntry("11000101", 0.15),
    PatternEntry("11111111", 0.15),
)


@dataclass(frozen=True)
class Patterns:
    """Holland's pattern recognition (docs/model.md, patterns)."""

    enabled: bool = False
    separation_weight: str = "similarity"
    set: tuple[PatternEntry, ...] = HOLLAND_TABLE_1

    def __post_init__(self):
        _choice("patterns.separation_weight", self.separation_weight, SEPARATION_WEIGHTS)
        if not self.set:
            raise ConfigError("patterns.set", "must name at least one pattern")
        lengths = {len(p.bits) for p in self.set}
        if len(lengths) != 1:
            raise ConfigError("patterns.set", f"all patterns must have the same length, got {sorted(lengths)}")
        total = math.fsum(p.fraction for p in self.set)
        if abs(total - 1.0) > 1e-9:
            raise ConfigError("patterns.set", f"fractions sum to {total!r}; they must sum to 1")

    @property
    def n_bits(self) -> int:
        return len(self.set[0].bits)
