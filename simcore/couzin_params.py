"""The ``couzin2002`` dynamics' descriptor (:mod:`simcore.registry`): its ``[couzin]`` table, capabilities
and random stream; its hooks are :mod:`simcore.couzin2002` (docs/model.md, "Couzin et al. 2002").

:class:`Couzin` is frozen and validated on construction (ConfigError naming ``couzin.<key>``, the bad value
and what is allowed). Lengths in world units, times in seconds, angles in degrees except the noise sd (in
radians, as the paper states it):

* ``repulsion_radius``    r_r: neighbours closer than this repel (and override everything else)
* ``orientation_width``   dr_o: the zone of orientation is r_r <= |d| < r_r + dr_o
* ``attraction_width``    dr_a: the zone of attraction is r_r + dr_o <= |d| < r_r + dr_o + dr_a
* ``blind_deg``           full angle of the blind cone behind a boid (360 - the paper's field alpha)
* ``turning_rate_deg``    theta: the largest turn, degrees per second (theta dt per step)
* ``noise_sd``            sigma: sd of the angular noise on the desired heading, radians
* ``speed``               s: the constant speed, units/s

A constant-speed heading model: it perceives with the sphere reaching the zone of attraction's outer edge
(a preset's canonical form records only ``perception.kind``), runs in 2-D or 3-D, has its own noise and
speed (no ``[noise]``, ``[cruise]``, change of leadership or pattern mode), and draws its noise from
stream ``STREAMS["noise"]``.
"""
from __future__ import annotations

from dataclasses import dataclass

from .plugin import PluginParams, parameter

TABLE = "couzin"
HOOKS = ".couzin2002"
PLANAR = True
HEADING = True
PERCEPTION = "sphere"
PATTERNS = False
SHARED_NOISE = False
USES = ("noise", "cruise", "plugin")   # recorded (off, None) in its canonical form since it shipped
STREAMS = {"noise": 8}       # the angular noise (normals)


@dataclass(frozen=True)
class Couzin(PluginParams):
    """Couzin et al. (2002) zones, blind angle, turning rate, angular noise and speed (paper's values)."""

    TABLE = "couzin"
    repulsion_radius: float = parameter(1.0, unit="world units", low=0.0, low_open=True, length=1, doc="r_r")
    orientation_width: float = parameter(2.0, unit="world units", low=0.0, length=1, doc="dr_o")
    attraction_width: float = parameter(14.0, unit="world units", low=0.0, length=1, doc="dr_a")
    blind_deg: float = parameter(90.0, unit="deg", low=0.0, high=360.0, high_open=True, length=0,
                                 doc="full angle of the blind cone")
    turning_rate_deg: float = parameter(40.0, unit="deg/s", low=0.0, low_open=True, high=1e9, length=0,
                                        doc="theta, the largest turn per second")
    noise_sd: float = parameter(0.05, unit="rad", low=0.0, length=0, doc="sigma, sd of the angular noise")
    speed: float = parameter(3.0, unit="units/s", low=0.0, low_open=True, length=1, doc="s, the constant speed")

    @property
    def outer_radius(self) -> float:
        """r_r + dr_o + dr_a: the reach of the zone of attraction (the perception sphere)."""
        return self.repulsion_radius + self.orientation_width + self.attraction_width


Params = Couzin


def sphere_radius(model) -> float:
    """The perception sphere: the outer edge of the zone of attraction."""
    return model.couzin.outer_radius
