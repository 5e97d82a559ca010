"""Sensitivity-analysis designs: a sweep's ``[design]`` table, sampled through SALib.

A ``[design]`` block is one more factor of the sweep's product, like ``[sample]`` (the two exclude each
other), whose points are the rows of a sensitivity-analysis sample over ``bounds``::

    [design]
    kind = "saltelli"          # Sobol' indices: Saltelli's scheme on a scrambled Sobol' sequence
    n = 256                    # base sample size N, a power of 2
    second_order = false       # true adds the second-order indices (N (2d + 2) rows instead of N (d + 2))
    bounds = { "perception.field_deg" = [30, 180], "perception.direction_deg" = [0, 90] }

    [design]
    kind = "morris"            # elementary effects (Morris 1991; Campolongo et al. 2007)
    trajectories = 20          # r one-at-a-time trajectories of d + 1 points each
    levels = 4                 # grid levels p per factor (even)
    bounds = { ... }

Contract
--------
``DesignTable`` is the table as written (read by :func:`simcore.schema.build`; its own checks name the
key); ``sweeps.config`` turns it into a :class:`SensitivityDesign` (bounds parsed like ``[sample]``'s).

``SensitivityDesign.sample(seed) -> (rows, d)`` is the SALib sample in SALib's row order
(``SALib.sample.sobol.sample`` or ``SALib.sample.morris.sample``), drawn from
``generator(seed, Tag.DESIGN_SENSITIVITY)`` (:mod:`sweeps.seeds`): the same sweep seed gives the same
rows. ``rows(seed, integer)`` rounds the keys flagged integer (e.g. ``init.n``). Rows that coincide
after rounding are one design point (run once per replicate, :func:`unique_rows`); the analysis maps
every row back to its point by its values, so SALib's estimators see the full sample.

``SensitivityDesign.problem()`` is SALib's problem dict; ``rows_count`` the sample's length.
Importing this module does not import SALib.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from flocksweep.simcore.schema import ConfigError, check_at_least

from .seeds import Tag, generator

KINDS = ("saltelli", "morris")
MAX_BASE = 1 << 20   # Saltelli's n, Morris' trajectories: checked before SALib allocates anything


@dataclass(frozen=True, kw_only=True)
class DesignTable:
    """``[design]`` as written (see the module docstring)."""

    kind: Literal["saltelli", "morris"] = field(metadata={"expected": '"saltelli" or "morris"'})
    bounds: Any = None
    n: int | None = None
    second_order: bool = False
    scramble: bool = True
    trajectories: int | None = None
    levels: int = 4

    def __post_init__(self):
        if self.kind == "saltelli":
            if self.n is None:
                raise ConfigError("n", "missing: a Saltelli design needs the base sample size n (a power of 2, "
                                       "e.g. 256; the sweep runs n x (d + 2) points)")
            check_at_least("n", self.n, 2)
            if self.n > MAX_BASE:
                raise ConfigError("n", f"got {self.n:,}; a Saltelli design here takes n up to {MAX_BASE:,} (n x (d + 2) "
                                       "runs; larger samples would not fit in memory): use a smaller n or split the "
                                       "study")
            if self.n & (self.n - 1):
                lower = 1 << (self.n.bit_length() - 1)
                raise ConfigError("n", f"got {self.n}; the Sobol' sequence behind a Saltelli design needs a power "
                                       f"of 2 (e.g. {lower} or {2 * lower})")
            for key in ("trajectories",):
                if getattr(self, key) is not None:
                    raise ConfigError(key, 'only for kind = "morris"')
        else:
            if self.trajectories is None:
                raise ConfigError("trajectories", "missing: a Morris design needs the number of trajectories "
                                                  "(e.g. 20; the sweep runs trajectories x (d + 1) points)")
            check_at_least("trajectories", self.trajectories, 2)
            if self.trajectories > MAX_BASE:
                raise ConfigError("trajectories", f"got {self.trajectories:,}; a Morris design here takes up to "
                                                  f"{MAX_BASE:,} trajectories: use fewer or split the study")
            check_at_least("levels", self.levels, 2)
            if self.levels % 2:
                raise ConfigError("levels", f"got {self.levels}; use an even number of grid levels (e.g. 4 or 6) "
                                            "so every step is half the grid and the levels are sampled evenly")
            if self.n is not None or self.second_order:
                raise ConfigError("n" if self.n is not None else "second_order", 'only for kind = "saltelli"')


@dataclass(frozen=True)
class SensitivityDesign:
    """A parsed ``[design]``: ``bounds`` are (key, low, high) in the table's order."""

    kind: str
    bounds: tuple[tuple[str, float, float], ...]
    n: int | None = None
    second_order: bool = False
    scramble: bool = True
    trajectories: int | None = None
    levels: int = 4

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(key for key, _, _ in self.bounds)

    @property
    def d(self) -> int:
        return len(self.bounds)

    @property
    def rows_count(self) -> int:
        if self.kind == "saltelli":
            return self.n * ((2 * self.d + 2) if self.second_order else (self.d + 2))
        return self.trajectories * (self.d + 1)

    def problem(self) -> dict:
        """SALib's problem definition."""
        return {"num_vars": self.d, "names": list(self.keys), "bounds": [[lo, hi] for _, lo, hi in self.bounds]}

    def sample(self, seed: int) -> np.ndarray:
        """(rows_count, d) SALib sample, deterministic in the sweep ``seed``."""
        rng = generator(seed, Tag.DESIGN_SENSITIVITY)
        if self.kind == "saltelli":
            from SALib.sample import sobol  # imported here: SALib loads scipy.stats and more

            return np.asarray(sobol.sample(self.problem(), self.n, calc_second_order=self.second_order,
                                           scramble=self.scramble, seed=rng), dtype=float)
        from SALib.sample import morris

        return np.asarray(morris.sample(self.problem(), self.trajectories, num_levels=self.levels, seed=rng),
                          dtype=float)

    def rows(self, seed: int, integer) -> list[tuple]:
        """The sample's rows as tuples of values, keys flagged ``integer`` rounded."""
        return [tuple(int(round(v)) if is_int else float(v) for v, is_int in zip(row, integer))
                for row in self.sample(seed)]

    def record(self) -> dict:
        """JSON-ready description (``describe`` of the sweep)."""
        out = {"kind": self.kind, "bounds": {k: [lo, hi] for k, lo, hi in self.bounds}, "rows": self.rows_count}
        if self.kind == "saltelli":
            out.update(n=self.n, second_order=self.second_order)
        else:
            out.update(trajectories=self.trajectories, levels=self.levels)
        return out


def unique_rows(rows: list[tuple]) -> list[tuple]:
    """The distinct rows in order of first appearance (the design points of the block)."""
    seen, out = set(), []
    for row in rows:
        if row not in seen:
            seen.add(row)
            out.append(row)
    return out
