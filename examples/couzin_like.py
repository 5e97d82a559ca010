"""A Couzin-like plug-in dynamics (docs/plugins.md): zones of repulsion, orientation and attraction.

Neighbours closer than ``zor`` repel and nothing else counts; otherwise boid i turns towards the mean
heading of those within ``zoo`` plus the directions to those within ``zoa`` (Couzin et al. 2002). Its
desired velocity is that direction (plus Gaussian noise) at ``cruise_speed``; it steers towards it.
"""
import math
from dataclasses import dataclass

from flocksweep.simcore.plugin import PluginParams, parameter, slots
from flocksweep.simcore.rng import STREAM_PLUGIN, normal
from flocksweep.simcore.schema import ConfigError


@dataclass(frozen=True)
class Params(PluginParams):
    zor: float = parameter(1.0, unit="world units", low=0.0, low_open=True, doc="zone of repulsion")
    zoo: float = parameter(5.0, unit="world units", low=0.0, doc="zone of orientation (outer radius)")
    zoa: float = parameter(9.0, unit="world units", low=0.0, doc="zone of attraction (outer radius)")
    cruise_speed: float = parameter(3.0, unit="world units/s", low=0.0)
    gain: float = parameter(4.0, unit="1/s", low=0.0, doc="steering force per unit velocity mismatch")
    noise: float = parameter(0.0, low=0.0, high=2.0, doc="s.d. of the noise added to the unit direction")

    def __post_init__(self):
        super().__post_init__()
        if not self.zor <= self.zoo <= self.zoa:
            raise ConfigError("zoo", f"zones must nest: zor {self.zor} <= zoo {self.zoo} <= zoa {self.zoa}")


P = slots(Params)


def steer(i, step, m, nbrs, state, fp, ip, p, key):
    pos, vel, fwd = state[0], state[1], state[2]
    rx = ry = rz = ox = oy = oz = ax = ay = az = 0.0
    repel = False
    for a in range(m):
        j, dx, dy, dz = nbrs.idx[a], nbrs.off[a, 0], nbrs.off[a, 1], nbrs.off[a, 2]
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        if d < p[P.zor]:
            repel = True
            rx, ry, rz = rx - dx / d, ry - dy / d, rz - dz / d
        elif d < p[P.zoo]:
            ox, oy, oz = ox + fwd[j, 0], oy + fwd[j, 1], oz + fwd[j, 2]
        elif d < p[P.zoa]:
            ax, ay, az = ax + dx / d, ay + dy / d, az + dz / d
    if repel:
        ux, uy, uz = rx, ry, rz
    elif ox == oy == oz == ax == ay == az == 0.0:
        ux, uy, uz = fwd[i, 0], fwd[i, 1], fwd[i, 2]
    else:
        ux, uy, uz = ox + ax, oy + ay, oz + az
    norm = math.sqrt(ux * ux + uy * uy + uz * uz) + 1e-12
    s = p[P.noise]
    ux, uy, uz = (ux / norm + s * normal(key, STREAM_PLUGIN, step, 3 * i),
                  uy / norm + s * normal(key, STREAM_PLUGIN, step, 3 * i + 1),
                  uz / norm + s * normal(key, STREAM_PLUGIN, step, 3 * i + 2))
    norm = math.sqrt(ux * ux + uy * uy + uz * uz) + 1e-12
    k, v = p[P.gain], p[P.cruise_speed] / norm
    return k * (ux * v - vel[i, 0]), k * (uy * v - vel[i, 1]), k * (uz * v - vel[i, 2])
