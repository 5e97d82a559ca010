"""Keys and values given by name in a sweep file: swept keys, the bounds of a sampled or sensitivity
block (``key = [low, high]``) and explicit ``[[points]]`` (every swept key once).

Each parser returns canonical keys (:func:`simcore.params.canonical_key`) and raises ConfigError naming
the table and key at fault.
"""
from __future__ import annotations

import math

from simcore.params import canonical_key
from simcore.schema import ConfigError, suggest


def canonical_axis_key(key, where: str) -> str:
    if not isinstance(key, str) or not key:
        raise ConfigError(where, f"got {key!r}; expected a dotted preset key such as 'perception.field_deg'")
    return canonical_key(key)


def parse_bounds(bounds, where_table: str) -> tuple[tuple[str, float, float], ...]:
    """A table of key = [low, high] -> ((canonical key, low, high), ...)."""
    if not isinstance(bounds, dict) or not bounds:
        raise ConfigError(where_table, "expected a table of key = [low, high]")
    out = []
    for key, pair in bounds.items():
        where = f"{where_table}.{key}"
        numbers = isinstance(pair, list) and len(pair) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in pair)
        if not numbers:
            raise ConfigError(where, f"got {pair!r}; expected [low, high] (finite numbers)")
        low, high = map(float, pair)
        if not low < high:
            raise ConfigError(where, f"got {pair!r}; low must be < high")
        out.append((canonical_axis_key(key, where), low, high))
    return tuple(out)


def parse_points(points: tuple[dict, ...], axes: tuple, keys: list[str]) -> tuple[dict, ...]:
    """``[[points]]``: each a table giving every swept key once (canonical keys); a labelled axis'
    value must be one of its values (it takes that value's label)."""
    out = []
    for i, point in enumerate(points):
        where = f"points[{i}]"
        given = {}
        for key, value in point.items():
            canonical = canonical_axis_key(key, where)
            if canonical not in keys:
                raise ConfigError(f"{where}.{key}", f"not a swept key{suggest(canonical, keys)}; a point gives a "
                                                    f"value to each swept key: {', '.join(keys)}")
            given[canonical] = value
        missing = [k for k in keys if k not in given]
        if missing:
            raise ConfigError(where, f"missing swept key(s) {', '.join(missing)}; a point gives a value to each "
                                     f"swept key: {', '.join(keys)}")
        for axis in axes:
            if axis.labels and tuple(given[k] for k in axis.keys) not in axis.points:
                raise ConfigError(f"{where}.{axis.keys[0]}", f"got {given[axis.keys[0]]!r}; axis {axis.name!r} is "
                                                             f"labelled, so a point takes one of its values "
                                                             f"{[p[0] if len(p) == 1 else list(p) for p in axis.points]}")
        out.append(given)
    return tuple(out)
