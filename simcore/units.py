"""The units a preset file is written in: body lengths (the simulator's own) or metres (docs/model.md section 12).

The simulator's length unit is the body length (BL: a boid's body radius is 0.5), its time unit the
second. A preset file may instead state its lengths in metres with a ``[units]`` table::

    [units]
    length = "m"            # "bl" (default): body lengths; "m": metres
    body_length_m = 0.3     # the species' body length in metres (required with length = "m")

:func:`to_body_lengths` then divides every value that carries length by ``body_length_m`` to the power
it carries (:data:`LENGTH_POWER`: 1 for a length, a speed or an acceleration; the separation weights,
whose request sums ``d / |d|^k``, carry ``1 + k`` in Reynolds 1987 and ``k`` in Hartman-Beneš), before
the model is validated: a preset in metres and its twin in body lengths are the same :class:`Preset`,
bit for bit. Times, angles, counts and dimensionless gains are unchanged (:data:`NO_LENGTH`). Only the
file (and ``--set`` overrides of it) is in metres: the loaded preset, ``Preset.replace`` and sweep values
are in body lengths. The shared keys' powers are listed here; a dynamics' own keys declare theirs where
they are declared (``parameter(..., length=...)`` in its descriptor, :mod:`simcore.registry`). Tables this
module does not convert (a dynamics' table whose keys declare no power, ``world.obstacles``, a plug-in's
``[plugin]``) are refused in a file in metres, naming the key. ``tests/simcore/test_units.py`` checks that every numeric key of the
model is classified here.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .schema import ConfigError, check_choice, check_positive

LENGTH_UNITS = ("bl", "m")


@dataclass(frozen=True)
class Units:
    """The ``[units]`` table: ``length`` ("bl" or "m") and ``body_length_m`` (metres; required for "m")."""

    length: str = "bl"
    body_length_m: float | None = None

    def __post_init__(self):
        check_choice("units.length", self.length, LENGTH_UNITS)
        if self.body_length_m is not None:
            check_positive("units.body_length_m", self.body_length_m)
        elif self.length == "m":
            raise ConfigError("units.body_length_m", "required with units.length = 'm': the body length of "
                                                     "the species in metres (e.g. 0.3 for a homing pigeon)")


# the shared keys (every model's): dotted key -> the power of length it carries
SHARED_LENGTH_POWER = {
    **{f"perception.{k}": 1 for k in ("radius", "near_radius", "separation_radius", "alignment_radius",
                                      "cohesion_radius", "range", "head_radius", "body_radius", "max_distance")},
    "vehicle.max_speed": 1, "vehicle.max_force": 1,
    "world.sphere_radius": 1, "world.box_size": 1,
    "leadership.slow_speed": 1,
    "noise.speed_sd": 1,
    "cruise.speed": 1,
    "init.radius": 1, "init.speed": 1,
}

# the shared numeric keys that carry no length: times, angles, cosines, counts, dimensionless gains
SHARED_NO_LENGTH = {
    *(f"perception.{k}" for k in ("separation_cos", "alignment_cos", "cohesion_cos", "direction_deg",
                                  "eye_position_deg", "field_deg", "neighbours", "blind_deg")),
    "vehicle.mass",
    *(f"leadership.{k}" for k in ("x", "sigma", "duration", "gain", "boost", "refractory")),
    "noise.kappa", "noise.angular_sd_deg", "cruise.tau", "world.dimensions",
    "init.n", "run.duration", "run.dt", "run.record_interval",
}


def declared_powers(table: str, cls) -> dict | None:
    """{dotted key: power} of a dynamics' table whose every field declares its power of length
    (:func:`simcore.plugin.parameter`'s ``length``); None when some field declares none (such a table
    is not converted: a file in metres that holds it is refused)."""
    powers = {f"{table}.{spec.name}": spec.metadata.get("length") for spec in dataclasses.fields(cls)
              if not isinstance(spec.default, (str, bool))}   # choices and flags carry no unit
    return None if any(power is None for power in powers.values()) else powers


def _tables() -> tuple[dict, tuple[str, ...]]:
    """(every converted key's power, the tables refused in metres), from the shared keys, the arena's and
    the registry's."""
    from .arena import Arena
    from .registry import builtin_tables

    powers, refused = {**SHARED_LENGTH_POWER, **declared_powers("arena", Arena)}, []
    for table, cls in builtin_tables().items():
        declared = declared_powers(table, cls)
        if declared is None:
            refused.append(table)
        else:
            powers.update(declared)
    return powers, tuple(refused)


_POWERS, _REFUSED_TABLES = _tables()
# dotted key -> the power of length it carries (a number, or a function of the file's data)
LENGTH_POWER = {key: power for key, power in _POWERS.items() if power != 0}
# numeric keys that carry no length
NO_LENGTH = SHARED_NO_LENGTH | {key for key, power in _POWERS.items() if power == 0}
# what a file in metres may not hold (not converted here): tables whose keys declare no power of length
REFUSED = (*_REFUSED_TABLES, "world.obstacles", "plugin")


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _own_table(dynamics: str) -> str | None:
    """The table of a built-in dynamics (None for any other name: plug-ins are refused by their table)."""
    from .registry import BUILTINS, describe

    return describe(dynamics).table if BUILTINS.get(dynamics) else None


def to_body_lengths(data: dict, units: Units) -> dict:
    """The preset dict ``data`` (model keys, ``init``, ``run``) with every length-carrying value in body
    lengths; unchanged when ``units.length`` is "bl". Values that are not numbers are left for validation."""
    if units.length == "bl":
        return data
    dynamics = data.get("dynamics")
    own = _own_table(dynamics) if isinstance(dynamics, str) else None
    for table in _REFUSED_TABLES:
        if table in data or own == table:
            raise ConfigError("units.length", f"got 'm', but the [{table}] keys are not converted from metres: "
                                              "state this model in body lengths (units.length = 'bl')")
    if "plugin" in data:
        raise ConfigError("units.length", "got 'm', but a plug-in dynamics' [plugin] keys are not converted from "
                                          "metres (their units are the plug-in's): state this model in body lengths "
                                          "(units.length = 'bl')")
    if isinstance(data.get("world"), dict) and data["world"].get("obstacles"):
        raise ConfigError("units.length", "got 'm', but world.obstacles are not converted from metres: state "
                                          "this model in body lengths (units.length = 'bl')")
    scale = units.body_length_m
    out = {key: dict(value) if isinstance(value, dict) else value for key, value in data.items()}
    for dotted, power in LENGTH_POWER.items():
        table, key = dotted.split(".")
        section = out.get(table)
        if not isinstance(section, dict) or key not in section:
            continue
        value = section[key]
        exponent = power(data) if callable(power) else power
        if _is_number(value):
            section[key] = value / scale ** exponent
        elif isinstance(value, list) and value and all(_is_number(v) for v in value):   # a point: [x, y, z]
            section[key] = [v / scale ** exponent for v in value]
    return out
