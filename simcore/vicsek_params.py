"""The ``vicsek`` dynamics' descriptor (:mod:`simcore.registry`): its ``[vicsek]`` table, capabilities and
random stream; its hooks are :mod:`simcore.vicsek` (docs/model.md, "Vicsek et al. 1995").

:class:`Vicsek` is frozen and validated on construction (ConfigError naming ``vicsek.<key>``):

* ``radius``  r: a boid aligns with every boid closer than r, itself included (world units)
* ``speed``   v0: the constant speed (units/s)
* ``noise``   eta in [0, 2 pi] radians: in 2-D the new heading angle is the neighbours' mean plus a draw
  uniform in [-eta/2, eta/2]; in 3-D the new heading is uniform on the spherical cap about the mean
  heading whose solid angle is 2 eta (the same share eta / 2 pi of all directions; the whole sphere at
  eta = 2 pi)

A constant-speed heading model: it perceives with the sphere of radius r (so a preset's canonical form
records only ``perception.kind``), runs in 2-D or 3-D, has its own noise and speed (no ``[noise]``,
``[cruise]``, change of leadership or pattern mode), and draws its noise from stream ``STREAMS["noise"]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .plugin import PluginParams, parameter

TABLE = "vicsek"
HOOKS = ".vicsek"
PLANAR = True
HEADING = True
PERCEPTION = "sphere"
PATTERNS = False
SHARED_NOISE = False
USES = ("noise", "cruise", "plugin")   # recorded (off, None) in its canonical form since it shipped
STREAMS = {"noise": 9}       # the angular noise (uniforms)


@dataclass(frozen=True)
class Vicsek(PluginParams):
    """Vicsek et al. (1995) alignment radius, speed and noise amplitude."""

    TABLE = "vicsek"
    radius: float = parameter(1.0, unit="world units", low=0.0, low_open=True, length=1, doc="r, the alignment radius")
    speed: float = parameter(0.03, unit="units/s", low=0.0, low_open=True, length=1, doc="v0, the constant speed")
    noise: float = parameter(2.0, unit="rad", low=0.0, high=2.0 * math.pi, length=0, doc="eta, the noise amplitude")


Params = Vicsek


def sphere_radius(model) -> float:
    """The perception sphere: the alignment radius."""
    return model.vicsek.radius
