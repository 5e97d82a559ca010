"""The ``[vicsek]`` table of a preset: parameters of the ``vicsek`` dynamics (docs/model.md, "Vicsek et al.
1995").

:class:`Vicsek` is frozen and validated on construction (ConfigError naming ``vicsek.<key>``):

* ``radius``  r: a boid aligns with every boid closer than r, itself included (world units)
* ``speed``   v0: the constant speed (units/s)
* ``noise``   eta in [0, 2 pi] radians: in 2-D the new heading angle is the neighbours' mean plus a draw
  uniform in [-eta/2, eta/2]; in 3-D the new heading is uniform on the spherical cap about the mean
  heading whose solid angle is 2 eta (the same share eta / 2 pi of all directions; the whole sphere at
  eta = 2 pi)
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import check_positive, check_within


@dataclass(frozen=True)
class Vicsek:
    """Vicsek et al. (1995) alignment radius, speed and noise amplitude."""

    radius: float = 1.0
    speed: float = 0.03
    noise: float = 2.0

    def __post_init__(self):
        check_positive("vicsek.radius", self.radius)
        check_positive("vicsek.speed", self.speed)
        check_within("vicsek.noise", self.noise, 0.0, 2.0 * math.pi)
