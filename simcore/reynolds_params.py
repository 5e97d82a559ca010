"""The ``reynolds87`` dynamics' descriptor (:mod:`simcore.registry`): its ``[reynolds]`` table and capabilities
(sphere perception, obstacles, 2-D motion; no change of leadership or pattern mode); its hooks are
:mod:`simcore.reynolds87` (docs/model.md, Reynolds 1987).

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

from .plugin import PluginParams, parameter
from .schema import ConfigError, check_choice, to_dict, unit_vector3

ALLOCATIONS = ("priority", "priority_magnitude", "weighted_sum")
MIGRATION_WHO = ("all", "front")


TABLE = "reynolds"
HOOKS = ".reynolds87"
PLANAR = True
OBSTACLES = True
PERCEPTION = "sphere"
PATTERNS = False
THREADS = False


def separation_length_power(data: dict) -> float:
    """The power of length of the separation weight: 1 + the falloff exponent the preset's data gives."""
    value = data.get("reynolds", {}).get("falloff_exponent", 2.0)
    return 1.0 + (float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else 2.0)


@dataclass(frozen=True)
class Reynolds(PluginParams):
    """Reynolds (1987) requests, priority allocation, speed limits, steer-to-avoid and migratory urge."""

    TABLE = "reynolds"
    falloff_exponent: float = parameter(2.0, low=0.0, high=4.0, length=0, doc="k, the distance falloff")
    allocation: str = parameter("priority", doc=f"one of {ALLOCATIONS}")
    max_accel: float = parameter(16.0, unit="units/s^2", low=0.0, low_open=True, length=1,
                                 doc="the acceleration budget")
    min_speed: float = parameter(3.0, unit="units/s", low=0.0, length=1, doc="the lower speed clamp")
    max_speed: float = parameter(6.0, unit="units/s", low=0.0, low_open=True, length=1, doc="the upper speed clamp")
    obstacle_weight: float = parameter(16.0, unit="units/s^2", low=0.0, length=1, doc="w_o")
    separation_weight: float = parameter(6.0, unit="units^(1+k)/s^2", low=0.0, length=separation_length_power,
                                         doc="w_s")
    alignment_weight: float = parameter(3.0, unit="1/s", low=0.0, length=0, doc="w_a")
    cohesion_weight: float = parameter(3.0, unit="1/s^2", low=0.0, length=0, doc="w_c")
    lookahead: float = parameter(10.0, unit="world units", low=0.0, low_open=True, length=1,
                                 doc="how far ahead obstacles are looked for")
    avoid_margin: float = parameter(1.0, unit="world units", low=0.0, length=1, doc="clearance kept from obstacles")
    body_radius: float = parameter(0.5, unit="world units", low=0.0, low_open=True, length=1,
                                   doc="the body radius of steer-to-avoid and of collisions")
    migration_direction: tuple[float, ...] = parameter((1.0, 0.0, 0.0), length=0,
                                                       doc="the migratory goal's direction (made unit)")
    migration_weight: float = parameter(0.0, unit="units/s^2", low=0.0, length=1, doc="w_m; 0: no migration")
    migration_who: str = parameter("all", doc=f"one of {MIGRATION_WHO}")

    def __post_init__(self):
        super().__post_init__()
        check_choice("reynolds.allocation", self.allocation, ALLOCATIONS)
        if self.min_speed > self.max_speed:
            raise ConfigError("reynolds.min_speed", f"got {self.min_speed!r}; must be <= reynolds.max_speed "
                                                    f"({self.max_speed!r})")
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


Params = Reynolds


def check(model) -> None:
    """No change of leadership; in 2-D the migratory goal lies in the plane (ConfigError naming the key)."""
    if model.world.dimensions == 2 and model.reynolds.migration_weight > 0.0 \
            and model.reynolds.migration_direction[2] != 0.0:
        raise ConfigError("reynolds.migration_direction", f"got {list(model.reynolds.migration_direction)!r}; "
                                                          "with world.dimensions = 2 the migratory goal lies in "
                                                          "the plane: its z must be 0")


def canonical(table: Reynolds) -> dict:
    return table.canonical()


def body_radius(model) -> float:
    """Obstacle collisions are measured with ``reynolds.body_radius``."""
    return float(model.reynolds.body_radius)


def migration(model) -> tuple[float, float, float] | None:
    """The migratory urge's unit direction when it is on in an open world, else None."""
    rey = model.reynolds
    if not rey.migrates or model.world.boundary != "open":
        return None
    return tuple(float(x) for x in rey.migration_direction)
