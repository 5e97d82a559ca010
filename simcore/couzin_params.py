"""The ``[couzin]`` table of a preset: parameters of the ``couzin2002`` dynamics (docs/model.md, "Couzin et
al. 2002").

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
"""
from __future__ import annotations

from dataclasses import dataclass

from .schema import ConfigError, check_non_negative, check_positive, check_within


@dataclass(frozen=True)
class Couzin:
    """Couzin et al. (2002) zones, blind angle, turning rate, angular noise and speed (paper's values)."""

    repulsion_radius: float = 1.0
    orientation_width: float = 2.0
    attraction_width: float = 14.0
    blind_deg: float = 90.0
    turning_rate_deg: float = 40.0
    noise_sd: float = 0.05
    speed: float = 3.0

    def __post_init__(self):
        check_positive("couzin.repulsion_radius", self.repulsion_radius)
        check_non_negative("couzin.orientation_width", self.orientation_width)
        check_non_negative("couzin.attraction_width", self.attraction_width)
        if not (0.0 <= self.blind_deg < 360.0):
            raise ConfigError("couzin.blind_deg", f"got {self.blind_deg!r}; allowed range [0, 360)")
        check_within("couzin.turning_rate_deg", self.turning_rate_deg, 0.0, 1e9, lo_open=True)
        check_non_negative("couzin.noise_sd", self.noise_sd)
        check_positive("couzin.speed", self.speed)

    @property
    def outer_radius(self) -> float:
        """r_r + dr_o + dr_a: the reach of the zone of attraction (the perception sphere)."""
        return self.repulsion_radius + self.orientation_width + self.attraction_width
