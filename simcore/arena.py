"""The ``[arena]`` table of a preset: a tank with walls (docs/model.md section 16), shared by every dynamics.

An arena is a cylinder or a box the flock lives in (``kind``; ``"none"``, the default, is the open world).
In 2-D (``world.dimensions = 2``) a cylinder is a circle and a box a rectangle in the plane z = 0; in 3-D a
cylinder stands along z (with a floor and a ceiling when ``height`` is set, none when it is not) and a box
has six faces. Lengths in world units (converted from metres with the rest of a preset in metres):

* ``centre``        the arena's centre [x, y, z] (z = 0 in 2-D)
* ``radius``        the cylinder's (circle's) radius
* ``height``        the cylinder's full height, centred on ``centre``; unset: unbounded along z (3-D only)
* ``size``          the box's full side lengths [sx, sy, sz] (sz unused in 2-D)
* ``wall_weight``   the wall term's strength: the acceleration a wall gives a boid touching it (units/s^2)
* ``wall_range``    the distance from a wall within which it acts; the term falls linearly to 0 there
* ``reflect``       the fallback: a boid the wall term did not hold is mirrored back inside, its velocity
  reflected off the wall (true by default)

The arena enters a run's identity only when it is on (``kind`` not "none"), so presets without one keep
their run ids (:func:`simcore.params.model_dict`). It needs an open world (``world.boundary = "open"``).
Numba-free: the compiled wall term is :mod:`simcore.walls`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .plugin import PluginParams, parameter
from .schema import ConfigError, check_choice

ARENA_KINDS = ("none", "cylinder", "box")
GEOMETRY = ("kind", "centre", "radius", "height", "size")   # where the walls are (what track files declare)


@dataclass(frozen=True)
class Arena(PluginParams):
    """A tank with walls: a cylinder (circle) or a box (rectangle), its wall term and reflecting fallback."""

    TABLE = "arena"
    kind: str = parameter("none", doc=f"one of {ARENA_KINDS}; none: the open world")
    centre: tuple[float, ...] = parameter((0.0, 0.0, 0.0), unit="world units", length=1, doc="the centre")
    radius: float = parameter(20.0, unit="world units", low=0.0, low_open=True, length=1, doc="cylinder radius")
    height: float | None = parameter(None, unit="world units", length=1, doc="cylinder height; unset: unbounded")
    size: tuple[float, ...] = parameter((40.0, 40.0, 40.0), unit="world units", length=1, doc="box sides")
    wall_weight: float = parameter(20.0, unit="units/s^2", low=0.0, length=1, doc="the wall term's strength")
    wall_range: float = parameter(3.0, unit="world units", low=0.0, low_open=True, length=1,
                                  doc="the distance a wall acts within")
    reflect: bool = parameter(True, doc="mirror a boid that crossed a wall back inside")

    def __post_init__(self):
        super().__post_init__()
        check_choice("arena.kind", self.kind, ARENA_KINDS)
        for name, count in (("centre", 3), ("size", 3)):
            value = getattr(self, name)
            if len(value) != count or not all(math.isfinite(v) for v in value):
                raise ConfigError(f"arena.{name}", f"got {list(value)!r}; expected {count} finite numbers")
        if not all(side > 0.0 for side in self.size):
            raise ConfigError("arena.size", f"got {list(self.size)!r}; every side must be > 0")
        if self.height is not None and not (math.isfinite(self.height) and self.height > 0.0):
            raise ConfigError("arena.height", f"got {self.height!r}; must be a finite number > 0 (or unset)")

    @property
    def enabled(self) -> bool:
        return self.kind != "none"

    def canonical(self) -> dict:
        """Run-identity form: the kind's own keys only (a cylinder's radius and height, a box's size)."""
        out = {"kind": self.kind, "centre": list(self.centre), "wall_weight": self.wall_weight,
               "wall_range": self.wall_range, "reflect": self.reflect}
        if self.kind == "cylinder":
            out["radius"] = self.radius
            if self.height is not None:
                out["height"] = self.height
        else:
            out["size"] = list(self.size)
        return out

    def contains(self, point, dimensions: int = 3) -> bool:
        """Whether ``point`` lies inside (walls included): the start region check and the tests."""
        x, y, z = (float(point[0]) - self.centre[0], float(point[1]) - self.centre[1],
                   float(point[2]) - self.centre[2])
        if self.kind == "cylinder":
            inside = math.hypot(x, y) <= self.radius
            return inside and (dimensions == 2 or self.height is None or abs(z) <= self.height / 2.0)
        axes = 2 if dimensions == 2 else 3
        return all(abs(c) <= side / 2.0 for c, side in zip((x, y, z)[:axes], self.size[:axes]))

    def inner_extent(self, dimensions: int) -> float:
        """The radius of the largest ball (disc in 2-D) about the centre that fits inside."""
        if self.kind == "cylinder":
            if dimensions == 3 and self.height is not None:
                return min(self.radius, self.height / 2.0)
            return self.radius
        return min(self.size[:dimensions]) / 2.0
