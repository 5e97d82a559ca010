"""The ``[reynolds]`` table of a preset: parameters of the ``reynolds87`` dynamics (docs/model.md, Reynolds 1987).

:class:`Reynolds` is frozen and validated on construction (ConfigError naming ``reynolds.<key>``, the bad
value and what is allowed). Lengths in world units, times in seconds; request weights turn each request
into an acceleration (units/s^2), so ``max_accel`` budgets them directly:

* separation  w_s * sum_j -d_j/|d_j| |d_j|^-k           (w_s in units^(1+k)/s^2)
* alignment   w_a * (sum_j w_j v_j / sum_j w_j - v_i)   (w_a in 1/s)
* cohesion    w_c * sum_j w_j d_j / sum_j w_j           (w_c in 1/s^2)
* obstacle    w_o * (unit steer-to-avoid direction)     (w_o in units/s^2)
* migration   w_m * (unit migration direction)          (w_m in units/s^2; 0 disables it)

with w_j = |d_j|^-k, k = ``falloff_exponent``. ``migration_direction`` is divided by its length on load
(kept as written when already unit within 1e-12, so the canonical form reloads to the same bits:
:func:`simcore.schema.unit_vector3`).
:meth:`Reynolds.canonical` is the run-identity form: the migration keys only when the urge is on.
"""
from __future__ import annotations

from dataclasses import dataclass

from .schema import (ConfigError, check_choice, check_non_negative, check_positive, check_within, to_dict,
                     unit_vector3)

ALLOCATIONS = ("priority", "priority_magnitude", "weighted_sum")
MIGRATION_WHO = ("all", "front")

@dataclass(frozen=True)
class Reynolds:
    """Reynolds (1987) requests, priority allocation, speed limits, steer-to-avoid and migratory urge."""

    falloff_exponent: float = 2.0
    allocation: str = "priority"
    max_accel: float = 16.0
    min_speed: float = 3.0
    max_speed: float = 6.0
    obstacle_weight: float = 16.0
    separation_weight: float = 6.0
    alignment_weight: float = 3.0
    cohesion_weight: float = 3.0
    lookahead: float = 10.0
    avoid_margin: float = 1.0
    body_radius: float = 0.5
    migration_direction: tuple[float, ...] = (1.0, 0.0, 0.0)
    migration_weight: float = 0.0
    migration_who: str = "all"

    def __post_init__(self):
        check_within("reynolds.falloff_exponent", self.falloff_exponent, 0.0, 4.0)
        check_choice("reynolds.allocation", self.allocation, ALLOCATIONS)
        check_positive("reynolds.max_accel", self.max_accel)
        check_non_negative("reynolds.min_speed", self.min_speed)
        check_positive("reynolds.max_speed", self.max_speed)
        if self.min_speed > self.max_speed:
            raise ConfigError("reynolds.min_speed", f"got {self.min_speed!r}; must be <= reynolds.max_speed "
                                                    f"({self.max_speed!r})")
        for name in ("obstacle_weight", "separation_weight", "alignment_weight", "cohesion_weight",
                     "migration_weight"):
            check_non_negative(f"reynolds.{name}", getattr(self, name))
        check_positive("reynolds.lookahead", self.lookahead)
        check_non_negative("reynolds.avoid_margin", self.avoid_margin)
        check_positive("reynolds.body_radius", self.body_radius)
        object.__setattr__(self, "migration_direction",
                           unit_vector3("reynolds.migration_direction", self.migration_direction))
        check_choice("reynolds.migration_who", self.migration_who, MIGRATION_WHO)

    @property
    def migrates(self) -> bool:
        """Whether the migratory urge is on (weight > 0)."""
        return self.migration_weight > 0.0

    def canonical(self) -> dict:
        """Run-identity form: every key, but the migration direction and who only when the urge is on."""
        out = to_dict(self)
        out["migration_direction"] = list(self.migration_direction)
        if not self.migrates:
            del out["migration_direction"], out["migration_who"]
        return out
