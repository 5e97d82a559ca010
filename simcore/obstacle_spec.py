"""Obstacles as data: one validated, frozen record per obstacle, and the flat table the kernel reads.

A preset lists obstacles as ``[[world.obstacles]]`` tables. Each has a ``kind`` and exactly the keys of
that kind (lengths in world units):

========== ============================================ ===============================================
kind       keys                                         solid it describes
========== ============================================ ===============================================
sphere     ``centre``, ``radius``                       ball |x - centre| <= radius
plane      ``centre``, ``normal``                       half-space n . (x - centre) <= 0: the solid side
                                                        is behind the plane, ``normal`` points to the
                                                        free side (a ground, a wall); ``centre`` is any
                                                        point of the plane (drawings centre a patch on it)
box        ``centre``, ``half_extents``                 axis-aligned box |x_i - centre_i| <= half_i
cylinder   ``centre``, ``axis``, ``radius``, ``length`` capped solid cylinder: axial coordinate
                                                        z = (x - centre) . axis in [-length/2, length/2],
                                                        distance from the axis <= radius
========== ============================================ ===============================================

``normal`` and ``axis`` may point in any direction; they are divided by their length on load (a zero
vector is an error), and a vector whose length is already within 1e-12 of 1 is kept as written, so
loading the canonical form again gives the same bits (:func:`simcore.schema.unit_vector3`). Radii,
lengths and half extents must be finite and > 0. Every check raises :class:`~simcore.schema.ConfigError` naming the key; through
:func:`obstacles_from_dicts` (or ``schema.build`` on a dataclass with a ``tuple[Obstacle, ...]`` field
``obstacles`` under ``world``) the key reads like ``world.obstacles[2].radius``. A key of another kind
(a ``radius`` on a box) is an error naming that key.

:meth:`Obstacle.canonical` is the form for run identity: ``kind`` and that kind's keys only.

:func:`pack_obstacles` turns a tuple of obstacles into ``(table, kinds)``: ``table`` float64
(K, OBSTACLE_COLUMNS) with one row per obstacle, columns named by the ``OBS_*`` constants below (unused
columns of a kind are 0), and ``kinds`` int64 (K,) with the ``KIND_*`` codes. The compiled geometry
(:mod:`simcore.obstacles`) reads nothing else.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from .schema import ConfigError, build, check_positive, check_vector3, suggest, unit_vector3

OBSTACLE_KINDS = ("sphere", "plane", "box", "cylinder")
KIND_SPHERE, KIND_PLANE, KIND_BOX, KIND_CYLINDER = range(4)

# keys each kind takes, besides ``kind``, in the order of the canonical form
KIND_KEYS = {
    "sphere": ("centre", "radius"),
    "plane": ("centre", "normal"),
    "box": ("centre", "half_extents"),
    "cylinder": ("centre", "axis", "radius", "length"),
}

# columns of the packed table, declared once: name -> slot
COLUMN_NAMES = ("centre_x", "centre_y", "centre_z", "radius", "normal_x", "normal_y", "normal_z",
                "half_x", "half_y", "half_z", "axis_x", "axis_y", "axis_z", "half_length", "bound_radius")
(OBS_CX, OBS_CY, OBS_CZ, OBS_RADIUS, OBS_NX, OBS_NY, OBS_NZ, OBS_HX, OBS_HY, OBS_HZ,
 OBS_AX, OBS_AY, OBS_AZ, OBS_HALF_LENGTH, OBS_BOUND, OBSTACLE_COLUMNS) = range(len(COLUMN_NAMES) + 1)
assert OBSTACLE_COLUMNS == len(COLUMN_NAMES)

@dataclass(frozen=True)
class Obstacle:
    """One obstacle (see the module docstring for the keys of each kind and the solid they describe)."""

    kind: str
    centre: tuple[float, ...] | None = None
    radius: float | None = None
    normal: tuple[float, ...] | None = None
    half_extents: tuple[float, ...] | None = None
    axis: tuple[float, ...] | None = None
    length: float | None = None

    def __post_init__(self):
        if self.kind not in OBSTACLE_KINDS:
            raise ConfigError("kind", f"got {self.kind!r}; allowed: {', '.join(map(repr, OBSTACLE_KINDS))}"
                              + suggest(str(self.kind), OBSTACLE_KINDS))
        wanted = KIND_KEYS[self.kind]
        article = "an" if self.kind[0] in "aeiou" else "a"
        for name in (f.name for f in fields(self) if f.name != "kind"):
            if name not in wanted and getattr(self, name) is not None:
                raise ConfigError(name, f"does not apply to kind '{self.kind}' ({article} {self.kind} takes "
                                        f"{', '.join(wanted)})")
        for name in wanted:
            if getattr(self, name) is None:
                raise ConfigError(name, f"missing key; {article} {self.kind} needs: {', '.join(wanted)}")
        object.__setattr__(self, "centre", check_vector3("centre", self.centre))
        if self.radius is not None:
            check_positive("radius", self.radius)
        if self.length is not None:
            check_positive("length", self.length)
        if self.normal is not None:
            object.__setattr__(self, "normal", unit_vector3("normal", self.normal))
        if self.axis is not None:
            object.__setattr__(self, "axis", unit_vector3("axis", self.axis))
        if self.half_extents is not None:
            half = check_vector3("half_extents", self.half_extents)
            for i, value in enumerate(half):
                if not value > 0.0:
                    raise ConfigError("half_extents", f"got {list(half)!r}; component {i} is {value!r}, every "
                                                      "half extent must be > 0")
            object.__setattr__(self, "half_extents", half)

    def canonical(self) -> dict:
        """Plain dict with ``kind`` and this kind's keys only (vectors as lists): the run-identity form."""
        out = {"kind": self.kind}
        for name in KIND_KEYS[self.kind]:
            value = getattr(self, name)
            out[name] = list(value) if isinstance(value, tuple) else value
        return out

    @property
    def bound_radius(self) -> float:
        """Radius of a ball about ``centre`` containing the solid (infinite for a plane)."""
        if self.kind == "sphere":
            return self.radius
        if self.kind == "box":
            return math.hypot(*self.half_extents)
        if self.kind == "cylinder":
            return math.hypot(self.radius, self.length / 2.0)
        return math.inf


def obstacle_from_dict(data: dict, path: str = "obstacle") -> Obstacle:
    """Validated :class:`Obstacle` from one parsed TOML table; errors are keyed ``<path>.<key>``."""
    if not isinstance(data, dict):
        raise ConfigError(path, f"expected a table with a 'kind' key, got {data!r}")
    return build(Obstacle, data, path)


def obstacles_from_dicts(items, path: str = "world.obstacles") -> tuple[Obstacle, ...]:
    """Validated obstacles from a parsed ``[[world.obstacles]]`` array (``path[i].key`` in errors)."""
    if not isinstance(items, (list, tuple)):
        raise ConfigError(path, f"expected an array of tables ([[{path}]]), got {items!r}")
    return tuple(obstacle_from_dict(item, f"{path}[{i}]") for i, item in enumerate(items))


def canonical_obstacles(obstacles) -> list[dict]:
    """Run-identity form of a tuple of obstacles, in their order (order breaks ties between hits)."""
    return [obstacle.canonical() for obstacle in obstacles]


def pack_obstacles(obstacles) -> tuple[np.ndarray, np.ndarray]:
    """``(table, kinds)`` for the compiled geometry (see the module docstring for the layout)."""
    table = np.zeros((len(obstacles), OBSTACLE_COLUMNS), dtype=np.float64)
    kinds = np.zeros(len(obstacles), dtype=np.int64)
    for row, obstacle in enumerate(obstacles):
        kinds[row] = OBSTACLE_KINDS.index(obstacle.kind)
        table[row, OBS_CX:OBS_CZ + 1] = obstacle.centre
        table[row, OBS_BOUND] = obstacle.bound_radius
        if obstacle.radius is not None:
            table[row, OBS_RADIUS] = obstacle.radius
        if obstacle.normal is not None:
            table[row, OBS_NX:OBS_NZ + 1] = obstacle.normal
        if obstacle.half_extents is not None:
            table[row, OBS_HX:OBS_HZ + 1] = obstacle.half_extents
        if obstacle.axis is not None:
            table[row, OBS_AX:OBS_AZ + 1] = obstacle.axis
        if obstacle.length is not None:
            table[row, OBS_HALF_LENGTH] = obstacle.length / 2.0
    return table, kinds
